"""Two bonded particles, one mode at a time: the oscillation period equals the analytic one
of the SPEC's linear springs (E A/L0, G A/L0, G J/L0, E I/L0) within 0.5 %.

Equal spheres, mass m, moment of inertia I_p = 2/5 m r^2, bond along x, L0 = 2 r:
- axial:    omega^2 = (E A/L0) / (m/2)             (reduced mass)
- twisting: omega^2 = (G J/L0) / (I_p/2)           (reduced inertia)
- bending:  omega^2 = 2 (E I/L0) / I_p             (w_i = -w_j, no shear coupling)
- shear:    omega^2 = (G A/L0) (2/m + L0^2/(2 I_p))
  u_j = -u_i = u with equal rotations phi = -m L0 u / (2 I_p): the translation couples
  to rotation through v_rel's (w_i + w_j) x r / 2 term and the (r/2) x F_t moment; this
  is the mode orthogonal (in the mass metric) to the rigid rotation of the pair.
"""
import numpy as np
import pytest

import bondem

from bondtools import RADIUS, SPACING, bond_constants


def measured_period(signal, dt):
    """Mean period (s) from the upward zero crossings of a signal, interpolated linearly."""
    s = np.asarray(signal) - np.mean(signal)
    k = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    crossings = (k + s[k] / (s[k] - s[k + 1])) * dt
    assert len(crossings) >= 4, "fewer than three periods recorded"
    return (crossings[-1] - crossings[0]) / (len(crossings) - 1)


def run_pair(glass, binder, velocity, angular_velocity, observe, periods=5, omega=None):
    position = [[0.0, 0.0, 0.0], [SPACING, 0.0, 0.0]]
    model, state = bondem.make_system(position, RADIUS, glass, velocity=velocity,
                                      angular_velocity=angular_velocity, bonds=[[0, 1]],
                                      bond_diameter=1e-3, bond_material=binder)
    dt = 0.05 * min(bondem.time_scales(model).values())
    sim = bondem.Simulation(model, state, time_step=dt)
    steps = int(periods * 2 * np.pi / omega / dt)
    signal = np.empty(steps)
    sim.step(0)  # start-up half kick
    for k in range(steps):
        sim.step(1)
        signal[k] = observe(state)
    return model, measured_period(signal, dt)


def test_axial_period(glass, binder):
    (kn, _, _, _), _ = bond_constants(binder)
    m = glass.density * 4 / 3 * np.pi * RADIUS ** 3
    omega = np.sqrt(kn / (m / 2))
    _, period = run_pair(glass, binder, [[-1e-4, 0, 0], [1e-4, 0, 0]], None,
                         lambda s: s.position[1, 0] - s.position[0, 0], omega=omega)
    assert period == pytest.approx(2 * np.pi / omega, rel=5e-3)


def test_twisting_period(glass, binder):
    (_, _, ktw, _), _ = bond_constants(binder)
    m = glass.density * 4 / 3 * np.pi * RADIUS ** 3
    inertia = 0.4 * m * RADIUS ** 2
    omega = np.sqrt(ktw / (inertia / 2))
    _, period = run_pair(glass, binder, None, [[1.0, 0, 0], [-1.0, 0, 0]],
                         lambda s: s.angular_velocity[0, 0], omega=omega)
    assert period == pytest.approx(2 * np.pi / omega, rel=5e-3)


def test_bending_period(glass, binder):
    (_, _, _, kb), _ = bond_constants(binder)
    m = glass.density * 4 / 3 * np.pi * RADIUS ** 3
    inertia = 0.4 * m * RADIUS ** 2
    omega = np.sqrt(2 * kb / inertia)
    _, period = run_pair(glass, binder, None, [[0, 0, 1.0], [0, 0, -1.0]],
                         lambda s: s.angular_velocity[0, 2], omega=omega)
    assert period == pytest.approx(2 * np.pi / omega, rel=5e-3)


def test_shear_period_with_rotation_coupling(glass, binder):
    (_, ks, _, _), _ = bond_constants(binder)
    m = glass.density * 4 / 3 * np.pi * RADIUS ** 3
    inertia = 0.4 * m * RADIUS ** 2
    omega = np.sqrt(ks * (2 / m + SPACING ** 2 / (2 * inertia)))
    a = 1e-4
    spin = -m * SPACING * a / (2 * inertia)
    _, period = run_pair(glass, binder, [[0, -a, 0], [0, a, 0]], [[0, 0, spin], [0, 0, spin]],
                         lambda s: s.position[1, 1] - s.position[0, 1], omega=omega)
    assert period == pytest.approx(2 * np.pi / omega, rel=5e-3)
    # Without the coupling the period would be that of G A/L0 on m/2: clearly different.
    assert abs(period - 2 * np.pi / np.sqrt(2 * ks / m)) > 0.1 * period

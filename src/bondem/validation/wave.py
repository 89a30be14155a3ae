"""Longitudinal wave speed along a bonded chain vs c = L0 sqrt(k / m).

A free chain of N equal spheres (mass m) along x joined by N - 1 bonds of axial
stiffness k = E A_b / L0 is a discrete spring chain. Its free-free longitudinal modes are
    u_n = cos(k_m pi (n + 1/2) / N),  q = k_m pi / (N L0),
    omega(q) = 2 sqrt(k/m) sin(q L0 / 2)
(the dispersion relation), whose long-wave limit is the wave speed
    c = omega / q -> L0 sqrt(k / m) = sqrt(E A_b L0 / m).
Each mode is started exactly (initial velocities in its shape) and its period measured
from particle 0's displacement. The speed from mode 1 is c sin(x)/x with x = pi/(2N)
(3e-4 below c for N = 40), inside the tolerance.
Pulse: on a long chain a smooth Gaussian displacement pulse of width w (bond lengths)
with velocities v = -c du/dx travels right; the centroid of its kinetic energy, timed
over a known travel, gives the wave speed directly (dispersion slows it by O(1/(8 w^2)),
1e-3 for w = 10).
"""
import numpy as np

import bondem

from .core import CaseResult, Plot, Series, case, compare
from .two_particle import measured_period


def mode_frequency(p, compat, mode):
    """Measured angular frequency (rad/s) of free-free longitudinal mode ``mode``."""
    n, spacing = p["particles"]["count"], p["particles"]["spacing"]
    position = np.column_stack([np.arange(n) * spacing, np.zeros(n), np.zeros(n)])
    shape = np.cos(mode * np.pi * (np.arange(n) + 0.5) / n)
    velocity = np.zeros((n, 3))
    velocity[:, 0] = p["run"]["amplitude"] * shape
    particle = bondem.Material(density=p["material"]["density"],
                               young_modulus=p["material"]["young_modulus"])
    binder = bondem.BondMaterial(young_modulus=p["bond"]["young_modulus"],
                                 poisson_ratio=p["bond"]["poisson_ratio"], breakage="none")
    model, state = bondem.make_system(position, p["particles"]["radius"], particle,
                                      velocity=velocity,
                                      bonds=[[k, k + 1] for k in range(n - 1)],
                                      bond_diameter=p["bond"]["diameter"], bond_material=binder)
    sim = bondem.Simulation(model, state, safety_factor=p["run"]["safety_factor"],
                            musen_compat=compat == "musen")
    k = _stiffness(p)
    expected = 2 * np.sqrt(k / model.mass[0]) * np.sin(mode * np.pi / (2 * n))
    dt = sim.time_step
    steps = int(p["run"]["periods"] * 2 * np.pi / expected / dt) + 2
    signal = np.empty(steps)
    sim.step(0)
    for s in range(steps):
        sim.step(1)
        signal[s] = state.position[0, 0]
    return 2 * np.pi / measured_period(signal, dt), expected, model.mass[0]


def _stiffness(p):
    radius = p["bond"]["diameter"] / 2
    return p["bond"]["young_modulus"] * np.pi * radius ** 2 / p["particles"]["spacing"]


def pulse_speed(p, compat):
    """Speed (m/s) of a right-moving Gaussian pulse's kinetic-energy centroid, and c."""
    pulse = p["pulse"]
    n, spacing = pulse["count"], p["particles"]["spacing"]
    x = np.arange(n) * spacing
    position = np.column_stack([x, np.zeros(n), np.zeros(n)])
    particle = bondem.Material(density=p["material"]["density"],
                               young_modulus=p["material"]["young_modulus"])
    binder = bondem.BondMaterial(young_modulus=p["bond"]["young_modulus"],
                                 poisson_ratio=p["bond"]["poisson_ratio"], breakage="none")
    mass = particle.density * 4 / 3 * np.pi * p["particles"]["radius"] ** 3
    speed = spacing * np.sqrt(_stiffness(p) / mass)
    centre, width = pulse["start"] * spacing, pulse["width"] * spacing
    shape = np.exp(-0.5 * ((x - centre) / width) ** 2)
    position[:, 0] += pulse["amplitude"] * shape
    velocity = np.zeros((n, 3))
    # u(x - c t): v = -c du/dx, a pulse moving toward +x only.
    velocity[:, 0] = speed * pulse["amplitude"] * shape * (x - centre) / width ** 2
    model, state = bondem.make_system(position, p["particles"]["radius"], particle,
                                      velocity=velocity,
                                      bonds=[[k, k + 1] for k in range(n - 1)],
                                      bond_diameter=p["bond"]["diameter"], bond_material=binder)
    # make_system takes the displaced positions as unstretched; measure stretch from the
    # regular lattice instead: reset the initial lengths to the spacing.
    model.bond_initial_length[:] = spacing
    sim = bondem.Simulation(model, state, safety_factor=p["run"]["safety_factor"],
                            musen_compat=compat == "musen")

    def centroid():
        energy = state.velocity[:, 0] ** 2
        return float(np.sum(energy * x) / np.sum(energy))
    sim.step(0)
    quarter = pulse["travel"] * spacing / speed / 4
    sim.run(until=quarter)
    t1, x1 = state.time, centroid()
    sim.run(until=quarter + pulse["travel"] * spacing / speed)
    t2, x2 = state.time, centroid()
    return (x2 - x1) / (t2 - t1), speed


@case("wave", quick=True)
def run(p, compat, quick=False):
    """Bonded chain: longitudinal dispersion relation and wave speed vs L0 sqrt(k/m)."""
    n, spacing = p["particles"]["count"], p["particles"]["spacing"]
    modes = p["run"]["modes"][:p["run"]["quick_modes"]] if quick else p["run"]["modes"]
    k = _stiffness(p)
    rows, measured = [], []
    mass = None
    for mode in modes:
        omega, expected, mass = mode_frequency(p, compat, mode)
        q = mode * np.pi / (n * spacing)
        measured.append((q, omega))
        rows.append(compare("wave", f"mode {mode} angular frequency (rad/s), q = {q:.4g} 1/m",
                            expected, omega, p["run"]["tolerance_frequency"]))
    speed = spacing * np.sqrt(k / mass)
    q1, omega1 = measured[0]
    rows.append(compare("wave", "long-wave speed c = L0 sqrt(k/m) (m/s)", speed, omega1 / q1,
                        p["run"]["tolerance_speed"]))
    measured_speed, _ = pulse_speed(p, compat)
    rows.append(compare("wave", f"pulse speed (m/s), width {p['pulse']['width']:g} L0", speed,
                        measured_speed, p["pulse"]["tolerance"]))
    q_curve = np.linspace(0, np.pi / spacing, 100)
    plot = Plot("Bonded chain: longitudinal dispersion", "wavenumber q (1/m)",
                "angular frequency (rad/s)", [
                    Series("bondem", [q for q, _ in measured], [w for _, w in measured], "o"),
                    Series("2 sqrt(k/m) sin(q L0/2)", list(q_curve),
                           list(2 * np.sqrt(k / mass) * np.sin(q_curve * spacing / 2)), "-"),
                    Series("c q", list(q_curve[:40]), list(speed * q_curve[:40]), "--")])
    return CaseResult(rows, [plot])

"""Two-particle bond: the four oscillation modes against their analytic periods.

Equal spheres (mass m, moment of inertia I_p = 2/5 m r^2) joined by one bond along x,
L0 = the centre distance. With the SPEC's linear springs k_n = E A/L0, k_s = G A/L0,
k_tw = G J/L0, k_b = E I/L0 (A = pi R_b^2, I = pi R_b^4/4, J = 2 I, G = E/(2(1+nu))):
- axial:    omega^2 = k_n / (m/2)                       (reduced mass)
- twisting: omega^2 = k_tw / (I_p/2)                    (reduced inertia)
- bending:  omega^2 = 2 k_b / I_p                       (w_i = -w_j, no shear coupling)
- shear:    omega^2 = k_s (2/m + L0^2 / (2 I_p))
  (u_j = -u_i = u with equal spins phi = -m L0 u / (2 I_p): the translation couples to
  rotation through v_rel's (w_i + w_j) x r / 2 term and the (r/2) x F_t moment.)
The period is measured from upward zero crossings (linear interpolation) over several
periods. The leapfrog's own period error is (omega dt)^2/24, below 1e-4 here.
"""
import numpy as np

import bondem

from .core import CaseResult, Plot, Series, case, compare


def measured_period(signal, dt):
    """Mean period (s) from upward zero crossings of ``signal`` sampled every dt (s)."""
    s = np.asarray(signal) - np.mean(signal)
    k = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    if len(k) < 2:
        return float("nan")
    crossings = (k + s[k] / (s[k] - s[k + 1])) * dt
    return (crossings[-1] - crossings[0]) / (len(crossings) - 1)


def _materials(p):
    glass = bondem.Material(density=p["material"]["density"],
                            young_modulus=p["material"]["young_modulus"],
                            poisson_ratio=p["material"]["poisson_ratio"], name="particle")
    binder = bondem.BondMaterial(young_modulus=p["bond"]["young_modulus"],
                                 poisson_ratio=p["bond"]["poisson_ratio"], breakage="none",
                                 name="bond")
    return glass, binder


def _run_mode(p, compat, velocity, angular_velocity, observe, omega):
    glass, binder = _materials(p)
    spacing, radius = p["particles"]["spacing"], p["particles"]["radius"]
    model, state = bondem.make_system([[0.0, 0.0, 0.0], [spacing, 0.0, 0.0]], radius, glass,
                                      velocity=velocity, angular_velocity=angular_velocity,
                                      bonds=[[0, 1]], bond_diameter=p["bond"]["diameter"],
                                      bond_material=binder)
    dt = p["run"]["time_step_fraction"] * min(bondem.time_scales(model).values())
    sim = bondem.Simulation(model, state, time_step=dt, musen_compat=compat == "musen")
    steps = int(p["run"]["periods"] * 2 * np.pi / omega / dt)
    signal = np.empty(steps)
    sim.step(0)  # MUSEN's prediction step in --compat musen, nothing otherwise
    for k in range(steps):
        sim.step(1)
        signal[k] = observe(state)
    return measured_period(signal, dt), signal, dt


@case("two_particle", quick=True)
def run(p, compat, quick=False):
    """Two bonded spheres: axial, shear, twisting and bending periods vs analytic."""
    radius, spacing = p["particles"]["radius"], p["particles"]["spacing"]
    bond_radius = p["bond"]["diameter"] / 2
    young, poisson = p["bond"]["young_modulus"], p["bond"]["poisson_ratio"]
    shear_modulus = young / (2 * (1 + poisson))
    area, second = np.pi * bond_radius ** 2, np.pi * bond_radius ** 4 / 4
    k_n, k_s = young * area / spacing, shear_modulus * area / spacing
    k_tw, k_b = shear_modulus * 2 * second / spacing, young * second / spacing
    m = p["material"]["density"] * 4 / 3 * np.pi * radius ** 3
    inertia = 0.4 * m * radius ** 2
    a, w = p["run"]["amplitude_velocity"], p["run"]["amplitude_spin"]
    spin = -m * spacing * a / (2 * inertia)
    modes = {
        "axial": (np.sqrt(k_n / (m / 2)), [[-a, 0, 0], [a, 0, 0]], None,
                  lambda s: s.position[1, 0] - s.position[0, 0]),
        "shear": (np.sqrt(k_s * (2 / m + spacing ** 2 / (2 * inertia))),
                  [[0, -a, 0], [0, a, 0]], [[0, 0, spin], [0, 0, spin]],
                  lambda s: s.position[1, 1] - s.position[0, 1]),
        "twisting": (np.sqrt(k_tw / (inertia / 2)), None, [[w, 0, 0], [-w, 0, 0]],
                     lambda s: s.angular_velocity[0, 0]),
        "bending": (np.sqrt(2 * k_b / inertia), None, [[0, 0, w], [0, 0, -w]],
                    lambda s: s.angular_velocity[0, 2]),
    }
    rows, series = [], []
    for name, (omega, velocity, angular_velocity, observe) in modes.items():
        period, signal, dt = _run_mode(p, compat, velocity, angular_velocity, observe, omega)
        reference = 2 * np.pi / omega
        rows.append(compare("two_particle", f"{name} period (s)", reference, period,
                            p["run"]["tolerance"]))
        t = (np.arange(len(signal)) + 1) * dt / reference
        scale = np.max(np.abs(signal - signal.mean())) or 1.0
        series.append(Series(f"{name} (T = {period:.3e} s)", t.tolist(),
                             ((signal - signal.mean()) / scale).tolist(), "-"))
    plot = Plot("Two-particle modes (time in analytic periods)", "t / T_analytic",
                "normalised signal", series)
    return CaseResult(rows, [plot])

"""Bond strength: tension, shear, torsion and bending of a single bond break at the load
the SPEC's formulas give, and the recorded break mode is right.

Both spheres are fixed (their velocities prescribed), so every bond quantity is known in
closed form. After the force evaluation at t = m dt the incremental springs hold m dt of
increments (SPEC 1: the start-up evaluation at t = 0 adds none, so offset s = 0); in
MUSEN-compatible mode the prediction step adds dt and t = 0 is evaluated once more, s = 2:
- tension, j moving away at v:        |F_n| = k_n v m dt,       sigma = |F_n| / A
- shear, both spinning at w about z:  |F_t| = k_s w L0 (m+s) dt, tau = |F_t| / A
- torsion, j spinning at w about x:   |M_n| = k_tw w (m+s) dt,   tau = |M_n| R_b / J
- bending, spins +w, -w about z, j drifting apart slowly (so L > L0), "separate"
  criterion (the bending term alone):  |M_t| = k_b 2 w (m+s) dt, sigma = |M_t| R_b / I
Each strength is set halfway between the stresses of steps M and M + 1, so the bond must
break in the evaluation at t = (M + 1) dt, in mode tension (tension, bending) or shear.
The stress at break is recovered from the elastic energy the bond held when it broke
(State.bond_break_energy) and must equal the closed-form stress of step M + 1, the first
at or above the strength.
"""
import numpy as np

import bondem
from bondem.physics.bond_elastic import BREAK_MODE_NAMES

from .core import CaseResult, Plot, Series, case, compare, compare_exact


def _constants(p):
    radius = p["bond"]["diameter"] / 2
    young, poisson = p["bond"]["young_modulus"], p["bond"]["poisson_ratio"]
    shear_modulus = young / (2 * (1 + poisson))
    length = p["particles"]["spacing"]
    area, second = np.pi * radius ** 2, np.pi * radius ** 4 / 4
    polar = 2 * second
    stiffness = dict(k_n=young * area / length, k_s=shear_modulus * area / length,
                     k_tw=shear_modulus * polar / length, k_b=young * second / length)
    return radius, area, second, polar, stiffness


def _run(p, compat, velocity, angular_velocity, **bond):
    binder = bondem.BondMaterial(young_modulus=p["bond"]["young_modulus"],
                                 poisson_ratio=p["bond"]["poisson_ratio"], **bond)
    particle = bondem.Material(density=p["material"]["density"],
                               young_modulus=p["material"]["young_modulus"])
    model, state = bondem.make_system([[0, 0, 0], [p["particles"]["spacing"], 0, 0]],
                                      p["particles"]["radius"], particle, fixed=[True, True],
                                      velocity=velocity, angular_velocity=angular_velocity,
                                      bonds=[[0, 1]], bond_diameter=p["bond"]["diameter"],
                                      bond_material=binder)
    sim = bondem.Simulation(model, state, time_step=p["run"]["time_step"],
                            musen_compat=compat == "musen")
    limit = 4 * p["run"]["break_step"]
    sim.step(0)
    while state.bond_active[0] and state.step < limit:
        sim.step(1)
    return state


@case("strength", quick=True)
def run(p, compat, quick=False):
    """Single bond in tension, shear, torsion and bending: break step, stress and mode."""
    dt, big_m = p["run"]["time_step"], p["run"]["break_step"]
    v, w, v_b = p["run"]["speed"], p["run"]["spin"], p["run"]["bending_speed"]
    length = p["particles"]["spacing"]
    radius, area, second, polar, k = _constants(p)
    s = 2.0 if compat == "musen" else 0.0
    # Per test: stress(m) in Pa, the loads, the criterion, how to get the stress at break
    # from the break energy E (J), and the expected mode.
    tests = {
        "tension": (lambda m: k["k_n"] * v * m * dt / area, [[0, 0, 0], [v, 0, 0]], None,
                    "normal_strength", {},
                    lambda e: np.sqrt(2 * k["k_n"] * e) / area, "tension"),
        "shear": (lambda m: k["k_s"] * w * length * (m + s) * dt / area, None,
                  [[0, 0, w], [0, 0, w]], "tangential_strength", {},
                  lambda e: np.sqrt(2 * k["k_s"] * e) / area, "shear"),
        "torsion": (lambda m: k["k_tw"] * w * (m + s) * dt * radius / polar, None,
                    [[0, 0, 0], [w, 0, 0]], "tangential_strength", {},
                    lambda e: np.sqrt(2 * k["k_tw"] * e) * radius / polar, "shear"),
        "bending": (lambda m: k["k_b"] * 2 * w * (m + s) * dt * radius / second,
                    [[0, 0, 0], [v_b, 0, 0]], [[0, 0, w], [0, 0, -w]], "normal_strength",
                    {"breakage": "separate"}, None, "tension"),
    }
    rows, labels, ratios = [], [], []
    for name, (stress, velocity, spin, key, extra, from_energy, mode) in tests.items():
        strength = 0.5 * (stress(big_m) + stress(big_m + 1))
        state = _run(p, compat, velocity, spin, **{key: strength}, **extra)
        energy = state.bond_break_energy[0]
        if name == "bending":
            # Energy = axial part (known, tiny) + bending part M_t^2 / (2 k_b).
            broke = not np.isnan(state.bond_break_time[0])
            m_break = round(state.bond_break_time[0] / dt) if broke else 0
            axial = 0.5 * k["k_n"] * (v_b * m_break * dt) ** 2
            stress_at_break = np.sqrt(max(2 * k["k_b"] * (energy - axial), 0.0)) \
                * radius / second
        else:
            stress_at_break = from_energy(energy)
        rows.append(compare("strength", f"{name}: break time (s)", (big_m + 1) * dt,
                            state.bond_break_time[0], p["run"]["tolerance_time"]))
        rows.append(compare("strength", f"{name}: stress at break (Pa)", stress(big_m + 1),
                            stress_at_break, p["run"]["tolerance_stress"],
                            note=f"strength {strength:.6g} Pa; the step before held "
                                 f"{stress(big_m):.6g} Pa"))
        rows.append(compare_exact("strength", f"{name}: break mode", mode,
                                  BREAK_MODE_NAMES[state.bond_break_mode[0]]))
        labels.append(name)
        ratios.append(stress_at_break / strength)
    plot = Plot("Bond strength: stress at break / strength", "test (0 tension, 1 shear, "
                "2 torsion, 3 bending)", "sigma_break / strength",
                [Series("bondem", list(range(len(labels))), ratios, "o"),
                 Series("strength", [0, len(labels) - 1], [1.0, 1.0], "--")])
    return CaseResult(rows, [plot])

"""The bond models beyond the elastic bond (physics/bond_*.py) against their closed forms,
on one bond between two driven spheres (both fixed, velocities prescribed) along the
oblique axis (1, 2, 2)/3:
- elastic-plastic: pulled to delta_1, pushed to delta_2: yield forces F_y = sigma_y A and
  -c F_y, the plastic offset delta_2 + c F_y/k, and the dissipated energy
  F_y (delta_1 - F_y/k) + c F_y (delta_1 - (1 + c) F_y/k - delta_2);
- creep (m = 2) held at a fixed stretch: sigma(t) = sigma_h / (1 + E A sigma_h t);
- parallel bond: the shear stress at break under three normal stresses on the
  Mohr-Coulomb line c - sigma tan phi, and with softening the energy the envelope
  dissipates, sigma_t eps_f A L0 / 2, eps_f = (sigma_t/E)(1 + 1/zeta).
"""
import math

import numpy as np

import bondem
from bondem.physics.bond_elastic import BREAK_MODE_NAMES

from .core import CaseResult, Plot, Series, case, compare, compare_exact

AXIS = np.array([1.0, 2.0, 2.0]) / 3.0
SIDE = np.array([2.0, -2.0, 1.0]) / 3.0


def _pair(p, compat, **bond):
    binder = bondem.BondMaterial(young_modulus=p["bond"]["young_modulus"],
                                 poisson_ratio=p["bond"]["poisson_ratio"], **bond)
    glass = bondem.Material(density=2500.0, young_modulus=1e8)
    model, state = bondem.make_system([[0.0, 0.0, 0.0], p["particles"]["spacing"] * AXIS],
                                      p["particles"]["radius"], glass, fixed=[True, True],
                                      bonds=[[0, 1]], bond_diameter=p["bond"]["diameter"],
                                      bond_material=binder)
    return bondem.Simulation(model, state, time_step=p["run"]["time_step"],
                             musen_compat=compat == "musen")


def _drive(sim, p, distance, direction):
    """Move sphere 1 by ``distance`` (m) along ``direction`` at the run's speed; returns
    the bond's axial force on sphere 0 after each step (N, positive in tension)."""
    speed, dt = p["run"]["speed"], p["run"]["time_step"]
    sim.state.velocity[1] = speed * np.sign(distance) * direction
    forces = []
    for _ in range(int(round(abs(distance) / (speed * dt)))):
        sim.step(1)
        forces.append(float(np.dot(sim.bonds.loads.force_i[0], AXIS)))
    sim.state.velocity[1] = 0.0
    return np.array(forces)


def _plastic(p, compat):
    q = p["plastic"]
    length, young = p["particles"]["spacing"], p["bond"]["young_modulus"]
    area = math.pi * (p["bond"]["diameter"] / 2) ** 2
    k = young * area / length
    f_y, ratio = q["yield_strength"] * area, q["compressive_yield_ratio"]
    sim = _pair(p, compat, model="elastic_plastic", yield_strength=q["yield_strength"],
                compressive_yield_ratio=ratio, fracture_strain=1.0, breakage="none")
    up = _drive(sim, p, q["pull"], AXIS)
    down = _drive(sim, p, -q["push"], AXIS)
    delta_1, delta_2 = q["pull"], q["pull"] - q["push"]
    offset = sim.state.extra["bond_model_state"][0, 1] * length
    dissipated = f_y * (delta_1 - f_y / k) + ratio * f_y * (delta_1 - (1 + ratio) * f_y / k
                                                            - delta_2)
    name = "elastic_plastic"
    rows = [compare("bond_models", f"{name}: tensile yield force (N)", f_y, up.max(), 1e-9),
            compare("bond_models", f"{name}: compressive yield force (N)", -ratio * f_y,
                    down.min(), 1e-9),
            compare("bond_models", f"{name}: plastic offset after compression (m)",
                    delta_2 + ratio * f_y / k, offset, q["tolerance"]),
            compare("bond_models", f"{name}: dissipated energy (J)", dissipated,
                    sim.energy_terms()["dissipated_plastic"], q["tolerance"])]
    return rows, np.concatenate([up, down])


def _creep(p, compat):
    q = p["creep"]
    young = p["bond"]["young_modulus"]
    area = math.pi * (p["bond"]["diameter"] / 2) ** 2
    sim = _pair(p, compat, model="creep", yield_strength=q["yield_strength"],
                creep_rate=q["creep_rate"], creep_exponent=q["creep_exponent"],
                fracture_strain=1.0, breakage="none")
    _drive(sim, p, q["stretch"], AXIS)
    sim.step(1)
    held, start = float(np.dot(sim.bonds.loads.force_i[0], AXIS)) / area, sim.state.time
    sim.step(int(round(q["hold"] / p["run"]["time_step"])))
    t = sim.state.time - start
    now = float(np.dot(sim.bonds.loads.force_i[0], AXIS)) / area
    expected = held / (1 + young * q["creep_rate"] * held * t)
    return [compare("bond_models", f"creep: stress after {t:.3g} s held (Pa)", expected, now,
                    q["tolerance"], note=f"from {held:.6g} Pa; m = 2")]


def _parallel(p, compat):
    q = p["parallel"]
    length, young = p["particles"]["spacing"], p["bond"]["young_modulus"]
    area = math.pi * (p["bond"]["diameter"] / 2) ** 2
    keys = dict(model="parallel", normal_strength=q["tensile_strength"],
                tangential_strength=q["cohesion"], friction_angle=q["friction_angle"])
    rows, normals, shears = [], [], []
    for strain in q["normal_strains"]:
        sim = _pair(p, compat, **keys)
        _drive(sim, p, strain * length, AXIS)
        state = sim.state
        state.velocity[1] = p["run"]["shear_speed"] * SIDE
        normal = shear = 0.0
        while state.bond_active[0] and state.time < 1.0:
            normal = -np.dot(sim.bonds.loads.force_i[0], state.bond_axis[0]) / area
            shear = np.linalg.norm(state.bond_tangential_force[0]) / area
            sim.step(1)
        strength = q["cohesion"] + normal * math.tan(math.radians(q["friction_angle"]))
        rows.append(compare("bond_models", f"parallel: shear stress at break under "
                                           f"{normal:.3g} Pa (Pa)", strength, shear,
                            q["tolerance"], note="Mohr-Coulomb: c - sigma tan phi"))
        rows.append(compare_exact("bond_models", f"parallel: break mode under {normal:.3g} Pa",
                                  "shear", BREAK_MODE_NAMES[state.bond_break_mode[0]]))
        normals.append(normal)
        shears.append(shear)
    sim = _pair(p, compat, **dict(keys, tangential_strength=float("inf"),
                                  softening=q["softening"]))
    eps_f = q["tensile_strength"] / young * (1 + 1 / q["softening"])
    _drive(sim, p, 1.1 * eps_f * length, AXIS)
    rows.append(compare("bond_models", "parallel: energy dissipated by softening (J)",
                        0.5 * q["tensile_strength"] * eps_f * area * length,
                        sim.energy_terms()["dissipated_softening"], q["tolerance"]))
    return rows, normals, shears


@case("bond_models", quick=True)
def run(p, compat, quick=False):
    """Plastic, creep and parallel bonds against their closed forms (yield, offset,
    dissipation, creep relaxation, Mohr-Coulomb line, softening energy)."""
    rows, loop = _plastic(p, compat)
    rows += _creep(p, compat)
    more, normals, shears = _parallel(p, compat)
    rows += more
    q = p["parallel"]
    line = np.array([min(normals), max(normals)])
    plot = Plot("Parallel bond: shear strength against normal stress", "normal stress (Pa, "
                "compression positive)", "shear stress at break (Pa)",
                [Series("bondem", normals, shears, "o"),
                 Series("c + sigma tan phi", list(line), list(
                     q["cohesion"] + line * math.tan(math.radians(q["friction_angle"]))),
                     "--")])
    return CaseResult(rows, [plot])

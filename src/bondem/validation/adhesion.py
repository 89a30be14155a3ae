"""The adhesive contact models (physics/contact_jkr.py, contact_vdw.py, contact_liquid.py)
against their closed forms, on two unlike spheres of two materials along the oblique axis
(1, 2, 2)/3, one driven at a prescribed speed (so the force follows the law's curve):
- JKR pulled apart from a deep overlap: the largest tensile force is the load-controlled
  pull-off force 3/2 pi w R*, the force changes sign at the zero-load overlap
  a_0^2 / (3 R*), a_0 = (9 pi w R*^2 / (2 E*))^(1/3), and the neck breaks at the gap
  delta_c = 3/4 (pi^2 w^2 R* / E*^2)^(1/3) (w = sqrt(w_a w_b));
- van der Waals: A R* / (6 h^2) at three gaps (A = sqrt(A_a A_b));
- liquid bridge: 2 pi R* gamma cos(theta) at contact and the rupture distance
  (1 + theta/2) V^(1/3) of Lian et al.;
- JKR without damping (e = 1): a sphere that hits a plane of its material at v_in leaves
  at v_out with v_in^2 - v_out^2 = v_s^2, the sticking speed of the energy balance
  1/2 m* v_s^2 = 7.09 (w^5 R*^4 / E*^2)^(1/3) (the JKR cycle's loss, Johnson & Pollock
  1994; Thornton & Ning 1998 estimate 1.84 (F_c^5 / (E*^2 R* m*^3))^(1/6), 1.8 times more:
  docs/contact_jkr.md).
"""
import math

import numpy as np

import bondem
from bondem.contacts import ContactSettings
from bondem.walls import PlaneWall

from .core import CaseResult, Plot, Series, case, compare

AXIS = np.array([1.0, 2.0, 2.0]) / 3.0


def _pair(p, model, gap, keys, speed=0.0):
    """Sphere 0 at the origin, sphere 1 at surface gap ``gap`` (m) along AXIS, driven away
    at ``speed`` (m/s); materials a and b with ``keys`` {key: (value_a, value_b)}."""
    q = p["particles"]
    materials = [bondem.Material(density=q["density"], young_modulus=q["young_modulus"][k],
                                 poisson_ratio=q["poisson_ratio"][k], restitution=1.0,
                                 name="ab"[k], **{key: v[k] for key, v in keys.items()})
                 for k in range(2)]
    r_a, r_b = q["radius"]
    model_, state = bondem.make_system(
        [[0.0, 0.0, 0.0], (r_a + r_b + gap) * AXIS], q["radius"], materials,
        material_index=[0, 1], velocity=[[0.0, 0.0, 0.0], speed * AXIS], fixed=[True, True])
    return bondem.Simulation(model_, state, contact=ContactSettings(model=model),
                             safety_factor=0.2)


def _reduced(p):
    q = p["particles"]
    r_a, r_b = q["radius"]
    e_star = 1.0 / sum((1 - nu ** 2) / e for e, nu in zip(q["young_modulus"],
                                                          q["poisson_ratio"]))
    return r_a * r_b / (r_a + r_b), e_star


def _normal_force(sim):
    """The contact's force on sphere 1 along AXIS (N, > 0 repulsive), 0 without a row."""
    rows = sim.state.extra["contact_force"]
    return -float(np.dot(rows[0], AXIS)) if rows.shape[0] else 0.0


def _jkr(p):
    q = p["jkr"]
    r_star, e_star = _reduced(p)
    w = math.sqrt(q["surface_energy"][0] * q["surface_energy"][1])
    sim = _pair(p, "jkr", -q["overlap"], {"surface_energy": q["surface_energy"]}, q["speed"])
    sim.time_step = q["time_step"]
    gaps, forces = [], []
    start = sim.state.position[1].copy()
    r_sum = sum(p["particles"]["radius"])
    while True:
        gap = float(np.dot(sim.state.position[1] - start, AXIS)) - q["overlap"]
        sim.step(1)
        force = _normal_force(sim)
        if force == 0.0 and gaps:
            break
        gaps.append(gap)
        forces.append(force)
    gaps, forces = np.array(gaps), np.array(forces)
    sign = np.flatnonzero((forces[:-1] > 0) & (forces[1:] <= 0))[0]
    zero = gaps[sign] + forces[sign] / (forces[sign] - forces[sign + 1]) * (gaps[sign + 1]
                                                                          - gaps[sign])
    a_0 = (9 * math.pi * w * r_star ** 2 / (2 * e_star)) ** (1 / 3)
    delta_c = 0.75 * (math.pi ** 2 * w ** 2 * r_star / e_star ** 2) ** (1 / 3)
    step = q["speed"] * q["time_step"]
    del r_sum
    rows = [compare("adhesion", "JKR: pull-off force 3/2 pi w R* (N)",
                    1.5 * math.pi * w * r_star, -forces.min(), q["tolerance"]),
            compare("adhesion", "JKR: zero-load overlap a_0^2 / (3 R*) (m)",
                    a_0 ** 2 / (3 * r_star), -zero, q["tolerance"]),
            compare("adhesion", "JKR: gap at which the neck breaks (m)", delta_c,
                    gaps[-1] + step, max(1e-4, 2 * step / delta_c))]
    plot = Plot("JKR: force against overlap, pulled apart", "overlap (m)",
                "normal force (N, repulsive > 0)",
                [Series("bondem", list(-gaps), list(forces), "-")])
    return rows, plot


def _vdw(p):
    q = p["vdw"]
    r_star, _ = _reduced(p)
    a = math.sqrt(q["hamaker_constant"][0] * q["hamaker_constant"][1])
    rows = []
    for gap in q["gaps"]:
        sim = _pair(p, "vdw", gap, {"hamaker_constant": q["hamaker_constant"],
                                    "vdw_cutoff": (q["cutoff"], q["cutoff"])})
        sim.step(1)
        rows.append(compare("adhesion", f"van der Waals: A R* / (6 h^2) at h = {gap:g} m (N)",
                            -a * r_star / (6 * gap * gap), _normal_force(sim), 1e-9))
    return rows


def _liquid(p):
    q = p["liquid"]
    r_star, _ = _reduced(p)
    keys = {k: (q[k], q[k]) for k in ("surface_tension", "contact_angle", "bridge_volume")}
    sim = _pair(p, "liquid_bridge", 0.0, keys, q["speed"])
    sim.state.position[1] -= 1e-12 * AXIS     # touching: the bridge forms
    start = sim.state.position[1].copy()
    sim.step(1)
    f_0 = 2 * math.pi * r_star * q["surface_tension"] * math.cos(math.radians(q["contact_angle"]))
    at_contact = -_normal_force(sim)
    while _normal_force(sim) != 0.0:
        gap = float(np.dot(sim.state.position[1] - start, AXIS))
        sim.step(1)
    rupture = (1 + math.radians(q["contact_angle"]) / 2) * q["bridge_volume"] ** (1 / 3)
    step = q["speed"] * sim.time_step
    return [compare("adhesion", "liquid bridge: force at contact 2 pi R* gamma cos(theta) (N)",
                    f_0, at_contact, 1e-6),
            compare("adhesion", "liquid bridge: rupture gap (1 + theta/2) V^(1/3) (m)",
                    rupture, gap, max(1e-3, 2 * step / rupture))]


def _sticking(p):
    q = p["jkr"]
    m = p["particles"]
    r, w = m["radius"][0], q["surface_energy"][0]
    material = bondem.Material(density=m["density"], young_modulus=m["young_modulus"][0],
                               poisson_ratio=m["poisson_ratio"][0], restitution=1.0,
                               surface_energy=w)
    e_star = m["young_modulus"][0] / (2.0 * (1.0 - m["poisson_ratio"][0] ** 2))
    mass = m["density"] * 4.0 / 3.0 * math.pi * r ** 3
    v_s = math.sqrt(2.0 * 7.09 * (w ** 5 * r ** 4 / e_star ** 2) ** (1 / 3) / mass)
    v_in = q["impact_speed_ratio"] * v_s
    model, state = bondem.make_system([[0.0, 0.0, r + 1e-3 * r]], r, material,
                                      velocity=[[0.0, 0.0, -v_in]])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="jkr"),
                            walls=[PlaneWall([0, 0, 0], [0, 0, 1], material)],
                            safety_factor=q["impact_safety_factor"])
    while state.velocity[0, 2] < 0.0 or state.extra["wall_force_rows"].any():
        sim.step(1)
    v_out = float(state.velocity[0, 2])
    return [compare("adhesion", "JKR (e = 1): sticking speed sqrt(v_in^2 - v_out^2) (m/s)",
                    v_s, math.sqrt(v_in ** 2 - v_out ** 2), q["impact_tolerance"])]


@case("adhesion", quick=True)
def run(p, compat, quick=False):
    """JKR, van der Waals and liquid bridges against their closed forms (pull-off force
    and gap, zero-load overlap, sticking speed, Hamaker's force, capillary force and rupture
    distance)."""
    rows, plot = _jkr(p)
    rows += _sticking(p)
    rows += _vdw(p)
    rows += _liquid(p)
    return CaseResult(rows, [plot])

"""Clumps (bondem.clumps; rigid grains of spheres) against closed forms:
- a free asymmetric clump (an L of three spheres): its body-frame angular velocity
  against Euler's equations I1 dw1/dt = (I2 - I3) w2 w3 (cyclic) solved to 1e-12, and
  its angular momentum, which must not change;
- the mass and principal moments of two overlapping spheres against a quadrature of
  their union, a solid of revolution;
- a trimer rolling down an incline on its two outer spheres: a = g sin / (1 + I/(M R^2));
- two clumps bonded by an elastic bond, one fixed, a moment on the other: it turns by
  theta = M L0 / (E I) about the bond's centre, so its bonded sphere, L0/2 from there,
  moves by theta L0 / 2.
"""
import math

import numpy as np
from scipy.integrate import quad, solve_ivp

import bondem
from bondem.clumps import make_clumps, mass_properties, rotation_matrix
from bondem.contacts import ContactSettings
from bondem.walls import PlaneWall

from .core import CaseResult, case, compare

CASE = "clumps"


def _material(p, friction=0.3):
    q = p["particles"]
    return bondem.Material(name="m", density=q["density"], young_modulus=q["young_modulus"],
                           poisson_ratio=q["poisson_ratio"], restitution=0.3,
                           friction=friction)


def _free(p):
    q, f = p["particles"], p["free"]
    r = q["radius"]
    shape = np.array([[0.0, 0.0, 0.0], [2.0 * r, 0.0, 0.0], [0.0, 2.6 * r, 0.0]])
    model, state = bondem.make_system(shape, [r, r, 0.9 * r], _material(p),
                                      angular_velocity=np.tile(f["spin"], (3, 1)))
    model, state = make_clumps(model, state, [0, 0, 0])
    sim = bondem.Simulation(model, state, time_step=f["time_step"], force_time_step=True)
    i1, i2, i3 = model.clump_inertia[0]
    w0 = rotation_matrix(state.clump_orientation[0]).T @ np.asarray(f["spin"], float)
    momentum = state.clump_angular_momentum[0].copy()

    def euler(_, w):
        return [(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2,
                (i1 - i2) * w[0] * w[1] / i3]

    truth = solve_ivp(euler, (0.0, f["time"]), w0, rtol=1e-12,
                      atol=1e-12 * np.linalg.norm(w0)).y[:, -1]
    sim.run(until=f["time"])
    body = rotation_matrix(sim.state.clump_orientation[0]).T @ sim.state.angular_velocity[0]
    size = float(np.linalg.norm(w0))
    change = float(np.linalg.norm(sim.state.clump_angular_momentum[0] - momentum))
    return [compare(CASE, "free L: body spin error at t (of |w0|)", 0.0,
                    float(np.linalg.norm(body - truth)) / size, f["tolerance"],
                    absolute=True, note="Euler's equations, solve_ivp 1e-12"),
            compare(CASE, "free L: |L - L0| / |L0|", 0.0,
                    change / float(np.linalg.norm(momentum)), 1e-12, absolute=True)]


def _overlap(p):
    rho = p["particles"]["density"]
    o = p["overlap"]
    r1, r2 = o["radii"]
    d = o["distance"]

    def radius(z):
        return math.sqrt(max(r1 * r1 - z * z, r2 * r2 - (z - d) ** 2, 0.0))

    kw = dict(points=[d - r2, r1], limit=200, epsabs=0.0, epsrel=1e-13)
    volume = quad(lambda z: math.pi * radius(z) ** 2, -r1, d + r2, **kw)[0]
    zc = quad(lambda z: math.pi * radius(z) ** 2 * z, -r1, d + r2, **kw)[0] / volume
    i_axis = rho * quad(lambda z: math.pi * radius(z) ** 4 / 2, -r1, d + r2, **kw)[0]
    i_perp = rho * quad(lambda z: math.pi * radius(z) ** 4 / 4
                        + math.pi * radius(z) ** 2 * (z - zc) ** 2, -r1, d + r2, **kw)[0]
    axis = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
    mass, _, tensor = mass_properties([[0.0, 0.0, 0.0], d * axis], [r1, r2], rho)
    moments = np.linalg.eigvalsh(tensor)
    return [compare(CASE, "overlapping pair: mass (kg)", rho * volume, mass, o["tolerance"]),
            compare(CASE, "overlapping pair: I about the axis (kg m^2)", i_axis,
                    float(axis @ tensor @ axis), o["tolerance"]),
            compare(CASE, "overlapping pair: I across (kg m^2)", i_perp, moments[2],
                    o["tolerance"])]


def _rolling(p):
    q, s = p["particles"], p["rolling"]
    r, g = q["radius"], 9.81
    theta = math.radians(s["angle"])
    normal = np.array([-math.sin(theta), 0.0, math.cos(theta)])
    gravity = np.array([0.0, 0.0, -g])
    downhill = gravity - (gravity @ normal) * normal
    downhill /= np.linalg.norm(downhill)
    across = np.cross(normal, downhill)
    small = s["middle_radius"] * r
    centres = [(k * s["spacing"] * r) * across + 0.999 * r * normal for k in (-1, 0, 1)]
    material = _material(p, s["friction"])
    model, state = bondem.make_system(centres, [r, small, r], material, gravity=gravity)
    model, state = make_clumps(model, state, [0, 0, 0])
    sim = bondem.Simulation(model, state, time_step=s["time_step"], force_time_step=True,
                            contact=ContactSettings(),
                            walls=[PlaneWall((0.0, 0.0, 0.0), normal, material)])
    sim.step(s["settle_steps"])
    t0, v0 = sim.state.time, sim.state.clump_velocity[0] @ downhill
    sim.step(s["steps"])
    a = (sim.state.clump_velocity[0] @ downhill - v0) / (sim.state.time - t0)
    rho = q["density"]
    m_out, m_mid = rho * 4 / 3 * math.pi * r ** 3, rho * 4 / 3 * math.pi * small ** 3
    mass = 2 * m_out + m_mid
    inertia = 0.4 * (2 * m_out * r * r + m_mid * small * small)
    return [compare(CASE, "rolling trimer: acceleration (m/s^2)",
                    g * math.sin(theta) / (1.0 + inertia / (mass * r * r)), a, s["tolerance"],
                    note="g sin / (1 + I/(M R^2))")]


def _bending(p):
    q, b = p["particles"], p["bending"]
    r = q["radius"]
    position = np.array([[-3 * r, 0, 0], [-r, 0, 0], [r, 0, 0], [3 * r, 0, 0],
                         [r, 2.1 * r, 0]], dtype=float)
    moment = np.zeros((5, 3))
    moment[4, 2] = b["moment"]
    bond = bondem.BondMaterial(name="b", young_modulus=b["bond_young_modulus"],
                               poisson_ratio=0.3)
    model, state = bondem.make_system(position, [r, r, r, r, 1.1 * r], _material(p),
                                      fixed=[True, True, False, False, False],
                                      external_moment=moment, bonds=[[1, 2]],
                                      bond_diameter=2 * b["bond_radius"], bond_material=bond,
                                      damping=b["damping"])
    model, state = make_clumps(model, state, [0, 0, 1, 1, 1])
    start = rotation_matrix(state.clump_orientation[1])
    sim = bondem.Simulation(model, state, time_step=b["time_step"], force_time_step=True)
    sim.step(b["steps"])
    turn = rotation_matrix(sim.state.clump_orientation[1]) @ start.T
    angle = 0.5 * (turn[1, 0] - turn[0, 1])
    length = 2.0 * r
    inertia = math.pi * b["bond_radius"] ** 4 / 4.0
    theta = b["moment"] * length / (b["bond_young_modulus"] * inertia)
    return [compare(CASE, "bonded clumps: bending angle (rad)", theta, angle, b["tolerance"],
                    note="M L0 / (E I)"),
            compare(CASE, "bonded clumps: bonded sphere's travel (m)", theta * length / 2.0,
                    sim.state.position[2, 1], b["tolerance"],
                    note="theta L0 / 2: the bond's centre stays")]


@case(CASE, quick=True)
def run(p, compat, quick=False):
    """Clumps: a free asymmetric clump against Euler's equations, the inertia of
    overlapping spheres, a rolling trimer and two bonded clumps bending."""
    return CaseResult(_free(p) + _overlap(p) + _rolling(p) + _bending(p))

"""Clumps (bondem.clumps, physics/rigid_body.py, loops.integrate_clump) against closed
forms: the inertia of spheres and of overlapping spheres, Euler's equations of a free
asymmetric body, the intermediate axis theorem, a rigid body on an incline and the
elastic bond's own closed forms with the clump's lever arms."""
import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from bondem import BondMaterial, Material, Simulation
from bondem.clumps import (make_clumps, mass_properties,
                           principal_frame, quaternion_from_matrix, random_orientations,
                           rotation_matrix, set_clump_motion)
from bondem.contacts import ContactSettings
from bondem.model import make_system
from bondem.walls import PlaneWall

RHO = 2500.0
GLASS = Material(name="glass", density=RHO, young_modulus=1e8, poisson_ratio=0.25,
                 restitution=0.5, friction=0.4)


def sphere_mass(r):
    return RHO * 4.0 / 3.0 * np.pi * r ** 3


# -- mass properties ------------------------------------------------------------------------

def test_dumbbell_inertia_is_the_closed_form():
    # two spheres of radii a and b, centres s apart (apart: exact sums): the centre of
    # mass divides s by the masses, I_axis = 2/5 (m_a a^2 + m_b b^2), I_perp adds
    # m_a m_b / (m_a + m_b) s^2 (the reduced mass at the distance)
    a, b, s = 1.0e-3, 0.6e-3, 2.3e-3
    axis = np.array([2.0, -1.0, 0.5]) / np.sqrt(5.25)
    start = np.array([0.1e-3, 0.2e-3, -0.3e-3])
    mass, centre, tensor = mass_properties([start, start + s * axis], [a, b], RHO)
    ma, mb = sphere_mass(a), sphere_mass(b)
    assert mass == pytest.approx(ma + mb, rel=1e-14)
    assert centre == pytest.approx(start + mb / (ma + mb) * s * axis, rel=1e-13, abs=0)
    i_axis = 0.4 * (ma * a * a + mb * b * b)
    i_perp = i_axis + ma * mb / (ma + mb) * s * s
    moments, axes = principal_frame(tensor)
    assert moments == pytest.approx([i_axis, i_perp, i_perp], rel=1e-12)
    assert abs(axes[:, 0] @ axis) == pytest.approx(1.0, rel=1e-12)
    assert np.linalg.det(axes) == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("direction", [(0.0, 0.0, 1.0), (1.0, 2.0, 3.0)])
def test_overlapping_pair_within_the_stated_accuracy(direction):
    # the union of two overlapping spheres is a solid of revolution about their axis,
    # cross-section radius R(z) = max of the two discs': its volume, centre and moments
    # by a 1D quadrature to 1e-13 are the truth for the column integral (1e-4 stated)
    r1, r2, d = 1.0e-3, 0.7e-3, 1.2e-3

    def radius(z):
        return np.sqrt(max(r1 * r1 - z * z, r2 * r2 - (z - d) ** 2, 0.0))

    kw = dict(points=[d - r2, r1], limit=200, epsabs=0.0, epsrel=1e-13)
    volume = quad(lambda z: np.pi * radius(z) ** 2, -r1, d + r2, **kw)[0]
    zc = quad(lambda z: np.pi * radius(z) ** 2 * z, -r1, d + r2, **kw)[0] / volume
    i_axis = RHO * quad(lambda z: np.pi * radius(z) ** 4 / 2, -r1, d + r2, **kw)[0]
    i_perp = RHO * quad(lambda z: np.pi * radius(z) ** 4 / 4
                        + np.pi * radius(z) ** 2 * (z - zc) ** 2, -r1, d + r2, **kw)[0]
    axis = np.asarray(direction) / np.linalg.norm(direction)
    start = np.array([0.3e-3, -0.1e-3, 0.2e-3])
    mass, centre, tensor = mass_properties([start, start + d * axis], [r1, r2], RHO)
    # overlap counted once: well below the two spheres' sum
    assert mass < 0.97 * (sphere_mass(r1) + sphere_mass(r2))
    assert mass == pytest.approx(RHO * volume, rel=1e-4)
    assert np.linalg.norm(centre - (start + zc * axis)) < 1e-4 * r1
    assert axis @ tensor @ axis == pytest.approx(i_axis, rel=1e-4)
    moments = np.linalg.eigvalsh(tensor)
    assert moments[1:] == pytest.approx([i_perp, i_perp], rel=1e-4)
    # and the integral converges: a coarse grid is further off
    coarse = mass_properties([start, start + d * axis], [r1, r2], RHO, resolution=32)[0]
    assert abs(coarse / (RHO * volume) - 1.0) > 3.0 * abs(mass / (RHO * volume) - 1.0)


def test_quaternions_round_trip():
    q = random_orientations(20, rng=3)
    assert np.linalg.norm(q, axis=1) == pytest.approx(np.ones(20), rel=1e-15)
    for row in q:
        m = rotation_matrix(row)
        assert m @ m.T == pytest.approx(np.eye(3), abs=1e-14)
        assert np.linalg.det(m) == pytest.approx(1.0, rel=1e-14)
        assert quaternion_from_matrix(m) == pytest.approx(row, abs=1e-14)


# -- a free asymmetric clump ----------------------------------------------------------------

R = 1.0e-3
L_SHAPE = np.array([[0.0, 0.0, 0.0], [2.0 * R, 0.0, 0.0], [0.0, 2.6 * R, 0.0]])
L_RADII = np.array([R, R, 0.9 * R])


def l_clump(spin, *, rotate=None):
    """The L of three spheres (touching, not overlapping: exact inertia), turned by the
    rotation matrix ``rotate``, spinning at ``spin`` (rad/s, lab frame)."""
    position = L_SHAPE if rotate is None else L_SHAPE @ np.asarray(rotate).T
    model, state = make_system(position + 0.01, L_RADII, GLASS,
                               angular_velocity=np.tile(spin, (3, 1)),
                               velocity=np.tile([0.01, -0.02, 0.005], (3, 1)))
    return make_clumps(model, state, [0, 0, 0])


def test_free_clump_keeps_angular_momentum_and_energy():
    model, state = l_clump([3.0, 20.0, -5.0])
    moments = model.clump_inertia[0]
    assert len(set(np.round(moments / moments[0], 6))) == 3   # asymmetric
    start = state.clump_position[0].copy()
    sim = Simulation(model, state, time_step=1e-4, force_time_step=True)
    momentum = sim.state.clump_angular_momentum[0].copy()
    energy = sum(sim.kinetic_energy())
    drift = []
    for _ in range(50):
        sim.step(2000)   # 10^5 steps, a hundred turns or so
        drift.append(sum(sim.kinetic_energy()) / energy - 1.0)
        assert np.linalg.norm(sim.state.clump_orientation[0]) == pytest.approx(1.0, abs=1e-14)
    change = np.linalg.norm(sim.state.clump_angular_momentum[0] - momentum)
    assert change <= 1e-10 * np.linalg.norm(momentum)
    # bounded, not drifting: the splitting is symplectic
    assert np.max(np.abs(drift)) < 1e-5
    assert abs(np.mean(drift[25:]) - np.mean(drift[:25])) < 2e-6
    # the centre moves on at its velocity, the members with it, rigidly
    assert sim.state.clump_position[0] == pytest.approx(
        start + sim.state.time * np.array([0.01, -0.02, 0.005]), rel=1e-12)
    d = sim.state.position[:, None, :] - sim.state.position[None, :, :]
    d0 = L_SHAPE[:, None, :] - L_SHAPE[None, :, :]
    assert np.linalg.norm(d, axis=2) == pytest.approx(np.linalg.norm(d0, axis=2), abs=1e-15)


def test_free_clump_follows_eulers_equations():
    # I1 dw1/dt = (I2 - I3) w2 w3 and cyclic, in the body frame: solved to 1e-12
    model, state = l_clump([3.0, 20.0, -5.0])
    sim = Simulation(model, state, time_step=2e-5, force_time_step=True)
    inertia = model.clump_inertia[0]
    axes0 = rotation_matrix(sim.state.clump_orientation[0])
    w0 = axes0.T @ np.array([3.0, 20.0, -5.0])
    i1, i2, i3 = inertia

    def euler(_, w):
        return [(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2,
                (i1 - i2) * w[0] * w[1] / i3]

    times = np.linspace(0.02, 0.4, 20)
    truth = solve_ivp(euler, (0.0, times[-1]), w0, t_eval=times, rtol=1e-12,
                      atol=1e-12 * np.linalg.norm(w0)).y.T
    worst = 0.0
    for t, w in zip(times, truth):
        sim.run(until=t)
        q = sim.state.clump_orientation[0]
        body = rotation_matrix(q).T @ sim.state.angular_velocity[0]
        worst = max(worst, np.linalg.norm(body - w) / np.linalg.norm(w0))
    # second order: measured 3.2e-8
    assert worst < 1e-6
    # and it does move: the body-frame spin is far from its start
    assert np.linalg.norm(truth[-1] - w0) > 0.3 * np.linalg.norm(w0)


@pytest.mark.parametrize("axis,flips", [(0, False), (1, True), (2, False)])
def test_tennis_racket_instability_about_the_middle_axis_only(axis, flips):
    # spin about principal axis k with a 1e-3 nudge: stable about the smallest and
    # largest moments, flips over about the middle one (Dzhanibekov), growth rate
    # w sqrt((I2 - I1)(I3 - I2) / (I1 I3)) ~ 9/s here: flipped within 1 s
    model, state = l_clump([0.0, 0.0, 0.0])
    axes = rotation_matrix(state.clump_orientation[0])
    spin = 20.0 * axes[:, axis] + 0.02 * axes[:, (axis + 1) % 3]
    set_clump_motion(model, state, 0, angular_velocity=spin)
    sim = Simulation(model, state, time_step=1e-4, force_time_step=True)
    momentum = sim.state.clump_angular_momentum[0]
    lowest = 1.0
    for _ in range(20):
        sim.step(500)
        body = rotation_matrix(sim.state.clump_orientation[0]).T @ momentum
        lowest = min(lowest, body[axis] / np.linalg.norm(momentum))
    if flips:
        assert lowest < -0.9
    else:
        assert lowest > 0.999


# -- contacts, walls and bonds -------------------------------------------------------------

def incline(angle_deg, friction, shape, radii, steps, *, dt=2e-6):
    """A clump on a plane tilted by ``angle`` (gravity 9.81 down); ``shape``'s rows are
    member centres in the slope's frame (downhill, across, height above the plane). Run
    for ``steps``: (sim, downhill unit vector)."""
    theta = np.radians(angle_deg)
    normal = np.array([-np.sin(theta), 0.0, np.cos(theta)])
    g = np.array([0.0, 0.0, -9.81])
    downhill = g - (g @ normal) * normal
    downhill /= np.linalg.norm(downhill)
    material = Material(name="m", density=RHO, young_modulus=1e8, poisson_ratio=0.25,
                        restitution=0.3, friction=friction)
    frame = np.column_stack([downhill, np.cross(normal, downhill), normal])
    model, state = make_system(np.asarray(shape) @ frame.T, radii, material, gravity=g)
    model, state = make_clumps(model, state, np.zeros(len(radii), dtype=int))
    sim = Simulation(model, state, time_step=dt, force_time_step=True,
                     contact=ContactSettings(),
                     walls=[PlaneWall((0.0, 0.0, 0.0), normal, material)])
    sim.step(steps)
    return sim, downhill


TRIANGLE = np.array([[0.0, 0.0, 0.999 * R], [2.0 * R, 0.0, 0.999 * R],
                     [R, np.sqrt(3.0) * R, 0.999 * R]])


def downhill_acceleration(sim, downhill, steps):
    """Mean downhill acceleration (m/s^2) of the clump over the next ``steps``."""
    t0, v0 = sim.state.time, sim.state.clump_velocity[0] @ downhill
    sim.step(steps)
    return (sim.state.clump_velocity[0] @ downhill - v0) / (sim.state.time - t0)


@pytest.mark.parametrize("angle,friction", [(25.0, 0.4), (25.0, 0.55)])
def test_flat_clump_slides_on_an_incline_only_above_its_friction_angle(angle, friction):
    # a flat triangle cannot roll: it slides with g (sin - mu cos) when tan > mu, else
    # it stays (tan 25 deg = 0.466)
    sim, downhill = incline(angle, friction, TRIANGLE, [R, R, R], 4000)
    a = downhill_acceleration(sim, downhill, 6000)
    theta = np.radians(angle)
    if np.tan(theta) > friction:
        assert a == pytest.approx(9.81 * (np.sin(theta) - friction * np.cos(theta)),
                                  rel=1e-4)
    else:
        assert abs(a) < 0.01 * 9.81 * np.sin(theta)
        assert np.linalg.norm(sim.state.clump_velocity[0]) < 1e-4


def test_clump_rolls_down_an_incline_as_a_rigid_body():
    # three spheres on a line across the slope, centres 0.999 R above the plane: the
    # outer two (radius R) touch it, the middle one (0.6 R) touches neither it nor them.
    # Pure rolling about that line gives a = g sin / (1 + I / (M R^2)), I the moment
    # about the line; it needs mu >= tan I / (I + M R^2) = 0.10 here (mu = 0.5)
    radii = [R, 0.6 * R, R]
    shape = np.array([[0.0, -2.2 * R, 0.999 * R], [0.0, 0.0, 0.999 * R],
                      [0.0, 2.2 * R, 0.999 * R]])
    sim, downhill = incline(20.0, 0.5, shape, radii, 4000)
    m_out, m_mid = sphere_mass(R), sphere_mass(0.6 * R)
    mass = 2 * m_out + m_mid
    inertia = 0.4 * (2 * m_out * R * R + m_mid * (0.6 * R) ** 2)
    a = downhill_acceleration(sim, downhill, 6000)
    theta = np.radians(20.0)
    # (a sphere's 5/7 g sin would be 3 % lower; sliding gives 0.14 g, no friction 0.34 g)
    assert a == pytest.approx(9.81 * np.sin(theta) / (1.0 + inertia / (mass * R * R)),
                              rel=1e-3)
    # rolling: the spin about the line matches the speed, w R = v
    spin = sim.state.angular_velocity[0] @ np.cross(np.array([-np.sin(theta), 0.0,
                                                              np.cos(theta)]), downhill)
    assert abs(spin) * R == pytest.approx(sim.state.clump_velocity[0] @ downhill, rel=0.01)


def test_clump_rests_on_a_plane_without_drift():
    material = Material(name="m", density=RHO, young_modulus=1e8, poisson_ratio=0.25,
                        restitution=0.3, friction=0.5)
    position = L_SHAPE + np.array([0.0, 0.0, 1.0]) * L_RADII[:, None] * 0.9995
    model, state = make_system(position, L_RADII, material, gravity=(0.0, 0.0, -9.81),
                               damping=0.1)
    model, state = make_clumps(model, state, [0, 0, 0])
    sim = Simulation(model, state, time_step=2e-6, force_time_step=True,
                     contact=ContactSettings(),
                     walls=[PlaneWall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), material)])
    sim.step(10000)
    x0 = sim.state.clump_position[0].copy()
    q0 = sim.state.clump_orientation[0].copy()
    sim.step(10000)
    assert np.linalg.norm(sim.state.clump_position[0, :2] - x0[:2]) < 1e-12
    assert abs(sim.state.clump_position[0, 2] - x0[2]) < 1e-9
    assert np.abs(sim.state.clump_orientation[0] - q0).max() < 1e-9
    # resting: the wall carries the clump's weight
    assert sim.wall_force[0, 2] == pytest.approx(-model.clump_mass[0] * 9.81, rel=1e-6)


# -- bonds between clumps -------------------------------------------------------------------

BOND_E, BOND_NU, BOND_RADIUS = 1e8, 0.3, 0.5 * R
L0 = 2.0 * R


def bonded_clumps(*, force=(0.0, 0.0, 0.0), moment=(0.0, 0.0, 0.0), damping=0.3):
    """Clump A (a dumbbell along x, fixed) bonded to clump B (an L whose centre is off
    the bond axis) between A's member at x = -R and B's at x = +R; the external force
    acts on B's bonded member, the moment on B. Returns the Simulation."""
    position = np.array([[-3.0 * R, 0.0, 0.0], [-R, 0.0, 0.0],
                         [R, 0.0, 0.0], [3.0 * R, 0.0, 0.0], [R, 2.1 * R, 0.0]])
    radii = [R, R, R, R, 1.1 * R]
    f = np.zeros((5, 3))
    m = np.zeros((5, 3))
    f[2] = force
    m[4] = moment
    bond = BondMaterial(young_modulus=BOND_E, poisson_ratio=BOND_NU, name="b")
    model, state = make_system(position, radii, GLASS, fixed=[True, True, False, False, False],
                               external_force=f, external_moment=m, bonds=[[1, 2]],
                               bond_diameter=2.0 * BOND_RADIUS, bond_material=bond,
                               damping=damping)
    model, state = make_clumps(model, state, [0, 0, 1, 1, 1])
    return Simulation(model, state, time_step=5e-7, force_time_step=True)


def settle(sim, steps=40000):
    sim.step(steps)
    # at rest: the damped oscillations died out
    assert np.linalg.norm(sim.state.clump_velocity[1]) < 1e-7
    return sim


def test_bonded_clumps_in_tension_stretch_by_f_l_over_e_a():
    force = 2.0   # N
    sim = settle(bonded_clumps(force=(force, 0.0, 0.0)))
    area = np.pi * BOND_RADIUS ** 2
    stretch = sim.state.position[2, 0] - sim.state.position[1, 0] - L0
    assert stretch == pytest.approx(force * L0 / (BOND_E * area), rel=1e-4)
    # the fixed clump did not move, B did not turn (the force acts on the bond's axis)
    assert sim.state.position[1] == pytest.approx([-R, 0.0, 0.0], abs=1e-18)
    assert np.abs(sim.state.clump_angular_momentum[1]).max() < 1e-14


def angle_about(sim, start_q, axis):
    """B's rotation (rad) about ``axis`` since orientation ``start_q``."""
    turn = rotation_matrix(sim.state.clump_orientation[1]) @ rotation_matrix(start_q).T
    vector = 0.5 * np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0],
                             turn[1, 0] - turn[0, 1]])
    return vector @ np.asarray(axis)


def test_bonded_clumps_twist_by_t_l_over_g_j():
    torque = 2e-5   # N m about the bond axis, on B's off-axis member
    sim = bonded_clumps(moment=(torque, 0.0, 0.0))
    q0 = sim.state.clump_orientation[1].copy()
    settle(sim)
    shear = BOND_E / (2.0 * (1.0 + BOND_NU))
    polar = np.pi * BOND_RADIUS ** 4 / 2.0
    assert angle_about(sim, q0, (1, 0, 0)) == pytest.approx(torque * L0 / (shear * polar),
                                                            rel=2e-4)
    # B turned about the bond's axis, not about its own centre (which is off the axis):
    # the bonded member stayed, up to the twist's second order
    off_axis = np.linalg.norm(sim.state.clump_position[1, 1:])
    assert off_axis > 0.3 * R
    moved = np.linalg.norm(sim.state.position[2] - [R, 0.0, 0.0])
    assert moved < 0.01 * angle_about(sim, q0, (1, 0, 0)) * off_axis


def test_bonded_clumps_bend_by_m_l_over_e_i_about_the_bond_centre():
    torque = 2e-5   # N m about z
    sim = bonded_clumps(moment=(0.0, 0.0, torque))
    q0 = sim.state.clump_orientation[1].copy()
    settle(sim)
    inertia = np.pi * BOND_RADIUS ** 4 / 4.0
    theta = torque * L0 / (BOND_E * inertia)
    assert angle_about(sim, q0, (0, 0, 1)) == pytest.approx(theta, rel=1e-4)
    # no shear force at rest: the bond's centre stays put, so B's bonded member (a lever
    # arm L0/2 from it) moved by theta L0 / 2 across the axis
    assert sim.state.position[2, 1] == pytest.approx(theta * L0 / 2.0, rel=1e-4)


# -- an agglomerate of clumps: generator, bit-identity, results, fragments -----------------

def agglomerate(seed=2):
    """An agglomerate of bonded L-trimers (compact packing, bonds within 0.1 r) falling
    at 2 m/s onto a plane, with gravity, contacts and damping. Returns (model, state,
    walls)."""
    from bondem.clumps import ClumpTemplate, bonds_between_clumps, pack_clumps
    from bondem.generate import Sphere
    r = 1e-4
    template = ClumpTemplate([[0, 0, 0], [1.6 * r, 0, 0], [0, 1.6 * r, 0]], [r, r, 0.8 * r],
                             name="L")
    glass = Material(name="glass", density=RHO, young_modulus=5e8, poisson_ratio=0.25,
                     restitution=0.5, friction=0.4)
    binder = BondMaterial(name="binder", young_modulus=5e8, poisson_ratio=0.25,
                          normal_strength=5e6, tangential_strength=5e6)
    packed = pack_clumps(Sphere(center=(0.0, 0.0, 0.62e-3), radius=0.6e-3), template, RHO,
                         solids_fraction=0.4, seed=seed, compact=0.6)
    bonds, diameter = bonds_between_clumps(packed["position"], packed["radius"],
                                           packed["clump_of"], 0.1 * r, diameter_ratio=0.5)
    n = packed["radius"].size
    model, state = make_system(packed["position"], packed["radius"], glass,
                               velocity=np.tile([0.3, 0.0, -2.0], (n, 1)), bonds=bonds,
                               bond_diameter=diameter, bond_material=binder,
                               gravity=(0.0, 0.0, -9.81), damping=0.02)
    model, state = make_clumps(model, state, packed["clump_of"], mass=packed["mass"],
                               inertia=packed["inertia"], centre=packed["centre"])
    return model, state, [PlaneWall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), glass)]


def test_packed_clumps_do_not_overlap_and_bond_only_across_clumps():
    model, state, _ = agglomerate()
    assert model.n_clumps >= 20
    x, r, of = state.position, model.radius, model.clump_of
    gap = (np.linalg.norm(x[:, None] - x[None, :], axis=2) - r[:, None] - r[None, :])
    other = of[:, None] != of[None, :]
    assert gap[other].min() > -1e-3 * r.min()   # max_overlap
    ends = of[model.bond_pairs]
    assert model.n_bonds > model.n_clumps and np.all(ends[:, 0] != ends[:, 1])
    # each clump has the template's shape: its members' distances are the template's
    for c in range(3):
        members = np.flatnonzero(of == c)
        d = np.linalg.norm(x[members[1]] - x[members[0]])
        assert d == pytest.approx(1.6e-4, rel=1e-12)
    # the masses are the template's union: its spheres less the two lenses where the
    # corner sphere overlaps the others (pairwise only: the two lenses do not meet)
    def lens(a, b, d):
        return np.pi * (a + b - d) ** 2 * (d * d + 2 * d * b - 3 * b * b + 2 * d * a
                                           + 6 * a * b - 3 * a * a) / (12 * d)

    r = 1e-4
    union = (2 * sphere_mass(r) + sphere_mass(0.8 * r)
             - RHO * (lens(r, r, 1.6 * r) + lens(r, 0.8 * r, 1.6 * r)))
    assert model.clump_mass == pytest.approx(np.full(model.n_clumps, union), rel=1e-4)


RUN_AGGLOMERATE = """
import sys
sys.path.insert(0, {tests!r})
import numpy as np
from bondem.backends import cpu
from bondem.contacts import ContactSettings
from bondem import Simulation
from test_clumps import agglomerate
cpu.SERIAL_BELOW = 0   # the parallel loops even for this small system
model, state, walls = agglomerate()
sim = Simulation(model, state, contact=ContactSettings(), walls=walls, time_step=1e-7)
sim.step(1500)
np.savez({out!r}, **{{k.replace('/', '_'): v for k, v in sim.state.arrays().items()}})
"""


def test_clumps_same_bits_with_one_and_two_threads(tmp_path):
    import os
    import pathlib
    import subprocess
    import sys
    tests = str(pathlib.Path(__file__).parent)
    results = []
    for threads in (1, 2):
        out = str(tmp_path / f"run{threads}.npz")
        env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
        subprocess.run([sys.executable, "-c", RUN_AGGLOMERATE.format(tests=tests, out=out)],
                       env=env, check=True, timeout=600)
        results.append(np.load(out))
    one, two = results
    assert one.files == two.files and "clump_orientation" in one.files
    assert np.any(~one["bond_active"]), "the impact must break bonds"
    for name in one.files:
        np.testing.assert_array_equal(one[name], two[name], err_msg=name, strict=True)


def test_clumps_resume_from_a_checkpoint_bit_identical(tmp_path):
    from bondem.io.checkpoint import read_checkpoint, write_checkpoint
    runs = []
    for split in (False, True):
        model, state, walls = agglomerate()
        sim = Simulation(model, state, contact=ContactSettings(), walls=walls,
                         time_step=1e-7)
        sim.step(600)
        if split:
            write_checkpoint(tmp_path / "c.npz", sim.state, frames=0)
            state = read_checkpoint(tmp_path / "c.npz")[0]
            sim = Simulation(model, state, contact=ContactSettings(), walls=walls,
                             time_step=1e-7)
        sim.step(600)
        runs.append(sim.state.arrays())
    assert runs[0].keys() == runs[1].keys()
    for name, value in runs[0].items():
        np.testing.assert_array_equal(value, runs[1][name], err_msg=name, strict=True)


def test_clump_results_paraview_and_fragments(tmp_path):
    from bondem.analysis.fragments import fragment_labels, fragment_sizes
    from bondem.analysis.results import Results
    from bondem.io.results import ResultsWriter
    from bondem.io.vtk import export_vtk
    model, state, walls = agglomerate()
    sim = Simulation(model, state, contact=ContactSettings(), walls=walls, time_step=1e-7)
    with ResultsWriter(tmp_path / "r.h5", sim) as writer:
        writer.append(sim)
        sim.run(until=4e-4)
        writer.append(sim)
    with Results(tmp_path / "r.h5") as results:
        clump_of = results.clump_of
        assert np.array_equal(clump_of, model.clump_of)
        assert np.array_equal(results.file["clumps/orientation"][1],
                              sim.state.clump_orientation)
        active = results.active(-1)
    assert np.any(~active)
    count, labels = fragment_labels(model.bond_pairs, active, model.n_particles, model.mass,
                                    clump_of)
    # no clump is split between fragments, and grains are counted once
    for c in range(model.n_clumps):
        assert np.unique(labels[clump_of == c]).size == 1
    counts, masses = fragment_sizes(labels, model.mass, clump_of)
    assert counts.sum() == model.n_clumps
    assert masses.sum() == pytest.approx(model.clump_mass.sum(), rel=1e-12)
    # without the clumps every member with no intact bond would be a fragment of its own
    plain = fragment_labels(model.bond_pairs, active, model.n_particles, model.mass)[0]
    assert plain > count
    pvd = export_vtk(tmp_path / "r.h5")
    text = (pvd.parent / "particles_000001.vtp").read_text(errors="replace")
    assert 'Name="clump"' in text


# -- input errors ---------------------------------------------------------------------------

def test_clump_input_errors_name_the_clump():
    position = L_SHAPE
    bond = BondMaterial(young_modulus=1e8, poisson_ratio=0.3, name="b")
    model, state = make_system(position, L_RADII, GLASS, bonds=[[0, 1]], bond_diameter=1e-4,
                               bond_material=bond)
    with pytest.raises(ValueError, match="bond 0 joins particles \\[0, 1\\] of the same clump"):
        make_clumps(model, state, [0, 0, 0])
    model, state = make_system(position, L_RADII, GLASS)
    with pytest.raises(ValueError, match="clump 1 has 1 member"):
        make_clumps(model, state, [0, 0, 1])
    model, state = make_system(position, L_RADII, GLASS, fixed=[True, False, False])
    with pytest.raises(ValueError, match="clump 0: some of its members are fixed"):
        make_clumps(model, state, [0, 0, 0])
    with pytest.raises(ValueError, match="resolution"):
        mass_properties([[0, 0, 0], [R, 0, 0]], [R, R], RHO, resolution=4)


# -- scenes ----------------------------------------------------------------------------------

EXAMPLE = __import__("pathlib").Path(__file__).resolve().parents[1] / "examples" / \
    "clump_agglomerate.toml"


def test_example_clump_agglomerate_runs_and_breaks_into_clump_fragments(tmp_path):
    from click.testing import CliRunner
    from bondem.analysis.fragments import frame_fragments
    from bondem.analysis.results import Results
    from bondem.cli import main
    from bondem.scene import load_scene
    scene = load_scene(EXAMPLE)
    model = scene.model
    assert model.n_clumps >= 30 and model.n_bonds > model.n_clumps
    # the template's union at the material's density (the lens volumes, as above)
    assert model.clump_mass[0] == pytest.approx(model.clump_mass.mean(), rel=1e-14)
    # the generator's velocity reaches the clumps
    assert scene.state.clump_velocity == pytest.approx(
        np.tile([0.0, 0.0, -2.0], (model.n_clumps, 1)), rel=1e-14)
    result = CliRunner().invoke(main, ["run", str(EXAMPLE), "--out", str(tmp_path),
                                       "--no-progress", "--set", "simulation.end_time=1e-4"])
    assert result.exit_code == 0, result.output
    with Results(tmp_path / "results.h5") as results:
        data = frame_fragments(results)
        assert results.file["clumps/position"].shape == (results.n_frames, model.n_clumps, 3)
    # it broke, into pieces made of whole clumps
    assert np.any(~results_active(tmp_path / "results.h5"))
    assert 1 < data["counts"].size and data["counts"].sum() == model.n_clumps


def results_active(path):
    from bondem.analysis.results import Results
    with Results(path) as results:
        return results.active(-1)


PARTICLES_WITH_CLUMPS = """x,y,z,radius,material,clump
0.0,0.0,0.0,1e-3,glass,0
2e-3,0.0,0.0,1e-3,glass,0
4.1e-3,0.0,0.0,1e-3,glass,1
6.1e-3,0.0,0.0,1e-3,glass,1
0.0,3e-3,0.0,1e-3,glass,-1
"""


def clump_csv_scene(folder, particles=PARTICLES_WITH_CLUMPS):
    from scenetools import SCENE
    text = SCENE.format(end_time=1e-4, save_every=1e-5, strength=1e9)
    text = text.replace('file = "bonds.csv"', 'max_gap = 2e-4\ndiameter_ratio = 0.5\n'
                        'material = "binder"')
    (folder / "scene.toml").write_text(text)
    (folder / "particles.csv").write_text(particles)
    return folder / "scene.toml"


def test_scene_particle_file_clump_column(tmp_path):
    from bondem.scene import load_scene
    scene = load_scene(clump_csv_scene(tmp_path))
    model = scene.model
    assert model.n_clumps == 2
    assert model.clump_of.tolist() == [0, 0, 1, 1, -1]
    # the generated bonds join the two clumps (gap 1e-4), none within one
    assert model.bond_pairs.tolist() == [[1, 2]]
    assert model.clump_mass == pytest.approx([2 * sphere_mass(1e-3)] * 2, rel=1e-14)


@pytest.mark.parametrize("particles,key,message", [
    (PARTICLES_WITH_CLUMPS.replace("glass,-1", "glass,2"), "particles.file.clump",
     "particles.csv line 6: clump 2 has one particle"),
    (PARTICLES_WITH_CLUMPS.replace("glass,-1", "glass,x"), "particles.file",
     "line 6: 'x'; allowed: a clump index >= 0, or -1"),
    (PARTICLES_WITH_CLUMPS.replace("glass,1\n6", "glass,3\n6"), "particles.file.clump",
     "clump 2 has no particle"),
])
def test_scene_clump_errors_name_file_line_and_key(tmp_path, particles, key, message):
    from bondem.errors import InputError
    from bondem.scene import load_scene
    with pytest.raises(InputError) as error:
        load_scene(clump_csv_scene(tmp_path, particles))
    assert message in str(error.value)
    assert error.value.key == key


def test_scene_clump_generator_errors(tmp_path):
    from bondem.errors import InputError
    from bondem.scene import load_scene
    text = EXAMPLE.read_text()
    for edit, key in (("compact = 0.6", "compact = 0.3"),
                      ("solids_fraction = 0.4", "particle_radius = 1e-4"),
                      ("radii = [1e-4, 1e-4, 0.8e-4]", "radii = [1e-4, -1e-4, 0.8e-4]")):
        (tmp_path / "s.toml").write_text(text.replace(edit, key))
        with pytest.raises(InputError) as error:
            load_scene(tmp_path / "s.toml")
        assert error.value.key.startswith("particles.generator"), (key, error.value)


def test_reordered_clumps_run_the_same():
    # renumbering the particles (the bench's Morton order) carries the clump arrays
    from bondem.reorder import reorder_system
    model, state, walls = agglomerate()
    order = np.random.default_rng(4).permutation(model.n_particles)
    runs = []
    for m, s in ((model, state.copy()), reorder_system(model, state.copy(), order)):
        sim = Simulation(m, s, contact=ContactSettings(), walls=walls, time_step=1e-7)
        sim.step(300)
        runs.append(sim.state)
    np.testing.assert_allclose(runs[1].clump_position, runs[0].clump_position, rtol=0,
                               atol=1e-15)
    np.testing.assert_allclose(runs[1].position, runs[0].position[order], rtol=0, atol=1e-15)


# -- MUSEN's multispheres ---------------------------------------------------------------------

def test_clumps_travel_through_musen_as_multispheres(tmp_path):
    """examples/clump_agglomerate.toml run for 2 us, exported with ``bondem export musen``
    (clumps as .mdem multispheres) and run by the real cmusen 1.74.2
    (tests/data/musen_mdem/clumps/agg_script.txt): MUSEN read the multispheres and wrote
    them back into its result, whose import gives the scene's clumps and bonds again."""
    from bondem.io.musen_mdem import import_mdem
    from bondem.scene import load_scene
    data = __import__("pathlib").Path(__file__).parent / "data" / "musen_mdem" / "clumps"
    path, notes = import_mdem(data / "agg_result.mdem", tmp_path)
    assert any("36 multisphere(s) imported as rigid clumps" in n for n in notes)
    imported = load_scene(path).model
    original = load_scene(EXAMPLE).model
    assert np.array_equal(imported.clump_of, original.clump_of)
    assert imported.n_bonds == original.n_bonds
    # MUSEN's run moved the spheres as free particles (it never calls MoveMultispheres),
    # so the clumps' shapes come back from its result up to 2 us of free motion: their
    # mass properties match the generator's to the integral's accuracy
    assert imported.clump_mass == pytest.approx(original.clump_mass, rel=1e-3)


def test_export_musen_writes_the_clumps_as_multispheres(tmp_path):
    from click.testing import CliRunner
    from bondem.cli import main
    from bondem.io.musen_mdem import MdemFile
    runner = CliRunner()
    result = runner.invoke(main, ["run", str(EXAMPLE), "--out", str(tmp_path), "--no-progress",
                                  "--set", "simulation.end_time=5e-7",
                                  "--set", "simulation.save_every=5e-7"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(main, ["export", "musen", str(tmp_path / "results.h5"), "--out",
                                  str(tmp_path / "agg.mdem")])
    assert result.exit_code == 0, result.output
    assert "36 clumps written as multispheres" in result.output
    mdem = MdemFile(tmp_path / "agg.mdem")
    mdem.check()
    groups = [m["id"] for m in mdem.info["multispheres"]]
    from bondem.scene import load_scene
    clump_of = load_scene(EXAMPLE).model.clump_of
    assert groups == [np.flatnonzero(clump_of == c).tolist() for c in range(36)]


# -- clump templates from a mesh -------------------------------------------------------------

def ellipsoid_mesh():
    import trimesh
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    mesh.apply_scale([1e-3, 0.6e-3, 0.4e-3])
    return mesh


def test_mesh_filled_with_spheres_inside_it_with_the_stated_quality():
    from bondem.clumps import ClumpTemplate
    from bondem.generate import MeshVolume
    mesh = ellipsoid_mesh()
    volume = MeshVolume(mesh)
    coarse = ClumpTemplate.from_mesh(mesh, 4, resolution=24)
    fine = ClumpTemplate.from_mesh(mesh, 12, resolution=24)
    assert fine.quality["spheres"] == 12
    # every sphere lies inside: its centre is at least its radius from the surface
    depth = volume.signed_distance(fine.centres)
    assert np.all(depth >= fine.radii * (1.0 - 1e-12))
    # the volume fraction, checked by sampling: points inside the union over inside the mesh
    rng = np.random.default_rng(1)
    low, high = volume.bounds()
    points = rng.uniform(low, high, (40000, 3))
    in_mesh = volume.signed_distance(points) > 0.0
    in_union = np.any(np.linalg.norm(points[:, None] - fine.centres[None], axis=2)
                      <= fine.radii[None], axis=1)
    sampled = np.count_nonzero(in_union) / np.count_nonzero(in_mesh)
    assert fine.quality["volume_fraction"] == pytest.approx(sampled, abs=0.02)
    # more spheres fill more of it, and spread the mass more like the shape
    assert 0.4 < coarse.quality["volume_fraction"] < fine.quality["volume_fraction"] < 1.0
    assert fine.quality["gyration_error"] < coarse.quality["gyration_error"] < 0.5
    # the ellipsoid's long axis is the clump's: its smallest moment lies along x
    moments, axes = principal_frame(fine.properties(RHO)[2])
    assert abs(axes[0, 0]) > 0.99


def test_scene_clump_generator_from_an_stl(tmp_path):
    from bondem.scene import load_scene
    ellipsoid_mesh().export(tmp_path / "grain.stl")
    text = EXAMPLE.read_text()
    start = text.index("clump = {")
    line = text[start:text.index("\n", start)]
    text = text.replace(line, 'clump = { file = "grain.stl", spheres = 6, resolution = 16, '
                        'scale = 0.2 }')
    (tmp_path / "s.toml").write_text(text)
    scene = load_scene(tmp_path / "s.toml")
    model = scene.model
    assert model.n_clumps >= 5
    sizes = np.bincount(model.clump_of[model.clump_of >= 0])
    assert np.all(sizes == 6)
    # scale 0.2: the grains are 0.4 mm long at most
    for c in range(3):
        x = scene.state.position[model.clump_of == c]
        r = model.radius[model.clump_of == c]
        extent = np.max(np.linalg.norm(x[:, None] - x[None], axis=2) + r[:, None] + r[None])
        assert extent <= 0.4e-3 * (1 + 1e-9)
    (tmp_path / "s.toml").write_text(text.replace("grain.stl", "missing.stl"))
    from bondem.errors import InputError
    with pytest.raises(InputError) as error:
        load_scene(tmp_path / "s.toml")
    assert error.value.key == "particles.generator.clump.file"


def test_generate_writes_the_clump_generators_members_with_their_clumps(tmp_path):
    """``bondem generate --from-scene`` of the clump generator: particles.csv with a clump
    column and bonds.csv across clumps, which a scene reads back into the same clumps."""
    from click.testing import CliRunner
    from bondem.cli import main
    from bondem.io.csv_files import read_bonds, read_particles
    from bondem.scene import load_scene
    result = CliRunner().invoke(main, ["generate", "--from-scene", str(EXAMPLE), "--out",
                                       str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "clumps: 36 of 3 spheres" in result.output
    particles = read_particles(tmp_path / "particles.csv")
    bonds = read_bonds(tmp_path / "bonds.csv")
    original = load_scene(EXAMPLE)
    assert np.array_equal(particles["clump"], original.model.clump_of)
    assert np.array_equal(np.column_stack([bonds["i"], bonds["j"]]),
                          original.model.bond_pairs)
    text = EXAMPLE.read_text()
    start = text.index("[particles.generator]")
    end = text.index("[bonds]")
    text = (text[:start] + 'file = "particles.csv"\n\n' + text[end:]).replace(
        "max_gap = 1e-5\ndiameter_ratio = 0.5\nmaterial = \"binder\"", 'file = "bonds.csv"')
    (tmp_path / "s.toml").write_text(text)
    again = load_scene(tmp_path / "s.toml")
    assert np.array_equal(again.model.clump_of, original.model.clump_of)
    assert again.model.clump_mass == pytest.approx(original.model.clump_mass, rel=1e-4)


def test_info_counts_the_clumps():
    from click.testing import CliRunner
    from bondem.cli import main
    result = CliRunner().invoke(main, ["info", str(EXAMPLE)])
    assert result.exit_code == 0, result.output
    assert "clumps:          36 (rigid grains of 108 of the particles)" in result.output

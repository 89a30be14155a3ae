"""Walls: a sphere pressed on a mesh of many small triangles feels the force of a plane,
wherever it sits (face, edge, shared vertex): Hertz F = 4/3 E* sqrt(R) delta^(3/2) once,
not once per triangle. A moving plane does work 1/2 m (2V)^2 on a resting sphere it hits
elastically (infinite-mass wall). A spinning mesh gives a falling sphere the sliding
friction impulse; a rolling torque decelerates a rolling sphere at 5/7 mu_r g.
"""
import math

import numpy as np
import pytest

import bondem
from bondem.contacts import ContactSettings
from bondem.walls import MeshWall, PlaneWall
from contacttools import collide, effective_modulus, flat_mesh

RADIUS = 1e-3


@pytest.fixture
def glass_e1():
    return bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                           restitution=1.0, friction=0.3)


@pytest.mark.parametrize("x, y", [(0.0, 0.0), (0.25e-3, 0.0), (0.25e-3, 0.25e-3),
                                  (0.1e-3, 0.3e-3), (0.123e-3, 0.377e-3)])
@pytest.mark.parametrize("wall_kind", ["plane", "mesh"])
def test_pressed_sphere_feels_one_hertz_force(glass_e1, wall_kind, x, y):
    delta = 2e-5
    if wall_kind == "plane":
        wall = PlaneWall((0, 0, 0), (0, 0, 1), glass_e1)
    else:
        wall = flat_mesh(4e-3, 16, glass_e1)  # triangles of 0.5 mm legs, radius 1 mm
    model, state = bondem.make_system([[x, y, RADIUS - delta]], RADIUS, glass_e1, fixed=True)
    sim = bondem.Simulation(model, state, contact=ContactSettings(), walls=[wall])
    sim.step(1)
    hertz = 4 / 3 * effective_modulus(glass_e1) * math.sqrt(RADIUS) * delta ** 1.5
    assert sim.contacts.touching()[1] == 1
    assert sim.wall_force[0] == pytest.approx([0.0, 0.0, -hertz], rel=1e-9, abs=1e-12 * hertz)
    # Torque about the reference point (the origin) of a vertical force at (x, y, 0).
    assert sim.wall_torque[0] == pytest.approx([-y * hertz, x * hertz, 0.0], rel=1e-9,
                                               abs=1e-12 * hertz * RADIUS)


def test_moving_plane_work(glass_e1):
    speed = 0.2
    model, state = bondem.make_system([[0.0, 0.0, RADIUS + 1e-6]], RADIUS, glass_e1)
    wall = PlaneWall((0, 0, 0), (0, 0, 1), glass_e1, velocity=(0, 0, speed))
    sim, steps = collide(model, state, walls=[wall])
    assert state.velocity[0, 2] == pytest.approx(2 * speed, rel=0.01)
    terms = sim.energy_terms()
    gained = 0.5 * model.mass[0] * (2 * speed) ** 2
    assert terms["work_walls"] == pytest.approx(gained, rel=0.01)
    assert terms["dissipated_contacts"] == pytest.approx(0.0, abs=1e-6 * gained)
    assert terms["kinetic_translational"] + terms["dissipated_contacts"] == pytest.approx(
        terms["work_walls"], rel=1e-6)
    assert sim.wall_positions()[0] == pytest.approx([0, 0, speed * state.time])


def test_rotating_mesh_friction_impulse():
    """A sphere falls (V_n) on a flat mesh spinning about z; at radius rho the surface
    moves at w rho along +y, fast enough for gross sliding, so the sphere leaves with
    v_y = mu (1 + e) V_n (rigid-body theory, see test_contacts_oblique), 3 %."""
    omega, rho, v_n, mu, e = 100.0, 20e-3, 0.2, 0.3, 0.9
    rough = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                            restitution=e, friction=mu)
    mesh = flat_mesh(30e-3, 8, rough)
    wall = MeshWall(mesh.vertices, mesh.triangles, rough, angular_velocity=(0, 0, omega))
    model, state = bondem.make_system([[rho, 0.0, RADIUS + 1e-7]], RADIUS, rough,
                                      velocity=[[0, 0, -v_n]])
    sim, _ = collide(model, state, walls=[wall])
    assert state.velocity[0, 2] == pytest.approx(e * v_n, rel=0.01)
    assert state.velocity[0, 1] == pytest.approx(mu * (1 + e) * v_n, rel=0.03)
    assert abs(state.velocity[0, 0]) < 0.05 * state.velocity[0, 1]
    assert sim.energy_terms()["work_walls"] > 0.0


def test_mesh_from_stl_matches_arrays(tmp_path, glass_e1):
    """An STL written by trimesh loads back (scaled mm -> m) and presses like a plane."""
    import trimesh
    mesh = flat_mesh(4.0, 8, glass_e1)  # in mm
    path = tmp_path / "floor.stl"
    trimesh.Trimesh(mesh.vertices, mesh.triangles).export(path)
    wall = MeshWall.from_stl(path, glass_e1, scale=1e-3)
    assert wall.triangles.shape == (128, 3)
    assert np.allclose(wall.vertices.min(0), [-4e-3, -4e-3, 0.0])
    delta = 1e-5
    model, state = bondem.make_system([[0.0, 0.0, RADIUS - delta]], RADIUS, glass_e1, fixed=True)
    sim = bondem.Simulation(model, state, contact=ContactSettings(), walls=[wall])
    sim.step(1)
    hertz = 4 / 3 * effective_modulus(glass_e1) * math.sqrt(RADIUS) * delta ** 1.5
    assert sim.wall_force[0, 2] == pytest.approx(-hertz, rel=1e-9)
    with pytest.raises(ValueError, match="cannot read"):
        MeshWall.from_stl(tmp_path / "missing.stl", glass_e1)


def test_rolling_resistance_decelerates_at_five_sevenths_mu_r_g():
    """A sphere rolling on a plane under gravity with a constant rolling torque
    mu_r R m g: rolling without slipping gives a = -(5/7) mu_r g (I = 2/5 m R^2). 2 %."""
    mu_r, v0, g = 0.1, 0.05, 9.81
    material = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                               restitution=0.3, friction=0.8, rolling_friction=mu_r)
    mass = 2500.0 * 4 / 3 * math.pi * RADIUS ** 3
    e_star = effective_modulus(material)
    resting = (3 * mass * g / (4 * e_star * math.sqrt(RADIUS))) ** (2 / 3)
    model, state = bondem.make_system([[0.0, 0.0, RADIUS - resting]], RADIUS, material,
                                      velocity=[[v0, 0, 0]], angular_velocity=[[0, v0 / RADIUS, 0]],
                                      gravity=(0, 0, -g))
    sim = bondem.Simulation(model, state, contact=ContactSettings(),
                            walls=[PlaneWall((0, 0, 0), (0, 0, 1), material)])
    duration = 5e-3
    sim.run(until=duration)
    expected = v0 - 5 / 7 * mu_r * g * state.time
    assert state.velocity[0, 0] - v0 == pytest.approx(expected - v0, rel=0.02)
    assert state.angular_velocity[0, 1] * RADIUS == pytest.approx(state.velocity[0, 0], rel=0.02)
    without = bondem.make_system([[0.0, 0.0, RADIUS - resting]], RADIUS, material,
                                 velocity=[[v0, 0, 0]], angular_velocity=[[0, v0 / RADIUS, 0]],
                                 gravity=(0, 0, -g))
    free = bondem.Simulation(*without, contact=ContactSettings(rolling_resistance=False),
                             walls=[PlaneWall((0, 0, 0), (0, 0, 1), material)])
    free.run(until=duration)
    assert free.state.velocity[0, 0] == pytest.approx(v0, rel=1e-3)


def test_rolling_torque_does_not_chatter_at_rest():
    """A sphere resting on a plane, nudged to a tiny spin, is stopped by the rolling torque
    and stays stopped: the torque is capped at what stops the relative rolling in one step
    (an uncapped constant torque would flip it by mu_r R m g dt / I ~ 0.01 rad/s each step)."""
    g = 9.81
    material = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                               restitution=0.3, friction=0.8, rolling_friction=0.1)
    mass = 2500.0 * 4 / 3 * math.pi * RADIUS ** 3
    resting = (3 * mass * g / (4 * effective_modulus(material) * math.sqrt(RADIUS))) ** (2 / 3)
    model, state = bondem.make_system([[0.0, 0.0, RADIUS - resting]], RADIUS, material,
                                      angular_velocity=[[0.0, 1e-3, 0.0]], gravity=(0, 0, -g))
    sim = bondem.Simulation(model, state, contact=ContactSettings(),
                            walls=[PlaneWall((0, 0, 0), (0, 0, 1), material)])
    sim.step(200)
    assert np.abs(state.angular_velocity).max() < 1e-6
    assert np.abs(state.velocity[0, :2]).max() < 1e-8


def test_tangential_force_carries_across_triangles(glass_e1):
    """A pressed sphere dragged slowly (prescribed velocity, sticking: the spring needs
    ~18 steps to reach the Coulomb limit) across the vertex shared by six triangles feels at
    every step the same wall force as on a plane: the tangential spring passes from
    triangle to triangle (no reset at edges), 1e-9."""
    delta, velocity = 2e-5, (0.05, 0.02, 0.0)
    start = [0.5e-3 - 2e-7, 0.5e-3 - 1e-7, RADIUS - delta]  # just before the vertex
    histories, elements = [], set()
    for wall in (PlaneWall((0, 0, 0), (0, 0, 1), glass_e1), flat_mesh(4e-3, 16, glass_e1)):
        model, state = bondem.make_system([start], RADIUS, glass_e1, fixed=True,
                                          velocity=[velocity])
        sim = bondem.Simulation(model, state, contact=ContactSettings(), walls=[wall])
        forces = []
        for _ in range(12):
            sim.step(1)
            forces.append(sim.wall_force[0].copy())
            active = np.any(state.extra["wall_force_rows"] != 0.0, axis=1)
            elements.update(state.extra["wall_pairs"][active, 1].tolist())
        histories.append(np.array(forces))
    plane, mesh = histories
    assert len(elements) >= 3  # the plane, and at least two triangles in turn
    assert np.abs(plane[-1, 0]) > 0.3 * np.abs(plane[:, 0]).max() > 0.0
    assert np.allclose(mesh, plane, rtol=1e-9, atol=1e-9 * np.abs(plane).max())


def test_pressed_sphere_near_edges_and_vertices(glass_e1):
    """As above at 40 spots: random, and 1e-8 m to 1e-12 m beside edges, diagonals and
    vertices (where a distance tolerance would count two triangles): one Hertz force."""
    rng = np.random.default_rng(11)
    spots = list(rng.uniform(-1e-3, 1e-3, (20, 2)))
    for offset in (1e-8, 1e-10, 1e-12, 0.0):
        spots += [(0.5e-3 + offset, 0.2e-3), (0.3e-3 + offset, 0.3e-3),  # edge, diagonal
                  (0.5e-3 + offset, 0.5e-3 - offset), (-offset, 0.5e-3 + offset),
                  (1e-3 - offset, 0.75e-3)]
    delta = 2e-5
    hertz = 4 / 3 * effective_modulus(glass_e1) * math.sqrt(RADIUS) * delta ** 1.5
    mesh = flat_mesh(4e-3, 16, glass_e1)
    for x, y in spots:
        model, state = bondem.make_system([[x, y, RADIUS - delta]], RADIUS, glass_e1,
                                          fixed=True)
        sim = bondem.Simulation(model, state, contact=ContactSettings(), walls=[mesh])
        sim.step(1)
        assert sim.wall_force[0, 2] == pytest.approx(-hertz, rel=1e-9), (x, y)


def _resting_overlap(g):
    """Hertz overlap (m) of a grain (2500 kg/m^3, E 1e8 Pa, nu 0.3) of RADIUS resting
    under gravity g (m/s^2) on a plate (E 2e8 Pa, nu 0.25): m g = 4/3 E* sqrt(R) d^1.5."""
    mass = 2500.0 * 4 / 3 * math.pi * RADIUS ** 3
    e_star = 1 / ((1 - 0.09) / 1e8 + (1 - 0.0625) / 2e8)
    return (3 * mass * g / (4 * e_star * math.sqrt(RADIUS))) ** (2 / 3)


@pytest.mark.parametrize("own, mu", [(False, 0.5 * (0.6 + 0.2)), (True, 0.2)])
@pytest.mark.parametrize("wall_kind", ["plane", "mesh"])
def test_a_sliding_sphere_decelerates_at_the_walls_own_friction(wall_kind, own, mu):
    """A sphere sliding (not spinning) on a horizontal wall under gravity decelerates at
    mu g while it slides, mu the mean of the sphere's (0.6) and the wall's (0.2) friction,
    or the wall's own with own_friction; friction spins it up at 5 mu g / (2 R), and it
    slides until v = w R (2 %)."""
    v0, g = 0.05, 9.81
    grain = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                            restitution=0.3, friction=0.6)
    plate = bondem.Material(density=7800.0, young_modulus=2e8, poisson_ratio=0.25,
                            restitution=0.3, friction=0.2)
    resting = _resting_overlap(g)
    model, state = bondem.make_system([[0.0, 0.0, RADIUS - resting]], RADIUS, grain,
                                      velocity=[[v0, 0, 0]], gravity=(0, 0, -g))
    wall = (PlaneWall((0, 0, 0), (0, 0, 1), plate, own_friction=own) if wall_kind == "plane"
            else MeshWall(np.array([[-0.1, -0.1, 0], [0.1, -0.1, 0], [0.1, 0.1, 0],
                                    [-0.1, 0.1, 0]]), np.array([[0, 1, 2], [0, 2, 3]]),
                          plate, own_friction=own))
    sim = bondem.Simulation(model, state, contact=ContactSettings(rolling_resistance=False),
                            walls=[wall])
    duration = 0.2 * v0 / (mu * g)     # well before rolling sets in at t = 2 v0 / (7 mu g)
    sim.run(until=duration)
    assert state.velocity[0, 0] - v0 == pytest.approx(-mu * g * state.time, rel=0.02)
    assert state.angular_velocity[0, 1] == pytest.approx(
        2.5 * mu * g * state.time / RADIUS, rel=0.02)


@pytest.mark.parametrize("own, mu", [(None, 0.5 * (0.6 + 0.2)), (True, 0.2)])
def test_a_scene_files_wall_takes_its_own_friction(tmp_path, own, mu):
    """The sliding sphere above from a scene file: ``own_friction = true`` on a [[walls]]
    entry gives the wall's own friction (0.2), left out the mean (0.4); the sphere
    decelerates at mu g while it slides."""
    from bondem.scene import load_scene
    v0, g = 0.05, 9.81
    resting = _resting_overlap(g)
    (tmp_path / "p.csv").write_text("x,y,z,radius,material,vx,vy,vz\n"
                                    f"0,0,{RADIUS - resting!r},{RADIUS!r},grain,{v0},0,0\n")
    wall = ('[[walls]]\ntype = "plane"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n'
            'material = "plate"\n' + ("own_friction = true\n" if own else ""))
    duration = 0.2 * v0 / (mu * g)     # well before rolling sets in at t = 2 v0 / (7 mu g)
    (tmp_path / "s.toml").write_text(f"""[simulation]
end_time = {duration!r}
gravity = [0.0, 0.0, {-g!r}]
rolling_resistance = false
[materials.grain]
density = 2500.0
young_modulus = 1e8
poisson_ratio = 0.3
restitution = 0.3
friction = 0.6
[materials.plate]
density = 7800.0
young_modulus = 2e8
poisson_ratio = 0.25
restitution = 0.3
friction = 0.2
[particles]
file = "p.csv"
{wall}""")
    scene = load_scene(tmp_path / "s.toml")
    assert scene.simulation_options["walls"][0].own_friction is bool(own)
    sim = scene.make_simulation()
    sim.run(until=duration)
    assert sim.state.velocity[0, 0] - v0 == pytest.approx(-mu * g * sim.state.time, rel=0.02)


def test_own_friction_is_true_or_false(glass_e1):
    assert PlaneWall((0, 0, 0), (0, 0, 1), glass_e1).own_friction is False
    for value in ("yes", 1, None):
        with pytest.raises(ValueError) as error:
            PlaneWall((0, 0, 0), (0, 0, 1), glass_e1, own_friction=value)
        assert str(error.value) == f"own_friction = {value!r}; expected True or False"
    with pytest.raises(ValueError, match="own_friction = 0; expected True or False"):
        MeshWall(np.eye(3), np.array([[0, 1, 2]]), glass_e1, own_friction=0)

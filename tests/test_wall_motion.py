"""Wall motion beyond a constant velocity: a velocity profile's position is the exact
integral of its piecewise-linear velocity (ramp, hold, jump, reverse); a servo plane settles
a sphere's Hertz contact at the target force, whose overlap is known in closed form; the
load on each wall is recorded every step it changes, kept whole across a resume; the scene
keys parse and their bad values name the key."""
import math

import numpy as np
import pytest

import bondem
from bondem.contacts import ContactSettings
from bondem.errors import InputError
from bondem.io.results import read_results
from bondem.runner import run_scene
from bondem.scene import load_scene
from bondem.walls import PlaneWall, Servo, VelocityProfile
from contacttools import effective_modulus

RADIUS = 1e-3


@pytest.fixture
def glass():
    return bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                           restitution=0.5, friction=0.3)


def test_profile_position_is_the_integral_of_ramp_hold_jump_and_reverse():
    v = 0.3
    profile = VelocityProfile([0.0, 1.0, 3.0, 3.0, 4.0],
                              [[0, 0, 0], [0, 0, v], [0, 0, v], [0, 0, -v], [0, 0, -v]])
    # ramp: v t^2 / 2 over the first second; hold at v; the jump; reverse at -v
    assert profile.displacement(0.5)[2] == pytest.approx(v * 0.125, rel=1e-14)
    assert profile.displacement(2.0)[2] == pytest.approx(v * 0.5 + v * 1.0, rel=1e-14)
    assert profile.displacement(3.5)[2] == pytest.approx(v * 2.5 - v * 0.5, rel=1e-14)
    assert profile.displacement(10.0)[2] == pytest.approx(v * 2.5 - v * 7.0, rel=1e-14)
    assert profile.velocity(0.25)[2] == pytest.approx(0.25 * v)
    assert profile.velocity(3.0)[2] == -v and profile.velocity(2.999)[2] == v
    assert profile.max_speed() == pytest.approx(v)
    # numerically: the mean velocity over a step times the step sums to the position
    t = np.linspace(0.0, 4.5, 90001)
    mid = 0.5 * (t[1:] + t[:-1])
    speeds = np.array([profile.velocity(x)[2] for x in mid])
    assert np.sum(speeds * np.diff(t)) == pytest.approx(profile.displacement(4.5)[2],
                                                         abs=1e-6 * v)


@pytest.mark.parametrize("bad", [dict(times=[0.5, 1.0]), dict(times=[0.0, 2.0, 1.0]),
                                 dict(times=[0.0, float("nan")])])
def test_profile_refuses_bad_times(bad):
    with pytest.raises(ValueError, match="times|finite"):
        VelocityProfile(bad["times"], np.zeros((len(bad["times"]), 3)))


def test_wall_on_a_profile_moves_in_the_simulation(glass):
    profile = VelocityProfile([0.0, 1e-4, 2e-4], [[0, 0, 0], [0, 0, 1.0], [0, 0, 1.0]])
    wall = PlaneWall((0, 0, -5e-3), (0, 0, 1), glass, motion=profile)
    model, state = bondem.make_system([[0.0, 0.0, 0.0]], RADIUS, glass)
    sim = bondem.Simulation(model, state, walls=[wall], contact=ContactSettings())
    sim.run(until=3e-4)
    t = state.time
    expected = -5e-3 + 0.5 * 1e-4 + (t - 1e-4)
    assert sim.wall_positions()[0, 2] == pytest.approx(expected, rel=1e-12)


def test_servo_settles_a_hertz_contact_at_its_target_force(glass):
    """A fixed sphere under a servo plane: the plane stops where the Hertz force
    4/3 E* sqrt(R) d^1.5 equals the target, and its position gives that overlap."""
    target = 0.05     # N
    e_star = effective_modulus(glass)
    overlap = (3 * target / (4 * e_star * math.sqrt(RADIUS))) ** (2 / 3)
    stiffness = 2 * e_star * math.sqrt(RADIUS * overlap)    # dF/dd at the target (N/m)
    model, state = bondem.make_system([[0.0, 0.0, 0.0]], RADIUS, glass, fixed=True)
    probe = bondem.Simulation(model, state.copy(), contact=ContactSettings())
    dt = probe.time_step
    servo = Servo(target_force=target, gain=0.2 / (stiffness * dt), max_velocity=0.05,
                  tolerance=0.005)
    wall = PlaneWall((0, 0, RADIUS + 1e-5), (0, 0, -1), glass, motion=servo)
    sim = bondem.Simulation(model, state, contact=ContactSettings(), walls=[wall])
    sim.step(4000)
    assert servo.reached
    assert -sim.wall_force[0, 2] == pytest.approx(-target, rel=0.005) or \
        sim.wall_force[0, 2] == pytest.approx(target, rel=0.005)
    assert RADIUS - sim.wall_positions()[0, 2] == pytest.approx(overlap, rel=0.005)
    assert state.extra["wall_servo"].shape == (1, 4)
    # every step changed the force while the wall moved: one history row per step
    time, force, position = sim.wall_history.take()
    assert time.shape[0] >= 3000 and np.all(np.diff(time) > 0)
    assert force[-1, 0] == pytest.approx(sim.wall_force[0], rel=1e-3)


def test_servo_checks_its_settings():
    with pytest.raises(ValueError, match="exactly one"):
        Servo(gain=1.0, max_velocity=1.0)
    with pytest.raises(ValueError, match="area"):
        Servo(target_stress=1e5, gain=1.0, max_velocity=1.0)
    with pytest.raises(ValueError, match="gain"):
        Servo(target_force=1.0, gain=-1.0, max_velocity=1.0)


SCENE = """\
[simulation]
end_time = 2e-3
save_every = 5e-4
contact_model = "hertz_mindlin"
checkpoint_minutes = 0.0

[materials.glass]
density = 2500.0
young_modulus = 1e8

[bond_materials.binder]
young_modulus = 1e8
normal_strength = 1e9
tangential_strength = 1e9

[particles]
generator = {{ shape = "box", low = [-2e-3, -2e-3, -2e-3], high = [2e-3, 2e-3, 2e-3], particle_radius = 5e-4, solids_fraction = 0.5, seed = 3, material = "glass" }}

[bonds]
max_gap = 1e-4
diameter_ratio = 0.5
material = "binder"

[[walls]]
type = "plane"
point = [0.0, 0.0, -2.0e-3]
normal = [0.0, 0.0, 1.0]
material = "glass"

[[walls]]
type = "plane"
point = [0.0, 0.0, {top}]
normal = [0.0, 0.0, -1.0]
material = "glass"
{motion}
"""


def _scene(tmp_path, motion, top=2.2e-3):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(motion=motion, top=top))
    return path


def test_scene_wall_profile_and_history_survive_a_resume(tmp_path):
    path = _scene(tmp_path, "velocity_profile = [[0, 0, 0, 0], [5e-4, 0, 0, -0.4], "
                            "[1.5e-3, 0, 0, -0.4], [1.5e-3, 0, 0, 0.2]]")
    scene = load_scene(path)
    assert isinstance(scene.simulation_options["walls"][1].motion, VelocityProfile)
    whole = run_scene(scene, tmp_path / "whole", progress=False)
    run_scene(scene, tmp_path / "cut", progress=False, stop_after_frames=2)
    run_scene(scene, tmp_path / "cut", progress=False, resume=True)
    a, b = read_results(whole), read_results(tmp_path / "cut" / "results.h5")
    for name in ("walls/history/time", "walls/history/force", "walls/history/position",
                 "walls/position"):
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    time, force = a["walls/history/time"], a["walls/history/force"]
    assert time.shape[0] > 10 * a["time"].shape[0]          # far more rows than frames
    assert np.all(np.diff(time) > 0)
    assert np.all(np.any(np.diff(force, axis=0) != 0.0, axis=(1, 2)))   # each one a change
    top = a["walls/position"][:, 1, 2]
    t = a["time"]
    expected = 2.2e-3 - 0.4 * np.clip(t, 0, 5e-4) ** 2 / (2 * 5e-4) \
        - 0.4 * np.clip(t - 5e-4, 0, 1e-3) + 0.2 * np.clip(t - 1.5e-3, 0, None)
    np.testing.assert_allclose(top, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("motion, key", [
    ("velocity_profile = [[1e-4, 0, 0, 0]]", "walls.1.velocity_profile"),
    ("velocity_profile = [[0, 0, 0]]", "walls.1.velocity_profile"),
    ("velocity = [0, 0, 1]\nvelocity_profile = [[0, 0, 0, 1]]", "walls.1.velocity_profile"),
    ("servo = { gain = 1.0, max_velocity = 0.1 }", "walls.1.servo.target_force"),
    ("servo = { target_stress = 1e4, gain = 1.0, max_velocity = 0.1 }", "walls.1.servo.area"),
    ("servo = { target_force = 1.0, gain = -1.0, max_velocity = 0.1 }", "walls.1.servo.gain"),
    ("servo = { target_force = 1.0, gain = 1.0, max_velocity = 0.1, speed = 2 }",
     "walls.1.servo.speed"),
])
def test_bad_wall_motion_names_the_key(tmp_path, motion, key):
    with pytest.raises(InputError) as error:
        load_scene(_scene(tmp_path, motion))
    assert error.value.key == key, str(error.value)


def test_scene_servo_holds_its_force(tmp_path):
    scene = load_scene(_scene(tmp_path, "servo = { target_force = 0.2, gain = 0.5, "
                                        "max_velocity = 0.5, tolerance = 0.02 }", 2.03e-3))
    sim = scene.make_simulation()
    sim.run(until=2e-3)
    servo = sim.walls[1].motion
    history = sim.wall_history.take()
    late = history[1][history[0] > 1.5e-3, 1, 2]
    assert late.size > 100
    assert np.all(np.abs(late - 0.2) < 0.02 * 0.2), (late.min(), late.max())
    assert servo.reached


def test_each_simulation_of_a_scene_starts_with_the_scene_s_walls(tmp_path):
    """A servo's travel, speed and integral live in its wall: a second simulation made
    from the same Scene (a study retrying a run) must start with the top plane where the
    scene puts it, at rest, and follow the first run's path to the bit."""
    scene = load_scene(_scene(tmp_path, "servo = { target_force = 0.2, gain = 0.5, "
                                        "max_velocity = 0.5, integral_time = 1e-4 }",
                              2.03e-3))
    first = scene.make_simulation()
    first.run(until=5e-4)
    moved = first.walls[1].position(first.state.time)[2]
    assert abs(moved - 2.03e-3) > 1e-6 and first.walls[1].motion.integral != 0.0
    second = scene.make_simulation()
    assert second.walls[1].position(0.0)[2] == 2.03e-3
    servo = second.walls[1].motion
    assert (servo.travel, servo.speed, servo.integral, servo.held) == (0.0, 0.0, 0.0, False)
    second.run(until=5e-4)
    assert second.walls[1].position(second.state.time)[2] == moved
    np.testing.assert_array_equal(second.state.position, first.state.position)


def test_an_untaken_history_keeps_its_newest_rows():
    from bondem.walls import WallHistory
    history = WallHistory(1, max_rows=10)
    for k in range(25):
        history.record(float(k), [[float(k), 0.0, 0.0]], [[0.0, 0.0, 0.0]])
    time, force, _ = history.take()
    assert history.dropped == 15 and time.tolist() == [float(k) for k in range(15, 25)]
    assert force[-1, 0, 0] == 24.0

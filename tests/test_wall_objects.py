"""The wall objects against their definitions, without a simulation: a rotation is
Rodrigues' (compared with SciPy's rotation vector), a velocity profile's position is the
integral of its velocity (compared with numerical quadrature), a servo's speed is the
control law it documents (gain times the force error, capped both ways; PFC's stiffness
gain; the PI integral without wind-up; the held speed's ramp), a mesh vertex moves as
c(t) + R(w t)(X0 - c0), the Verlet bound covers each wall's motion, and the history keeps
each change of load. Directions are off the axes and numbers away from special points."""
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

import bondem
from bondem.walls import (PLANE, TRIANGLE, ConstantVelocity, MeshWall, PlaneWall, Servo,
                          VelocityProfile, WallHistory, WallSet, build_wall_pairs,
                          rotation_matrix)

STEEL = bondem.Material(density=7800.0, young_modulus=2e11, poisson_ratio=0.3,
                        restitution=0.5, friction=0.3)
TILTED = np.array([1.0, 2.0, -2.0]) / 3.0         # a unit normal off every axis


def _message(call, *args, **kwargs):
    with pytest.raises(ValueError) as error:
        call(*args, **kwargs)
    return str(error.value)


# ---------------------------------------------------------------- rotation

@pytest.mark.parametrize("w, t", [((0.3, -1.1, 2.0), 0.7), ((-4.0, 0.5, 0.25), -0.3),
                                  ((0.0, 0.0, 9.0), 0.21), ((0.5, 0.2, -0.7), 1.0)])
def test_rotation_is_the_rotation_vector_w_t(w, t):
    expected = Rotation.from_rotvec(np.multiply(w, t)).as_matrix()
    np.testing.assert_allclose(rotation_matrix(w, t), expected, rtol=0, atol=1e-14)


def test_no_rotation_is_the_identity():
    assert np.array_equal(rotation_matrix((0.0, 0.0, 0.0), 3.0), np.eye(3))
    assert np.array_equal(rotation_matrix((0.3, -1.1, 2.0), 0.0), np.eye(3))


# ---------------------------------------------------------------- motions

def test_constant_velocity():
    motion = ConstantVelocity((0.3, -0.4, 1.2))
    assert np.array_equal(motion.velocity(5.0), [0.3, -0.4, 1.2])
    np.testing.assert_allclose(motion.displacement(2.5), [0.75, -1.0, 3.0], rtol=1e-15)
    assert motion.max_speed() == pytest.approx(1.3, rel=1e-15)
    assert np.array_equal(ConstantVelocity().displacement(4.0), [0.0, 0.0, 0.0])


@pytest.mark.parametrize("value", [(1.0, 2.0), (1.0, float("inf"), 0.0),
                                   (float("nan"), 0.0, 0.0), ((1.0, 2.0, 3.0),)])
def test_a_bad_vector_is_named(value):
    assert _message(ConstantVelocity, value) == \
        f"velocity = {value!r}: expected three finite numbers"


PROFILE_TIMES = [0.0, 0.3, 0.3, 1.1, 2.0]
PROFILE_VELOCITIES = [[0.0, 0.2, -0.1], [0.5, -0.3, 0.4], [-0.2, 0.6, 0.1],
                      [0.7, 0.1, -0.9], [0.3, 0.8, 0.0]]


def test_profile_velocity_is_linear_between_knots_and_jumps_at_a_repeated_time():
    profile = VelocityProfile(PROFILE_TIMES, PROFILE_VELOCITIES)
    v = np.array(PROFILE_VELOCITIES)
    np.testing.assert_allclose(profile.velocity(0.1), v[0] + (v[1] - v[0]) / 3, rtol=1e-14)
    np.testing.assert_allclose(profile.velocity(0.3), v[2], rtol=0)        # after the jump
    np.testing.assert_allclose(profile.velocity(0.2999999), v[1], atol=1e-6)
    np.testing.assert_allclose(profile.velocity(0.9), v[2] + 0.75 * (v[3] - v[2]),
                               rtol=1e-14)
    np.testing.assert_allclose(profile.velocity(1.4), v[3] + (v[4] - v[3]) / 3, rtol=1e-13)
    assert np.array_equal(profile.velocity(2.0), v[4])
    assert np.array_equal(profile.velocity(7.5), v[4])
    # the largest speed of a knot, as a vector's length: |(0.7, 0.1, -0.9)|
    assert profile.max_speed() == pytest.approx(math.sqrt(1.31), rel=1e-15)


@pytest.mark.parametrize("t", [0.0, 0.17, 0.3, 0.64, 1.1, 1.55, 2.0, 3.25])
def test_profile_displacement_is_the_integral_of_its_velocity(t):
    profile = VelocityProfile(PROFILE_TIMES, PROFILE_VELOCITIES)
    expected = [quad(lambda s: profile.velocity(s)[k], 0.0, t, points=[0.3, 1.1, 2.0],
                     limit=200, epsabs=1e-14)[0] if t > 0 else 0.0 for k in range(3)]
    np.testing.assert_allclose(profile.displacement(t), expected, rtol=1e-12, atol=1e-15)


def test_a_profile_of_whole_numbers_moves_in_floating_point():
    """Kernels take float64 velocities: integer knots are converted, after the last too."""
    profile = VelocityProfile([0, 2], [[0, 0, 1], [0, 0, 3]])
    for t in (1.0, 2.0, 5.0):
        assert profile.velocity(t).dtype == np.float64
    assert profile.velocity(1.0)[2] == 2.0 and profile.displacement(3.0)[2] == 7.0


def test_a_one_knot_profile_is_a_constant_velocity():
    profile = VelocityProfile([0.0], [[0.2, -0.5, 0.1]])
    np.testing.assert_allclose(profile.displacement(3.0), [0.6, -1.5, 0.3], rtol=1e-15)
    assert np.array_equal(profile.velocity(1.0), [0.2, -0.5, 0.1])


@pytest.mark.parametrize("times, velocities, message", [
    ([0.0, 1.0], np.zeros((3, 3)),
     "velocity profile: 2 times and velocities of shape (3, 3); expected K times and (K, 3)"),
    ([0.0, 1.0], np.zeros((2, 2)),
     "velocity profile: 2 times and velocities of shape (2, 2); expected K times and (K, 3)"),
    ([], np.zeros((0, 3)),
     "velocity profile: 0 times and velocities of shape (0, 3); expected K times and (K, 3)"),
    ([0.0, float("inf")], np.zeros((2, 3)),
     "velocity profile: times and velocities must be finite"),
    ([0.0, 1.0], [[0.0, 0.0, 0.0], [0.0, float("nan"), 0.0]],
     "velocity profile: times and velocities must be finite"),
    ([0.25, 1.0], np.zeros((2, 3)),
     "velocity profile: times [0.25, 1.0] must start at 0 s and not decrease"),
    ([0.0, 1.0, 0.5], np.zeros((3, 3)),
     "velocity profile: times [0.0, 1.0, 0.5] must start at 0 s and not decrease"),
])
def test_a_bad_profile_is_explained(times, velocities, message):
    assert _message(VelocityProfile, times, velocities) == message


# ---------------------------------------------------------------- servo

def _servo(**kwargs):
    settings = dict(target_force=2.5, gain=0.04, max_velocity=0.3)
    settings.update(kwargs)
    servo = Servo(**settings)
    servo.normal = TILTED
    return servo


def _push(force):
    """The wall force (N) whose component along -TILTED is ``force``."""
    return -force * TILTED + 0.7 * np.array([2.0, -1.0, 0.0]) / math.sqrt(5.0)


@pytest.mark.parametrize("kwargs, message", [
    (dict(gain=1.0, max_velocity=1.0),
     "servo: give exactly one of target_force (N) or target_stress (Pa)"),
    (dict(target_force=1.0, target_stress=1.0, area=1.0, gain=1.0, max_velocity=1.0),
     "servo: give exactly one of target_force (N) or target_stress (Pa)"),
    (dict(target_stress=1e5, gain=1.0, max_velocity=1.0),
     "servo: target_stress needs the area (m^2) it acts on"),
    (dict(target_force=1.0, max_velocity=1.0),
     "servo: give exactly one of gain (m/s per N) or stiffness"),
    (dict(target_force=1.0, gain=1.0, stiffness=lambda: 1.0, max_velocity=1.0),
     "servo: give exactly one of gain (m/s per N) or stiffness"),
    (dict(target_force=1.0, gain=0.0, max_velocity=1.0),
     "servo: gain = 0.0; must be a positive number"),
    (dict(target_force=1.0, gain=1.0, max_velocity=-2),
     "servo: max_velocity = -2; must be a positive number"),
    (dict(target_force=1.0, gain=1.0, max_velocity=float("inf")),
     "servo: max_velocity = inf; must be a positive number"),
    (dict(target_force=1.0, gain=1.0, max_velocity=1.0, tolerance="1"),
     "servo: tolerance = '1'; must be a positive number"),
    (dict(target_force=1.0, stiffness=lambda: 1.0, max_velocity=1.0, fraction=float("nan")),
     "servo: fraction = nan; must be a positive number"),
])
def test_bad_servo_settings_are_explained(kwargs, message):
    assert _message(Servo, **kwargs) == message


def test_servo_defaults():
    servo = Servo(target_force=1.5, gain=0.02, max_velocity=0.1)
    assert (servo.tolerance, servo.fraction, servo.integral_time) == (0.01, 0.3, None)
    assert (servo.travel, servo.speed, servo.measured, servo.integral) == (0, 0, 0, 0)
    assert servo.held is False and servo.max_speed() == 0.1
    assert isinstance(servo.gain, float) and isinstance(servo.max_velocity, float)
    assert np.array_equal(servo.normal, [0.0, 0.0, 1.0])


def test_servo_target_from_a_force_or_a_stress_on_a_changing_area():
    assert Servo(target_force=3, gain=1.0, max_velocity=1.0).target() == 3.0
    assert Servo(target_stress=2e5, area=1.5e-4, gain=1.0,
                 max_velocity=1.0).target() == pytest.approx(30.0, rel=1e-15)
    areas = iter([1e-4, 1.25e-4])
    servo = Servo(target_stress=4e5, area=lambda: next(areas), gain=1.0, max_velocity=1.0)
    assert servo.target() == pytest.approx(40.0, rel=1e-15)
    assert servo.target() == pytest.approx(50.0, rel=1e-15)


def test_servo_speed_is_the_gain_times_the_force_error_capped_both_ways():
    servo = _servo()
    dt = 3e-3
    servo.update(_push(1.0), dt)                 # 1.5 N short: advances at 0.06 m/s
    assert servo.measured == pytest.approx(1.0, rel=1e-14)
    assert servo.speed == pytest.approx(0.04 * 1.5, rel=1e-13)
    assert servo.travel == 0.0                   # it stood still during that step
    np.testing.assert_allclose(servo.velocity(1.0), 0.06 * TILTED, rtol=1e-13)
    servo.update(_push(4.0), dt)                 # 1.5 N over: backs off
    assert servo.travel == pytest.approx(0.06 * dt, rel=1e-13)
    assert servo.speed == pytest.approx(-0.06, rel=1e-13)
    servo.update(_push(-20.0), dt)               # pulled away: capped at +0.3
    assert servo.speed == 0.3
    assert servo.travel == pytest.approx(0.0, abs=1e-17)
    servo.update(_push(40.0), dt)                # overloaded: capped at -0.3
    assert servo.speed == -0.3
    assert servo.travel == pytest.approx(0.3 * dt, rel=1e-13)
    np.testing.assert_allclose(servo.displacement(123.0), 0.3 * dt * TILTED, rtol=1e-13)


def test_servo_error_and_reached_at_the_tolerance():
    servo = Servo(target_force=4.0, gain=0.04, max_velocity=0.3, tolerance=0.125)
    for force, error, reached in ((4.5, 0.125, True), (3.5, -0.125, True),
                                  (4.5000001, 0.125000025, False),
                                  (3.4999999, -0.125000025, False), (2.0, -0.5, False)):
        servo.update(np.array([0.3, -0.2, -force]), 1e-4)   # along -normal: exact
        assert servo.error == pytest.approx(error, rel=1e-6)
        assert servo.reached is reached, force
    zero = _servo(target_force=0.0)
    zero.update(_push(0.02), 1e-4)
    assert zero.error == pytest.approx(0.02, rel=1e-12)
    assert zero.reached is False
    zero.update(_push(0.005), 1e-4)
    assert zero.reached is True


def test_stiffness_servo_takes_pfcs_gain_and_the_cap_while_nothing_touches():
    k = [0.0]
    servo = _servo(target_force=-0.5, gain=None, stiffness=lambda: k[0], fraction=0.35,
                   max_velocity=0.2)
    servo.update(_push(-0.2), 1e-5)              # no contact: v_max / |target| per N
    assert servo.gain == pytest.approx(0.2 / 0.5, rel=1e-15)
    assert servo.speed == pytest.approx(0.4 * -0.3, rel=1e-12)
    k[0] = 2.5e6
    servo.update(_push(-0.499), 1e-5)            # fraction / (k dt)
    assert servo.gain == pytest.approx(0.35 / 25.0, rel=1e-14)
    assert servo.speed == pytest.approx(0.014 * -0.001, rel=1e-9)
    k[0] = 0.5                                   # a soft contact (below 1 N/m) all the same
    servo.update(_push(-0.5001), 1e-2)
    assert servo.gain == pytest.approx(0.35 / 5e-3, rel=1e-14)
    assert servo.speed == pytest.approx(70.0 * 1e-4, rel=1e-9)


def test_pi_servo_adds_the_integrated_error_and_stops_integrating_at_the_cap():
    dt, ti, gain = 2e-3, 0.05, 0.01
    servo = _servo(target_force=3.0, gain=gain, integral_time=ti, max_velocity=0.03)
    integral = 0.0
    for force in (2.2, 2.6, 2.9, 3.3):           # below the cap: integrates
        error = 3.0 - force
        integral += error * dt
        servo.update(_push(force), dt)
        assert servo.speed == pytest.approx(gain * error + gain * integral / ti, rel=1e-12)
        assert servo.integral == pytest.approx(integral, rel=1e-12)
    servo.update(_push(-1.0), dt)                # 4 N short: 0.04 + ..., capped
    assert servo.speed == 0.03
    assert servo.integral == pytest.approx(integral, rel=1e-12)   # no wind-up
    servo.update(_push(3.1), dt)
    assert servo.speed == pytest.approx(gain * -0.1 + gain * (integral - 0.1 * dt) / ti,
                                        rel=1e-12)


def test_pi_servo_exactly_at_the_cap_is_saturated():
    """Conditional integration: the integral grows only while the output is below its
    limit; at the limit the controller is saturated. gain 0.25, T_i = dt = 0.5, error 1:
    0.25 + 0.25 x 0.5 / 0.5 = 0.5 m/s, the cap, in binary-exact numbers."""
    servo = Servo(target_force=1.0, gain=0.25, integral_time=0.5, max_velocity=0.5)
    servo.update(np.zeros(3), 0.5)
    assert servo.speed == 0.5 and servo.integral == 0.0


def test_held_servo_ramps_to_its_speed_and_keeps_measuring():
    servo = _servo(max_velocity=0.5)
    servo.update(_push(1.5), 1e-3)               # 0.04 m/s
    servo.hold(-0.16, ramp=0.01)                 # 0.2 m/s down in 10 ms: 20 m/s^2
    assert servo.held and servo.acceleration == pytest.approx(20.0, rel=1e-13)
    speeds = []
    for _ in range(12):
        servo.update(_push(7.0), 1e-3)
        speeds.append(servo.speed)
    assert servo.measured == pytest.approx(7.0, rel=1e-14)
    np.testing.assert_allclose(speeds[:9], 0.04 - 0.02 * np.arange(1, 10), rtol=1e-12)
    assert speeds[9:] == [-0.16] * 3
    up = _servo(max_velocity=0.5)
    up.hold(0.25, ramp=0.02)                     # from rest: 12.5 m/s^2
    for step in range(1, 4):
        up.update(_push(2.5), 4e-4)
        assert up.speed == pytest.approx(12.5 * 4e-4 * step, rel=1e-12)
    sudden = _servo()
    sudden.hold(-0.2)
    assert sudden.speed == -0.2 and sudden.acceleration == 0.0
    sudden.update(_push(0.0), 2e-3)
    assert sudden.speed == -0.2 and sudden.travel == pytest.approx(-4e-4, rel=1e-14)


def test_a_bad_hold_is_explained():
    servo = _servo()
    assert _message(servo.hold, -0.31) == \
        "servo: held speed -0.31 m/s exceeds max_velocity 0.3 m/s"
    assert _message(servo.hold, 0.1, ramp=-1e-3) == \
        "servo: ramp = -0.001; must be a time >= 0 s"
    assert _message(servo.hold, 0.1, ramp=float("inf")) == \
        "servo: ramp = inf; must be a time >= 0 s"
    servo.hold(0.3)                              # the cap itself is allowed
    assert servo.speed == 0.3


# ---------------------------------------------------------------- walls

def test_plane_wall_moves_its_point_and_keeps_a_unit_normal():
    wall = PlaneWall((0.1, -0.2, 0.3), (1.0, 2.0, -2.0), STEEL, velocity=(0.5, 0.0, -0.25))
    np.testing.assert_allclose(wall.normal, TILTED, rtol=1e-15)
    np.testing.assert_allclose(wall.position(0.4), [0.3, -0.2, 0.2], rtol=1e-15)
    np.testing.assert_allclose(wall.center(0.4), [0.3, -0.2, 0.2], rtol=1e-15)
    assert wall.velocity.dtype == np.float64
    assert np.array_equal(wall.velocity, [0.5, 0.0, -0.25])
    assert np.array_equal(wall.velocity_at(9.0), [0.5, 0.0, -0.25])
    assert wall.extent() == 0.0 and np.array_equal(wall.angular_velocity, np.zeros(3))
    assert wall.material is STEEL and wall.point.dtype == np.float64
    assert PlaneWall((0, 0, 1), (0, 0, 1), STEEL, velocity=(1, 0, 0)).velocity.dtype \
        == np.float64
    rows, types = wall.elements(0.4)
    np.testing.assert_allclose(rows[0], [[0.3, -0.2, 0.2], TILTED, [0, 0, 0]], rtol=1e-15)
    assert rows.shape == (1, 3, 3) and types.tolist() == [PLANE] and types.dtype == np.int8


def test_a_servo_plane_moves_along_its_own_normal():
    servo = Servo(target_force=1.0, gain=0.1, max_velocity=1.0)
    wall = PlaneWall((0.0, 0.0, 0.5), (0.0, -3.0, 4.0), STEEL, motion=servo)
    np.testing.assert_allclose(servo.normal, [0.0, -0.6, 0.8], rtol=1e-15)
    servo.update(np.zeros(3), 0.1)
    servo.update(np.zeros(3), 0.1)               # 0.1 m/s for 0.1 s
    np.testing.assert_allclose(wall.position(0.2), [0.0, -0.006, 0.508], rtol=1e-13)


@pytest.mark.parametrize("args, kwargs, message", [
    (((0, 0, 0), (0, 0, 0), STEEL), {}, "normal = (0, 0, 0): a plane needs a non-zero normal"),
    (((0, 0, 0), (0, 0, 1), "steel"), {}, "material: expected a bondem.Material"),
    (((0, 0), (0, 0, 1), STEEL), {}, "point = (0, 0): expected three finite numbers"),
    (((0, 0, 0), (0, 0, 1), STEEL), dict(velocity=(0, 0, 1), motion=ConstantVelocity()),
     "give a wall either a constant velocity or a motion, not both"),
    (((0, 0, 0), (0, 0), STEEL), {}, "normal = (0, 0): expected three finite numbers"),
    (((0, 0, 0), (0, 0, 1), STEEL), dict(velocity=(0, 1), motion=ConstantVelocity()),
     "velocity = (0, 1): expected three finite numbers"),
    (((0, 0, 0), (0, 0, 1), STEEL), dict(motion=3.0),
     "motion: expected ConstantVelocity, VelocityProfile or Servo, got 3.0"),
])
def test_bad_plane_walls_are_explained(args, kwargs, message):
    assert _message(PlaneWall, *args, **kwargs) == message


SQUARE = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
HALVES = np.array([[0, 1, 2], [0, 2, 3]])


def test_mesh_vertices_turn_about_a_travelling_centre():
    w, centre = np.array([0.4, -0.3, 1.2]), np.array([0.5, 0.25, -0.1])
    profile = VelocityProfile([0.0, 1.0], [[0.1, 0.0, 0.0], [0.3, -0.2, 0.1]])
    wall = MeshWall(SQUARE + 0.01, HALVES, STEEL, angular_velocity=w, rotation_center=centre,
                    motion=profile)
    t = 0.8
    shift = profile.displacement(t)
    turned = Rotation.from_rotvec(w * t).apply(SQUARE + 0.01 - centre)
    np.testing.assert_allclose(wall.current_vertices(t), centre + shift + turned, atol=1e-15)
    np.testing.assert_allclose(wall.center(t), centre + shift, rtol=1e-15)
    np.testing.assert_allclose(wall.position(t), centre + shift, rtol=1e-15)
    np.testing.assert_allclose(wall.velocity_at(t), profile.velocity(t), rtol=1e-15)
    assert np.array_equal(wall.velocity, [0.1, 0.0, 0.0])
    # the farthest vertex from the centre: (2.01, 1.01, 0.01)
    assert wall.extent() == pytest.approx(math.sqrt(1.51 ** 2 + 0.76 ** 2 + 0.11 ** 2),
                                          rel=1e-15)
    rows, types = wall.elements(t)
    np.testing.assert_allclose(rows, (centre + shift + turned)[HALVES], atol=1e-15)
    assert types.tolist() == [TRIANGLE, TRIANGLE] and types.dtype == np.int8
    assert wall.material is STEEL


@pytest.mark.parametrize("vertices, triangles, kwargs, message", [
    (SQUARE[:, :2], HALVES, {},
     "vertices: shape (4, 2); expected (V, 3) finite numbers"),
    (np.where(SQUARE == 2.0, np.nan, SQUARE), HALVES, {},
     "vertices: shape (4, 3); expected (V, 3) finite numbers"),
    (SQUARE, HALVES[:, :2], {}, "triangles: shape (2, 2); expected (T, 3), T >= 1"),
    (SQUARE, np.zeros((0, 3), dtype=int), {},
     "triangles: shape (0, 3); expected (T, 3), T >= 1"),
    (SQUARE, [[0, 1, 4]], {}, "triangles: vertex indices must lie in [0, 3]"),
    (SQUARE, [[0, -1, 2]], {}, "triangles: vertex indices must lie in [0, 3]"),
    (SQUARE + 0.5, [[0, 1, 2], [1, 1, 2]], {}, "triangles: triangle 1 has zero area"),
    (SQUARE + 0.5, [[2, 3, 2], [0, 1, 2]], {}, "triangles: triangle 0 has zero area"),
    (SQUARE + 0.5, [[0, 1, 2], [3, 0, 3], [0, 1, 3]], {},
     "triangles: triangle 1 has zero area"),
    (SQUARE, HALVES, dict(angular_velocity=(1, 2)),
     "angular_velocity = (1, 2): expected three finite numbers"),
    (SQUARE, HALVES, dict(material=None), "material: expected a bondem.Material"),
    (SQUARE, HALVES, dict(motion=Servo(target_force=1.0, gain=1.0, max_velocity=1.0)),
     "a servo drives plane walls only"),
    (SQUARE, HALVES, dict(rotation_center=(0, 0)),
     "rotation_center = (0, 0): expected three finite numbers"),
])
def test_bad_meshes_are_explained(vertices, triangles, kwargs, message):
    kwargs = dict(kwargs)                        # the parameter's dict is shared
    material = kwargs.pop("material", STEEL)
    assert _message(MeshWall, vertices, triangles, material, **kwargs) == message


def test_mesh_from_stl_is_scaled_and_bad_files_are_named(tmp_path):
    import trimesh
    path = tmp_path / "square.stl"
    trimesh.Trimesh(SQUARE, HALVES, process=False).export(path)
    wall = MeshWall.from_stl(path, STEEL, scale=1e-3, velocity=(0.0, 0.0, -0.1))
    np.testing.assert_allclose(np.sort(wall.vertices, axis=0), np.sort(SQUARE * 1e-3, axis=0),
                               rtol=1e-7)
    assert wall.triangles.shape == (2, 3)
    assert np.array_equal(wall.velocity, [0.0, 0.0, -0.1])
    other = tmp_path / "square.mesh"             # STL whatever the file is called
    other.write_bytes(path.read_bytes())
    unscaled = MeshWall.from_stl(other, STEEL)
    np.testing.assert_allclose(np.sort(unscaled.vertices, axis=0), np.sort(SQUARE, axis=0))
    missing = tmp_path / "none.stl"
    assert _message(MeshWall.from_stl, missing, STEEL) == \
        f"{missing}: cannot read STL file (no such file)"
    bad = tmp_path / "bad.stl"
    bad.write_bytes(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 1 2\n")
    assert _message(MeshWall.from_stl, bad, STEEL).startswith(f"{bad}: ")
    broken = tmp_path / "broken.stl"               # a facet of two vertices
    broken.write_text("solid x\nfacet normal 0 0 1\nouter loop\nvertex 1 2 3\n"
                      "vertex 4 5 6\nendloop\nendfacet\nendsolid x\n")
    message = _message(MeshWall.from_stl, broken, STEEL)
    assert message.startswith(f"{broken}: cannot read as STL (") and message.endswith(")")


# ---------------------------------------------------------------- the set of walls

def _walls():
    still = PlaneWall((0.0, 0.0, -1.0), (0.0, 0.0, 1.0), STEEL)
    mesh = MeshWall(SQUARE, HALVES, STEEL, angular_velocity=(0.0, 0.6, 0.8),
                    rotation_center=(1.0, 0.5, 0.0))
    sliding = PlaneWall((0.0, 0.0, 2.0), (0.0, 0.0, -1.0), STEEL,
                        motion=VelocityProfile([0.0, 2.0], [[0.0, 0.0, 0.0], [0.0, 0.0, -4.0]]))
    return [still, mesh, sliding]


def test_wall_set_flattens_the_walls_into_elements():
    walls = WallSet(_walls())
    assert walls.n_walls == 3 and walls.n_elements == 4
    assert walls.element_type.tolist() == [PLANE, TRIANGLE, TRIANGLE, PLANE]
    assert walls.element_wall.tolist() == [0, 1, 1, 2]
    assert walls.element_wall.dtype == np.int64
    np.testing.assert_allclose(walls.angular_velocity, [[0, 0, 0], [0, 0.6, 0.8], [0, 0, 0]])
    np.testing.assert_allclose(walls.extent, [0.0, math.sqrt(1.25), 0.0], rtol=1e-15)
    assert walls.moving is True
    t = 0.5
    rows = walls.elements(t)
    assert rows.shape == (4, 3, 3) and rows.flags.c_contiguous
    np.testing.assert_allclose(rows[1:3], walls.walls[1].elements(t)[0], rtol=1e-15)
    np.testing.assert_allclose(rows[3, 0], [0.0, 0.0, 2.0 - 0.25], rtol=1e-15)  # -t^2
    np.testing.assert_allclose(walls.velocities(t), [[0, 0, 0], [0, 0, 0], [0, 0, -1.0]])
    np.testing.assert_allclose(walls.centers(t), [[0, 0, -1.0], [1.0, 0.5, 0], [0, 0, 1.75]])
    np.testing.assert_allclose(walls.positions(t), walls.centers(t))
    assert walls.velocities(t).dtype == np.float64


def test_a_still_wall_set_computes_its_elements_once():
    walls = WallSet(_walls()[:1] + [MeshWall(SQUARE, HALVES, STEEL)])
    assert walls.moving is False
    first = walls.elements(0.0)
    assert first.shape == (3, 3, 3) and first[0, 0, 2] == -1.0
    np.testing.assert_allclose(first[1:], SQUARE[HALVES])
    assert walls.elements(5.0) is first
    moving = WallSet(_walls())
    assert moving.elements(0.5) is not moving.elements(0.5)
    assert not np.array_equal(moving.elements(0.5), moving.elements(1.0))
    assert WallSet([PlaneWall((0, 0, 0), (0, 0, 1), STEEL, velocity=(1e-9, 0, 0))]).moving
    assert WallSet([MeshWall(SQUARE, HALVES, STEEL, angular_velocity=(0, 0, 1e-9))]).moving


def test_an_empty_wall_set():
    walls = WallSet([])
    assert (walls.n_walls, walls.n_elements, walls.moving) == (0, 0, False)
    assert walls.elements(1.0).shape == (0, 3, 3)
    for values in (walls.velocities(1.0), walls.centers(1.0), walls.positions(1.0),
                   walls.angular_velocity):
        assert values.shape == (0, 3)
    assert walls.element_type.shape == walls.element_wall.shape == (0,)
    assert walls.element_type.dtype == np.int8 and walls.element_wall.dtype == np.int64
    assert walls.max_displacement(1.0, 0.5) == 0.0


def test_wall_set_refuses_what_is_not_a_wall():
    assert _message(WallSet, [_walls()[0], "plane"]) == \
        "walls[1]: expected a PlaneWall or MeshWall, got 'plane'"


def test_verlet_bound_covers_each_walls_motion():
    """Each wall's bound: how far its farthest point can have gone in the elapsed time."""
    still, mesh, sliding = _walls()
    # the sliding plane between t = 1.5 and 2.0: z from 2 - 1.5^2 to 2 - 4
    assert WallSet([still, sliding]).max_displacement(2.0, 0.5) == \
        pytest.approx(4.0 - 2.25, rel=1e-14)
    # the mesh turns at 1 rad/s: its farthest vertex sweeps at most extent * angle
    assert WallSet([still, mesh]).max_displacement(2.0, 0.5) == \
        pytest.approx(math.sqrt(1.25) * 0.5, rel=1e-14)
    # a long time: a turn sweeps at most two extents (the diameter)
    assert WallSet([mesh]).max_displacement(30.0, 10.0) == \
        pytest.approx(2.0 * math.sqrt(1.25), rel=1e-14)
    assert WallSet([still, mesh, sliding]).max_displacement(2.0, 0.5) == \
        pytest.approx(1.75, rel=1e-14)
    # two turning meshes: each at its own rate, the larger sweep bounds
    slow = MeshWall(SQUARE, HALVES, STEEL, angular_velocity=(0.0, 0.0, 0.25),
                    rotation_center=(0.0, 0.0, 0.0))
    assert WallSet([mesh, slow]).max_displacement(2.0, 0.5) == \
        pytest.approx(max(math.sqrt(1.25) * 0.5, math.sqrt(5.0) * 0.125), rel=1e-14)


def test_verlet_bound_of_a_servo_from_its_travel_since_the_mark():
    servo = Servo(target_force=1.0, gain=0.1, max_velocity=0.4)
    walls = WallSet([PlaneWall((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), STEEL, motion=servo),
                     _walls()[0]])
    # never marked: the cap times the time
    assert walls.max_displacement(1.0, 0.25) == pytest.approx(0.1, rel=1e-15)
    servo.update(np.zeros(3), 0.1)               # 1 N short: 0.1 m/s
    servo.update(np.zeros(3), 0.1)
    walls.mark(0.2)                              # at a travel of 0.01 m
    servo.update(np.zeros(3), 0.1)               # 0.02 m
    servo.update(np.array([0.0, 0.0, 5.0]), 0.1)  # 0.03 m, then backs off at the cap
    servo.update(np.zeros(3), 0.1)               # -0.01 m
    assert servo.travel == pytest.approx(-0.01, rel=1e-12)
    assert walls.max_displacement(0.5, 0.3) == pytest.approx(0.02, rel=1e-12)


# ---------------------------------------------------------------- history

def test_history_records_each_change_of_load():
    history = WallHistory(2)
    assert np.array_equal(history.last, np.zeros((2, 3))) and len(history) == 0
    a = np.array([[0.5, -1.0, 2.0], [0.0, 0.0, -3.0]])
    history.record(1e-3, a, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    history.record(2e-3, a.copy(), [[0.0, 0.0, 0.9], [0.0, 0.0, -1.0]])   # no change
    b = a.copy()
    b[1, 0] = 1e-12
    history.record(3e-3, b, [[0.0, 0.0, 0.8], [0.0, 0.0, -1.0]])
    assert len(history) == 2 and np.array_equal(history.last, b)
    b[0, 0] = 99.0                               # the caller's array, changed later
    time, force, position = history.take()
    assert time.tolist() == [1e-3, 3e-3]
    assert force.shape == (2, 2, 3) and force[1, 0, 0] == 0.5 and force[1, 1, 0] == 1e-12
    assert position[1, 0, 2] == 0.8 and position.dtype == np.float64
    assert len(history) == 0
    time, force, position = history.take()
    assert time.shape == (0,) and force.shape == (0, 2, 3) and position.shape == (0, 2, 3)


def test_a_resumed_history_skips_the_load_it_ended_with():
    last = [[0.0, 0.0, 4.0]]
    history = WallHistory(1, last=last)
    assert np.array_equal(history.last, last)
    history.record(5e-3, [[0.0, 0.0, 4.0]], [[0.0, 0.0, 0.0]])
    assert len(history) == 0
    history.record(6e-3, [[0.0, 0.0, 4.5]], [[0.0, 0.0, 0.0]])
    assert len(history) == 1
    # a last row of another number of walls is not the last row
    other = WallHistory(1, last=[[0.0, 0.0, 4.0], [0.0, 0.0, 1.0]])
    assert np.array_equal(other.last, np.zeros((1, 3)))
    other.record(0.0, [[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]])
    assert len(other) == 1


def test_a_full_history_drops_its_older_half():
    history = WallHistory(1, max_rows=7)
    for k in range(8):
        history.record(float(k), [[float(k) + 1.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]])
    # full at 7 rows: the 8th drops the oldest 3
    assert history.dropped == 3 and len(history) == 5
    for k in range(8, 13):
        history.record(float(k), [[float(k) + 1.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]])
    # full again at the 11th: 3 more dropped
    assert history.dropped == 6 and len(history) == 7
    time, force, _ = history.take()
    assert time.tolist() == [6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0]
    assert force[:, 0, 0].tolist() == [7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0]


# ---------------------------------------------------------------- wall pairs

def _distance_to_triangle(points, a, b, c):
    """Distances (m) from points to the triangle: to the nearest of a fine barycentric grid
    on it, never below the true distance and at most 2 mm above it here; slow and
    independent of the kernel's closest point."""
    s = np.linspace(0.0, 1.0, 401)
    u, v = np.meshgrid(s, s)
    inside = u + v <= 1.0
    grid = a + np.outer(u[inside], b - a) + np.outer(v[inside], c - a)
    return cKDTree(grid).query(points)[0]


def test_wall_pairs_are_every_particle_within_its_radius_and_the_skin():
    rng = np.random.default_rng(7)
    triangle = np.array([[0.21, 0.05, 0.1], [1.3, 0.4, 0.0], [0.4, 1.1, 0.35]])
    plane = np.array([[0.0, 0.0, -0.2], TILTED, [0.0, 0.0, 0.0]])
    rows = np.array([plane, triangle, triangle[[0, 2, 1]] + [0.0, 0.0, 0.5]])
    types = np.array([PLANE, TRIANGLE, TRIANGLE], dtype=np.int8)
    position = rng.uniform([-0.5, -0.5, -0.6], [1.8, 1.6, 1.0], size=(1000, 3))
    radius = rng.uniform(0.02, 0.09, 1000)
    skin = 0.03
    pairs = build_wall_pairs(position, radius, skin, rows, types)
    gaps = {e: _distance_to_triangle(position, *rows[e]) - radius for e in (1, 2)}
    expected = []
    for p in range(1000):
        d = float(np.dot(position[p] - plane[0], plane[1]))
        if -radius[p] < d < radius[p] + skin:
            expected.append((p, 0))
        for e in (1, 2):
            gap = gaps[e][p]
            if gap < skin:               # the grid's distance is never below the true one
                expected.append((p, e))
            elif gap < skin + 4e-3:      # too close to call on the grid: take the kernel's
                expected += [(p, e)] if any((pairs == (p, e)).all(axis=1)) else []
    assert pairs.dtype == np.int64
    assert sorted(map(tuple, pairs.tolist())) == sorted(expected)
    assert len(expected) > 100 and {e for _, e in expected} == {0, 1, 2}
    for empty in (build_wall_pairs(position[:0], radius[:0], skin, rows, types),
                  build_wall_pairs(position, radius, skin, rows[:0], types[:0])):
        assert empty.shape == (0, 2) and empty.dtype == np.int64


def test_wall_pairs_of_planes_alone():
    """A floor and a tilted plane, no triangles: a pair wherever -r < d < r + skin; the last
    particle touches both, so a pair list cut at its end would show."""
    floor = np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    tilted = np.array([[0.3, 0.2, 0.0], TILTED, [0.0, 0.0, 0.0]])
    rng = np.random.default_rng(11)
    position = rng.uniform([-1.0, -1.0, -0.2], [1.0, 1.0, 0.6], size=(300, 3))
    position[-1] = [0.3, 0.2, 0.12]              # 0.02 above the floor, behind the plane
    radius = rng.uniform(0.01, 0.05, 300)
    radius[-1] = 0.05
    for rows in (np.array([floor]), np.array([floor, tilted])):
        types = np.zeros(rows.shape[0], dtype=np.int8)
        pairs = build_wall_pairs(position, radius, 0.02, rows, types)
        expected = [(p, e) for p in range(300) for e in range(rows.shape[0])
                    if -radius[p] < np.dot(position[p] - rows[e, 0], rows[e, 1])
                    < radius[p] + 0.02]
        assert pairs.tolist() == [list(pair) for pair in expected]
        assert pairs[-1, 0] == 299 and len(expected) > 20


def test_wall_pairs_with_a_skin_wider_than_the_particles():
    """Verlet lists with a skin of 5 radii: a triangle is found up to r + skin away."""
    triangle = np.array([[[0.0, 0.0, 0.0], [0.002, 0.0, 0.0], [0.0, 0.002, 0.0]]]) + 0.3
    types = np.array([TRIANGLE], dtype=np.int8)
    radius = np.full(5, 0.01)
    # straight above the triangle's inside point (0.3005, 0.3005, 0.3), gaps 0.01 to 0.07
    position = np.array([[0.3005, 0.3005, 0.3 + 0.01 * (1 + k * 1.5)] for k in range(5)])
    pairs = build_wall_pairs(position, radius, 0.05, triangle, types)
    # distance 0.01 + 0.015 k, gap 0.015 k: within the skin of 0.05 for k <= 3
    assert pairs.tolist() == [[0, 0], [1, 0], [2, 0], [3, 0]]

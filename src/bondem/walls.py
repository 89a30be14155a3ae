"""Walls: infinite planes and triangle meshes, moving by translation and rotation.

A wall has a particle ``Material`` (its E, nu, e, mu, mu_r meet the particle's as in
``physics.contact_hertz``) and a rigid motion: a translation u(t) with velocity v(t) (a
``motion``: constant velocity, a piecewise-linear ``VelocityProfile`` or a force-controlled
``Servo``) and, for meshes, a constant angular velocity w (rad/s) about the axis through
``rotation_center`` (which travels with u). At time t a mesh vertex X0 is at
    c(t) + R(w t) (X0 - c0),  c(t) = c0 + u(t)
and the wall's surface velocity at a point q is v(t) + w x (q - c(t)). Planes only
translate.

All walls are flattened into *elements* for the kernels: a plane is one element (type
PLANE: row 0 its point, row 1 its unit normal), a mesh contributes one TRIANGLE element per
face (rows: its three vertices). A plane pushes particles towards its normal side (it is
one-sided); a triangle is two-sided.
"""
from __future__ import annotations

import bisect
import math

import numba
import numpy as np
from numba import prange

from .model import Material
from .neighbors import csr_pairs, grid_shape, sort_row
from .physics import compile_physics

closest_point_on_triangle = compile_physics(numba.njit(cache=False)).closest_point_on_triangle

PLANE, TRIANGLE = 0, 1


def _vector(name, value):
    array = np.asarray(value, dtype=np.float64)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} = {value!r}: expected three finite numbers")
    return array


def rotation_matrix(angular_velocity, time):
    """Rotation by |w| t about w / |w| (Rodrigues), (3,3); identity for w = 0."""
    w = np.asarray(angular_velocity, dtype=np.float64)
    speed = float(np.linalg.norm(w))
    if speed == 0.0 or time == 0.0:
        return np.eye(3)
    k = w / speed
    angle = speed * time
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


class ConstantVelocity:
    """Translation at a constant ``velocity`` (m/s): u(t) = v t."""

    def __init__(self, velocity=(0.0, 0.0, 0.0)):
        self.constant = _vector("velocity", velocity)

    def velocity(self, time):
        """Velocity (3,) m/s at ``time`` (s)."""
        return self.constant

    def displacement(self, time):
        """Translation (3,) m from t = 0 to ``time`` (s)."""
        return self.constant * time

    def max_speed(self):
        """Largest speed (m/s) the motion can have."""
        return float(np.linalg.norm(self.constant))


class VelocityProfile:
    """Piecewise-linear velocity in time: ``times`` (K,) s from 0, non-decreasing, and
    ``velocities`` (K,3) m/s at those times; linear between knots, a jump where a time is
    repeated, the last velocity kept after the last knot. A ramp is two knots with
    different velocities, a hold two with zero velocity, an unload a reversed velocity.
    u(t) is the exact integral of v."""

    def __init__(self, times, velocities):
        times = np.asarray(times, dtype=np.float64).reshape(-1)
        velocities = np.asarray(velocities, dtype=np.float64)
        if velocities.shape != (times.shape[0], 3) or times.shape[0] == 0:
            raise ValueError(f"velocity profile: {times.shape[0]} times and velocities of "
                             f"shape {velocities.shape}; expected K times and (K, 3)")
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(velocities))):
            raise ValueError("velocity profile: times and velocities must be finite")
        if times[0] != 0.0 or np.any(np.diff(times) < 0.0):
            raise ValueError(f"velocity profile: times {times.tolist()} must start at 0 s "
                             "and not decrease")
        self.times, self.velocities = times, velocities
        span = np.diff(times)[:, None]
        self._start = np.vstack([np.zeros(3), np.cumsum(
            0.5 * (velocities[1:] + velocities[:-1]) * span, axis=0)])
        self._times = times.tolist()
        self._last, self._last_time = len(self._times) - 1, self._times[-1]

    def _segment(self, time):
        # asked several times per step (elements, velocities, totals, Verlet bound): the
        # last segment, where most of a test runs, without a search
        if time >= self._last_time:
            return self._last
        return max(bisect.bisect_right(self._times, time) - 1, 0)

    def velocity(self, time):
        """Velocity (3,) m/s at ``time`` (s)."""
        k = self._segment(time)
        if k + 1 >= self.times.shape[0]:
            return self.velocities[-1]
        fraction = (time - self._times[k]) / (self._times[k + 1] - self._times[k])
        return self.velocities[k] + fraction * (self.velocities[k + 1] - self.velocities[k])

    def displacement(self, time):
        """Translation (3,) m from t = 0 to ``time`` (s), the integral of the velocity."""
        k = self._segment(time)
        tau = time - self._times[k]
        if k + 1 >= self.times.shape[0]:
            return self._start[k] + self.velocities[k] * tau
        slope = (self.velocities[k + 1] - self.velocities[k]) / (self._times[k + 1]
                                                                 - self._times[k])
        return self._start[k] + self.velocities[k] * tau + 0.5 * slope * tau * tau

    def max_speed(self):
        """Largest speed (m/s) of the profile."""
        return float(np.max(np.linalg.norm(self.velocities, axis=1)))


class Servo:
    """A plane wall driven along its normal to hold a target force (N) or stress (Pa).

    target_force (N, the particles' push on the wall, along -normal) or target_stress (Pa)
    with ``area`` (m^2, a number or a function of no arguments giving the current area,
    e.g. a lateral wall's height times width); gain (m/s per N of force error); max_velocity
    (m/s, the cap on the wall's speed); tolerance (fraction of the target within which
    ``reached`` is true); stiffness: instead of a fixed gain, a function of no arguments
    giving the stiffness k (N/m) the wall meets now (e.g. the sum of its contacts'
    tangent stiffnesses), the gain then being fraction / (k dt) each step, as PFC's servo
    (fraction 1 would close the gap in one step; the cap applies while k = 0);
    integral_time (s): adds the integral of the force error over this time (a PI servo:
    no lasting error while the wall must keep moving, e.g. a dilating specimen). After
    every step the wall moves on by its speed times the step and takes the speed
    gain (F_target - F) along its normal, capped: with F below the target it advances into
    the particles. The travel, speed, force and integral are state
    (``state.extra["wall_servo"]``, kept by checkpoints).
    """

    def __init__(self, *, target_force=None, target_stress=None, area=None, gain=None,
                 max_velocity, tolerance=0.01, stiffness=None, fraction=0.3,
                 integral_time=None):
        if (target_force is None) == (target_stress is None):
            raise ValueError("servo: give exactly one of target_force (N) or target_stress (Pa)")
        if target_stress is not None and area is None:
            raise ValueError("servo: target_stress needs the area (m^2) it acts on")
        if (gain is None) == (stiffness is None):
            raise ValueError("servo: give exactly one of gain (m/s per N) or stiffness")
        for name, value in (("gain", 1.0 if gain is None else gain),
                            ("max_velocity", max_velocity), ("tolerance", tolerance),
                            ("fraction", fraction)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"servo: {name} = {value!r}; must be a positive number")
        self.target_force, self.target_stress, self.area = target_force, target_stress, area
        self.gain = None if gain is None else float(gain)
        self.max_velocity, self.tolerance = float(max_velocity), float(tolerance)
        self.stiffness, self.fraction = stiffness, float(fraction)
        self.integral_time = None if integral_time is None else float(integral_time)
        self.integral = 0.0    # N s: the force error integrated (with integral_time)
        self.normal = np.array([0.0, 0.0, 1.0])
        self.travel = 0.0      # m along the normal since t = 0
        self.speed = 0.0       # m/s along the normal
        self.measured = 0.0    # N, the particles' push in the last step
        self.held = False      # True: moving at a held speed, the force only measured
        self.held_speed = self.acceleration = 0.0

    def target(self):
        """The target force (N) now."""
        if self.target_force is not None:
            return float(self.target_force)
        area = self.area() if callable(self.area) else self.area
        return float(self.target_stress) * float(area)

    def velocity(self, time):
        """Velocity (3,) m/s: the current speed along the normal."""
        return self.speed * self.normal

    def displacement(self, time):
        """Translation (3,) m since t = 0 (the travel so far; ``time`` is not used)."""
        return self.travel * self.normal

    def max_speed(self):
        """The speed cap (m/s)."""
        return self.max_velocity

    @property
    def error(self):
        """Relative force error (F - F_target) / F_target of the last step."""
        target = self.target()
        return (self.measured - target) / target if target else self.measured

    @property
    def reached(self):
        """True when the last step's force lay within the tolerance of the target."""
        return abs(self.error) <= self.tolerance

    def hold(self, speed, ramp=0.0):
        """Stop controlling: move on at ``speed`` (m/s along the normal, within the cap),
        still measuring the force (a platen switched from confinement to loading);
        ramp (s): reach that speed linearly from the current one over this time (a
        sudden start sends a stress wave through the specimen)."""
        if abs(speed) > self.max_velocity:
            raise ValueError(f"servo: held speed {speed!r} m/s exceeds max_velocity "
                             f"{self.max_velocity!r} m/s")
        if not (isinstance(ramp, (int, float)) and math.isfinite(ramp) and ramp >= 0.0):
            raise ValueError(f"servo: ramp = {ramp!r}; must be a time >= 0 s")
        self.held, self.held_speed = True, float(speed)
        self.acceleration = abs(self.held_speed - self.speed) / ramp if ramp > 0.0 else 0.0
        if ramp == 0.0:
            self.speed = self.held_speed

    def update(self, wall_force, time_step):
        """After a step of ``time_step`` s whose load on the wall was ``wall_force`` (3,) N:
        move on and set the new speed."""
        self.travel += self.speed * time_step
        self.measured = -float(np.dot(wall_force, self.normal))
        if self.held:
            if self.speed != self.held_speed:   # on the ramp to the held speed
                change = self.acceleration * time_step
                self.speed = (min(self.speed + change, self.held_speed)
                              if self.held_speed > self.speed
                              else max(self.speed - change, self.held_speed))
            return
        if self.stiffness is not None:
            k = float(self.stiffness())
            self.gain = (self.fraction / (k * time_step) if k > 0.0
                         else self.max_velocity / max(abs(self.target()), 1e-300))
        error = self.target() - self.measured
        speed = self.gain * error
        if self.integral_time is not None:
            speed += self.gain * (self.integral + error * time_step) / self.integral_time
            if abs(speed) < self.max_velocity:   # no wind-up against the cap
                self.integral += error * time_step
        self.speed = min(max(speed, -self.max_velocity), self.max_velocity)


def _motion(velocity, motion):
    if motion is None:
        return ConstantVelocity(velocity)
    if np.any(_vector("velocity", velocity)):
        raise ValueError("give a wall either a constant velocity or a motion, not both")
    if not hasattr(motion, "displacement"):
        raise ValueError(f"motion: expected ConstantVelocity, VelocityProfile or Servo, "
                         f"got {motion!r}")
    return motion


def _own_friction(value):
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"own_friction = {value!r}; expected True or False")
    return bool(value)


class PlaneWall:
    """Infinite plane through ``point`` (m) with outward ``normal`` (the particles' side),
    a particle ``material`` and a constant ``velocity`` (m/s) or a ``motion``
    (``VelocityProfile``, ``Servo``). own_friction: True makes the material's friction and
    rolling friction its contacts' own (a frictionless platen: friction 0), instead of
    their means with each particle's material."""

    def __init__(self, point, normal, material, velocity=(0.0, 0.0, 0.0), motion=None,
                 own_friction=False):
        self.point = _vector("point", point)
        normal = _vector("normal", normal)
        length = float(np.linalg.norm(normal))
        if length == 0.0:
            raise ValueError("normal = (0, 0, 0): a plane needs a non-zero normal")
        self.normal = normal / length
        if not isinstance(material, Material):
            raise ValueError("material: expected a bondem.Material")
        self.material = material
        self.own_friction = _own_friction(own_friction)
        self.motion = _motion(velocity, motion)
        if isinstance(self.motion, Servo):
            self.motion.normal = self.normal
        self.angular_velocity = np.zeros(3)

    @property
    def velocity(self):
        """Velocity (3,) m/s at t = 0 (``velocity_at`` for other times)."""
        return np.array(self.motion.velocity(0.0), dtype=np.float64)

    def velocity_at(self, time):
        """Velocity (3,) m/s at ``time`` (s)."""
        return self.motion.velocity(time)

    def position(self, time):
        """Reference point (m) at ``time`` (s): the given point moved with the wall."""
        return self.point + self.motion.displacement(time)

    def center(self, time):
        """Rotation centre (m) at ``time`` (s): the reference point for a plane."""
        return self.position(time)

    def extent(self):
        """Largest distance (m) of the wall's geometry from its rotation centre (0: planes
        do not rotate)."""
        return 0.0

    def elements(self, time):
        """(E,3,3) element rows and (E,) types at ``time`` (s)."""
        rows = np.zeros((1, 3, 3))
        rows[0, 0] = self.position(time)
        rows[0, 1] = self.normal
        return rows, np.array([PLANE], dtype=np.int8)


class MeshWall:
    """Triangle mesh: vertices (V,3) m, triangles (T,3) vertex indices, a particle
    ``material``, constant ``velocity`` (m/s) or a translating ``motion``
    (``VelocityProfile``), and ``angular_velocity`` (rad/s) about an axis through
    ``rotation_center`` (m), which moves with the translation. own_friction: as for
    ``PlaneWall``."""

    def __init__(self, vertices, triangles, material, velocity=(0.0, 0.0, 0.0),
                 angular_velocity=(0.0, 0.0, 0.0), rotation_center=(0.0, 0.0, 0.0),
                 motion=None, own_friction=False):
        vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        triangles = np.ascontiguousarray(triangles, dtype=np.int64)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.all(np.isfinite(vertices)):
            raise ValueError(f"vertices: shape {vertices.shape}; expected (V, 3) finite numbers")
        if triangles.ndim != 2 or triangles.shape[1] != 3 or triangles.shape[0] == 0:
            raise ValueError(f"triangles: shape {triangles.shape}; expected (T, 3), T >= 1")
        if triangles.min() < 0 or triangles.max() >= vertices.shape[0]:
            raise ValueError(f"triangles: vertex indices must lie in [0, {vertices.shape[0] - 1}]")
        area = 0.5 * np.linalg.norm(np.cross(vertices[triangles[:, 1]] - vertices[triangles[:, 0]],
                                             vertices[triangles[:, 2]] - vertices[triangles[:, 0]]),
                                    axis=1)
        if np.any(area <= 0.0):
            bad = int(np.flatnonzero(area <= 0.0)[0])
            raise ValueError(f"triangles: triangle {bad} has zero area")
        if not isinstance(material, Material):
            raise ValueError("material: expected a bondem.Material")
        self.vertices = vertices
        self.triangles = triangles
        self.material = material
        self.own_friction = _own_friction(own_friction)
        self.motion = _motion(velocity, motion)
        if isinstance(self.motion, Servo):
            raise ValueError("a servo drives plane walls only")
        self.angular_velocity = _vector("angular_velocity", angular_velocity)
        self.rotation_center = _vector("rotation_center", rotation_center)

    @classmethod
    def from_stl(cls, path, material, scale=1.0, **motion):
        """Load an STL file (trimesh); coordinates multiplied by ``scale`` (to metres)."""
        import pathlib

        import trimesh
        if not pathlib.Path(path).is_file():
            raise ValueError(f"{path}: cannot read STL file (no such file)")
        try:
            mesh = trimesh.load_mesh(str(path), file_type="stl", process=True)
        except Exception as error:  # trimesh raises many kinds on malformed files
            raise ValueError(f"{path}: cannot read as STL ({error})") from error
        if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
            raise ValueError(f"{path}: the STL file holds no triangles")
        return cls(np.asarray(mesh.vertices) * float(scale), np.asarray(mesh.faces), material,
                   **motion)

    @property
    def velocity(self):
        """Velocity (3,) m/s at t = 0 (``velocity_at`` for other times)."""
        return np.array(self.motion.velocity(0.0), dtype=np.float64)

    def velocity_at(self, time):
        """Velocity (3,) m/s at ``time`` (s)."""
        return self.motion.velocity(time)

    def center(self, time):
        """Rotation centre (m) at ``time`` (s)."""
        return self.rotation_center + self.motion.displacement(time)

    def position(self, time):
        """Reference point (m) at ``time`` (s): the rotation centre, moved with the wall."""
        return self.center(time)

    def extent(self):
        """Largest distance (m) of a vertex from the rotation centre."""
        return float(np.linalg.norm(self.vertices - self.rotation_center, axis=1).max())

    def current_vertices(self, time):
        """Vertices (V,3) m at ``time`` (s)."""
        rotation = rotation_matrix(self.angular_velocity, time)
        return self.center(time) + (self.vertices - self.rotation_center) @ rotation.T

    def elements(self, time):
        """(T,3,3) triangle vertex rows and (T,) types at ``time`` (s)."""
        return (np.ascontiguousarray(self.current_vertices(time)[self.triangles]),
                np.full(self.triangles.shape[0], TRIANGLE, dtype=np.int8))


class WallSet:
    """All walls flattened into elements: ``element_wall`` (E,) wall index,
    ``element_type`` (E,), and per-wall motion arrays for the kernels."""

    def __init__(self, walls):
        self.walls = list(walls)
        for k, wall in enumerate(self.walls):
            if not isinstance(wall, (PlaneWall, MeshWall)):
                raise ValueError(f"walls[{k}]: expected a PlaneWall or MeshWall, got {wall!r}")
        types, owners = [], []
        for k, wall in enumerate(self.walls):
            _, t = wall.elements(0.0)
            types.append(t)
            owners.append(np.full(t.shape[0], k, dtype=np.int64))
        self.element_type = np.concatenate(types) if types else np.zeros(0, dtype=np.int8)
        self.element_wall = np.concatenate(owners) if owners else np.zeros(0, dtype=np.int64)
        self.angular_velocity = np.array([w.angular_velocity for w in self.walls]).reshape(-1, 3)
        self.extent = np.array([w.extent() for w in self.walls])
        self.moving = bool(any(w.motion.max_speed() for w in self.walls)
                           or np.any(self.angular_velocity))
        self._static_rows = None

    @property
    def n_walls(self):
        return len(self.walls)

    @property
    def n_elements(self):
        return self.element_type.shape[0]

    def elements(self, time):
        """(E,3,3) element rows at ``time`` (s); computed once when no wall moves."""
        if not self.walls:
            return np.zeros((0, 3, 3))
        if not self.moving and self._static_rows is not None:
            return self._static_rows
        rows = np.ascontiguousarray(np.concatenate([w.elements(time)[0] for w in self.walls]))
        if not self.moving:
            self._static_rows = rows
        return rows

    def velocities(self, time):
        """(W,3) translation velocities (m/s) at ``time`` (s)."""
        return np.array([w.velocity_at(time) for w in self.walls],
                        dtype=np.float64).reshape(-1, 3)

    def centers(self, time):
        """(W,3) rotation centres (m) at ``time`` (s)."""
        return np.array([w.center(time) for w in self.walls]).reshape(-1, 3)

    def positions(self, time):
        """(W,3) reference points (m) at ``time`` (s)."""
        return np.array([w.position(time) for w in self.walls]).reshape(-1, 3)

    def mark(self, time):
        """Remember where the servo walls are at ``time`` (s): the Verlet lists were built
        then (``max_displacement`` measures from here)."""
        self._marked = {k: w.motion.travel for k, w in enumerate(self.walls)
                        if isinstance(w.motion, Servo)}

    def max_displacement(self, time, elapsed):
        """Bound (m) on how far any wall point moved in the ``elapsed`` seconds up to
        ``time``: the translation itself (a servo's from its travel since ``mark``, or
        its speed cap times the time when none was marked) plus the rotation's sweep."""
        if not self.walls:
            return 0.0
        marked = getattr(self, "_marked", {})
        moved = np.empty(len(self.walls))
        for k, w in enumerate(self.walls):
            if isinstance(w.motion, Servo):
                moved[k] = (abs(w.motion.travel - marked[k]) if k in marked
                            else w.motion.max_speed() * elapsed)
            else:
                moved[k] = float(np.linalg.norm(w.motion.displacement(time)
                                                - w.motion.displacement(time - elapsed)))
        turn = np.linalg.norm(self.angular_velocity, axis=1)
        return float(np.max(moved + self.extent * np.minimum(turn * elapsed, 2.0)))


class WallHistory:
    """The load on every wall, step by step: each step whose wall forces differ from the
    last recorded ones adds a row (time at which the loads were evaluated, s; force (W,3)
    N; reference point (W,3) m). ``take()`` hands the rows over and empties the buffer.
    last: the forces (W,3) N of the last row recorded before (a resumed run's). A buffer
    nobody takes from keeps its newest ``max_rows`` rows (``dropped`` counts the others).
    """

    def __init__(self, n_walls, last=None, max_rows=200_000):
        self.n_walls = n_walls
        self.max_rows, self.dropped = int(max_rows), 0
        self._time, self._force, self._position = [], [], []
        self._last = None if last is None or np.shape(last) != (n_walls, 3) else \
            np.array(last, dtype=np.float64)

    @property
    def last(self):
        """The forces (W,3) N of the last row recorded (zeros before the first)."""
        return np.zeros((self.n_walls, 3)) if self._last is None else self._last

    def __len__(self):
        return len(self._time)

    def record(self, time, force, position):
        """Add a row unless the forces equal the last recorded ones."""
        if self._last is not None and np.array_equal(force, self._last):
            return
        self._last = np.array(force, dtype=np.float64)
        if len(self._time) >= self.max_rows:
            half = self.max_rows // 2
            self.dropped += half
            del self._time[:half], self._force[:half], self._position[:half]
        self._time.append(float(time))
        self._force.append(self._last)
        self._position.append(np.array(position, dtype=np.float64))

    def take(self):
        """(times (H,), forces (H,W,3), positions (H,W,3)) recorded since the last take."""
        w = self.n_walls
        out = (np.array(self._time, dtype=np.float64),
               np.array(self._force, dtype=np.float64).reshape(-1, w, 3),
               np.array(self._position, dtype=np.float64).reshape(-1, w, 3))
        self._time, self._force, self._position = [], [], []
        return out


@numba.njit(cache=True, nogil=True)
def _triangle_distance_sq(p, a, b, c):
    q, _ = closest_point_on_triangle((p[0], p[1], p[2]), (a[0], a[1], a[2]),
                                     (b[0], b[1], b[2]), (c[0], c[1], c[2]))
    return (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2


@numba.njit(cache=True, nogil=True)
def _bin_triangles(rows, types, reach, low, width, counts):
    """Each triangle listed in every cell its box, grown by ``reach``, overlaps."""
    n_cells = counts[0] * counts[1] * counts[2]
    start = np.zeros(n_cells + 1, dtype=np.int64)
    fill = np.zeros(0, dtype=np.int64)
    items = np.zeros(0, dtype=np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            for c in range(n_cells):
                start[c + 1] += start[c]
            fill = start[:-1].copy()
            items = np.empty(start[-1], dtype=np.int64)
        for e in range(rows.shape[0]):
            if types[e] != TRIANGLE:
                continue
            lo = np.empty(3, dtype=np.int64)
            hi = np.empty(3, dtype=np.int64)
            for k in range(3):
                a = min(rows[e, 0, k], rows[e, 1, k], rows[e, 2, k]) - reach
                b = max(rows[e, 0, k], rows[e, 1, k], rows[e, 2, k]) + reach
                lo[k] = min(max(int(np.floor((a - low[k]) / width[k])), 0), counts[k] - 1)
                hi[k] = min(max(int(np.floor((b - low[k]) / width[k])), 0), counts[k] - 1)
            for x in range(lo[0], hi[0] + 1):
                for y in range(lo[1], hi[1] + 1):
                    for z in range(lo[2], hi[2] + 1):
                        c = (x * counts[1] + y) * counts[2] + z
                        if pass_ == 0:
                            start[c + 1] += 1
                        else:
                            items[fill[c]] = e
                            fill[c] += 1
    return start, items


@numba.njit(parallel=True, cache=True, nogil=True)
def _wall_pass(position, radius, skin, rows, types, low, width, counts, cell_start, items,
               row_start, out_e, fill):
    n = position.shape[0]
    for p in prange(n):
        found = 0
        x = position[p]
        reach = radius[p] + skin
        for e in range(rows.shape[0]):
            if types[e] == PLANE:
                d = ((x[0] - rows[e, 0, 0]) * rows[e, 1, 0] + (x[1] - rows[e, 0, 1]) * rows[e, 1, 1]
                     + (x[2] - rows[e, 0, 2]) * rows[e, 1, 2])
                if -radius[p] < d < reach:
                    if fill:
                        out_e[row_start[p] + found] = e
                    found += 1
        # None without triangles: Numba prunes the branch by type and a scene of planes
        # never compiles the triangle distance (~1.8 s of a first run)
        if cell_start is not None:
            inside = True
            cell = np.empty(3, dtype=np.int64)
            for k in range(3):
                ik = int(np.floor((x[k] - low[k]) / width[k]))
                if ik < 0 or ik >= counts[k]:
                    inside = False
                cell[k] = ik
            if inside:
                c = (cell[0] * counts[1] + cell[1]) * counts[2] + cell[2]
                for s in range(cell_start[c], cell_start[c + 1]):
                    e = items[s]
                    if _triangle_distance_sq(x, rows[e, 0], rows[e, 1],
                                             rows[e, 2]) < reach * reach:
                        if fill:
                            out_e[row_start[p] + found] = e
                        found += 1
        if fill:
            sort_row(out_e, row_start[p], row_start[p] + found)
        else:
            row_start[p + 1] = found


def build_wall_pairs(position, radius, skin, rows, types):
    """Candidate (particle, element) pairs (K,2) int64, sorted, with gap < skin (m)."""
    n = position.shape[0]
    if n == 0 or rows.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.int64)
    reach = float(radius.max()) + float(skin)
    triangles = rows[types == TRIANGLE]
    if triangles.shape[0]:
        pts = triangles.reshape(-1, 3)
        lo = pts.min(axis=0) - reach
        hi = pts.max(axis=0) + reach
        box = np.vstack([lo, hi])
        low, width, counts = grid_shape(box, 2.0 * reach, np.zeros(3, dtype=bool), lo, hi,
                                        max(64, 4 * n + 4 * triangles.shape[0]))
        cell_start, items = _bin_triangles(rows, types, reach, low, width, counts)
    else:
        low, width, counts = np.zeros(3), np.ones(3), np.ones(3, dtype=np.int64)
        cell_start, items = None, None
    row_start = np.zeros(n + 1, dtype=np.int64)
    dummy = np.zeros(0, dtype=np.int64)
    _wall_pass(position, radius, float(skin), rows, types, low, width, counts, cell_start,
               items, row_start, dummy, False)
    np.cumsum(row_start, out=row_start)
    out_e = np.empty(row_start[-1], dtype=np.int64)
    _wall_pass(position, radius, float(skin), rows, types, low, width, counts, cell_start,
               items, row_start, out_e, True)
    return csr_pairs(row_start, out_e)

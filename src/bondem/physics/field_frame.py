"""A rotating frame of reference: the scene seen from a drum, mill or granulator turning
at a constant angular velocity Omega (rad/s) about an axis through the point c (m).

In that frame a particle of mass m at x moving at v feels two inertial forces (Goldstein,
Classical Mechanics, 4.9):
    centrifugal  F = -m Omega x (Omega x (x - c))   (outward, m |Omega|^2 r_perp)
    Coriolis     F = -2 m Omega x v
and its spin w (rad/s, relative to the frame) a torque -I Omega x w (the spin seen from
the frame: I dw/dt = M - I Omega x w for a sphere of moment of inertia I), so the walls
of a drum can stand still while the particles tumble. The centrifugal force does work
(it has the potential -m |Omega x (x - c)|^2 / 2), the Coriolis force and the torque none.
The frame travels as one array (``FRAME_*`` columns) like gravity.
"""
import numpy as np

from ._registry import physics

FRAME_OMEGA, FRAME_CENTER, FRAME_COLUMNS = 0, 3, 6

# The field model's declaration (physics/field_models.py): the scene's [frame] table.
NAME = "frame"
KEYS = {
    "angular_velocity": ("vector3", [0.0, 0.0, 0.0], -float("inf"), float("inf"), False,
                         False),
    "center": ("vector3", [0.0, 0.0, 0.0], -float("inf"), float("inf"), False, False),
}
ARRAY = "frame_array"
INPUTS = ()
FORCE = "frame_field_force"
MOMENT = "frame_moment"
# a clump's spin relative to a turning frame is not modelled (its torque is the spheres')
CLUMPS = False


def frame_array(angular_velocity=(0.0, 0.0, 0.0), center=(0.0, 0.0, 0.0)):
    """A rotating frame of reference (FRAME_* columns): its angular velocity (3,) rad/s
    about the point center (3,) m. ValueError names a bad one."""
    out = np.zeros(FRAME_COLUMNS)
    for name, value, column in (("angular_velocity", angular_velocity, FRAME_OMEGA),
                                ("center", center, FRAME_CENTER)):
        value = np.asarray(value, dtype=np.float64)
        if value.shape != (3,) or not np.all(np.isfinite(value)):
            raise ValueError(f"{name}: expected 3 finite numbers, got {value!r}")
        out[column:column + 3] = value
    return out


def active(frame):
    """Whether the frame ``frame`` (FRAME_* columns) turns."""
    return bool(np.any(frame[FRAME_OMEGA:FRAME_OMEGA + 3]))


def time_scales(frame, mass, radius):
    """{"frame_rotation": s} of a turning frame: it turns by one radian in 1 / |Omega|."""
    if not active(frame):
        return {}
    return {"frame_rotation": float(1.0 / np.linalg.norm(frame[FRAME_OMEGA:FRAME_OMEGA + 3]))}


@physics
def frame_force(frame, mass, x, v):
    """Centrifugal plus Coriolis force (N, 3-tuple) on a particle of mass (kg) at x (m)
    moving at v (m/s, in the frame) in the rotating frame ``frame`` (FRAME_* columns)."""
    wx = frame[FRAME_OMEGA]
    wy = frame[FRAME_OMEGA + 1]
    wz = frame[FRAME_OMEGA + 2]
    if wx == 0.0 and wy == 0.0 and wz == 0.0:
        return (0.0, 0.0, 0.0)
    rx = x[0] - frame[FRAME_CENTER]
    ry = x[1] - frame[FRAME_CENTER + 1]
    rz = x[2] - frame[FRAME_CENTER + 2]
    # Omega x r, then Omega x (Omega x r)
    ax = wy * rz - wz * ry
    ay = wz * rx - wx * rz
    az = wx * ry - wy * rx
    cx = wy * az - wz * ay
    cy = wz * ax - wx * az
    cz = wx * ay - wy * ax
    # Omega x v
    dx = wy * v[2] - wz * v[1]
    dy = wz * v[0] - wx * v[2]
    dz = wx * v[1] - wy * v[0]
    return (-mass * (cx + 2.0 * dx), -mass * (cy + 2.0 * dy), -mass * (cz + 2.0 * dz))


@physics
def frame_field_force(frame, p, mass, radius, x, v, gravity):
    """The field model's FORCE (physics/field_models.py): ``frame_force`` on particle p
    of mass (kg) at x (m) moving at v (m/s). N, 3-tuple."""
    return frame_force(frame, mass, x, v)


@physics
def frame_moment(frame, inertia, w):
    """The rotating frame's torque (N m, 3-tuple) on a sphere of moment of inertia
    (kg m^2) spinning at w (rad/s, relative to the frame): -I Omega x w."""
    wx = frame[FRAME_OMEGA]
    wy = frame[FRAME_OMEGA + 1]
    wz = frame[FRAME_OMEGA + 2]
    return (-inertia * (wy * w[2] - wz * w[1]), -inertia * (wz * w[0] - wx * w[2]),
            -inertia * (wx * w[1] - wy * w[0]))

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
from ._registry import physics

FRAME_OMEGA, FRAME_CENTER, FRAME_COLUMNS = 0, 3, 6


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
def frame_moment(frame, inertia, w):
    """The rotating frame's torque (N m, 3-tuple) on a sphere of moment of inertia
    (kg m^2) spinning at w (rad/s, relative to the frame): -I Omega x w."""
    wx = frame[FRAME_OMEGA]
    wy = frame[FRAME_OMEGA + 1]
    wz = frame[FRAME_OMEGA + 2]
    return (-inertia * (wy * w[2] - wz * w[1]), -inertia * (wz * w[0] - wx * w[2]),
            -inertia * (wx * w[1] - wy * w[0]))

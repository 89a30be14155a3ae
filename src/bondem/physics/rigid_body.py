"""Rigid bodies (clumps): orientation quaternions and the free rotation of an asymmetric
body, for grains made of several spheres (``bondem.clumps``).

A clump's orientation is the unit quaternion q = (q0, q1, q2, q3) that turns its body
frame (the principal axes of its inertia, moments I1, I2, I3 in kg m^2) into the lab
frame: x_lab = R(q) x_body. Its angular momentum L (N m s) is kept in the lab frame,
where only torques change it, so a free clump keeps L to the last bit.

The rotation over a step of h seconds is NO_SQUISH's symplectic splitting (Miller,
Eleftheriou, Pattnaik, Ndirango, Newns and Martyna, J. Chem. Phys. 116 (2002) 8649): the
free-rotor Hamiltonian L_b1^2/2I1 + L_b2^2/2I2 + L_b3^2/2I3 split into its three terms,
each an exact rotation about one principal axis, composed symmetrically as
    axis 3 for h/2, axis 2 for h/2, axis 1 for h, axis 2 for h/2, axis 3 for h/2.
A rotation about body axis k by phi = L_bk h'/I_k turns q into q (cos phi/2, sin phi/2 e_k)
and the body-frame momentum L_b = R(q)^T L by -phi about e_k. Why this scheme: it is
time-reversible and symplectic, so the energy of a free asymmetric body stays bounded
(no drift over 10^5 steps), each sub-step is an exact rotation, so |q| = 1 up to
round-off (renormalised each step to keep it there), and it needs no iteration (the
implicit midpoint schemes do; Omelyan's leapfrog is second order too but integrates the
angular velocity, so it does not keep L exactly). Second order in h, like the leapfrog of
the translations.
"""
import math

from ._registry import physics


@physics
def quaternion_rotate(q, v):
    """R(q) v: the body-frame vector v turned into the lab frame by the unit quaternion
    q = (q0, q1, q2, q3) (any unit)."""
    q0, q1, q2, q3 = q
    # v + 2 q0 (u x v) + 2 u x (u x v), u = (q1, q2, q3)
    tx = 2.0 * (q2 * v[2] - q3 * v[1])
    ty = 2.0 * (q3 * v[0] - q1 * v[2])
    tz = 2.0 * (q1 * v[1] - q2 * v[0])
    return (v[0] + q0 * tx + q2 * tz - q3 * ty,
            v[1] + q0 * ty + q3 * tx - q1 * tz,
            v[2] + q0 * tz + q1 * ty - q2 * tx)


@physics
def quaternion_rotate_back(q, v):
    """R(q)^T v: the lab-frame vector v in the body frame of q."""
    return quaternion_rotate((q[0], -q[1], -q[2], -q[3]), v)


@physics
def quaternion_normalised(q):
    """q / |q|."""
    s = 1.0 / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] * s, q[1] * s, q[2] * s, q[3] * s)


@physics
def principal_turn(q, lb, k, phi):
    """One NO_SQUISH sub-step: q turned by phi (rad) about its body axis k (0, 1, 2),
    q (cos phi/2, sin phi/2 e_k), and the body-frame vector lb turned by -phi about e_k.
    Returns (q, lb)."""
    c = math.cos(0.5 * phi)
    s = math.sin(0.5 * phi)
    q0, q1, q2, q3 = q
    cp = math.cos(phi)
    sp = math.sin(phi)
    if k == 0:
        q = (q0 * c - q1 * s, q1 * c + q0 * s, q2 * c + q3 * s, q3 * c - q2 * s)
        lb = (lb[0], cp * lb[1] + sp * lb[2], -sp * lb[1] + cp * lb[2])
    elif k == 1:
        q = (q0 * c - q2 * s, q1 * c - q3 * s, q2 * c + q0 * s, q3 * c + q1 * s)
        lb = (cp * lb[0] - sp * lb[2], lb[1], sp * lb[0] + cp * lb[2])
    else:
        q = (q0 * c - q3 * s, q1 * c + q2 * s, q2 * c - q1 * s, q3 * c + q0 * s)
        lb = (cp * lb[0] + sp * lb[1], -sp * lb[0] + cp * lb[1], lb[2])
    return q, lb


@physics
def free_rotation(q, angular_momentum, inertia, h):
    """The orientation after h seconds of free rotation (NO_SQUISH, see the module) of a
    body at orientation q with lab-frame angular momentum L (N m s) and principal
    moments ``inertia`` (3-tuple, kg m^2). Returns the new unit quaternion."""
    lb = quaternion_rotate_back(q, angular_momentum)
    half = 0.5 * h
    q, lb = principal_turn(q, lb, 2, lb[2] / inertia[2] * half)
    q, lb = principal_turn(q, lb, 1, lb[1] / inertia[1] * half)
    q, lb = principal_turn(q, lb, 0, lb[0] / inertia[0] * h)
    q, lb = principal_turn(q, lb, 1, lb[1] / inertia[1] * half)
    q, lb = principal_turn(q, lb, 2, lb[2] / inertia[2] * half)
    return quaternion_normalised(q)


@physics
def body_angular_velocity(q, angular_momentum, inertia):
    """The lab-frame angular velocity (rad/s) R I^-1 R^T L of a body at orientation q with
    lab-frame angular momentum L (N m s) and principal moments ``inertia`` (kg m^2)."""
    lb = quaternion_rotate_back(q, angular_momentum)
    return quaternion_rotate(q, (lb[0] / inertia[0], lb[1] / inertia[1],
                                 lb[2] / inertia[2]))

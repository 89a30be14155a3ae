"""The bond rotation T of the elastic bond (SPEC section 2).

T carries the bond's previous axis n_prev onto its current axis n by the shortest
rotation (Rodrigues), then twists about n by the angle ((w_i + w_j) . n) dt / 2. Both
parts are exact rotations, so vectors carried by a rigidly turning bond keep their length.

Shortest rotation with k = n_prev x n (|k| = sin a) and c = n_prev . n = cos a:
    R v = c v + k x v + k (k . v) / (1 + c)
The last term is (1 - c)/sin^2 a = 1/(1 + c), which stays accurate as a -> 0.
Rotation by angle b about the unit axis n:
    Q v = cos b v + sin b (n x v) + (1 - cos b) n (n . v)
"""
import math

from ._registry import physics
from .vector import add, cross, dot, scale


@physics
def align_rotate(v, n_prev, n):
    """Apply the shortest rotation carrying unit ``n_prev`` onto unit ``n`` to ``v``."""
    k = cross(n_prev, n)
    c = dot(n_prev, n)
    if c <= -1.0 + 1e-12:
        # Half turn: a bond cannot flip within one step; keep v rather than divide by 0.
        return v
    return add(add(scale(v, c), cross(k, v)), scale(k, dot(k, v) / (1.0 + c)))


@physics
def axis_rotate(v, n, angle):
    """Rotate ``v`` by ``angle`` (rad) about the unit axis ``n``."""
    cb = math.cos(angle)
    sb = math.sin(angle)
    return add(add(scale(v, cb), scale(cross(n, v), sb)), scale(n, dot(n, v) * (1.0 - cb)))


@physics
def bond_rotate(v, n_prev, n, twist_angle):
    """T v: align n_prev onto n, then twist by ``twist_angle`` (rad) about n."""
    return axis_rotate(align_rotate(v, n_prev, n), n, twist_angle)

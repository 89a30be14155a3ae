"""The bond rotation T of the elastic bond (SPEC section 2).

T carries the bond's previous axis n_prev onto its current axis n by the shortest
rotation (Rodrigues), then twists about n by the angle ((w_i + w_j) . n) dt / 2. Both
parts are exact rotations, so vectors carried by a rigidly turning bond keep their length.

Shortest rotation with k = n_prev x n (|k| = sin a) and c = n_prev . n = cos a:
    R v = c v + k x v + k (k . v) / (1 + c)
The last term is (1 - c)/sin^2 a = 1/(1 + c), which stays accurate as a -> 0.
Rotation by angle b about the unit axis n:
    Q v = cos b v + sin b (n x v) + (1 - cos b) n (n . v)
The twist angle of one step is tiny (|b| ~ 1e-6 rad), so ``twist_sincos`` evaluates
sin b and 1 - cos b from their Taylor series below |b| = 0.01 (truncation < 1e-16
relative, and 1 - cos b without the cancellation of 1 - math.cos(b)), which spares the bond
kernel two libm calls per bond (docs/performance.md).
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


SMALL_ANGLE = 0.01  # rad; below it the series of twist_sincos are exact to round-off


@physics
def twist_sincos_series(angle):
    """(sin b, cos b, 1 - cos b) of ``angle`` b (rad) by series: exact to round-off only
    for |b| < SMALL_ANGLE, and free of branches and libm calls, so loops vectorise."""
    b2 = angle * angle
    # Horner forms of b - b^3/3! + b^5/5! - b^7/7! and b^2/2! - b^4/4! + b^6/6! - b^8/8!;
    # the first omitted terms are below 1e-16 of the leading ones at |b| = 0.01.
    sb = angle * (1.0 - b2 * (1.0 / 6.0) * (1.0 - b2 * (1.0 / 20.0)
                                             * (1.0 - b2 * (1.0 / 42.0))))
    omc = 0.5 * b2 * (1.0 - b2 * (1.0 / 12.0) * (1.0 - b2 * (1.0 / 30.0)
                                                   * (1.0 - b2 * (1.0 / 56.0))))
    return sb, 1.0 - omc, omc


@physics
def twist_sincos(angle):
    """(sin b, cos b, 1 - cos b) of ``angle`` b (rad), by series for |b| < SMALL_ANGLE."""
    if abs(angle) < SMALL_ANGLE:
        return twist_sincos_series(angle)
    cb = math.cos(angle)
    return math.sin(angle), cb, 1.0 - cb


@physics
def axis_rotate(v, n, angle):
    """Rotate ``v`` by ``angle`` (rad) about the unit axis ``n``."""
    sb, cb, omc = twist_sincos(angle)
    return add(add(scale(v, cb), scale(cross(n, v), sb)), scale(n, dot(n, v) * omc))


@physics
def bond_rotate(v, n_prev, n, twist_angle):
    """T v: align n_prev onto n, then twist by ``twist_angle`` (rad) about n."""
    return axis_rotate(align_rotate(v, n_prev, n), n, twist_angle)

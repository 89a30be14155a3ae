"""Closest point of a triangle to a point (Ericson, Real-Time Collision Detection, 5.1.5).

Used for sphere-triangle contacts of mesh walls. Returns the point and the feature it lies
on: FACE (interior), EDGE or VERTEX, which the wall contact search needs to avoid counting
a contact twice where triangles share an edge or a vertex.
"""
from ._registry import physics
from .vector import add, dot, scale, sub

FACE, EDGE, VERTEX = 0, 1, 2


@physics
def closest_point_on_triangle(p, a, b, c):
    """Closest point (m) of triangle abc to p, and its feature (FACE, EDGE or VERTEX)."""
    ab = sub(b, a)
    ac = sub(c, a)
    ap = sub(p, a)
    d1 = dot(ab, ap)
    d2 = dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return a, VERTEX
    bp = sub(p, b)
    d3 = dot(ab, bp)
    d4 = dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return b, VERTEX
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return add(a, scale(ab, d1 / (d1 - d3))), EDGE
    cp = sub(p, c)
    d5 = dot(ab, cp)
    d6 = dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return c, VERTEX
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return add(a, scale(ac, d2 / (d2 - d6))), EDGE
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        return add(b, scale(sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)))), EDGE
    denominator = 1.0 / (va + vb + vc)
    v = vb * denominator
    w = vc * denominator
    return add(add(a, scale(ab, v)), scale(ac, w)), FACE

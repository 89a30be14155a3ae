"""Small vector helpers on 3-tuples, usable from every backend (see _registry)."""
import math

from ._registry import physics


@physics
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@physics
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@physics
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@physics
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@physics
def scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@physics
def norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@physics
def minimum_image(r, box_length, periodic_x, periodic_y, periodic_z):
    """Shortest periodic image of the separation ``r`` (m) in a box of ``box_length`` (m)."""
    x, y, z = r
    if periodic_x:
        x -= box_length[0] * math.floor(x / box_length[0] + 0.5)
    if periodic_y:
        y -= box_length[1] * math.floor(y / box_length[1] + 0.5)
    if periodic_z:
        z -= box_length[2] * math.floor(z / box_length[2] + 0.5)
    return (x, y, z)

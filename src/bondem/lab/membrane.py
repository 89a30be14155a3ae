"""A flexible membrane around a cylindrical specimen: the confining pressure applied as
forces on its outermost particles (pure functions of arrays).

The lateral surface between the platens is cut into cells of about one particle diameter
in angle and in height. In each cell the particle reaching farthest from the axis
(radial distance plus radius) is a vertex of the membrane: in each row of cells the
vertices, in order round the axis, make a closed polygon, and the membrane is that
polygon's prism of the row's height dz. Each vertex carries the pressure on half of each
of its two edges, sigma_3 dz rot(P_next - P_prev) / 2 towards the inside (P: the
vertices' reach points), so a gap in a staircase of particles or a crack is spanned by the
edge across it. The forces follow the particles as the specimen bulges, narrows or breaks,
as a latex membrane's would (the boundary-particle method of PFC's and Yade's
flexible-membrane triaxial tests, e.g. Cheung and O'Sullivan 2008, with cells instead of a
Voronoi tessellation). Because a closed polygon's edges sum to nothing, the forces have no
net lateral force whatever the specimen's shape, and no torque about the axis at the
points they press (at the particles' centres, where they act, a few 1e-4 of their
moment): the membrane neither pushes the specimen sideways over frictionless platens nor
twists it.
The specimen's cross-section is the mean area the polygons enclose: with it the pressure
is exactly the specimen's mean lateral stress.
"""
from __future__ import annotations

import math

import numpy as np


def membrane_forces(position, radius, axis, low, high, pressure, cell):
    """Forces (N,3) N of the confining ``pressure`` (Pa) on the vertices of the membrane
    between ``low`` and ``high`` (m, along ``axis``), its lateral surface 2 pi R h_p (m^2)
    and its radius R (m): R = sqrt(A / pi), A the mean area its pressed rows' polygons
    enclose (the specimen's cross-section), h_p their height.

    In each cell of target size ``cell`` (m, about a particle diameter) the particle
    reaching farthest from the axis is a vertex; a row's vertices make a closed polygon
    pressed by ``pressure`` over the row's height. A row of fewer than three vertices
    encloses nothing and is not pressed. With A as the cross-section the pressure is the
    specimen's mean lateral stress exactly: the forces' virial -sum(f . P) over the
    vertices' reach points P is 2 pressure A h_p. The axis passes through the centroid of
    the particles between low and high."""
    force = np.zeros_like(position)
    z = position[:, axis]
    inside = np.flatnonzero((z >= low) & (z <= high))
    if inside.size == 0 or high <= low:
        return force, 0.0, 0.0
    lateral = [k for k in range(3) if k != axis]
    xy = position[inside][:, lateral]
    xy = xy - xy.mean(axis=0)
    rho = np.hypot(xy[:, 0], xy[:, 1])
    reach = rho + radius[inside]
    mean_reach = float(np.percentile(reach, 90.0))
    n_theta = max(6, int(round(2.0 * math.pi * mean_reach / cell)))
    n_z = max(1, int(round((high - low) / cell)))
    d_theta, d_z = 2.0 * math.pi / n_theta, (high - low) / n_z
    theta = np.arctan2(xy[:, 1], xy[:, 0])
    i_theta = np.minimum((theta + math.pi) / d_theta, n_theta - 1).astype(np.int64)
    i_z = np.minimum((z[inside] - low) / d_z, n_z - 1).astype(np.int64)
    key = i_z * n_theta + i_theta
    order = np.lexsort((reach, key))
    last = np.flatnonzero(np.r_[key[order][1:] != key[order][:-1], True])
    vertex = order[last]            # the farthest-reaching particle of each cell, by row
    row = key[vertex] // n_theta    # and in each row in order of angle
    _, start, count = np.unique(row, return_index=True, return_counts=True)
    first, size = np.repeat(start, count), np.repeat(count, count)
    here = np.arange(vertex.size) - first
    after = first + (here + 1) % size
    before = first + (here - 1) % size
    closed = size >= 3
    safe = np.maximum(rho[vertex], 1e-300)
    point = (reach[vertex] / safe)[:, None] * xy[vertex]
    chord = point[after[closed]] - point[before[closed]]
    pressed = inside[vertex[closed]]
    # rot(chord) = (chord_y, -chord_x) points out of a polygon gone round anticlockwise
    force[pressed, lateral[0]] = -0.5 * pressure * d_z * chord[:, 1]
    force[pressed, lateral[1]] = 0.5 * pressure * d_z * chord[:, 0]
    # the shoelace formula: each vertex and the next one span a triangle with the axis
    cross = point[:, 0] * point[after, 1] - point[after, 0] * point[:, 1]
    rows = np.count_nonzero(count >= 3)
    enclosed = 0.5 * float(np.sum(cross[closed]))
    if not enclosed > 0.0:
        return force, 0.0, 0.0
    mean_radius = math.sqrt(enclosed / rows / math.pi)
    return force, 2.0 * math.pi * mean_radius * d_z * rows, mean_radius

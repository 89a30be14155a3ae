"""A flexible membrane around a cylindrical specimen: the confining pressure applied as
forces on its outermost particles (pure functions of arrays).

The lateral surface between the platens is cut into cells of about one particle diameter
in angle and in height. In each cell the particle reaching farthest from the axis
(radial distance plus radius) carries the cell's share of the pressure: sigma_3 times the
cell's area at that particle's reach, R_c dtheta dz, pushing towards the axis. The forces
follow the particles as the specimen bulges, narrows or breaks, as a latex membrane's
would (the boundary-particle method of PFC's and Yade's flexible-membrane triaxial tests,
e.g. Cheung and O'Sullivan 2008, with cells instead of a Voronoi tessellation). Their sum
is sigma_3 times the specimen's current lateral surface.
"""
from __future__ import annotations

import math

import numpy as np


def membrane_forces(position, radius, axis, low, high, pressure, cell):
    """Forces (N,3) N of the confining ``pressure`` (Pa) on the outermost particle of each
    cell of the lateral surface between ``low`` and ``high`` (m, along ``axis``), the
    surface (m^2) they press on and its mean radius (m). A row's empty cells are pressed
    through the nearest filled one (the one before it when tied); a row without a
    particle is not pressed. cell: the cells'
    target size (m), about a particle diameter. The axis passes through the centroid of
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
    outer = order[last]                      # the farthest-reaching particle of each cell
    # an empty cell (a gap in a staircase of particles, a crack) gives its area to the
    # nearest filled cell of its row: the membrane spans it
    filled = key[outer]
    share = np.ones(outer.size)
    grid = np.zeros(n_z * n_theta, bool)
    grid[filled] = True
    if not grid.all():
        slot = np.full(n_z * n_theta, -1, np.int64)
        slot[filled] = np.arange(outer.size)
        target = nearest_filled(grid.reshape(n_z, n_theta))
        empty = np.flatnonzero(~grid & (target >= 0))
        np.add.at(share, slot[target[empty]], 1.0)
    r_cell = reach[outer]
    area = r_cell * d_theta * d_z * share
    unit = np.zeros((outer.size, 3))
    safe = np.maximum(rho[outer], 1e-300)
    unit[:, lateral[0]] = xy[outer, 0] / safe
    unit[:, lateral[1]] = xy[outer, 1] / safe
    np.add.at(force, inside[outer], -pressure * area[:, None] * unit)
    return force, float(area.sum()), float(np.sum(r_cell * share) / np.sum(share))


def nearest_filled(grid):
    """For each cell of ``grid`` (rows of cells around the circumference, True where
    filled): the flat index of the nearest filled cell of its row going round (the one
    before it when two are as near; itself when filled), -1 in a row with none."""
    n_rows, n = grid.shape
    column = np.arange(3 * n) - n                  # three turns: the row's neighbours wrap
    tiled = np.tile(grid, 3)
    before = np.maximum.accumulate(np.where(tiled, column, -4 * n), axis=1)[:, n:2 * n]
    after = np.minimum.accumulate(np.where(tiled, column, 4 * n)[:, ::-1],
                                  axis=1)[:, ::-1][:, n:2 * n]
    here = np.arange(n)
    pick = np.where(here - before <= after - here, before, after) % n
    out = np.arange(n_rows)[:, None] * n + pick
    out[~grid.any(axis=1)] = -1
    return out.ravel()

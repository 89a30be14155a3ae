"""Numba kernels of the packing generator (``bondem.generate``): the overlap energy of
soft spheres in a container and its FIRE minimisation.

Energy (all lengths in m, unit stiffness, unit mass; only the minimum matters):
    U = 1/2 sum_pairs max(0, (r_i + r_j)(1 + delta) - d_ij)^2
      + 1/2 sum_i sum_walls max(0, r_i (1 + delta) + margin_i - s_w(x_i))^2
with s_w the distance of the centre to wall w (positive inside). The radii are inflated by
delta so that the minimiser stops with the *true* overlaps strictly negative.

Walls: kind 0 sphere (center, radius), 1 box (low, high; six planes), 2 cylinder
(center, axis, radius, half height; mantle and two caps), 3 signed-distance grid of a
closed mesh (trilinear interpolation, gradient of the interpolant).
"""
import math

import numba
import numpy as np

_jit = dict(cache=True, nogil=True, fastmath=False)

SPHERE, BOX, CYLINDER, GRID = 0, 1, 2, 3
# status codes of relax()
CONVERGED, REBUILD, MAX_ITERATIONS = 0, 1, 2


@numba.njit(**_jit)
def grid_sample(grid, origin, spacing, x, y, z):
    """Trilinear interpolation of a signed-distance grid at (x, y, z): value and gradient."""
    nx, ny, nz = grid.shape
    fx = (x - origin[0]) / spacing
    fy = (y - origin[1]) / spacing
    fz = (z - origin[2]) / spacing
    i = min(max(int(math.floor(fx)), 0), nx - 2)
    j = min(max(int(math.floor(fy)), 0), ny - 2)
    k = min(max(int(math.floor(fz)), 0), nz - 2)
    tx = min(max(fx - i, 0.0), 1.0)
    ty = min(max(fy - j, 0.0), 1.0)
    tz = min(max(fz - k, 0.0), 1.0)
    c000 = grid[i, j, k]
    c100 = grid[i + 1, j, k]
    c010 = grid[i, j + 1, k]
    c110 = grid[i + 1, j + 1, k]
    c001 = grid[i, j, k + 1]
    c101 = grid[i + 1, j, k + 1]
    c011 = grid[i, j + 1, k + 1]
    c111 = grid[i + 1, j + 1, k + 1]
    c00 = c000 * (1 - tx) + c100 * tx
    c10 = c010 * (1 - tx) + c110 * tx
    c01 = c001 * (1 - tx) + c101 * tx
    c11 = c011 * (1 - tx) + c111 * tx
    c0 = c00 * (1 - ty) + c10 * ty
    c1 = c01 * (1 - ty) + c11 * ty
    value = c0 * (1 - tz) + c1 * tz
    gx = ((c100 - c000) * (1 - ty) * (1 - tz) + (c110 - c010) * ty * (1 - tz)
          + (c101 - c001) * (1 - ty) * tz + (c111 - c011) * ty * tz) / spacing
    gy = ((c10 - c00) * (1 - tz) + (c11 - c01) * tz) / spacing
    gz = (c1 - c0) / spacing
    return value, gx, gy, gz


@numba.njit(**_jit)
def wall_push(kind, params, grid, origin, spacing, x, y, z, reach, out):
    """Add to ``out`` (3,) the inward push of every wall on a sphere of radius ``reach`` (m)
    centred at (x, y, z); return the largest penetration (m, <= 0 when fully inside)."""
    worst = -1e300
    if kind == SPHERE:
        rx, ry, rz = x - params[0], y - params[1], z - params[2]
        rho = math.sqrt(rx * rx + ry * ry + rz * rz)
        pen = reach - (params[3] - rho)
        worst = pen
        if pen > 0.0 and rho > 0.0:
            out[0] -= pen * rx / rho
            out[1] -= pen * ry / rho
            out[2] -= pen * rz / rho
    elif kind == BOX:
        xs = (x, y, z)
        for a in range(3):
            pen = reach - (xs[a] - params[a])
            worst = max(worst, pen)
            if pen > 0.0:
                out[a] += pen
            pen = reach - (params[3 + a] - xs[a])
            worst = max(worst, pen)
            if pen > 0.0:
                out[a] -= pen
    elif kind == CYLINDER:
        rx, ry, rz = x - params[0], y - params[1], z - params[2]
        ax, ay, az = params[3], params[4], params[5]
        t = rx * ax + ry * ay + rz * az
        px, py, pz = rx - t * ax, ry - t * ay, rz - t * az
        rho = math.sqrt(px * px + py * py + pz * pz)
        pen = reach - (params[6] - rho)
        worst = pen
        if pen > 0.0 and rho > 0.0:
            out[0] -= pen * px / rho
            out[1] -= pen * py / rho
            out[2] -= pen * pz / rho
        pen = reach - (params[7] - t)
        worst = max(worst, pen)
        if pen > 0.0:
            out[0] -= pen * ax
            out[1] -= pen * ay
            out[2] -= pen * az
        pen = reach - (params[7] + t)
        worst = max(worst, pen)
        if pen > 0.0:
            out[0] += pen * ax
            out[1] += pen * ay
            out[2] += pen * az
    else:
        value, gx, gy, gz = grid_sample(grid, origin, spacing, x, y, z)
        pen = reach - value
        worst = pen
        g = math.sqrt(gx * gx + gy * gy + gz * gz)
        if pen > 0.0 and g > 0.0:
            out[0] += pen * gx / g
            out[1] += pen * gy / g
            out[2] += pen * gz / g
    return worst


@numba.njit(**_jit)
def penetrations(kind, params, grid, origin, spacing, position, reach):
    """Largest wall penetration (m) of each sphere (N,) of radius ``reach`` (N,)."""
    n = position.shape[0]
    out = np.empty(n)
    push = np.zeros(3)
    for i in range(n):
        out[i] = wall_push(kind, params, grid, origin, spacing, position[i, 0],
                           position[i, 1], position[i, 2], reach[i], push)
    return out


@numba.njit(**_jit)
def overlap_forces(position, radius, inflation, wall_inflation, margin, pairs, kind, params, grid, origin,
                   spacing, force):
    """Forces -dU/dx (unit stiffness) into ``force``; return the largest true pair overlap
    relative to the smaller radius and the largest true wall penetration relative to the
    radius (both without inflation)."""
    n = position.shape[0]
    force[:, :] = 0.0
    worst_pair = -1e300
    for p in range(pairs.shape[0]):
        i = pairs[p, 0]
        j = pairs[p, 1]
        dx = position[j, 0] - position[i, 0]
        dy = position[j, 1] - position[i, 1]
        dz = position[j, 2] - position[i, 2]
        d2 = dx * dx + dy * dy + dz * dz
        contact = (radius[i] + radius[j]) * (1.0 + inflation)
        if d2 >= contact * contact:
            continue
        d = math.sqrt(d2)
        overlap = contact - d
        if d > 0.0:
            nx, ny, nz = dx / d, dy / d, dz / d
        else:  # coincident centres: any direction separates them
            nx, ny, nz = 1.0, 0.0, 0.0
        force[i, 0] -= overlap * nx
        force[i, 1] -= overlap * ny
        force[i, 2] -= overlap * nz
        force[j, 0] += overlap * nx
        force[j, 1] += overlap * ny
        force[j, 2] += overlap * nz
        true_overlap = (radius[i] + radius[j] - d) / min(radius[i], radius[j])
        worst_pair = max(worst_pair, true_overlap)
    worst_wall = -1e300
    for i in range(n):
        reach = radius[i] * (1.0 + wall_inflation) + margin[i]
        pen = wall_push(kind, params, grid, origin, spacing, position[i, 0], position[i, 1],
                        position[i, 2], reach, force[i])
        worst_wall = max(worst_wall, (pen - radius[i] * wall_inflation) / radius[i])
    return worst_pair, worst_wall


@numba.njit(**_jit)
def relax(position, velocity, radius, inflation, wall_inflation, margin, pairs, kind, params, grid, origin,
          spacing, reference, half_skin, tolerance, max_iterations, fire):
    """FIRE minimisation (Bitzek et al., PRL 97, 170201, 2006) of the overlap energy.

    Stops with CONVERGED once the largest true pair overlap is below ``tolerance`` (relative
    to the smaller radius) and no sphere crosses a wall; with REBUILD when a sphere moved
    more than ``half_skin`` (m) from ``reference`` (the neighbour list is then stale); or
    with MAX_ITERATIONS. ``fire`` = [dt, alpha, steps since P < 0] is carried between calls.
    Returns (status, iterations, worst pair overlap, worst wall penetration).
    """
    n = position.shape[0]
    force = np.empty((n, 3))
    dt_max = fire[3]
    alpha_start, f_inc, f_dec, f_alpha, n_min = 0.1, 1.1, 0.5, 0.99, 5
    # cap on a single move: keeps the first steps from a random start (large overlaps)
    # from throwing spheres across the container
    max_move = 0.1 * radius.min()
    dt, alpha, n_positive = fire[0], fire[1], int(fire[2])
    worst_pair, worst_wall = overlap_forces(position, radius, inflation, wall_inflation, margin, pairs, kind,
                                            params, grid, origin, spacing, force)
    status = MAX_ITERATIONS
    it = 0
    while it < max_iterations:
        if worst_pair < tolerance and worst_wall <= 0.0:
            status = CONVERGED
            break
        power = 0.0
        v2 = 0.0
        f2 = 0.0
        for i in range(n):
            for a in range(3):
                power += force[i, a] * velocity[i, a]
                v2 += velocity[i, a] * velocity[i, a]
                f2 += force[i, a] * force[i, a]
        if power > 0.0:
            scale = alpha * math.sqrt(v2 / f2) if f2 > 0.0 else 0.0
            for i in range(n):
                for a in range(3):
                    velocity[i, a] = (1.0 - alpha) * velocity[i, a] + scale * force[i, a]
            n_positive += 1
            if n_positive > n_min:
                dt = min(dt * f_inc, dt_max)
                alpha *= f_alpha
        else:
            dt *= f_dec
            alpha = alpha_start
            n_positive = 0
            velocity[:, :] = 0.0
        moved = 0.0
        for i in range(n):
            dx2 = 0.0
            for a in range(3):
                velocity[i, a] += force[i, a] * dt
            step2 = 0.0
            for a in range(3):
                step2 += (velocity[i, a] * dt) ** 2
            shrink = 1.0
            if step2 > max_move * max_move:
                shrink = max_move / math.sqrt(step2)
            for a in range(3):
                position[i, a] += velocity[i, a] * dt * shrink
                dx2 += (position[i, a] - reference[i, a]) ** 2
            moved = max(moved, dx2)
        it += 1
        worst_pair, worst_wall = overlap_forces(position, radius, inflation, wall_inflation, margin, pairs,
                                                kind, params, grid, origin, spacing, force)
        if moved > half_skin * half_skin:
            status = REBUILD
            break
    if status == MAX_ITERATIONS and worst_pair < tolerance and worst_wall <= 0.0:
        status = CONVERGED
    fire[0], fire[1], fire[2] = dt, alpha, n_positive
    return status, it, worst_pair, worst_wall

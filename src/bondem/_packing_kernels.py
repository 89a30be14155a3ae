"""Numba kernels of the packing generator (``bondem.generate``): the overlap energy of
soft spheres in a container and its FIRE minimisation.

Energy (all lengths in m, unit stiffness, unit mass; only the minimum matters):
    U = 1/2 sum_pairs max(0, (r_i + r_j)(1 + inflation) - d_ij)^2
      + 1/2 sum_i sum_walls max(0, r_i (1 + wall_inflation) + margin_i - s_w(x_i))^2
with s_w the distance of the centre to wall w (positive inside). Inflating the radii
makes the minimiser stop with the true overlaps (penetrations) strictly negative.

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
def overlap_forces(position, radius, inflation, wall_inflation, margin, pairs, kind, params,
                   grid, origin, spacing, force):
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
def relax(position, velocity, radius, inflation, wall_inflation, margin, pairs, kind, params,
          grid, origin, spacing, reference, half_skin, tolerance, max_iterations, fire):
    """FIRE minimisation (Bitzek et al., PRL 97, 170201, 2006) of the overlap energy.

    Stops with CONVERGED once the largest true pair overlap is below ``tolerance`` (relative
    to the smaller radius) and no sphere crosses a wall; with REBUILD when a sphere moved
    more than ``half_skin`` (m) from ``reference`` (the neighbour list is then stale); or
    with MAX_ITERATIONS. ``fire`` = [dt, alpha, steps since P < 0, dt_max] (time in units
    of sqrt(mass / stiffness) = 1) is carried between calls.
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
    worst_pair, worst_wall = overlap_forces(position, radius, inflation, wall_inflation,
                                            margin, pairs, kind, params, grid, origin,
                                            spacing, force)
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
        worst_pair, worst_wall = overlap_forces(position, radius, inflation, wall_inflation,
                                                margin, pairs, kind, params, grid, origin,
                                                spacing, force)
        if moved > half_skin * half_skin:
            status = REBUILD
            break
    if status == MAX_ITERATIONS and worst_pair < tolerance and worst_wall <= 0.0:
        status = CONVERGED
    fire[0], fire[1], fire[2] = dt, alpha, n_positive
    return status, it, worst_pair, worst_wall


@numba.njit(**_jit, inline="always")
def _dot(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


@numba.njit(**_jit)
def _triangle_distance2(px, py, pz, tri):
    """Squared distance from p to triangle tri (3,3) (Ericson, Real-Time Collision
    Detection, 5.1.5: Voronoi regions of vertices, edges and face); scalars only, so the
    loop over triangles allocates nothing."""
    ax, ay, az = tri[0, 0], tri[0, 1], tri[0, 2]
    abx, aby, abz = tri[1, 0] - ax, tri[1, 1] - ay, tri[1, 2] - az
    acx, acy, acz = tri[2, 0] - ax, tri[2, 1] - ay, tri[2, 2] - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = _dot(abx, aby, abz, apx, apy, apz)
    d2 = _dot(acx, acy, acz, apx, apy, apz)
    # barycentric weights (v along ab, w along ac) of the closest point
    if d1 <= 0.0 and d2 <= 0.0:
        v, w = 0.0, 0.0
    else:
        bpx, bpy, bpz = apx - abx, apy - aby, apz - abz
        d3 = _dot(abx, aby, abz, bpx, bpy, bpz)
        d4 = _dot(acx, acy, acz, bpx, bpy, bpz)
        cpx, cpy, cpz = apx - acx, apy - acy, apz - acz
        d5 = _dot(abx, aby, abz, cpx, cpy, cpz)
        d6 = _dot(acx, acy, acz, cpx, cpy, cpz)
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            v, w = 1.0, 0.0
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            v, w = d1 / (d1 - d3), 0.0
        elif d6 >= 0.0 and d5 <= d6:
            v, w = 0.0, 1.0
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            v, w = 0.0, d2 / (d2 - d6)
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            v = 1.0 - w
        else:
            denominator = 1.0 / (va + vb + vc)
            v, w = vb * denominator, vc * denominator
    dx = apx - v * abx - w * acx
    dy = apy - v * aby - w * acy
    dz = apz - v * abz - w * acz
    return dx * dx + dy * dy + dz * dz


@numba.njit(cache=True, parallel=True)
def mesh_signed_distance(points, triangles):
    """Exact distance (m) of points (P,3) to a closed triangle mesh (T,3,3), positive
    inside. Sign from the winding number (sum of the triangles' solid angles, Van
    Oosterom & Strackee, IEEE Trans. Biomed. Eng. 30, 125, 1983): 4 pi inside, 0 outside.
    Brute force, O(P T): meant for the packing's grid and its final check."""
    out = np.empty(points.shape[0])
    for k in numba.prange(points.shape[0]):
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        best = 1e300
        winding = 0.0
        for t in range(triangles.shape[0]):
            tri = triangles[t]
            best = min(best, _triangle_distance2(px, py, pz, tri))
            ax, ay, az = tri[0, 0] - px, tri[0, 1] - py, tri[0, 2] - pz
            bx, by, bz = tri[1, 0] - px, tri[1, 1] - py, tri[1, 2] - pz
            cx, cy, cz = tri[2, 0] - px, tri[2, 1] - py, tri[2, 2] - pz
            la = math.sqrt(ax * ax + ay * ay + az * az)
            lb = math.sqrt(bx * bx + by * by + bz * bz)
            lc = math.sqrt(cx * cx + cy * cy + cz * cz)
            triple = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
            denominator = (la * lb * lc + _dot(ax, ay, az, bx, by, bz) * lc
                           + _dot(ax, ay, az, cx, cy, cz) * lb + _dot(bx, by, bz, cx, cy, cz) * la)
            winding += 2.0 * math.atan2(triple, denominator)
        distance = math.sqrt(best)
        out[k] = distance if winding > 2.0 * math.pi else -distance
    return out

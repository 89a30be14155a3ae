"""O(N) neighbour search: a cell grid builds a Verlet list of candidate pairs with a skin.

Pairs (i, j), i < j, whose surfaces are closer than ``skin`` (minimum image along periodic
axes) are listed, sorted by i then j. The list stays valid until some particle has moved
more than skin/2 since the build (two particles approaching each other by skin/2 each close
the gap); ``max_displacement`` measures that. Cells are at least 2 r_max + skin wide, so a
particle's candidates lie in its own and the 26 adjacent cells; along a periodic axis with
fewer than three cells the wrapped neighbours are visited once each. The search is a
parallel pass per particle (into rows of a guessed room, or counting then filling when a
row outgrows it), each row sorted, so the list is the same whatever the thread count.
History of contacts is carried across rebuilds by ``carry_history`` (match by pair key).
``relative_spread`` bounds how far neighbours moved relative to each other, which lets a
list outlive skin/2 of common motion.
"""
import math

import numba
import numpy as np
from numba import prange

from .status import SimulationBlowUp

_jit = dict(parallel=True, cache=True, nogil=True)


def grid_shape(position, cell_size, periodic, box_low, box_high, max_cells):
    """Cell grid (low (3,), cell widths (3,), counts (3,) int64) covering the particles.

    Along periodic axes the grid spans the periodic cell exactly; along the others the
    particles' bounding box. Cells grow beyond cell_size (m) while the grid would have more
    than max_cells cells (sparse systems).
    """
    if position.shape[0]:
        least, most = bounding_box(position)
        low = np.where(periodic, box_low, least)
        extent = np.where(periodic, box_high - box_low, most - low)
    else:
        low = np.zeros(3)
        extent = np.zeros(3)
    size = float(cell_size)
    with np.errstate(all="ignore"):
        spread = float(np.max(extent)) / size
    if not spread < 1e15:   # NaN, infinite or absurd: the grid would be garbage
        raise SimulationBlowUp("simulation blew up: positions became NaN, infinite or "
                               f"{spread:.3g} cut-offs apart (met by the neighbour grid); "
                               "reduce the time step or check the loads")
    while True:
        counts = np.maximum(1, np.floor(extent / size).astype(np.int64))
        counts = np.where(periodic, counts, counts + 1)
        if np.prod(counts.astype(np.float64)) <= max_cells:
            break
        size *= 1.25
    width = np.where(periodic, extent / counts, size)
    return low.astype(np.float64), width.astype(np.float64), counts.astype(np.int64)


@numba.njit(cache=True, nogil=True)
def bounding_box(position):
    """(lowest (3,), highest (3,)) coordinates of position (N,3), N > 0, in m; both NaN if
    a coordinate is NaN. numpy's min(axis=0) of this layout took 0.25 ms for 10^4 rows."""
    low = position[0].copy()
    high = position[0].copy()
    finite = True
    for p in range(position.shape[0]):
        for k in range(3):
            x = position[p, k]
            finite &= x == x
            low[k] = min(low[k], x)
            high[k] = max(high[k], x)
    if not finite:
        low[:] = np.nan
        high[:] = np.nan
    return low, high


@numba.njit(cache=True, nogil=True)
def _axis_cell(x, low, width, count, periodic):
    """Index of the cell holding coordinate x (m) along one axis of the grid."""
    c = int(math.floor((x - low) / width))
    if periodic:
        return c % count
    return min(max(c, 0), count - 1)


@numba.njit(cache=True, nogil=True)
def _axis_neighbours(c, count, periodic):
    """The distinct cells along one axis at most one from cell c: (how many, first,
    second, third). Along a periodic axis of one or two cells the wrapped neighbours are
    the same cells, visited once."""
    if periodic:
        if count >= 3:
            return 3, (c + count - 1) % count, c, (c + 1) % count
        return count, 0, 1, 1
    first = max(c - 1, 0)
    last = min(c + 1, count - 1)
    return last - first + 1, first, first + 1, first + 2


@numba.njit(cache=True, nogil=True)
def _pick(q, a, b, c):
    return a if q == 0 else (b if q == 1 else c)


@numba.njit(cache=True, nogil=True)
def counting_sort(index, n):
    """Rows grouped by ``index`` (int64 values in 0..n-1), stable: (start (n+1,), order),
    the rows of group g being order[start[g]:start[g+1]], ascending. O(rows + n)."""
    start = np.zeros(n + 1, dtype=np.int64)
    for r in range(index.shape[0]):
        start[index[r] + 1] += 1
    for g in range(n):
        start[g + 1] += start[g]
    fill = start[:-1].copy()
    order = np.empty(index.shape[0], dtype=np.int64)
    for r in range(index.shape[0]):
        order[fill[index[r]]] = r
        fill[index[r]] += 1
    return start, order


@numba.njit(cache=True, nogil=True)
def bin_particles(position, low, width, counts, periodic):
    """Counting sort of particles into cells: (cell_start (C+1,), particles by cell (N,))."""
    n = position.shape[0]
    cell = np.empty(n, dtype=np.int64)
    for p in range(n):
        c0 = _axis_cell(position[p, 0], low[0], width[0], counts[0], periodic[0])
        c1 = _axis_cell(position[p, 1], low[1], width[1], counts[1], periodic[1])
        c2 = _axis_cell(position[p, 2], low[2], width[2], counts[2], periodic[2])
        cell[p] = (c0 * counts[1] + c1) * counts[2] + c2
    return counting_sort(cell, counts[0] * counts[1] * counts[2])


@numba.njit(cache=True, nogil=True)
def sort_row(values, start, stop):
    """Insertion sort of values[start:stop] in place (a row of a few neighbours)."""
    for s in range(start + 1, stop):
        v = values[s]
        t = s - 1
        while t >= start and values[t] > v:
            values[t + 1] = values[t]
            t -= 1
        values[t + 1] = v


@numba.njit(**_jit)
def _pair_pass(position, radius, skin, low, width, counts, periodic, box_length,
               cell_start, order, row_start, stride, out_j, found_rows):
    """Pairs (i, j > i) with gap < skin: found_rows[i] receives row i's count; with an
    empty out_j that is all (a counting pass), else the row's j, sorted, go to out_j from
    i * stride (stride > 0: room for stride of them) or from row_start[i] (CSR, stride 0);
    a row longer than its room writes only what fits."""
    # The cells are tuples, not arrays: an array made per particle inside the parallel
    # loop was a heap allocation each, and they were most of a rebuild's time.
    n = position.shape[0]
    fill = out_j.shape[0] > 0
    any_periodic = periodic[0] or periodic[1] or periodic[2]
    for i in prange(n):
        n0, a0, a1, a2 = _axis_neighbours(
            _axis_cell(position[i, 0], low[0], width[0], counts[0], periodic[0]),
            counts[0], periodic[0])
        n1, b0, b1, b2 = _axis_neighbours(
            _axis_cell(position[i, 1], low[1], width[1], counts[1], periodic[1]),
            counts[1], periodic[1])
        n2, e0, e1, e2 = _axis_neighbours(
            _axis_cell(position[i, 2], low[2], width[2], counts[2], periodic[2]),
            counts[2], periodic[2])
        found = 0
        if stride > 0:
            start = i * stride
            capacity = stride
        else:
            start = row_start[i]
            capacity = row_start[i + 1] - start if fill else 0
        xi = position[i, 0]
        yi = position[i, 1]
        zi = position[i, 2]
        ri = radius[i]
        # Cells consecutive along z (all but a periodic wrap) hold their particles in one
        # span of ``order``: one loop instead of three short ones, whose varying trip
        # counts of 0-3 were mispredicted branches.
        along = n2 == 1 or (e1 == e0 + 1 and (n2 == 2 or e2 == e1 + 1))
        runs = 1 if along else n2
        for qa in range(n0):
            for qb in range(n1):
                row = (_pick(qa, a0, a1, a2) * counts[1] + _pick(qb, b0, b1, b2)) * counts[2]
                for qe in range(runs):
                    first = row + (e0 if along else _pick(qe, e0, e1, e2))
                    last = first + (n2 if along else 1)
                    for s in range(cell_start[first], cell_start[last]):
                        j = order[s]
                        dx = position[j, 0] - xi
                        dy = position[j, 1] - yi
                        dz = position[j, 2] - zi
                        if any_periodic:
                            if periodic[0]:
                                dx -= box_length[0] * np.floor(dx / box_length[0] + 0.5)
                            if periodic[1]:
                                dy -= box_length[1] * np.floor(dy / box_length[1] + 0.5)
                            if periodic[2]:
                                dz -= box_length[2] * np.floor(dz / box_length[2] + 0.5)
                        reach = ri + radius[j] + skin
                        # No branch on the test (j <= i is half the candidates, at random:
                        # a branch on it was mispredicted half the time). The fill pass
                        # writes every candidate into the next free slot of the row; a
                        # miss is overwritten by the hit that must still come.
                        hit = (j > i) & (dx * dx + dy * dy + dz * dz < reach * reach)
                        if fill and found < capacity:
                            out_j[start + found] = j
                        found += hit
        if fill:
            # Pairs ordered by (i, j) whatever the cell order.
            sort_row(out_j, start, start + min(found, capacity))
        found_rows[i] = found


@numba.njit(**_jit)
def _compact_rows(buffer, stride, row_start, out_j):
    """Rows written ``stride`` apart in buffer, packed into CSR order (row_start)."""
    for i in prange(row_start.shape[0] - 1):
        for k in range(row_start[i + 1] - row_start[i]):
            out_j[row_start[i] + k] = buffer[i * stride + k]


def build_pairs(position, radius, skin, periodic, box_low, box_high, row_room=0):
    """Verlet list: (M,2) int64 pairs i < j with surface gap < skin (m), sorted by (i, j).

    position (N,3) m; radius (N,) m; periodic (3,) bool with box_low/box_high (3,) m.
    Periodic axes must be longer than twice the cut-off 2 r_max + skin (minimum image).
    row_room: a guess of the longest row (pairs of one i); with it the search runs once,
    into rows of that room, instead of counting first and filling after (a longer row
    found falls back to the two passes): the same list, in 60 % of the time.
    """
    position = np.ascontiguousarray(position, dtype=np.float64)
    n = position.shape[0]
    periodic = np.asarray(periodic, dtype=np.bool_)
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64)
    cutoff = 2.0 * float(radius.max()) + float(skin)
    box_length = np.where(periodic, np.asarray(box_high) - np.asarray(box_low), 1.0)
    if np.any(periodic & (box_length < 2.0 * cutoff)):
        raise ValueError(f"periodic box lengths {box_length[periodic].tolist()} m must be at "
                         f"least twice the contact cut-off 2 r_max + skin = {cutoff:.3g} m")
    low, width, counts = grid_shape(position, cutoff, periodic, np.asarray(box_low, float),
                                    np.asarray(box_high, float), max(64, 2 * n))
    cell_start, order = bin_particles(position, low, width, counts, periodic)
    skin = float(skin)
    found = np.empty(n, dtype=np.int64)
    row_start = np.zeros(n + 1, dtype=np.int64)
    row_room = int(row_room)
    if row_room > 0:
        buffer = np.empty(n * row_room, dtype=np.int64)
        _pair_pass(position, radius, skin, low, width, counts, periodic, box_length,
                   cell_start, order, row_start, row_room, buffer, found)
        if found.max() <= row_room:
            np.cumsum(found, out=row_start[1:])
            out_j = np.empty(row_start[-1], dtype=np.int64)
            _compact_rows(buffer, row_room, row_start, out_j)
            return csr_pairs(row_start, out_j)
    else:
        _pair_pass(position, radius, skin, low, width, counts, periodic, box_length,
                   cell_start, order, row_start, 0, np.zeros(0, dtype=np.int64), found)
    np.cumsum(found, out=row_start[1:])
    out_j = np.empty(row_start[-1], dtype=np.int64)
    _pair_pass(position, radius, skin, low, width, counts, periodic, box_length,
               cell_start, order, row_start, 0, out_j, found)
    return csr_pairs(row_start, out_j)


def csr_pairs(row_start, out_j):
    """(M,2) pairs from CSR rows: i repeated over its row, j."""
    out_i = np.repeat(np.arange(row_start.shape[0] - 1, dtype=np.int64), np.diff(row_start))
    return np.ascontiguousarray(np.column_stack([out_i, out_j]))


@numba.njit(cache=True, nogil=True)
def _max_displacement_range(first, last, position, reference, box_length, periodic):
    worst = 0.0
    if not (periodic[0] or periodic[1] or periodic[2]):
        # without the per-component test LLVM vectorises the loop: for the n = 47
        # lattice, 0.4 of the time with the arrays in cache (docs/performance.md)
        for p in range(first, last):
            dx = position[p, 0] - reference[p, 0]
            dy = position[p, 1] - reference[p, 1]
            dz = position[p, 2] - reference[p, 2]
            worst = max(worst, dx * dx + dy * dy + dz * dz)
        return worst
    for p in range(first, last):
        d2 = 0.0
        for k in range(3):
            d = position[p, k] - reference[p, k]
            if periodic[k]:
                d -= box_length[k] * np.floor(d / box_length[k] + 0.5)
            d2 += d * d
        worst = max(worst, d2)
    return worst


DISPLACEMENT_BLOCK = 16384    # particles per parallel block of the displacement test


# A maximum per block into an array, not a prange reduction (which compiles for seconds):
# the maximum does not depend on the order, so the result is the same with any threads.
@numba.njit(cache=True, nogil=True, parallel=True)
def _max_displacement_sq(position, reference, box_length, periodic):
    n = position.shape[0]
    blocks = (n + DISPLACEMENT_BLOCK - 1) // DISPLACEMENT_BLOCK
    worst = np.zeros(max(blocks, 1))
    for b in prange(blocks):
        worst[b] = _max_displacement_range(b * DISPLACEMENT_BLOCK,
                                           min(n, (b + 1) * DISPLACEMENT_BLOCK), position,
                                           reference, box_length, periodic)
    return worst.max()


def max_displacement(position, reference, box_length, periodic):
    """Largest distance (m) any particle moved from ``reference`` (minimum image)."""
    periodic = np.asarray(periodic, dtype=np.bool_)
    if position.shape[0] < 2 * DISPLACEMENT_BLOCK:   # not worth waking the threads
        worst = _max_displacement_range(0, position.shape[0], position, reference,
                                        box_length, periodic)
    else:
        worst = _max_displacement_sq(position, reference, box_length, periodic)
    return float(np.sqrt(worst))


@numba.njit(cache=True, nogil=True)
def _matching_rows(old_pairs, new_pairs, n_particles):
    """Merge of the two lists, both sorted by key i * n_particles + j: (new rows whose key
    is in old_pairs, their old rows)."""
    new_rows = np.empty(new_pairs.shape[0], dtype=np.int64)
    old_rows = np.empty(new_pairs.shape[0], dtype=np.int64)
    found = 0
    o = 0
    n_old = old_pairs.shape[0]
    for r in range(new_pairs.shape[0]):
        key = new_pairs[r, 0] * n_particles + new_pairs[r, 1]
        while o < n_old and old_pairs[o, 0] * n_particles + old_pairs[o, 1] < key:
            o += 1
        if o < n_old and old_pairs[o, 0] * n_particles + old_pairs[o, 1] == key:
            new_rows[found] = r
            old_rows[found] = o
            found += 1
    return new_rows[:found], old_rows[:found]


@numba.njit(cache=True, nogil=True)
def _copy_rows(old_values, new_values, new_rows, old_rows):
    """new_values[new_rows] = old_values[old_rows] for (M, K) arrays."""
    for q in range(new_rows.shape[0]):
        for k in range(old_values.shape[1]):
            new_values[new_rows[q], k] = old_values[old_rows[q], k]


def history_map(old_pairs, new_pairs, n_particles):
    """(new rows that were listed before, their old rows): the rows of ``new_pairs`` whose
    (i, j) key is also in ``old_pairs``, both sorted by key. One merge serves every
    history array of a rebuild (``carry_history``)."""
    if old_pairs.shape[0] == 0 or new_pairs.shape[0] == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return _matching_rows(np.ascontiguousarray(old_pairs, dtype=np.int64),
                          np.ascontiguousarray(new_pairs, dtype=np.int64),
                          np.int64(n_particles))


def carry_history(old_pairs, old_values, new_pairs, n_particles, mapping=None):
    """History values (e.g. tangential springs) of ``new_pairs`` taken from ``old_pairs``
    where the same (i, j) key was listed before, zero elsewhere. Pairs sorted by key;
    mapping: their ``history_map``, when several arrays are carried at once."""
    new_values = np.zeros((new_pairs.shape[0],) + old_values.shape[1:], dtype=old_values.dtype)
    new_rows, old_rows = (history_map(old_pairs, new_pairs, n_particles) if mapping is None
                          else mapping)
    if new_rows.size and old_values.shape[0]:
        rows = old_values.shape[0]
        _copy_rows(np.ascontiguousarray(old_values).reshape(rows, -1),
                   new_values.reshape(new_values.shape[0], -1), new_rows, old_rows)
    return new_values


# -- the relative trigger ------------------------------------------------------------------
# A pair's gap changes by at most |d_i - d_j| (d: displacements since the build), not
# d_i + d_j: particles that move together (a falling agglomerate, a flying fragment) do not
# close their gaps. Bounding |d_i - d_j| over every pair that could come into reach lets a
# list live until the particles have moved relative to their neighbours, not past them.

def reference_cells(reference, cell_size, max_cells):
    """Cells of the reference positions (N,3) m for ``relative_spread``: (counts (3,) int64,
    cell of each particle (N,) int32); cells at least ``cell_size`` (m) wide, at most
    ``max_cells`` (< 2^31) of them."""
    n = reference.shape[0]
    low, width, counts = grid_shape(reference, cell_size, np.zeros(3, dtype=np.bool_),
                                    np.zeros(3), np.zeros(3), max_cells)
    cell = np.empty(n, dtype=np.int32)
    _cells_of(reference, low, width, counts, cell)
    return counts, cell


@numba.njit(cache=True, nogil=True)
def _cells_of(position, low, width, counts, cell):
    for p in range(position.shape[0]):
        cell[p] = ((_axis_cell(position[p, 0], low[0], width[0], counts[0], False) * counts[1]
                    + _axis_cell(position[p, 1], low[1], width[1], counts[1], False))
                   * counts[2] + _axis_cell(position[p, 2], low[2], width[2], counts[2], False))


@numba.njit(cache=True, nogil=True)
def _window3(s, t, axis, sign):
    """t = the extreme (minimum for sign 1, maximum for -1: of sign * value) of each cell
    of the (n0, n1, n2) grid s over itself and its two neighbours along ``axis``."""
    n0, n1, n2 = s.shape
    for i in range(n0):
        for j in range(n1):
            if axis == 2:
                for k in range(n2):
                    v = s[i, j, k]
                    if k > 0 and sign * s[i, j, k - 1] < sign * v:
                        v = s[i, j, k - 1]
                    if k + 1 < n2 and sign * s[i, j, k + 1] < sign * v:
                        v = s[i, j, k + 1]
                    t[i, j, k] = v
            else:
                below = (i > 0) if axis == 0 else (j > 0)
                above = (i + 1 < n0) if axis == 0 else (j + 1 < n1)
                i0, j0 = (i - 1, j) if axis == 0 else (i, j - 1)
                i1, j1 = (i + 1, j) if axis == 0 else (i, j + 1)
                for k in range(n2):
                    t[i, j, k] = s[i, j, k]
                if below:
                    for k in range(n2):
                        if sign * s[i0, j0, k] < sign * t[i, j, k]:
                            t[i, j, k] = s[i0, j0, k]
                if above:
                    for k in range(n2):
                        if sign * s[i1, j1, k] < sign * t[i, j, k]:
                            t[i, j, k] = s[i1, j1, k]


@numba.njit(cache=True, nogil=True)
def relative_spread(position, reference, cell, counts, scratch):
    """Bound (m) on |d_i - d_j| over the particles i, j of neighbouring cells (``cell``,
    ``counts`` from ``reference_cells``; d = position - reference, no periodic images):
    the largest diagonal of the box holding the displacements of a non-empty cell and
    its 26 neighbours. scratch: at least 12 C float64, C = counts' product."""
    cells = counts[0] * counts[1] * counts[2]
    values = scratch[:6 * cells]
    spare = scratch[6 * cells:12 * cells]
    values[:3 * cells] = np.inf
    values[3 * cells:] = -np.inf
    for p in range(position.shape[0]):
        c = cell[p]
        for k in range(3):
            d = position[p, k] - reference[p, k]
            values[k * cells + c] = min(values[k * cells + c], d)
            values[(3 + k) * cells + c] = max(values[(3 + k) * cells + c], d)
    occupied = np.empty(cells, dtype=np.bool_)
    for c in range(cells):
        occupied[c] = values[c] <= values[3 * cells + c]
    shape = (counts[0], counts[1], counts[2])
    for row in range(6):
        grid = values[row * cells:(row + 1) * cells].reshape(shape)
        other = spare[row * cells:(row + 1) * cells].reshape(shape)
        sign = 1.0 if row < 3 else -1.0
        _window3(grid, other, 0, sign)
        _window3(other, grid, 1, sign)
        _window3(grid, other, 2, sign)
    worst = 0.0
    for c in range(cells):
        if occupied[c]:
            d2 = 0.0
            for k in range(3):
                d2 += (spare[(3 + k) * cells + c] - spare[k * cells + c]) ** 2
            worst = max(worst, d2)
    return math.sqrt(worst)

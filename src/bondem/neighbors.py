"""O(N) neighbour search: a cell grid builds a Verlet list of candidate pairs with a skin.

Pairs (i, j), i < j, whose surfaces are closer than ``skin`` (minimum image along periodic
axes) are listed, sorted by i then j. The list stays valid until some particle has moved
more than skin/2 since the build (two particles approaching each other by skin/2 each close
the gap); ``max_displacement`` measures that. Cells are at least 2 r_max + skin wide, so a
particle's candidates lie in its own and the 26 adjacent cells; along a periodic axis with
fewer than three cells the wrapped neighbours are visited once each. The grid is counted
and filled in two parallel passes, so the list is the same whatever the thread count.
History of contacts is carried across rebuilds by ``carry_history`` (match by pair key).
"""
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
        low = np.where(periodic, box_low, position.min(axis=0))
        extent = np.where(periodic, box_high - box_low, position.max(axis=0) - low)
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
def _cell_of(x, low, width, counts, periodic):
    c = np.empty(3, dtype=np.int64)
    for k in range(3):
        ik = int(np.floor((x[k] - low[k]) / width[k]))
        if periodic[k]:
            ik %= counts[k]
        else:
            ik = min(max(ik, 0), counts[k] - 1)
        c[k] = ik
    return c


@numba.njit(cache=True, nogil=True)
def bin_particles(position, low, width, counts, periodic):
    """Counting sort of particles into cells: (cell_start (C+1,), particles by cell (N,))."""
    n = position.shape[0]
    n_cells = counts[0] * counts[1] * counts[2]
    cell = np.empty(n, dtype=np.int64)
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    for p in range(n):
        c = _cell_of(position[p], low, width, counts, periodic)
        cell[p] = (c[0] * counts[1] + c[1]) * counts[2] + c[2]
        cell_start[cell[p] + 1] += 1
    for c in range(n_cells):
        cell_start[c + 1] += cell_start[c]
    fill = cell_start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for p in range(n):
        order[fill[cell[p]]] = p
        fill[cell[p]] += 1
    return cell_start, order


@numba.njit(cache=True, nogil=True)
def _neighbour_cells(c, counts, periodic):
    """Distinct cells adjacent to (and including) cell c: (flat ids (27,), how many)."""
    out = np.empty(27, dtype=np.int64)
    axis_cells = np.empty((3, 3), dtype=np.int64)
    axis_n = np.zeros(3, dtype=np.int64)
    for k in range(3):
        for d in range(-1, 2):
            ik = c[k] + d
            if periodic[k]:
                ik %= counts[k]
            elif ik < 0 or ik >= counts[k]:
                continue
            seen = False
            for q in range(axis_n[k]):
                if axis_cells[k, q] == ik:
                    seen = True
            if not seen:
                axis_cells[k, axis_n[k]] = ik
                axis_n[k] += 1
    m = 0
    for a in range(axis_n[0]):
        for b in range(axis_n[1]):
            for e in range(axis_n[2]):
                out[m] = (axis_cells[0, a] * counts[1] + axis_cells[1, b]) * counts[2] \
                    + axis_cells[2, e]
                m += 1
    return out, m


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
               cell_start, order, row_start, out_j, fill):
    n = position.shape[0]
    for i in prange(n):
        c = _cell_of(position[i], low, width, counts, periodic)
        cells, m = _neighbour_cells(c, counts, periodic)
        found = 0
        for q in range(m):
            cc = cells[q]
            for s in range(cell_start[cc], cell_start[cc + 1]):
                j = order[s]
                if j <= i:
                    continue
                d2 = 0.0
                for k in range(3):
                    d = position[j, k] - position[i, k]
                    if periodic[k]:
                        d -= box_length[k] * np.floor(d / box_length[k] + 0.5)
                    d2 += d * d
                reach = radius[i] + radius[j] + skin
                if d2 < reach * reach:
                    if fill:
                        out_j[row_start[i] + found] = j
                    found += 1
        if fill:
            # Pairs ordered by (i, j) whatever the cell order.
            sort_row(out_j, row_start[i], row_start[i] + found)
        else:
            row_start[i + 1] = found


def build_pairs(position, radius, skin, periodic, box_low, box_high):
    """Verlet list: (M,2) int64 pairs i < j with surface gap < skin (m), sorted by (i, j).

    position (N,3) m; radius (N,) m; periodic (3,) bool with box_low/box_high (3,) m.
    Periodic axes must be longer than twice the cut-off 2 r_max + skin (minimum image).
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
    row_start = np.zeros(n + 1, dtype=np.int64)
    dummy = np.zeros(0, dtype=np.int64)
    _pair_pass(position, radius, float(skin), low, width, counts, periodic, box_length,
               cell_start, order, row_start, dummy, False)
    np.cumsum(row_start, out=row_start)
    out_j = np.empty(row_start[-1], dtype=np.int64)
    _pair_pass(position, radius, float(skin), low, width, counts, periodic, box_length,
               cell_start, order, row_start, out_j, True)
    out_i = np.repeat(np.arange(n, dtype=np.int64), np.diff(row_start))
    return np.ascontiguousarray(np.column_stack([out_i, out_j]))


# Serial: a parallel reduction costs ~2 s of compilation on the first run and gains
# nothing measurable here (one memory-bound pass over the positions per step).
@numba.njit(cache=True, nogil=True)
def _max_displacement_sq(position, reference, box_length, periodic):
    worst = 0.0
    for p in range(position.shape[0]):
        d2 = 0.0
        for k in range(3):
            d = position[p, k] - reference[p, k]
            if periodic[k]:
                d -= box_length[k] * np.floor(d / box_length[k] + 0.5)
            d2 += d * d
        worst = max(worst, d2)
    return worst


def max_displacement(position, reference, box_length, periodic):
    """Largest distance (m) any particle moved from ``reference`` (minimum image)."""
    return float(np.sqrt(_max_displacement_sq(position, reference, box_length,
                                              np.asarray(periodic, dtype=np.bool_))))


def history_map(old_pairs, new_pairs, n_particles):
    """(new rows that were listed before, their old rows): the rows of ``new_pairs`` whose
    (i, j) key is also in ``old_pairs``, both sorted by key. One search serves every
    history array of a rebuild (``carry_history``)."""
    if old_pairs.shape[0] == 0 or new_pairs.shape[0] == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    old_key = old_pairs[:, 0] * np.int64(n_particles) + old_pairs[:, 1]
    new_key = new_pairs[:, 0] * np.int64(n_particles) + new_pairs[:, 1]
    where = np.minimum(np.searchsorted(old_key, new_key), old_key.shape[0] - 1)
    found = np.flatnonzero(old_key[where] == new_key)
    return found, where[found]


def carry_history(old_pairs, old_values, new_pairs, n_particles, mapping=None):
    """History values (e.g. tangential springs) of ``new_pairs`` taken from ``old_pairs``
    where the same (i, j) key was listed before, zero elsewhere. Pairs sorted by key;
    mapping: their ``history_map``, when several arrays are carried at once."""
    new_values = np.zeros((new_pairs.shape[0],) + old_values.shape[1:], dtype=old_values.dtype)
    new_rows, old_rows = (history_map(old_pairs, new_pairs, n_particles) if mapping is None
                          else mapping)
    if new_rows.size and old_values.shape[0]:
        new_values[new_rows] = old_values[old_rows]
    return new_values

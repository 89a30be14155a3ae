"""Spatially sorted particle order, for cache locality of the per-bond and per-particle loops.

A bond kernel reads both of its particles' positions and velocities; when bonded
particles sit close in memory those reads hit cache lines already loaded for neighbouring
bonds. Particles from a generator or a file come in arbitrary order, so the bench (and
any long run) renumbers them along a Morton (Z-order) curve over a cell grid, and sorts
the bonds by their first particle so that the bond loop walks memory forwards.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .model import INDEX


def _spread_bits(value):
    """Interleave the low 21 bits of ``value`` (uint64) with two zero bits each."""
    v = value.astype(np.uint64) & np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    v = (v | (v << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    v = (v | (v << np.uint64(2))) & np.uint64(0x1249249249249249)
    return v


def spatial_order(position, cell):
    """Permutation (N,) that sorts particles along a Morton curve of cubic cells.

    position: (N,3) m; cell: cell edge in m (about one particle diameter). Particles in
    the same cell keep their relative order (stable sort). Returns int64 indices: the
    particle at new index k is old particle ``order[k]``.
    """
    position = np.asarray(position, dtype=np.float64)
    if not (cell > 0.0 and np.isfinite(cell)):
        raise ValueError(f"spatial_order: cell = {cell!r}; must be a positive length in m")
    if position.shape[0] == 0:
        return np.zeros(0, dtype=INDEX)
    index = np.floor((position - position.min(axis=0)) / cell).astype(np.int64)
    # 21 bits per axis; a larger grid folds (still a valid, if less local, order).
    index &= 0x1FFFFF
    key = (_spread_bits(index[:, 0]) | (_spread_bits(index[:, 1]) << np.uint64(1))
           | (_spread_bits(index[:, 2]) << np.uint64(2)))
    return np.argsort(key, kind="stable").astype(INDEX)


def reorder_system(model, state, order):
    """Renumber particles by ``order`` (new k = old order[k]) and sort bonds by first particle.

    Returns new (model, state); the inputs are untouched. Each bond keeps its own pair
    orientation (i, j) and its history vectors, which are stored on particle i, so the
    physics is unchanged: only the numbering (and the order of sums) differs. The
    per-particle entries of ``state.extra`` (arrays with N rows) are permuted too; other
    extra arrays (contact lists) must be rebuilt by their law.
    """
    order = np.asarray(order, dtype=INDEX)
    n = model.n_particles
    if order.shape != (n,) or not np.array_equal(np.sort(order), np.arange(n)):
        raise ValueError(f"reorder_system: order must be a permutation of 0..{n - 1}")
    new_index = np.empty(n, dtype=INDEX)
    new_index[order] = np.arange(n, dtype=INDEX)
    pairs = new_index[model.bond_pairs]
    bond_order = np.lexsort((pairs[:, 1], np.minimum(pairs[:, 0], pairs[:, 1])))
    pairs = np.ascontiguousarray(pairs[bond_order])

    def particles(a):
        return np.ascontiguousarray(a[order])

    def bonds(a):
        return np.ascontiguousarray(a[bond_order])

    new_model = replace(
        model, radius=particles(model.radius), mass=particles(model.mass),
        inertia=particles(model.inertia), material=particles(model.material),
        fixed=particles(model.fixed), external_force=particles(model.external_force),
        external_moment=particles(model.external_moment), bond_pairs=pairs,
        bond_diameter=bonds(model.bond_diameter),
        bond_initial_length=bonds(model.bond_initial_length),
        bond_material=bonds(model.bond_material))
    if model.n_clumps:   # the clumps keep their numbers, their members move with them
        new_model = replace(new_model, clump_of=particles(model.clump_of),
                            clump_offset=particles(model.clump_offset))
    extra = {k: (particles(v) if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == n
                 else v) for k, v in state.extra.items()}
    new_state = replace(
        state, position=particles(state.position), velocity=particles(state.velocity),
        angular_velocity=particles(state.angular_velocity),
        bond_active=bonds(state.bond_active), bond_axis=bonds(state.bond_axis),
        bond_tangential_force=bonds(state.bond_tangential_force),
        bond_normal_moment=bonds(state.bond_normal_moment),
        bond_tangential_moment=bonds(state.bond_tangential_moment),
        bond_break_time=bonds(state.bond_break_time),
        bond_break_mode=bonds(state.bond_break_mode),
        bond_break_energy=bonds(state.bond_break_energy), extra=extra,
        bond_previous_length=(None if state.bond_previous_length is None
                              else bonds(state.bond_previous_length)))
    return new_model, new_state

"""CPU backend: Numba loops over bonds and particles calling the physics functions.

Deterministic sums: each bond writes its loads to its own slot, then each particle sums
its bonds through a fixed CSR index (particle -> bond ends). No atomics, and the same bits
whatever the number of threads, which is what makes a resumed run bit-identical.
"""
import contextlib

import numba
import numpy as np
from numba import prange

from ..physics import bond_models, compile_physics, field_models
from ..status import STATUS_OK
from ..physics.bond_elastic import CRITERION_NONE
from ..physics.rotation import SMALL_ANGLE
from . import loops, raw
from .raw import get, get2, get3, prefetch, put, put3

# No fastmath, not even FMA contraction ({"contract"}: 10 % faster bond kernel): it moves
# the rounding of L = |r|, and L - L0 amplifies that to 3e-12 relative in F_n, above the
# 1e-12 of the MUSEN transcription check (validation/rotation.py).
# The loop bodies (backends/loops.py) are inlined into serial loops over chunks of items,
# which the kernels run in parallel (``chunks``; see loops.py why); the cache stamp of
# these kernels covers the physics and loops.py (_kernel_cache).
L = loops.compile_loops(numba.njit(cache=False, inline="always"), numba.njit(cache=False),
                       given=raw.ROWS)
advance_bond = L.advance_bond
bond_ends_sum = L.bond_ends_sum
integrate_particle = L.integrate_particle
integrate_clump = L.integrate_clump
bond_energy = L.bond_energy
minimum_image = L.minimum_image
row3 = L.row3
# The compiled physics, for callers that use one law directly (validation/rotation.py).
elastic_bond = L.elastic_bond
bond_stiffnesses = L.bond_stiffnesses
bond_loads_on_particles = L.bond_loads_on_particles
store3 = L.store3
add = L.add
field_force = L.field_force

# The same physics for the vectorised bond loop (``advance_bond_block``): inlined into the
# loop, without the twist's libm branch (bonds with a large twist are redone by the scalar
# path), and without zero-division checks (a zero-length bond gives NaN, which
# ``integrate`` reports), so that LLVM can turn the loop into AVX code.
V = compile_physics(numba.njit(cache=False, inline="always", error_model="numpy"),
                    substitute={"twist_sincos": "twist_sincos_series"})
elastic_bond_inline = V.elastic_bond
bond_stiffnesses_inline = V.bond_stiffnesses
bond_loads_on_particles_inline = V.bond_loads_on_particles
bond_surely_intact_inline = V.bond_surely_intact
bond_breaks_inline = V.bond_breaks


_jit = dict(parallel=True, cache=True, fastmath=False, nogil=True)
# The serial loops run without Numba's reference counting (_nrt=False; they allocate
# nothing): the bodies inlined into them read their arrays from named tuples, and each
# read was an atomic increment and decrement of the array's count per item, ~20 per
# contact row. Two threads sharing those counts bounced their cache lines: an apart
# contact row cost 66 ns with the counts, 9 ns without.
_serial = dict(cache=True, fastmath=False, nogil=True, error_model="numpy", _nrt=False)

# Items per chunk of a parallel loop. Each chunk is one call of a serial loop with the
# body inlined: a body inlined into the prange itself would read its arrays from named
# tuples inside the parallel region, where this Numba (0.68) drops their stores, and a
# body called per item pays a reference count round trip per array per item (integrate:
# 2.5x slower). 256 particles or bonds: the call is ~1 % of the chunk's time.
CHUNK = 256


@numba.njit(cache=True)
def chunks(n):
    """Number of CHUNKs covering n items."""
    return (n + CHUNK - 1) // CHUNK


@numba.njit(cache=True, nogil=True)
def balanced_shares(work, parts):
    """Boundaries (parts + 1,) that cut chunks 0..len(work)-1 into ``parts`` contiguous
    runs of about equal summed ``work`` (any unit, >= 0), one run per thread.

    Numba gives each thread of a ``prange`` one contiguous share of equal length, and the
    costly chunks of a scene are often side by side: the touching contacts at the bottom
    of a settling bed, the bonds that break where an agglomerate hits a wall. In a 10^5
    bed one thread got 78 % of the touching rows. Cutting by last step's work keeps the
    shares contiguous (each thread streams its rows in order) and even."""
    m = work.shape[0]
    bounds = np.empty(parts + 1, dtype=np.int64)
    bounds[0] = 0
    total = 0.0
    for c in range(m):
        total += work[c]
    if total <= 0.0:      # nothing measured: even lengths
        for t in range(1, parts + 1):
            bounds[t] = m * t // parts
        return bounds
    done = 0.0
    c = 0
    for t in range(1, parts):
        target = total * t / parts
        while c < m and done + 0.5 * work[c] < target:
            done += work[c]
            c += 1
        bounds[t] = c
    bounds[parts] = m
    return bounds


# Below this many particles + bonds a step costs less than waking and joining the
# worker threads of three parallel loops (tens of microseconds), so it runs on one.
SERIAL_BELOW = 2048


# Bonds per block of the vectorised kernel, and the rows of a thread's scratch: the
# block's inputs, gathered from the particle and bond arrays, then its results. 64: the
# n = 47 lattice's kernel 0.87-1.02 (median 0.945) of its time with 32, the impact under
# way 0.985 (once the gather shrank, docs/performance.md, twelfth round; 128 no better).
BOND_BLOCK = 64
(_R, _VI, _VJ, _WI, _WJ, _AXIS, _FT0, _MN0, _MT0) = range(0, 27, 3)
(_L0, _DIAMETER, _YOUNG, _POISSON, _NORMAL_STRENGTH, _TANGENTIAL_STRENGTH,
 _CRITERION) = range(27, 34)
(_N, _FT, _MN, _MT, _FORCE_I, _MOMENT_I, _MOMENT_J) = range(34, 55, 3)
_LENGTH, _SLOW = 55, 56
SCRATCH_ROWS = 57
# The marks of ``elastic_bonds``' slow (per bond): SLOW, left to the scalar path this
# step; ZEROED, broken with its loads zeroed (so not visited again); else 0.
SLOW, ZEROED = 1, 2


@numba.njit(cache=True, error_model="numpy")
def advance_bond_block(s, count, dt):
    """Advance the ``count`` bonds gathered in scratch ``s`` by dt (s), without branches.

    Reads the input rows, writes the result rows; row _SLOW is 2 where the twist may be
    too large for the series (redo with ``elastic_bond``), 1 where the bond may break
    (``settle_block_breaks`` tests it exactly), else 0. Returns how many are 1.
    """
    B = BOND_BLOCK
    small_angle_sq = SMALL_ANGLE * SMALL_ANGLE
    flagged = 0
    for q in range(count):
        r = (s[(_R + 0) * B + q], s[(_R + 1) * B + q], s[(_R + 2) * B + q])
        vi = (s[(_VI + 0) * B + q], s[(_VI + 1) * B + q], s[(_VI + 2) * B + q])
        vj = (s[(_VJ + 0) * B + q], s[(_VJ + 1) * B + q], s[(_VJ + 2) * B + q])
        wi = (s[(_WI + 0) * B + q], s[(_WI + 1) * B + q], s[(_WI + 2) * B + q])
        wj = (s[(_WJ + 0) * B + q], s[(_WJ + 1) * B + q], s[(_WJ + 2) * B + q])
        axis = (s[(_AXIS + 0) * B + q], s[(_AXIS + 1) * B + q], s[(_AXIS + 2) * B + q])
        f_t0 = (s[(_FT0 + 0) * B + q], s[(_FT0 + 1) * B + q], s[(_FT0 + 2) * B + q])
        m_n0 = (s[(_MN0 + 0) * B + q], s[(_MN0 + 1) * B + q], s[(_MN0 + 2) * B + q])
        m_t0 = (s[(_MT0 + 0) * B + q], s[(_MT0 + 1) * B + q], s[(_MT0 + 2) * B + q])
        initial_length = s[_L0 * B + q]
        diameter = s[_DIAMETER * B + q]
        kn, kt, ktw, kb = bond_stiffnesses_inline(s[_YOUNG * B + q],
                                                  s[_POISSON * B + q], diameter,
                                                  initial_length)
        length, n, f_n, f_t, m_n, m_t = elastic_bond_inline(
            r, vi, vj, wi, wj, axis, f_t0, m_n0, m_t0, initial_length, kn, kt, ktw, kb, dt)
        force_i, moment_i, moment_j = bond_loads_on_particles_inline(r, f_n, f_t, m_n, m_t)
        # |twist angle| = |(w_i + w_j) . n| dt / 2 <= |w_i + w_j| dt / 2.
        w_sum = (wi[0] + wj[0], wi[1] + wj[1], wi[2] + wj[2])
        large_twist = 0.25 * dt * dt * (w_sum[0] * w_sum[0] + w_sum[1] * w_sum[1]
                                        + w_sum[2] * w_sum[2]) >= small_angle_sq
        criterion = s[_CRITERION * B + q]
        surely_intact = bond_surely_intact_inline(
            f_n, f_t, m_n, m_t, diameter, s[_NORMAL_STRENGTH * B + q],
            s[_TANGENTIAL_STRENGTH * B + q], criterion)
        may_break = (criterion != CRITERION_NONE) & (not surely_intact)
        s[_LENGTH * B + q] = length
        s[_SLOW * B + q] = 2.0 if large_twist else (1.0 if may_break else 0.0)
        flagged += may_break & (not large_twist)
        s[(_N + 0) * B + q], s[(_N + 1) * B + q], s[(_N + 2) * B + q] = n
        s[(_FT + 0) * B + q], s[(_FT + 1) * B + q], s[(_FT + 2) * B + q] = f_t
        s[(_MN + 0) * B + q], s[(_MN + 1) * B + q], s[(_MN + 2) * B + q] = m_n
        s[(_MT + 0) * B + q], s[(_MT + 1) * B + q], s[(_MT + 2) * B + q] = m_t
        (s[(_FORCE_I + 0) * B + q], s[(_FORCE_I + 1) * B + q],
         s[(_FORCE_I + 2) * B + q]) = force_i
        (s[(_MOMENT_I + 0) * B + q], s[(_MOMENT_I + 1) * B + q],
         s[(_MOMENT_I + 2) * B + q]) = moment_i
        (s[(_MOMENT_J + 0) * B + q], s[(_MOMENT_J + 1) * B + q],
         s[(_MOMENT_J + 2) * B + q]) = moment_j
    return flagged


@numba.njit(inline="always")
def slot_bond(q, start, dense, at):
    """The bond in slot q of the block from bond ``start``: start + q in a block of intact
    bonds (``dense``), else at[q]."""
    return start + q if dense else at[q]


@numba.njit(**_serial)
def settle_block_breaks(s, count, dt, start, dense, at, material, compressive_breakage):
    """The exact break test (``bond_breaks``) of the bonds that ``advance_bond_block``
    marked 1 in row _SLOW (not surely intact): their row becomes 0 if intact, so only the
    bonds that break, or twist too far (2), are left to the scalar path. Each is advanced
    again by ``elastic_bond`` from its gathered inputs (no memory read; the same bits as
    the block), for the normal force the block does not keep. start, dense, at: the
    block's slots (``slot_bond``); material (B,), compressive_breakage (materials,) as in
    ``loops.Bonds``, ``loops.BondMaterials``.

    Under way in the 10^5 impact 2.6 % of the bonds carry more than half their strength,
    and each cost ~370 ns on the scalar path (a sixth of the bond kernel)."""
    B = BOND_BLOCK
    for q in range(count):
        if s[_SLOW * B + q] != 1.0:
            continue
        initial_length = s[_L0 * B + q]
        diameter = s[_DIAMETER * B + q]
        kn, kt, ktw, kb = bond_stiffnesses_inline(s[_YOUNG * B + q], s[_POISSON * B + q],
                                                  diameter, initial_length)
        length, n, f_n, f_t, m_n, m_t = elastic_bond_inline(
            (s[(_R + 0) * B + q], s[(_R + 1) * B + q], s[(_R + 2) * B + q]),
            (s[(_VI + 0) * B + q], s[(_VI + 1) * B + q], s[(_VI + 2) * B + q]),
            (s[(_VJ + 0) * B + q], s[(_VJ + 1) * B + q], s[(_VJ + 2) * B + q]),
            (s[(_WI + 0) * B + q], s[(_WI + 1) * B + q], s[(_WI + 2) * B + q]),
            (s[(_WJ + 0) * B + q], s[(_WJ + 1) * B + q], s[(_WJ + 2) * B + q]),
            (s[(_AXIS + 0) * B + q], s[(_AXIS + 1) * B + q], s[(_AXIS + 2) * B + q]),
            (s[(_FT0 + 0) * B + q], s[(_FT0 + 1) * B + q], s[(_FT0 + 2) * B + q]),
            (s[(_MN0 + 0) * B + q], s[(_MN0 + 1) * B + q], s[(_MN0 + 2) * B + q]),
            (s[(_MT0 + 0) * B + q], s[(_MT0 + 1) * B + q], s[(_MT0 + 2) * B + q]),
            initial_length, kn, kt, ktw, kb, dt)
        breaks = bond_breaks_inline(
            length, initial_length, f_n, f_t, m_n, m_t, diameter,
            s[_NORMAL_STRENGTH * B + q], s[_TANGENTIAL_STRENGTH * B + q],
            s[_CRITERION * B + q],
            compressive_breakage[material[slot_bond(q, start, dense, at)]])
        s[_SLOW * B + q] = 1.0 if breaks else 0.0


@numba.njit(**_serial)
def advance_bonds(first, last, bonds, materials, state, particles, box, time, dt, musen,
                  loads):
    """``loops.advance_bond`` for bonds first to last - 1."""
    for b in range(first, last):
        advance_bond(b, bonds, materials, state, particles, box, time, dt, musen, loads)


@numba.njit(**_serial)
def advance_slow_bonds(first, last, slow, bonds, materials, state, particles, box, time,
                       dt, musen, loads):
    """``loops.advance_bond`` for the bonds first to last - 1 marked SLOW in ``slow``."""
    for b in range(first, last):
        if slow[b] == SLOW:
            advance_bond(b, bonds, materials, state, particles, box, time, dt, musen, loads)


@numba.njit(**_jit)
def elastic_bonds(bonds, materials, state, particles, box, time, dt, musen, vectorised,
                  uniform, scratch, slots, slow, pending, loads):
    """Advance every intact bond by one increment dt (s) at ``time`` (s) and store its
    loads in its own row of ``loads`` (``loops.advance_bond``, the named tuples of
    ``loops``).

    With ``vectorised`` True, the intact bonds of each BOND_BLOCK of bonds are gathered
    into the thread's scratch, advanced by the branch-free ``advance_bond_block``,
    scattered back; a bond it marks slow (large twist, possible break) is redone by
    ``advance_bond``. A broken bond is neither read nor written: its loads were zeroed
    when it broke, or are zeroed once (marked ZEROED) when found broken. Both paths give
    the same bits (tests/test_bond_blocked.py), the vectorised one 1.3-1.9x faster
    (docs/performance.md). vectorised None: every bond by ``advance_bond`` (None, not
    False: Numba prunes the block code by type, so small systems never compile it).
    musen: True for MUSEN's numerics, None for the SPEC's (None: a SPEC run never
    compiles MUSEN's law, ~1.2 s). uniform: True where every bond has the same material
    and strength factor (the vectorised path then writes their constants into the scratch
    once, not per bond), else None. scratch: (NUMBA_NUM_THREADS, SCRATCH_ROWS * BOND_BLOCK)
    float64 and slots (NUMBA_NUM_THREADS, BOND_BLOCK) int64, one row set per thread,
    owned by one simulation; slow (B,) uint8: SLOW for the bonds the vectorised path left
    to ``advance_bond``, ZEROED for broken bonds whose loads it zeroed, else 0; pending
    (NUMBA_NUM_THREADS,) int64: how many bonds each thread marked SLOW.
    """
    n_bonds = bonds.pairs.shape[0]
    if vectorised is None:
        for c in prange(chunks(n_bonds)):
            advance_bonds(c * CHUNK, min(n_bonds, (c + 1) * CHUNK), bonds, materials, state,
                          particles, box, time, dt, musen, loads)
        return
    # The arrays are taken out of the named tuples before the prange: this Numba (0.68)
    # drops a store into ``t.a[i]`` written inside a parallel loop body.
    pairs, material, initial_length, diameter = (bonds.pairs, bonds.material,
                                                 bonds.initial_length, bonds.diameter)
    strength = bonds.strength
    position, velocity, angular_velocity = particles
    active, axis, previous_length = state.active, state.axis, state.previous_length
    tangential_force, normal_moment = state.tangential_force, state.normal_moment
    tangential_moment = state.tangential_moment
    force_i, moment_i, moment_j = loads
    young, poisson = materials.young_modulus, materials.poisson_ratio
    normal_strength = materials.normal_strength
    tangential_strength = materials.tangential_strength
    criterion = materials.breakage
    compressive = materials.compressive_breakage
    # the box as scalars: read from its arrays per bond, LLVM could not keep them (the
    # scratch stores might alias them)
    length_x, length_y, length_z = box.length[0], box.length[1], box.length[2]
    periodic_x, periodic_y, periodic_z = box.periodic[0], box.periodic[1], box.periodic[2]
    # get3 and put3 take rows of three (the state's arrays are made so)
    for rows in (position, velocity, angular_velocity, axis, tangential_force, normal_moment,
                 tangential_moment, force_i, moment_i, moment_j):
        if rows.shape[1] != 3:
            raise ValueError("elastic_bonds: vector arrays need 3 columns")
    B = BOND_BLOCK
    pending[:] = 0
    if uniform is not None and n_bonds > 0:
        # one material, one strength factor: the same constants for every bond, written
        # into each thread's scratch here, not per bond by the gather (~13 fewer loads and
        # stores per bond, and the material and strength arrays not read)
        m0 = material[0]
        constants = ((_YOUNG, young[m0]), (_POISSON, poisson[m0]),
                     (_NORMAL_STRENGTH, normal_strength[m0] * strength[0]),
                     (_TANGENTIAL_STRENGTH, tangential_strength[m0] * strength[0]),
                     (_CRITERION, float(criterion[m0])))
        for t in range(scratch.shape[0]):
            for row, value in constants:
                for q in range(B):
                    scratch[t, row * B + q] = value
    for block in prange((n_bonds + B - 1) // B):
        thread = numba.get_thread_id()
        s = scratch[thread]
        at = slots[thread]
        start = block * B
        # The next block's far ends, whose rows lie anywhere (the near ends follow the
        # bond order): fetched while this block runs, the kernel of the n = 47 lattice
        # took ~0.91x the time (docs/performance.md, ninth round).
        for b in range(start + B, min(n_bonds, start + 2 * B)):
            far = pairs[b, 1]
            prefetch(position, far)
            prefetch(velocity, far)
            prefetch(angular_velocity, far)
        # Only the intact bonds are gathered: under way in the 10^5 impact a third of
        # the bonds are broken, and each cost a full gather, block and scatter.
        end = min(n_bonds, start + B)
        count = 0
        for b in range(start, end):
            count += active[b]
        # a block of intact bonds (all of them at the start) reads its bonds in order,
        # not through the slots, whose indirection measured a few per cent slower there
        dense = count == end - start
        if not dense:
            count = 0
            for b in range(start, end):
                at[count] = b
                count += 1 if active[b] else 0
            for b in range(start, end):
                if not active[b] and slow[b] != ZEROED:
                    for k in range(3):
                        force_i[b, k] = 0.0
                        moment_i[b, k] = 0.0
                        moment_j[b, k] = 0.0
                    slow[b] = ZEROED
        # The gather and the scatter are most of the kernel's instructions: they address
        # the arrays directly (``raw``; 0.85-0.88 of the kernel's time at n = 47, against
        # checked indexing)
        for q in range(count):
            b = slot_bond(q, start, dense, at)
            i = get2(pairs, b, 0)
            j = get2(pairs, b, 1)
            r = minimum_image((get3(position, j, 0) - get3(position, i, 0),
                               get3(position, j, 1) - get3(position, i, 1),
                               get3(position, j, 2) - get3(position, i, 2)),
                              (length_x, length_y, length_z),
                              periodic_x, periodic_y, periodic_z)
            for k in range(3):
                put(s, (_R + k) * B + q, r[k])
                put(s, (_VI + k) * B + q, get3(velocity, i, k))
                put(s, (_VJ + k) * B + q, get3(velocity, j, k))
                put(s, (_WI + k) * B + q, get3(angular_velocity, i, k))
                put(s, (_WJ + k) * B + q, get3(angular_velocity, j, k))
                put(s, (_AXIS + k) * B + q, get3(axis, b, k))
                put(s, (_FT0 + k) * B + q, get3(tangential_force, b, k))
                put(s, (_MN0 + k) * B + q, get3(normal_moment, b, k))
                put(s, (_MT0 + k) * B + q, get3(tangential_moment, b, k))
            put(s, _L0 * B + q, get(initial_length, b))
            put(s, _DIAMETER * B + q, get(diameter, b))
            if uniform is None:
                m = get(material, b)
                put(s, _YOUNG * B + q, get(young, m))
                put(s, _POISSON * B + q, get(poisson, m))
                put(s, _NORMAL_STRENGTH * B + q, get(normal_strength, m) * get(strength, b))
                put(s, _TANGENTIAL_STRENGTH * B + q,
                    get(tangential_strength, m) * get(strength, b))
                put(s, _CRITERION * B + q, get(criterion, m))
        if count == 0:
            continue
        if advance_bond_block(s, count, dt):
            settle_block_breaks(s, count, dt, start, dense, at, material, compressive)
        for q in range(count):
            b = slot_bond(q, start, dense, at)
            if get(s, _SLOW * B + q) != 0.0:
                put(slow, b, SLOW)
                pending[thread] += 1
                continue
            put(slow, b, 0)
            put(previous_length, b, get(s, _LENGTH * B + q))
            for k in range(3):
                put3(axis, b, k, get(s, (_N + k) * B + q))
                put3(tangential_force, b, k, get(s, (_FT + k) * B + q))
                put3(normal_moment, b, k, get(s, (_MN + k) * B + q))
                put3(tangential_moment, b, k, get(s, (_MT + k) * B + q))
                put3(force_i, b, k, get(s, (_FORCE_I + k) * B + q))
                put3(moment_i, b, k, get(s, (_MOMENT_I + k) * B + q))
                put3(moment_j, b, k, get(s, (_MOMENT_J + k) * B + q))
    # The slow bonds in a second pass, so that the first loop takes plain arrays only: with
    # the named tuples passed on inside it, the bond kernel measured 1.5-4 % slower. None
    # marked (most steps of an intact solid): no pass (~0.1 ms at 3 10^5 bonds).
    if pending.sum() == 0:
        return
    for c in prange(chunks(n_bonds)):
        advance_slow_bonds(c * CHUNK, min(n_bonds, (c + 1) * CHUNK), slow, bonds, materials,
                           state, particles, box, time, dt, musen, loads)


@numba.njit(**_serial)
def gather_bond_range(first, last, index, loads, force, moment, assign):
    """The bond loads of particles first to last - 1 (``loops.bond_ends_sum``), stored
    (``assign``) or added to force and moment."""
    for p in range(first, last):
        if assign:
            f, m = bond_ends_sum(p, index, loads, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        else:
            f, m = bond_ends_sum(p, index, loads, row3(force, p), row3(moment, p))
        store3(force, p, f)
        store3(moment, p, m)


@numba.njit(**_jit)
def gather_bond_loads(index, loads, force, moment, assign=False):
    """Each particle's bond loads stored in (``assign``: the same bits as adding them to
    zeroed arrays) or added to force (N), moment (N m)."""
    n = index.offsets.shape[0] - 1
    for c in prange(chunks(n)):
        gather_bond_range(c * CHUNK, min(n, (c + 1) * CHUNK), index, loads, force, moment,
                          assign)


@numba.njit(**_serial)
def integrate_range(first, last, particles, bodies, force, moment, fields, damping,
                    kick_dt, drift_dt, box, track_energy):
    """``loops.integrate_particle`` for particles first to last - 1; returns (their work
    and damping loss in J, summed in particle order, and the status of the last one
    that blew up, STATUS_OK if none)."""
    status = STATUS_OK
    gained = 0.0
    removed = 0.0
    for p in range(first, last):
        work, lost, code = integrate_particle(p, row3(force, p), row3(moment, p), particles,
                                              bodies, fields, damping, kick_dt,
                                              drift_dt, box, track_energy)
        if track_energy or work != 0.0 or lost != 0.0:
            gained += work
            removed += lost
        if code != STATUS_OK:
            status = code
    return gained, removed, status


@numba.njit(**_jit)
def integrate(particles, bodies, force, moment, fields, damping, kick_dt, drift_dt, box,
              status, track_energy, energy):
    """``loops.integrate_particle`` for every particle with its loads force (N), moment
    (N m) and the body-force ``fields`` (``loops.Fields``: gravity, the fluid, the
    rotating frame). Sets status[0] when a
    particle blows up. energy (chunks(N), 2) receives each chunk's (work of gravity, the
    fluid and external loads, energy removed by damping) in J over this kick, summed over
    its particles in order: all of it if track_energy, else the external loads' work
    alone (0 where there are none)."""
    # Energies go to per-chunk slots, summed by the caller in a fixed order: a scalar
    # "+=" here would be a prange reduction, whose sum depends on the thread count (and
    # which numba 0.68 silently dropped, returning 0, inside this nested loop). Slots per
    # particle cost a pass of their own to sum (0.33 ms for 10^5 particles).
    n = particles.position.shape[0]
    for c in prange(chunks(n)):
        gained, removed, code = integrate_range(
            c * CHUNK, min(n, (c + 1) * CHUNK), particles, bodies, force, moment, fields,
            damping, kick_dt, drift_dt, box, track_energy)
        energy[c, 0] = gained
        energy[c, 1] = removed
        if code != STATUS_OK:
            status[0] = code


@numba.njit(**_serial)
def integrate_clump_range(first, last, force, moment, clumps, clump_state, particles,
                          bodies, fields, damping, kick_dt, drift_dt, box, track_energy,
                          energy):
    """``loops.integrate_clump`` for clumps first to last - 1; returns the status of the
    last one that blew up (STATUS_OK if none)."""
    status = STATUS_OK
    for c in range(first, last):
        work, lost, code = integrate_clump(c, force, moment, clumps, clump_state, particles,
                                           bodies, fields, damping, kick_dt, drift_dt, box,
                                           track_energy)
        energy[c, 0] = work
        energy[c, 1] = lost
        if code != STATUS_OK:
            status = code
    return status


@numba.njit(**_jit)
def integrate_clumps(force, moment, clumps, clump_state, particles, bodies, fields, damping,
                     kick_dt, drift_dt, box, status, track_energy, energy):
    """``loops.integrate_clump`` for every clump, after ``integrate`` (which leaves the
    members alone): their loads force (N), moment (N m) move the clumps, which then place
    their members. Sets status[0] when a clump blows up; energy (C,2) as ``integrate``'s."""
    n = clump_state.position.shape[0]
    for c in prange(chunks(n)):
        code = integrate_clump_range(c * CHUNK, min(n, (c + 1) * CHUNK), force, moment,
                                     clumps, clump_state, particles, bodies, fields, damping,
                                     kick_dt, drift_dt, box, track_energy, energy)
        if code != STATUS_OK:
            status[0] = code


@numba.njit(**_serial)
def field_forces(position, velocity, radius, mass, fixed, fields, out):
    """out[p] = the field models' force on particle p (N; loops.field_force, as
    loops.integrate_particle adds it), zero for fixed particles."""
    for p in range(position.shape[0]):
        if fixed[p]:
            store3(out, p, (0.0, 0.0, 0.0))
            continue
        store3(out, p, field_force(fields, p, mass[p], radius[p], row3(position, p),
                                   row3(velocity, p)))


def field_force_array(model, state):
    """(N,3) N: the fields' force on each particle in ``state`` (``field_forces``)."""
    out = np.zeros((model.n_particles, 3))
    field_forces(state.position, state.velocity, model.radius, model.mass, model.fixed,
                 fields(model), out)
    return out


@numba.njit(cache=True, nogil=True)
def column_sums(a):
    """Sum of each column of a (N,K) array, row after row: numpy's ``a.sum(axis=0)`` to
    the bit (which adds this layout's rows in order too), without its per-row overhead
    (0.15 ms for the 10^4 x 2 energies, a tenth of a contact bed's step; here 0.01)."""
    out = np.zeros(a.shape[1])
    for p in range(a.shape[0]):
        for k in range(a.shape[1]):
            out[k] += a[p, k]
    return out


@numba.njit(**_serial)
def _bond_energy_range(first, last, bonds, materials, state, position, box, out):
    for b in range(first, last):
        out[b] = bond_energy(b, bonds, materials, state, position, box)


# Parallel: a frame asks once, but the lab's kinetic-energy ratio asks at every sample (a
# fifth of a 1680-particle UCS test's time when serial). Each bond writes its own item.
@numba.njit(**_jit)
def bond_energies(bonds, materials, state, position, box, out):
    """Elastic energy (J) stored in each bond (``loops.bond_energy``); 0 for broken bonds."""
    n_bonds = bonds.pairs.shape[0]
    for c in prange(chunks(n_bonds)):
        _bond_energy_range(c * CHUNK, min(n_bonds, (c + 1) * CHUNK), bonds, materials,
                           state, position, box, out)


def particle_bond_index(pairs, n_particles):
    """CSR index particle -> bond ends: (offsets (N+1,), ends (2B,) = 2*bond + side)."""
    n_bonds = pairs.shape[0]
    particle = pairs.reshape(-1)  # [i0, j0, i1, j1, ...] so entry k is end k = 2*bond + side
    order = np.argsort(particle, kind="stable")
    counts = np.bincount(particle, minlength=n_particles)
    offsets = np.zeros(n_particles + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    assert order.shape[0] == 2 * n_bonds
    return offsets, order.astype(np.int64)


@numba.njit(cache=True, nogil=True)
def intact_ends(offsets, ends, active):
    """The particle -> bond end index (``particle_bond_index``) without the ends of the
    bonds not ``active``, each particle's ends in the same order: (offsets, ends)."""
    n = offsets.shape[0] - 1
    kept_offsets = np.zeros(n + 1, dtype=np.int64)
    kept = np.empty(ends.shape[0], dtype=np.int64)
    k = 0
    for p in range(n):
        for e in range(offsets[p], offsets[p + 1]):
            if active[ends[e] >> 1]:
                kept[k] = ends[e]
                k += 1
        kept_offsets[p + 1] = k
    return kept_offsets, kept[:k].copy()


@numba.njit(cache=True, nogil=True)
def _index_check(active, indexed):
    """(intact bonds, whether one of them is not in ``indexed``)."""
    count = 0
    missing = False
    for b in range(active.shape[0]):
        count += active[b]
        missing |= active[b] and not indexed[b]
    return count, missing


def bond_tuples(model, put=lambda a: a):
    """(Bonds, BondMaterials, BondIndex) of ``model`` (``loops``); ``put`` places each
    array (the CUDA backend passes cuda.to_device)."""
    table = model.bond_material_table()
    bonds = loops.Bonds(put(model.bond_pairs), put(model.bond_diameter),
                        put(model.bond_initial_length), put(model.bond_material),
                        put(model.bond_strength_factors()))
    materials = loops.BondMaterials(*(put(table[k]) for k in loops.BondMaterials._fields))
    offsets, ends = particle_bond_index(model.bond_pairs, model.n_particles)
    return bonds, materials, loops.BondIndex(put(offsets), put(ends))


def bond_state(state, model_state):
    """The bond arrays of ``state`` (a State or a DeviceState) and ``model_state`` (the bond
    models' per-bond state, or one unused row) as a ``loops.BondState``."""
    return loops.BondState(state.bond_active, state.bond_axis, state.bond_previous_length,
                           state.bond_tangential_force, state.bond_normal_moment,
                           state.bond_tangential_moment, state.bond_break_time,
                           state.bond_break_mode, state.bond_break_energy, model_state)


def has_model_state(model):
    """True when a bond of ``model`` uses a bond model with a per-bond state (STATE or
    SPRINGS)."""
    return bool(model.n_bonds) and any(bond_models.has_state(m)
                                       for m in model.bond_models_used())


def particles(state):
    """Position, velocity, angular velocity of ``state`` as a ``loops.Particles``."""
    return loops.Particles(state.position, state.velocity, state.angular_velocity)


def box(model, put=lambda a: a):
    """The model's domain as a ``loops.Box`` (low, high, length in m; periodic flags)."""
    return loops.Box(put(model.box_low), put(model.box_high), put(model.box_length),
                     put(model.periodic))


def fields(model, put=lambda a: a):
    """The model's body-force fields as a ``loops.Fields``: gravity, the models'
    switches (field_models.switches), each field model's parameter array (Model.fields),
    their INPUTS (Model attributes, as gravity)."""
    def value(name):
        if name == "acting":
            return field_models.switches(model.fields)
        return model.fields[name] if name in model.fields else getattr(model, name)
    return loops.Fields(*(put(value(name)) for name in loops.Fields._fields))


def bodies(model, put=lambda a: a):
    """The model's per-particle constants as a ``loops.Bodies`` (kg, kg m^2, N, N m)."""
    return loops.Bodies(put(model.mass), put(model.inertia), put(model.integrated()),
                        put(model.external_force), put(model.external_moment),
                        put(model.radius))


def clumps(model, put=lambda a: a):
    """The model's clumps as a ``loops.Clumps`` (one unused row when there are none)."""
    offsets, members = model.clump_members()
    offset = model.clump_offset if model.n_clumps else np.zeros((1, 3))
    fixed = model.fixed[members[offsets[:-1]]] if model.n_clumps else np.zeros(1, bool)
    return loops.Clumps(put(offsets), put(members if members.size else np.zeros(1, np.int64)),
                        put(np.ascontiguousarray(offset)), put(model.clump_mass),
                        put(model.clump_inertia), put(np.ascontiguousarray(fixed)))


def clump_state(state):
    """The state's clump arrays as a ``loops.ClumpState`` (views, updated in place)."""
    return loops.ClumpState(state.clump_position, state.clump_orientation,
                            state.clump_velocity, state.clump_angular_momentum)


class ElasticBonds:
    """The elastic bond law over all bonds of a model, on the CPU.

    Holds the bond-material tables, the particle -> bond CSR index and per-bond scratch;
    ``accumulate`` advances the bonds by one increment and adds their loads.
    """

    name = "elastic_bond"
    # True: MUSEN's numerics (bond_elastic_musen), set by Simulation(musen_compat=True).
    musen_compat = False
    # False: every bond by the scalar path (the reference the vectorised one is tested to).
    vectorised = True
    # Bonds from which the vectorised path runs. Its gain, ~30 ns per bond and step, pays
    # for its compilation on a first run (~2 s) after 16,000 steps at this size, while the
    # 1812-bond demo's 866 steps would save 0.05 s. Both paths give the same bits, so this
    # changes the speed only.
    vectorise_from = 4096

    def __init__(self, model):
        self._bonds, self._materials, self._index = bond_tuples(model)
        # The gather's index lists the ends of the bonds intact when it was made
        # (``_index_intact``): a broken bond's loads are zero, so leaving it out changes
        # no sum, and saves reading its loads each step (a third of the bonds are broken
        # under way in the 10^5 impact).
        self._all_ends = self._index
        self._indexed = np.ones(model.n_bonds, dtype=np.bool_)
        self._indexed_count = model.n_bonds
        self._box = box(model)
        # True: a bond model with a per-bond state (state.extra["bond_model_state"]) is used.
        self.model_state = has_model_state(model)
        # The vectorised block has the elastic bond only.
        self._vectorisable = all(m.VECTORISED for m in model.bond_models_used())
        self._no_model_state = np.zeros((1, bond_models.STATE_COLUMNS))
        # one material and one strength factor for all bonds (``elastic_bonds``' uniform)
        self._uniform = bool(model.n_bonds and np.all(self._bonds.material
                                                      == self._bonds.material[0])
                             and np.all(self._bonds.strength == self._bonds.strength[0]))
        n_bonds = model.n_bonds
        self.loads = loops.BondLoads(np.zeros((n_bonds, 3)), np.zeros((n_bonds, 3)),
                                     np.zeros((n_bonds, 3)))
        self.force_i, self.moment_i, self.moment_j = self.loads
        # One scratch row per Numba thread (get_thread_id < NUMBA_NUM_THREADS).
        self._scratch = np.zeros((numba.config.NUMBA_NUM_THREADS,
                                  SCRATCH_ROWS * BOND_BLOCK))
        self._slots = np.zeros((numba.config.NUMBA_NUM_THREADS, BOND_BLOCK), dtype=np.int64)
        self._slow = np.zeros(n_bonds, dtype=np.uint8)
        self._pending = np.zeros(numba.config.NUMBA_NUM_THREADS, dtype=np.int64)

    def accumulate(self, model, state, force, moment, increment_dt):
        """Advance the bonds by ``increment_dt`` (s); add loads to force (N), moment (N m)."""
        if model.n_bonds == 0:
            return
        self.compute(model, state, increment_dt)
        self.gather(force, moment)

    def acts(self, model):
        """False for a model without bonds: this law adds no load, and the step leaves it
        out so that the next law may store its loads (``assign``)."""
        return model.n_bonds > 0

    def assign(self, model, state, force, moment, increment_dt):
        """As ``accumulate`` into zeroed force and moment, but storing the loads (zero for
        a particle without bonds): the step, whose first law this is, then need not zero
        the arrays (48 B per particle written and read again less)."""
        if model.n_bonds == 0:
            force.fill(0.0)
            moment.fill(0.0)
            return
        self.compute(model, state, increment_dt)
        self.gather(force, moment, assign=True)

    def compute(self, model, state, increment_dt):
        """Advance every intact bond by ``increment_dt`` (s); loads kept per bond."""
        self._index_intact(state)
        elastic_bonds(self._bonds, self._materials, self._bond_state(model, state),
                      particles(state), self._box, state.time, increment_dt,
                      True if self.musen_compat else None, self._vectorised(model),
                      True if self._uniform else None,
                      self._scratch, self._slots, self._slow, self._pending, self.loads)

    def _index_intact(self, state):
        """Remake the gather's index over the intact bonds when a twentieth of the bonds
        (at least 64) broke since it was made, or when an intact bond is missing from it
        (set intact again between steps). Breaks come a few per step: this is rare."""
        count, missing = _index_check(state.bond_active, self._indexed)
        if missing or count <= self._indexed_count - max(64, self._indexed.shape[0] // 20):
            self._indexed = state.bond_active.copy()
            self._indexed_count = count
            self._index = loops.BondIndex(*intact_ends(self._all_ends.offsets,
                                                       self._all_ends.ends, self._indexed))

    def _bond_state(self, model, state):
        """The bond arrays the kernels take, with the bond models' per-bond state
        state.extra["bond_model_state"] (made by Simulation) if a model has one."""
        if not self.model_state:
            return bond_state(state, self._no_model_state)
        return bond_state(state, state.extra["bond_model_state"])

    def _vectorised(self, model):
        """True for the vectorised path, None for the scalar one (None, not False: Numba
        then prunes the vectorised code from the kernel it compiles). Bonds of other models
        than the elastic bond (VECTORISED False) take the scalar path."""
        use = (self.vectorised and not self.musen_compat and self._vectorisable
               and model.n_bonds >= self.vectorise_from)
        return True if use else None

    def gather(self, force, moment, assign=False):
        """Add the per-bond loads of the last ``compute`` to force (N), moment (N m), or
        store them there (``assign``)."""
        gather_bond_loads(self._index, self.loads, force, moment, assign)

    def energy(self, model, state):
        """Elastic energy stored in each bond (J), shape (B,)."""
        out = np.zeros(model.n_bonds)
        if model.n_bonds:
            bond_energies(self._bonds, self._materials, self._bond_state(model, state),
                          state.position, self._box, out)
        return out


class Integrator:
    """Semi-implicit Euler update of all particles on the CPU (see ``integrate``)."""

    def __init__(self, model):
        self.status = np.zeros(1, dtype=np.int64)
        self.energy = np.zeros((chunks(model.n_particles), 2))
        self.clumps = clumps(model) if model.n_clumps else None
        self.clump_energy = np.zeros((model.n_clumps, 2))

    @contextlib.contextmanager
    def thread_limit(self, model):
        """Run the enclosed steps on one thread when the system is small (SERIAL_BELOW).

        Results do not depend on the thread count, so this changes only the speed
        (a 125-particle system on two busy cores: 450 -> 78 us per step).
        """
        if model.n_particles + model.n_bonds >= SERIAL_BELOW:
            yield
            return
        previous = numba.get_num_threads()
        numba.set_num_threads(1)
        try:
            yield
        finally:
            numba.set_num_threads(previous)

    def advance(self, model, state, force, moment, kick_dt, drift_dt):
        """Kick velocities by kick_dt (s), drift positions by drift_dt (s); return status."""
        self.status[0] = STATUS_OK
        # Energy bookkeeping where gravity, a field or damping act; external loads (which
        # a coupled solver or a script may set between any two steps) are tracked by the
        # kernels wherever they are not zero, without a pass over them here.
        body_fields = fields(model)
        track = (model.damping > 0.0 or bool(np.any(model.gravity))
                 or bool(body_fields.acting.any()))
        integrate(particles(state), bodies(model), force, moment, body_fields,
                  model.damping, kick_dt, drift_dt, box(model), self.status, track,
                  self.energy)
        if self.clumps is not None:
            integrate_clumps(force, moment, self.clumps, clump_state(state), particles(state),
                             bodies(model), body_fields, model.damping, kick_dt, drift_dt,
                             box(model), self.status, track, self.clump_energy)
        # a sum in a fixed order: the same bits whatever the thread count (+0 where
        # nothing acts).
        work, dissipated = column_sums(self.energy)
        state.work_external += float(work)
        state.dissipated_damping += float(dissipated)
        if self.clumps is not None:
            work, dissipated = column_sums(self.clump_energy)
            state.work_external += float(work)
            state.dissipated_damping += float(dissipated)
        return int(self.status[0])

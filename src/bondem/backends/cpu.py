"""CPU backend: Numba loops over bonds and particles calling the physics functions.

Deterministic sums: each bond writes its loads to its own slot, then each particle sums
its bonds through a fixed CSR index (particle -> bond ends). No atomics, and the same bits
whatever the number of threads, which is what makes a resumed run bit-identical.
"""
import contextlib

import numba
import numpy as np
from numba import prange

from ..physics import compile_physics
from ..status import STATUS_NOT_FINITE, STATUS_OK, STATUS_OUT_OF_DOMAIN  # noqa: F401
from ..physics.bond_elastic import CRITERION_NONE, INTACT
from ..physics.rotation import SMALL_ANGLE

# No fastmath, not even FMA contraction ({"contract"}: 10 % faster bond kernel): it moves
# the rounding of L = |r|, and L - L0 amplifies that to 3e-12 relative in F_n, above the
# 1e-12 of the MUSEN transcription check (validation/rotation.py).
# Numba's cache keys a kernel on this file only; backends/__init__.py drops the cached
# kernels when a physics source changes (with NUMBA_CACHE_DIR set, delete them by hand).
P = compile_physics(numba.njit(cache=False))
elastic_bond = P.elastic_bond
elastic_bond_musen = P.elastic_bond_musen
bond_break_mode_musen = P.bond_break_mode_musen
bond_stiffnesses = P.bond_stiffnesses
bond_loads_on_particles = P.bond_loads_on_particles
bond_break_mode = P.bond_break_mode
bond_elastic_energy = P.bond_elastic_energy
minimum_image = P.minimum_image

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


_jit = dict(parallel=True, cache=True, fastmath=False, nogil=True)

# Below this many particles + bonds a step costs less than waking and joining the
# worker threads of three parallel loops (tens of microseconds), so it runs on one.
SERIAL_BELOW = 2048


# Bonds per block of the vectorised kernel, and the rows of a thread's scratch: the
# block's inputs, gathered from the particle and bond arrays, then its results.
BOND_BLOCK = 32
(_R, _VI, _VJ, _WI, _WJ, _AXIS, _FT0, _MN0, _MT0) = range(0, 27, 3)
(_L0, _DIAMETER, _YOUNG, _POISSON, _NORMAL_STRENGTH, _TANGENTIAL_STRENGTH,
 _CRITERION) = range(27, 34)
(_N, _FT, _MN, _MT, _FORCE_I, _MOMENT_I, _MOMENT_J) = range(34, 55, 3)
_LENGTH, _SLOW = 55, 56
SCRATCH_ROWS = 57


@numba.njit(cache=True, error_model="numpy")
def advance_bond_block(s, count, dt):
    """Advance the ``count`` bonds gathered in scratch ``s`` by dt (s), without branches.

    Reads the input rows, writes the result rows; row _SLOW is 1 where the twist may be
    too large for the series (redo with ``elastic_bond``) or the bond may break (test it
    exactly): both rare, both left to the caller's scalar path.
    """
    B = BOND_BLOCK
    small_angle_sq = SMALL_ANGLE * SMALL_ANGLE
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
        s[_SLOW * B + q] = 1.0 if large_twist | may_break else 0.0
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


@numba.njit(**_jit)
def elastic_bonds(pairs, diameter, initial_length, bond_material, bm_young, bm_poisson,
                  bm_normal_strength, bm_tangential_strength, bm_criterion, bm_compressive,
                  position, velocity, angular_velocity, box_length, periodic, active, axis,
                  previous_length, tangential_force, normal_moment, tangential_moment,
                  break_time, break_mode, break_energy, time, dt, musen, vectorised,
                  scratch, out_force_i, out_moment_i, out_moment_j):
    """Advance every intact bond by one increment dt (s) and store its loads per bond.

    Bonds go in blocks of BOND_BLOCK: gathered into the thread's scratch, advanced by the
    vectorised ``advance_bond_block`` (if ``vectorised`` is True), scattered back. A bond
    that it marks slow (large twist, possible break), or every bond when ``vectorised`` is
    None (pruned by type: small systems never compile the vectorised code), is
    advanced one at a time by the scalar physics and tested for breakage exactly; both
    paths give the same bits (tests/test_bond_blocked.py), the vectorised one 1.3-1.9x
    faster (docs/performance.md).
    musen: True for MUSEN's numerics (``elastic_bond_musen``, ``bond_break_mode_musen``,
    scalar only) instead of the SPEC's, None for the SPEC's (None, not False: Numba
    prunes the branch by type, so a SPEC run never compiles MUSEN's law, ~1.2 s);
    previous_length (B,) m: |r| of the last step, which
    MUSEN's rotation needs. scratch: (NUMBA_NUM_THREADS, SCRATCH_ROWS * BOND_BLOCK)
    float64, one row set per thread, owned by one simulation.
    """
    B = BOND_BLOCK
    n_bonds = pairs.shape[0]
    for block in prange((n_bonds + B - 1) // B):
        s = scratch[numba.get_thread_id()]
        start = block * B
        count = min(B, n_bonds - start)
        for q in range(count):
            b = start + q
            i = pairs[b, 0]
            j = pairs[b, 1]
            m = bond_material[b]
            r = minimum_image((position[j, 0] - position[i, 0],
                               position[j, 1] - position[i, 1],
                               position[j, 2] - position[i, 2]),
                              (box_length[0], box_length[1], box_length[2]),
                              periodic[0], periodic[1], periodic[2])
            for k in range(3):
                s[(_R + k) * B + q] = r[k]
                s[(_VI + k) * B + q] = velocity[i, k]
                s[(_VJ + k) * B + q] = velocity[j, k]
                s[(_WI + k) * B + q] = angular_velocity[i, k]
                s[(_WJ + k) * B + q] = angular_velocity[j, k]
                s[(_AXIS + k) * B + q] = axis[b, k]
                s[(_FT0 + k) * B + q] = tangential_force[b, k]
                s[(_MN0 + k) * B + q] = normal_moment[b, k]
                s[(_MT0 + k) * B + q] = tangential_moment[b, k]
            s[_L0 * B + q] = initial_length[b]
            s[_DIAMETER * B + q] = diameter[b]
            s[_YOUNG * B + q] = bm_young[m]
            s[_POISSON * B + q] = bm_poisson[m]
            s[_NORMAL_STRENGTH * B + q] = bm_normal_strength[m]
            s[_TANGENTIAL_STRENGTH * B + q] = bm_tangential_strength[m]
            s[_CRITERION * B + q] = bm_criterion[m]
        if vectorised is not None:
            advance_bond_block(s, count, dt)
        for q in range(count):
            b = start + q
            if not active[b]:
                for k in range(3):
                    out_force_i[b, k] = 0.0
                    out_moment_i[b, k] = 0.0
                    out_moment_j[b, k] = 0.0
                continue
            if vectorised is not None and s[_SLOW * B + q] == 0.0:
                previous_length[b] = s[_LENGTH * B + q]
                for k in range(3):
                    axis[b, k] = s[(_N + k) * B + q]
                    tangential_force[b, k] = s[(_FT + k) * B + q]
                    normal_moment[b, k] = s[(_MN + k) * B + q]
                    tangential_moment[b, k] = s[(_MT + k) * B + q]
                    out_force_i[b, k] = s[(_FORCE_I + k) * B + q]
                    out_moment_i[b, k] = s[(_MOMENT_I + k) * B + q]
                    out_moment_j[b, k] = s[(_MOMENT_J + k) * B + q]
                continue
            m = bond_material[b]
            l0 = initial_length[b]
            r = (s[_R * B + q], s[(_R + 1) * B + q], s[(_R + 2) * B + q])
            vi = (s[_VI * B + q], s[(_VI + 1) * B + q], s[(_VI + 2) * B + q])
            vj = (s[_VJ * B + q], s[(_VJ + 1) * B + q], s[(_VJ + 2) * B + q])
            wi = (s[_WI * B + q], s[(_WI + 1) * B + q], s[(_WI + 2) * B + q])
            wj = (s[_WJ * B + q], s[(_WJ + 1) * B + q], s[(_WJ + 2) * B + q])
            n_prev = (s[_AXIS * B + q], s[(_AXIS + 1) * B + q], s[(_AXIS + 2) * B + q])
            f_t0 = (s[_FT0 * B + q], s[(_FT0 + 1) * B + q], s[(_FT0 + 2) * B + q])
            m_n0 = (s[_MN0 * B + q], s[(_MN0 + 1) * B + q], s[(_MN0 + 2) * B + q])
            m_t0 = (s[_MT0 * B + q], s[(_MT0 + 1) * B + q], s[(_MT0 + 2) * B + q])
            kn, kt, ktw, kb = bond_stiffnesses(bm_young[m], bm_poisson[m], diameter[b], l0)
            if musen is not None:
                # MUSEN's numerics (physics/bond_elastic_musen.py): previous bond with length.
                lp = previous_length[b]
                length, n, f_n, f_t, m_n, m_t = elastic_bond_musen(
                    r, vi, vj, wi, wj, (n_prev[0] * lp, n_prev[1] * lp, n_prev[2] * lp),
                    f_t0, m_n0, m_t0, l0, bm_young[m], bm_poisson[m], diameter[b], dt)
                mode = bond_break_mode_musen(length, l0, f_n, f_t, m_n, m_t, diameter[b],
                                             bm_normal_strength[m],
                                             bm_tangential_strength[m], bm_criterion[m])
            else:
                length, n, f_n, f_t, m_n, m_t = elastic_bond(
                    r, vi, vj, wi, wj, n_prev, f_t0, m_n0, m_t0, l0, kn, kt, ktw, kb, dt)
                mode = bond_break_mode(length, l0, f_n, f_t, m_n, m_t, diameter[b],
                                       bm_normal_strength[m], bm_tangential_strength[m],
                                       bm_criterion[m], bm_compressive[m])
            if mode != INTACT:
                active[b] = False
                break_time[b] = time
                break_mode[b] = mode
                break_energy[b] = bond_elastic_energy(length, l0, f_t, m_n, m_t, kn, kt,
                                                      ktw, kb)
                for k in range(3):
                    out_force_i[b, k] = 0.0
                    out_moment_i[b, k] = 0.0
                    out_moment_j[b, k] = 0.0
                continue
            force_i, moment_i, moment_j = bond_loads_on_particles(r, f_n, f_t, m_n, m_t)
            previous_length[b] = length
            for k in range(3):
                axis[b, k] = n[k]
                tangential_force[b, k] = f_t[k]
                normal_moment[b, k] = m_n[k]
                tangential_moment[b, k] = m_t[k]
                out_force_i[b, k] = force_i[k]
                out_moment_i[b, k] = moment_i[k]
                out_moment_j[b, k] = moment_j[k]


@numba.njit(**_jit)
def gather_bond_loads(offsets, ends, force_i, moment_i, moment_j, force, moment):
    """Add each particle's bond loads (CSR ``ends`` = 2*bond + side, side 1 for j)."""
    for p in prange(offsets.shape[0] - 1):
        fx = fy = fz = mx = my = mz = 0.0
        for k in range(offsets[p], offsets[p + 1]):
            b = ends[k] >> 1
            if ends[k] & 1:
                fx -= force_i[b, 0]
                fy -= force_i[b, 1]
                fz -= force_i[b, 2]
                mx += moment_j[b, 0]
                my += moment_j[b, 1]
                mz += moment_j[b, 2]
            else:
                fx += force_i[b, 0]
                fy += force_i[b, 1]
                fz += force_i[b, 2]
                mx += moment_i[b, 0]
                my += moment_i[b, 1]
                mz += moment_i[b, 2]
        force[p, 0] += fx
        force[p, 1] += fy
        force[p, 2] += fz
        moment[p, 0] += mx
        moment[p, 1] += my
        moment[p, 2] += mz


@numba.njit(**_jit)
def integrate(position, velocity, angular_velocity, force, moment, mass, inertia, fixed,
              gravity, external_force, external_moment, damping, kick_dt, drift_dt,
              box_low, box_high, periodic, status, track_energy, energy):
    """Semi-implicit Euler: v += F/m kick_dt; x += v drift_dt; w += M/I kick_dt.

    Fixed particles keep their velocity (they move with it). Local damping (Cundall)
    removes damping * |F_k| against the sign of v_k per component. Sets status[0] to
    STATUS_NOT_FINITE or STATUS_OUT_OF_DOMAIN when a particle blows up.
    If track_energy, energy (N,2) receives each particle's (work of gravity and external
    loads, energy removed by damping) in J over this kick, each load times the mean of
    the old and new velocity, which is exactly the leapfrog's change of kinetic energy.
    """
    # Energies go to per-particle slots, summed by the caller in a fixed order: a scalar
    # "+=" here would be a prange reduction, whose sum depends on the thread count (and
    # which numba 0.68 silently dropped, returning 0, inside this nested loop).
    for p in prange(position.shape[0]):
        if track_energy:
            energy[p, 0] = 0.0
            energy[p, 1] = 0.0
        if not fixed[p]:
            for k in range(3):
                applied = mass[p] * gravity[k] + external_force[p, k]
                f = force[p, k] + applied
                mk = moment[p, k] + external_moment[p, k]
                damp_f = 0.0
                damp_m = 0.0
                if damping > 0.0:
                    damp_f = -damping * abs(f) * np.sign(velocity[p, k])
                    damp_m = -damping * abs(mk) * np.sign(angular_velocity[p, k])
                v_old = velocity[p, k]
                w_old = angular_velocity[p, k]
                velocity[p, k] = v_old + (f + damp_f) / mass[p] * kick_dt
                angular_velocity[p, k] = w_old + (mk + damp_m) / inertia[p] * kick_dt
                if track_energy:
                    v_mean = 0.5 * (v_old + velocity[p, k])
                    w_mean = 0.5 * (w_old + angular_velocity[p, k])
                    energy[p, 0] += (applied * v_mean + external_moment[p, k] * w_mean) \
                        * kick_dt
                    energy[p, 1] -= (damp_f * v_mean + damp_m * w_mean) * kick_dt
        for k in range(3):
            x = position[p, k] + velocity[p, k] * drift_dt
            if periodic[k]:
                length = box_high[k] - box_low[k]
                x -= length * np.floor((x - box_low[k]) / length)
            elif x < box_low[k] or x > box_high[k]:
                status[0] = STATUS_OUT_OF_DOMAIN
            if not np.isfinite(x) or not np.isfinite(velocity[p, k]) \
                    or not np.isfinite(angular_velocity[p, k]):
                status[0] = STATUS_NOT_FINITE
            position[p, k] = x


# Serial: called once per frame, not per step; a parallel loop would cost ~0.7 s more
# compilation on a first run for no measurable gain.
@numba.njit(cache=True, fastmath=False, nogil=True)
def bond_energies(pairs, diameter, initial_length, bond_material, bm_young, bm_poisson,
                  position, box_length, periodic, active, tangential_force, normal_moment,
                  tangential_moment, out):
    """Elastic energy (J) stored in each bond; 0 for broken bonds."""
    for b in range(pairs.shape[0]):
        if not active[b]:
            out[b] = 0.0
            continue
        i = pairs[b, 0]
        j = pairs[b, 1]
        m = bond_material[b]
        r = minimum_image((position[j, 0] - position[i, 0], position[j, 1] - position[i, 1],
                           position[j, 2] - position[i, 2]),
                          (box_length[0], box_length[1], box_length[2]),
                          periodic[0], periodic[1], periodic[2])
        kn, kt, ktw, kb = bond_stiffnesses(bm_young[m], bm_poisson[m], diameter[b],
                                           initial_length[b])
        length = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        out[b] = bond_elastic_energy(
            length, initial_length[b],
            (tangential_force[b, 0], tangential_force[b, 1], tangential_force[b, 2]),
            (normal_moment[b, 0], normal_moment[b, 1], normal_moment[b, 2]),
            (tangential_moment[b, 0], tangential_moment[b, 1], tangential_moment[b, 2]),
            kn, kt, ktw, kb)


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
        table = model.bond_material_table()
        self._table = (table["young_modulus"], table["poisson_ratio"],
                       table["normal_strength"], table["tangential_strength"],
                       table["criterion"], table["compressive_breakage"])
        self._box_length = model.box_length
        self._offsets, self._ends = particle_bond_index(model.bond_pairs, model.n_particles)
        n_bonds = model.n_bonds
        self.force_i = np.zeros((n_bonds, 3))
        self.moment_i = np.zeros((n_bonds, 3))
        self.moment_j = np.zeros((n_bonds, 3))
        # One scratch row per Numba thread (get_thread_id < NUMBA_NUM_THREADS).
        self._scratch = np.zeros((numba.config.NUMBA_NUM_THREADS,
                                  SCRATCH_ROWS * BOND_BLOCK))

    def accumulate(self, model, state, force, moment, increment_dt):
        """Advance the bonds by ``increment_dt`` (s); add loads to force (N), moment (N m)."""
        if model.n_bonds == 0:
            return
        self.compute(model, state, increment_dt)
        self.gather(force, moment)

    def compute(self, model, state, increment_dt):
        """Advance every intact bond by ``increment_dt`` (s); loads kept per bond."""
        elastic_bonds(model.bond_pairs, model.bond_diameter, model.bond_initial_length,
                      model.bond_material, *self._table, state.position, state.velocity,
                      state.angular_velocity, self._box_length, model.periodic,
                      state.bond_active, state.bond_axis, state.bond_previous_length,
                      state.bond_tangential_force, state.bond_normal_moment,
                      state.bond_tangential_moment, state.bond_break_time,
                      state.bond_break_mode, state.bond_break_energy, state.time,
                      increment_dt, True if self.musen_compat else None,
                      self._vectorised(model), self._scratch, self.force_i,
                      self.moment_i, self.moment_j)

    def _vectorised(self, model):
        """True for the vectorised path, None for the scalar one (None, not False: Numba
        then prunes the vectorised code from the kernel it compiles)."""
        use = (self.vectorised and not self.musen_compat
               and model.n_bonds >= self.vectorise_from)
        return True if use else None

    def gather(self, force, moment):
        """Add the per-bond loads of the last ``compute`` to force (N), moment (N m)."""
        gather_bond_loads(self._offsets, self._ends, self.force_i, self.moment_i,
                          self.moment_j, force, moment)

    def energy(self, model, state):
        """Elastic energy stored in each bond (J), shape (B,)."""
        out = np.zeros(model.n_bonds)
        if model.n_bonds:
            bond_energies(model.bond_pairs, model.bond_diameter, model.bond_initial_length,
                          model.bond_material, self._table[0], self._table[1],
                          state.position, self._box_length, model.periodic,
                          state.bond_active, state.bond_tangential_force,
                          state.bond_normal_moment, state.bond_tangential_moment, out)
        return out


class Integrator:
    """Semi-implicit Euler update of all particles on the CPU (see ``integrate``)."""

    def __init__(self, model):
        self.status = np.zeros(1, dtype=np.int64)
        self.energy = np.zeros((model.n_particles, 2))
        self._external = bool(np.any(model.external_force) or np.any(model.external_moment))

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
        # Energy bookkeeping only where gravity, external loads or damping act.
        track = self._external or model.damping > 0.0 or bool(np.any(model.gravity))
        integrate(state.position, state.velocity, state.angular_velocity, force, moment,
                  model.mass, model.inertia, model.fixed, model.gravity,
                  model.external_force, model.external_moment, model.damping, kick_dt,
                  drift_dt, model.box_low, model.box_high, model.periodic, self.status,
                  track, self.energy)
        if track:
            # numpy's sum in a fixed order: the same bits whatever the thread count.
            work, dissipated = self.energy.sum(axis=0)
            state.work_external += float(work)
            state.dissipated_damping += float(dissipated)
        return int(self.status[0])

"""CPU loops for contacts: one slot per listed pair, then a gather by particle.

Each particle-particle pair and each particle-wall candidate writes its loads to its own
row; particles sum their rows through fixed CSR indices built with the Verlet list. No
atomics, so the sums are the same bits with any number of threads.
"""
import weakref

import numba
from numba import prange

import numpy as np

from ..contacts import (MUSEN_PAIR_HISTORY, MUSEN_WALL_HISTORY, PAIR_HISTORY,
                        WALL_HISTORY, ContactSettings, contact_cutoff, contact_reach,
                        material_parameters)
from ..neighbors import (build_pairs, carry_history, counting_sort, history_map,
                         max_displacement, reference_cells, relative_spread)
from ..physics.contact_hertz_musen import MUSEN_VERSION, MUSEN_VERSIONS
from ..physics import contact_models
from ..walls import PLANE, WallSet, build_wall_pairs
from . import cpu, loops, raw
from .cpu import CHUNK, L, _jit, _serial, balanced_shares, chunks, store3

# The pair loop inlines its contact law as well (Hertz-Mindlin, friction and rolling, at
# Numba's IR level; the small vector helpers LLVM inlines anyway): a touching row costs
# half (113 -> ~55 ns, one thread, 10^4 bed, the kernel alone). Only these: inlining
# every physics function made the first compile of the demo 29 -> 52 s.
_LAWS = {"hertz_mindlin", "hertz_mindlin_pulled", "hertz_mindlin_law", "friction_and_rolling",
         "hertz_mindlin_musen_pp"}


def _law_inlined(function):
    return numba.njit(cache=False, inline="always" if function.__name__ in _LAWS
                      else "never")(function)


_INLINED = loops.compile_loops(numba.njit(cache=False, inline="always"), _law_inlined,
                               given=raw.ROWS)
pair_contact = _INLINED.pair_contact
pair_geometry = L.pair_geometry
row_quiet = L.row_quiet
pair_rows_sum = L.pair_rows_sum
wall_contacts_of = L.wall_contacts_of
add_wall_rows = L.add_wall_rows
# The compiled physics, for tests that call one law directly.
hertz_mindlin = L.hertz_mindlin
contact_law = L.contact_law
restitution_beta = L.restitution_beta


# What a row that ``pair_contact`` evaluates costs, in quiet rows skipped: 73 against
# 5.5 ns (one thread, 10^5 bed). The unit of ``particle_contacts``' work per chunk.
EVALUATED_ROW_WORK = 13.0


@numba.njit(**_serial)
def pair_contact_range(first, last, live, quiet, pairs, pair_bond, bond_active, particles,
                       grains, materials, law, reach, use_rolling, box, rows, dt,
                       moved_dt, musen):
    """``loops.pair_contact`` for the rows live[first:last], but for quiet rows whose pair
    is still apart, which it would leave as they are. Returns the range's work (rows,
    EVALUATED_ROW_WORK for each evaluated one)."""
    evaluated = 0
    for s in range(first, last):
        c = live[s]
        if quiet[c] and pair_geometry(c, pairs, pair_bond, bond_active, particles.position,
                                      grains.radius, box, reach)[5]:
            continue
        pair_contact(c, pairs, pair_bond, bond_active, particles, grains, materials,
                     law, reach, use_rolling, box, rows, dt, moved_dt, musen)
        quiet[c] = row_quiet(c, rows)
        evaluated += 1
    return (last - first) + EVALUATED_ROW_WORK * evaluated


@numba.njit(**_jit)
def particle_contacts(live, quiet, pairs, pair_bond, bond_active, particles, grains,
                      materials, law, reach, use_rolling, box, rows, dt,
                      moved_dt, musen, work, threads):
    """Loads, stored energy and dissipation of every contact row listed in ``live``
    (``loops.pair_contact``), advancing the springs by dt (s); moved_dt (s): time since
    the previous evaluation.

    quiet (uint8 per row, ``row_quiet``, kept up to date here): a quiet row whose pair is
    still apart is not visited. Its check reads the pair, its flag and the two positions
    (17 B of row data, against the 72 B that ``pair_contact`` reads and writes to leave
    such a row as it is); most listed pairs are such rows in a packing.

    Only the rows listed in ``live`` are visited: the other rows belong to pairs joined by
    an intact bond, which carry no contact load and keep zero rows (bonds never form during
    a run), so skipping them saves the memory traffic of every bonded neighbour.
    law: the contact model's CODE, None for Hertz-Mindlin (the other laws are then not
    compiled); reach (m): its longest range beyond contact. musen: None for the SPEC's law (MUSEN's
    is then not compiled), else the MUSEN release's code (contact_hertz_musen.MUSEN_1_70,
    MUSEN_1_74).
    work (one per CHUNK of ``live``): each chunk's work in the last call, which shares
    the chunks out among ``threads`` (``numba.get_num_threads()``, read by the caller: the
    call inside would make the kernel uncachable) with ``cpu.balanced_shares``, and is
    updated here; the results depend on neither.
    """
    n = live.shape[0]
    bounds = balanced_shares(work, threads)
    for t in prange(bounds.shape[0] - 1):
        for c in range(bounds[t], bounds[t + 1]):
            work[c] = pair_contact_range(
                c * CHUNK, min(n, (c + 1) * CHUNK), live, quiet, pairs, pair_bond,
                bond_active, particles, grains, materials, law, reach,
                use_rolling, box, rows, dt, moved_dt, musen)


@numba.njit(**_serial)
def gather_pair_range(first, last, index, rows, force, moment, assign):
    """Add the contact loads of particles first to last - 1 (``loops.pair_rows_sum``), or
    store them (``assign``).

    When adding, a particle whose sums are all zero is not written: adding +0 changes no
    load, since every load is a sum that starts at +0 and so is never -0. That saves
    reading and writing the loads of every particle without a touching neighbour.
    Storing gives the same bits as adding to zeroed loads, without the pass that zeroes
    them."""
    for p in range(first, last):
        f, m = pair_rows_sum(p, index, rows)
        if assign:
            store3(force, p, f)
            store3(moment, p, m)
            continue
        if (f[0] == 0.0 and f[1] == 0.0 and f[2] == 0.0 and m[0] == 0.0 and m[1] == 0.0
                and m[2] == 0.0):
            continue
        for k in range(3):
            force[p, k] += f[k]
            moment[p, k] += m[k]


@numba.njit(**_jit)
def gather_pair_loads(index, rows, force, moment, assign):
    """Add each particle's contact loads (a ``loops.PairIndex`` over the live rows) to
    force (N) and moment (N m), or store them there (``assign``)."""
    n = index.i_start.shape[0] - 1
    for c in prange(chunks(n)):
        gather_pair_range(c * CHUNK, min(n, (c + 1) * CHUNK), index, rows, force, moment,
                          assign)


@numba.njit(**_serial)
def wall_contact_range(first, last, near, wall_start, wall_pairs, walls, particles, grains,
                       materials, law, reach, use_rolling, triangles, rows, dt,
                       moved_dt, force, moment, musen):
    """``loops.wall_contacts_of`` for particles near[first:last], then their wall loads
    added to force (N) and moment (N m)."""
    for s in range(first, last):
        p = near[s]
        wall_contacts_of(p, wall_start, wall_pairs, walls, particles, grains, materials, law,
                         reach, use_rolling, triangles, rows, dt, moved_dt, musen)
        add_wall_rows(p, wall_start, rows, force, moment)


@numba.njit(**_jit)
def wall_contacts(near, wall_start, wall_pairs, walls, particles, grains, materials, law,
                  reach, use_rolling, triangles, rows, dt, moved_dt, force,
                  moment, musen):
    """Loads of every particle-wall candidate (``loops.wall_contacts_of``; rows sorted by
    particle, ``wall_start`` their CSR offsets), added to force (N) and moment (N m).
    triangles: None when every wall element is a plane (the triangle code is then not
    compiled), else True. musen: None for the SPEC's law, the MUSEN release's code. near: the
    particles that have wall candidates (the others have nothing to do)."""
    n = near.shape[0]
    for c in prange(chunks(n)):
        wall_contact_range(c * CHUNK, min(n, (c + 1) * CHUNK), near, wall_start, wall_pairs,
                           walls, particles, grains, materials, law, reach,
                           use_rolling, triangles, rows, dt, moved_dt, force, moment, musen)


@numba.njit(cache=True, nogil=True)
def wall_totals(wall_pairs, element_wall, scratch_point, force_c, moment_c, position, radius,
                wall_reference, out_force, out_torque):
    """Force (N) and torque (N m, about each wall's reference point) on every wall, summed
    serially in list order (deterministic)."""
    out_force[:] = 0.0
    out_torque[:] = 0.0
    for c in range(wall_pairs.shape[0]):
        if force_c[c, 0] == 0.0 and force_c[c, 1] == 0.0 and force_c[c, 2] == 0.0:
            continue
        p = wall_pairs[c, 0]
        w = element_wall[wall_pairs[c, 1]]
        f = (-force_c[c, 0], -force_c[c, 1], -force_c[c, 2])
        r = (scratch_point[c, 0] - wall_reference[w, 0], scratch_point[c, 1] - wall_reference[w, 1],
             scratch_point[c, 2] - wall_reference[w, 2])
        # The particle's couple about the contact point, M_x + (x - q) x F, acts back on the wall.
        arm = (position[p, 0] - scratch_point[c, 0], position[p, 1] - scratch_point[c, 1],
               position[p, 2] - scratch_point[c, 2])
        m_part = (moment_c[c, 0] + (arm[1] * force_c[c, 2] - arm[2] * force_c[c, 1]),
                  moment_c[c, 1] + (arm[2] * force_c[c, 0] - arm[0] * force_c[c, 2]),
                  moment_c[c, 2] + (arm[0] * force_c[c, 1] - arm[1] * force_c[c, 0]))
        out_force[w, 0] += f[0]
        out_force[w, 1] += f[1]
        out_force[w, 2] += f[2]
        out_torque[w, 0] += r[1] * f[2] - r[2] * f[1] - m_part[0]
        out_torque[w, 1] += r[2] * f[0] - r[0] * f[2] - m_part[1]
        out_torque[w, 2] += r[0] * f[1] - r[1] * f[0] - m_part[2]


# The tangential-force rows of a SPEC run: one row, never read or written.
NO_TANGENTIAL = np.zeros((1, 3))


def pair_rows(extra, dissipated):
    """The contact history rows of ``state.extra`` and ``dissipated`` (J per row) as a
    ``loops.PairRows``."""
    return loops.PairRows(extra["contact_spring"], extra["contact_force"],
                          extra["contact_moment_i"], extra["contact_moment_j"],
                          extra["contact_energy"], dissipated,
                          extra.get("contact_tangential", NO_TANGENTIAL))


@numba.njit(cache=True, nogil=True)
def quiet_rows(rows):
    """``loops.row_quiet`` of every contact row (uint8)."""
    quiet = np.empty(rows.energy.shape[0], dtype=np.uint8)
    for c in range(quiet.shape[0]):
        quiet[c] = row_quiet(c, rows)
    return quiet


@numba.njit(cache=True, nogil=True)
def _carry_rows(new_rows, old_rows, old_quiet, unflagged, old_values, new_values, rows,
                new_quiet):
    """Copy the mapped rows (``history_map``) of the pair history arrays ``old_values``
    into ``new_values`` (zeros), except rows that hold nothing: flagged in ``old_quiet``
    with every value of ``unflagged`` (the arrays the flag does not cover: springs) zero.
    new_quiet (ones) receives ``row_quiet`` of each copied row, read from ``rows`` (the
    new arrays as ``PairRows``, with no dissipation: the rows before their first step in
    the new list). Arrays as (rows, K) views."""
    for q in range(new_rows.shape[0]):
        o = old_rows[q]
        r = new_rows[q]
        if old_quiet[o]:
            empty = True
            for a in unflagged:
                for k in range(a.shape[1]):
                    empty &= a[o, k] == 0.0
            if empty:
                continue
        for t in range(len(old_values)):
            for k in range(old_values[t].shape[1]):
                new_values[t][r, k] = old_values[t][o, k]
        new_quiet[r] = row_quiet(r, rows)


# The arrays ``row_quiet`` reads: a row flagged quiet holds zeros in these.
FLAGGED = ("contact_force", "contact_moment_i", "contact_moment_j", "contact_energy")


def carry_pair_rows(old_pairs, old_extra, new_pairs, n_particles, names, old_quiet=None):
    """The pair history arrays ``names`` (``ContactLaw.history``) of ``new_pairs``, carried
    from ``old_extra`` listed for ``old_pairs`` (both sorted by key) as
    ``neighbors.carry_history`` does, and the new rows' ``quiet_rows`` flags (as a
    derivation would find them). old_quiet: the old rows' current flags, if known (then
    the rows that hold nothing are neither read whole nor written: most of a packing's
    rows). Returns (dict name -> array, flags (M,) uint8)."""
    m, m_old = new_pairs.shape[0], old_pairs.shape[0]
    new = {name: np.zeros((m,) + shape) for name, shape in names.items()}
    new_quiet = np.ones(m, dtype=np.uint8)
    if m == 0 or m_old == 0:
        return new, new_quiet
    # an array the old lists lack (a SPEC checkpoint resumed MUSEN-compatible) held zeros
    old = {name: (old_extra[name] if name in old_extra and old_extra[name].shape[0] == m_old
                  else np.zeros((m_old,) + shape)) for name, shape in names.items()}
    if old_quiet is None:
        old_quiet = quiet_rows(pair_rows(old, np.zeros(m_old)))
    new_rows, old_rows = history_map(old_pairs, new_pairs, n_particles)

    def view(a):
        return np.ascontiguousarray(a).reshape(a.shape[0], -1)

    _carry_rows(new_rows, old_rows, old_quiet,
                tuple(view(old[name]) for name in names if name not in FLAGGED),
                tuple(view(old[name]) for name in names),
                tuple(view(new[name]) for name in names), pair_rows(new, np.zeros(m)),
                new_quiet)
    return new, new_quiet


def csr_by(index, n):
    """(start (n+1,), order) grouping rows by ``index`` (values in 0..n-1; stable: a
    counting sort, O(rows + n))."""
    return counting_sort(np.ascontiguousarray(index, dtype=np.int64), n)


@numba.njit(cache=True, nogil=True)
def live_rows(pairs, pair_bond, bond_active, n):
    """The rows of ``pairs`` (sorted by i) that no intact bond joins (pair_bond[c]: the
    bond of row c, or -1), ascending, and their CSR indices by particle (n of them):
    (live, i_start, j_start, j_order), j's rows j_order[j_start[j]:j_start[j+1]]
    ascending."""
    keep = np.empty(pairs.shape[0], dtype=np.bool_)
    for c in range(pairs.shape[0]):
        keep[c] = pair_bond[c] < 0 or not bond_active[pair_bond[c]]
    live = np.flatnonzero(keep)
    # rows are sorted by i, so the live rows are too: i's CSR is a count per particle
    i_start = np.zeros(n + 1, dtype=np.int64)
    for c in live:
        i_start[pairs[c, 0] + 1] += 1
    for p in range(n):
        i_start[p + 1] += i_start[p]
    j_start, order = counting_sort(pairs[live, 1], n)
    return live, i_start, j_start, live[order]


@numba.njit(cache=True, nogil=True)
def _insert_rows(live, j_order, i_start, j_start, pairs, rows):
    """``live`` (ascending) and ``j_order`` (grouped by j, ascending within) with the
    ascending ``rows`` merged in where a full derivation would put them; the CSR offsets
    i_start, j_start (n+1,) grow in place. Returns (live, j_order).

    Each new row's place is found by binary search (in ``live``, and in its j's group of
    ``j_order``) and the row inserted there (``np.insert``, block copies): a merge that
    compared every row of j_order read the pair of each (a random read per row, most of
    the 1.6 ms this took per step of the 10^5 impact)."""
    n = i_start.shape[0] - 1
    merged = np.insert(live, np.searchsorted(live, rows), rows)
    # the new rows by (j, row), each placed in its j's group (ascending rows)
    size = pairs.shape[0]
    key = np.sort(pairs[rows, 1] * size + rows)
    at = np.empty(key.shape[0], dtype=np.int64)
    for k in range(key.shape[0]):
        j = key[k] // size
        at[k] = j_start[j] + np.searchsorted(j_order[j_start[j]:j_start[j + 1]],
                                             key[k] % size)
    grouped = np.insert(j_order, at, key % size)
    added_i = np.zeros(n + 1, dtype=np.int64)
    added_j = np.zeros(n + 1, dtype=np.int64)
    for r in rows:
        added_i[pairs[r, 0] + 1] += 1
        added_j[pairs[r, 1] + 1] += 1
    for p in range(n):
        added_i[p + 1] += added_i[p]
        added_j[p + 1] += added_j[p]
        i_start[p + 1] += added_i[p + 1]
        j_start[p + 1] += added_j[p + 1]
    return merged, grouped


class ContactLaw:
    """Particle-particle and particle-wall contacts on the CPU.

    model: the Model; settings: ContactSettings; walls: PlaneWall / MeshWall objects.
    After each step ``wall_force`` (W,3) N and ``wall_torque`` (W,3) N m (about each wall's
    reference point) hold the loads on the walls.
    """

    name = "contacts"
    # False: rebuild the lists whenever a particle has moved skin/2 (the test of
    # neighbors.max_displacement alone); True: then also ask whether any two neighbours
    # moved skin relative to each other (``_needs_rebuild``). The lists, and so the
    # results, are the same bits either way; the relative test rebuilds less where
    # particles move together (the impact under way: every 8 steps instead of 5).
    relative_trigger = True
    # True: MUSEN's Hertz-Mindlin (contact_hertz_musen), set by Simulation(musen_compat=True);
    # musen_code: which MUSEN release's (contact_hertz_musen.MUSEN_VERSIONS)
    musen_compat = False
    musen_code = MUSEN_VERSIONS[MUSEN_VERSION]

    def __init__(self, model, settings=None, walls=()):
        self.settings = settings if settings is not None else ContactSettings()
        # the contact model (physics/contact_models.py); "none": no particle pairs, and
        # Hertz-Mindlin for the walls
        name = self.settings.model if self.settings.model != "none" else "hertz_mindlin"
        self.law_module = contact_models.BY_NAME[name]
        self.pair_law = self.law_module.CODE if self.settings.model != "none" else -1
        self.wall_law = self.law_module.CODE
        # None selects Hertz-Mindlin in the CPU kernels (by type: only the law in use compiles)
        self._law = None if self.wall_law == 0 else self.wall_law
        self.walls = WallSet(walls)
        table = model.material_table()
        parameters = [material_parameters(self.law_module, m) for m in model.materials]
        wm = [w.material for w in self.walls.walls]
        self._wall_materials = tuple(np.array([getattr(m, k) for m in wm], dtype=np.float64)
                                     for k in ("young_modulus", "poisson_ratio", "restitution",
                                               "friction", "rolling_friction"))
        self._k_linear = float(self.settings.linear_stiffness or 0.0)  # N/m, 0: default
        rolling = bool(self.settings.rolling_resistance)
        columns = (table["young_modulus"], table["poisson_ratio"], table["restitution"],
                   table["friction"], table["rolling_friction"])
        self._materials = loops.contact_materials(*columns, self.law_module, parameters,
                                                  self._k_linear, rolling)
        self._wall_pair = loops.contact_materials(
            *columns, self.law_module, parameters, self._k_linear, rolling,
            wall=self._wall_materials + ([material_parameters(self.law_module, m)
                                          for m in wm],)).pair
        for w, wall in enumerate(self.walls.walls):
            if getattr(wall, "own_friction", False):   # rows a W + w: material a, wall w
                rows = np.arange(len(table["friction"])) * len(wm) + w
                self._wall_pair[rows, loops.PAIR_FRICTION] = wall.material.friction
                self._wall_pair[rows, loops.PAIR_ROLLING] = (wall.material.rolling_friction
                                                             if rolling else 0.0)
        r_max = float(model.radius.max(initial=0.0))
        # the longest gaps the law acts across (m): pairs (R* <= r_max / 2), walls (R* = r)
        self._reach_pairs = contact_reach(self.law_module, self._materials.pair, 0.5 * r_max)
        self._reach_walls = (contact_reach(self.law_module, self._wall_pair, r_max)
                             if self.walls.n_walls else 0.0)
        n = model.n_particles
        cutoff, self.skin = contact_cutoff(model.radius, self.settings.skin,
                                           self._reach_pairs)
        self._box_length = model.box_length
        # True when a wall has triangles, else None (the kernel then has no triangle code)
        self._triangles = True if np.any(self.walls.element_type != PLANE) else None
        if np.any(model.periodic & (self._box_length < 2.0 * cutoff)):
            raise ValueError(f"periodic box lengths {self._box_length[model.periodic].tolist()} "
                             f"m must be at least twice the contact cut-off {cutoff:.3g} m")
        bonds = np.sort(model.bond_pairs, axis=1)
        self._bond_order = np.argsort(bonds[:, 0] * np.int64(n) + bonds[:, 1], kind="stable")
        self._bonds_sorted = np.ascontiguousarray(bonds[self._bond_order])
        self._derived_for = None
        self._carried_quiet = None  # the flags of a rebuild's rows, for the next _derive
        self._row_room = 0      # room per row of the next pair search (build_pairs)
        self._chunk_work = np.ones(0)   # particle_contacts' work per chunk of live rows
        self._last_state = None
        self._t_wall = 0.0   # s, where the walls stand for the step being evaluated
        # the relative trigger's cells (counts, cell of each particle) of the reference
        # positions they were made for (weakly held), and its scratch (12 per cell)
        self._cells = None
        self._cells_for = None
        self._spread_scratch = np.empty(0)
        self.wall_force = np.zeros((self.walls.n_walls, 3))
        self.wall_torque = np.zeros((self.walls.n_walls, 3))

    # -- lists ------------------------------------------------------------------------
    def reach(self):
        """(pairs, walls): the longest gap (m) across which the law acts; 0 for MUSEN's
        laws, which act in contact only (MUSEN's contact radius is the radius here)."""
        if self.musen_compat:
            return 0.0, 0.0
        return self._reach_pairs, self._reach_walls

    def history(self):
        """(pair, wall) history arrays this law keeps in ``state.extra``: name -> row
        shape; MUSEN-compatible runs add the stored tangential forces."""
        if self.musen_compat:
            return ({**PAIR_HISTORY, **MUSEN_PAIR_HISTORY},
                    {**WALL_HISTORY, **MUSEN_WALL_HISTORY})
        return PAIR_HISTORY, WALL_HISTORY

    def _rebuild(self, model, state):
        extra = state.extra
        position = state.position
        empty2 = np.zeros((0, 2), np.int64)
        if self.pair_law >= 0:
            pairs = build_pairs(position, model.radius, self.skin + self.reach()[0],
                                model.periodic,
                                model.box_low, model.box_high, self._row_room)
            # the next search runs once if no row outgrows the longest of this one by
            # more than a quarter (else it counts first, as this first one did)
            longest = int(np.bincount(pairs[:, 0]).max()) if pairs.shape[0] else 0
            self._row_room = longest + max(4, longest // 4)
            if model.n_clumps and pairs.shape[0]:
                # members of one clump never touch: it is rigid
                clump = model.clump_of[pairs]
                pairs = np.ascontiguousarray(
                    pairs[(clump[:, 0] < 0) | (clump[:, 0] != clump[:, 1])])
        else:
            pairs = empty2
        pair_history, wall_history = self.history()
        if not self.musen_compat:   # a MUSEN-compatible checkpoint resumed in SPEC mode
            for name in (*MUSEN_PAIR_HISTORY, *MUSEN_WALL_HISTORY):
                extra.pop(name, None)
        old_pairs = extra.get("contact_pairs", empty2)
        # the pair kernel keeps the flags of the rows it derived them for
        flags = self._quiet if self._derived(extra) else None
        carried, self._carried_quiet = carry_pair_rows(old_pairs, extra, pairs,
                                                       model.n_particles, pair_history, flags)
        extra.update(carried)
        extra["contact_pairs"] = pairs
        rows = self.walls.elements(self._t_wall)
        wall_pairs = build_wall_pairs(position, model.radius, self.skin + self.reach()[1],
                                      rows,
                                      self.walls.element_type)
        old_wall_pairs = extra.get("wall_pairs", empty2)
        mapping = history_map(old_wall_pairs, wall_pairs, max(1, self.walls.n_elements))
        for name, shape in wall_history.items():
            extra[name] = carry_history(old_wall_pairs,
                                        extra.get(name, np.zeros((0,) + shape)), wall_pairs,
                                        max(1, self.walls.n_elements), mapping)
        extra["wall_pairs"] = wall_pairs
        extra["contact_reference_position"] = position.copy()
        extra["contact_reference_time"] = np.array([self._t_wall])
        self.walls.mark(self._t_wall)
        counters = extra.setdefault("contact_counters", np.array([0.0, 0.0, 0.0, state.time]))
        counters[2] += 1.0

    def _needs_rebuild(self, model, state):
        extra = state.extra
        if "contact_pairs" not in extra:
            return True
        reference = extra["contact_reference_position"]
        moved = max_displacement(state.position, reference, self._box_length, model.periodic)
        moved += self.walls.max_displacement(
            self._t_wall, self._t_wall - extra["contact_reference_time"][0])
        if moved <= 0.5 * self.skin:
            return False
        # Past skin/2 a listed gap may only have closed if its two particles moved
        # relative to each other (neighbors.relative_spread): while no particle (plus the
        # walls) has moved a whole skin, the walls' list holds, and pairs farther apart
        # than the cells of the reference positions cannot have come into reach.
        if (moved >= self.skin or not self.relative_trigger or np.any(model.periodic)
                or model.n_particles < 2):
            return True
        return self._relative_spread(model, state.position, reference) >= self.skin

    def _relative_spread(self, model, position, reference):
        """``neighbors.relative_spread`` of the particles since ``reference`` (m), in cells
        2 r_max + reach + 2 skin wide: two particles of cells that are not neighbours were
        at least that far apart, and have closed less than 2 skin since."""
        if self._cells_for is None or self._cells_for() is not reference:
            size = 2.0 * float(model.radius.max()) + self.reach()[0] + 2.0 * self.skin
            self._cells = reference_cells(reference, size, max(64, model.n_particles // 8))
            # a weak reference: the old positions are not kept alive past a rebuild
            self._cells_for = weakref.ref(reference)
            cells = int(np.prod(self._cells[0]))
            if self._spread_scratch.shape[0] < 12 * cells:
                self._spread_scratch = np.empty(12 * cells)
        counts, cell = self._cells
        return relative_spread(position, reference, cell, counts, self._spread_scratch)

    def _derive_live(self, model, state):
        """Rows that can carry a contact load (no intact bond joins the pair) and their
        CSR indices by particle; redone when a bond breaks."""
        self._live, self._i_start, self._j_start, self._j_order = live_rows(
            state.extra["contact_pairs"], self._pair_bond, state.bond_active,
            model.n_particles)
        self._i_order = self._live
        self._active_bonds = int(np.count_nonzero(state.bond_active))
        self._bond_was_active = state.bond_active.copy()

    def _add_broken(self, model, state):
        """The rows of bonds broken since the last derivation join the live rows and the
        CSR indices where ``_derive_live`` would put them (live rows ascending, j's rows
        grouped by j in row order): O(rows + particles) per step in which bonds break,
        instead of a sort of every row."""
        active = state.bond_active
        newly = self._bond_was_active & ~active
        self._bond_was_active = active.copy()
        self._active_bonds = int(np.count_nonzero(active))
        rows = self._bond_row[np.flatnonzero(newly)]
        rows = np.sort(rows[rows >= 0])
        if rows.size == 0:
            return
        self._live, self._j_order = _insert_rows(
            self._live, self._j_order, self._i_start, self._j_start,
            state.extra["contact_pairs"], rows)
        self._i_order = self._live

    @staticmethod
    def _key(extra):
        # the history arrays too: ``_quiet`` caches what their rows hold
        return (extra["contact_pairs"], extra["wall_pairs"], extra["contact_force"],
                extra["contact_moment_i"], extra["contact_moment_j"], extra["contact_energy"])

    def _derived(self, extra):
        """True when the derived indices and flags belong to ``extra``'s current lists."""
        if self._derived_for is None or "contact_pairs" not in extra:
            return False
        return all(a is b for a, b in zip(self._key(extra), self._derived_for))

    def _derive(self, model, state):
        """CSR indices and bond lookup for the current lists (cached per list object)."""
        extra = state.extra
        if self._derived(extra):
            if int(np.count_nonzero(state.bond_active)) != self._active_bonds:
                self._add_broken(model, state)
            return
        n = model.n_particles
        pairs = extra["contact_pairs"]
        self._pair_bond = np.full(pairs.shape[0], -1, dtype=np.int64)
        if self._bonds_sorted.shape[0] and pairs.shape[0] and not self.settings.bonded_pairs:
            # the bonds sorted by key, matched to the pairs like the rows of a rebuild
            rows, where = history_map(self._bonds_sorted, pairs, n)
            self._pair_bond[rows] = self._bond_order[where]
        self._bond_row = np.full(model.n_bonds, -1, dtype=np.int64)
        held = np.flatnonzero(self._pair_bond >= 0)
        self._bond_row[self._pair_bond[held]] = held
        self._derive_live(model, state)
        self._dissipated = np.zeros(pairs.shape[0])
        carried, self._carried_quiet = self._carried_quiet, None
        self._quiet = (carried if carried is not None and carried.shape[0] == pairs.shape[0]
                       else quiet_rows(pair_rows(extra, self._dissipated)))
        wall_pairs = extra["wall_pairs"]
        k = wall_pairs.shape[0]
        self._wall_start = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(wall_pairs[:, 0], minlength=n), out=self._wall_start[1:])
        self._wall_near = np.flatnonzero(np.diff(self._wall_start)).astype(np.int64)
        self._w_distance = np.zeros(k)
        self._w_point = np.zeros((k, 3))
        self._w_feature = np.zeros(k, dtype=np.int64)
        self._w_dissipated = np.zeros(k)
        self._w_work = np.zeros(k)
        self._derived_for = self._key(extra)

    # -- the law ----------------------------------------------------------------------
    def wall_time(self, state, increment_dt):
        """The time (s) at which the walls are placed for this step's loads: the state's
        time; in MUSEN-compatible runs one step later after the start-up, since MUSEN moves
        its walls in its prediction step too (BaseSimulator::MoveObjectsStep), so that
        they lead its particles by one step from then on."""
        if self.musen_compat and state.started:
            return state.time + increment_dt
        return state.time

    def _walls_still(self, state):
        """MUSEN's walls have no velocity in its prediction step: their motion is set by
        the first MoveWalls, after it (CSimplifiedScene::InitializeGeometricalObjects)."""
        return self.musen_compat and not state.started

    def accumulate(self, model, state, force, moment, increment_dt):
        """Add contact and wall loads (N, N m) for the state at the start of the step;
        advance the tangential springs by ``increment_dt`` (s)."""
        self._loads(model, state, force, moment, increment_dt, False)

    def assign(self, model, state, force, moment, increment_dt):
        """As ``accumulate`` into zeroed force and moment, but the pair loads stored (zero
        for a particle without a loaded row): the step, whose first law this is without
        bonds, then need not zero the arrays (0.3 ms of the 10^5 bed's 9 ms step)."""
        self._loads(model, state, force, moment, increment_dt, True)

    def _loads(self, model, state, force, moment, increment_dt, assign):
        moved_dt = self.update_lists(model, state, increment_dt)
        self.pair_loads(model, state, force, moment, increment_dt, moved_dt, assign=assign)
        self.wall_loads(model, state, force, moment, increment_dt, moved_dt)

    def update_lists(self, model, state, increment_dt):
        """The step's first part: rebuild the pair and wall lists if something moved more
        than skin/2 and derive their indices; returns the time (s) since the last
        evaluation (``pair_loads``, ``wall_loads``)."""
        self._last_state = state
        self._t_wall = self.wall_time(state, increment_dt)
        if self._needs_rebuild(model, state):
            self._rebuild(model, state)
        self._derive(model, state)
        counters = state.extra["contact_counters"]
        moved_dt = state.time - counters[3]  # 0 after the start-up kick: nothing moved
        counters[3] = state.time
        return moved_dt

    def pair_loads(self, model, state, force, moment, increment_dt, moved_dt, assign=False):
        """Add the particle-particle contacts' loads (N, N m) after ``update_lists``, or
        store them (``assign``)."""
        extra = state.extra
        if not self._live.shape[0]:
            # no pair listed, or every one bonded: no load, nothing dissipated
            if assign:
                force.fill(0.0)
                moment.fill(0.0)
            return
        rows = pair_rows(extra, self._dissipated)
        if self._chunk_work.shape[0] != chunks(self._live.shape[0]):
            self._chunk_work = np.ones(chunks(self._live.shape[0]))
        particle_contacts(
            self._live, self._quiet, extra["contact_pairs"], self._pair_bond,
            state.bond_active, cpu.particles(state), self.grains(model), self._materials,
            self._kernel_law(), self.reach()[0], bool(self.settings.rolling_resistance),
            cpu.box(model), rows, increment_dt, moved_dt,
            self.musen_code if self.musen_compat else None, self._chunk_work,
            numba.get_num_threads())
        gather_pair_loads(
            loops.PairIndex(self._i_start, self._i_order, self._j_start, self._j_order,
                            self._quiet),
            rows, force, moment, assign)
        extra["contact_counters"][0] += float(self._dissipated.sum())

    def _kernel_law(self):
        """The kernels' law argument: None (Hertz-Mindlin pruned in by type) only in SPEC
        mode. MUSEN's numerics always take the code, and the walls' triangle code too:
        each mode then compiles one variant of the big kernels (compile time, not speed,
        matters for the compatibility runs)."""
        return self.wall_law if self.musen_compat else self._law

    def wall_loads(self, model, state, force, moment, increment_dt, moved_dt):
        """Add the particle-wall contacts' loads (N, N m) after ``update_lists``; the
        walls' totals go to ``wall_force`` and ``wall_torque``."""
        if not self.walls.n_walls:
            return
        extra = state.extra
        counters = extra["contact_counters"]
        wall_pairs = extra["wall_pairs"]
        if wall_pairs.shape[0]:
            wall_contacts(
                self._wall_near, self._wall_start, wall_pairs,
                self.wall_tuple(self._t_wall, still=self._walls_still(state)),
                cpu.particles(state), self.grains(model), self._materials,
                self._kernel_law(), self.reach()[1], bool(self.settings.rolling_resistance),
                True if self.musen_compat else self._triangles,
                loops.WallRows(extra["wall_spring"], extra["wall_force_rows"],
                               extra["wall_moment_rows"], extra["wall_energy_rows"],
                               self._w_dissipated, self._w_work, self._w_distance,
                               self._w_point, self._w_feature,
                               extra.get("wall_tangential", NO_TANGENTIAL)),
                increment_dt, moved_dt, force, moment,
                self.musen_code if self.musen_compat else None)
            counters[0] += float(self._w_dissipated.sum())
            counters[1] += float(self._w_work.sum())
        wall_totals(wall_pairs, self.walls.element_wall, self._w_point,
                    extra["wall_force_rows"], extra["wall_moment_rows"],
                    state.position, model.radius, self.walls.positions(self._t_wall),
                    self.wall_force, self.wall_torque)

    def grains(self, model, put=lambda a: a):
        """The particle constants the contact bodies read, as a ``loops.Grains``."""
        return loops.Grains(put(model.radius), put(model.mass), put(model.inertia),
                            put(model.material))

    def wall_tuple(self, time, put=lambda a: a, rows=None, still=False):
        """The walls at ``time`` (s) as a ``loops.Walls``; rows: their element rows if
        already placed; still: with zero velocities and spins (MUSEN's walls in its
        prediction step, before its first MoveWalls sets their motion)."""
        w = self.walls
        velocity, spin = w.velocities(time), w.angular_velocity
        if still:
            velocity, spin = np.zeros_like(velocity), np.zeros_like(spin)
        return loops.Walls(put(w.elements(time)) if rows is None else rows,
                           put(w.element_type), put(w.element_wall), put(velocity),
                           put(spin), put(w.centers(time)),
                           *(put(a) for a in self._wall_materials), put(self._wall_pair))

    def row_counts(self):
        """What the last step's pair and wall kernels went through (the bench's byte
        counts, ``bench.part_bytes``): a dict of ``live`` (pair rows visited),
        ``evaluated`` (live rows holding a load, an energy or a dissipation), ``loaded``
        (particles in an evaluated row), ``ends`` (rows the gather sums: every row of a
        loaded particle, at each of its ends) and ``wall_rows`` (particle-wall
        candidates); all 0 before the first step."""
        if self._last_state is None:
            return dict.fromkeys(("live", "evaluated", "loaded", "ends", "wall_rows"), 0)
        extra = self._last_state.extra
        live = self._live
        busy = live[self._quiet[live] == 0]
        loaded = np.zeros(self._i_start.shape[0] - 1, dtype=bool)
        loaded[extra["contact_pairs"][busy, 0]] = True
        loaded[extra["contact_pairs"][busy, 1]] = True
        rows = np.diff(self._i_start) + np.diff(self._j_start)
        return {"live": int(live.shape[0]), "evaluated": int(busy.shape[0]),
                "loaded": int(loaded.sum()), "ends": int(rows[loaded].sum()),
                "wall_rows": int(extra["wall_pairs"].shape[0])}

    def touching(self):
        """(particle pairs, particle-wall contacts) that carried a load in the last step."""
        if self._last_state is None:
            return 0, 0
        extra = self._last_state.extra
        return (int(np.count_nonzero(np.any(extra["contact_force"] != 0.0, axis=1))),
                int(np.count_nonzero(np.any(extra["wall_force_rows"] != 0.0, axis=1))))

    def energy_terms(self, model, state):
        """contact_elastic (J stored in the contacts at the last evaluation),
        dissipated_contacts and work_walls (J, cumulative)."""
        extra = state.extra
        counters = extra.get("contact_counters", np.zeros(4))
        elastic = float(extra["contact_energy"].sum()) + float(extra["wall_energy_rows"].sum()) \
            if "contact_energy" in extra else 0.0
        return {"contact_elastic": elastic, "dissipated_contacts": float(counters[0]),
                "work_walls": float(counters[1])}

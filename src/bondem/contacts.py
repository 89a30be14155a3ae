"""Contact settings and the contact law the Simulation runs (SPEC section 3).

``ContactSettings`` chooses the pair law (``physics.contact_hertz`` / ``contact_linear``);
``ContactLaw`` is the object in ``Simulation.laws``: each step it refreshes the Verlet lists
(``neighbors``, ``walls``) when some particle or wall moved more than skin/2, computes every
listed contact and adds the loads per particle.

All contact history lives in ``state.extra`` as NumPy arrays, so a checkpoint of
``state.arrays()`` resumes bit for bit:
    contact_pairs (M,2) int64        Verlet list of particle pairs (i < j, sorted)
    contact_spring (M,3) m           tangential spring of each pair (0 when apart)
    contact_reference_position (N,3) m  positions at the last rebuild
    contact_reference_time (1,) s    time of the last rebuild (walls move from there)
    contact_force, contact_moment_i, contact_moment_j (M,3)  last loads of each pair (N, N m)
    contact_energy (M,) J            energy stored in each pair at the last evaluation
    contact_counters (4,)            [dissipated J, work of walls J, rebuilds, time of the
                                     last evaluation s]
    wall_pairs (K,2) int64           (particle, wall element) candidates, sorted
    wall_spring (K,3) m              tangential spring of each wall candidate
    wall_force_rows, wall_moment_rows (K,3), wall_energy_rows (K,)  as for pairs
The last loads and energies serve the work balance that books the dissipated energy:
per contact, minus the work of its loads over the step (trapezoidal) minus the change of
its stored energy; with the leapfrog this closes the energy balance to O(dt^2).
Everything else (CSR indices, bond lookup) is derived from these and rebuilt on demand.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .backends import cpu, loops
from .backends import cpu_contacts as kernels
from .neighbors import build_pairs, carry_history, max_displacement
from .walls import PLANE, WallSet, build_wall_pairs

PAIR_HISTORY = {"contact_spring": (3,), "contact_force": (3,), "contact_moment_i": (3,),
                "contact_moment_j": (3,), "contact_energy": ()}
WALL_HISTORY = {"wall_spring": (3,), "wall_force_rows": (3,), "wall_moment_rows": (3,),
                "wall_energy_rows": ()}
MODELS = {"hertz_mindlin": kernels.MODEL_HERTZ, "linear": kernels.MODEL_LINEAR, "none": -1}


def contact_cutoff(radius, skin=None):
    """(cut-off 2 r_max + skin, skin) in m of the pair search for particle radii ``radius``
    (m); skin: the Verlet skin (m), default a fifth of the mean radius."""
    radius = np.asarray(radius, dtype=np.float64)
    if skin is None:
        skin = 0.2 * float(radius.mean()) if radius.size else 0.0
    return 2.0 * float(radius.max(initial=0.0)) + skin, skin


@dataclass(frozen=True)
class ContactSettings:
    """Contact options.

    model: "hertz_mindlin" | "linear" | "none" (no particle-particle contacts; walls then
    use Hertz-Mindlin); bonded_pairs: also give contact forces to pairs joined by an intact
    bond; rolling_resistance: apply the materials' rolling friction; skin: Verlet skin (m),
    None for 0.2 times the mean radius; linear_stiffness: k_n (N/m) of the linear model,
    None for the Hertz stiffness at an overlap of 1 % of R* (see contact_linear).
    """
    model: str = "hertz_mindlin"
    bonded_pairs: bool = False
    rolling_resistance: bool = True
    skin: float | None = None
    linear_stiffness: float | None = None

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"contact model = {self.model!r}; allowed: "
                             + ", ".join(repr(k) for k in MODELS))
        if self.skin is not None and not (self.skin > 0.0 and math.isfinite(self.skin)):
            raise ValueError(f"contact skin = {self.skin!r} m; allowed range (0, inf)")
        if self.linear_stiffness is not None and not (
                self.linear_stiffness > 0.0 and math.isfinite(self.linear_stiffness)):
            raise ValueError(f"contact linear_stiffness = {self.linear_stiffness!r} N/m; "
                             "allowed range (0, inf)")


def contact_time_scales(model, settings):
    """Extra time scales (s) of the contact law: for the linear model sqrt(m*/k_n) of the
    lightest self-pair (m* = m/2); Hertz-Mindlin is covered by the Rayleigh step."""
    if settings is None or settings.model != "linear" or model.n_particles == 0:
        return {}
    table = model.material_table()
    young = table["young_modulus"][model.material]
    poisson = table["poisson_ratio"][model.material]
    if settings.linear_stiffness is not None:
        stiffness = np.full(model.n_particles, settings.linear_stiffness)
    else:
        e_star = young / (2.0 * (1.0 - poisson ** 2))
        stiffness = (2.0 * e_star * math.sqrt(kernels.LINEAR_REFERENCE_OVERLAP)
                     * 0.5 * model.radius)
    return {"contact_linear": float(np.sqrt(0.5 * model.mass / stiffness).min())}


def pair_rows(extra, dissipated):
    """The contact history rows of ``state.extra`` and ``dissipated`` (J per row) as a
    ``loops.PairRows``."""
    return loops.PairRows(extra["contact_spring"], extra["contact_force"],
                          extra["contact_moment_i"], extra["contact_moment_j"],
                          extra["contact_energy"], dissipated)


def _csr_by(index, n):
    """(start (n+1,), order) grouping rows by ``index`` (stable)."""
    order = np.argsort(index, kind="stable").astype(np.int64)
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(index, minlength=n), out=start[1:])
    return start, order


class ContactLaw:
    """Particle-particle and particle-wall contacts on the CPU.

    model: the Model; settings: ContactSettings; walls: PlaneWall / MeshWall objects.
    After each step ``wall_force`` (W,3) N and ``wall_torque`` (W,3) N m (about each wall's
    reference point) hold the loads on the walls.
    """

    name = "contacts"

    def __init__(self, model, settings=None, walls=()):
        self.settings = settings if settings is not None else ContactSettings()
        self.pair_law = MODELS[self.settings.model]
        self.wall_law = self.pair_law if self.pair_law >= 0 else kernels.MODEL_HERTZ
        self.walls = WallSet(walls)
        table = model.material_table()
        self._materials = loops.ContactMaterials(
            table["young_modulus"], table["poisson_ratio"], table["restitution"],
            table["friction"], table["rolling_friction"])
        wm = [w.material for w in self.walls.walls]
        self._wall_materials = tuple(np.array([getattr(m, k) for m in wm], dtype=np.float64)
                                     for k in ("young_modulus", "poisson_ratio", "restitution",
                                               "friction", "rolling_friction"))
        n = model.n_particles
        cutoff, self.skin = contact_cutoff(model.radius, self.settings.skin)
        self._box_length = model.box_length
        self._k_linear = float(self.settings.linear_stiffness or 0.0)  # N/m, 0: default
        # None selects Hertz-Mindlin in the CPU kernels (by type: only the law in use compiles)
        self._linear_stiffness = (None if self.pair_law == kernels.MODEL_HERTZ
                                  or self.pair_law < 0
                                  else self._k_linear)
        self._wall_stiffness = (None if self.wall_law == kernels.MODEL_HERTZ
                                else self._linear_stiffness)
        # True when a wall has triangles, else None (the kernel then has no triangle code)
        self._triangles = True if np.any(self.walls.element_type != PLANE) else None
        if np.any(model.periodic & (self._box_length < 2.0 * cutoff)):
            raise ValueError(f"periodic box lengths {self._box_length[model.periodic].tolist()} "
                             f"m must be at least twice the contact cut-off {cutoff:.3g} m")
        bonds = np.sort(model.bond_pairs, axis=1)
        self._bond_key = bonds[:, 0] * np.int64(n) + bonds[:, 1]
        self._bond_order = np.argsort(self._bond_key, kind="stable")
        self._derived_for = None
        self._last_state = None
        self.wall_force = np.zeros((self.walls.n_walls, 3))
        self.wall_torque = np.zeros((self.walls.n_walls, 3))

    # -- lists ------------------------------------------------------------------------
    def _rebuild(self, model, state):
        extra = state.extra
        position = state.position
        empty2 = np.zeros((0, 2), np.int64)
        if self.pair_law >= 0:
            pairs = build_pairs(position, model.radius, self.skin, model.periodic,
                                model.box_low, model.box_high)
        else:
            pairs = empty2
        old_pairs = extra.get("contact_pairs", empty2)
        for name, shape in PAIR_HISTORY.items():
            extra[name] = carry_history(old_pairs, extra.get(name, np.zeros((0,) + shape)),
                                        pairs, model.n_particles)
        extra["contact_pairs"] = pairs
        rows = self.walls.elements(state.time)
        wall_pairs = build_wall_pairs(position, model.radius, self.skin, rows,
                                      self.walls.element_type)
        old_wall_pairs = extra.get("wall_pairs", empty2)
        for name, shape in WALL_HISTORY.items():
            extra[name] = carry_history(old_wall_pairs,
                                        extra.get(name, np.zeros((0,) + shape)), wall_pairs,
                                        max(1, self.walls.n_elements))
        extra["wall_pairs"] = wall_pairs
        extra["contact_reference_position"] = position.copy()
        extra["contact_reference_time"] = np.array([state.time])
        counters = extra.setdefault("contact_counters", np.array([0.0, 0.0, 0.0, state.time]))
        counters[2] += 1.0

    def _needs_rebuild(self, model, state):
        extra = state.extra
        if "contact_pairs" not in extra:
            return True
        moved = max_displacement(state.position, extra["contact_reference_position"],
                                 self._box_length, model.periodic)
        moved += self.walls.max_displacement(state.time - extra["contact_reference_time"][0])
        return moved > 0.5 * self.skin

    def _derive_live(self, model, state):
        """Rows that can carry a contact load (no intact bond joins the pair) and their
        CSR indices by particle; redone when a bond breaks."""
        pairs = state.extra["contact_pairs"]
        n = model.n_particles
        bonded = self._pair_bond >= 0
        bonded[bonded] = state.bond_active[self._pair_bond[bonded]]
        self._live = np.flatnonzero(~bonded).astype(np.int64)
        # rows are sorted by i, so the live rows are too: i's CSR needs no sort
        self._i_order = self._live
        self._i_start = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(pairs[self._live, 0], minlength=n), out=self._i_start[1:])
        j_start, j_order = _csr_by(pairs[self._live, 1], n)
        self._j_start, self._j_order = j_start, self._live[j_order]
        self._active_bonds = int(np.count_nonzero(state.bond_active))

    def _derive(self, model, state):
        """CSR indices and bond lookup for the current lists (cached per list object)."""
        extra = state.extra
        key = (extra["contact_pairs"], extra["wall_pairs"])
        if self._derived_for is not None and all(a is b for a, b in zip(key, self._derived_for)):
            if int(np.count_nonzero(state.bond_active)) != self._active_bonds:
                self._derive_live(model, state)
            return
        n = model.n_particles
        pairs = extra["contact_pairs"]
        self._pair_bond = np.full(pairs.shape[0], -1, dtype=np.int64)
        if self._bond_key.size and pairs.shape[0] and not self.settings.bonded_pairs:
            key_pairs = pairs[:, 0] * np.int64(n) + pairs[:, 1]
            sorted_keys = self._bond_key[self._bond_order]
            where = np.minimum(np.searchsorted(sorted_keys, key_pairs), sorted_keys.size - 1)
            hit = sorted_keys[where] == key_pairs
            self._pair_bond[hit] = self._bond_order[where[hit]]
        self._derive_live(model, state)
        self._dissipated = np.zeros(pairs.shape[0])
        wall_pairs = extra["wall_pairs"]
        k = wall_pairs.shape[0]
        self._wall_start = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(wall_pairs[:, 0], minlength=n), out=self._wall_start[1:])
        self._w_distance = np.zeros(k)
        self._w_point = np.zeros((k, 3))
        self._w_feature = np.zeros(k, dtype=np.int64)
        self._w_dissipated = np.zeros(k)
        self._w_work = np.zeros(k)
        self._derived_for = key

    # -- the law ----------------------------------------------------------------------
    def accumulate(self, model, state, force, moment, increment_dt):
        """Add contact and wall loads (N, N m) for the state at the start of the step;
        advance the tangential springs by ``increment_dt`` (s)."""
        self._last_state = state
        if self._needs_rebuild(model, state):
            self._rebuild(model, state)
        self._derive(model, state)
        extra = state.extra
        counters = extra["contact_counters"]
        moved_dt = state.time - counters[3]  # 0 after the start-up kick: nothing moved
        counters[3] = state.time
        use_rolling = bool(self.settings.rolling_resistance)
        particles = cpu.particles(state)
        grains = self.grains(model)
        if extra["contact_pairs"].shape[0]:
            rows = pair_rows(extra, self._dissipated)
            kernels.particle_contacts(
                self._live, extra["contact_pairs"], self._pair_bond, state.bond_active,
                particles, grains, self._materials, self.pair_law, self._linear_stiffness,
                use_rolling, cpu.box(model), rows, increment_dt, moved_dt)
            kernels.gather_pair_loads(
                loops.PairIndex(self._i_start, self._i_order, self._j_start, self._j_order),
                rows, force, moment)
            counters[0] += float(self._dissipated.sum())
        if self.walls.n_walls:
            wall_pairs = extra["wall_pairs"]
            if wall_pairs.shape[0]:
                kernels.wall_contacts(
                    self._wall_start, wall_pairs, self.wall_tuple(state.time), particles,
                    grains, self._materials, self.wall_law, self._wall_stiffness,
                    use_rolling, self._triangles,
                    loops.WallRows(extra["wall_spring"], extra["wall_force_rows"],
                                   extra["wall_moment_rows"], extra["wall_energy_rows"],
                                   self._w_dissipated, self._w_work, self._w_distance,
                                   self._w_point, self._w_feature),
                    increment_dt, moved_dt, force, moment)
                counters[0] += float(self._w_dissipated.sum())
                counters[1] += float(self._w_work.sum())
            kernels.wall_totals(wall_pairs, self.walls.element_wall, self._w_point,
                                extra["wall_force_rows"], extra["wall_moment_rows"],
                                state.position, model.radius, self.walls.positions(state.time),
                                self.wall_force, self.wall_torque)

    def grains(self, model, put=lambda a: a):
        """The particle constants the contact bodies read, as a ``loops.Grains``."""
        return loops.Grains(put(model.radius), put(model.mass), put(model.inertia),
                            put(model.material))

    def wall_tuple(self, time, put=lambda a: a, rows=None):
        """The walls at ``time`` (s) as a ``loops.Walls``; rows: their element rows if
        already placed."""
        w = self.walls
        return loops.Walls(put(w.elements(time)) if rows is None else rows,
                           put(w.element_type), put(w.element_wall), put(w.velocity),
                           put(w.angular_velocity), put(w.centers(time)),
                           *(put(a) for a in self._wall_materials))

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

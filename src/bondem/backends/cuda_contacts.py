"""Particle contacts and walls on the CUDA backend: the CPU ContactLaw's loops as kernels.

``ContactLawGpu`` is ``cpu_contacts.ContactLaw`` with its per-step loops moved to the device;
the kernels run the CPU's loop bodies (``backends/loops.py``: pair_contact,
pair_rows_sum, wall_contacts_of, add_wall_rows), compiled with ``cuda.jit(device=True)``.

What runs where:
- every step, on the device: the rebuild test (largest displacement since the list was
  built, minimum image, plus the walls' motion bound), the pair kernel (one thread per
  listed pair, each writing its own row), the pair gather (one thread per particle, CSR,
  no atomics), the wall kernel (one thread per particle: its wall candidates, the
  double-hit filter of meshes, the spring hand-over, the loads, and the gather of its
  wall rows, in the CPU's order);
- once a particle moved half the skin: the device positions are copied back and the CPU
  law's own test decides (its relative trigger: whether neighbours moved a skin relative
  to each other), so both backends rebuild at the same steps;
- at a list rebuild, on the host: the device
  position, bond flags and history rows are copied back, the CPU ``ContactLaw`` rebuilds
  the lists with the same code (so the lists, their order and the carried springs are the
  CPU's), and the new lists go back to the device;
- at the end of each batch of steps (``to_host``): the history rows are copied into
  ``state.extra`` with the CPU layout (contact_pairs, contact_spring, ..., wall_pairs,
  wall_spring, ...), the dissipated energy and wall work counters are added to
  ``contact_counters`` and ``wall_force`` / ``wall_torque`` of the last step are summed
  on the host by the CPU's ``wall_totals`` (serial, list order).

Differences from the CPU law that do not change results: every listed pair is visited
(the CPU visits only pairs not held by an intact bond; on the device such a pair's row is
left at zero, as the CPU leaves it), so the gather adds exact zeros; energy counters are
summed per particle, then on the host, instead of per step (round-off only).
"""
import math

import numpy as np
from numba import cuda

from ..contacts import MUSEN_PAIR_HISTORY, MUSEN_WALL_HISTORY
from .cpu_contacts import NO_TANGENTIAL, ContactLaw, csr_by, pair_rows
from . import cpu_contacts, loops
from .cpu import particles
from .cuda_device import K, launch

pair_contact = K.pair_contact
pair_rows_sum = K.pair_rows_sum
wall_contacts_of = K.wall_contacts_of
add_wall_rows = K.add_wall_rows
row3 = K.row3


@cuda.jit(device=True)
def _image(d, length, periodic):
    """Component d (m) wrapped into [-length/2, length/2) if periodic (minimum image)."""
    if periodic:
        return d - length * math.floor(d / length + 0.5)
    return d


@cuda.jit
def displacement_flag_kernel(position, reference, box_length, periodic, limit_squared, flag):
    """flag[0] = 1 when a particle moved more than sqrt(limit_squared) (m, minimum image)
    since the lists were built (a plain store of 1: any order gives the same flag)."""
    p = cuda.grid(1)
    if p < position.shape[0]:
        d2 = 0.0
        for k in range(3):
            d = _image(position[p, k] - reference[p, k], box_length[k], periodic[k])
            d2 += d * d
        if d2 > limit_squared:
            flag[0] = 1


@cuda.jit
def particle_contacts_kernel(pairs, pair_bond, bond_active, particles, grains, materials,
                             law, reach, use_rolling, box, rows, dt, moved_dt,
                             musen):
    """``loops.pair_contact`` for every listed pair (the CPU visits only the rows no
    intact bond holds; a held row stays zero either way)."""
    for c in range(cuda.grid(1), pairs.shape[0], cuda.gridsize(1)):
        pair_contact(c, pairs, pair_bond, bond_active, particles, grains, materials, law,
                     reach, use_rolling, box, rows, dt, moved_dt, musen)


@cuda.jit
def gather_pairs_kernel(index, rows, force, moment, dissipated):
    """``loops.pair_rows_sum`` for every particle, added to force (N) and moment (N m);
    the J dissipated by the rows where it is i added to dissipated[p] (summed on the host
    at the end of the batch)."""
    for p in range(cuda.grid(1), index.i_start.shape[0] - 1, cuda.gridsize(1)):
        f, m = pair_rows_sum(p, index, rows)
        lost = 0.0
        for s in range(index.i_start[p], index.i_start[p + 1]):
            lost += rows.dissipated[index.i_order[s]]
        for k in range(3):
            force[p, k] += f[k]
            moment[p, k] += m[k]
        dissipated[p] += lost


@cuda.jit
def wall_contacts_kernel(wall_start, wall_pairs, walls, particles, grains, materials, law,
                         reach, use_rolling, rows, dt, moved_dt, force, moment,
                         dissipated, work_walls, evaluated_position, musen):
    """``loops.wall_contacts_of`` for every particle, its wall loads added to force (N)
    and moment (N m) after the pair loads, in list order; the J its rows dissipated and
    the walls' work on it added to dissipated[p] and work_walls[p]; the position it used
    (m) stored for the wall totals summed on the host."""
    for p in range(cuda.grid(1), wall_start.shape[0] - 1, cuda.gridsize(1)):
        for k in range(3):
            evaluated_position[p, k] = particles.position[p, k]
        wall_contacts_of(p, wall_start, wall_pairs, walls, particles, grains, materials, law,
                         reach, use_rolling, True, rows, dt, moved_dt, musen)
        add_wall_rows(p, wall_start, rows, force, moment)
        lost = 0.0
        done = 0.0
        for c in range(wall_start[p], wall_start[p + 1]):
            lost += rows.dissipated[c]
            done += rows.work[c]
        dissipated[p] += lost
        work_walls[p] += done


def _at_least_one(array):
    """Kernels take non-empty arrays; an empty list passes one unused row."""
    return array if array.shape[0] else np.zeros((1,) + array.shape[1:], array.dtype)


class ContactLawGpu(ContactLaw):
    """``ContactLaw`` (particle contacts and walls, Hertz-Mindlin or linear) on the device.

    Same arguments, results, ``state.extra`` layout, ``wall_force`` (W,3) N and
    ``wall_torque`` (W,3) N m (of the last step, updated at the end of each batch) and
    ``energy_terms`` as the CPU law; ``Simulation(..., backend="gpu", contact=...,
    walls=...)`` builds it. Lists are rebuilt on the host by the CPU code (see the module
    docstring); the host ``state.extra`` is refreshed by ``to_host`` at the end of each
    batch, and a host ``state.extra`` (a checkpoint) is taken up by ``to_device``.
    """

    backend = "gpu"

    def attach(self, backend):
        """Take the device state of ``backend`` (a GpuBackend); upload the constants."""
        self.g = backend
        model = backend.model
        put = cuda.to_device
        self._d_grains = self.grains(model, put)
        self._d_materials = loops.ContactMaterials(*(put(a) for a in self._materials))
        self._put_walls = lambda a: put(_at_least_one(a))
        self._moving = self.walls.moving
        self._flag = put(np.zeros(1, dtype=np.int64))
        self._d_rows = None
        self._rows_host = None
        n = model.n_particles
        self._d_lost = cuda.to_device(np.zeros(n))
        self._d_work = cuda.to_device(np.zeros(n))
        self._evaluated_position = cuda.to_device(np.zeros((n, 3)))
        self._evaluated_time = None
        self._dev = None   # device lists and history rows; None: take them from the host
        backend.register_transfers(self)

    # -- host <-> device ------------------------------------------------------------------
    def to_device(self, state):
        """The host ``state`` (incl. ``state.extra``) was edited or replaced: the next step
        takes the lists and history rows from it."""
        self._dev = None
        zeros = np.zeros(self.g.model.n_particles)
        self._d_lost.copy_to_device(zeros)
        self._d_work.copy_to_device(zeros)

    def _pull_history(self, state):
        """Copy the device history rows into ``state.extra`` (new host arrays)."""
        pair_history, wall_history = self.history()
        for name in (*pair_history, *wall_history):
            count = self._counts[0] if name in pair_history else self._counts[1]
            state.extra[name] = self._dev[name].copy_to_host()[:count]

    def to_host(self, state):
        """Copy the history rows into ``state.extra``, add the energy counters and sum the
        loads on the walls of the last step (N, N m)."""
        if self._dev is None:
            return
        self._pull_history(state)
        counters = state.extra["contact_counters"]
        counters[0] += float(self._d_lost.copy_to_host().sum())
        counters[1] += float(self._d_work.copy_to_host().sum())
        zeros = np.zeros(self.g.model.n_particles)
        self._d_lost.copy_to_device(zeros)
        self._d_work.copy_to_device(zeros)
        if self.walls.n_walls and self._evaluated_time is not None:
            wall_pairs = state.extra["wall_pairs"]
            point = self._dev["wall_rows"].point.copy_to_host()[:wall_pairs.shape[0]]
            cpu_contacts.wall_totals(
                wall_pairs, self.walls.element_wall, point, state.extra["wall_force_rows"],
                state.extra["wall_moment_rows"], self._evaluated_position.copy_to_host(),
                self.g.model.radius, self.walls.positions(self._evaluated_time),
                self.wall_force, self.wall_torque)

    def _upload(self, model, state):
        """Send the host lists (just built or taken from a checkpoint) to the device."""
        self._derive(model, state)
        extra = state.extra
        put = cuda.to_device
        n = model.n_particles
        pairs = extra["contact_pairs"]
        wall_pairs = extra["wall_pairs"]
        # CSR over every row (the CPU's over live rows; the others stay zero).
        i_start = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(pairs[:, 0], minlength=n), out=i_start[1:])
        j_start, j_order = csr_by(pairs[:, 1], n)
        k = wall_pairs.shape[0]
        dev = {"pairs": put(_at_least_one(pairs)),
               "pair_bond": put(_at_least_one(self._pair_bond)),
               "index": loops.PairIndex(put(i_start),
                                        put(np.arange(max(pairs.shape[0], 1))),
                                        put(j_start), put(_at_least_one(j_order)),
                                        put(np.zeros(max(pairs.shape[0], 1), np.uint8))),
               "wall_pairs": put(_at_least_one(wall_pairs)),
               "wall_start": put(self._wall_start),
               "reference": put(extra["contact_reference_position"])}
        pair_history, wall_history = self.history()
        for name in (*pair_history, *wall_history):
            dev[name] = put(_at_least_one(np.ascontiguousarray(extra[name])))
        for name in (*MUSEN_PAIR_HISTORY, *MUSEN_WALL_HISTORY):   # a SPEC run's unused row
            if name not in dev:
                dev[name] = put(NO_TANGENTIAL)
        dev["pair_rows"] = pair_rows(dev, cuda.device_array(max(pairs.shape[0], 1)))
        dev["wall_rows"] = loops.WallRows(
            dev["wall_spring"], dev["wall_force_rows"], dev["wall_moment_rows"],
            dev["wall_energy_rows"], cuda.device_array(max(k, 1)),
            cuda.device_array(max(k, 1)), cuda.device_array(max(k, 1)),
            cuda.to_device(np.zeros((max(k, 1), 3))),
            cuda.device_array(max(k, 1), dtype=np.int64), dev["wall_tangential"])
        self._counts = (pairs.shape[0], k)
        self._dev = dev

    def _sync_for_rebuild(self, state):
        """Bring what the host rebuild reads up to date: position, bond flags, history."""
        d = self.g.device
        d.position.copy_to_host(state.position)
        d.bond_active.copy_to_host(state.bond_active)
        self._pull_history(state)

    def _host_needs_rebuild(self, model, state):
        """The CPU law's test (``ContactLaw._needs_rebuild``, its relative trigger
        included) on the device's positions, once the device saw a particle move skin/2:
        both backends rebuild at the same steps, so their lists stay equal."""
        self.g.device.position.copy_to_host(state.position)
        return self._needs_rebuild(model, state)

    def _device_needs_rebuild(self, model, state):
        extra = state.extra
        limit = 0.5 * self.skin - self.walls.max_displacement(
            self._t_wall, self._t_wall - extra["contact_reference_time"][0])
        if not limit > 0.0:
            return True
        self._flag.copy_to_device(np.zeros(1, dtype=np.int64))
        n = model.n_particles
        launch(displacement_flag_kernel, n, self.g.device.position, self._dev["reference"],
               self.g.box_length, self.g.periodic, limit * limit, self._flag)
        return bool(self._flag.copy_to_host()[0])

    # -- the law ----------------------------------------------------------------------
    def accumulate(self, model, state, force, moment, increment_dt):
        """Add contact and wall loads (N, N m) into the device force and moment, for the
        device state at the start of the step; springs advance by ``increment_dt`` (s)."""
        self._last_state = state
        self._t_wall = self.wall_time(state, increment_dt)
        if self._dev is None:
            # The host state is current here (just uploaded by the backend).
            if self._needs_rebuild(model, state):
                self._rebuild(model, state)
            self._upload(model, state)
        elif self._device_needs_rebuild(model, state) and self._host_needs_rebuild(model,
                                                                                  state):
            self._sync_for_rebuild(state)
            self._rebuild(model, state)
            self._upload(model, state)
        dev = self._dev
        g = self.g
        d = g.device
        n = model.n_particles
        counters = state.extra["contact_counters"]
        moved_dt = state.time - counters[3]  # 0 after the start-up kick: nothing moved
        counters[3] = state.time
        use_rolling = bool(self.settings.rolling_resistance)
        if self._counts[0]:
            launch(particle_contacts_kernel, self._counts[0], dev["pairs"], dev["pair_bond"],
                   d.bond_active, particles(d), self._d_grains, self._d_materials,
                   self.wall_law, self.reach()[0], use_rolling, g.box, dev["pair_rows"],
                   increment_dt, moved_dt, self.musen_code if self.musen_compat else 0)
            launch(gather_pairs_kernel, n, dev["index"], dev["pair_rows"], force,
                   moment, self._d_lost)
        if self.walls.n_walls:
            rows = self.walls.elements(self._t_wall)
            if rows is not self._rows_host:   # static walls: the same rows object
                self._d_rows = cuda.to_device(rows)
                self._rows_host = rows
            launch(wall_contacts_kernel, n, dev["wall_start"], dev["wall_pairs"],
                   self.wall_tuple(self._t_wall, self._put_walls, self._d_rows,
                                   self._walls_still(state)), particles(d),
                   self._d_grains, self._d_materials, self.wall_law, self.reach()[1],
                   use_rolling, dev["wall_rows"], increment_dt, moved_dt, force, moment,
                   self._d_lost, self._d_work, self._evaluated_position,
                   self.musen_code if self.musen_compat else 0)
            self._evaluated_time = self._t_wall

"""CUDA backend: the CPU backend's loops as numba-cuda kernels, calling the same physics.

The physics functions of ``bondem.physics`` are compiled once more, with
``numba.cuda.jit(device=True)``; the kernels here only index arrays and call them, exactly
as ``backends/cpu.py`` does with ``numba.njit``. So the two backends differ only in the
order of floating-point sums where a sum has no fixed order (energy totals), and in what
the compilers do with round-off (fused multiply-add on the GPU).

Design (the same as the CPU backend's, see its docstring):
- one thread per bond computes the bond law and writes its loads to the bond's own slot;
- one thread per particle sums its bonds through the fixed CSR index (particle -> bond
  ends): no atomics, the same bits every run; the same thread adds the other laws' loads
  (if any) and integrates, so a bonds-only step is two launches and never stores the
  particle forces; a particle that turns NaN or leaves the domain sets a status flag,
  checked by the host once per batch of steps (no exceptions in kernels);
- every changing array lives on the device (``DeviceState``) between outputs; the host
  ``State`` is refreshed by ``GpuBackend.to_host`` at the end of each batch of steps.
- work and damping energies are accumulated per particle on the device and summed on the
  host only when the state is copied back (a fixed order, so no atomics there either).

The neighbour search (``neighbour_pairs``) sorts particles by cell (bitonic sort of
(cell, particle) keys), finds each cell's start by binary search in the sorted keys, then
counts, scans and writes each particle's pairs: deterministic, no atomics.

Importing this module does not need a GPU; ``GpuBackend`` raises ``BackendUnavailable``
when neither a CUDA device nor the simulator (NUMBA_ENABLE_CUDASIM=1) is there.
"""
import math

import numpy as np
from numba import cuda

from ..errors import InputError
from ..physics import compile_physics
from ..physics.bond_elastic import INTACT
from ..integrate import step_plan
from ..status import STATUS_NOT_FINITE, STATUS_OK, STATUS_OUT_OF_DOMAIN, blow_up
from .cpu import particle_bond_index

D = compile_physics(cuda.jit(device=True))
elastic_bond = D.elastic_bond
elastic_bond_musen = D.elastic_bond_musen
bond_break_mode_musen = D.bond_break_mode_musen
bond_stiffnesses = D.bond_stiffnesses
bond_loads_on_particles = D.bond_loads_on_particles
bond_break_mode = D.bond_break_mode
bond_elastic_energy = D.bond_elastic_energy
minimum_image = D.minimum_image

THREADS = 128  # threads per block: a multiple of the warp, small enough for any register use


class BackendUnavailable(InputError, RuntimeError):
    """The requested backend cannot run on this machine (an input error for the command
    line: one line, exit status 2)."""


def _blocks(n):
    return max(1, (n + THREADS - 1) // THREADS)


# ---------------------------------------------------------------------------------------
# Kernels: bond law, gather, integration, energies
# ---------------------------------------------------------------------------------------

@cuda.jit
def elastic_bonds_kernel(pairs, diameter, initial_length, bond_material, bm_young,
                         bm_poisson, bm_normal_strength, bm_tangential_strength, bm_criterion,
                         bm_compressive, position, velocity, angular_velocity, box_length,
                         periodic, active, axis, previous_length, tangential_force,
                         normal_moment, tangential_moment, break_time, break_mode,
                         break_energy, time, dt, musen, out_force_i, out_moment_i,
                         out_moment_j):
    """One thread per bond: advance it by dt (s) and store its loads in its own slot.

    musen: MUSEN's numerics (``elastic_bond_musen``, ``bond_break_mode_musen``) instead of
    the SPEC's; previous_length (B,) m: |r| of the last step, which MUSEN's rotation needs.
    """
    b = cuda.grid(1)
    if b >= pairs.shape[0]:
        return
    if not active[b]:
        for k in range(3):
            out_force_i[b, k] = 0.0
            out_moment_i[b, k] = 0.0
            out_moment_j[b, k] = 0.0
        return
    i = pairs[b, 0]
    j = pairs[b, 1]
    m = bond_material[b]
    r = minimum_image((position[j, 0] - position[i, 0], position[j, 1] - position[i, 1],
                       position[j, 2] - position[i, 2]),
                      (box_length[0], box_length[1], box_length[2]),
                      periodic[0], periodic[1], periodic[2])
    kn, kt, ktw, kb = bond_stiffnesses(bm_young[m], bm_poisson[m], diameter[b],
                                       initial_length[b])
    vi = (velocity[i, 0], velocity[i, 1], velocity[i, 2])
    vj = (velocity[j, 0], velocity[j, 1], velocity[j, 2])
    wi = (angular_velocity[i, 0], angular_velocity[i, 1], angular_velocity[i, 2])
    wj = (angular_velocity[j, 0], angular_velocity[j, 1], angular_velocity[j, 2])
    f_t0 = (tangential_force[b, 0], tangential_force[b, 1], tangential_force[b, 2])
    m_n0 = (normal_moment[b, 0], normal_moment[b, 1], normal_moment[b, 2])
    m_t0 = (tangential_moment[b, 0], tangential_moment[b, 1], tangential_moment[b, 2])
    if musen:
        # MUSEN's numerics (physics/bond_elastic_musen.py): previous bond with length.
        lp = previous_length[b]
        length, n, f_n, f_t, m_n, m_t = elastic_bond_musen(
            r, vi, vj, wi, wj, (axis[b, 0] * lp, axis[b, 1] * lp, axis[b, 2] * lp),
            f_t0, m_n0, m_t0, initial_length[b], bm_young[m], bm_poisson[m],
            diameter[b], dt)
        mode = bond_break_mode_musen(length, initial_length[b], f_n, f_t, m_n, m_t,
                                     diameter[b], bm_normal_strength[m],
                                     bm_tangential_strength[m], bm_criterion[m])
    else:
        length, n, f_n, f_t, m_n, m_t = elastic_bond(
            r, vi, vj, wi, wj, (axis[b, 0], axis[b, 1], axis[b, 2]), f_t0, m_n0, m_t0,
            initial_length[b], kn, kt, ktw, kb, dt)
        mode = bond_break_mode(length, initial_length[b], f_n, f_t, m_n, m_t, diameter[b],
                               bm_normal_strength[m], bm_tangential_strength[m],
                               bm_criterion[m], bm_compressive[m])
    if mode != INTACT:
        active[b] = False
        break_time[b] = time
        break_mode[b] = mode
        break_energy[b] = bond_elastic_energy(length, initial_length[b], f_t, m_n, m_t,
                                              kn, kt, ktw, kb)
        for k in range(3):
            out_force_i[b, k] = 0.0
            out_moment_i[b, k] = 0.0
            out_moment_j[b, k] = 0.0
        return
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


@cuda.jit(device=True)
def _bond_sum(p, offsets, ends, force_i, moment_i, moment_j):
    """Force (N) and moment (N m) of particle p's bonds: the CSR ends of p in a fixed
    order (end = 2*bond + side, side 1 = j, which gets -F and its own moment)."""
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
    return (fx, fy, fz), (mx, my, mz)


@cuda.jit
def gather_bond_loads_kernel(offsets, ends, force_i, moment_i, moment_j, force, moment,
                             assign):
    """One thread per particle: sum its bond (or contact) ends through the CSR index and
    store (``assign``) or add the sums to force (N) and moment (N m)."""
    p = cuda.grid(1)
    if p >= offsets.shape[0] - 1:
        return
    f, m = _bond_sum(p, offsets, ends, force_i, moment_i, moment_j)
    for k in range(3):
        if assign:
            force[p, k] = f[k]
            moment[p, k] = m[k]
        else:
            force[p, k] += f[k]
            moment[p, k] += m[k]


@cuda.jit(device=True)
def _sign(x):
    """np.sign for a float: -1, 0 or +1."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@cuda.jit
def integrate_kernel(offsets, ends, bond_force_i, bond_moment_i, bond_moment_j, use_loads,
                     position, velocity, angular_velocity, force, moment, mass, inertia,
                     fixed, gravity, external_force, external_moment, damping, kick_dt,
                     drift_dt, box_low, box_high, periodic, status, work, dissipated):
    """One thread per particle: gather its bond loads (CSR, as the gather kernel), add
    the other laws' loads in force/moment when ``use_loads``, then the CPU ``integrate``
    step for step (see there). Fusing the gather saves a launch and the force arrays'
    write and read (96 B per particle) when the bonds are the only law.

    Instead of returning energy totals, adds each particle's work of gravity and external
    loads and its damping loss (J) to ``work[p]`` and ``dissipated[p]``, summed on the host
    when the state is copied back. Sets status[0] on a NaN or a particle out of the domain.
    """
    p = cuda.grid(1)
    if p >= position.shape[0]:
        return
    bond_f, bond_m = _bond_sum(p, offsets, ends, bond_force_i, bond_moment_i, bond_moment_j)
    if not fixed[p]:
        for k in range(3):
            load_f = bond_f[k]
            load_m = bond_m[k]
            if use_loads:
                load_f += force[p, k]
                load_m += moment[p, k]
            applied = mass[p] * gravity[k] + external_force[p, k]
            f = load_f + applied
            mk = load_m + external_moment[p, k]
            damp_f = 0.0
            damp_m = 0.0
            if damping > 0.0:
                damp_f = -damping * abs(f) * _sign(velocity[p, k])
                damp_m = -damping * abs(mk) * _sign(angular_velocity[p, k])
            v_old = velocity[p, k]
            w_old = angular_velocity[p, k]
            velocity[p, k] = v_old + (f + damp_f) / mass[p] * kick_dt
            angular_velocity[p, k] = w_old + (mk + damp_m) / inertia[p] * kick_dt
            v_mean = 0.5 * (v_old + velocity[p, k])
            w_mean = 0.5 * (w_old + angular_velocity[p, k])
            work[p] += (applied * v_mean + external_moment[p, k] * w_mean) * kick_dt
            dissipated[p] -= (damp_f * v_mean + damp_m * w_mean) * kick_dt
    for k in range(3):
        x = position[p, k] + velocity[p, k] * drift_dt
        if periodic[k]:
            length = box_high[k] - box_low[k]
            x -= length * math.floor((x - box_low[k]) / length)
        elif x < box_low[k] or x > box_high[k]:
            status[0] = STATUS_OUT_OF_DOMAIN
        if not (math.isfinite(x) and math.isfinite(velocity[p, k])
                and math.isfinite(angular_velocity[p, k])):
            status[0] = STATUS_NOT_FINITE
        position[p, k] = x


@cuda.jit
def bond_energies_kernel(pairs, diameter, initial_length, bond_material, bm_young,
                         bm_poisson, position, box_length, periodic, active,
                         tangential_force, normal_moment, tangential_moment, out):
    """One thread per bond: elastic energy it stores (J); 0 for broken bonds."""
    b = cuda.grid(1)
    if b >= pairs.shape[0]:
        return
    if not active[b]:
        out[b] = 0.0
        return
    i = pairs[b, 0]
    j = pairs[b, 1]
    m = bond_material[b]
    r = minimum_image((position[j, 0] - position[i, 0], position[j, 1] - position[i, 1],
                       position[j, 2] - position[i, 2]),
                      (box_length[0], box_length[1], box_length[2]),
                      periodic[0], periodic[1], periodic[2])
    kn, kt, ktw, kb = bond_stiffnesses(bm_young[m], bm_poisson[m], diameter[b],
                                       initial_length[b])
    length = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    out[b] = bond_elastic_energy(
        length, initial_length[b],
        (tangential_force[b, 0], tangential_force[b, 1], tangential_force[b, 2]),
        (normal_moment[b, 0], normal_moment[b, 1], normal_moment[b, 2]),
        (tangential_moment[b, 0], tangential_moment[b, 1], tangential_moment[b, 2]),
        kn, kt, ktw, kb)


# ---------------------------------------------------------------------------------------
# Device-resident state and the backend object used by Simulation
# ---------------------------------------------------------------------------------------

# State arrays that change during a run and live on the device.
STATE_ARRAYS = ("position", "velocity", "angular_velocity", "bond_active", "bond_axis",
                "bond_previous_length",
                "bond_tangential_force", "bond_normal_moment", "bond_tangential_moment",
                "bond_break_time", "bond_break_mode", "bond_break_energy")


def require_device(name="gpu"):
    """Raise BackendUnavailable unless a CUDA device (or numba's simulator) is usable."""
    try:
        available = cuda.is_available()
    except Exception as error:  # a broken driver install reports here
        raise BackendUnavailable(f"backend = {name!r}: CUDA is not usable here ({error}); "
                                 "use backend = 'cpu'") from None
    if not available:
        raise BackendUnavailable(
            f"backend = {name!r}: no CUDA GPU found (numba.cuda.is_available() is False); "
            "use backend = 'cpu', or set NUMBA_ENABLE_CUDASIM=1 to run the CUDA kernels "
            "in numba's (slow) simulator")


class DeviceState:
    """Device copies of every changing array of a ``State`` (same names), plus the
    per-particle energy counters ``work`` and ``dissipated`` (J) since the last copy back."""

    def __init__(self, state):
        for name in STATE_ARRAYS:
            setattr(self, name, cuda.to_device(np.ascontiguousarray(getattr(state, name))))
        n = state.position.shape[0]
        self.work = cuda.to_device(np.zeros(n))
        self.dissipated = cuda.to_device(np.zeros(n))


class GpuBackend:
    """The CUDA backend for one model: device copies of the model's constant arrays and
    of the state, the laws' kernels, and the host <-> device transfers.

    ``to_device(state)`` uploads a host state (done at construction); ``to_host(state)``
    copies the device state into the host ``State`` in place and checks the status flag.
    """

    name = "gpu"

    def __init__(self, model, state):
        require_device(self.name)
        self.model = model
        n = model.n_particles
        put = cuda.to_device
        self.mass = put(model.mass)
        self.inertia = put(model.inertia)
        self.fixed = put(model.fixed)
        self.gravity = put(model.gravity)
        self.external_force = put(model.external_force)
        self.external_moment = put(model.external_moment)
        self.box_low = put(model.box_low)
        self.box_high = put(model.box_high)
        self.periodic = put(model.periodic)
        self.box_length = put(model.box_length)
        self.status = put(np.zeros(1, dtype=np.int64))
        self.force = cuda.device_array((n, 3))
        self.moment = cuda.device_array((n, 3))
        self._transfers = []   # laws with their own device state (to_host / to_device)
        self.to_device(state)

    # -- transfers ------------------------------------------------------------------------
    def to_device(self, state):
        """Upload every changing array of the host ``state`` (after editing it on the host)."""
        self.device = DeviceState(state)
        self.status.copy_to_device(np.zeros(1, dtype=np.int64))
        for law in self._transfers:
            law.to_device(state)

    def register_transfers(self, law):
        """Have ``law.to_host(state)`` / ``law.to_device(state)`` called with this backend's
        (a law keeping its own device arrays, e.g. contact history in ``state.extra``)."""
        self._transfers.append(law)

    def to_host(self, state):
        """Copy the device state into ``state`` in place; add the energy counters.

        Raises SimulationBlowUp if a kernel flagged a NaN or a particle out of the domain
        since the last check (the state is copied first, so it shows the blow-up)."""
        for name in STATE_ARRAYS:
            getattr(self.device, name).copy_to_host(getattr(state, name))
        state.work_external += float(self.device.work.copy_to_host().sum())
        state.dissipated_damping += float(self.device.dissipated.copy_to_host().sum())
        zeros = np.zeros(state.position.shape[0])
        self.device.work.copy_to_device(zeros)
        self.device.dissipated.copy_to_device(zeros)
        for law in self._transfers:
            law.to_host(state)
        status = int(self.status.copy_to_host()[0])
        if status != STATUS_OK:
            self.status.copy_to_device(np.zeros(1, dtype=np.int64))
            raise blow_up(status, state.time, state.step, backend="gpu")

    def synchronize(self):
        """Wait until every queued kernel has finished (for timing)."""
        cuda.synchronize()

    def device_bytes(self, laws=()):
        """Device memory held (bytes): (per-particle arrays, per-bond arrays, other),
        classified by leading dimension like the bench's host count."""
        n, b = self.model.n_particles, self.model.n_bonds
        seen = {}
        for holder in (self, self.device, *laws):
            for value in vars(holder).values():
                for item in (value if isinstance(value, tuple) else (value,)):
                    if hasattr(item, "copy_to_host") and hasattr(item, "dtype"):
                        seen[id(item)] = item
        per_particle = per_bond = other = 0
        for array in seen.values():
            size = array.size * array.dtype.itemsize
            lead = array.shape[0] if array.ndim else -1
            if lead in (n, n + 1) and n != b:
                per_particle += size
            elif b and lead in (b, 2 * b):
                per_bond += size
            else:
                other += size
        return per_particle, per_bond, other

    # -- what Simulation asks a backend for ---------------------------------------------
    def bond_law(self, model):
        return ElasticBondsGpu(self, model)

    def contact_law(self, model, settings, walls):
        """The contact and wall law on the device (``cuda_contacts.ContactLawGpu``)."""
        from .cuda_contacts import ContactLawGpu
        return ContactLawGpu(model, settings, walls)

    def integrator(self, model):
        return IntegratorGpu(self)

    def load_arrays(self, n_particles):
        """The (N,3) force and moment scratch arrays, on the device."""
        return self.force, self.moment

    def step(self, model, state, laws, integrator, force, moment, dt, musen_compat=False):
        """One step, as ``integrate.step`` but on the device; status checked in to_host.

        The elastic bonds (first law) only compute their per-bond loads; the integrator
        gathers them itself. Other laws add into the zeroed force and moment arrays.
        """
        increment_dt, kick, drift, advances = step_plan(state.started, dt, musen_compat)
        bonds = laws[0] if laws and isinstance(laws[0], ElasticBondsGpu) else None
        others = laws[1:] if bonds is not None else laws
        if bonds is not None:
            bonds.compute(model, state, increment_dt)
        if others:
            _zero_kernel[_blocks(force.shape[0]), THREADS](force, moment)
            for law in others:
                law.accumulate(model, state, force, moment, increment_dt)
        integrator.advance(model, state, force, moment, kick, drift, bonds=bonds,
                           use_loads=bool(others))
        state.started = True
        if advances:
            state.time += dt
            state.step += 1

    def check_laws(self, laws):
        """Extra laws must run on the device (``law.backend == 'gpu'``); each is given
        this backend by ``law.attach(backend)`` (if it has one), from which it reads the
        device state (``backend.device.position`` ...) in ``accumulate``, where it adds
        its loads into the device force and moment arrays."""
        for law in laws:
            if getattr(law, "backend", "cpu") != self.name:
                raise ValueError(f"backend = 'gpu': law {type(law).__name__} runs on the CPU "
                                 "only (it has no backend = 'gpu'); use backend = 'cpu'")
            if hasattr(law, "attach"):
                law.attach(self)


@cuda.jit
def _zero_kernel(force, moment):
    p = cuda.grid(1)
    if p < force.shape[0]:
        for k in range(3):
            force[p, k] = 0.0
            moment[p, k] = 0.0


class ElasticBondsGpu:
    """The elastic bond law over all bonds, on the device (see ``cpu.ElasticBonds``).

    ``accumulate`` assigns (not adds) the particle loads; in ``GpuBackend.step`` only
    ``compute`` runs and the integrator gathers the per-bond loads.
    """

    name = "elastic_bond"
    backend = "gpu"
    # True: MUSEN's numerics (bond_elastic_musen), set by Simulation(musen_compat=True).
    musen_compat = False

    def __init__(self, backend, model):
        self.backend_object = backend
        table = model.bond_material_table()
        put = cuda.to_device
        self._table = tuple(put(table[k]) for k in (
            "young_modulus", "poisson_ratio", "normal_strength", "tangential_strength",
            "criterion", "compressive_breakage"))
        offsets, ends = particle_bond_index(model.bond_pairs, model.n_particles)

        def at_least_one(array):
            # A model without bonds still passes these arrays to the kernels; keep them
            # non-empty (never read then: the offsets are all 0 and no bond thread runs).
            return array if array.shape[0] else np.zeros((1,) + array.shape[1:], array.dtype)
        self._offsets, self._ends = put(offsets), put(at_least_one(ends))
        self._pairs = put(at_least_one(model.bond_pairs))
        self._diameter = put(at_least_one(model.bond_diameter))
        self._initial_length = put(at_least_one(model.bond_initial_length))
        self._material = put(at_least_one(model.bond_material))
        n_bonds = max(model.n_bonds, 1)
        self.force_i = cuda.device_array((n_bonds, 3))
        self.moment_i = cuda.device_array((n_bonds, 3))
        self.moment_j = cuda.device_array((n_bonds, 3))

    def accumulate(self, model, state, force, moment, increment_dt):
        """Advance the bonds by ``increment_dt`` (s); set the device force (N), moment (N m)."""
        self.compute(model, state, increment_dt)
        gather_bond_loads_kernel[_blocks(model.n_particles), THREADS](
            self._offsets, self._ends, self.force_i, self.moment_i, self.moment_j, force,
            moment, True)

    def compute(self, model, state, increment_dt):
        """Advance every intact bond by ``increment_dt`` (s); loads kept per bond."""
        g = self.backend_object
        d = g.device
        if model.n_bonds:
            elastic_bonds_kernel[_blocks(model.n_bonds), THREADS](
                self._pairs, self._diameter, self._initial_length, self._material,
                *self._table, d.position, d.velocity, d.angular_velocity, g.box_length,
                g.periodic, d.bond_active, d.bond_axis, d.bond_previous_length,
                d.bond_tangential_force, d.bond_normal_moment, d.bond_tangential_moment,
                d.bond_break_time, d.bond_break_mode, d.bond_break_energy, state.time,
                increment_dt, self.musen_compat, self.force_i, self.moment_i, self.moment_j)

    def energy(self, model, state):
        """Elastic energy stored in each bond (J), shape (B,), copied to the host."""
        if model.n_bonds == 0:
            return np.zeros(0)
        g = self.backend_object
        d = g.device
        out = cuda.device_array(model.n_bonds)
        bond_energies_kernel[_blocks(model.n_bonds), THREADS](
            self._pairs, self._diameter, self._initial_length, self._material,
            self._table[0], self._table[1], d.position, g.box_length, g.periodic,
            d.bond_active, d.bond_tangential_force, d.bond_normal_moment,
            d.bond_tangential_moment, out)
        return out.copy_to_host()


class IntegratorGpu:
    """Semi-implicit Euler on the device (see ``cpu.Integrator``); never syncs."""

    backend = "gpu"

    def __init__(self, backend):
        self.backend_object = backend
        n = backend.model.n_particles
        # An empty bond index, for steps without a fused bond law.
        self._no_bonds = (cuda.to_device(np.zeros(n + 1, dtype=np.int64)),
                          cuda.to_device(np.zeros(1, dtype=np.int64)),
                          *(cuda.to_device(np.zeros((1, 3))) for _ in range(3)))

    def advance(self, model, state, force, moment, kick_dt, drift_dt, bonds=None,
                use_loads=True):
        """Kick by kick_dt (s), drift by drift_dt (s); the status is read in to_host.

        bonds: an ``ElasticBondsGpu`` whose per-bond loads of this step are gathered here;
        use_loads: also add the force (N) and moment (N m) arrays.
        """
        g = self.backend_object
        d = g.device
        csr = self._no_bonds if bonds is None else (
            bonds._offsets, bonds._ends, bonds.force_i, bonds.moment_i, bonds.moment_j)
        integrate_kernel[_blocks(model.n_particles), THREADS](
            *csr, use_loads, d.position, d.velocity, d.angular_velocity, force, moment,
            g.mass, g.inertia, g.fixed, g.gravity, g.external_force, g.external_moment,
            model.damping, kick_dt,
            drift_dt, g.box_low, g.box_high, g.periodic, g.status, d.work, d.dissipated)
        return STATUS_OK


# ---------------------------------------------------------------------------------------
# Neighbour search: cell index, sort by cell, cell starts by search, count/scan/write pairs
# ---------------------------------------------------------------------------------------

_KEY_PAD = np.iinfo(np.int64).max


@cuda.jit(device=True)
def _cell_coordinate(x, low, cell_size, count):
    """Cell index of coordinate x (m) along one axis, clamped into [0, count - 1]."""
    c = int(math.floor((x - low) / cell_size))
    if c < 0:
        return 0
    if c > count - 1:
        return count - 1
    return c


@cuda.jit
def cell_keys_kernel(position, low, cell_size, dims, n_padded, keys):
    """key = cell * N + particle (int64), so sorting keys sorts by cell, then by index;
    padding slots get the largest key. Particles outside the grid are clamped into the
    edge cells, which keeps every neighbour within one cell (clamping never separates)."""
    p = cuda.grid(1)
    n = position.shape[0]
    if p >= n_padded:
        return
    if p >= n:
        keys[p] = _KEY_PAD
        return
    cell = 0
    for k in range(2, -1, -1):
        cell = cell * dims[k] + _cell_coordinate(position[p, k], low[k], cell_size, dims[k])
    keys[p] = cell * n + p


@cuda.jit
def bitonic_stage_kernel(keys, k, j):
    """One compare-exchange stage of a bitonic sort of ``keys`` (length a power of two)."""
    i = cuda.grid(1)
    if i >= keys.shape[0]:
        return
    partner = i ^ j
    if partner > i:
        ascending = (i & k) == 0
        a = keys[i]
        b = keys[partner]
        if (a > b) == ascending:
            keys[i] = b
            keys[partner] = a


def sort_keys(keys):
    """Sort device int64 ``keys`` (length a power of two) in place, ascending: a bitonic
    network, deterministic and without atomics; log2(P)(log2(P)+1)/2 launches."""
    size = keys.shape[0]
    k = 2
    while k <= size:
        j = k // 2
        while j >= 1:
            bitonic_stage_kernel[_blocks(size), THREADS](keys, k, j)
            j //= 2
        k *= 2


@cuda.jit
def cell_start_kernel(keys, n, n_cells, start):
    """start[c] = first slot of sorted ``keys`` whose cell is >= c (binary search);
    start[n_cells] = n. Cell c holds slots start[c] .. start[c+1]-1."""
    c = cuda.grid(1)
    if c > n_cells:
        return
    if c == n_cells:
        start[c] = n
        return
    target = c * n
    lo = 0
    hi = n
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < target:
            lo = mid + 1
        else:
            hi = mid
    start[c] = lo


@cuda.jit(device=True)
def _visit_neighbours(p, position, radius, skin, low, cell_size, dims, keys, start, n,
                      pairs, offset, write):
    """Count (and write at ``offset`` when ``write``) the pairs (p, q), q > p, with
    |x_q - x_p| < r_p + r_q + skin, scanning the 27 cells around p's cell."""
    c0 = _cell_coordinate(position[p, 0], low[0], cell_size, dims[0])
    c1 = _cell_coordinate(position[p, 1], low[1], cell_size, dims[1])
    c2 = _cell_coordinate(position[p, 2], low[2], cell_size, dims[2])
    found = 0
    for d2 in range(-1, 2):
        z = c2 + d2
        if z < 0 or z >= dims[2]:
            continue
        for d1 in range(-1, 2):
            y = c1 + d1
            if y < 0 or y >= dims[1]:
                continue
            for d0 in range(-1, 2):
                x = c0 + d0
                if x < 0 or x >= dims[0]:
                    continue
                cell = (z * dims[1] + y) * dims[0] + x
                for s in range(start[cell], start[cell + 1]):
                    q = keys[s] - cell * n
                    if q <= p:
                        continue
                    dx = position[q, 0] - position[p, 0]
                    dy = position[q, 1] - position[p, 1]
                    dz = position[q, 2] - position[p, 2]
                    reach = radius[p] + radius[q] + skin
                    if dx * dx + dy * dy + dz * dz < reach * reach:
                        if write:
                            pairs[offset + found, 0] = p
                            pairs[offset + found, 1] = q
                        found += 1
    return found


@cuda.jit
def count_pairs_kernel(position, radius, skin, low, cell_size, dims, keys, start, counts,
                       pairs):
    p = cuda.grid(1)
    n = position.shape[0]
    if p < n:
        counts[p] = _visit_neighbours(p, position, radius, skin, low, cell_size, dims, keys,
                                      start, n, pairs, 0, False)


@cuda.jit
def write_pairs_kernel(position, radius, skin, low, cell_size, dims, keys, start, offsets,
                       pairs):
    """Write particle p's pairs at offsets[p], then sort them by j (insertion sort of a
    short segment), so the whole list is sorted by (i, j): deterministic, and searchable
    when contact history is carried to a rebuilt list (``remap_pair_history``)."""
    p = cuda.grid(1)
    n = position.shape[0]
    if p < n:
        first = offsets[p]
        found = _visit_neighbours(p, position, radius, skin, low, cell_size, dims, keys,
                                  start, n, pairs, first, True)
        for a in range(first + 1, first + found):
            q = pairs[a, 1]
            b = a - 1
            while b >= first and pairs[b, 1] > q:
                pairs[b + 1, 1] = pairs[b, 1]
                b -= 1
            pairs[b + 1, 1] = q


@cuda.jit
def remap_history_kernel(old_pairs, old_history, new_pairs, new_history):
    """One thread per new pair: copy its history row from the old list (both sorted by
    (i, j)) found by binary search, or zero it for a new contact."""
    c = cuda.grid(1)
    if c >= new_pairs.shape[0]:
        return
    i = new_pairs[c, 0]
    j = new_pairs[c, 1]
    lo = 0
    hi = old_pairs.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if old_pairs[mid, 0] < i or (old_pairs[mid, 0] == i and old_pairs[mid, 1] < j):
            lo = mid + 1
        else:
            hi = mid
    found = lo < old_pairs.shape[0] and old_pairs[lo, 0] == i and old_pairs[lo, 1] == j
    for k in range(new_history.shape[1]):
        new_history[c, k] = old_history[lo, k] if found else 0.0


def remap_pair_history(old_pairs, old_history, new_pairs):
    """Carry per-pair history (e.g. the tangential spring, (C_old, K)) from an old pair
    list to a rebuilt one; all device arrays, pair lists sorted by (i, j) as
    ``device_neighbour_pairs`` returns them. Pairs new to the list start from zero."""
    width = old_history.shape[1]
    new_history = cuda.device_array((new_pairs.shape[0], width))
    if new_pairs.shape[0] == 0:
        return new_history
    if old_pairs.shape[0] == 0:
        old_pairs = cuda.to_device(np.full((1, 2), -1, dtype=np.int64))
        old_history = cuda.to_device(np.zeros((1, width)))
    remap_history_kernel[_blocks(new_pairs.shape[0]), THREADS](old_pairs, old_history,
                                                               new_pairs, new_history)
    return new_history


@cuda.jit
def _block_scan_kernel(values, out, block_sums):
    """Inclusive scan of each THREADS-long block (Hillis-Steele in shared memory)."""
    buffer = cuda.shared.array(THREADS, dtype=np.int64)
    t = cuda.threadIdx.x
    i = cuda.grid(1)
    buffer[t] = values[i] if i < values.shape[0] else 0
    cuda.syncthreads()
    step = 1
    while step < THREADS:
        add = buffer[t - step] if t >= step else 0
        cuda.syncthreads()
        buffer[t] += add
        cuda.syncthreads()
        step *= 2
    if i < values.shape[0]:
        out[i] = buffer[t]
    if t == THREADS - 1:
        block_sums[cuda.blockIdx.x] = buffer[t]


@cuda.jit
def _add_block_offsets_kernel(out, scanned_block_sums):
    i = cuda.grid(1)
    block = cuda.blockIdx.x
    if i < out.shape[0] and block > 0:
        out[i] += scanned_block_sums[block - 1]


def inclusive_scan(values):
    """Inclusive prefix sum of a device int64 array (new device array); blocks scanned in
    shared memory, block totals scanned recursively: deterministic, no atomics."""
    n = values.shape[0]
    blocks = _blocks(n)
    out = cuda.device_array(n, dtype=np.int64)
    block_sums = cuda.device_array(blocks, dtype=np.int64)
    _block_scan_kernel[blocks, THREADS](values, out, block_sums)
    if blocks > 1:
        _add_block_offsets_kernel[blocks, THREADS](out, inclusive_scan(block_sums))
    return out


def device_neighbour_pairs(position, radius, skin, low, high, max_cells=1 << 26):
    """Pairs (i < j) of particles closer than r_i + r_j + skin, found on the device.

    position (N,3) m and radius (N,) m: device arrays; skin: m; low, high: (3,) host
    bounds of the grid (m; particles outside are clamped into the edge cells). Returns a
    device (P,2) int64 array sorted by (i, j).
    """
    n = position.shape[0]
    empty = cuda.device_array((0, 2), dtype=np.int64)
    if n < 2:
        return empty
    host_radius_max = float(radius.copy_to_host().max())
    cell_size = 2.0 * host_radius_max + skin
    extent = np.maximum(np.asarray(high, float) - np.asarray(low, float), cell_size)
    # More cells than ~2 per particle buy nothing and a scattered scene (or a blow-up)
    # would make the start table huge.
    max_cells = min(max_cells, max(2 * n, 64))
    while np.prod(np.ceil(extent / cell_size)) > max_cells:
        cell_size *= 1.26  # coarser cells keep the start table bounded for sparse scenes
    dims = np.ceil(extent / cell_size).astype(np.int64)
    n_cells = int(np.prod(dims))
    n_padded = 1 << (n - 1).bit_length()
    keys = cuda.device_array(n_padded, dtype=np.int64)
    d_low = cuda.to_device(np.asarray(low, dtype=np.float64))
    d_dims = cuda.to_device(dims)
    cell_keys_kernel[_blocks(n_padded), THREADS](position, d_low, cell_size, d_dims,
                                                 n_padded, keys)
    sort_keys(keys)
    start = cuda.device_array(n_cells + 1, dtype=np.int64)
    cell_start_kernel[_blocks(n_cells + 1), THREADS](keys, n, n_cells, start)
    counts = cuda.device_array(n, dtype=np.int64)
    count_pairs_kernel[_blocks(n), THREADS](position, radius, skin, d_low, cell_size, d_dims,
                                            keys, start, counts, empty)
    ends = inclusive_scan(counts)
    total = int(ends[n - 1])
    if total == 0:
        return empty
    offsets = cuda.device_array(n, dtype=np.int64)
    offsets[0:1].copy_to_device(np.zeros(1, dtype=np.int64))
    offsets[1:].copy_to_device(ends[:n - 1])
    pairs = cuda.device_array((total, 2), dtype=np.int64)
    write_pairs_kernel[_blocks(n), THREADS](position, radius, skin, d_low, cell_size, d_dims,
                                            keys, start, offsets, pairs)
    return pairs


def neighbour_pairs(position, radius, skin=0.0):
    """Host convenience: (P,2) int64 pairs i < j with |x_j - x_i| < r_i + r_j + skin.

    position (N,3) m, radius (N,) m, skin m (NumPy arrays); runs ``device_neighbour_pairs``
    on a grid spanning the particles.
    """
    position = np.ascontiguousarray(position, dtype=np.float64)
    radius = np.ascontiguousarray(radius, dtype=np.float64)
    if position.shape[0] < 2:
        return np.zeros((0, 2), dtype=np.int64)
    pairs = device_neighbour_pairs(cuda.to_device(position), cuda.to_device(radius),
                                   float(skin), position.min(axis=0), position.max(axis=0))
    return pairs.copy_to_host()


# ---------------------------------------------------------------------------------------
# Particle-particle contacts: a kernel around any compiled pair law
# ---------------------------------------------------------------------------------------

def make_contact_kernel(pair_law):
    """A kernel over a contact list that calls ``pair_law``, a device-compiled pair law
    with the contact laws' common signature (physics/contact_hertz.py, contact_linear.py):

        pair_law(n, overlap, v_rel, w_rel, spring, stiffness_a, stiffness_b, r_star,
                 m_star, beta, friction, rolling_friction, dt)
            -> (force on i, rolling torque on i, F_t on i, new spring, energy, dissipated)

    The kernel takes (pairs (C,2), pair_bond (C,) bond index or -1, bond_active,
    position, velocity, angular_velocity, radius, mass, material, pair_table (M,M,5):
    per material pair (stiffness_a, stiffness_b, beta, friction, rolling_friction),
    box_length, periodic, spring (C,3) m updated in place, dt) and writes per contact
    force_i, moment_i, moment_j, energy, dissipated, like the bond kernel, so
    ``gather_bond_loads_kernel`` with a CSR index of the contact list
    (``particle_bond_index(pairs, N)``) sums them per particle without atomics.
    Intact bonded pairs and pairs without overlap apply nothing; the latter lose their
    spring (the contact ended).
    """
    @cuda.jit
    def contact_kernel(pairs, pair_bond, bond_active, position, velocity, angular_velocity,
                       radius, mass, material, pair_table, box_length, periodic, spring, dt,
                       out_force_i, out_moment_i, out_moment_j, out_energy, out_dissipated):
        c = cuda.grid(1)
        if c >= pairs.shape[0]:
            return
        i = pairs[c, 0]
        j = pairs[c, 1]
        r = minimum_image((position[j, 0] - position[i, 0], position[j, 1] - position[i, 1],
                           position[j, 2] - position[i, 2]),
                          (box_length[0], box_length[1], box_length[2]),
                          periodic[0], periodic[1], periodic[2])
        distance = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        overlap = radius[i] + radius[j] - distance
        bonded = pair_bond[c] >= 0 and bond_active[pair_bond[c]]
        for k in range(3):
            out_force_i[c, k] = 0.0
            out_moment_i[c, k] = 0.0
            out_moment_j[c, k] = 0.0
        out_energy[c] = 0.0
        out_dissipated[c] = 0.0
        if bonded or overlap <= 0.0 or distance <= 0.0:
            for k in range(3):
                spring[c, k] = 0.0
            return
        n = (r[0] / distance, r[1] / distance, r[2] / distance)
        arm_i = radius[i] - 0.5 * overlap
        arm_j = radius[j] - 0.5 * overlap
        wi = (angular_velocity[i, 0], angular_velocity[i, 1], angular_velocity[i, 2])
        wj = (angular_velocity[j, 0], angular_velocity[j, 1], angular_velocity[j, 2])
        # Surface velocity of j relative to i at the contact point (lever arms a_i, a_j).
        spin = (arm_i * wi[0] + arm_j * wj[0], arm_i * wi[1] + arm_j * wj[1],
                arm_i * wi[2] + arm_j * wj[2])
        v_rel = (velocity[j, 0] - velocity[i, 0] - (spin[1] * n[2] - spin[2] * n[1]),
                 velocity[j, 1] - velocity[i, 1] - (spin[2] * n[0] - spin[0] * n[2]),
                 velocity[j, 2] - velocity[i, 2] - (spin[0] * n[1] - spin[1] * n[0]))
        w_rel = (wi[0] - wj[0], wi[1] - wj[1], wi[2] - wj[2])
        mi = material[i]
        mj = material[j]
        r_star = radius[i] * radius[j] / (radius[i] + radius[j])
        m_star = mass[i] * mass[j] / (mass[i] + mass[j])
        force_i, torque, f_t, xi, energy, dissipated = pair_law(
            n, overlap, v_rel, w_rel, (spring[c, 0], spring[c, 1], spring[c, 2]),
            pair_table[mi, mj, 0], pair_table[mi, mj, 1], r_star, m_star,
            pair_table[mi, mj, 2], pair_table[mi, mj, 3], pair_table[mi, mj, 4], dt)
        lever = (n[1] * f_t[2] - n[2] * f_t[1], n[2] * f_t[0] - n[0] * f_t[2],
                 n[0] * f_t[1] - n[1] * f_t[0])
        for k in range(3):
            spring[c, k] = xi[k]
            out_force_i[c, k] = force_i[k]
            out_moment_i[c, k] = arm_i * lever[k] + torque[k]
            out_moment_j[c, k] = arm_j * lever[k] - torque[k]
        out_energy[c] = energy
        out_dissipated[c] = dissipated

    return contact_kernel


def synchronize():
    """Wait for every queued kernel (for timing: call before reading a clock)."""
    cuda.synchronize()


@cuda.jit
def _displacement_flag_kernel(position, reference, limit_squared, flag):
    """flag[0] = 1 when some particle moved more than sqrt(limit_squared) (m) since the
    pair list was built (the list then may miss a contact)."""
    p = cuda.grid(1)
    if p < position.shape[0]:
        dx = position[p, 0] - reference[p, 0]
        dy = position[p, 1] - reference[p, 1]
        dz = position[p, 2] - reference[p, 2]
        if dx * dx + dy * dy + dz * dz > limit_squared:
            flag[0] = 1


@cuda.jit
def _bounds_kernel(position, low, high):
    """Bounding box of the particles (m) by atomic min/max: exact, so order-independent."""
    p = cuda.grid(1)
    if p < position.shape[0]:
        for k in range(3):
            cuda.atomic.min(low, k, position[p, k])
            cuda.atomic.max(high, k, position[p, k])


@cuda.jit
def _pair_bond_kernel(pairs, bond_keys, bond_index, out):
    """out[c] = the bond joining pair c's particles, or -1: binary search of i*N + j in
    the sorted keys of the bonds (i < j)."""
    c = cuda.grid(1)
    if c >= pairs.shape[0]:
        return
    n = bond_keys.shape[0]
    out[c] = -1
    key = pairs[c, 0] * bond_index[n] + pairs[c, 1]  # bond_index[n] holds N
    lo = 0
    hi = n
    while lo < hi:
        mid = (lo + hi) // 2
        if bond_keys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    if lo < n and bond_keys[lo] == key:
        out[c] = bond_index[lo]


class ParticleContactsGpu:
    """Particle-particle contacts on the device for any pair law (``make_contact_kernel``).

    pair_law: a device-compiled pair law with the contact laws' signature (e.g.
    ``compile_physics(cuda.jit(device=True)).hertz_mindlin``); pair_table (M, M, 5): per
    material pair (stiffness_a, stiffness_b, beta, friction, rolling_friction) in that
    law's units (Hertz: E* Pa, G* Pa); skin: m, the pair list holds pairs closer than
    r_i + r_j + skin and is rebuilt (history carried) when a particle moved skin/2.
    Intact bonded pairs get no contact force. ``state.extra`` is not used: the springs
    stay on the device (``spring``, with ``pairs`` sorted by (i, j)).
    """

    name = "particle_contacts"
    backend = "gpu"

    def __init__(self, model, pair_law, pair_table, *, skin):
        table = np.ascontiguousarray(pair_table, dtype=np.float64)
        m = len(model.materials)
        if table.shape != (m, m, 5):
            raise ValueError(f"pair_table: shape {table.shape}, expected ({m}, {m}, 5)")
        if not skin > 0.0:
            raise ValueError(f"skin = {skin!r} m; must be > 0")
        if np.any(model.periodic):
            raise ValueError("ParticleContactsGpu: periodic boundaries are not supported "
                             "yet by the GPU pair search; use backend = 'cpu'")
        self.kernel = make_contact_kernel(pair_law)
        self.table = table
        self.skin = float(skin)
        self.rebuilds = 0

    def attach(self, backend):
        """Take the device state of ``backend``; upload the constant per-particle arrays."""
        model = backend.model
        self.g = backend
        put = cuda.to_device
        self.radius = put(model.radius)
        self.mass = put(model.mass)
        self.material = put(model.material)
        self.d_table = put(self.table)
        n = model.n_particles
        ordered = np.sort(model.bond_pairs, axis=1)
        keys = ordered[:, 0] * n + ordered[:, 1]
        order = np.argsort(keys)
        self.bond_keys = put(keys[order] if len(keys) else np.full(1, -1, dtype=np.int64))
        # bond_index[-1] holds N, the key's multiplier, so the kernel needs no extra scalar.
        self.bond_index = put(np.append(order, n).astype(np.int64))
        self.n_bond_keys = len(keys)
        self.pairs = cuda.to_device(np.zeros((0, 2), dtype=np.int64))
        self.spring = cuda.to_device(np.zeros((0, 3)))
        self.reference = None
        self.flag = put(np.zeros(1, dtype=np.int64))

    def _needs_rebuild(self, n):
        if self.reference is None:
            return True
        self.flag.copy_to_device(np.zeros(1, dtype=np.int64))
        _displacement_flag_kernel[_blocks(n), THREADS](self.g.device.position, self.reference,
                                                      (0.5 * self.skin) ** 2, self.flag)
        return bool(self.flag.copy_to_host()[0])

    def _rebuild(self, model):
        n = model.n_particles
        position = self.g.device.position
        low = cuda.to_device(np.full(3, np.inf))
        high = cuda.to_device(np.full(3, -np.inf))
        _bounds_kernel[_blocks(n), THREADS](position, low, high)
        pairs = device_neighbour_pairs(position, self.radius, self.skin, low.copy_to_host(),
                                       high.copy_to_host())
        self.spring = remap_pair_history(self.pairs, self.spring, pairs)
        self.pairs = pairs
        count = pairs.shape[0]
        self.pair_bond = cuda.device_array(max(count, 1), dtype=np.int64)
        if count and self.n_bond_keys:
            _pair_bond_kernel[_blocks(count), THREADS](pairs, self.bond_keys[:self.n_bond_keys],
                                                       self.bond_index, self.pair_bond)
        elif count:
            self.pair_bond.copy_to_device(np.full(count, -1, dtype=np.int64))
        # The gather's CSR index of the contact list, built on the host (rebuilds are rare).
        offsets, ends = particle_bond_index(pairs.copy_to_host(), n)
        self.offsets = cuda.to_device(offsets)
        self.ends = cuda.to_device(ends if len(ends) else np.zeros(1, dtype=np.int64))
        width = max(count, 1)
        self.out = ([cuda.device_array((width, 3)) for _ in range(3)]
                    + [cuda.device_array(width) for _ in range(2)])
        self.reference = cuda.device_array_like(position)
        self.reference.copy_to_device(position)
        self.rebuilds += 1

    def accumulate(self, model, state, force, moment, increment_dt):
        """Advance every contact by ``increment_dt`` (s); add loads to the device arrays."""
        n = model.n_particles
        if self._needs_rebuild(n):
            self._rebuild(model)
        count = self.pairs.shape[0]
        if count == 0:
            return
        g = self.g
        d = g.device
        self.kernel[_blocks(count), THREADS](
            self.pairs, self.pair_bond, d.bond_active, d.position, d.velocity,
            d.angular_velocity, self.radius, self.mass, self.material, self.d_table,
            g.box_length, g.periodic, self.spring, increment_dt, *self.out)
        gather_bond_loads_kernel[_blocks(n), THREADS](
            self.offsets, self.ends, self.out[0], self.out[1], self.out[2], force, moment,
            False)

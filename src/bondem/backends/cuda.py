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

from ..errors import BackendUnavailable, InputError  # noqa: F401
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

"""CUDA backend: the CPU backend's loop bodies as numba-cuda kernels.

The loop bodies of ``backends/loops.py`` and the physics they call are compiled once
more, with ``numba.cuda.jit(device=True)``; each kernel here is a grid-stride loop over
its items calling a body, as ``backends/cpu.py`` runs the same bodies in ``prange``. So
the two backends differ only in the order of floating-point sums where a sum has no fixed
order (energy totals), and in what the compilers do with round-off (fused multiply-add on
the GPU).

Design (the same as the CPU backend's, see its docstring):
- one thread per bond computes the bond law and writes its loads to the bond's own slot;
- one thread per particle sums its bonds through the fixed CSR index (particle -> bond
  ends): no atomics, the same bits every run; the same thread adds the other laws' loads
  (if any), stores the particle's total loads (what the results save, the clumps read)
  and integrates, so a bonds-only step is two launches; a particle that turns NaN or
  leaves the domain sets a status flag, checked by the host once per batch of steps (no
  exceptions in kernels);
- every changing array lives on the device (``DeviceState``) between outputs; the host
  ``State`` is refreshed by ``GpuBackend.to_host`` at the end of each batch of steps.
- work and damping energies are accumulated per particle on the device and summed on the
  host only when the state is copied back (a fixed order, so no atomics there either).

Importing this module does not need a GPU; ``GpuBackend`` raises ``BackendUnavailable``
when neither a CUDA device nor the simulator (NUMBA_ENABLE_CUDASIM=1) is there.
"""
import numpy as np
from numba import cuda

from ..errors import BackendUnavailable, InputError  # noqa: F401
from ..integrate import step_plan
from ..physics import bond_models
from ..status import STATUS_OK, blow_up
from . import loops
from .cpu import (bodies, bond_state, bond_tuples, box, clump_state, clumps, fields,
                  has_model_state, particles)
from .cuda_device import K, launch
add = K.add
row3 = K.row3
advance_bond = K.advance_bond
bond_ends_sum = K.bond_ends_sum
bond_energy = K.bond_energy
integrate_particle = K.integrate_particle
integrate_clump = K.integrate_clump
minimum_image = K.minimum_image


# ---------------------------------------------------------------------------------------
# Kernels: the loop bodies of backends/loops.py, one thread per item (grid-stride)
# ---------------------------------------------------------------------------------------

@cuda.jit
def elastic_bonds_kernel(bonds, materials, state, particles, box, time, dt, musen, loads):
    """``loops.advance_bond`` for every bond: one increment dt (s) at ``time`` (s), loads
    in the bond's own row. musen: True for MUSEN's numerics, False for the SPEC's."""
    for b in range(cuda.grid(1), bonds.pairs.shape[0], cuda.gridsize(1)):
        advance_bond(b, bonds, materials, state, particles, box, time, dt, musen, loads)


@cuda.jit
def gather_bond_loads_kernel(index, loads, force, moment, assign):
    """``loops.bond_ends_sum`` for every particle, stored (``assign``) or added to force
    (N) and moment (N m)."""
    for p in range(cuda.grid(1), index.offsets.shape[0] - 1, cuda.gridsize(1)):
        f, m = bond_ends_sum(p, index, loads, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        for k in range(3):
            if assign:
                force[p, k] = f[k]
                moment[p, k] = m[k]
            else:
                force[p, k] += f[k]
                moment[p, k] += m[k]


@cuda.jit
def integrate_kernel(index, loads, use_loads, particles, bodies, force, moment, fields,
                     damping, kick_dt, drift_dt, box, status, work, dissipated):
    """``loops.integrate_particle`` for every particle, with its bond loads gathered here
    (``loops.bond_ends_sum``) plus, when ``use_loads``, the other laws' loads in force (N)
    and moment (N m); the total is stored in force and moment (the particles' loads of
    this evaluation, as on the CPU: saved to the results, read by the clumps). Fusing the
    gather saves a launch and the force arrays' read (48 B per particle) when the bonds
    are the only law. Adds each particle's work of gravity, the fields and external loads
    and its damping loss (J) to ``work[p]`` and ``dissipated[p]``, summed on the host
    when the state is copied back; sets status[0] on a NaN or a particle out of the
    domain."""
    for p in range(cuda.grid(1), particles.position.shape[0], cuda.gridsize(1)):
        f, m = bond_ends_sum(p, index, loads, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        if use_loads:
            f = add(f, row3(force, p))
            m = add(m, row3(moment, p))
        for k in range(3):
            force[p, k] = f[k]
            moment[p, k] = m[k]
        gained, lost, code = integrate_particle(p, f, m, particles, bodies, fields, damping,
                                                kick_dt, drift_dt, box, True)
        work[p] += gained
        dissipated[p] += lost
        if code != STATUS_OK:
            status[0] = code


@cuda.jit
def clump_kernel(force, moment, clumps, clump_state, particles, bodies, fields, damping,
                 kick_dt, drift_dt, box, status, work, dissipated):
    """``loops.integrate_clump`` for every clump, after ``integrate_kernel`` stored the
    members' loads; its work and damping loss (J) go to its first member's slots of
    ``work`` and ``dissipated`` (which the member itself leaves at zero)."""
    for c in range(cuda.grid(1), clump_state.position.shape[0], cuda.gridsize(1)):
        gained, lost, code = integrate_clump(c, force, moment, clumps, clump_state,
                                             particles, bodies, fields, damping, kick_dt,
                                             drift_dt, box, True)
        first = clumps.members[clumps.offsets[c]]
        work[first] += gained
        dissipated[first] += lost
        if code != STATUS_OK:
            status[0] = code


@cuda.jit
def bond_energies_kernel(bonds, materials, state, position, box, out):
    """``loops.bond_energy`` for every bond: the elastic energy it stores (J)."""
    for b in range(cuda.grid(1), bonds.pairs.shape[0], cuda.gridsize(1)):
        out[b] = bond_energy(b, bonds, materials, state, position, box)


# ---------------------------------------------------------------------------------------
# Device-resident state and the backend object used by Simulation
# ---------------------------------------------------------------------------------------

# State arrays that change during a run and live on the device.
STATE_ARRAYS = ("position", "velocity", "angular_velocity", "bond_active", "bond_axis",
                "bond_previous_length",
                "bond_tangential_force", "bond_normal_moment", "bond_tangential_moment",
                "bond_break_time", "bond_break_mode", "bond_break_energy")
# ... and those of the clumps, when there are any
CLUMP_ARRAYS = ("clump_position", "clump_orientation", "clump_velocity",
                "clump_angular_momentum")


def state_arrays(state):
    """Names of the state's arrays that live on the device."""
    return STATE_ARRAYS + (CLUMP_ARRAYS if state.clump_position.shape[0] else ())


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
    problem = cuda_target_problem()
    if problem:
        raise BackendUnavailable(f"backend = {name!r}: {problem}")


def cuda_target_problem():
    """Why numba-cuda cannot compile kernels with this NumPy, or None. numba-cuda loads its
    array typing at the first kernel compile; its releases up to now register np.row_stack,
    which NumPy 2.5 removed (NVIDIA/numba-cuda#907), so every launch would fail deep in
    numba: say so at the start instead."""
    try:
        import numba.cuda.np.arrayobj  # noqa: F401
    except ImportError:              # numba's own older CUDA target, or the simulator
        return None
    except AttributeError as error:
        return (f"numba-cuda cannot compile kernels with NumPy {np.__version__} ({error}; "
                "NVIDIA/numba-cuda#907): install numpy<2.5, as pip install 'bondem[gpu]' does")
    return None


class DeviceState:
    """Device copies of every changing array of a ``State`` (same names), plus the
    per-particle energy counters ``work`` and ``dissipated`` (J) since the last copy back."""

    def __init__(self, state):
        for name in state_arrays(state):
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
        self.bodies = bodies(model, put)
        self.box = box(model, put)
        self.gravity = put(model.gravity)
        self.fields = fields(model, put)
        # the domain's arrays the contact law's kernels take directly
        self.periodic, self.box_length = self.box.periodic, self.box.length
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
        for name in state_arrays(state):
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

    def set_fluid_local(self, local):
        """Upload the per-particle fluid (N, 4) (``Model.fluid_local``, set by a flow
        field law on the host; the Simulation gives it its size before the device copy is
        made) for the next steps."""
        self.fields.fluid_local.copy_to_device(np.ascontiguousarray(local))

    def set_external_loads(self, force, moment):
        """Upload the particles' external force (N,3) N and moment (N,3) N m (a coupled
        solver's, set on the host)."""
        self.bodies.external_force.copy_to_device(np.ascontiguousarray(force))
        self.bodies.external_moment.copy_to_device(np.ascontiguousarray(moment))

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
        # MUSEN evaluates contacts before bonds (integrate.step): a pair whose bond breaks
        # in this step touches from the next one
        if bonds is not None and not musen_compat:
            bonds.compute(model, state, increment_dt)
        if others:
            launch(_zero_kernel, force.shape[0], force, moment)
            for law in others:
                law.accumulate(model, state, force, moment, increment_dt)
        if bonds is not None and musen_compat:
            bonds.compute(model, state, increment_dt)
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

        def put(array):
            # A model without bonds still passes these arrays to the kernels; keep them
            # non-empty (never read then: the offsets are all 0 and no bond thread runs).
            return cuda.to_device(array if array.shape[0] else
                                  np.zeros((1,) + array.shape[1:], array.dtype))
        self._bonds, self._materials, self.index = bond_tuples(model, put)
        n_bonds = max(model.n_bonds, 1)
        self.loads = loops.BondLoads(*(cuda.device_array((n_bonds, 3)) for _ in range(3)))
        # The bond models' per-bond state (state.extra["bond_model_state"]), if one has it.
        self.model_state = has_model_state(model)
        self._model_state = cuda.to_device(
            np.zeros((n_bonds if self.model_state else 1, bond_models.STATE_COLUMNS)))
        self._pending = self.model_state   # take a resumed state's values at the first step
        if self.model_state:
            backend.register_transfers(self)

    def to_device(self, state):
        """Take the bond models' per-bond state of a host ``state``."""
        self._pending = False
        if "bond_model_state" in state.extra:
            self._model_state.copy_to_device(state.extra["bond_model_state"])

    def to_host(self, state):
        """Copy the bond models' per-bond state into state.extra["bond_model_state"]."""
        state.extra["bond_model_state"] = self._model_state.copy_to_host()

    def accumulate(self, model, state, force, moment, increment_dt):
        """Advance the bonds by ``increment_dt`` (s); set the device force (N), moment (N m)."""
        self.compute(model, state, increment_dt)
        launch(gather_bond_loads_kernel, model.n_particles, self.index, self.loads, force,
               moment, True)

    def compute(self, model, state, increment_dt):
        """Advance every intact bond by ``increment_dt`` (s); loads kept per bond."""
        g = self.backend_object
        if self._pending:
            self.to_device(state)
        if model.n_bonds:
            launch(elastic_bonds_kernel, model.n_bonds, self._bonds, self._materials,
                   bond_state(g.device, self._model_state), particles(g.device), g.box,
                   state.time, increment_dt, bool(self.musen_compat), self.loads)

    def energy(self, model, state):
        """Elastic energy stored in each bond (J), shape (B,), copied to the host."""
        if model.n_bonds == 0:
            return np.zeros(0)
        g = self.backend_object
        out = cuda.device_array(model.n_bonds)
        launch(bond_energies_kernel, model.n_bonds, self._bonds, self._materials,
               bond_state(g.device, self._model_state), g.device.position, g.box, out)
        return out.copy_to_host()


class IntegratorGpu:
    """Semi-implicit Euler on the device (see ``cpu.Integrator``); never syncs."""

    backend = "gpu"

    def __init__(self, backend):
        self.backend_object = backend
        n = backend.model.n_particles
        self.clumps = (clumps(backend.model, cuda.to_device) if backend.model.n_clumps
                       else None)
        # An empty bond index, for steps without a fused bond law.
        self._no_bonds = (loops.BondIndex(cuda.to_device(np.zeros(n + 1, dtype=np.int64)),
                                          cuda.to_device(np.zeros(1, dtype=np.int64))),
                          loops.BondLoads(*(cuda.to_device(np.zeros((1, 3)))
                                            for _ in range(3))))

    def advance(self, model, state, force, moment, kick_dt, drift_dt, bonds=None,
                use_loads=True):
        """Kick by kick_dt (s), drift by drift_dt (s); the status is read in to_host.

        bonds: an ``ElasticBondsGpu`` whose per-bond loads of this step are gathered here;
        use_loads: also add the force (N) and moment (N m) arrays.
        """
        g = self.backend_object
        index, loads = self._no_bonds if bonds is None else (bonds.index, bonds.loads)
        launch(integrate_kernel, model.n_particles, index, loads, use_loads, particles(g.device),
               g.bodies, force, moment, g.fields, model.damping, kick_dt, drift_dt, g.box,
               g.status, g.device.work, g.device.dissipated)
        if self.clumps is not None:
            launch(clump_kernel, model.n_clumps, force, moment, self.clumps,
                   clump_state(g.device), particles(g.device), g.bodies, g.fields,
                   model.damping, kick_dt, drift_dt, g.box, g.status, g.device.work,
                   g.device.dissipated)
        return STATUS_OK

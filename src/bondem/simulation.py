"""Simulation: owns a Model, a State and the laws, and runs the time loop. No physics here."""
from __future__ import annotations

import contextlib
import math

import numpy as np

from .physics import bond_models, field_models
from .physics.contact_hertz_musen import MUSEN_VERSION, musen_code

from .backends import select_backend
from .integrate import extra_start_up_steps
from .status import SimulationBlowUp
from .timestep import stable_time_step, time_scales
from .walls import Servo, WallHistory


class Simulation:
    """Run a bonded-particle system in time.

    model, state: from ``make_system`` or a scene; time_step: s, or "auto" (safety_factor
    times the smallest time scale, see ``timestep``); a given step above the smallest time
    scale raises ValueError unless force_time_step; musen_compat: reproduce MUSEN's
    numerical choices where they differ from the SPEC; musen_version: the MUSEN release
    reproduced, "1.74.2" (default) or "1.70.0" (their Hertz-Mindlin contacts differ,
    docs/musen_compat.md); laws: extra force laws (contacts,
    walls) with ``accumulate(model, state, force, moment, increment_dt)``; contact: a
    ``ContactSettings`` (None: no particle contacts); walls: PlaneWall / MeshWall objects;
    backend: "cpu" or "gpu" (CUDA; the state then lives on the device and ``self.state``
    is refreshed at the end of every ``step``/``run`` batch; after editing ``self.state``
    on the host, call ``self.backend.to_device(self.state)``). Contacts and walls run on
    both backends (GPU: ``backends.cuda_contacts.ContactLawGpu``); flow: a
    ``coupling.FlowField`` (the fluid's velocity as a function of position and time, a
    local voidage; evaluated before each step).
    """

    def __init__(self, model, state, *, time_step="auto", safety_factor=0.2,
                 force_time_step=False, musen_compat=False, musen_version=MUSEN_VERSION,
                 laws=(), contact=None, walls=(), backend="cpu", flow=None):
        self.model = model
        self.state = state
        stable, cause = stable_time_step(model, safety_factor, musen_compat)
        scales = time_scales(model, musen_compat)
        if contact is not None:
            from .contacts import contact_time_scales
            scales.update(contact_time_scales(model, contact))
            cause = min(scales, key=scales.get)
            stable = safety_factor * scales[cause]
        if isinstance(time_step, str):
            if time_step != "auto":
                raise ValueError(f"time_step = {time_step!r}; expected a number (s) or 'auto'")
            time_step = stable
        time_step = float(time_step)
        if not (time_step > 0.0 and math.isfinite(time_step)):
            raise ValueError(f"time_step = {time_step!r}; must be a positive number of seconds")
        critical = min(scales.values())
        if time_step > critical and not force_time_step:
            raise ValueError(f"time_step = {time_step:.3g} s exceeds the stable limit "
                             f"{critical:.3g} s ({cause}); use a smaller step or force it")
        self.time_step = time_step
        self.time_step_cause = cause
        self.musen_compat = bool(musen_compat)
        # the MUSEN release whose numerics musen_compat reproduces (ValueError if unknown);
        # only the contacts differ between the releases
        self.musen_version = str(musen_version)
        musen_contacts = musen_code(self.musen_version)
        if self.musen_compat:
            for material in model.bond_materials:
                values = {k: getattr(material, k) for k in bond_models.bond_material_schema()}
                for key, message in bond_models.check(values, musen_compat=True):
                    raise ValueError(f"bond material {material.name!r}: {message}")
        if model.n_clumps:
            for name in model.acting_fields:
                if not field_models.BY_NAME[name].CLUMPS:
                    raise ValueError(f"the field [{name}] does not act on clumps yet "
                                     f"(physics/field_{name}.py, docs/fields.md)")
        if flow is not None:
            # the flow's values at the start (a frame saved before the first step shows
            # them; the device gets the array at its size)
            model.fluid_local = flow.values(model, state.position, state.time)
        if state.bond_previous_length is None:
            # A state from before this array existed: its bonds start at their L0.
            state.bond_previous_length = model.bond_initial_length.copy()
        self.backend = select_backend(backend, model, state)
        self.backend_name = backend
        self.contacts = None
        if contact is not None or len(walls):
            from .contacts import ContactSettings
            if contact is None:
                contact = ContactSettings(model="none")
            self.contacts = self.backend.contact_law(model, contact, walls)
            # MUSEN's numerics (physics/contact_hertz_musen.py) for the contact models
            # that declare a MUSEN law ("kind_pp"); the others (linear, liquid bridge)
            # have no MUSEN counterpart here and stay bondem's own
            self.contacts.musen_compat = self.musen_compat and "kind_pp" in getattr(
                self.contacts.law_module, "MUSEN", {})
            self.contacts.musen_code = musen_contacts
            laws = (self.contacts, *laws)
        if flow is not None:
            flow.backend = backend
            flow.attach(None)   # the GPU backend attaches it again in check_laws
            laws = (*laws, flow)
        self.flow = flow
        self.walls = list(walls)
        self._servos = [(k, w.motion) for k, w in enumerate(self.walls)
                        if isinstance(w.motion, Servo)]
        saved = state.extra.get("wall_servo")
        if self._servos and saved is not None and saved.shape == (len(self._servos), 4):
            for (_, servo), (travel, speed, measured, integral) in zip(self._servos, saved):
                servo.travel, servo.speed, servo.measured, servo.integral = \
                    float(travel), float(speed), float(measured), float(integral)
        self.wall_history = (WallHistory(len(self.walls), state.extra.get("wall_history_last"))
                             if self.walls else None)
        self.backend.check_laws(laws)
        self.bonds = self.backend.bond_law(model)
        self.bonds.musen_compat = self.musen_compat
        if self.bonds.model_state:
            # the bond models' per-bond state (a state array: checkpoints keep it); a
            # checkpoint of 0.x before SPRINGS holds the energy column only
            kept = state.extra.get("bond_model_state")
            columns = np.zeros((model.n_bonds, bond_models.STATE_COLUMNS))
            if kept is not None and kept.ndim == 1:
                columns[:, 0] = kept
                state.extra["bond_model_state"] = columns
            elif kept is None:
                state.extra["bond_model_state"] = columns
        self.laws = [self.bonds, *laws]
        self.integrator = self.backend.integrator(model)
        self.force, self.moment = self.backend.load_arrays(model.n_particles)

    def couple(self, solver, every=1, grid=None):
        """Couple a fluid solver (coupling.py): every ``every`` steps ``solver`` gets an
        ``Exchange`` (positions, velocities, radii, the voidage of ``grid`` = (low, high,
        shape) or None, the time its loads will act) and returns the particles' force
        (N,3) N [and moment (N,3) N m], which act as external loads until the next
        exchange. On the GPU the particles come to the host for each exchange. Returns the
        coupling (its ``exchanges`` count)."""
        from .coupling import FluidCoupling
        coupling = FluidCoupling(self.model, solver, every, grid, self.time_step,
                                 self.musen_compat)
        coupling.backend = self.backend_name
        self.backend.check_laws([coupling])
        self.laws.append(coupling)
        return coupling

    def __repr__(self):
        state = self.state
        intact = int(np.count_nonzero(state.bond_active))
        contact = self.contacts.settings.model if self.contacts else "none"
        return (f"Simulation(t = {state.time:.6g} s, step {state.step}, "
                f"dt = {self.time_step:.4g} s, {self.model.n_particles} particles, "
                f"{intact} of {self.model.n_bonds} bonds intact, contacts {contact}, "
                f"{len(self.walls)} walls, backend {self.backend_name})")

    @property
    def wall_force(self):
        """(W,3) N: total force on each wall in the last step."""
        return self.contacts.wall_force if self.contacts else np.zeros((0, 3))

    @property
    def wall_torque(self):
        """(W,3) N m: torque on each wall about its reference point in the last step."""
        return self.contacts.wall_torque if self.contacts else np.zeros((0, 3))

    def wall_positions(self):
        """(W,3) m: each wall's reference point at the current time."""
        return np.array([w.position(self.state.time) for w in self.walls]).reshape(-1, 3)

    def step(self, steps=1):
        """Advance by ``steps`` time steps of ``time_step`` s (the first one is the
        start-up step of SPEC 1; MUSEN-compatible runs add MUSEN's prediction step)."""
        # CPU: small systems run on one thread (same results, less thread overhead).
        limit = getattr(self.integrator, "thread_limit", None)
        with limit(self.model) if limit else contextlib.nullcontext():
            # the GPU keeps the wall loads on the device: they come back per step only
            # for servos, else at the end of the batch
            per_step = self.wall_history is not None and (
                self._servos or self.backend_name == "cpu")
            for _ in range(steps + extra_start_up_steps(self.state.started,
                                                         self.musen_compat)):
                evaluated = self.state.time
                self.backend.step(self.model, self.state, self.laws, self.integrator,
                                  self.force, self.moment, self.time_step, self.musen_compat)
                if per_step:
                    self._after_step(evaluated)
        self.backend.to_host(self.state)
        if self.wall_history is not None and not per_step and steps:
            evaluated = getattr(self.contacts, "_evaluated_time", None)
            self._after_step(self.state.time if evaluated is None else evaluated,
                             servos=False)

    def _after_step(self, evaluated, servos=True):
        """Record the wall loads of the step evaluated at ``evaluated`` (s) and move the
        servo walls on (their state goes into ``state.extra["wall_servo"]``)."""
        if self.backend_name != "cpu":
            self.contacts.to_host(self.state)
        force = self.wall_force
        self.wall_history.record(evaluated, force,
                                 [w.position(evaluated) for w in self.walls])
        # a resumed run records from the same last row (checkpoints keep it)
        self.state.extra["wall_history_last"] = self.wall_history.last
        if servos and self._servos:
            saved = np.empty((len(self._servos), 4))
            for row, (k, servo) in enumerate(self._servos):
                servo.update(force[k], self.time_step)
                saved[row] = servo.travel, servo.speed, servo.measured, servo.integral
            self.state.extra["wall_servo"] = saved

    def synchronize(self):
        """Wait until the backend has finished every queued step (for timing)."""
        self.backend.synchronize()

    def run(self, until=None, *, steps=None, callback=None, every=None):
        """Run to time ``until`` (s) or for ``steps`` steps.

        callback(simulation) is called every ``every`` seconds of simulated time (and at
        the end). On a blow-up, SimulationBlowUp is raised with ``last_good_state`` set to
        a copy of the state at the last callback (or at the start).
        """
        if (until is None) == (steps is None):
            raise ValueError("run: give exactly one of until (s) or steps")
        dt = self.time_step
        if steps is None:
            steps = max(0, int(round((until - self.state.time) / dt)))
        stride = steps if every is None else max(1, int(round(every / dt)))
        good = self.state.copy()
        done = 0
        try:
            while done < steps:
                chunk = min(stride, steps - done)
                self.step(chunk)
                done += chunk
                if callback is not None:
                    callback(self)
                good = self.state.copy() if done < steps else good
        except SimulationBlowUp as error:
            error.last_good_state = good
            raise

    def kinetic_energy(self):
        """(translational, rotational) kinetic energy in J at the current velocities:
        the free spheres' and the clumps' (``clumps.clump_kinetic_energy``)."""
        m = self.model
        mass, inertia = m.mass, m.inertia
        if m.n_clumps:
            free = m.clump_of < 0
            mass, inertia = np.where(free, mass, 0.0), np.where(free, inertia, 0.0)
        translational = 0.5 * float(np.sum(mass * np.einsum("ij,ij->i", self.state.velocity,
                                                               self.state.velocity)))
        rotational = 0.5 * float(np.sum(inertia * np.einsum(
            "ij,ij->i", self.state.angular_velocity, self.state.angular_velocity)))
        if m.n_clumps:
            from .clumps import clump_kinetic_energy
            t, r = clump_kinetic_energy(m, self.state)
            translational += t
            rotational += r
        return translational, rotational

    def bond_energy(self):
        """Elastic energy stored in all intact bonds (J)."""
        return float(self.bonds.energy(self.model, self.state).sum())

    def energy_terms(self):
        """Energy bookkeeping in J: stored (kinetic, bond elastic, and each law's own),
        and cumulative since t = 0 (work of gravity and external loads, energy removed by
        damping, energy held by bonds when they broke, and each law's counters).
        Balance: stored(t) - stored(0) = work - dissipated - released."""
        translational, rotational = self.kinetic_energy()
        state = self.state
        terms = {"kinetic_translational": translational, "kinetic_rotational": rotational,
                 "bond_elastic": self.bond_energy(), "work_external": state.work_external,
                 "dissipated_damping": state.dissipated_damping,
                 "released_breakage": float(state.bond_break_energy.sum())}
        if "bond_model_state" in state.extra:
            # each bond model's state is an energy term (STATE): its sum over its bonds
            codes = self.model.bond_model_codes()
            for module in self.model.bond_models_used():
                if module.STATE:
                    mine = codes == module.CODE
                    terms[module.STATE[1]] = float(
                        state.extra["bond_model_state"][mine, 0].sum())
        for law in self.laws[1:]:
            if hasattr(law, "energy_terms"):
                terms.update(law.energy_terms(self.model, state))
        return terms

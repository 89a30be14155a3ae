"""Coupling to a fluid solver (CFD, lattice Boltzmann, a model of one's own): every N
steps bondem hands the solver the particles and a voidage field, and takes back a force
and a moment per particle, which then act until the next exchange.

The exchange (``Exchange``) holds the time (s), the particles' positions (m), velocities
(m/s, the leapfrog's: half a step behind the positions), radii (m) and fixed flags, the
voidage of each grid cell (the particle-centre method: 1 - the volume of the spheres
whose centre lies in the cell over the cell's volume) and ``interval``, the time (s) for
which the returned loads will act (the kicks until the next exchange: the solver applies
the opposite impulse to its fluid over the same time, and the momentum exchanged sums to
zero). The solver returns ``force`` (N, 3) N and optionally ``moment`` (N, 3) N m.

The loads go through the particles' external loads (``Model.external_force`` and
``external_moment``, on top of any given ones), so the integrator books their work in
``work_external`` exactly and the energy balance stays closed. On the GPU the particles
are copied to the host for each exchange and the loads back to the device.

``FlowField`` gives the fluid a velocity that varies in space and time (a function of the
positions and the time, e.g. ``expression.flow_function``'s formulas) and the drag laws a
local voidage (that of the grid cell a particle's centre lies in), both evaluated before
every step on the host and handed to the particle loop as ``Model.fluid_local``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .integrate import step_plan


@dataclass
class Exchange:
    """What a fluid solver is handed (module docstring; SI units)."""
    time: float
    step: int
    interval: float
    position: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    radius: np.ndarray
    fixed: np.ndarray
    voidage: np.ndarray | None
    grid: tuple | None


def voidage_grid(position, radius, low, high, shape):
    """Voidage (-) of each cell of the box low..high (m) cut into ``shape`` (3 ints)
    cells: 1 - the volume of the spheres (radius in m) whose centre lies in the cell, over
    the cell's volume; centres outside the box are left out. Can be below 0 where spheres
    crowd a cell smaller than they are."""
    cell, inside, size = grid_cells(position, low, high, shape)
    volume = 4.0 / 3.0 * np.pi * np.asarray(radius, dtype=float) ** 3
    solid = np.zeros(tuple(int(s) for s in shape))
    np.add.at(solid, tuple(cell[inside].T), volume[inside])
    return 1.0 - solid / float(np.prod(size))


def grid_cells(position, low, high, shape):
    """The cell (i, j, k) of each position (N,3) m in the box low..high (m) cut into
    ``shape`` cells, (N,3) int64; whether it lies in the box, (N,) bool; the cell size
    (3,) m."""
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    shape = np.array([int(s) for s in shape])
    size = (high - low) / shape
    cell = np.floor((np.asarray(position) - low) / size).astype(np.int64)
    return cell, np.all((cell >= 0) & (cell < shape), axis=1), size


def host_particles(device, state, names):
    """The state's particle arrays ``names`` on the host: the state's own (CPU), or copies
    from a GPU backend's device state (``device``: the backend attached, or None)."""
    if device is None:
        return [getattr(state, name) for name in names]
    return [getattr(device.device, name).copy_to_host() for name in names]


class FlowField:
    """A law of a Simulation (its ``flow`` argument): before each step, the fluid's
    velocity at each particle, ``velocity(position (N,3) m, time s) -> (N,3) m/s`` (added
    to the fluid's own: its uniform velocity, spin and grid; None: nothing added), and the
    voidage around each particle, that of the cell of ``voidage_grid`` = (low (3,) m,
    high (3,) m, cells (3 ints)) its centre lies in (``voidage_grid``), clipped to
    [voidage_floor, 1] (None: the fluid's single voidage), into ``Model.fluid_local``.
    Evaluated every step from the positions and the time at its start, so a resumed run
    repeats a straight one bit for bit. On the GPU the positions come to the host and the
    array goes back each step."""

    def __init__(self, velocity=None, voidage_grid=None, voidage_floor=0.2):
        if velocity is None and voidage_grid is None:
            raise ValueError("FlowField: give a velocity function, a voidage grid or both")
        if velocity is not None and not callable(velocity):
            raise ValueError(f"FlowField: velocity must be a function (position, time), "
                             f"got {velocity!r}")
        if voidage_grid is not None:
            low, high, cells = voidage_grid
            low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
            cells = np.asarray(cells)
            if (low.shape != (3,) or high.shape != (3,) or cells.shape != (3,)
                    or not np.all(np.isfinite(low) & np.isfinite(high)) or np.any(high <= low)
                    or np.any(cells < 1) or np.any(cells != np.round(cells))):
                raise ValueError(f"voidage_grid = {voidage_grid!r}: expected (low (3,) m, "
                                 "high (3,) m > low, cells (3 integers >= 1))")
            voidage_grid = (low, high, tuple(int(c) for c in cells))
        if not 0.0 < float(voidage_floor) <= 1.0:
            raise ValueError(f"voidage_floor = {voidage_floor!r}; allowed: (0, 1]")
        self.velocity, self.voidage_grid = velocity, voidage_grid
        self.voidage_floor = float(voidage_floor)
        self.backend = "cpu"   # set by the Simulation that runs it
        self._device = None

    def attach(self, backend):
        """Run on a GPU ``backend`` (its device state, ``set_fluid_local``)."""
        self._device = backend

    def values(self, model, position, time, out=None):
        """(N, 4): the fluid's added velocity (m/s) and the voidage (-) at each particle at
        ``position`` (N,3) m and ``time`` (s), into ``out`` when given. ValueError if the
        function gives a shape other than (N,3) or (3,), or a value that is not finite."""
        n = position.shape[0]
        out = np.zeros((n, 4)) if out is None else out
        if self.velocity is not None:
            u = np.asarray(self.velocity(position, time), dtype=np.float64)
            if u.shape not in ((n, 3), (3,)):
                raise ValueError(f"fluid velocity: expected {n} x 3 values (m/s), got shape "
                                 f"{u.shape}")
            bad = ~np.isfinite(np.broadcast_to(u, (n, 3))).all(axis=1)
            if bad.any():
                p = int(np.flatnonzero(bad)[0])
                raise ValueError(f"fluid velocity at t = {time:.6g} s is not finite at particle "
                                 f"{p}, x = {position[p].tolist()} m")
            out[:, :3] = u
        if self.voidage_grid is not None:
            low, high, cells = self.voidage_grid
            field = voidage_grid(position, model.radius, low, high, cells)
            cell, inside, _ = grid_cells(position, low, high, cells)
            out[:, 3] = 1.0
            out[inside, 3] = field[tuple(cell[inside].T)]
            np.clip(out[:, 3], self.voidage_floor, 1.0, out=out[:, 3])
        return out

    def accumulate(self, model, state, force, moment, increment_dt):
        """Set ``model.fluid_local`` for this step (no loads of its own)."""
        position, = host_particles(self._device, state, ("position",))
        # the Simulation gave the array its (N, 4) at the start
        self.values(model, position, state.time, out=model.fluid_local)
        if self._device is not None:
            self._device.set_fluid_local(model.fluid_local)


class FluidCoupling:
    """An extra law of a Simulation (``Simulation.couple``): calls ``solver(exchange)``
    every ``every`` steps and sets the particles' external loads to the given ones plus
    what it returns. ``grid``: (low (3,) m, high (3,) m, shape (3,)) of the voidage field,
    or None for none. ``time_step`` (s) and ``musen_compat``: the Simulation's, for the
    kicks' durations. On a GPU backend (``attach``) the particles come to the host for
    each exchange and the loads go back to the device."""
    backend = "cpu"

    def __init__(self, model, solver, every, grid, time_step, musen_compat=False):
        if int(every) < 1:
            raise ValueError(f"every = {every!r}; allowed: an integer >= 1")
        self.solver, self.every, self.grid = solver, int(every), grid
        self.time_step, self.musen_compat = float(time_step), musen_compat
        self.base_force = model.external_force.copy()
        self.base_moment = model.external_moment.copy()
        self.exchanges = 0
        self._last = -1
        self._device = None

    def attach(self, backend):
        """Run on a GPU ``backend`` (its device state, ``set_external_loads``)."""
        self._device = backend

    def _interval(self, state):
        """The kicks' time (s) from this step to the next exchange."""
        started = state.started
        total = 0.0
        steps = 0
        while steps < self.every:
            _, kick, _, advances = step_plan(started, self.time_step, self.musen_compat)
            total += kick
            started = True
            steps += 1 if advances else 0
        return total

    def accumulate(self, model, state, force, moment, increment_dt):
        """On an exchange step, ask the solver for the loads (the force and moment arrays
        of the step are left alone: the loads go into the external ones)."""
        # once per exchange step (MUSEN's prediction step repeats step 0)
        if state.step % self.every or state.step == self._last:
            return
        self._last = state.step
        position, velocity, angular_velocity = (
            a.copy() for a in host_particles(self._device, state,
                                             ("position", "velocity", "angular_velocity")))
        voidage = None
        if self.grid is not None:
            voidage = voidage_grid(position, model.radius, *self.grid)
        exchange = Exchange(state.time, state.step, self._interval(state), position,
                            velocity, angular_velocity, model.radius.copy(),
                            model.fixed.copy(), voidage, self.grid)
        answer = self.solver(exchange)
        loads = answer if isinstance(answer, tuple) else (answer, None)
        n = model.n_particles
        for k, (name, value) in enumerate(zip(("force", "moment"), loads)):
            if value is None:
                continue
            value = np.asarray(value, dtype=np.float64)
            if value.shape != (n, 3) or not np.all(np.isfinite(value)):
                raise ValueError(f"coupling solver: {name} must be {n} x 3 finite numbers, "
                                 f"got shape {value.shape}")
            target = model.external_force if k == 0 else model.external_moment
            target[...] = (self.base_force if k == 0 else self.base_moment) + value
        if self._device is not None:
            self._device.set_external_loads(model.external_force, model.external_moment)
        self.exchanges += 1

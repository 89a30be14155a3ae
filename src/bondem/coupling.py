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
``work_external`` exactly and the energy balance stays closed. CPU backend.
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
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    shape = tuple(int(s) for s in shape)
    size = (high - low) / np.array(shape)
    cell = np.floor((np.asarray(position) - low) / size).astype(np.int64)
    inside = np.all((cell >= 0) & (cell < np.array(shape)), axis=1)
    volume = 4.0 / 3.0 * np.pi * np.asarray(radius, dtype=float) ** 3
    solid = np.zeros(shape)
    np.add.at(solid, tuple(cell[inside].T), volume[inside])
    return 1.0 - solid / float(np.prod(size))


class FluidCoupling:
    """An extra law of a Simulation (``Simulation.couple``): calls ``solver(exchange)``
    every ``every`` steps and sets the particles' external loads to the given ones plus
    what it returns. ``grid``: (low (3,) m, high (3,) m, shape (3,)) of the voidage field,
    or None for none. ``time_step`` (s) and ``musen_compat``: the Simulation's, for the
    kicks' durations."""
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
        voidage = None
        if self.grid is not None:
            voidage = voidage_grid(state.position, model.radius, *self.grid)
        exchange = Exchange(state.time, state.step, self._interval(state),
                            state.position.copy(), state.velocity.copy(),
                            state.angular_velocity.copy(), model.radius.copy(),
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
        self.exchanges += 1

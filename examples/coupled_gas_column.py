"""Two-way coupling of bondem to a fluid solver written for this example: a column of gas
cut into cells along z (periodic), each with one velocity, exchanging Stokes drag with
the particles in it (docs/fields.md, "Coupling to a fluid solver").

Every exchange, a particle of diameter d at velocity v in a cell whose gas moves at u
gets F = 3 pi mu d (u - v) for the exchange's interval T; the cell's gas gets -F for the
same T (and diffuses its momentum to its neighbours by the gas viscosity, in a flux form
that moves momentum between cells without making or losing any). The gas is dilute: a
cell's gas mass is rho A dz whatever the particles in it (the exchange's voidage is
printed, not used). So the total momentum, particles' plus gas', stays what it was, and
everything ends at its mean velocity.

    python examples/coupled_gas_column.py     # prints the momentum and the end velocities
"""
import numpy as np

import bondem


class GasColumn:
    """A periodic column of gas, ``cells`` cells along z between z_low and z_high (m), of
    cross-section ``area`` (m^2), density rho (kg/m^3), viscosity mu (Pa s), velocities
    u (cells, 3) m/s. ``__call__`` is the coupling solver (bondem.coupling)."""

    def __init__(self, cells, z_low, z_high, area, rho, mu, u):
        self.cells, self.z_low, self.z_high = cells, z_low, z_high
        self.dz = (z_high - z_low) / cells
        self.area, self.rho, self.mu = area, rho, mu
        self.u = np.array(u, dtype=float).reshape(cells, 3)
        self.impulse = []    # per exchange: (impulse on particles, on gas) N s

    def mass(self):
        """Gas mass (kg) of each cell (dilute: the particles displace none)."""
        return np.full(self.cells, self.rho * self.area * self.dz)

    def __call__(self, exchange):
        z = exchange.position[:, 2]
        cell = np.floor((z - self.z_low) / self.dz).astype(int) % self.cells
        drag = (3.0 * np.pi * self.mu * 2.0 * exchange.radius)[:, None] \
            * (self.u[cell] - exchange.velocity)
        drag[exchange.fixed] = 0.0
        self.voidage = exchange.voidage.reshape(self.cells)
        mass = self.mass()
        # the gas: -drag over the interval, then viscous exchange between cells
        # (periodic, the same flux leaves one cell and enters the next)
        kick = np.zeros_like(self.u)
        np.add.at(kick, cell, -drag * exchange.interval)
        momentum = mass[:, None] * self.u + kick
        flux = self.mu * self.area / self.dz * (np.roll(self.u, -1, axis=0) - self.u) \
            * exchange.interval
        momentum += flux - np.roll(flux, 1, axis=0)
        self.u = momentum / mass[:, None]
        self.impulse.append((drag.sum(axis=0) * exchange.interval, kick.sum(axis=0)))
        return drag

    def momentum(self):
        """The gas's momentum (3,) kg m/s."""
        return (self.mass()[:, None] * self.u).sum(axis=0)


def column(seed=4, particles=20, cells=4):
    """Particles at rest in a 4 x 4 x 16 mm periodic column of a viscous gas moving up
    and sideways, slower at the bottom. Returns (simulation, gas, grid)."""
    rng = np.random.default_rng(seed)
    low, high = np.array([0.0, 0.0, 0.0]), np.array([4e-3, 4e-3, 16e-3])
    position = low + (high - low) * rng.uniform(0.1, 0.9, (particles, 3))
    radius = rng.uniform(5e-5, 1e-4, particles)
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    model, state = bondem.make_system(position, radius, glass)
    sim = bondem.Simulation(model, state, time_step=1e-5, force_time_step=True)
    speeds = np.linspace(0.2, 1.0, cells)
    gas = GasColumn(cells, low[2], high[2], 16e-6, 1.0, 1e-2,
                    np.column_stack([0.3 * speeds, np.zeros(cells), speeds]))
    grid = (low, high, (1, 1, cells))
    return sim, gas, grid


def main():
    sim, gas, grid = column()
    coupling = sim.couple(gas, every=10, grid=grid)

    def total():
        return (sim.model.mass[:, None] * sim.state.velocity).sum(axis=0) + gas.momentum()

    before = total()
    sim.run(until=0.15)
    print(f"{coupling.exchanges} exchanges; momentum before {before}, after {total()} kg m/s")
    print(f"gas velocities (m/s, z): {gas.u[:, 2].round(4)}")
    print(f"particle velocities (m/s, z): {sim.state.velocity[:5, 2].round(4)} ...")
    print(f"voidage of the cells: {gas.voidage.round(5)}")


if __name__ == "__main__":
    main()

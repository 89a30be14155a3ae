"""Conservation laws of the bonded system without damping or breakage.

- Energy: kinetic + rotational + bond elastic energy (the four springs' potentials) shows
  no secular drift: the window means at the start and the end of 10^5 steps agree to
  1e-4 (leapfrog's bounded O(dt^2) oscillation averages out in a window).
- Linear and angular momentum: bond forces are equal and opposite and their moments
  balance (r x F_t = (r/2) x F_t on each side), so sum m v and
  sum m x x v + I w are conserved to round-off by the leapfrog (with x_n, v_{n-1/2}).
- Rigid rotation: a pair or a cube spinning about a principal axis needs only the
  centripetal tension. Shear force and moments stay at the small bounded level set by
  the leapfrog start (velocities half a step behind positions: O((w dt)^2) per step) and
  do not grow with the turns: T is an exact rotation (test_bond_pure checks that T keeps
  lengths exactly; an approximate T grows stored vectors by (1 + (w dt)^2) per step).
"""
import numpy as np
import pytest

import bondem


def random_cluster(glass, n_side=5, seed=1):
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(*[np.arange(n_side)] * 3, indexing="ij"), -1).reshape(-1, 3)
    position = grid * 2e-3 + rng.normal(0, 5e-5, grid.shape)
    radius = rng.uniform(0.9e-3, 1.1e-3, len(grid))
    distance = np.linalg.norm(position[:, None] - position[None], axis=-1)
    i, j = np.nonzero(np.triu(distance < 3.0e-3, 1))  # nearest and face-diagonal pairs
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, breakage="none")
    return bondem.make_system(position, radius, glass,
                              velocity=rng.normal(0, 2e-3, grid.shape),
                              angular_velocity=rng.normal(0, 2.0, grid.shape),
                              bonds=np.column_stack([i, j]),
                              bond_diameter=rng.uniform(0.6e-3, 1.0e-3, len(i)),
                              bond_material=binder)


def momenta(model, state):
    linear = (model.mass[:, None] * state.velocity).sum(0)
    angular = (np.cross(state.position, model.mass[:, None] * state.velocity).sum(0)
               + (model.inertia[:, None] * state.angular_velocity).sum(0))
    return linear, angular


def total_energy(sim):
    return sum(sim.kinetic_energy()) + sim.bond_energy()


@pytest.mark.slow
def test_energy_and_momentum_over_1e5_steps(glass):
    model, state = random_cluster(glass)
    assert model.n_particles >= 100 and model.n_bonds >= 300
    sim = bondem.Simulation(model, state, safety_factor=0.1)
    p0, l0 = momenta(model, state)
    sim.step(0)
    window, sample = 2000, 10

    def window_mean():
        values = []
        for _ in range(window // sample):
            sim.step(sample)
            values.append(total_energy(sim))
        return np.mean(values)

    first = window_mean()
    sim.step(100_000 - 2 * window)
    last = window_mean()
    assert state.step == 100_000
    assert abs(last - first) / first < 1e-4
    p1, l1 = momenta(model, state)
    scale_p = np.sum(model.mass * np.linalg.norm(state.velocity, axis=1))
    scale_l = np.sum(model.mass * np.linalg.norm(np.cross(state.position, state.velocity), axis=1))
    assert np.all(np.abs(p1 - p0) < 1e-12 * scale_p)
    assert np.all(np.abs(l1 - l0) < 1e-10 * scale_l)


def spin_up(model, state, omega):
    centre = (model.mass[:, None] * state.position).sum(0) / model.mass.sum()
    state.angular_velocity[:] = omega
    state.velocity[:] = np.cross(omega, state.position - centre)


@pytest.mark.parametrize("shape", ["pair", "cube"])
def test_rigid_rotation_stores_no_spurious_bond_load(glass, binder, shape):
    if shape == "pair":
        position, bonds = [[0, 0, 0], [2e-3, 0, 0]], [[0, 1]]
    else:
        position = np.array([[x, y, z] for x in (0, 2e-3) for y in (0, 2e-3) for z in (0, 2e-3)])
        bonds = [(a, b) for a in range(8) for b in range(a + 1, 8)
                 if np.isclose(np.linalg.norm(position[a] - position[b]), 2e-3)]
    model, state = bondem.make_system(position, 1e-3, glass, bonds=bonds, bond_diameter=1e-3,
                                      bond_material=binder)
    omega = np.array([0.0, 0.0, 500.0])  # rad/s about a principal axis through the centre
    spin_up(model, state, omega)
    sim = bondem.Simulation(model, state)
    normal, shear, moment = [], [], []
    for _ in range(200):
        sim.step(50)
        load = np.linalg.norm(sim.bonds.force_i, axis=1)
        tangential = np.linalg.norm(state.bond_tangential_force, axis=1)
        normal.append(np.sqrt(np.maximum(load ** 2 - tangential ** 2, 0)).max())
        shear.append(tangential.max())
        moment.append(max(np.linalg.norm(state.bond_normal_moment, axis=1).max(),
                          np.linalg.norm(state.bond_tangential_moment, axis=1).max()))
    assert np.linalg.norm(omega) * state.time > 2 * np.pi  # more than a full turn
    # centripetal tension m w^2 R at the centre of mass, as the mean of the axial swing
    centripetal = model.mass[0] * 500.0 ** 2 * 1e-3
    if shape == "pair":
        assert np.mean(normal) == pytest.approx(centripetal, rel=0.1)
    peak = max(normal)
    assert max(shear) < 0.02 * peak
    assert max(moment) < 0.02 * peak * 2e-3
    assert max(shear[-70:]) < 2 * max(shear[:70])      # bounded, not growing with turns
    assert max(moment[-70:]) <= 2 * max(moment[:70])
    assert np.allclose(state.angular_velocity, omega, rtol=1e-3)

"""The vectorised path of the bond kernel (cpu.elastic_bonds) gives the scalar path's bits.

Both paths advance the same random bonded cluster for several steps: particles spinning fast
enough that some twists leave the series' range (the vectorised path's fallback), bonds
that break in tension, shear and compression under three criteria (its exact break test),
bonds already broken, a periodic axis, and a bond count that is not a multiple of the
block. Every array the kernels write must be identical, not merely close.
"""
import copy

import numba
import numpy as np
import pytest

from bondem.backends import cpu
from bondem.model import BondMaterial, Material, make_system
from bondem.physics.rotation import SMALL_ANGLE

DT = 1e-6


def random_cluster(seed, n_particles=150, periodic=False):
    rng = np.random.default_rng(seed)
    radius = 1e-3
    position = rng.uniform(0.0, 0.012, size=(n_particles, 3))
    distance = np.linalg.norm(position[:, None] - position[None], axis=2)
    i, j = np.nonzero(np.triu(distance < 3.2 * radius, 1))
    bonds = np.stack([i, j], axis=1)
    glass = Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                     restitution=0.5, friction=0.3, name="glass")
    weak = dict(young_modulus=1e8, poisson_ratio=0.3, normal_strength=4e5,
                tangential_strength=4e5)
    materials = [BondMaterial(**weak, name="combined"),
                 BondMaterial(**weak, breakage="separate", compressive_breakage=True,
                              name="separate"),
                 BondMaterial(**weak, breakage="none", name="unbreakable")]
    model, state = make_system(
        position, radius, glass, velocity=rng.normal(0.0, 0.3, size=(n_particles, 3)),
        bonds=bonds, bond_diameter=rng.uniform(0.5e-3, 1e-3, size=len(bonds)),
        bond_material=materials, bond_material_index=rng.integers(0, 3, size=len(bonds)),
        periodic=(periodic, False, False), box_low=(0.0, 0.0, 0.0),
        box_high=(0.012, 0.012, 0.012))
    # A spin whose twist per step, |w| dt / 2, exceeds the series' range for some bonds.
    state.angular_velocity[:] = rng.normal(0.0, 2.0 * SMALL_ANGLE / DT / 3.0,
                                           size=(n_particles, 3))
    state.bond_active[rng.random(len(bonds)) < 0.1] = False
    return model, state


def advance(vectorised, model, state, steps):
    bonds = cpu.ElasticBonds(model)
    bonds.vectorised = vectorised
    bonds.vectorise_from = 0      # this small cluster too
    loads = []
    for step in range(steps):
        bonds.compute(model, state, DT)
        loads.append(np.concatenate([bonds.force_i, bonds.moment_i, bonds.moment_j]))
        # Move the particles so that the bonds stretch, shear, bend and twist.
        state.position += state.velocity * DT * 20
        state.time += DT
    return loads


@pytest.mark.parametrize("periodic", [False, True])
def test_vectorised_path_matches_the_scalar_path_bit_for_bit(periodic):
    model, start = random_cluster(7, periodic=periodic)
    assert model.n_bonds % cpu.BOND_BLOCK != 0
    scalar, blocked = copy.deepcopy(start), copy.deepcopy(start)
    loads_scalar = advance(False, model, scalar, 12)
    loads_blocked = advance(True, model, blocked, 12)
    for a, b in zip(loads_scalar, loads_blocked):
        np.testing.assert_array_equal(a, b)
    for name in ("bond_active", "bond_axis", "bond_previous_length",
                 "bond_tangential_force", "bond_normal_moment", "bond_tangential_moment",
                 "bond_break_mode", "bond_break_energy", "bond_break_time"):
        np.testing.assert_array_equal(getattr(scalar, name), getattr(blocked, name),
                                      err_msg=name)
    # The case must exercise what it claims: breaks of several kinds, and large twists.
    broke = (blocked.bond_break_mode != 0) & start.bond_active
    assert broke.sum() >= 5 and len(set(blocked.bond_break_mode[broke])) >= 2
    w_sum = (start.angular_velocity[model.bond_pairs[:, 0]]
             + start.angular_velocity[model.bond_pairs[:, 1]])
    assert np.any(0.5 * np.linalg.norm(w_sum, axis=1) * DT > SMALL_ANGLE)


def test_vectorised_path_is_the_same_with_one_and_two_threads():
    model, start = random_cluster(11)
    results = []
    previous = numba.get_num_threads()
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            state = copy.deepcopy(start)
            results.append((advance(True, model, state, 5), state))
    finally:
        numba.set_num_threads(previous)
    (loads_1, state_1), (loads_2, state_2) = results
    for a, b in zip(loads_1, loads_2):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(state_1.bond_tangential_moment,
                                  state_2.bond_tangential_moment)

"""The vectorised path of the bond kernel (cpu.elastic_bonds) gives the scalar path's bits.

Both paths advance the same random bonded cluster for several steps: particles spinning fast
enough that some twists leave the series' range (the vectorised path's fallback), bonds
that break in tension, shear and compression under three criteria (its exact break test),
bonds already broken, a periodic axis, and a bond count that is not a multiple of the
block. Every array the kernels write must be identical, not merely close. The vectorised
path skips broken bonds and tests the bonds near their strength exactly in the block
(cpu.settle_block_breaks), so the case has both, and bonds broken outside the kernel must
put no load on their particles.
"""
import copy

import numba
import numpy as np
import pytest

from bondem.backends import cpu
from bondem.model import BondMaterial, Material, make_system
from bondem.physics.bond_elastic import (CRITERION_CODES, CRITERION_NONE, INTACT,
                                         bond_break_mode, bond_breaks, bond_surely_intact)
from bondem.physics.rotation import SMALL_ANGLE

DT = 1e-6


def random_cluster(seed, n_particles=150, periodic=False, materials="three"):
    """A random bonded cluster; materials: "three" bond materials (three criteria), "one"
    (every bond the same, no strength scatter: the kernel's uniform constants), or
    "scattered" (one material whose strengths scatter from bond to bond)."""
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
    index = rng.integers(0, 3, size=len(bonds))
    if materials == "three":
        materials = [BondMaterial(**weak, name="combined"),
                     BondMaterial(**weak, breakage="separate", compressive_breakage=True,
                                  name="separate"),
                     BondMaterial(**weak, breakage="none", name="unbreakable")]
    else:
        # normal and tangential strengths apart, so that a swap of the two shows
        scatter = (dict(strength_scatter="normal", strength_spread=0.3, strength_seed=5)
                   if materials == "scattered" else {})
        materials = [BondMaterial(young_modulus=1.3e8, poisson_ratio=0.21,
                                  normal_strength=3e5, tangential_strength=6e5,
                                  name="one", **scatter)]
        index = np.zeros(len(bonds), dtype=int)
    model, state = make_system(
        position, radius, glass, velocity=rng.normal(0.0, 0.3, size=(n_particles, 3)),
        bonds=bonds, bond_diameter=rng.uniform(0.5e-3, 1e-3, size=len(bonds)),
        bond_material=materials, bond_material_index=index,
        periodic=(periodic, False, False), box_low=(0.0, 0.0, 0.0),
        box_high=(0.012, 0.012, 0.012))
    # A spin whose twist per step, |w| dt / 2, exceeds the series' range for some bonds.
    state.angular_velocity[:] = rng.normal(0.0, 2.0 * SMALL_ANGLE / DT / 3.0,
                                           size=(n_particles, 3))
    state.bond_active[rng.random(len(bonds)) < 0.1] = False
    return model, state


def advance(vectorised, model, state, steps, near=None):
    bonds = cpu.ElasticBonds(model)
    bonds.vectorised = vectorised
    bonds.vectorise_from = 0      # this small cluster too
    loads = []
    for step in range(steps):
        bonds.compute(model, state, DT)
        loads.append(np.concatenate([bonds.force_i, bonds.moment_i, bonds.moment_j]))
        if near is not None:
            near.append(not_surely_intact(model, state, bonds))
        # Move the particles so that the bonds stretch, shear, bend and twist.
        state.position += state.velocity * DT * 20
        state.time += DT
    return loads


def not_surely_intact(model, state, bonds):
    """Intact bonds whose loads ``bond_surely_intact`` cannot clear (the normal force
    taken as force_i - F_t, close enough for a count)."""
    table = model.bond_material_table()
    count = 0
    for b in np.flatnonzero(state.bond_active):
        m = model.bond_material[b]
        criterion = int(table["breakage"][m])
        f_t = tuple(state.bond_tangential_force[b])
        f_n = tuple(bonds.force_i[b] - state.bond_tangential_force[b])
        count += criterion != CRITERION_NONE and not bond_surely_intact(
            f_n, f_t, tuple(state.bond_normal_moment[b]), tuple(state.bond_tangential_moment[b]),
            model.bond_diameter[b], table["normal_strength"][m], table["tangential_strength"][m],
            criterion)
    return count


@pytest.mark.parametrize("periodic, materials", [(False, "three"), (True, "three"),
                                                 (False, "one"), (True, "scattered")])
def test_vectorised_path_matches_the_scalar_path_bit_for_bit(periodic, materials):
    model, start = random_cluster(7, periodic=periodic, materials=materials)
    assert model.n_bonds % cpu.BOND_BLOCK != 0
    # one material and no scatter: the kernel writes the bonds' constants once
    assert cpu.ElasticBonds(model)._uniform == (materials == "one")
    scalar, blocked = copy.deepcopy(start), copy.deepcopy(start)
    near = []
    loads_scalar = advance(False, model, scalar, 12)
    loads_blocked = advance(True, model, blocked, 12, near)
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
    # bonds past half their strength that stay intact: the block's exact test clears them
    assert sum(near) >= 20
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


@pytest.mark.parametrize("vectorised", [False, True])
def test_a_bond_broken_outside_the_kernel_puts_no_load(vectorised):
    """A bond set broken between steps (a resumed state, a user's edit) has zero loads
    after the next step, though the vectorised path never visits broken bonds again; set
    intact again, it carries load."""
    model, state = random_cluster(5)
    bonds = cpu.ElasticBonds(model)
    bonds.vectorised = vectorised
    bonds.vectorise_from = 0
    bonds.compute(model, state, DT)
    loaded = np.flatnonzero(state.bond_active & (np.abs(bonds.force_i).sum(axis=1) > 0))
    chosen = loaded[::7]
    assert chosen.size >= 10
    state.bond_active[chosen] = False
    bonds.compute(model, state, DT)
    for loads in (bonds.force_i, bonds.moment_i, bonds.moment_j):
        assert not np.any(loads[chosen])
    force = np.zeros((model.n_particles, 3))
    moment = np.zeros_like(force)
    bonds.gather(force, moment, assign=True)
    # each particle's sum is that of its intact bonds alone
    expected = np.zeros_like(force)
    for b in np.flatnonzero(state.bond_active):
        i, j = model.bond_pairs[b]
        expected[i] += bonds.force_i[b]
        expected[j] -= bonds.force_i[b]
    np.testing.assert_allclose(force, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    state.bond_active[chosen] = True
    bonds.compute(model, state, DT)
    held = chosen[state.bond_active[chosen]]   # (some break again at once: this spin)
    assert held.size >= 5 and np.all(np.abs(bonds.force_i[held]).sum(axis=1) > 0)


def test_the_blocks_exact_break_test_is_the_break_mode_of_the_scalar_path():
    """``bond_breaks`` (the block's test) says "breaks" exactly where ``bond_break_mode``
    gives a mode: random loads around the strengths, in tension and compression, with and
    without compressive breakage, under each criterion."""
    rng = np.random.default_rng(3)
    diameter, strength = 1e-3, 1e6
    area = np.pi * (0.5 * diameter) ** 2
    seen = {True: 0, False: 0}
    for _ in range(3000):
        # each load up to ~1.5x what alone would reach the strength
        f_n = tuple(rng.normal(0.0, 0.6 * strength * area, 3))
        f_t = tuple(rng.normal(0.0, 0.6 * strength * area, 3))
        m_n = tuple(rng.normal(0.0, 0.6 * strength * area * diameter / 4, 3))
        m_t = tuple(rng.normal(0.0, 0.6 * strength * area * diameter / 8, 3))
        length = 1e-3 * (1.0 + rng.choice([-1.0, 1.0]) * 1e-3)
        criterion = int(rng.choice(list(CRITERION_CODES.values())))
        compressive = bool(rng.random() < 0.5)
        args = (length, 1e-3, f_n, f_t, m_n, m_t, diameter, strength, 0.8 * strength,
                criterion, compressive)
        breaks = bool(bond_breaks(*args))
        assert breaks == (bond_break_mode(*args) != INTACT), args
        seen[breaks] += 1
    assert min(seen.values()) > 300


def bond_sums(model, state, bonds):
    """Each particle's force and moment from its intact bonds' loads, summed in numpy."""
    force = np.zeros((model.n_particles, 3))
    moment = np.zeros_like(force)
    for b in np.flatnonzero(state.bond_active):
        i, j = model.bond_pairs[b]
        force[i] += bonds.force_i[b]
        force[j] -= bonds.force_i[b]
        moment[i] += bonds.moment_i[b]
        moment[j] += bonds.moment_j[b]
    return force, moment


def test_the_gather_sums_the_intact_bonds_after_breaks_and_repairs():
    """The gather leaves out bonds broken since its index was made (a twentieth of them,
    here two fifths); bonds set intact again between steps are summed again."""
    model, state = random_cluster(9, n_particles=300)
    state.angular_velocity *= 1e-3     # few breaks of its own: the repairs add bonds
    rng = np.random.default_rng(4)
    bonds = cpu.ElasticBonds(model)
    bonds.vectorise_from = 0
    broken = rng.random(model.n_bonds) < 0.4
    state.bond_active[broken] = False
    repaired = np.flatnonzero(broken)[::3]
    assert broken.sum() >= 64 and repaired.size >= 20
    for step in range(3):
        if step == 2:
            state.bond_active[repaired] = True
        bonds.compute(model, state, DT)
        force = np.zeros((model.n_particles, 3))
        moment = np.zeros_like(force)
        bonds.gather(force, moment, assign=True)
        expected_force, expected_moment = bond_sums(model, state, bonds)
        scale = np.abs(expected_force).max()
        np.testing.assert_allclose(force, expected_force, rtol=1e-12, atol=1e-12 * scale)
        np.testing.assert_allclose(moment, expected_moment, rtol=1e-12,
                                   atol=1e-12 * np.abs(expected_moment).max())
    held = repaired[state.bond_active[repaired]]
    assert held.size >= 10 and np.all(np.abs(bonds.force_i[held]).sum(axis=1) > 0)


def test_prefetch_emits_llvms_prefetch_and_changes_nothing():
    """The bond kernel's prefetch is a hint: LLVM's llvm.prefetch on the row's address,
    with every value read and written as without it."""
    prefetch = cpu.prefetch

    @numba.njit
    def sum_ahead(a, rows, ahead):
        total = 0.0
        for k in range(rows.shape[0]):
            if k + ahead < rows.shape[0]:
                prefetch(a, rows[k + ahead])
            total += a[rows[k], 1]
        return total

    rng = np.random.default_rng(3)
    a = rng.random((500, 3))
    rows = rng.integers(0, 500, 200)
    before = a.copy()
    expected = 0.0
    for r in rows:
        expected += a[r, 1]
    assert sum_ahead(a, rows, 4) == expected
    assert np.array_equal(a, before)
    ir = sum_ahead.inspect_llvm(sum_ahead.signatures[0])
    assert "@llvm.prefetch" in ir

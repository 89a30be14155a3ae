"""Neighbour search and contact bookkeeping.

- The Verlet list equals the brute-force set (scipy cKDTree, all pairs within the
  cut-off, filtered by r_i + r_j + skin) on random polydisperse packings: open, periodic in
  all axes, periodic in some, a periodic box only 2 cells wide, and a sparse cloud.
- During a run of a dense periodic gas the touching pairs found by the law equal the
  brute-force overlapping pairs at every checked step (the skin/2 rebuild rule is safe),
  and total linear momentum is conserved to round-off (forces equal and opposite).
- Bonded pairs get no contact force by default; they do with bonded_pairs=True.
- Energy: kinetic + contact stored + dissipated is conserved (1e-3).
- A run resumed from a copy of the state reproduces the uninterrupted run bit for bit.
"""
import numpy as np
import pytest
from scipy.spatial import cKDTree

import bondem
from bondem.contacts import ContactSettings
from bondem.neighbors import build_pairs, carry_history, max_displacement
from bondem.status import SimulationBlowUp


def brute_pairs(position, radius, skin, periodic, low, high):
    shifted = position - low
    size = np.where(periodic, high - low, 1e6 * (np.ptp(position) + 1.0))
    shifted = np.where(periodic, np.mod(shifted, size), shifted + 1e5 * (np.ptp(position) + 1))
    tree = cKDTree(shifted, boxsize=size)
    candidates = tree.query_pairs(2 * radius.max() + skin, output_type="ndarray")
    d = shifted[candidates[:, 1]] - shifted[candidates[:, 0]]
    d -= np.where(periodic, size * np.round(d / size), 0.0)
    keep = np.linalg.norm(d, axis=1) < radius[candidates[:, 0]] + radius[candidates[:, 1]] + skin
    found = np.sort(candidates[keep], axis=1)
    return set(map(tuple, found.tolist()))


@pytest.mark.parametrize("periodic, n, box", [
    ((False, False, False), 3000, 0.03), ((True, True, True), 3000, 0.03),
    ((True, False, True), 2000, 0.025), ((True, True, True), 30, 0.005),
    ((False, False, False), 40, 1.0)])
def test_verlet_list_equals_brute_force(periodic, n, box):
    rng = np.random.default_rng(n)
    periodic = np.array(periodic)
    low, high = np.zeros(3), np.full(3, box)
    position = rng.uniform(0, box, (n, 3))
    position[:, 0] += np.where(periodic[0], box * rng.integers(-1, 2, n), 0.0)  # outside images
    if box > 0.5:  # sparse cloud: pairs only where a particle got a close partner
        position[1::2] = position[0::2] + rng.uniform(-1.2e-3, 1.2e-3, position[1::2].shape)
    radius = rng.uniform(0.5e-3, 1e-3, n)
    skin = 2e-4
    pairs = build_pairs(position, radius, skin, periodic, low, high)
    assert np.all(pairs[:, 0] < pairs[:, 1])
    key = pairs[:, 0] * n + pairs[:, 1]
    assert np.all(np.diff(key) > 0)  # sorted, no duplicates
    assert set(map(tuple, pairs.tolist())) == brute_pairs(position, radius, skin, periodic,
                                                          low, high)
    assert len(pairs) > (3 if n < 100 else 100)
    # one pass into rows of a given room, with the two passes as fallback when a row is
    # longer (room 1): the same list
    for room in (1, 64):
        np.testing.assert_array_equal(
            build_pairs(position, radius, skin, periodic, low, high, row_room=room), pairs)


@pytest.mark.parametrize("n", [50, 70000])       # serial, and in parallel blocks
@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("periodic", [False, True])
def test_max_displacement_is_the_largest_move(n, axis, periodic):
    """Every particle moved a little (< 1 um); one moved 3 um along one axis, across the
    box's edge if that axis is periodic (its minimum image is 3 um, not the box less
    3 um): the largest displacement is 3 um."""
    rng = np.random.default_rng(axis + 3 * n)
    length = np.array([0.02, 0.03, 0.05])
    reference = rng.uniform(0.0, 1.0, (n, 3)) * length
    position = reference + rng.uniform(-0.57e-6, 0.57e-6, (n, 3))
    mover = n // 3
    reference[mover, axis] = length[axis] - 1e-6 if periodic else 0.5 * length[axis]
    position[mover] = reference[mover]
    position[mover, axis] += 3e-6
    if periodic:
        position[mover, axis] -= length[axis]      # wrapped into the box
    flags = np.zeros(3, dtype=bool)
    flags[axis] = periodic
    assert max_displacement(position, reference, length, flags) == pytest.approx(3e-6,
                                                                                 rel=1e-6)


def test_history_follows_pairs_across_rebuilds():
    old = np.array([[0, 1], [0, 5], [2, 3], [4, 7]])
    values = np.arange(12.0).reshape(4, 3)
    new = np.array([[0, 5], [1, 2], [4, 7], [6, 7]])
    carried = carry_history(old, values, new, 8)
    assert np.array_equal(carried, [[3, 4, 5], [0, 0, 0], [9, 10, 11], [0, 0, 0]])


def test_history_of_scalar_rows_and_duplicated_keys():
    # energies are (M,) arrays; a key listed twice in the old list (a bond given twice)
    # maps to its first row, as a search for the leftmost match does
    old = np.array([[0, 1], [2, 3], [2, 3], [4, 7]])
    new = np.array([[0, 1], [2, 3], [3, 4], [4, 7]])
    carried = carry_history(old, np.array([1.0, 2.0, 3.0, 4.0]), new, 8)
    assert np.array_equal(carried, [1.0, 2.0, 0.0, 4.0])


@pytest.mark.parametrize("musen", [False, True])
def test_carried_rows_and_flags_equal_a_row_by_row_carry(musen):
    """A rebuild carries the pair history arrays without reading or writing the rows that
    hold nothing (``carry_pair_rows``): every array must equal ``carry_history``'s, and the
    flags must equal ``quiet_rows`` of the carried rows, with the old flags given (kept by
    the pair kernel, which also flags a row whose dissipation is not 0) or not."""
    from bondem.backends import cpu_contacts
    from bondem.contacts import MUSEN_PAIR_HISTORY, PAIR_HISTORY
    rng = np.random.default_rng(3)
    n, m = 40, 300
    keys = np.sort(rng.choice(n * n, size=2 * m, replace=False))
    every = np.column_stack([keys // n, keys % n])
    old_pairs, new_pairs = every[rng.random(2 * m) < 0.6], every[rng.random(2 * m) < 0.6]
    names = {**PAIR_HISTORY, **(MUSEN_PAIR_HISTORY if musen else {})}
    k = old_pairs.shape[0]
    extra = {name: np.zeros((k,) + shape) for name, shape in names.items()}
    touching = rng.random(k) < 0.3
    for name in names:
        extra[name][touching] = rng.normal(size=(int(touching.sum()),) + names[name])
    # rows with only a spring (or MUSEN's stored force) left: quiet, yet carried
    only_spring = np.flatnonzero(~touching)[:6]
    extra["contact_spring"][only_spring[:3], 1] = 1e-9
    if musen:
        extra["contact_tangential"][only_spring[3:], 2] = -2.0
    dissipating = np.flatnonzero(~touching)[6:12]   # reset rows that booked dissipation
    dissipated = np.zeros(k)
    dissipated[dissipating] = 1e-12
    kept = cpu_contacts.quiet_rows(cpu_contacts.pair_rows(extra, dissipated))
    assert kept[only_spring].all() and not kept[dissipating].any()
    expected = {name: carry_history(old_pairs, extra[name], new_pairs, n) for name in names}
    flags = cpu_contacts.quiet_rows(cpu_contacts.pair_rows(expected, np.zeros(len(new_pairs))))
    for old_flags in (kept, None):
        carried, carried_flags = cpu_contacts.carry_pair_rows(old_pairs, extra, new_pairs, n,
                                                              names, old_flags)
        assert carried.keys() == expected.keys()
        for name in names:
            assert carried[name].tobytes() == expected[name].tobytes(), name
        np.testing.assert_array_equal(carried_flags, flags)
    assert 0 < flags.sum() < len(new_pairs)
    carried_spring = carried["contact_spring"][:, 1] == 1e-9
    assert carried_spring.any()     # the case holds a spring-only row listed again


@pytest.mark.parametrize("row", [0, 7, 19])
def test_a_nan_position_anywhere_stops_the_neighbour_grid(row):
    position = np.random.default_rng(1).uniform(0.0, 0.01, (20, 3))
    position[row, 1] = np.nan
    with pytest.raises(SimulationBlowUp):
        build_pairs(position, np.full(20, 1e-3), 1e-4, np.zeros(3, bool), np.zeros(3),
                    np.full(3, 0.01))


def gas(n_side=6, friction=0.3, rolling=0.05, seed=3):
    rng = np.random.default_rng(seed)
    material = bondem.Material(density=2500.0, young_modulus=1e7, poisson_ratio=0.3,
                               restitution=0.5, friction=friction, rolling_friction=rolling)
    spacing = 2.05e-3
    grid = np.stack(np.meshgrid(*[np.arange(n_side)] * 3, indexing="ij"), -1).reshape(-1, 3)
    position = (grid + 0.5) * spacing
    radius = rng.uniform(0.9e-3, 1.0e-3, len(grid))
    velocity = rng.normal(0.0, 0.5, grid.shape)
    return bondem.make_system(position, radius, material, velocity=velocity,
                              angular_velocity=rng.normal(0, 50.0, grid.shape),
                              periodic=(True, True, True), box_low=np.zeros(3),
                              box_high=np.full(3, n_side * spacing))


def test_periodic_gas_momentum_and_contacts():
    model, state = gas()
    sim = bondem.Simulation(model, state, contact=ContactSettings(skin=1e-4))
    momentum0 = model.mass @ state.velocity
    scale = model.mass @ np.abs(state.velocity).sum(1)
    checked = 0
    for _ in range(30):
        sim.step(20)
        touching = brute_pairs(state.position, model.radius, 0.0, model.periodic,
                               model.box_low, model.box_high)
        # The law saw the positions at the start of its last step; compare with those.
        assert sim.contacts.touching()[0] >= 0
        checked += len(touching)
    pairs = state.extra["contact_pairs"]
    listed = set(map(tuple, pairs.tolist()))
    assert touching <= listed  # every overlapping pair is in the current list
    assert checked > 50
    assert state.extra["contact_counters"][2] > 2  # the list was rebuilt during the run
    assert np.allclose(model.mass @ state.velocity, momentum0, rtol=0, atol=1e-12 * scale)
    assert sim.energy_terms()["dissipated_contacts"] > 0.0


@pytest.mark.parametrize("friction, rolling", [(0.0, 0.0), (0.5, 0.1)])
def test_periodic_gas_energy_balance(friction, rolling):
    """kinetic + stored in contacts + dissipated (damping, sliding, rolling) stays equal to
    the initial kinetic energy; the work balance per contact is second order, so 1e-3 of
    the initial energy at the default step, with most of it dissipated."""
    model, state = gas(n_side=5, seed=7, friction=friction, rolling=rolling)
    sim = bondem.Simulation(model, state, contact=ContactSettings(skin=1e-4))
    initial = sum(sim.kinetic_energy())
    sim.step(600)
    terms = sim.energy_terms()
    total = (terms["kinetic_translational"] + terms["kinetic_rotational"]
             + terms["contact_elastic"] + terms["dissipated_contacts"])
    assert total == pytest.approx(initial, rel=1e-3)
    assert terms["dissipated_contacts"] > 0.5 * initial


def test_touching_pairs_equal_brute_force_each_step():
    model, state = gas(n_side=5, seed=4)
    sim = bondem.Simulation(model, state, contact=ContactSettings(skin=1e-4))
    for _ in range(200):
        before = state.position.copy()
        sim.step(1)
        expected = brute_pairs(before, model.radius, 0.0, model.periodic, model.box_low,
                               model.box_high)
        assert sim.contacts.touching()[0] == len(expected)


def test_bonded_pairs_get_no_contact_force(glass, binder):
    position = [[0.0, 0.0, 0.0], [1.8e-3, 0.0, 0.0]]  # overlap 0.2 mm, bond at rest
    for bonded_pairs in (False, True):
        model, state = bondem.make_system(position, 1e-3, glass, bonds=[[0, 1]],
                                          bond_diameter=1e-3, bond_material=binder)
        sim = bondem.Simulation(model, state,
                                contact=ContactSettings(bonded_pairs=bonded_pairs))
        sim.step(20)
        assert (np.abs(state.velocity).max() > 1e-6) == bonded_pairs
        if not bonded_pairs:
            # Once the bond is broken the pair repels (the exclusion reads bond_active).
            state.bond_active[:] = False
            sim.step(20)
            assert state.velocity[0, 0] < -1e-6 and state.velocity[1, 0] > 1e-6


def test_resume_is_bit_identical():
    model, state = gas(n_side=5, seed=5)
    sim = bondem.Simulation(model, state, contact=ContactSettings(skin=1e-4))
    sim.step(150)
    saved = state.copy()
    sim.step(150)
    resumed = bondem.Simulation(model, saved, contact=ContactSettings(skin=1e-4))
    resumed.step(150)
    a, b = state.arrays(), saved.arrays()
    assert a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    assert state.extra["contact_counters"][2] >= 2


RUN_GAS = """
import sys, numpy as np
sys.path.insert(0, {tests!r})
import bondem
import bondem.backends.cpu as cpu
from bondem.contacts import ContactSettings
from test_contacts_neighbors import gas
cpu.SERIAL_BELOW = 0   # the parallel loops even for this small gas (else one thread)
model, state = gas(n_side=8, seed=7)
sim = bondem.Simulation(model, state, contact=ContactSettings(skin=1e-4))
sim.step(200)
np.savez({out!r}, **{{k.replace('/', '_'): v for k, v in state.arrays().items()}})
"""


def test_same_bits_with_one_and_two_threads(tmp_path):
    """Per-contact rows gathered through CSR: no atomics, so thread count changes nothing."""
    import os
    import pathlib
    import subprocess
    import sys
    tests = str(pathlib.Path(__file__).parent)
    results = []
    for threads in (1, 2):
        out = str(tmp_path / f"run{threads}.npz")
        env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
        subprocess.run([sys.executable, "-c", RUN_GAS.format(tests=tests, out=out)], env=env,
                       check=True, timeout=300)
        results.append(np.load(out))
    one, two = results
    assert one.files == two.files
    for name in one.files:
        assert np.array_equal(one[name], two[name]), name


def test_bonds_breaking_join_the_live_rows_as_a_full_derivation_puts_them():
    """The rows of bonds that break between steps are inserted into the live rows and the
    CSR indices (ContactLaw._add_broken) exactly where deriving everything again puts
    them, over several rounds of random breaks."""
    from bondem.backends.cpu_contacts import ContactLaw
    rng = np.random.default_rng(5)
    position = rng.uniform(0.0, 8e-3, (300, 3))
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3)
    pairs = build_pairs(position, np.full(300, 5e-4), 2e-4, np.zeros(3, bool),
                        np.full(3, -np.inf), np.full(3, np.inf))
    bonds = pairs[rng.random(len(pairs)) < 0.6]
    model, state = bondem.make_system(position, 5e-4, glass, bonds=bonds,
                                      bond_diameter=5e-4, bond_material=binder)
    law = ContactLaw(model, ContactSettings(skin=2e-4))
    law.accumulate(model, state, np.zeros((300, 3)), np.zeros((300, 3)), 1e-8)
    assert law._live.size < state.extra["contact_pairs"].shape[0]
    for _ in range(4):
        intact = np.flatnonzero(state.bond_active)
        state.bond_active[rng.choice(intact, size=max(1, intact.size // 5),
                                     replace=False)] = False
        law._derive(model, state)           # incremental
        got = [law._live.copy(), law._i_start.copy(), law._j_start.copy(),
               law._j_order.copy()]
        law._derive_live(model, state)      # everything again
        for a, b in zip(got, (law._live, law._i_start, law._j_start, law._j_order)):
            np.testing.assert_array_equal(a, b)


def test_quiet_rows_skipped_give_the_same_bits_as_visiting_every_row(monkeypatch):
    """Rows that hold nothing and stay apart are not visited, and a particle whose rows all
    hold nothing is not gathered (ContactLaw._quiet). A gas where pairs meet, part and
    meet again runs to the same bits as the same gas with every row visited and gathered
    each step, and rows do turn from quiet to touching on the way (a skip that missed such
    a row would change the bits)."""
    import bondem.backends.cpu_contacts as cc
    gather = cc.gather_pair_loads

    def gather_every_row(index, rows, force, moment, assign):
        gather(index._replace(quiet=np.zeros_like(index.quiet)), rows, force, moment, assign)

    runs = []
    woke = 0
    for skip in (True, False):
        model, state = gas(n_side=6, seed=11)
        sim = bondem.Simulation(model, state, contact=ContactSettings(skin=1e-4))
        law = sim.contacts
        pair_loads = law.pair_loads

        def every_row(*arguments, law=law, pair_loads=pair_loads, **keywords):
            law._quiet[:] = 0
            pair_loads(*arguments, **keywords)
        with monkeypatch.context() as patch:
            if not skip:
                law.pair_loads = every_row
                patch.setattr(cc, "gather_pair_loads", gather_every_row)
            for _ in range(300):
                quiet = law._quiet.copy() if skip and hasattr(law, "_quiet") else None
                sim.step(1)
                if quiet is not None and quiet.shape == law._quiet.shape:
                    loaded = np.any(state.extra["contact_force"] != 0.0, axis=1)
                    woke += int(np.count_nonzero(quiet.astype(bool) & loaded))
        runs.append(state)
    assert woke > 10
    a, b = runs
    for name in ("position", "velocity", "angular_velocity"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    for name, value in a.extra.items():
        np.testing.assert_array_equal(value, b.extra[name], err_msg=name)


class _Adding:
    """A contact law seen without its ``assign``: the step then zeroes the loads and the
    law adds to them (the reference for the law that stores them)."""

    def __init__(self, law):
        self.law = law

    def accumulate(self, *arguments):
        self.law.accumulate(*arguments)


@pytest.mark.parametrize("model_name, spread", [("hertz_mindlin", 1.0), ("none", 1.0),
                                                 ("hertz_mindlin", 3.0)])
def test_contacts_that_store_their_loads_give_the_bits_of_adding_them_to_zeros(
        model_name, spread):
    """Without bonds the contact law comes first and stores the loads (``assign``): every
    particle's, those without a loaded row too (they get +0), whatever the arrays held.
    A bed (most particles touching), a bed without pair contacts (walls only) and the
    same bed spread out (no pair listed: zeros stored) give the bits of the law adding its
    loads to zeroed arrays, step by step and in the loads themselves."""
    from bondem import bench
    from bondem.integrate import step
    model, state, walls = bench.bed_system(500)
    state.position *= spread
    runs = []
    for storing in (True, False):
        sim = bondem.Simulation(model, state.copy(), contact=ContactSettings(model_name),
                                walls=walls)
        laws = sim.laws if storing else [sim.laws[0], _Adding(sim.laws[1])]
        assert not laws[0].acts(model)       # no bonds: the bond law is left out
        for _ in range(30):
            step(model, sim.state, laws, sim.integrator, sim.force, sim.moment,
                 sim.time_step)
        runs.append(sim)
    a, b = runs
    assert np.any(a.force != 0.0) == (spread == 1.0)
    for name in ("position", "velocity", "angular_velocity"):
        np.testing.assert_array_equal(getattr(a.state, name), getattr(b.state, name))
    # the loads of one more evaluation, stored over NaN against added to zeros
    stored = (np.full_like(a.force, np.nan), np.full_like(a.moment, np.nan))
    added = (np.zeros_like(b.force), np.zeros_like(b.moment))
    a.contacts.assign(model, a.state, *stored, a.time_step)
    b.contacts.accumulate(model, b.state, *added, b.time_step)
    listed = a.state.extra["contact_pairs"].shape[0]
    assert (listed == 0) == (spread > 1.0 or model_name == "none")
    if model_name == "hertz_mindlin" and spread == 1.0:
        unloaded = ~np.any(added[0] != 0.0, axis=1)
        assert np.any(unloaded) and np.any(~unloaded)
    for mine, reference in zip(stored, added):
        np.testing.assert_array_equal(mine.view(np.int64), reference.view(np.int64))


def test_balanced_shares_cut_contiguous_runs_of_even_work():
    """cpu.balanced_shares: contiguous runs covering every chunk once, each within one
    chunk's work of an equal share; a bed-like skew (the first half of the chunks 13x
    costlier) is split by work, not by length."""
    from bondem.backends.cpu import balanced_shares
    rng = np.random.default_rng(2)
    skewed = np.r_[np.full(500, 13.0), np.ones(500)]
    for work in (np.ones(10), rng.exponential(1.0, 1000), skewed, np.zeros(7), np.ones(1),
                 np.zeros(0)):
        for parts in (1, 2, 3, 8):
            bounds = balanced_shares(work, parts)
            assert bounds.shape == (parts + 1,)
            assert bounds[0] == 0 and bounds[-1] == work.shape[0]
            assert np.all(np.diff(bounds) >= 0)
            if work.size:
                shares = [work[a:b].sum() for a, b in zip(bounds[:-1], bounds[1:])]
                assert max(shares) <= work.sum() / parts + work.max() + 1e-9
    np.testing.assert_array_equal(balanced_shares(np.zeros(9), 3), [0, 3, 6, 9])
    bounds = balanced_shares(skewed, 2)
    assert skewed[:bounds[1]].sum() == pytest.approx(0.5 * skewed.sum(), rel=0.01)
    assert 260 <= bounds[1] <= 280       # 500 chunks by length would give 6500 : 500


def test_contact_kernel_gives_the_same_bits_however_its_chunks_are_shared():
    """The pair kernel shares its chunks of rows out by the work they took last time
    (particle_contacts' ``work``); any sharing, over any number of parts, gives the same
    rows to the bit, and the kernel records each chunk's work for the next step."""
    from bondem import bench
    from bondem.backends import cpu, cpu_contacts as cc
    model, state, walls = bench.bed_system(3000)
    sim, _ = bench.scene_simulation(model, state, walls)
    sim.step(20)
    law = sim.contacts
    extra = state.extra
    names = ("contact_spring", "contact_force", "contact_moment_i", "contact_moment_j",
             "contact_energy")
    before = {name: extra[name].copy() for name in names}
    quiet = law._quiet.copy()
    m = cpu.chunks(law._live.shape[0])
    assert m >= 8
    rng = np.random.default_rng(4)
    layouts = ((1, np.ones(m)), (2, np.ones(m)), (2, np.r_[np.full(m - 1, 0.0), 1e6]),
               (3, rng.exponential(1.0, m)), (7, np.zeros(m)))
    results = []
    for threads, work in layouts:
        for name in names:
            extra[name][...] = before[name]
        law._quiet[:] = quiet
        dissipated = np.zeros(extra["contact_pairs"].shape[0])
        cc.particle_contacts(
            law._live, law._quiet, extra["contact_pairs"], law._pair_bond, state.bond_active,
            cpu.particles(state), law.grains(model), law._materials, law._law,
            law.reach()[0], False, cpu.box(model),
            cc.pair_rows(extra, dissipated), sim.time_step, sim.time_step, None, work,
            threads)
        evaluated = (work - np.diff(np.minimum(np.arange(m + 1) * cpu.CHUNK,
                                               law._live.shape[0]))) / cc.EVALUATED_ROW_WORK
        np.testing.assert_array_equal(evaluated, np.round(evaluated))
        assert evaluated.sum() >= np.count_nonzero(quiet[law._live] == 0) > 0
        results.append([extra[name].copy() for name in names] + [law._quiet.copy(),
                                                                 dissipated])
    for other in results[1:]:
        for a, b in zip(results[0], other):
            np.testing.assert_array_equal(a, b)
    assert not np.array_equal(results[0][1], before["contact_force"])


def test_relative_spread_is_the_box_of_each_cell_and_its_neighbours():
    """neighbors.relative_spread is, by its definition, the largest diagonal of the box
    holding the displacements of an occupied cell and its 26 neighbours (brute force over
    the cells here), so it bounds |d_i - d_j| for every two particles of neighbouring
    cells; on a grid of unequal sides, with empty cells."""
    from bondem.neighbors import reference_cells, relative_spread
    rng = np.random.default_rng(8)
    reference = rng.uniform((0.0, 0.0, 0.0), (9.5, 6.2, 4.1), (300, 3))
    displacement = rng.normal(0.0, 0.05, reference.shape)
    displacement[rng.random(300) < 0.1] *= 7.0
    counts, cell = reference_cells(reference, 1.0, 10**6)
    assert len(set(counts.tolist())) == 3 and np.unique(cell).size < counts.prod()
    got = relative_spread(reference + displacement, reference, cell, counts,
                          np.empty(12 * counts.prod()))
    where = np.stack(np.unravel_index(cell, counts), axis=1)
    moved = (reference + displacement) - reference
    worst = 0.0
    pair_worst = 0.0
    for c in np.unique(cell):
        near = np.all(np.abs(where - where[cell == c][0]) <= 1, axis=1)
        box = moved[near].max(axis=0) - moved[near].min(axis=0)
        worst = max(worst, float(np.sqrt(box[0] ** 2 + box[1] ** 2 + box[2] ** 2)))
        own = moved[cell == c]
        pair_worst = max(pair_worst, float(np.linalg.norm(
            own[:, None, :] - moved[near][None, :, :], axis=2).max()))
    assert got == pytest.approx(worst, rel=1e-15, abs=0.0)
    assert got >= pair_worst > 0.0


def test_relative_trigger_rebuilds_less_for_the_same_bits():
    """The relative trigger (ContactLaw.relative_trigger) keeps a list past skin/2 while
    neighbours have not moved a skin relative to each other: an agglomerate hitting a
    plane (contacts forming inside it and with the plane, bonds breaking) runs to the same
    bits as with a rebuild whenever a particle has moved skin/2, with fewer rebuilds. A
    trigger that let a pair come into reach unlisted would change the bits."""
    from bondem import bench
    model, state, walls = bench.impact_system(1500)
    runs = []
    for relative in (False, True):
        sim = bondem.Simulation(model, state.copy(), contact=ContactSettings(),
                                walls=walls)
        sim.contacts.relative_trigger = relative
        sim.step(400)
        runs.append(sim.state)
    plain, relative = runs
    print("rebuilds", plain.extra["contact_counters"][2], relative.extra["contact_counters"][2],
          "broken", np.count_nonzero(~relative.bond_active), "touching",
          np.count_nonzero(np.any(relative.extra["contact_force"] != 0.0, axis=1)))
    assert relative.extra["contact_counters"][2] < plain.extra["contact_counters"][2]
    assert np.count_nonzero(~relative.bond_active) > 10
    assert np.count_nonzero(np.any(relative.extra["contact_force"] != 0.0, axis=1)) > 100
    for name in ("position", "velocity", "angular_velocity", "bond_active"):
        np.testing.assert_array_equal(getattr(plain, name), getattr(relative, name))


@pytest.mark.parametrize("shift, expected", [
    ((0.9, 0.9, 0.9), False),      # all move together 0.9 skin: no gap closed
    ((0.0, 0.9, -0.9), True),      # A and B close 1.8 skin of their 1.5 skin gap
    ((0.0, 0.45, -0.45), False),   # they close 0.9 skin: still apart
    ((0.0, 0.55, -0.55), True),    # just past skin/2 each, they close 1.1 skin
    ((1.05, 1.05, 1.05), True),    # a whole skin moved: the walls' list may not hold
])
def test_relative_trigger_rebuilds_before_an_unlisted_pair_can_touch(shift, expected):
    """Three spheres on a line: P at 0, A just below 2 r, B 2 r + 1.5 skin beyond A (an
    unlisted pair). The trigger must rebuild when A and B close more than their gap's
    excess over the listed margin, also when they sit two cells apart in a grid of the
    bare cut-off (the cells must be 2 skin wider), and not when all move together."""
    from bondem.backends.cpu_contacts import ContactLaw
    r, skin = 1e-3, 2e-4
    a = 2 * r - 0.2 * skin
    position = np.array([[0.0, 0.0, 0.0], [a, 0.0, 0.0], [a + 2 * r + 1.5 * skin, 0.0, 0.0]])
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    model, state = bondem.make_system(position, r, glass)
    law = ContactLaw(model, ContactSettings(skin=skin))
    law.update_lists(model, state, 1e-8)
    assert law.skin == skin
    assert [0, 1] in state.extra["contact_pairs"].tolist()
    assert [1, 2] not in state.extra["contact_pairs"].tolist()
    state.position[:, 0] += np.array(shift) * skin
    assert law._needs_rebuild(model, state) is expected


def test_particles_of_cells_that_are_not_neighbours_lie_a_cell_size_apart():
    """What the relative trigger rests on (neighbors.reference_cells): two particles whose
    cells are not neighbours were at least the asked cell size apart, on an elongated
    cloud where the grid has cells of unequal counts per axis."""
    from bondem.neighbors import reference_cells
    rng = np.random.default_rng(21)
    reference = rng.uniform((-2.0, 0.5, 3.0), (7.5, 3.9, 5.2), (400, 3))
    size = 0.7
    counts, cell = reference_cells(reference, size, 10**6)
    where = np.stack(np.unravel_index(cell, counts), axis=1)
    apart = np.any(np.abs(where[:, None, :] - where[None, :, :]) > 1, axis=2)
    distance = np.linalg.norm(reference[:, None, :] - reference[None, :, :], axis=2)
    assert apart.sum() > 1000 and (~apart).sum() > 1000
    assert distance[apart].min() >= size

"""Fragments on constructed graphs with known answers, checked also against a brute-force
flood fill (tests' naive reference), and the breakage statistics of constructed files."""
import h5py
import numpy as np
import pytest

from bondem.analysis import (Results, broken_bond_fraction, broken_series,
                             count_distribution, fragment_labels, fragment_series,
                             fragment_sizes, largest_fragment_fraction, radial_breakage,
                             size_distribution, write_fragment_ids)

from resultsfile import write_static


def flood_fill(pairs, active, n):
    """Naive reference: label components by repeated relaxation to the smallest index."""
    label = np.arange(n)
    edges = [tuple(p) for p, a in zip(np.asarray(pairs).reshape(-1, 2), active) if a]
    changed = True
    while changed:
        changed = False
        for i, j in edges:
            low = min(label[i], label[j])
            if label[i] != low or label[j] != low:
                label[i] = label[j] = low
                changed = True
    return label


def same_partition(a, b):
    """Two labelings describe the same partition of the particles."""
    pairs_a = a[:, None] == a[None, :]
    pairs_b = b[:, None] == b[None, :]
    return np.array_equal(pairs_a, pairs_b)


def test_chain_breaks_into_pieces_at_each_broken_link():
    n = 10
    pairs = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    active = np.ones(n - 1, bool)
    assert fragment_labels(pairs, active, n)[0] == 1
    active[[2, 6]] = False          # pieces 0-2, 3-6, 7-9
    count, labels = fragment_labels(pairs, active, n)
    assert count == 3
    assert np.array_equal(labels, [1, 1, 1, 0, 0, 0, 0, 2, 2, 2])  # largest first
    counts, masses = fragment_sizes(labels, np.ones(n))
    assert counts.tolist() == [4, 3, 3] and masses.tolist() == [4.0, 3.0, 3.0]


def test_two_halves_isolated_particles_and_all_broken():
    # 2x2x4 grid, bonds between nearest neighbours; cutting the x = 1.5 plane gives halves.
    grid = np.stack(np.meshgrid(np.arange(4), np.arange(2), np.arange(2), indexing="ij"),
                    -1).reshape(-1, 3)
    d = np.linalg.norm(grid[:, None] - grid[None], axis=-1)
    pairs = np.column_stack(np.nonzero(np.triu(d == 1.0, 1)))
    cut = (grid[pairs[:, 0], 0] < 1.5) != (grid[pairs[:, 1], 0] < 1.5)
    count, labels = fragment_labels(pairs, ~cut, len(grid))
    assert count == 2 and np.array_equal(labels[grid[:, 0] < 1.5], labels[grid[:, 0] < 1.5][:1]
                                         .repeat(8))
    assert labels[0] != labels[-1]
    # heavier right half gets id 0
    mass = np.where(grid[:, 0] > 1.5, 2.0, 1.0)
    _, labels = fragment_labels(pairs, ~cut, len(grid), mass)
    assert np.all(labels[grid[:, 0] > 1.5] == 0)
    # isolate particle 5: all its bonds broken
    active = ~cut & ~np.any(pairs == 5, axis=1)
    count, labels = fragment_labels(pairs, active, len(grid))
    assert count == 3 and np.sum(labels == labels[5]) == 1
    # all broken: every particle alone; no bonds at all: the same
    assert fragment_labels(pairs, np.zeros(len(pairs), bool), len(grid))[0] == len(grid)
    assert fragment_labels(np.zeros((0, 2), int), np.zeros(0, bool), 7)[0] == 7


def test_random_graphs_match_flood_fill():
    rng = np.random.default_rng(3)
    for _ in range(20):
        n = int(rng.integers(1, 40))
        pairs = rng.integers(0, n, size=(int(rng.integers(0, 60)), 2))
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        active = rng.random(len(pairs)) < 0.6
        count, labels = fragment_labels(pairs, active, n)
        reference = flood_fill(pairs, active, n)
        assert count == len(np.unique(reference))
        assert same_partition(labels, reference)


def test_bad_active_length_is_rejected():
    with pytest.raises(ValueError, match="one per bond"):
        fragment_labels([[0, 1]], [True, False], 2)


def test_size_distributions_by_mass_and_by_count():
    masses, fraction = size_distribution([3.0, 1.0, 6.0])
    assert masses.tolist() == [1.0, 3.0, 6.0]
    assert fraction == pytest.approx([0.1, 0.4, 1.0])
    sizes, number = count_distribution([5, 1, 1, 2, 1, 5])
    assert sizes.tolist() == [1, 2, 5] and number.tolist() == [3, 1, 2]


@pytest.fixture
def chain_file(tmp_path):
    """A 6-particle chain along x over 3 frames: intact; link 1-2 broken (tension);
    also link 4-5 broken (shear). Particle masses 1..6."""
    position = np.column_stack([np.arange(6.0), np.zeros(6), np.zeros(6)])
    pairs = np.column_stack([np.arange(5), np.arange(1, 6)])
    active = np.ones((3, 5), bool)
    active[1:, 1] = False
    active[2, 4] = False
    mode = np.array([0, 1, 0, 0, 3], np.int8)
    return write_static(tmp_path / "chain.h5", position, 0.5, pairs, active,
                        time=[0.0, 1e-3, 2e-3], mass=np.arange(1.0, 7.0), break_mode=mode)


def test_file_series_on_a_chain(chain_file):
    with Results(chain_file) as results:
        fragments = fragment_series(results)
        broken = broken_series(results)
        radial = radial_breakage(results, bins=2)
    assert fragments["fragments"].tolist() == [1, 2, 3]
    assert fragments["fragments_multi"].tolist() == [1, 2, 2]
    # masses 1..6 sum to 21: frame 1 -> {1,2} and {3..6} = 18; frame 2 -> {3,4,5} = 12
    assert fragments["largest_fraction"] == pytest.approx([1.0, 18 / 21, 12 / 21])
    assert broken["broken"].tolist() == [0, 1, 2]
    assert broken["tension"].tolist() == [0, 1, 1] and broken["shear"].tolist() == [0, 0, 1]
    assert broken["compression"].tolist() == [0, 0, 0]
    assert broken["fraction"] == pytest.approx([0, 0.2, 0.4])
    assert largest_fragment_fraction(chain_file) == pytest.approx(12 / 21)
    assert largest_fragment_fraction(chain_file, frame=0) == 1.0
    assert broken_bond_fraction(chain_file) == pytest.approx(0.4)
    # centre of mass at x = sum (k+1) k / 21 = 70/21; outer radius = max |x - c| + 0.5
    centre = 70 / 21
    outer = centre + 0.5
    expected = np.abs(np.arange(5) + 0.5 - centre) / outer
    assert radial["radius"] == pytest.approx(expected)
    assert radial["all"].sum() == 5 and radial["broken_count"].sum() == 2
    assert radial["broken"].tolist() == [False, True, False, False, True]


def test_write_fragment_ids_into_closed_file(chain_file):
    written = write_fragment_ids(chain_file)
    assert written == chain_file
    with h5py.File(chain_file, "r") as f:
        ids = f["particles/fragment"][()]
    assert ids.shape == (3, 6)
    assert ids[0].tolist() == [0] * 6
    assert ids[1].tolist() == [1, 1, 0, 0, 0, 0]
    assert ids[2].tolist() == [2, 2, 0, 0, 0, 1]  # {5} (mass 6) outweighs {0, 1} (3)
    write_fragment_ids(chain_file)  # again: replaces, does not fail


def test_series_over_many_frames_match_frame_by_frame(tmp_path):
    # 150 frames (more than one read block of 64); bonds break at random frames
    rng = np.random.default_rng(7)
    n, n_frames = 30, 150
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)
                      if rng.random() < 0.15])
    break_frame = rng.integers(1, 2 * n_frames, len(pairs))
    active = np.arange(n_frames)[:, None] < break_frame[None, :]
    mode = rng.integers(1, 4, len(pairs)).astype(np.int8)
    mass = rng.uniform(1, 2, n)
    path = write_static(tmp_path / "many.h5", rng.normal(size=(n, 3)), 0.1, pairs, active,
                        mass=mass, break_mode=mode)
    with Results(path) as results:
        fragments = fragment_series(results)
        broken = broken_series(results)
    for f in (0, 63, 64, 65, 149):
        count, labels = fragment_labels(pairs, active[f], n)
        assert fragments["fragments"][f] == count
        masses = np.bincount(labels, weights=mass)
        assert fragments["largest_fraction"][f] == pytest.approx(masses.max() / mass.sum())
    for code, name in enumerate(("tension", "compression", "shear"), start=1):
        assert np.array_equal(broken[name], (~active & (mode == code)).sum(axis=1))
    assert np.array_equal(broken["broken"], (~active).sum(axis=1))

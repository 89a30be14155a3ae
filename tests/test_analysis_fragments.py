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


def _line_body(tmp_path, mode=(1, 0, 3)):
    """Four spheres (radius 0.5 mm) on a line off the origin, masses 1, 1, 1, 3: at t = 0
    the centre of mass is 6 mm along the line, the outer radius 6 + 0.5 mm (later frames
    move particle 3 away: the shells are those of t = 0). Bonds (0,1), (1,2), (2,3) have
    their centres 5, 3 and 1 mm from it: relative radii 10/13, 6/13, 2/13. Bonds 0 and 2
    break between the frames at 1e-4 and 2e-4 s (tension at 1.1e-4 s, shear at 1.5e-4 s),
    bond 1 never."""
    offset = np.array([5e-3, -3e-3, 2e-3])
    x = np.array([0.0, 2e-3, 4e-3, 10e-3])
    position = np.repeat((offset + x[:, None] * np.array([1.0, 0.0, 0.0]))[None], 3, axis=0)
    position[1:, 3, 0] += np.array([2e-3, 6e-3])
    active = np.array([[1, 1, 1], [1, 1, 1], [0, 1, 0]], bool)
    path = write_static(tmp_path / "line.h5", position, 0.5e-3, [[0, 1], [1, 2], [2, 3]],
                        active, time=np.array([0.0, 1e-4, 2e-4]), mass=[1.0, 1.0, 1.0, 3.0],
                        break_mode=None if mode is None else list(mode))
    with h5py.File(path, "a") as f:
        f["bonds/break_time"] = [1.1e-4, np.nan, 1.5e-4]
    return path, offset


def test_radial_breakage_by_its_definition(tmp_path):
    path, offset = _line_body(tmp_path)
    with Results(path) as results:
        shells = radial_breakage(results)
        coarse = radial_breakage(results, frame=1, bins=4)
        halves = radial_breakage(results, bins=2)
    np.testing.assert_allclose(shells["centre"], offset + [6e-3, 0.0, 0.0], rtol=1e-12)
    assert shells["outer_radius"] == pytest.approx(6.5e-3, rel=1e-12)
    np.testing.assert_allclose(shells["radius"], [10 / 13, 6 / 13, 2 / 13], rtol=1e-12)
    assert shells["broken"].tolist() == [True, False, True]
    assert shells["mode"].tolist() == [1, 0, 3]
    np.testing.assert_allclose(shells["edges"], np.linspace(0.0, 1.0, 11))
    expected_all = np.zeros(10, int)
    expected_all[[7, 4, 1]] = 1
    assert shells["all"].tolist() == expected_all.tolist()
    expected_hit = np.zeros(10, int)
    expected_hit[[7, 1]] = 1
    assert shells["broken_count"].tolist() == expected_hit.tolist()
    fraction = shells["broken_fraction"]
    assert fraction[7] == 1.0 and fraction[1] == 1.0 and fraction[4] == 0.0
    assert np.isnan(np.delete(fraction, [1, 4, 7])).all()
    # frame 1: nothing broken yet; four shells of 0.25
    assert coarse["broken"].tolist() == [False, False, False]
    assert coarse["all"].tolist() == [1, 1, 0, 1] and coarse["broken_count"].tolist() == \
        [0, 0, 0, 0]
    np.testing.assert_allclose(coarse["edges"], [0.0, 0.25, 0.5, 0.75, 1.0])
    # two shells: the inner one holds two bonds, one broken
    assert halves["all"].tolist() == [2, 1]
    np.testing.assert_allclose(halves["broken_fraction"], [0.5, 1.0])


def test_breakage_without_recorded_modes_or_bonds(tmp_path):
    """A file without /bonds/break_mode: broken bonds count as 'unknown', the modes read
    0; a file without bonds: no fraction to speak of (0, not a division by zero)."""
    from bondem.analysis import broken_series
    path, _ = _line_body(tmp_path, mode=None)
    with Results(path) as results:
        series = broken_series(results)
        shells = radial_breakage(results)
    assert series["unknown"].tolist() == [0, 0, 2] and series["tension"].tolist() == [0, 0, 0]
    assert series["broken"].dtype.kind == "i" and series["broken"].tolist() == [0, 0, 2]
    np.testing.assert_allclose(series["fraction"], [0.0, 0.0, 2 / 3])
    np.testing.assert_allclose(series["time"], [0.0, 1e-4, 2e-4])
    assert shells["mode"].dtype == np.int8 and shells["mode"].tolist() == [0, 0, 0]
    assert broken_bond_fraction(path) == pytest.approx(2 / 3)
    none = write_static(tmp_path / "none.h5", [[0, 0, 0], [3e-3, 0, 0]], 0.5e-3,
                        np.zeros((0, 2)), np.ones((2, 0), bool), time=np.array([0.0, 1e-4]))
    with Results(none) as results:
        series = broken_series(results)
    assert series["fraction"].tolist() == [0.0, 0.0]
    assert broken_bond_fraction(none) == 0.0
    one = write_static(tmp_path / "one.h5", [[0, 0, 0], [1e-3, 0, 0]], 0.5e-3, [[0, 1]],
                       np.array([[True], [False]]))
    assert broken_bond_fraction(one) == 1.0


def test_the_first_break_time_is_the_earliest_recorded_among_the_broken(tmp_path):
    """From /bonds/break_time where recorded (1.1e-4 s, not the frame at 2e-4 s where it
    is first seen), among the bonds broken by the last frame; else the first frame with a
    broken bond; None when none broke."""
    from bondem.analysis.breakage import first_break_time
    path, _ = _line_body(tmp_path)
    with Results(path) as results:
        assert first_break_time(results) == 1.1e-4
    with h5py.File(path, "a") as f:
        f["bonds/break_time"][...] = [1.1e-4, 0.5e-4, 1.5e-4]   # bond 1: not broken at the end
    with Results(path) as results:
        assert first_break_time(results) == 1.1e-4
    with h5py.File(path, "a") as f:
        del f["bonds/break_time"]
    with Results(path) as results:
        assert first_break_time(results) == 2e-4
    with h5py.File(path, "a") as f:
        f["bonds/break_time"] = [np.nan, np.nan, np.nan]      # recorded, but not these
    with Results(path) as results:
        assert first_break_time(results) == 2e-4
    intact = write_static(tmp_path / "intact.h5", [[0, 0, 0], [1e-3, 0, 0]], 0.5e-3, [[0, 1]],
                          np.ones((3, 1), bool), time=np.array([0.0, 1e-4, 2e-4]))
    with Results(intact) as results:
        assert first_break_time(results) is None


def test_fragment_definitions_on_a_small_body_of_unequal_masses(tmp_path):
    """Five particles of masses 1, 1, 1, 1, 5: the pair {0,1} (2 kg, 2 particles) and the
    heavy single 4 (5 kg, 1 particle) and the pair {2,3} (2 kg): the heaviest fragment
    comes first whatever its particle count; of equal masses, more particles first; the
    largest fraction is by mass (5/9), the largest count that fragment's (1)."""
    pairs = [[0, 1], [2, 3], [1, 2]]
    active = [True, True, False]
    mass = np.array([1.0, 1.0, 1.0, 1.0, 5.0])
    count, labels = fragment_labels(pairs, active, 5, mass)
    assert count == 3 and labels.tolist() == [1, 1, 2, 2, 0]
    # by particle count without masses: the pairs first, the single last
    count, by_count = fragment_labels(pairs, active, 5)
    assert by_count.tolist() == [0, 0, 1, 1, 2]
    counts, masses = fragment_sizes(labels, mass)
    assert counts.tolist() == [1, 2, 2] and masses.tolist() == [5.0, 2.0, 2.0]
    # equal masses: the fragment of more particles comes first
    counts, masses = fragment_sizes([0, 0, 1], [1.0, 1.0, 2.0])
    assert counts.tolist() == [2, 1] and masses.tolist() == [2.0, 2.0]
    ascending, fraction = size_distribution([5.0, 2.0, 2.0], total_mass=18.0)
    assert ascending.tolist() == [2.0, 2.0, 5.0]
    np.testing.assert_allclose(fraction, [2 / 18, 4 / 18, 9 / 18])   # of a larger total
    with pytest.raises(ValueError, match="active: length 2, expected 3 "):
        fragment_labels(pairs, [True, False], 5)
    assert fragment_labels(np.zeros((0, 2)), [], 0)[0] == 0
    assert fragment_labels(np.zeros((0, 2)), [], 0)[1].shape == (0,)
    path = write_static(tmp_path / "five.h5", np.arange(15.0).reshape(5, 3), 0.5, pairs,
                        np.array([[True, True, True], active]), mass=mass,
                        time=np.array([0.0, 2.5e-4]))
    with Results(path) as results:
        series = fragment_series(results)
    np.testing.assert_allclose(series["time"], [0.0, 2.5e-4])
    assert series["fragments"].tolist() == [2, 3]
    assert series["largest_fraction"] == pytest.approx([5 / 9, 5 / 9])
    assert series["largest_count"].tolist() == [1, 1]
    assert series["fragments_multi"].tolist() == [1, 2]
    for key in ("fragments", "fragments_multi", "largest_count"):
        assert series[key].dtype == np.int64
    assert isinstance(series["largest_fraction"], np.ndarray)
    assert series["largest_fraction"].dtype == np.float64


def test_one_particle_no_particle_and_a_file_another_process_writes(tmp_path, monkeypatch):
    """A single particle is one fragment of itself; a frame's fragments carry their
    time, labels, counts and masses; a results file that cannot be opened for writing
    (another process holds it) gets its fragment ids in the sidecar <stem>.fragments.h5
    with the frames' times."""
    from bondem.analysis.fragments import frame_fragments
    count, labels = fragment_labels(np.zeros((0, 2)), [], 1)
    assert count == 1 and labels.tolist() == [0]
    path = write_static(tmp_path / "pair.h5", [[0, 0, 0], [1, 0, 0], [3, 0, 0]], 0.5,
                        [[0, 1]], np.array([[True], [False]]), mass=[1.0, 2.0, 4.0],
                        time=np.array([0.0, 3e-4]))
    with Results(path) as results:
        data = frame_fragments(results, 0)
    assert data["time"] == 0.0 and data["labels"].tolist() == [1, 1, 0]
    assert data["counts"].tolist() == [1, 2] and data["masses"].tolist() == [4.0, 3.0]
    assert data["total_mass"] == 7.0
    real_file = h5py.File

    def locked(name, mode="r", *args, **kwargs):
        if mode == "r+":
            raise OSError("unable to lock file (held by a writer)")
        return real_file(name, mode, *args, **kwargs)

    import bondem.analysis.fragments as fragments
    monkeypatch.setattr(fragments.h5py, "File", locked)
    written = write_fragment_ids(path)
    monkeypatch.undo()
    assert written == tmp_path / "pair.fragments.h5"
    with h5py.File(written, "r") as f:
        np.testing.assert_array_equal(f["time"][()], [0.0, 3e-4])
        assert f["particles/fragment"][()].tolist() == [[1, 1, 0], [2, 1, 0]]   # by mass
    with h5py.File(path, "r") as f:
        assert "particles/fragment" not in f


def test_fragment_ids_as_written_and_a_body_without_particles(tmp_path):
    """The ids ParaView reads: int32, one chunk per frame, compressed, described; a
    results file without particles has no fragments (0, not an error); a wrong bond
    count names what it expected."""
    path = write_static(tmp_path / "pair.h5", [[0, 0, 0], [1, 0, 0], [3, 0, 0]], 0.5,
                        [[0, 1]], np.array([[True], [False]]), mass=[1.0, 2.0, 4.0])
    write_fragment_ids(path)
    with h5py.File(path, "r") as f:
        ids = f["particles/fragment"]
        assert ids.dtype == np.int32 and ids.chunks == (1, 3)
        assert ids.compression == "gzip"
        assert ids.attrs["description"].startswith("fragment id per frame and particle")
    empty = write_static(tmp_path / "empty.h5", np.zeros((0, 3)), 0.5, np.zeros((0, 2)),
                         np.ones((2, 0), bool))
    with Results(empty) as results:
        series = fragment_series(results)
    assert series["fragments"].tolist() == [0, 0]
    assert series["largest_fraction"].tolist() == [0.0, 0.0]
    assert series["largest_count"].tolist() == [0, 0]
    with pytest.raises(ValueError, match=r"expected 1 \(one per bond\)"):
        fragment_labels([[0, 1]], [True, True], 2)
    # one particle, and none: their ids are written too (one chunk of one particle)
    single = write_static(tmp_path / "single.h5", [[0.0, 0.0, 0.0]], 0.5, np.zeros((0, 2)),
                          np.ones((2, 0), bool))
    write_fragment_ids(single)
    with h5py.File(single, "r") as f:
        assert f["particles/fragment"].chunks == (1, 1)
        assert f["particles/fragment"][()].tolist() == [[0], [0]]
    write_fragment_ids(empty)
    with h5py.File(empty, "r") as f:
        assert f["particles/fragment"].shape == (2, 0)

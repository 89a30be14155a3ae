"""Reading a results file (bondem.analysis.Results, SPEC 6) written by hand with h5py:
complete frames only when datasets differ in length (as while a run writes), negative
frame indices, the contacts of each frame from their running end, blocks of bond flags,
and the defaults of files without masses, clumps, break records, energy or contacts."""
from pathlib import Path

import h5py
import numpy as np
import pytest

from bondem.analysis import Results
from bondem.errors import InputError


def a_file(path, *, frames=5, bonds=True, extra=True):
    """Frames at t = 0.25 ms steps; /bonds/active has one frame fewer (being written);
    three particles, two bonds (one breaks at frame 2), two walls, contacts."""
    with h5py.File(path, "w") as f:
        f["time"] = 0.25e-3 * np.arange(frames)
        f["particles/radius"] = np.array([1e-3, 2e-3, 0.5e-3])
        f["particles/position"] = np.zeros((frames, 3, 3))
        f["bonds/pairs"] = np.array([[0, 1], [1, 2]] if bonds else np.zeros((0, 2)),
                                    dtype=np.int64)
        active = np.ones((frames - 1, 2 if bonds else 0), dtype=bool)
        if bonds:
            active[2:, 1] = False
        f["bonds/active"] = active
        f["walls/force"] = np.zeros((frames, 2, 3))
        if extra:
            f["particles/mass"] = np.array([1.0, 8.0, 0.125]) * 1e-6
            f["particles/clump"] = np.array([0, 0, -1], dtype=np.int32)
            f["bonds/break_mode"] = np.array([0, 3], dtype=np.int8)
            f["bonds/break_time"] = np.array([np.nan, 0.4e-3], dtype=np.float32)
            f["energy/kinetic_translational"] = np.arange(frames, dtype=np.float32)
            f["energy/work_walls"] = np.arange(frames + 1) * 2.0
            # contacts: 2 rows in frame 0, none in frame 1, 3 in frame 2, 1 in frame 3
            f["contacts/end"] = np.array([2, 2, 5, 6])
            f["contact_rows/i"] = np.array([0, 1, 0, 0, 2, 1])
            f["contact_rows/j"] = np.array([1, -1, 2, -2, 1, 0])
            f["contact_rows/force"] = np.arange(18, dtype=float).reshape(6, 3)
        f.attrs["bondem_version"] = "test"
    return path


def test_complete_frames_and_their_indices(tmp_path):
    path = a_file(tmp_path / "r.h5")
    with Results(path) as results:
        assert results.n_frames == 4    # /bonds/active lags /time by one frame
        np.testing.assert_array_equal(results.time, [0.0, 0.25e-3, 0.5e-3, 0.75e-3])
        assert results.frame_index(-1) == 3 and results.frame_index(-4) == 0
        assert results.frame_index(2) == 2
        for bad in (4, -5):
            with pytest.raises(IndexError) as error:
                results.frame_index(bad)
            assert str(error.value) == f"frame {bad} out of range: 4 complete frames"
        assert results.frames("particles/position").shape == (4, 3, 3)
        assert results.has("walls/force") and not results.has("walls/torque")
        assert results.n_walls == 2 and results.n_particles == 3 and results.n_bonds == 2
        assert results.attrs == {"bondem_version": "test"}
        assert repr(results) == (f"Results({str(path)!r}: 4 frames, t = 0 .. 0.00075 s, "
                                 "3 particles, 2 walls, 1 of 2 bonds intact at the end)")
    assert repr(results) == f"Results({str(path)!r}, closed)"
    # the last complete frame's bonds, not the one before
    with h5py.File(path, "a") as f:
        f["bonds/active"][3, 0] = False
    with Results(path) as results:
        assert repr(results).endswith("0 of 2 bonds intact at the end)")
    # one whose opening failed before it had a file
    half = Results.__new__(Results)
    half.path = Path("lost.h5")
    assert repr(half) == "Results('lost.h5', closed)"


def test_flags_stored_as_bytes_and_a_single_bond(tmp_path):
    # another writer's 0/1 bytes are flags: a broken bond is one whose byte is 0
    path = a_file(tmp_path / "r.h5", frames=4)
    with h5py.File(path, "a") as f:
        del f["bonds/pairs"], f["bonds/active"]
        f["bonds/pairs"] = np.array([[0, 2]])
        f["bonds/active"] = np.array([[1], [1], [0]], dtype=np.uint8)
    with Results(path) as results:
        assert results.n_bonds == 1
        active = results.active()
        assert active.dtype == bool and active.tolist() == [[True], [True], [False]]
        assert results.active(-1).dtype == bool and results.active(-1).tolist() == [False]
        (start, block), = results.iter_active()
        assert start == 0 and block.dtype == bool and block.tolist() == active.tolist()
        broken = results.any_broken()
        assert broken.dtype == bool and broken.tolist() == [False, False, True]


def test_energy_shorter_than_time_limits_the_frames(tmp_path):
    path = a_file(tmp_path / "r.h5", frames=6)
    with h5py.File(path, "a") as f:
        del f["energy/kinetic_translational"]
        f["energy/kinetic_translational"] = np.arange(3.0)
    with Results(path) as results:
        assert results.n_frames == 3
        energy = results.energy()
        assert sorted(energy) == ["kinetic_translational", "work_walls"]
        np.testing.assert_array_equal(energy["work_walls"], [0.0, 2.0, 4.0])
        assert energy["work_walls"].dtype == np.float64
    with Results(a_file(tmp_path / "single.h5")) as results:
        # a term stored in single precision is read in double
        assert results.energy()["kinetic_translational"].dtype == np.float64


def test_bond_flags_whole_by_frame_and_in_blocks(tmp_path):
    with Results(a_file(tmp_path / "r.h5", frames=7)) as results:
        active = results.active()
        assert active.shape == (6, 2) and active.dtype == bool
        np.testing.assert_array_equal(results.active(1), [True, True])
        np.testing.assert_array_equal(results.active(-1), [True, False])
        blocks = list(results.iter_active(block=4))
        assert [start for start, _ in blocks] == [0, 4]
        assert [b.shape for _, b in blocks] == [(4, 2), (2, 2)]
        np.testing.assert_array_equal(np.vstack([b for _, b in blocks]), active)
        np.testing.assert_array_equal(results.any_broken(),
                                      [False, False, True, True, True, True])
        np.testing.assert_array_equal(results.break_mode, [0, 3])
        assert results.break_mode.dtype == np.int8
        np.testing.assert_array_equal(results.break_time, [np.nan, np.float32(0.4e-3)])
        assert results.break_time.dtype == np.float64
        np.testing.assert_array_equal(results.mass, [1e-6, 8e-6, 0.125e-6])
        assert results.clump_of.tolist() == [0, 0, -1] and results.clump_of.dtype == np.int64
        assert results.pairs.dtype == np.int64 and results.pairs.shape == (2, 2)
        np.testing.assert_array_equal(results.radius, [1e-3, 2e-3, 0.5e-3])


def test_a_file_without_bonds_or_records(tmp_path):
    path = a_file(tmp_path / "r.h5", frames=3, bonds=False, extra=False)
    with Results(path) as results:
        assert results.n_bonds == 0 and results.n_frames == 2
        assert results.active().shape == (2, 0) and results.active(0).shape == (0,)
        assert results.active().dtype == bool and results.active(0).dtype == bool
        blocks = list(results.iter_active(block=1))
        assert [(s, b.shape) for s, b in blocks] == [(0, (1, 0)), (1, (1, 0))]
        assert not results.any_broken().any() and results.any_broken().shape == (2,)
        # masses from radii cubed (relative), no clumps, no break records, no energy
        np.testing.assert_allclose(results.mass, np.array([1.0, 8.0, 0.125]) * 1e-9)
        assert results.clump_of is None and results.break_mode is None
        assert results.break_time is None and results.energy() == {}
        contacts = results.contacts()
        assert {k: (v.shape, v.dtype) for k, v in contacts.items()} == {
            "i": ((0,), np.int64), "j": ((0,), np.int64), "force": ((0, 3), np.float64)}
        assert repr(results) == (f"Results({str(path)!r}: 2 frames, t = 0 .. 0.00025 s, "
                                 "3 particles, 2 walls)")


def test_the_contacts_of_each_frame(tmp_path):
    with Results(a_file(tmp_path / "r.h5")) as results:
        first = results.contacts(0)
        assert first["i"].tolist() == [0, 1] and first["j"].tolist() == [1, -1]
        np.testing.assert_array_equal(first["force"], [[0, 1, 2], [3, 4, 5]])
        assert results.contacts(1)["i"].size == 0
        third = results.contacts(2)
        assert third["i"].tolist() == [0, 0, 2] and third["j"].tolist() == [2, -2, 1]
        assert results.contacts()["i"].tolist() == [1]
        assert results.contacts(-1)["force"].tolist() == [[15.0, 16.0, 17.0]]


def test_a_file_that_is_not_a_results_file(tmp_path):
    with pytest.raises(InputError) as error:
        Results(tmp_path / "none.h5")
    assert error.value.reason == "no such results file"
    assert error.value.file == str(tmp_path / "none.h5")
    for missing in ("time", "particles/radius", "bonds/pairs"):
        path = a_file(tmp_path / f"{missing.replace('/', '_')}.h5")
        with h5py.File(path, "a") as f:
            del f[missing]
        with pytest.raises(InputError) as error:
            Results(path)
        assert error.value.key == missing and error.value.file == str(path)
        assert error.value.reason == f"missing dataset /{missing} (not a bondem results file?)"
        # the file was closed again: it can be opened for writing
        with h5py.File(path, "a") as f:
            f.attrs["touched"] = 1
    path = a_file(tmp_path / "empty.h5", frames=1)
    with Results(path) as results:
        assert results.n_frames == 0
        assert repr(results) == f"Results({str(path)!r}: 0 frames, 3 particles, 2 walls)"

"""Checkpoints (bondem.io.checkpoint): every array of a State and of its extras comes back
bit for bit with its dtype and shape, float scalars that JSON would round come back
exact, the file is replaced atomically, and a checkpoint of another format or of an
older State (an optional array missing) is read as the format says."""
import json
import os

import numpy as np
import pytest

import bondem
from bondem.io import checkpoint
from bondem.io.checkpoint import read_checkpoint, write_checkpoint
from bondem.model import make_system


def a_state():
    glass = bondem.Material(density=2500.0, young_modulus=1e8)
    bond = bondem.BondMaterial(young_modulus=1e8)
    rng = np.random.default_rng(7)
    _, state = make_system(rng.normal(size=(4, 3)), 1e-3, glass, velocity=rng.normal(
        size=(4, 3)), bonds=[[0, 1], [1, 2], [2, 3]], bond_diameter=5e-4, bond_material=bond)
    state.time = 0.1 + 0.2            # 0.30000000000000004: JSON keeps it, text may not
    state.step = 2 ** 40 + 3
    state.started = True
    state.work_external = 1.0 / 3.0
    state.dissipated_damping = np.nextafter(2.5e-7, 1.0)
    state.bond_break_time[1] = 1.5e-4
    state.bond_break_mode[1] = 2
    state.extra = {"contact_pairs": np.array([[0, 2], [1, 3]], dtype=np.int64),
                   "contact_force": rng.normal(size=(2, 3)).astype(np.float32),
                   "flags": np.array([True, False]),
                   "rebuilds": 17, "skin": 1e-5 / 3.0, "empty": np.zeros((0, 4))}
    return state


def test_a_state_comes_back_bit_for_bit(tmp_path):
    state = a_state()
    path = write_checkpoint(tmp_path / "run.ckpt", state, frames=12,
                            scene_text="[simulation]\n# \u00e9t\u00e9\n",
                            info={"time_step": 1e-7 / 3.0, "note": "x"})
    assert path == tmp_path / "run.ckpt"
    assert sorted(os.listdir(tmp_path)) == ["run.ckpt"]   # no temporary file left
    back, frames, scene, info = read_checkpoint(path)
    assert frames == 12 and scene == "[simulation]\n# \u00e9t\u00e9\n"
    assert info == {"time_step": 1e-7 / 3.0, "note": "x"}
    for name in ("position", "velocity", "angular_velocity", "bond_active", "bond_axis",
                 "bond_tangential_force", "bond_break_time", "bond_break_mode",
                 "bond_previous_length", "clump_position", "clump_orientation"):
        np.testing.assert_array_equal(getattr(back, name), getattr(state, name),
                                      strict=True)
        assert getattr(back, name).flags["C_CONTIGUOUS"]
    assert back.time == 0.1 + 0.2 and back.step == 2 ** 40 + 3 and back.started is True
    assert back.work_external == 1.0 / 3.0
    assert back.dissipated_damping == np.nextafter(2.5e-7, 1.0)
    assert type(back.step) is int and type(back.time) is float
    assert set(back.extra) == set(state.extra)
    for key in ("contact_pairs", "contact_force", "flags", "empty"):
        np.testing.assert_array_equal(back.extra[key], state.extra[key], strict=True)
        assert back.extra[key].flags["C_CONTIGUOUS"]
    assert back.extra["rebuilds"] == 17 and type(back.extra["rebuilds"]) is int
    assert back.extra["skin"] == 1e-5 / 3.0 and type(back.extra["skin"]) is float


def test_a_new_checkpoint_replaces_the_old_one_whole(tmp_path):
    state = a_state()
    path = tmp_path / "run.ckpt"
    write_checkpoint(path, state, frames=3)
    state.time = 2.0
    state.extra = {}
    write_checkpoint(path, state, frames=4)
    back, frames, scene, info = read_checkpoint(path)
    assert back.time == 2.0 and frames == 4 and back.extra == {}
    assert scene == "" and info == {}
    assert sorted(os.listdir(tmp_path)) == ["run.ckpt"]


def test_a_folder_that_cannot_be_synced_still_gets_its_checkpoint(tmp_path, monkeypatch):
    opened = []

    def refuse(path, flags):
        opened.append((str(path), flags))
        raise OSError("no fsync of folders here")
    monkeypatch.setattr(checkpoint.os, "open", refuse)
    write_checkpoint(tmp_path / "run.ckpt", a_state(), frames=1)
    assert opened == [(str(tmp_path), os.O_RDONLY)]
    assert read_checkpoint(tmp_path / "run.ckpt")[1] == 1


def test_the_folder_is_synced_and_closed(tmp_path, monkeypatch):
    synced, closed = [], []
    real_fsync, real_close = os.fsync, os.close
    monkeypatch.setattr(checkpoint.os, "fsync", lambda fd: synced.append(fd) or
                        real_fsync(fd))
    monkeypatch.setattr(checkpoint.os, "close", lambda fd: closed.append(fd) or
                        real_close(fd))
    write_checkpoint(tmp_path / "run.ckpt", a_state(), frames=1)
    # the file's descriptor, then the folder's, which is closed
    assert len(synced) == 2 and closed == [synced[1]]


def save(path, arrays):
    """A checkpoint's arrays written as they are (np.savez of a name adds .npz)."""
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


def test_an_optional_array_absent_and_another_format(tmp_path):
    state = a_state()
    state.bond_previous_length = None
    # the arrays after it in the State (a clump's) are still written and read
    state.clump_position = np.array([[1.0, 2.0, 3.0]])
    state.clump_orientation = np.array([[0.6, 0.8, 0.0, 0.0]])
    path = write_checkpoint(tmp_path / "old.ckpt", state, frames=2)
    back = read_checkpoint(path)[0]
    assert back.bond_previous_length is None
    np.testing.assert_array_equal(back.clump_position, [[1.0, 2.0, 3.0]], strict=True)
    np.testing.assert_array_equal(back.clump_orientation, [[0.6, 0.8, 0.0, 0.0]],
                                  strict=True)
    # a checkpoint of an older State without the clump arrays reads them as empty
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if not k.startswith("state/clump_")}
    save(tmp_path / "older.ckpt", arrays)
    back = read_checkpoint(tmp_path / "older.ckpt")[0]
    assert back.clump_orientation.shape == (0, 4) and back.position.shape == (4, 3)
    # a checkpoint is never unpickled: an object array in it is refused
    meta = json.loads(bytes(arrays["meta"]).decode())
    meta["extra"]["evil"] = "array"
    evil = dict(arrays, meta=np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8))
    evil["extra/evil"] = np.array([{"a": 1}], dtype=object)
    save(tmp_path / "evil.ckpt", evil)
    with pytest.raises(ValueError, match="allow_pickle"):
        read_checkpoint(tmp_path / "evil.ckpt")
    # a required array missing is an error, not a default
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != "state/velocity"}
    save(tmp_path / "torn.ckpt", arrays)
    with pytest.raises(KeyError, match="state/velocity"):
        read_checkpoint(tmp_path / "torn.ckpt")
    meta = json.loads(bytes(arrays["meta"]).decode())
    meta["format"] = 2
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    save(tmp_path / "future.ckpt", arrays)
    with pytest.raises(ValueError) as error:
        read_checkpoint(tmp_path / "future.ckpt")
    assert str(error.value) == f"{tmp_path / 'future.ckpt'}: checkpoint format 2, expected 1"

"""Results file (SPEC 6) and checkpoint/resume.

References: a plain Simulation run of the same steps (the results must hold its states
bit for bit); the uninterrupted run (a resumed run must reproduce it bit for bit)."""
import h5py
import numpy as np
import pytest

from bondem.io.checkpoint import read_checkpoint, write_checkpoint
from bondem.io.results import read_results
from bondem.runner import frame_schedule, run_scene
from bondem.scene import load_scene
from scenetools import cube_scene

SPEC6 = {  # name: shape as a function of (F, N, B, W)
    "time": lambda F, N, B, W: (F,),
    "particles/radius": lambda F, N, B, W: (N,),
    "particles/material": lambda F, N, B, W: (N,),
    "particles/position": lambda F, N, B, W: (F, N, 3),
    "particles/velocity": lambda F, N, B, W: (F, N, 3),
    "particles/angular_velocity": lambda F, N, B, W: (F, N, 3),
    "bonds/pairs": lambda F, N, B, W: (B, 2),
    "bonds/diameter": lambda F, N, B, W: (B,),
    "bonds/initial_length": lambda F, N, B, W: (B,),
    "bonds/active": lambda F, N, B, W: (F, B),
    "bonds/break_time": lambda F, N, B, W: (B,),
    "bonds/force": lambda F, N, B, W: (F, B, 3),
    "bonds/normal_moment": lambda F, N, B, W: (F, B, 3),
    "bonds/tangential_moment": lambda F, N, B, W: (F, B, 3),
    "walls/force": lambda F, N, B, W: (F, W, 3),
    "walls/position": lambda F, N, B, W: (F, W, 3),
    # extras
    "walls/torque": lambda F, N, B, W: (F, W, 3),
    "bonds/break_mode": lambda F, N, B, W: (B,),
    "bonds/material": lambda F, N, B, W: (B,),
    "particles/mass": lambda F, N, B, W: (N,),
}
UNITS = {"time": "s", "particles/position": "m", "particles/velocity": "m/s",
         "particles/angular_velocity": "rad/s", "bonds/force": "N",
         "bonds/normal_moment": "N m", "bonds/tangential_moment": "N m",
         "bonds/break_time": "s", "walls/force": "N", "bonds/diameter": "m"}


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    folder = tmp_path_factory.mktemp("finished")
    scene = load_scene(cube_scene(folder))
    path = run_scene(scene, folder / "out", progress=False)
    return scene, path


def test_spec6_layout_and_contents(finished):
    scene, path = finished
    sim = scene.make_simulation()
    total, stride = frame_schedule(scene, sim.time_step)
    F = 1 + -(-total // stride)
    N, B = scene.model.n_particles, scene.model.n_bonds
    with h5py.File(path, "r", swmr=True) as f:
        for name, shape in SPEC6.items():
            assert f[name].shape == shape(F, N, B, 0), name
        for name, unit in UNITS.items():
            assert f[name].attrs["unit"] == unit, name
        assert f["particles/position"].compression == "gzip"
        assert f["bonds/active"].dtype == np.bool_
        assert f.attrs["scene"] == scene.text
        assert f.attrs["backend"] == "cpu" and f.attrs["time_step"] == sim.time_step
        assert f.attrs["bondem_version"]
        assert list(f["materials/names"].asstr()[()]) == ["glass"]
    r = read_results(path)
    # frame k is the state after k * stride steps (and the last one after all steps),
    # bit for bit what a plain Simulation gives.
    steps = [min(k * stride, total) for k in range(F)]
    done = 0
    for k, target in enumerate(steps):
        if target > done:
            sim.step(target - done)
            done = target
        assert r["time"][k] == sim.state.time
        np.testing.assert_array_equal(r["particles/position"][k], sim.state.position)
        np.testing.assert_array_equal(r["particles/velocity"][k], sim.state.velocity)
        np.testing.assert_array_equal(r["bonds/active"][k], sim.state.bond_active)
        intact = sim.state.bond_active[:, None]
        np.testing.assert_array_equal(r["bonds/tangential_moment"][k],
                                      np.where(intact, sim.state.bond_tangential_moment, 0.0))
        np.testing.assert_array_equal(r["bonds/normal_moment"][k],
                                      np.where(intact, sim.state.bond_normal_moment, 0.0))
    for name, value in sim.energy_terms().items():
        assert r[f"energy/{name}"][-1] == value, name
    np.testing.assert_array_equal(r["bonds/break_time"], sim.state.bond_break_time)
    np.testing.assert_array_equal(r["bonds/break_mode"], sim.state.bond_break_mode)
    # the scene breaks bonds along x during the run and keeps the others
    assert r["bonds/active"][0].all() and 0 < r["bonds/active"][-1].sum() < B
    assert np.all(np.isnan(r["bonds/break_time"]) == r["bonds/active"][-1])
    # broken bonds carry no force; intact ones: F_n + F_t on particle i with
    # F_n = E A_b (L - L0) / L0 n (SPEC 2; pulls i towards j in tension)
    k = F - 1
    active = r["bonds/active"][k]
    assert np.all(r["bonds/force"][k][~active] == 0.0)
    pairs = r["bonds/pairs"]
    sep = r["particles/position"][k][pairs[:, 1]] - r["particles/position"][k][pairs[:, 0]]
    length = np.linalg.norm(sep, axis=1)
    area = np.pi * (0.5 * r["bonds/diameter"]) ** 2
    l0 = r["bonds/initial_length"]
    expected = ((1e8 * area * (length - l0) / l0)[:, None] * sep / length[:, None]
                + sim.state.bond_tangential_force)
    np.testing.assert_allclose(r["bonds/force"][k][active], expected[active], rtol=1e-9,
                               atol=1e-12)
    assert np.any(np.einsum("ij,ij->i", r["bonds/force"][k], sep)[active] != 0.0)


def _assert_same_results(a, b):
    ra, rb = read_results(a), read_results(b)
    assert set(ra) == set(rb)
    for name in ra:
        if name == "attrs":
            continue
        assert ra[name].shape == rb[name].shape, name
        np.testing.assert_array_equal(ra[name], rb[name], err_msg=name)  # NaN == NaN here


def test_resume_is_bit_identical(finished, tmp_path):
    """Stop after one frame (bonds are breaking then), resume from the checkpoint: the
    results equal the uninterrupted run's bit for bit, and more bonds break after."""
    scene, reference = finished
    scene = load_scene(scene.path)
    out = tmp_path / "out"
    run_scene(scene, out, progress=False, checkpoint_minutes=0.0, stop_after_frames=1)
    state, frames, _, _ = read_checkpoint(out / "checkpoint.npz")
    assert frames == 2 and state.step > 0
    with h5py.File(out / "results.h5", "r") as f:
        assert f["time"].shape == (2,)
        intact_at_checkpoint = f["bonds/active"][1].sum()
    run_scene(scene, out, progress=False, resume=True)
    _assert_same_results(reference, out / "results.h5")
    assert read_results(out / "results.h5")["bonds/active"][-1].sum() < intact_at_checkpoint


def test_resume_truncates_frames_written_after_checkpoint(finished, tmp_path):
    """A checkpoint older than the last frames (as after a kill between checkpoints): the
    results are cut back to the checkpoint's frame and the run still matches."""
    scene, reference = finished
    out = tmp_path / "out"
    run_scene(scene, out, progress=False, checkpoint_minutes=1e9, stop_after_frames=4)
    state, frames, _, _ = read_checkpoint(out / "checkpoint.npz")
    assert frames == 1 and state.step == 0  # only the initial checkpoint
    with h5py.File(out / "results.h5", "r") as f:
        assert f["time"].shape == (5,)
    run_scene(scene, out, progress=False, resume=True)
    _assert_same_results(reference, out / "results.h5")


def test_checkpoint_round_trip_with_extra_arrays(finished, tmp_path):
    """Every State array and extra entry (any shape, scalars) survives bit for bit."""
    scene, _ = finished
    state = scene.state.copy()
    state.time, state.step, state.started = 1.0 / 3.0, 7, True
    state.work_external = np.nextafter(0.1, 1.0)
    state.extra = {"contact_pairs": np.arange(10, dtype=np.int64).reshape(5, 2),
                   "contact_tangential": np.random.default_rng(0).normal(size=(5, 3)),
                   "empty": np.zeros((0, 3)), "count": 3}
    path = write_checkpoint(tmp_path / "c.npz", state, frames=4, scene_text="x = 1")
    back, frames, text, _ = read_checkpoint(path)
    assert frames == 4 and text == "x = 1" and not (tmp_path / "c.npz.tmp").exists()
    for name, value in state.arrays().items():
        np.testing.assert_array_equal(back.arrays()[name], value, err_msg=name)
        if isinstance(value, np.ndarray):
            assert back.arrays()[name].dtype == value.dtype and back.arrays()[name].shape == value.shape
    assert (back.time, back.step, back.started, back.work_external, back.extra["count"]) == \
        (state.time, state.step, state.started, state.work_external, 3)


def test_resume_refuses_changed_scene(finished, tmp_path):
    from bondem.errors import InputError
    scene, _ = finished
    out = tmp_path / "out"
    run_scene(scene, out, progress=False, stop_after_frames=1)
    changed = load_scene(scene.path, {"materials.glass.density": 2600.0})
    with pytest.raises(InputError, match="--resume"):
        run_scene(changed, out, progress=False, resume=True)


def test_resume_from_checkpoint_between_frames(finished, tmp_path, monkeypatch):
    """Checkpoints taken between two frames (one step per batch): resuming from one taken
    mid-interval still reproduces the uninterrupted run bit for bit."""
    import shutil

    import bondem.runner as runner
    scene, reference = finished
    monkeypatch.setattr(runner, "BATCH_SECONDS", 0.0)  # batches of one step
    saved = {}
    original = runner.write_checkpoint

    def keep_mid_frame(path, state, **kwargs):
        original(path, state, **kwargs)
        if state.step == 13 and path.name == runner.CHECKPOINT_NAME:  # stride is 9
            shutil.copyfile(path, tmp_path / "mid.npz")
            saved["frames"] = kwargs["frames"]

    monkeypatch.setattr(runner, "write_checkpoint", keep_mid_frame)
    out = tmp_path / "out"
    run_scene(scene, out, progress=False, checkpoint_minutes=0.0)
    monkeypatch.undo()
    assert saved["frames"] == 2  # t = 0 and step 9
    shutil.copyfile(tmp_path / "mid.npz", out / runner.CHECKPOINT_NAME)
    run_scene(scene, out, progress=False, resume=True)
    _assert_same_results(reference, out / "results.h5")

"""A run killed with SIGKILL mid-way leaves a readable results file holding every frame
flushed so far; ``bondem run --resume`` then finishes it bit for bit like an
uninterrupted run (reference: the uninterrupted run of the same scene)."""
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
from click.testing import CliRunner

import bondem
from bondem.cli import main
from bondem.io.results import read_results, rewrite_results
from bondem.runner import run_scene
from bondem.scene import load_scene
from scenetools import cube_scene


def _frames(path):
    try:
        with h5py.File(path, "r", swmr=True) as f:
            return f["time"].shape[0]
    except (OSError, KeyError):
        return 0


def test_sigkill_leaves_readable_file_and_resume_matches(tmp_path):
    scene_path = cube_scene(tmp_path, end_time=2e-2, save_every=2e-4)
    out = tmp_path / "killed"
    env = dict(os.environ, PYTHONPATH=str(Path(bondem.__file__).parents[1]),
               NUMBA_NUM_THREADS="1")
    process = subprocess.Popen(
        [sys.executable, "-m", "bondem", "run", str(scene_path), "--out", str(out),
         "--no-progress", "--checkpoint-minutes", "0"], env=env,
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while _frames(out / "results.h5") < 4 and time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read().decode()
        time.sleep(0.02)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    assert process.returncode == -signal.SIGKILL

    # readable in SWMR mode (HDF5 keeps the "open for write" flag of the killed writer);
    # every dataset holds at least the complete frames
    with h5py.File(out / "results.h5", "r", swmr=True) as f:
        frames = f["time"].shape[0]
        assert 4 <= frames < 101
        for name in ("particles/position", "particles/velocity", "bonds/active",
                     "bonds/force", "energy/kinetic_translational"):
            assert f[name].shape[0] >= frames, name
        position = f["particles/position"][:frames]
        assert np.all(np.isfinite(position)) and np.all(np.diff(f["time"][()]) > 0)

    # rewrite_results gives a clean copy that opens without SWMR too
    copy = tmp_path / "copy.h5"
    shutil.copyfile(out / "results.h5", copy)
    assert rewrite_results(copy) == frames
    with h5py.File(copy, "r") as f:
        np.testing.assert_array_equal(f["particles/position"][()], position)

    result = CliRunner().invoke(main, ["run", str(scene_path), "--out", str(out),
                                       "--resume", "--no-progress"])
    assert result.exit_code == 0, result.output
    reference = run_scene(load_scene(scene_path), tmp_path / "reference", progress=False)
    a, b = read_results(reference), read_results(out / "results.h5")
    assert a["time"].shape == (101,)
    for name in a:
        if name != "attrs":
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_resume_without_checkpoint_is_input_error(tmp_path):
    result = CliRunner().invoke(main, ["run", str(cube_scene(tmp_path)), "--out",
                                       str(tmp_path / "empty"), "--resume"])
    assert result.exit_code == 2 and "--resume" in result.stderr


def test_blow_up_exits_nonzero_and_keeps_last_good_state(tmp_path):
    """A forced time step 4x the bond's axial time scale blows up (explicit integration is unstable
    above 2/omega); the run stops with exit status 1, the frames before it are kept and
    the last good state is saved."""
    from bondem.io.checkpoint import read_checkpoint
    path = cube_scene(tmp_path, end_time=2e-2, save_every=2e-4)
    text = path.read_text().replace('time_step = "auto"',
                                    "time_step = 5e-5\nforce_time_step = true")
    text = text.replace("\n[particles]", 'breakage = "none"\n\n[particles]')
    path.write_text(text)
    result = CliRunner().invoke(main, ["run", str(path), "--no-progress"])
    assert result.exit_code == 1, result.output
    assert "blew up" in result.stderr and "last_good_state.npz" in result.stderr
    out = tmp_path / "scene"
    state, frames, _, _ = read_checkpoint(out / "last_good_state.npz")
    r = read_results(out / "results.h5")
    assert 1 <= frames == r["time"].shape[0] < 101
    assert np.all(np.isfinite(state.position)) and state.time == r["time"][-1]
    np.testing.assert_array_equal(state.position, r["particles/position"][-1])


def test_ctrl_c_and_sigterm_keep_a_checkpoint_and_say_how_to_resume(tmp_path):
    """SIGINT (Ctrl-C) and SIGTERM mid-run, with checkpoints 10 minutes apart (none would
    be written before the end): the run writes a checkpoint of the state it stopped at,
    closes the results file (plain h5py opens it), exits 128 + the signal and prints the
    --resume command, which finishes the run bit for bit like an uninterrupted one."""
    import shlex
    scene_path = cube_scene(tmp_path, end_time=2e-2, save_every=2e-4)
    reference = run_scene(load_scene(scene_path), tmp_path / "reference", progress=False)
    env = dict(os.environ, PYTHONPATH=str(Path(bondem.__file__).parents[1]),
               NUMBA_NUM_THREADS="1")
    for number in (signal.SIGINT, signal.SIGTERM):
        out = tmp_path / f"stopped {number.name}"     # a space: the command is quoted
        process = subprocess.Popen(
            [sys.executable, "-m", "bondem", "run", str(scene_path), "--out", str(out),
             "--no-progress", "--checkpoint-minutes", "10"], env=env,
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        while _frames(out / "results.h5") < 4 and time.monotonic() < deadline:
            assert process.poll() is None, process.stderr.read()
            time.sleep(0.02)
        process.send_signal(number)
        stderr = process.communicate(timeout=120)[1]
        assert process.returncode == 128 + number, stderr
        assert f"stopped by {number.name}" in stderr and "Traceback" not in stderr
        (command,) = [line for line in stderr.splitlines()
                      if line.startswith("continue with: ")]
        words = shlex.split(command[len("continue with: "):])
        assert words[:2] == ["bondem", "run"] and "--resume" in words
        assert Path(words[words.index("--out") + 1]) == out
        with h5py.File(out / "results.h5", "r") as f:      # closed cleanly, no SWMR needed
            frames = f["time"].shape[0]
        assert 4 <= frames < 101
        from bondem.io.checkpoint import read_checkpoint
        state, kept_frames, _, _ = read_checkpoint(out / "checkpoint.npz")
        # the signal's checkpoint, not the one at t = 0 (the next was 10 minutes away)
        assert kept_frames == frames
        assert state.time >= float(read_results(out / "results.h5")["time"][-1]) > 0.0
        result = CliRunner().invoke(main, words[1:] + ["--no-progress"])
        assert result.exit_code == 0, result.output
        a, b = read_results(reference), read_results(out / "results.h5")
        for name in a:
            if name != "attrs":
                np.testing.assert_array_equal(a[name], b[name], err_msg=name)

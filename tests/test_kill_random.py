"""SIGKILL at random moments (seeded): while Python starts, while the results file is
made, within a frame, within a checkpoint, at the end. After every kill the results file,
if there is one, opens with plain ``h5py.File(path)`` (no SWMR, no h5clear) and holds
complete, increasing frames; ``--resume`` (or ``--overwrite`` when the kill came before the
first checkpoint) carries on, and the run that finally ends is bit for bit the
uninterrupted one."""
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np

import bondem
from bondem.io.results import read_results
from bondem.runner import run_scene
from bondem.scene import load_scene
from scenetools import cube_scene

KILLS = 6


def _open_plain(path, grace=5.0):
    """Plain ``h5py.File(path)``, retried for ``grace`` s: a kill within a frame leaves
    HDF5's open-for-write mark, which the writer's watchman (io/_h5guard.py) clears as
    soon as the writer's pipe closes, within milliseconds on an idle machine but later on
    one whose two cores are busy."""
    deadline = time.monotonic() + grace
    while True:
        try:
            return h5py.File(path, "r")
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def _check_plain_readable(path):
    with _open_plain(path) as f:     # plain: what HDFView and other readers do
        frames = f["time"].shape[0]
        times = f["time"][()]
        assert np.all(np.diff(times) > 0)
        for name in ("particles/position", "particles/velocity", "bonds/active",
                     "bonds/force", "energy/kinetic_translational"):
            assert f[name].shape[0] >= frames, name
        assert np.all(np.isfinite(f["particles/position"][:frames]))
    return frames


def test_sigkill_at_random_moments(tmp_path):
    scene_path = cube_scene(tmp_path, n=4, end_time=0.12, save_every=2e-4)
    # the uninterrupted reference (also fills Numba's cache for the runs below)
    reference = read_results(run_scene(load_scene(scene_path), tmp_path / "reference",
                                       progress=False))
    out = tmp_path / "killed"
    env = dict(os.environ, PYTHONPATH=str(Path(bondem.__file__).parents[1]),
               NUMBA_NUM_THREADS="1")
    command = [sys.executable, "-m", "bondem", "run", str(scene_path), "--out", str(out),
               "--no-progress", "--checkpoint-minutes", "0"]
    # The kills fall within a window of 4 s on an idle machine; on a loaded one the start
    # (Python, the imports, Numba's cache) takes longer, and the window grows with it.
    started = time.monotonic()
    subprocess.run([sys.executable, "-c", "import bondem.runner, bondem.walls"], env=env,
                   check=True)
    window = 4.0 * max(1.0, (time.monotonic() - started) / 1.5)
    rng = random.Random(20261201)
    seen = []
    for _ in range(KILLS):
        again = ["--resume"] if (out / "checkpoint.npz").exists() else ["--overwrite"]
        process = subprocess.Popen(command + again, env=env, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE)
        time.sleep(rng.uniform(0.0, window))
        process.send_signal(signal.SIGKILL)
        _, error = process.communicate()
        assert process.returncode in (-signal.SIGKILL, 0), error.decode()
        if (out / "results.h5").exists():
            seen.append(_check_plain_readable(out / "results.h5"))
    again = ["--resume"] if (out / "checkpoint.npz").exists() else ["--overwrite"]
    finished = subprocess.run(command + again, env=env, capture_output=True)
    assert finished.returncode == 0, finished.stderr.decode()
    assert _check_plain_readable(out / "results.h5") == reference["time"].shape[0]
    result = read_results(out / "results.h5")
    for name in reference:
        if name != "attrs":
            np.testing.assert_array_equal(reference[name], result[name], err_msg=name)
    assert not (out / "previous_run").exists()
    assert seen, "no kill came after the results file existed: the moments are too early"

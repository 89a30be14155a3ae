"""The exit statuses docs/scene.md promises, each from the real command line in a
subprocess (the shell sees what a user's script sees): 0 done, 1 the run failed, 2 bad
input, 128 + the signal for a run stopped by SIGINT or SIGTERM (tests/test_kill_resume.py
checks what such a run keeps)."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import bondem
from scenetools import cube_scene
from test_bad_files import BLOW_UP

ENV = dict(os.environ, PYTHONPATH=str(Path(bondem.__file__).parents[1]),
           NUMBA_NUM_THREADS="1")


def _bondem(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "bondem", *map(str, args)], env=ENV,
                          capture_output=True, text=True, timeout=300, **kwargs)


def test_done_is_0_failed_is_1_bad_input_is_2(tmp_path):
    scene = cube_scene(tmp_path, end_time=2e-5, save_every=1e-5)
    done = _bondem("run", scene, "--no-progress")
    assert done.returncode == 0, done.stderr
    (tmp_path / "blow.toml").write_text(BLOW_UP)
    failed = _bondem("run", tmp_path / "blow.toml", "--no-progress")
    assert failed.returncode == 1 and "run failed" in failed.stderr
    bad = _bondem("run", scene, "--set", "simulation.end_time=-1", "--out", tmp_path / "x")
    assert bad.returncode == 2
    assert bad.stderr.strip().count("\n") == 0 and "simulation.end_time" in bad.stderr
    assert _bondem("analyze", tmp_path / "nothing.h5").returncode == 2


def test_a_signal_is_128_plus_its_number(tmp_path):
    scene = cube_scene(tmp_path, end_time=2e-2, save_every=2e-4)
    for number in (signal.SIGINT, signal.SIGTERM):
        out = tmp_path / number.name
        process = subprocess.Popen([sys.executable, "-m", "bondem", "run", str(scene),
                                    "--out", str(out), "--no-progress"], env=ENV,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                   text=True)
        deadline = time.monotonic() + 120
        while not (out / "results.h5").is_file() and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.5)
        process.send_signal(number)
        stderr = process.communicate(timeout=120)[1]
        assert process.returncode == 128 + number, stderr
        assert {signal.SIGINT: 130, signal.SIGTERM: 143}[number] == process.returncode

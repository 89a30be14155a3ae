"""Files a user may really have: not UTF-8 (Latin-1, UTF-16, binary), numbers too large
for a float, an index beyond int64, an output path that is a file, a GPU scene on a
machine without one. Each ends with exit status 2 and one line naming the file (and line,
for CSV) and the key; none is a traceback. A byte-order mark is accepted."""
from pathlib import Path

import pytest
from click.testing import CliRunner

from bondem.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _cantilever(tmp_path, particles=None, bonds=None, scene_edit=lambda s: s):
    scene = (EXAMPLES / "cantilever.toml").read_text()
    (tmp_path / "p.csv").write_bytes(particles if particles is not None else
                                     (EXAMPLES / "cantilever_particles.csv").read_bytes())
    (tmp_path / "b.csv").write_bytes(bonds if bonds is not None else
                                     (EXAMPLES / "cantilever_bonds.csv").read_bytes())
    scene = scene.replace("cantilever_particles.csv", "p.csv").replace("cantilever_bonds.csv",
                                                                        "b.csv")
    path = tmp_path / "scene.toml"
    path.write_bytes(scene_edit(scene).encode("utf-8") if isinstance(scene_edit(scene), str)
                     else scene_edit(scene))
    return path


def _fails_cleanly(args, *names):
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    for name in names:
        assert name in lines[0], (name, lines[0])
    return lines[0]


PARTICLES = (EXAMPLES / "cantilever_particles.csv").read_bytes()


@pytest.mark.parametrize("label, particles, bonds, edit, names", [
    ("latin-1 particles", PARTICLES.replace(b"glass", b"gl\xe4ss", 1), None, None,
     ("p.csv", "line 2", "particles.file")),
    ("utf-16 bonds", None, (EXAMPLES / "cantilever_bonds.csv").read_text().encode("utf-16"),
     None, ("b.csv", "line 1", "bonds.file")),
    ("binary scene", None, None, lambda s: b"\x00\x81\xff" + s.encode(), ("scene.toml",)),
    ("400-digit number", None, None,
     lambda s: s.replace("end_time = 0.05", "end_time = 1" + "0" * 400),
     ("scene.toml", "simulation.end_time", "digits")),
    ("index beyond int64", None, b"i,j,diameter,material\n0," + b"9" * 30 + b",0.002,binder\n",
     None, ("b.csv", "line 2", "j")),
])
def test_bad_files_are_input_errors(tmp_path, label, particles, bonds, edit, names):
    scene = _cantilever(tmp_path, particles, bonds, edit or (lambda s: s))
    _fails_cleanly(["info", str(scene)], *names)


def test_byte_order_mark_is_accepted(tmp_path):
    scene = _cantilever(tmp_path, particles=b"\xef\xbb\xbf" + PARTICLES)
    result = CliRunner().invoke(main, ["info", str(scene)])
    assert result.exit_code == 0, result.output


def test_output_folder_that_is_a_file_and_gpu_without_gpu(tmp_path, monkeypatch):
    (tmp_path / "taken").write_text("")
    scene = EXAMPLES / "cantilever.toml"
    _fails_cleanly(["run", str(scene), "--out", str(tmp_path / "taken"), "--no-progress"],
                   "taken", "--out")
    monkeypatch.delenv("NUMBA_ENABLE_CUDASIM", raising=False)
    from numba import cuda
    if cuda.is_available():
        pytest.skip("a GPU is here")
    _fails_cleanly(["run", str(scene), "--out", str(tmp_path / "g"), "--backend", "gpu",
                    "--no-progress"], "cantilever.toml", "simulation.backend")


BLOW_UP = """
[simulation]
end_time = 1e-3
time_step = 5e-6          # 8.7 times the stable step
force_time_step = true
save_every = 1e-4
[materials.glass]
density = 2500.0
young_modulus = 1e8
[bond_materials.binder]
young_modulus = 1e8
normal_strength = 1e6
tangential_strength = 1e6
[particles]
generator = { shape = "sphere", radius = 2e-3, particle_radius = 2.5e-4, solids_fraction = 0.55, seed = 2, material = "glass" }
velocity = [0.0, 0.0, -1.0]
[bonds]
max_gap = 2e-5
diameter_ratio = 0.5
material = "binder"
"""


def test_an_energy_blow_up_is_a_failed_run(tmp_path):
    """A forced time step far above the stable one creates energy from nothing (every bond
    breaks, the energy balance is off by 100 times the initial energy) without a NaN: the
    run must stop with exit 1, keep the last good state and every good frame."""
    import h5py
    scene = tmp_path / "blow.toml"
    scene.write_text(BLOW_UP)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(scene), "--out", str(out), "--no-progress"])
    assert result.exit_code == 1, result.output
    assert "appeared from nothing" in result.stderr and "reduce the time step" in result.stderr
    assert (out / "last_good_state.npz").is_file()
    with h5py.File(out / "results.h5", "r", swmr=True) as f:
        assert f["time"].shape[0] >= 1
        assert f["bonds/active"][-1].all()       # the good frames are before the blow-up
    # the same scene at a stable step runs to its end
    stable = tmp_path / "stable.toml"
    stable.write_text(BLOW_UP.replace("time_step = 5e-6", "time_step = 5e-7"))
    result = CliRunner().invoke(main, ["run", str(stable), "--out", str(tmp_path / "s"),
                                       "--no-progress"])
    assert result.exit_code == 0, result.output


def test_second_run_into_a_busy_folder_is_refused(tmp_path):
    """While one run holds its folder, another run into it stops at once (exit 2) and
    leaves the first run's files alone."""
    from bondem.runner import _lock_folder
    out = tmp_path / "busy"
    out.mkdir()
    (out / "results.h5").write_bytes(b"the first run's frames")
    lock = _lock_folder(out)
    try:
        _fails_cleanly(["run", str(EXAMPLES / "cantilever.toml"), "--out", str(out),
                        "--overwrite", "--no-progress"], "busy", "another bondem run")
    finally:
        lock.close()
    assert (out / "results.h5").read_bytes() == b"the first run's frames"
    result = CliRunner().invoke(main, ["run", str(EXAMPLES / "cantilever.toml"), "--out",
                                       str(out), "--overwrite", "--no-progress",
                                       "--set", "simulation.end_time=1e-3"])
    assert result.exit_code == 0, result.output


def test_runs_beyond_max_steps_are_refused():
    line = _fails_cleanly(["info", str(EXAMPLES / "impact.toml"), "--set",
                           "simulation.end_time=1e300"], "simulation.end_time", "max_steps")
    assert "1.44e+306 steps" in line


def test_demo_replaces_only_its_own_run(tmp_path):
    own = tmp_path / "demo"
    for _ in range(2):   # a second demo replaces the first
        result = CliRunner().invoke(main, ["demo", "--out", str(own), "--end-time", "5e-5",
                                           "--no-progress"])
        assert result.exit_code == 0, result.output
    other = tmp_path / "mine"
    other.mkdir()
    (other / "results.h5").write_bytes(b"my run")
    _fails_cleanly(["demo", "--out", str(other), "--end-time", "5e-5", "--no-progress"],
                   "mine", "--overwrite")
    assert (other / "results.h5").read_bytes() == b"my run"
    assert not (other / "scene.toml").exists()


@pytest.mark.parametrize("setting, key", [
    ("particles.velocity=[1e300,0,0]", "particles.velocity"),
    ("simulation.box_high=[0,0,0]", "simulation.box_high"),
    ("simulation.box_low=[0.01,0,0]", "simulation.box_low"),
    ("simulation.gravity=[0,0,1e300]", "simulation.gravity"),
    ("particles.velocity=[0,0,1e150]", "particles.velocity"),
    ("particles.offset=[1e300,0,0]", "particles.offset"),
    ("materials.glass.density=1e300", "materials"),
])
def test_scenes_that_cannot_start_are_input_errors(tmp_path, setting, key):
    """Checked at load, not found at run time: infinite energy at t = 0, particles outside
    the domain at t = 0, particles that would move more than a radius in the first step
    (their speed, gravity), coordinates doubles cannot resolve, a stable time step longer
    than the whole run (each used to crash a kernel, run a garbage run or blame another
    key)."""
    _fails_cleanly(["run", str(EXAMPLES / "cantilever.toml"), "--out", str(tmp_path / "o"),
                    "--no-progress", "--set", setting], "cantilever.toml", key)
    assert not (tmp_path / "o" / "results.h5").exists()


def _frames(path):
    import h5py
    with h5py.File(path, "r") as f:     # plain: no SWMR needed after a run
        return f["time"].shape[0]


def test_overwrite_keeps_the_earlier_run_until_the_new_one_finishes(tmp_path):
    """--overwrite of a good run by one that blows up at its first steps: the good run's
    six frames stay (in previous_run/); a run that finishes then removes them."""
    good = ["run", str(EXAMPLES / "cantilever.toml"), "--out", str(tmp_path / "o"),
            "--no-progress", "--set", "simulation.end_time=5e-3"]
    assert CliRunner().invoke(main, good).exit_code == 0
    assert _frames(tmp_path / "o" / "results.h5") == 6
    scene = tmp_path / "blow.toml"
    scene.write_text(BLOW_UP)
    result = CliRunner().invoke(main, ["run", str(scene), "--out", str(tmp_path / "o"),
                                       "--no-progress", "--overwrite"])
    assert result.exit_code == 1 and "previous_run" in result.stderr, result.output
    assert _frames(tmp_path / "o" / "previous_run" / "results.h5") == 6
    # a second failure does not push the good run out
    result = CliRunner().invoke(main, ["run", str(scene), "--out", str(tmp_path / "o"),
                                       "--no-progress", "--overwrite"])
    assert result.exit_code == 1
    assert _frames(tmp_path / "o" / "previous_run" / "results.h5") == 6
    assert CliRunner().invoke(main, good + ["--overwrite"]).exit_code == 0
    assert not (tmp_path / "o" / "previous_run").exists()
    assert _frames(tmp_path / "o" / "results.h5") == 6


def test_a_full_disk_is_a_failed_run_with_every_frame_kept(tmp_path, monkeypatch):
    """The disk fills up at the fourth frame: exit 1, one line saying what is kept (no
    second error from closing the file), the three frames readable, and --resume goes on
    once there is room."""
    import errno

    from bondem.io.results import ResultsWriter
    append = ResultsWriter.append

    def full_after_three(self, sim, energy=None):
        if self.n_frames >= 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return append(self, sim, energy)
    monkeypatch.setattr(ResultsWriter, "append", full_after_three)
    args = ["run", str(EXAMPLES / "cantilever.toml"), "--out", str(tmp_path / "o"),
            "--no-progress", "--set", "simulation.end_time=5e-3", "--checkpoint-minutes", "0"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 1, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "No space left on device" in lines[0], result.stderr
    assert "--resume" in lines[0]
    assert _frames(tmp_path / "o" / "results.h5") == 3
    monkeypatch.setattr(ResultsWriter, "append", append)
    result = CliRunner().invoke(main, args + ["--resume"])
    assert result.exit_code == 0, result.output
    assert _frames(tmp_path / "o" / "results.h5") == 6


@pytest.mark.parametrize("damage", ["empty", "half", "garbage", "flipped"])
@pytest.mark.parametrize("target", ["results.h5", "checkpoint.npz"])
def test_resume_and_readers_refuse_damaged_files(tmp_path, damage, target):
    """A damaged results file or checkpoint: --resume, analyze, report and export vtk end
    with exit 2 and one line naming the file, at once (a results file cut in half used to
    make the SWMR reader wait forever)."""
    import random
    args = ["run", str(EXAMPLES / "cantilever.toml"), "--out", str(tmp_path / "o"),
            "--no-progress", "--set", "simulation.end_time=2e-3"]
    assert CliRunner().invoke(main, args).exit_code == 0
    path = tmp_path / "o" / target
    data = path.read_bytes()
    rng = random.Random(7)
    path.write_bytes({"empty": b"", "half": data[:len(data) // 2],
                      "garbage": bytes(rng.randrange(256) for _ in data),
                      "flipped": data[:3000] + bytes(b ^ 0x55 for b in data[3000:6000])
                      + data[6000:]}[damage])
    _fails_cleanly(args + ["--resume"], target, "--resume")
    if target == "results.h5":
        for command in (["analyze"], ["report"], ["export", "vtk"]):
            result = CliRunner().invoke(main, command + [str(path)])
            assert result.exit_code in (0, 2), (command, result.output)
            assert result.exception is None or isinstance(result.exception, SystemExit)
            if result.exit_code == 2:
                assert "results.h5" in result.stderr.strip().splitlines()[-1]


def test_a_wall_faster_than_a_radius_per_step_is_refused(tmp_path):
    _fails_cleanly(["info", str(EXAMPLES / "impact.toml"), "--set",
                    "walls.0.velocity=[0,0,1e300]"], "impact.toml", "walls.0.velocity")


def test_usage_errors_are_one_line():
    for args in (["run"], ["run", "--bogus", "x.toml"], ["frobnicate"]):
        line = _fails_cleanly(args, "bondem")
        assert "--help" in line


def test_first_hour_slips_get_messages_that_say_what_to_do(tmp_path):
    """A repeated CSV column is named; '--set =1' is an empty key; a misspelt key gets
    the nearest allowed one; a scene given where results are wanted is named as a scene
    with the results file to give; a folder is taken when it holds results.h5, else
    named as a folder without one."""
    doubled = PARTICLES.replace(b"fixed", b"z", 1)
    line = _fails_cleanly(["info", str(_cantilever(tmp_path, particles=doubled))], "p.csv")
    assert "the column 'z' appears 2 times" in line
    scene = _cantilever(tmp_path)
    assert "empty key" in _fails_cleanly(["info", str(scene), "--set", "=1"], "--set")
    (tmp_path / "typo").mkdir()
    typo = _cantilever(tmp_path / "typo", scene_edit=lambda s: s.replace("young_modulus",
                                                                          "young_modulis", 1))
    assert "did you mean 'young_modulus'?" in _fails_cleanly(["info", str(typo)],
                                                             "young_modulis")
    line = _fails_cleanly(["info", str(scene), "--set", "simulation.end_tiem=1"],
                          "simulation.end_tiem")
    assert "did you mean 'end_time'?" in line
    for command in (["report"], ["analyze"], ["export", "vtk"], ["export", "musen"]):
        line = _fails_cleanly(command + [str(scene)], "scene.toml")
        assert "this is a scene file" in line and str(tmp_path / "scene" / "results.h5") \
            in line
    empty = tmp_path / "empty"
    empty.mkdir()
    for command in (["report"], ["analyze"], ["export", "vtk"]):
        assert "folder without results.h5" in _fails_cleanly(command + [str(empty)], "empty")
    run = CliRunner().invoke(main, ["run", str(scene), "--no-progress"])
    assert run.exit_code == 0, run.output
    done = CliRunner().invoke(main, ["export", "vtk", str(tmp_path / "scene")])
    assert done.exit_code == 0 and (tmp_path / "scene" / "vtk" / "results.pvd").is_file()


def test_a_reader_that_goes_away_is_no_error(tmp_path):
    """'bondem analyze ... | head -1': no 'Broken pipe' message when head stops reading."""
    import subprocess
    import sys
    scene = _cantilever(tmp_path)
    assert CliRunner().invoke(main, ["run", str(scene), "--no-progress"]).exit_code == 0
    code = ("import sys; from bondem.cli import main; "
            "sys.argv = ['bondem', 'analyze', sys.argv[1], '--out', sys.argv[2]]; main()")
    reader = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "scene"),
                               str(tmp_path / "a")], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE)
    reader.stdout.close()                 # the reader goes away before the first line
    stderr = reader.stderr.read().decode()
    reader.wait(timeout=120)
    assert "Broken pipe" not in stderr and "Traceback" not in stderr, stderr
    assert reader.returncode == 1

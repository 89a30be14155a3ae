"""Ensemble studies (issue 10): study files, Dask runs equal to serial runs, a killed worker
and an interrupted study lose no finished case, resume runs only the missing ones, and the
Vogel-Peukert fit recovers known parameters.

The cases use ``bondem.impact.cluster_impact`` (a 27-particle bonded cube stopped dead on
a sticking target, Weibull bond strengths from the case seed): real simulations, about
0.05 s each once compiled.
"""
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.errors import InputError
from bondem.impact import (breakage_probability, cluster_impact, fit_master_curve,
                           master_curve)
from bondem.study import (Table, cases, load_study, read_table, run_case, run_study,
                          scene_quantities)

SRC = str(Path(__file__).resolve().parents[1] / "src")
QUANTITIES = '["broken_bond_fraction", "largest_fragment_fraction", "peak_wall_force"]'


def write_study(folder, runner="bondem.impact:cluster_impact", extra=""):
    """A dozen impact cases: 3 velocities x 2 strengths x 2 seeds."""
    path = Path(folder) / "impact.toml"
    path.write_text(textwrap.dedent(f"""\
        [study]
        runner = "{runner}"
        quantities = {QUANTITIES}
        repeats = 2
        seed = 7
        [parameters]
        impact_velocity = {{ range = [0.3, 2.1, 3] }}
        normal_strength = [1e6, 2e6]
        {extra}"""))
    return path


def without_timing(rows):
    return [{k: v for k, v in r.items() if k != "wall_time"} for r in rows]


@pytest.fixture(scope="module")
def client():
    """One LocalCluster (2 single-threaded worker processes) shared by the Dask tests."""
    from distributed import Client, LocalCluster
    # Two numba threads per worker process, so that the single thread of every case
    # (test below) comes from run_case, not from the environment.
    env = {"NUMBA_NUM_THREADS": "2", "PYTHONPATH": SRC}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None, env=env) as cluster, Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def serial_rows(tmp_path_factory):
    """Reference: every case run one by one in this process, in case order."""
    folder = tmp_path_factory.mktemp("serial")
    study = load_study(write_study(folder))
    return [run_case(study, case, folder) for case in cases(study)]


# --- study files --------------------------------------------------------------------------

def test_cases_are_deterministic_and_combine_as_asked(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(textwrap.dedent("""\
        [study]
        runner = "m:f"
        quantities = ["q"]
        combine = "product"
        [parameters]
        a = [1, 2]
        b = { range = [0.0, 1.0, 3] }
        c = { random = [5.0, 6.0], n = 2, seed = 4 }
        """))
    study = load_study(path)
    all_cases = cases(study)
    assert len(all_cases) == 2 * 3 * 2
    assert all_cases[0]["params"]["b"] == 0.0 and all_cases[-1]["params"]["b"] == 1.0
    assert study.parameters["b"] == (0.0, 0.5, 1.0)
    rng = np.random.default_rng(4)
    assert study.parameters["c"] == tuple(rng.uniform(5.0, 6.0, 2))
    assert [c["case"] for c in all_cases] == [f"{k:05d}" for k in range(12)]
    again = cases(load_study(path))
    assert again == all_cases and len({c["seed"] for c in all_cases}) == 12
    path.write_text(path.read_text().replace('"product"', '"zip"').replace(
        "range = [0.0, 1.0, 3]", "range = [0.0, 1.0, 2]"))
    zipped = cases(load_study(path))
    assert [c["params"]["a"] for c in zipped] == [1, 2] and len(zipped) == 2


@pytest.mark.parametrize("body, key", [
    ('[study]\nrunner = "m:f"\nquantities = ["q"]\nbogus = 1\n', "study.bogus"),
    ('[study]\nquantities = ["q"]\n', "study.scene"),
    ('[study]\nscene = "missing.toml"\n', "study.scene"),
    ('[study]\nrunner = "nocolon"\nquantities = ["q"]\n', "study.runner"),
    ('[study]\nrunner = "m:f"\nquantities = ["q"]\nrepeats = 0\n', "study.repeats"),
    ('[study]\nrunner = "m:f"\nquantities = ["q"]\n[parameters]\nv = { range = [0, 1] }\n',
     "parameters.v"),
    ('[study]\nrunner = "m:f"\nquantities = ["q"]\n[parameters]\nv = { random = [2, 1], n = 3 }\n',
     "parameters.v"),
    ('[study]\nrunner = "m:f"\nquantities = ["q"]\ncombine = "zip"\n[parameters]\n'
     'a = [1, 2]\nb = [1, 2, 3]\n', "study.combine"),
])
def test_bad_study_files_name_file_and_key(tmp_path, body, key):
    path = tmp_path / "bad.toml"
    path.write_text(body)
    with pytest.raises(InputError) as error:
        load_study(path)
    assert error.value.key == key and str(path) in str(error.value)
    result = CliRunner().invoke(main, ["study", str(path)])
    assert result.exit_code == 2 and key in result.output


# --- the self-contained impact case -------------------------------------------------------

def test_cluster_impact_is_linear_elastic_below_breakage():
    # No bond can break (strength 1e30 Pa): the response is linear in the impact velocity,
    # so the peak force on the target doubles with the velocity (to round-off).
    strong = {"normal_strength": 1e30}
    slow = cluster_impact({"impact_velocity": 0.1, **strong}, None, 0)
    fast = cluster_impact({"impact_velocity": 0.2, **strong}, None, 0)
    assert slow["broken_bond_fraction"] == 0.0 and fast["largest_fragment_fraction"] == pytest.approx(1.0)
    assert fast["peak_wall_force"] / slow["peak_wall_force"] == pytest.approx(2.0, rel=1e-9)
    # The first force peak of a stopped column is of order sqrt(k m) v (bond stiffness k,
    # particle mass m, 9 columns): order-of-magnitude check of the physics.
    k = 1e8 * np.pi * 0.5e-3 ** 2 / 2e-3
    m = 2500 * 4 / 3 * np.pi * 1e-3 ** 3
    assert 0.3 < fast["peak_wall_force"] / (9 * np.sqrt(k * m) * 0.2) < 3.0


# --- Dask ---------------------------------------------------------------------------------

def test_dask_study_gives_the_same_table_as_serial_runs(tmp_path, client, serial_rows):
    # Through the command line, to the cluster's scheduler by its address.
    result = CliRunner().invoke(main, ["study", str(write_study(tmp_path)), "--out",
                                       str(tmp_path / "o"), "--no-progress", "--scheduler",
                                       client.scheduler.address])
    assert result.exit_code == 0, result.output
    rows = read_table(tmp_path / "o" / "table.csv")
    assert without_timing(rows) == without_timing(serial_rows)
    assert len(rows) == 12 and all(r["status"] == "ok" for r in rows)
    broken = [r["broken_bond_fraction"] > 0 for r in rows]
    assert any(broken) and not all(broken)  # the dozen spans intact and broken cases


KILLER = """\
import os, signal
from pathlib import Path
from bondem.impact import cluster_impact

def run(params, case_dir, seed):
    # Case 00003 kills the worker process running it, once (the marker says it did).
    marker = Path(__file__).with_name("killed")
    if case_dir.name == "00003" and not marker.exists():
        marker.write_text(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    return cluster_impact(params, case_dir, seed)
"""


def test_killed_worker_loses_no_case_and_the_study_completes(tmp_path, client, serial_rows):
    (tmp_path / "killer_study.py").write_text(KILLER)
    study = write_study(tmp_path, runner="killer_study:run")
    path = run_study(study, scheduler=client, progress=False, out_dir=tmp_path / "o")
    assert (tmp_path / "killed").exists()  # a worker really died mid-study
    rows = read_table(path)
    lines = path.read_text().splitlines()
    assert len(lines) == 1 + 12  # one row per case, none twice
    assert without_timing(rows) == without_timing(serial_rows)


THREADS = """\
import os, numba

def run(params, case_dir, seed):
    return {"threads": numba.get_num_threads(), "pool": numba.config.NUMBA_NUM_THREADS,
            "pid": os.getpid()}
"""


def test_cases_run_single_threaded_on_separate_worker_processes(tmp_path, client):
    (tmp_path / "threads_study.py").write_text(THREADS)
    study = tmp_path / "threads.toml"
    study.write_text('[study]\nrunner = "threads_study:run"\nquantities = ["threads", "pool", '
                     '"pid"]\n[parameters]\nk = { range = [0, 1, 8] }\n')
    rows = read_table(run_study(study, scheduler=client, progress=False, out_dir=tmp_path / "o"))
    assert [r["threads"] for r in rows] == [1] * 8 and {r["pool"] for r in rows} == {2}
    assert os.getpid() not in {r["pid"] for r in rows}


LOGGER = """\
import os, time
from bondem.impact import cluster_impact

def run(params, case_dir, seed):
    with open(os.path.join(os.path.dirname(__file__), "started.log"), "a") as log:
        log.write(case_dir.name + "\\n")
    time.sleep(0.3)  # slow enough to interrupt the study halfway
    return cluster_impact(params, case_dir, seed)
"""


def test_interrupted_study_resumes_only_missing_cases(tmp_path, serial_rows):
    (tmp_path / "logger_study.py").write_text(LOGGER)
    study = write_study(tmp_path, runner="logger_study:run")
    out = tmp_path / "o"
    env = {**os.environ, "PYTHONPATH": SRC, "NUMBA_NUM_THREADS": "1"}
    process = subprocess.Popen([sys.executable, "-m", "bondem", "study", str(study),
                                "--workers", "1", "--out", str(out), "--no-progress"],
                               env=env, start_new_session=True, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    table = out / "table.csv"
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline:
            if table.exists() and len(read_table(table)) >= 3:
                break
            time.sleep(0.05)
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the client and its workers, at once
        process.wait()
    finished = {r["case"] for r in read_table(table)}
    assert 3 <= len(finished) < 12
    log = tmp_path / "started.log"
    log.write_text("")
    result = CliRunner().invoke(main, ["study", str(study), "--resume", "--out", str(out),
                                       "--scheduler", "serial", "--no-progress"])
    assert result.exit_code == 0, result.output
    rerun = log.read_text().split()
    assert sorted(rerun) == sorted({c["case"] for c in serial_rows} - finished)
    assert without_timing(read_table(table)) == without_timing(serial_rows)
    # Resuming a finished study runs nothing.
    log.write_text("")
    run_study(study, scheduler="serial", resume=True, out_dir=out, progress=False)
    assert log.read_text() == ""


def test_table_drops_a_row_cut_by_a_crash_and_resume_truncates_it(tmp_path):
    table = Table(tmp_path / "t.csv", ["case", "seed", "q", "status", "wall_time"])
    table.open(resume=False)
    table.append({"case": "00000", "seed": 1, "q": 0.1, "status": "ok", "wall_time": 1.0})
    with open(table.path, "a") as handle:
        handle.write("00001,2,0.")  # a crash in the middle of a row
    assert [r["case"] for r in read_table(table.path)] == ["00000"]
    table.open(resume=True)
    assert table.path.read_text().endswith("ok,1.0\n")
    with pytest.raises(InputError):
        Table(table.path, ["case", "other"]).open(resume=True)


def test_peak_wall_force_from_results_file(tmp_path):
    path = tmp_path / "results.h5"
    force = np.zeros((4, 2, 3))
    force[2, 1] = [3.0, 0.0, -4.0]
    force[1, 0] = [0.0, 2.0, 0.0]
    with h5py.File(path, "w") as handle:
        handle["/walls/force"] = force
    assert scene_quantities(path, ("peak_wall_force",)) == {"peak_wall_force": 5.0}


# --- Vogel-Peukert ------------------------------------------------------------------------

def test_master_curve_fit_recovers_known_parameters():
    rate, w_min = 2.5, 0.4  # kg/J, J/kg
    energy = np.linspace(0.0, 3.0, 40)
    exact = fit_master_curve(energy, master_curve(energy, rate, w_min), size=2e-3, impacts=2)
    assert exact.rate == pytest.approx(rate, rel=1e-6)
    assert exact.minimum_energy == pytest.approx(w_min, rel=1e-6)
    assert exact.f_mat == pytest.approx(rate / (2e-3 * 2), rel=1e-6)
    # Bernoulli outcomes (what a study gives): the estimate is within its error bars.
    rng = np.random.default_rng(11)
    energy = rng.uniform(0.0, 3.0, 4000)
    outcome = rng.random(energy.size) < master_curve(energy, rate, w_min)
    noisy = fit_master_curve(energy, outcome)
    assert abs(noisy.rate - rate) < 4 * noisy.rate_error and noisy.rate_error < 0.1 * rate
    assert abs(noisy.minimum_energy - w_min) < 4 * noisy.minimum_energy_error
    assert noisy.minimum_energy_error < 0.05
    centres, probability, count, _ = breakage_probability([1, 1, 2, 2, 2], [0, 1, 1, 1, 0])
    assert centres.tolist() == [1, 2] and count.tolist() == [2, 3]
    assert probability == pytest.approx([0.5, 2 / 3])


def test_fit_command_on_a_table_with_a_plot(tmp_path):
    rate, w_min = 1.5, 0.5
    rng = np.random.default_rng(5)
    velocity = np.repeat(np.linspace(0.5, 3.0, 11), 40)
    broken = rng.random(velocity.size) < master_curve(0.5 * velocity ** 2, rate, w_min)
    table = Table(tmp_path / "table.csv", ["case", "seed", "impact_velocity",
                                           "broken_bond_fraction", "status", "wall_time"])
    table.open(resume=False)
    for k, (v, b) in enumerate(zip(velocity, broken)):
        table.append({"case": f"{k:05d}", "seed": k, "impact_velocity": float(v),
                      "broken_bond_fraction": 0.2 * b, "status": "ok", "wall_time": 0.0})
    plot = tmp_path / "curve.png"
    result = CliRunner().invoke(main, ["study", "fit", str(table.path), "--plot", str(plot)])
    assert result.exit_code == 0, result.output
    fitted = float(result.output.split("f_mat x k = ")[1].split()[0])
    w_fit = float(result.output.split("W_m,min   = ")[1].split()[0])
    assert fitted == pytest.approx(rate, rel=0.25) and w_fit == pytest.approx(w_min, abs=0.15)
    assert plot.stat().st_size > 10_000
    result = CliRunner().invoke(main, ["study", "fit", str(table.path), "--quantity", "nope"])
    assert result.exit_code == 2 and "--quantity" in result.output


FLAKY = """\
from pathlib import Path
from bondem.impact import cluster_impact

def run(params, case_dir, seed):
    if case_dir.name == "00001" and not Path(__file__).with_name("fixed").exists():
        raise RuntimeError("solver diverged")
    return cluster_impact(params, case_dir, seed)
"""


def test_failed_case_is_recorded_and_rerun_on_resume(tmp_path, serial_rows):
    (tmp_path / "flaky_study.py").write_text(FLAKY)
    study = write_study(tmp_path, runner="flaky_study:run")
    path = run_study(study, scheduler="serial", progress=False, out_dir=tmp_path / "o")
    rows = read_table(path)
    assert rows[1]["status"] == "error: RuntimeError: solver diverged"
    assert np.isnan(rows[1]["peak_wall_force"]) and rows[0]["status"] == "ok"
    (tmp_path / "fixed").write_text("")
    run_study(study, scheduler="serial", resume=True, progress=False, out_dir=tmp_path / "o")
    assert without_timing(read_table(path)) == without_timing(serial_rows)


def test_example_study_loads_and_its_first_case_runs(tmp_path):
    example = Path(__file__).resolve().parents[1] / "examples" / "study_cluster_impact.toml"
    study = load_study(example)
    all_cases = cases(study)
    assert len(all_cases) >= 50
    first = dict(all_cases[0], params={**all_cases[0]["params"], "duration": 2e-4})
    row = run_case(study, first, tmp_path)
    assert row["status"] == "ok" and row["specific_energy"] == pytest.approx(
        0.5 * first["params"]["impact_velocity"] ** 2)


def test_scene_runner_passes_overrides_and_reads_the_results(tmp_path, monkeypatch):
    """The default runner's plumbing, with stand-ins for bondem.scene, bondem.runner and
    bondem.analysis (separate parts of bondem): each case loads the base scene with its
    parameters (and its seed under seed_key) as overrides, runs into its own folder, and
    the table gets the quantities of that folder's results.h5."""
    import types
    calls = []

    def load_scene(path, overrides=None):
        calls.append((Path(path), dict(overrides)))
        return dict(overrides)

    def run_scene(scene, out_dir, *, progress=True, resume=False, overwrite=False):
        assert progress is False and not resume
        path = Path(out_dir) / "results.h5"
        with h5py.File(path, "w") as handle:
            handle["/walls/force"] = np.array([[[0.0, 0.0, scene["walls.0.velocity.2"]]]])
            handle.attrs["fraction"] = scene["simulation.end_time"]
        return path

    def attribute(path, frame=-1):
        with h5py.File(path, "r") as handle:
            return float(handle.attrs["fraction"])

    modules = {"bondem.scene": {"load_scene": load_scene},
               "bondem.runner": {"run_scene": run_scene}, "bondem.analysis": {},
               "bondem.analysis.breakage": {"broken_bond_fraction": attribute},
               "bondem.analysis.fragments": {"largest_fragment_fraction": attribute}}
    for name, content in modules.items():
        module = types.ModuleType(name)
        module.__dict__.update(content)
        monkeypatch.setitem(sys.modules, name, module)
    (tmp_path / "base.toml").write_text("# base scene\n")
    study = tmp_path / "s.toml"
    study.write_text('[study]\nscene = "base.toml"\nseed_key = "particles.seed"\n'
                     '[parameters]\n"simulation.end_time" = [1e-3, 2e-3]\n'
                     '"walls.0.velocity.2" = [-3.0]\n')
    rows = read_table(run_study(study, scheduler="serial", progress=False, out_dir=tmp_path / "o"))
    expected = cases(load_study(study))
    assert [c[0] for c in calls] == [tmp_path / "base.toml"] * 2
    assert [c[1] for c in calls] == [{**c["params"], "particles.seed": c["seed"]} for c in expected]
    assert [r["broken_bond_fraction"] for r in rows] == [1e-3, 2e-3]
    assert [r["largest_fragment_fraction"] for r in rows] == [1e-3, 2e-3]
    assert [r["peak_wall_force"] for r in rows] == [3.0, 3.0]
    assert (tmp_path / "o" / "cases" / "00001" / "results.h5").is_file()


def test_scene_study_with_the_real_scene_runner(tmp_path):
    """End to end with bondem.scene, bondem.runner and bondem.analysis: the cube's x-layers
    fly apart; weak bonds (3e5 Pa) break along x, strong ones (1e12 Pa) do not, and every
    row equals the analysis of that case's own results file."""
    from bondem.analysis.breakage import broken_bond_fraction
    from scenetools import cube_scene
    cube_scene(tmp_path, end_time=2e-4, save_every=5e-5)
    study = tmp_path / "s.toml"
    study.write_text('[study]\nscene = "scene.toml"\n'
                     f'quantities = {QUANTITIES}\n'
                     '[parameters]\n"bond_materials.binder.normal_strength" = [3e5, 1e12]\n'
                     '"bond_materials.binder.tangential_strength" = [1e12]\n')
    table = run_study(study, scheduler="serial", progress=False, out_dir=tmp_path / "o")
    rows = read_table(table)
    assert [r["status"] for r in rows] == ["ok", "ok"]
    weak, strong = rows
    assert weak["broken_bond_fraction"] > 0.0 and strong["broken_bond_fraction"] == 0.0
    assert strong["largest_fragment_fraction"] == 1.0
    for row in rows:
        path = tmp_path / "o" / "cases" / row["case"] / "results.h5"
        assert row["broken_bond_fraction"] == broken_bond_fraction(path)

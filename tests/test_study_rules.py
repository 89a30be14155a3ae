"""study.py's rules against its definitions, with a runner in closed form next to the
study file (no simulation): how a file's parameters become values (a list, a range, a
seeded random draw), the order and seeds of the cases, the table's exact text and what a
crash leaves of it, a resume that runs only what is missing, a failing case recorded, the
Dask path with a client standing in for Dask, and the scene runner's overrides and
retries. Every message is compared whole."""
import math
import textwrap
from pathlib import Path

import numba
import numpy as np
import pytest

import bondem.study as study_module
from bondem.errors import InputError
from bondem.study import (Study, Table, cases, default_out_dir, load_study, pending_cases,
                          read_table, resolve_runner, run_case, run_study, scene_quantities,
                          table_columns)

RUNNER = '''
import math


def run(params, case_dir, seed):
    """y = a x + b, a failure where x is negative, an extra entry dropped."""
    (case_dir / "ran.txt").write_text(str(seed))
    if params["x"] < 0:
        raise ValueError("x below zero\\nsecond line")
    return {"y": params.get("a", 2.0) * params["x"] + 1.0, "label": "ok" + str(seed % 2),
            "extra": 1}


def partial(params, case_dir, seed):
    return {"y": 1.0}
'''


def _study(folder, body, module="mylab"):
    (folder / f"{module}.py").write_text(RUNNER)
    path = folder / "sweep.toml"
    path.write_text(textwrap.dedent(body))
    return path


SWEEP = """\
[study]
runner = "mylab:run"
quantities = ["y", "label"]
repeats = 2
seed = 11
[parameters]
x = [0.5, 1.5, -1.0]
a = { range = [1.0, 2.0, 2] }
"""


# ---------------------------------------------------------------- the file

def test_a_study_file_read_whole(tmp_path):
    study = load_study(_study(tmp_path, SWEEP))
    assert study == Study(path=(tmp_path / "sweep.toml").resolve(), scene=None,
                          runner="mylab:run", quantities=("y", "label"),
                          parameters={"x": (0.5, 1.5, -1.0), "a": (1.0, 2.0)},
                          combine="product", repeats=2, seed=11, seed_key=None)
    assert study.columns == ("case", "seed", "x", "a", "y", "label", "status", "wall_time")
    assert default_out_dir(study) == (tmp_path / "sweep").resolve()


def test_a_scene_study_takes_the_default_quantities(tmp_path):
    (tmp_path / "base.toml").write_text("")
    study = load_study(_study(tmp_path, """\
        [study]
        scene = "base.toml"
        seed_key = "particles.seed"
        combine = "zip"
        [parameters]
        "simulation.end_time" = [1e-3, 2e-3]
        "walls.0.velocity.2" = [-1.0, -2.0]
        """))
    assert study.scene == (tmp_path / "base.toml").resolve() and study.runner is None
    assert study.quantities == ("broken_bond_fraction", "largest_fragment_fraction",
                                "peak_wall_force")
    assert (study.combine, study.repeats, study.seed, study.seed_key) == \
        ("zip", 1, 0, "particles.seed")


def test_ranges_are_evenly_spaced_and_random_values_are_seeded(tmp_path):
    study = load_study(_study(tmp_path, """\
        [study]
        runner = "mylab:run"
        quantities = ["y"]
        [parameters]
        x = { range = [-3.0, 6.0, 4] }
        a = { random = [2.0, 5.0], n = 3, seed = 4 }
        b = { random = [7, 7], n = 1 }
        c = ["soft", "hard"]
        """))
    assert study.parameters["x"] == (-3.0, 0.0, 3.0, 6.0)
    assert study.parameters["a"] == tuple(np.random.default_rng(4).uniform(2.0, 5.0, 3))
    assert all(2.0 <= v < 5.0 for v in study.parameters["a"])
    assert study.parameters["b"] == (7.0,) and study.parameters["c"] == ("soft", "hard")
    other = load_study(_study(tmp_path, """\
        [study]
        runner = "mylab:run"
        quantities = ["y"]
        [parameters]
        a = { random = [2.0, 5.0], n = 3 }
        """))
    assert other.parameters["a"] == tuple(np.random.default_rng(0).uniform(2.0, 5.0, 3))


ALLOWED = "'product', 'zip'"
BAD = [
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[other]\nx = 1\n", "other",
     "unknown section(s) ['other']; allowed: [study], [parameters]"),
    ("[parameters]\nx = [1]\n", "study", "missing [study] section"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\nrepeat = 2\n", "study.repeat",
     "unknown key 'repeat'; did you mean 'repeats'? allowed: combine, quantities, repeats, "
     "runner, scene, seed, seed_key"),
    ("[study]\nquantities = ['y']\n", "study.scene",
     "give exactly one of scene (a base scene file) or runner ('package.module:function')"),
    ("[study]\nscene = 'base.toml'\nrunner = 'mylab:run'\n", "study.scene",
     "give exactly one of scene (a base scene file) or runner ('package.module:function')"),
    ("[study]\nscene = 3\n", "study.scene", "scene = 3; expected a file name"),
    ("[study]\nrunner = 'mylab.run'\nquantities = ['y']\n", "study.runner",
     "runner = 'mylab.run'; expected 'package.module:function'"),
    ("[study]\nrunner = 'mylab:'\nquantities = ['y']\n", "study.runner",
     "runner = 'mylab:'; expected 'package.module:function'"),
    ("[study]\nrunner = 'a:b:c'\nquantities = ['y']\n", "study.runner",
     "runner = 'a:b:c'; expected 'package.module:function'"),
    ("[study]\nrunner = 'mylab:run'\n", "study.quantities",
     "quantities = None; expected a non-empty list of distinct names"),
    ("[study]\nrunner = 'mylab:run'\nquantities = []\n", "study.quantities",
     "quantities = []; expected a non-empty list of distinct names"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y', 'y']\n", "study.quantities",
     "quantities = ['y', 'y']; expected a non-empty list of distinct names"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y', '']\n", "study.quantities",
     "quantities = ['y', '']; expected a non-empty list of distinct names"),
    ("[study]\nscene = 'base.toml'\nquantities = ['y']\n", "study.quantities",
     "quantity 'y' unknown to the scene runner; allowed: broken_bond_fraction, "
     "largest_fragment_fraction, peak_wall_force"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\ncombine = 'cross'\n",
     "study.combine", f"combine = 'cross'; allowed: {ALLOWED}"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\nrepeats = 0\n", "study.repeats",
     "repeats = 0; expected an integer >= 1"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\nrepeats = true\n", "study.repeats",
     "repeats = True; expected an integer >= 1"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\nseed = -1\n", "study.seed",
     "seed = -1; expected an integer >= 0"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\nseed = 1.5\n", "study.seed",
     "seed = 1.5; expected an integer >= 0"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\nseed_key = 'particles.seed'\n",
     "study.seed_key", "seed_key = 'particles.seed'; a dotted scene key, only with scene"),
    ("[study]\nscene = 'base.toml'\nseed_key = 3\n", "study.seed_key",
     "seed_key = 3; a dotted scene key, only with scene"),
    ("parameters = 3\n[study]\nrunner = 'mylab:run'\nquantities = ['y']\n", "parameters",
     "[parameters] must be a table"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\ny = [1.0]\n",
     "parameters.y", "parameter name 'y' clashes with a table column"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\nstatus = [1.0]\n",
     "parameters.status", "parameter name 'status' clashes with a table column"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\ncombine = 'zip'\n[parameters]\n"
     "x = [1, 2]\na = [1]\n", "study.combine",
     "combine = 'zip' needs lists of one length; got {'x': 2, 'a': 1}"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\nx = []\n",
     "parameters.x", "[]; expected a non-empty list of numbers or strings"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\nx = [[1]]\n",
     "parameters.x", "[[1]]; expected a non-empty list of numbers or strings"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\nx = 3\n",
     "parameters.x", "3; expected a list, { range = [lo, hi, n] } or "
                     "{ random = [lo, hi], n = N, seed = S }"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\nx = { ranges = 1 }\n",
     "parameters.x", "{'ranges': 1}; expected a list, { range = [lo, hi, n] } or "
                     "{ random = [lo, hi], n = N, seed = S }"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { range = [0, 1, 2], n = 3 }\n", "parameters.x", "unknown keys ['n'] beside range"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { range = [0, 1, 0] }\n", "parameters.x",
     "range = [0, 1, 0]; expected [lo, hi, n] with n an integer >= 1"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { range = [0, 1] }\n", "parameters.x",
     "range = [0, 1]; expected [lo, hi, n] with n an integer >= 1"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { range = [0, nan, 2] }\n", "parameters.x",
     "range = [0, nan, 2]; expected [lo, hi, n] with n an integer >= 1"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { range = [true, 1, 2] }\n", "parameters.x",
     "range = [True, 1, 2]; expected [lo, hi, n] with n an integer >= 1"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { random = [0, 1], n = 2, s = 1 }\n", "parameters.x",
     "unknown keys ['s'] beside random"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { random = [2, 1], n = 2 }\n", "parameters.x",
     "random = [2, 1]; expected [lo, hi] with lo <= hi"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { random = [1, 2, 3], n = 2 }\n", "parameters.x",
     "random = [1, 2, 3]; expected [lo, hi] with lo <= hi"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { random = [1, 2] }\n", "parameters.x", "n = None; expected an integer >= 1"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { random = [1, 2], n = 2, seed = -3 }\n", "parameters.x",
     "seed = -3; expected an integer >= 0"),
    ("[study]\nrunner = 'mylab:run'\nquantities = ['y']\n[parameters]\n"
     "x = { random = [1, 2], n = 2, seed = false }\n", "parameters.x",
     "seed = False; expected an integer >= 0"),
]


@pytest.mark.parametrize("body, key, message", BAD)
def test_a_bad_study_file_names_the_key(tmp_path, body, key, message):
    (tmp_path / "base.toml").write_text("")
    path = _study(tmp_path, body)
    with pytest.raises(InputError) as error:
        load_study(path)
    assert (error.value.file, error.value.key, error.value.reason) == (path, key, message)


def test_missing_files_are_named(tmp_path):
    with pytest.raises(InputError) as error:
        load_study(tmp_path / "none.toml")
    assert str(error.value) == f"{tmp_path / 'none.toml'}: study file not found"
    path = _study(tmp_path, "[study]\nscene = 'gone.toml'\n")
    with pytest.raises(InputError) as error:
        load_study(path)
    assert (error.value.file, error.value.key, error.value.reason) == (
        path, "study.scene", f"scene file {str(tmp_path / 'gone.toml')!r} not found")
    path.write_text("[study\n")
    with pytest.raises(InputError) as error:
        load_study(path)
    assert error.value.file == path and error.value.reason.startswith("not valid TOML (")


# ---------------------------------------------------------------- the cases

def test_cases_vary_the_last_parameter_fastest_and_repeats_innermost(tmp_path):
    study = load_study(_study(tmp_path, SWEEP))
    every = cases(study)
    assert [c["case"] for c in every] == [f"{k:05d}" for k in range(12)]
    assert [(c["params"]["x"], c["params"]["a"]) for c in every[:6]] == [
        (0.5, 1.0), (0.5, 1.0), (0.5, 2.0), (0.5, 2.0), (1.5, 1.0), (1.5, 1.0)]
    # each case's seed from (study seed, case number): the same whatever the parameters
    seeds = [c["seed"] for c in every]
    assert len(set(seeds)) == 12 and all(isinstance(s, int) for s in seeds)
    assert seeds == [int(np.random.SeedSequence([11, k]).generate_state(1)[0])
                     for k in range(12)]
    zipped = Study(path=study.path, scene=None, runner="mylab:run", quantities=("y",),
                   parameters={"x": (1.0, 2.0), "a": (3.0, 4.0)}, combine="zip", seed=11)
    assert [c["params"] for c in cases(zipped)] == [{"x": 1.0, "a": 3.0},
                                                     {"x": 2.0, "a": 4.0}]
    assert [c["seed"] for c in cases(zipped)] == seeds[:2]


def test_case_ids_widen_past_a_hundred_thousand(tmp_path):
    big = Study(path=tmp_path / "s.toml", scene=None, runner="m:f", quantities=("y",),
                parameters={"x": (1.0,)}, repeats=100_001)
    every = cases(big)
    assert every[0]["case"] == "000000" and every[-1]["case"] == "100000"
    exact = Study(path=tmp_path / "s.toml", scene=None, runner="m:f", quantities=("y",),
                  parameters={"x": (1.0,)}, repeats=100_000)
    assert cases(exact)[-1]["case"] == "99999"


# ---------------------------------------------------------------- one case

def test_a_case_is_its_runners_quantities_as_numbers(tmp_path, monkeypatch):
    study = load_study(_study(tmp_path, SWEEP))
    case = cases(study)[3]                       # x 0.5, a 2.0
    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)
    threads = []
    monkeypatch.setattr(numba, "set_num_threads", threads.append)
    row = run_case(study, case, tmp_path / "out")
    assert threads == [1, 2]                     # one thread for the case, then restored
    assert (tmp_path / "out" / "cases" / "00003" / "ran.txt").read_text() == \
        str(case["seed"])
    assert run_case(study, case, tmp_path / "out")["y"] == 2.0    # its folder there already
    assert (tmp_path / "out" / "cases" / "00003").is_dir()
    assert row["y"] == 2.0 and isinstance(row["y"], float)
    assert row["label"] == f"ok{case['seed'] % 2}" and "extra" not in row
    assert (row["case"], row["seed"], row["x"], row["a"], row["status"]) == \
        ("00003", case["seed"], 0.5, 2.0, "ok")
    assert 0.0 <= row["wall_time"] < 60.0
    partial = load_study(_study(tmp_path, SWEEP.replace("mylab:run", "mylab:partial")))
    with pytest.raises(KeyError) as error:
        run_case(partial, cases(partial)[0], tmp_path / "out")
    assert error.value.args[0] == \
        "runner mylab:partial returned no ['label'] for case 00000"


def test_a_runner_that_cannot_be_imported_is_named(tmp_path):
    study = load_study(_study(tmp_path, SWEEP.replace("mylab:run", "mylab:gone")))
    with pytest.raises(InputError) as error:
        resolve_runner(study)
    assert (error.value.file, error.value.key) == (study.path, "study.runner")
    assert error.value.reason.startswith("runner 'mylab:gone' cannot be imported (")
    with pytest.raises(InputError):
        run_study(study, scheduler="serial", progress=False)


# ---------------------------------------------------------------- the table

def test_the_table_text_and_its_numbers_read_back(tmp_path):
    table = Table(tmp_path / "t" / "u" / "table.csv", ("case", "seed", "x", "name", "status"))
    table.open(resume=False)
    assert table.path.read_text() == "case,seed,x,name,status\n"
    assert not (tmp_path / "t" / "u" / "table.tmp").exists()
    table.append({"case": "00001", "seed": np.int64(12), "x": 1 / 3, "name": "a,b",
                  "status": "ok"})
    table.append({"case": "00000", "seed": 7, "x": np.float32(0.25), "name": "0123",
                  "status": "ok"})
    table.append({"case": "00001", "seed": 12, "x": -2.0, "name": "-5", "status": "ok"})
    table.append({"case": "00003", "seed": 1, "x": 0.5, "status": "ok"})    # no name
    assert table.path.read_text().splitlines()[-1] == "00003,1,0.5,,ok"
    assert table.path.read_text().splitlines()[1] == '00001,12,0.3333333333333333,"a,b",ok'
    rows = table.rows()[:2]
    assert rows == [{"case": "00000", "seed": 7, "x": 0.25, "name": 123.0, "status": "ok"},
                    {"case": "00001", "seed": 12, "x": -2.0, "name": -5, "status": "ok"}]
    assert isinstance(rows[1]["name"], int) and isinstance(rows[0]["name"], float)
    columns = table_columns(table.path)
    assert columns["x"].dtype == np.float64
    assert list(columns["case"]) == ["00000", "00001", "00003"]
    assert columns["status"].dtype == object and list(columns["status"]) == ["ok"] * 3
    assert columns["name"].dtype == object and list(columns["name"]) == [123.0, -5, ""]
    # a row cut by a crash: not read, and cut off when the table is opened to resume
    with open(table.path, "a") as handle:
        handle.write("00002,5,1.0")
    assert [r["case"] for r in read_table(table.path)] == ["00000", "00001", "00003"]
    whole = table.path.read_text()
    table.open(resume=True)
    assert table.path.read_text() == whole[:whole.rindex("\n") + 1]
    table.open(resume=False)
    assert table.path.read_text() == "case,seed,x,name,status\n"
    assert read_table(table.path) == [] and table_columns(table.path) == {}
    (tmp_path / "empty.csv").write_text("")
    assert read_table(tmp_path / "empty.csv") == []


def test_another_studys_table_is_refused(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text("case,seed,z\n00000,1,2.0\n")
    with pytest.raises(InputError) as error:
        Table(path, ("case", "seed", "x")).open(resume=True)
    assert str(error.value) == (f"{path}: existing table has columns ['case,seed,z'], the "
                                "study has ['case', 'seed', 'x']; use another --out")
    one = tmp_path / "one.csv"
    one.write_text("case,seed,x\n00000,1,2.5\n")
    assert {k: v.tolist() for k, v in table_columns(one).items()} == \
        {"case": ["00000"], "seed": [1.0], "x": [2.5]}


# ---------------------------------------------------------------- a whole study

def test_a_serial_study_and_its_resume(tmp_path):
    path = _study(tmp_path, SWEEP)
    table = run_study(path, scheduler="serial", progress=False)
    assert table == (tmp_path / "sweep" / "table.csv").resolve()
    rows = read_table(table)
    assert [r["case"] for r in rows] == [f"{k:05d}" for k in range(12)]
    failed = [r for r in rows if r["x"] == -1.0]
    assert [r["seed"] for r in failed] == [c["seed"] for c in cases(load_study(path))[8:]]
    assert len(failed) == 4 and all(
        r["status"] == "error: ValueError: x below zero second line" for r in failed)
    assert all(math.isnan(r["y"]) and math.isnan(r["wall_time"]) for r in failed)
    assert [r["y"] for r in rows if r["status"] == "ok"] == \
        [1.5, 1.5, 2.0, 2.0, 2.5, 2.5, 4.0, 4.0]
    # resumed: only the failed cases run again, appended after the others
    text = table.read_text()
    assert [c["case"] for c in pending_cases(load_study(path), table)] == \
        ["00008", "00009", "00010", "00011"]
    run_study(path, scheduler="serial", progress=False, resume=True)
    assert table.read_text().startswith(text)
    assert len(table.read_text().splitlines()) == 1 + 12 + 4
    # nothing left to run: the table stays as it is
    done = Study(**{**load_study(path).__dict__,
                    "parameters": {"x": (0.5, 1.5), "a": (1.0, 2.0)}})
    before = table.read_text()
    assert run_study(done, scheduler="serial", progress=False, resume=True,
                     out_dir=tmp_path / "sweep") == table
    assert table.read_text() == before
    # run afresh (no resume): the table again, every case run once more
    run_study(path, scheduler="serial", progress=False)
    assert len(table.read_text().splitlines()) == 13
    assert [r["case"] for r in read_table(table)] == [f"{k:05d}" for k in range(12)]
    assert pending_cases(load_study(path), tmp_path / "none.csv") == cases(load_study(path))
    with pytest.raises(InputError) as error:
        run_study(path, scheduler="serial", workers=0, progress=False)
    assert (error.value.key, error.value.reason) == (
        "--workers", "workers = 0; expected an integer >= 1")


def test_a_changed_study_is_refused_on_resume(tmp_path):
    path = _study(tmp_path, SWEEP)
    run_study(path, scheduler="serial", progress=False, out_dir=tmp_path / "out")
    path.write_text(SWEEP.replace("x = [0.5, 1.5, -1.0]", "x = [0.75, 1.5, -1.0]"))
    with pytest.raises(InputError) as error:
        run_study(path, scheduler="serial", progress=False, out_dir=tmp_path / "out",
                  resume=True)
    assert (error.value.file, error.value.key, error.value.reason) == (
        tmp_path / "out" / "table.csv", "x",
        "case 00000 in the table has x = 0.5, the study gives 0.75: the study changed; "
        "use another --out")


class _Future:
    def __init__(self, function, args):
        self.released = False
        try:
            self.value, self.error = function(*args), None
        except Exception as error:      # noqa: BLE001 - kept for result()
            self.value, self.error = None, error

    def result(self):
        if self.error is not None:
            raise self.error
        return self.value

    def release(self):
        self.released = True


class _Client:
    """Stands in for a Dask client: runs each submitted case at once."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs, self.submitted, self.closed = args, kwargs, [], False

    def submit(self, function, *args, **kwargs):
        self.submitted.append((function, args, kwargs))
        future = _Future(function, args)
        self.futures = getattr(self, "futures", []) + [future]
        return future

    def close(self):
        self.closed = True


@pytest.fixture
def fake_dask(monkeypatch):
    import distributed
    made = {"clusters": [], "clients": []}

    class Cluster(_Client):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made["clusters"].append(self)

    class Client(_Client):
        def __init__(self, *args, **kwargs):
            if args and args[0] == "tcp://nowhere:1":
                raise OSError("Timed out")
            super().__init__(*args, **kwargs)
            made["clients"].append(self)

    monkeypatch.setattr(distributed, "LocalCluster", Cluster)
    monkeypatch.setattr(distributed, "Client", Client)
    monkeypatch.setattr(distributed, "as_completed", lambda futures: list(futures)[::-1])
    return made


def test_a_study_on_dask_gives_the_serial_table(tmp_path, fake_dask):
    path = _study(tmp_path, SWEEP)
    serial = read_table(run_study(path, scheduler="serial", progress=False,
                                  out_dir=tmp_path / "serial"))
    table = run_study(path, workers=3, progress=False, out_dir=tmp_path / "dask")
    rows = read_table(table)

    def same(r):                                 # NaN quantities compared as text
        return repr({k: v for k, v in r.items() if k != "wall_time"})

    assert [same(r) for r in rows] == [same(r) for r in serial]
    (cluster,), (client,) = fake_dask["clusters"], fake_dask["clients"]
    assert cluster.kwargs == {"n_workers": 3, "threads_per_worker": 1, "processes": True,
                              "dashboard_address": None,
                              "env": {"OMP_NUM_THREADS": "1"}}
    assert client.args == (cluster,) and cluster.closed and client.closed
    function, args, kwargs = client.submitted[0]
    assert function is study_module._run_case_task
    assert args == (load_study(path), cases(load_study(path))[0], str(tmp_path / "dask"))
    assert kwargs["retries"] == 2 and kwargs["pure"] is False
    assert kwargs["key"].startswith("bondem-case-sweep-00000-")
    keys = [k["key"] for _, _, k in client.submitted]
    assert len(set(keys)) == 12
    assert all(f.released for f in client.futures)


def test_dask_defaults_addresses_and_a_given_client(tmp_path, fake_dask, monkeypatch):
    import os
    path = _study(tmp_path, SWEEP)
    monkeypatch.setattr(os, "cpu_count", lambda: 6)
    run_study(path, progress=False, out_dir=tmp_path / "a", retries=5)
    assert fake_dask["clusters"][0].kwargs["n_workers"] == 6
    assert fake_dask["clients"][0].submitted[0][2]["retries"] == 5
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    run_study(path, progress=False, out_dir=tmp_path / "b")
    assert fake_dask["clusters"][1].kwargs["n_workers"] == 1
    run_study(path, scheduler="tcp://there:8786", progress=False, out_dir=tmp_path / "c")
    client = fake_dask["clients"][2]
    assert client.args == ("tcp://there:8786",) and client.kwargs == {"timeout": "30s"}
    assert client.closed and len(fake_dask["clusters"]) == 2
    mine = _Client()
    run_study(path, scheduler=mine, progress=False, out_dir=tmp_path / "d")
    assert len(mine.submitted) == 12 and mine.closed is False
    with pytest.raises(InputError) as error:
        run_study(path, scheduler="tcp://nowhere:1", progress=False, out_dir=tmp_path / "e")
    assert (error.value.key, error.value.reason) == (
        "--scheduler", "cannot reach the Dask scheduler 'tcp://nowhere:1' (Timed out)")


def test_a_case_that_fails_on_dask_is_recorded(tmp_path, fake_dask, monkeypatch):
    path = _study(tmp_path, SWEEP)

    def dies(study, case, out_dir):
        raise RuntimeError("worker died " + "x" * 400)

    monkeypatch.setattr(study_module, "_run_case_task", dies)
    rows = read_table(run_study(path, progress=False, out_dir=tmp_path / "out"))
    assert len(rows) == 12
    message = rows[0]["status"]
    assert message.startswith("error: RuntimeError: worker died xxx") and len(message) == 300


# ---------------------------------------------------------------- the scene runner

def test_the_scene_runner_applies_the_case_and_retries_from_a_checkpoint(tmp_path,
                                                                          monkeypatch):
    import bondem.runner
    import bondem.scene
    loaded, runs = [], []
    monkeypatch.setattr(bondem.scene, "load_scene",
                        lambda path, overrides=None: loaded.append((path, overrides))
                        or f"scene{len(loaded)}")

    def run_scene(scene, case_dir, progress=True, resume=False, overwrite=False):
        runs.append((scene, Path(case_dir), progress, resume, overwrite))
        if resume and "refused" in str(case_dir):
            raise InputError("another scene's checkpoint")
        return "results.h5"

    monkeypatch.setattr(bondem.runner, "run_scene", run_scene)
    monkeypatch.setattr(study_module, "scene_quantities",
                        lambda results, quantities: {"from": results, "asked": quantities})
    (tmp_path / "base.toml").write_text("")
    study = load_study(_study(tmp_path, """\
        [study]
        scene = "base.toml"
        seed_key = "particles.seed"
        quantities = ["peak_wall_force"]
        [parameters]
        "simulation.end_time" = [1e-3]
        """))
    runner = resolve_runner(study)
    out = runner({"simulation.end_time": 1e-3}, tmp_path / "fresh", 77)
    assert out == {"from": "results.h5", "asked": ("peak_wall_force",)}
    assert loaded == [((tmp_path / "base.toml").resolve(),
                       {"simulation.end_time": 1e-3, "particles.seed": 77})]
    assert runs == [("scene1", tmp_path / "fresh", False, False, True)]
    for name, expected in (("kept", [(True, False)]),
                           ("refused", [(True, False), (False, True)])):
        (tmp_path / name).mkdir()
        (tmp_path / name / "checkpoint.npz").write_bytes(b"")
        runs.clear()
        runner({}, tmp_path / name, 1)
        assert [(r[3], r[4]) for r in runs] == expected
        assert all(r[:3] == (f"scene{len(loaded)}", tmp_path / name, False) for r in runs)
    unseeded = resolve_runner(Study(**{**study.__dict__, "seed_key": None}))
    loaded.clear()
    unseeded({"a": 1}, tmp_path / "fresh", 5)
    assert loaded[0][1] == {"a": 1}


def test_scene_quantities_from_a_results_file(tmp_path, monkeypatch):
    import h5py

    import bondem.analysis.breakage
    import bondem.analysis.fragments
    path = tmp_path / "results.h5"
    monkeypatch.setattr(bondem.analysis.breakage, "broken_bond_fraction",
                        lambda r: 0.25 if r == path else math.nan)
    monkeypatch.setattr(bondem.analysis.fragments, "largest_fragment_fraction",
                        lambda r: np.float32(0.5) if r == path else math.nan)
    with h5py.File(path, "w") as handle:
        handle["walls/force"] = np.array([[[3.0, 4.0, 0.0], [0.0, 0.0, -2.0]],
                                          [[0.0, -6.0, 8.0], [1.0, 0.0, 0.0]]])
    every = scene_quantities(path)
    assert every == {"broken_bond_fraction": 0.25, "largest_fragment_fraction": 0.5,
                     "peak_wall_force": 10.0}
    assert all(type(v) is float for v in every.values())
    assert scene_quantities(path, ("peak_wall_force",)) == {"peak_wall_force": 10.0}
    with h5py.File(tmp_path / "none.h5", "w") as handle:
        handle["time"] = np.zeros(2)
    assert scene_quantities(tmp_path / "none.h5", ("peak_wall_force",)) == \
        {"peak_wall_force": 0.0}


def test_a_runner_module_next_to_the_study_file(tmp_path, monkeypatch):
    import sys
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.setattr(sys, "modules", dict(sys.modules))
    study = load_study(_study(tmp_path, SWEEP.replace("mylab:run", "ownlab:run"), "ownlab"))
    function = resolve_runner(study)
    assert function.__module__ == "ownlab" and sys.path[0] == str(tmp_path.resolve())
    resolve_runner(study)
    assert sys.path.count(str(tmp_path.resolve())) == 1


def test_a_scene_runner_missing_a_quantity_is_named(tmp_path, monkeypatch):
    (tmp_path / "base.toml").write_text("")
    study = load_study(_study(tmp_path, "[study]\nscene = 'base.toml'\n"))
    monkeypatch.setattr(study_module._SceneRunner, "__call__",
                        lambda self, params, case_dir, seed: {"peak_wall_force": 1.0})
    with pytest.raises(KeyError) as error:
        run_case(study, cases(study)[0], tmp_path / "out")
    assert error.value.args[0] == ("runner scene returned no ['broken_bond_fraction', "
                                   "'largest_fragment_fraction'] for case 00000")
    assert load_study(_study(tmp_path, "[study]\nscene = 'base.toml'\n")).parameters == {}


def test_the_progress_bar_counts_cases(tmp_path, capsys, fake_dask):
    path = _study(tmp_path, SWEEP)
    run_study(path, scheduler="serial", out_dir=tmp_path / "a")
    err = capsys.readouterr().err
    assert "study: 100%" in err and "12/12" in err and ("case/s" in err or "s/case" in err)
    run_study(path, scheduler="serial", progress=False, out_dir=tmp_path / "b")
    assert capsys.readouterr().err == ""
    run_study(path, workers=1, out_dir=tmp_path / "c")
    err = capsys.readouterr().err
    assert "study: 100%" in err and "12/12" in err
    assert fake_dask["clusters"][0].kwargs["n_workers"] == 1

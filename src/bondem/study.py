"""Ensemble studies (parameter sweeps) run as Dask tasks, collected into one durable table.

A study file (TOML)::

    [study]
    scene = "base.toml"            # base scene, relative to the study file ...
    # runner = "package.module:function"   # ... or a runner: f(params, case_dir, seed) -> dict
    quantities = ["broken_bond_fraction", "largest_fragment_fraction", "peak_wall_force"]
    combine = "product"            # "product" (every combination) | "zip" (same lengths)
    repeats = 1                    # runs per parameter combination (different seeds)
    seed = 0                       # base seed; case k gets its own seed from (seed, k)
    # seed_key = "particles.seed"  # scene key that receives each case's seed (scene runner)

    [parameters]
    "simulation.end_time" = [1e-3, 2e-3]                  # a list
    "walls.0.velocity.2" = { range = [-10.0, -1.0, 10] }   # linspace(lo, hi, n)
    "bond_materials.binder.normal_strength" = { random = [1e5, 1e6], n = 50, seed = 1 }

Cases are numbered in a fixed order (the parameters in file order, the last varying
fastest, repeats innermost), so case ids and seeds are the same on every run. The default
runner applies a case's parameters as overrides to the base scene
(``bondem.scene.load_scene(path, overrides=...)``), runs it (``bondem.runner.run_scene``)
into its own folder and computes the quantities from its results.h5.

``run_study`` submits every case to Dask (a LocalCluster of single-threaded worker
processes by default, or any scheduler address), with retries, and appends one row per
finished case to ``table.csv``: each row is one write to a file opened for appending,
flushed and fsync'ed, so a study killed at any moment keeps every finished case, and
``resume=True`` runs only the cases missing from the table.
"""
from __future__ import annotations

import csv
import importlib
import io
import itertools
import math
import os
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError, unknown_key

STUDY_KEYS = {"scene", "runner", "quantities", "combine", "repeats", "seed", "seed_key"}
DEFAULT_QUANTITIES = ("broken_bond_fraction", "largest_fragment_fraction", "peak_wall_force")
KNOWN_SCENE_QUANTITIES = set(DEFAULT_QUANTITIES)
TABLE_NAME = "table.csv"
FIXED_COLUMNS = ("case", "seed")
TAIL_COLUMNS = ("status", "wall_time")


@dataclass(frozen=True)
class Study:
    """A parsed, validated study file.

    path: the study file; scene: base scene path or None; runner: "module:function" or
    None (then the scene runner); quantities: names collected per case; parameters:
    {dotted key: tuple of values}; combine: "product" | "zip"; repeats: runs per
    combination; seed: base seed; seed_key: scene key set to each case's seed, or None.
    """
    path: Path
    scene: Path | None
    runner: str | None
    quantities: tuple
    parameters: dict = field(default_factory=dict)
    combine: str = "product"
    repeats: int = 1
    seed: int = 0
    seed_key: str | None = None

    @property
    def columns(self) -> tuple:
        """Columns of the study's table, in order."""
        return (*FIXED_COLUMNS, *self.parameters, *self.quantities, *TAIL_COLUMNS)


def load_study(path) -> Study:
    """Read and validate a study file (TOML). Raises InputError naming the file and key."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise InputError("study file not found", file=path) from None
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"not valid TOML ({error})", file=path) from None
    unknown = set(data) - {"study", "parameters"}
    if unknown:
        raise InputError(f"unknown section(s) {sorted(unknown)}; allowed: [study], "
                         "[parameters]", file=path, key=sorted(unknown)[0])
    section = data.get("study")
    if not isinstance(section, dict):
        raise InputError("missing [study] section", file=path, key="study")
    for key in section:
        if key not in STUDY_KEYS:
            raise InputError(unknown_key(key, sorted(STUDY_KEYS)), file=path,
                             key=f"study.{key}")

    scene = section.get("scene")
    runner = section.get("runner")
    if (scene is None) == (runner is None):
        raise InputError("give exactly one of scene (a base scene file) or runner "
                         "('package.module:function')", file=path, key="study.scene")
    if scene is not None:
        if not isinstance(scene, str):
            raise InputError(f"scene = {scene!r}; expected a file name", file=path,
                             key="study.scene")
        scene = (path.parent / scene).resolve()
        if not scene.is_file():
            raise InputError(f"scene file {str(scene)!r} not found", file=path,
                             key="study.scene")
    if runner is not None and not (isinstance(runner, str) and runner.count(":") == 1
                                   and all(runner.split(":"))):
        raise InputError(f"runner = {runner!r}; expected 'package.module:function'",
                         file=path, key="study.runner")

    quantities = section.get("quantities", list(DEFAULT_QUANTITIES) if scene else None)
    if (not isinstance(quantities, list) or not quantities
            or not all(isinstance(q, str) and q for q in quantities)
            or len(set(quantities)) != len(quantities)):
        raise InputError(f"quantities = {quantities!r}; expected a non-empty list of distinct "
                         "names", file=path, key="study.quantities")
    if scene is not None:
        for q in quantities:
            if q not in KNOWN_SCENE_QUANTITIES:
                raise InputError(f"quantity {q!r} unknown to the scene runner; allowed: "
                                 + ", ".join(sorted(KNOWN_SCENE_QUANTITIES)), file=path,
                                 key="study.quantities")

    combine = section.get("combine", "product")
    if combine not in ("product", "zip"):
        raise InputError(f"combine = {combine!r}; allowed: 'product', 'zip'", file=path,
                         key="study.combine")
    repeats = section.get("repeats", 1)
    if not (isinstance(repeats, int) and not isinstance(repeats, bool) and repeats >= 1):
        raise InputError(f"repeats = {repeats!r}; expected an integer >= 1", file=path,
                         key="study.repeats")
    seed = section.get("seed", 0)
    if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
        raise InputError(f"seed = {seed!r}; expected an integer >= 0", file=path,
                         key="study.seed")
    seed_key = section.get("seed_key")
    if seed_key is not None and (runner is not None or not isinstance(seed_key, str)):
        raise InputError(f"seed_key = {seed_key!r}; a dotted scene key, only with scene",
                         file=path, key="study.seed_key")

    raw = data.get("parameters", {})
    if not isinstance(raw, dict):
        raise InputError("[parameters] must be a table", file=path, key="parameters")
    parameters = {name: _parameter_values(path, name, spec) for name, spec in raw.items()}
    reserved = set(FIXED_COLUMNS) | set(TAIL_COLUMNS) | set(quantities)
    for name in parameters:
        if name in reserved:
            raise InputError(f"parameter name {name!r} clashes with a table column",
                             file=path, key=f"parameters.{name}")
    if combine == "zip" and len({len(v) for v in parameters.values()}) > 1:
        lengths = {k: len(v) for k, v in parameters.items()}
        raise InputError(f"combine = 'zip' needs lists of one length; got {lengths}",
                         file=path, key="study.combine")
    return Study(path=path.resolve(), scene=scene, runner=runner, quantities=tuple(quantities),
                 parameters=parameters, combine=combine, repeats=repeats, seed=seed,
                 seed_key=seed_key)


def _parameter_values(path, name, spec):
    key = f"parameters.{name}"
    scalar = (int, float, str, bool)
    if isinstance(spec, list):
        if not spec or not all(isinstance(v, scalar) for v in spec):
            raise InputError(f"{spec!r}; expected a non-empty list of numbers or strings",
                             file=path, key=key)
        return tuple(spec)
    if not isinstance(spec, dict):
        raise InputError(f"{spec!r}; expected a list, {{ range = [lo, hi, n] }} or "
                         "{ random = [lo, hi], n = N, seed = S }", file=path, key=key)
    if "range" in spec:
        if set(spec) != {"range"}:
            raise InputError(f"unknown keys {sorted(set(spec) - {'range'})} beside range",
                             file=path, key=key)
        value = spec["range"]
        if not (isinstance(value, list) and len(value) == 3
                and all(_is_number(v) for v in value[:2]) and _is_count(value[2])):
            raise InputError(f"range = {value!r}; expected [lo, hi, n] with n an integer "
                             ">= 1", file=path, key=key)
        return tuple(float(v) for v in np.linspace(value[0], value[1], value[2]))
    if "random" in spec:
        extra = set(spec) - {"random", "n", "seed"}
        if extra:
            raise InputError(f"unknown keys {sorted(extra)} beside random", file=path, key=key)
        bounds, n, seed = spec["random"], spec.get("n"), spec.get("seed", 0)
        if not (isinstance(bounds, list) and len(bounds) == 2
                and all(_is_number(v) for v in bounds) and bounds[0] <= bounds[1]):
            raise InputError(f"random = {bounds!r}; expected [lo, hi] with lo <= hi",
                             file=path, key=key)
        if not _is_count(n):
            raise InputError(f"n = {n!r}; expected an integer >= 1", file=path, key=key)
        if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
            raise InputError(f"seed = {seed!r}; expected an integer >= 0", file=path, key=key)
        rng = np.random.default_rng(seed)
        return tuple(float(v) for v in rng.uniform(bounds[0], bounds[1], n))
    raise InputError(f"{spec!r}; expected a list, {{ range = [lo, hi, n] }} or "
                     "{ random = [lo, hi], n = N, seed = S }", file=path, key=key)


def _is_number(value):
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _is_count(value):
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1


def cases(study: Study) -> list:
    """Every case of a study, in a fixed order: dicts with ``case`` (id "00000", ...),
    ``seed`` (int, from the study seed and the case number) and ``params`` ({key: value})."""
    names = list(study.parameters)
    values = [study.parameters[n] for n in names]
    combos = list(itertools.product(*values) if study.combine == "product" else zip(*values))
    out = []
    width = max(5, len(str(len(combos) * study.repeats - 1)))
    for number, (combo, _) in enumerate(itertools.product(combos, range(study.repeats))):
        seed = int(np.random.SeedSequence([study.seed, number]).generate_state(1)[0])
        out.append({"case": f"{number:0{width}d}", "seed": seed,
                    "params": dict(zip(names, combo))})
    return out


# --- running one case -----------------------------------------------------------------------

def resolve_runner(study: Study):
    """The case function f(params, case_dir, seed) -> dict of a study.

    A named runner is imported as ``module:function``, looking first in the study file's
    folder (so a runner module can sit next to the study file)."""
    if study.runner is None:
        return _SceneRunner(study.scene, study.quantities, study.seed_key)
    module_name, function_name = study.runner.split(":")
    folder = str(study.path.parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    try:
        module = importlib.import_module(module_name)
        return getattr(module, function_name)
    except (ImportError, AttributeError) as error:
        raise InputError(f"runner {study.runner!r} cannot be imported ({error})",
                         file=study.path, key="study.runner") from None


class _SceneRunner:
    """Default case function: the base scene with the case's overrides, run to results.h5.

    Imported lazily: bondem.scene, bondem.runner and bondem.analysis.* are separate parts."""

    def __init__(self, scene, quantities, seed_key):
        self.scene, self.quantities, self.seed_key = scene, quantities, seed_key

    def __call__(self, params, case_dir, seed):
        from .runner import run_scene
        from .scene import load_scene

        overrides = dict(params)
        if self.seed_key:
            overrides[self.seed_key] = seed
        scene = load_scene(self.scene, overrides=overrides)
        results = None
        if (Path(case_dir) / "checkpoint.npz").is_file():
            # A retry after a worker died: continue from the case's last checkpoint; a
            # checkpoint of another scene text is refused by run_scene, then start afresh.
            try:
                results = run_scene(scene, case_dir, progress=False, resume=True)
            except InputError:
                results = None
        if results is None:
            results = run_scene(scene, case_dir, progress=False, overwrite=True)
        return scene_quantities(results, self.quantities)


def scene_quantities(results, quantities=DEFAULT_QUANTITIES) -> dict:
    """Quantities of one results.h5: broken_bond_fraction and largest_fragment_fraction
    (from bondem.analysis) and peak_wall_force (N, the largest |force| on any wall in any
    saved frame, from /walls/force; 0 without walls)."""
    out = {}
    if "broken_bond_fraction" in quantities:
        from .analysis.breakage import broken_bond_fraction
        out["broken_bond_fraction"] = float(broken_bond_fraction(results))
    if "largest_fragment_fraction" in quantities:
        from .analysis.fragments import largest_fragment_fraction
        out["largest_fragment_fraction"] = float(largest_fragment_fraction(results))
    if "peak_wall_force" in quantities:
        import h5py
        with h5py.File(results, "r") as handle:
            force = handle["/walls/force"][...] if "/walls/force" in handle else np.zeros(0)
        out["peak_wall_force"] = float(np.linalg.norm(force, axis=-1).max()) if force.size else 0.0
    return out


def run_case(study: Study, case: dict, out_dir) -> dict:
    """Run one case in this process, single-threaded; returns its table row (a dict).

    The case's folder is out_dir/cases/<id>. The runner's result must contain every
    quantity of the study (extra entries are dropped); numbers are stored as floats."""
    from .parallel import single_threaded

    runner = resolve_runner(study)
    case_dir = Path(out_dir) / "cases" / case["case"]
    case_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    # cores are used by cases, not threads (the caller's setting is restored after)
    result = single_threaded(runner, dict(case["params"]), case_dir, case["seed"])
    wall = time.perf_counter() - start
    missing = [q for q in study.quantities if q not in result]
    if missing:
        raise KeyError(f"runner {study.runner or 'scene'} returned no {missing} for case "
                       f"{case['case']}")
    row = {"case": case["case"], "seed": case["seed"], **case["params"]}
    row.update({q: _number(result[q]) for q in study.quantities})
    row.update(status="ok", wall_time=wall)
    return row


def _number(value):
    try:
        return float(value)
    except (TypeError, ValueError):
        return str(value)


# --- the table ------------------------------------------------------------------------------

def _format(value):
    if isinstance(value, (float, np.floating)):
        return repr(float(value))  # round-trips exactly
    if isinstance(value, np.integer):
        return str(int(value))
    return str(value)


def _parse(text):
    try:
        return int(text) if text.lstrip("-").isdigit() and not text.startswith("0") else float(text)
    except ValueError:
        return text


class Table:
    """One CSV row per finished case, each appended with a single write, flushed and
    fsync'ed, so a reader (or a resumed study) never sees half a row except possibly a
    last line cut by a crash, which ``read`` drops and ``open`` truncates."""

    def __init__(self, path, columns):
        self.path = Path(path)
        self.columns = tuple(columns)

    def open(self, *, resume):
        """Create the table (header only), or with resume keep its complete rows."""
        header = self._line(dict(zip(self.columns, self.columns)))
        if resume and self.path.exists():
            text = self.path.read_text()
            if not text.startswith(header):
                raise InputError(f"existing table has columns {text.splitlines()[:1]}, the "
                                 f"study has {list(self.columns)}; use another --out",
                                 file=self.path)
            complete = text[:text.rfind("\n") + 1]
            if complete != text:  # a row cut by a crash
                with open(self.path, "r+") as handle:
                    handle.truncate(len(complete.encode()))
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_suffix(".tmp")
            tmp.write_text(header)
            os.replace(tmp, self.path)

    def _line(self, row):
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow(
            [_format(row.get(c, "")) for c in self.columns])
        return buffer.getvalue()

    def append(self, row):
        """Append one row atomically (one O_APPEND write) and make it durable."""
        data = self._line(row).encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)

    def rows(self):
        return read_table(self.path)


def read_table(path) -> list:
    """Rows of a study table as dicts (numbers parsed), one per case (the last row of a
    case wins), in case order. A last line without its newline (cut by a crash) is
    ignored."""
    text = Path(path).read_text()
    text = text[:text.rfind("\n") + 1]
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader)
    except StopIteration:
        return []
    rows = {}
    for values in reader:
        row = {k: (v if k == "case" else _parse(v)) for k, v in zip(header, values)}
        rows[row["case"]] = row
    return [rows[k] for k in sorted(rows)]


def table_columns(path) -> dict:
    """A study table as {column: numpy array} (float where every entry is a number)."""
    rows = read_table(path)
    if not rows:
        return {}
    out = {}
    for name in rows[0]:
        values = [r[name] for r in rows]
        try:
            out[name] = np.array(values, dtype=np.float64) if name != "case" else np.array(values)
        except (TypeError, ValueError):
            out[name] = np.array(values, dtype=object)
    return out


# --- the study on Dask ----------------------------------------------------------------------

def _run_case_task(study, case, out_dir):
    """Dask task body (module level so that it pickles by reference)."""
    return run_case(study, case, out_dir)


def default_out_dir(study: Study) -> Path:
    """Folder next to the study file, named after it."""
    return study.path.parent / study.path.stem


def run_study(study, *, scheduler=None, workers=None, resume=False, progress=True,
              out_dir=None, retries=2):
    """Run every case of a study on Dask and collect the table; returns its path.

    study: a Study or a study file path; scheduler: None (a LocalCluster of ``workers``
    single-threaded processes, default: the CPU count), a scheduler address
    ("tcp://host:8786"), a distributed.Client, or "serial" (this process, no Dask);
    resume: keep the finished cases of an existing table and run only the missing ones
    (and those that failed); out_dir: folder of table.csv and cases/ (default: next to
    the study file, named after it); retries: per case, for workers that die.
    A case that still fails is recorded with status "error: ..." and NaN quantities.
    """
    if not isinstance(study, Study):
        study = load_study(study)
    if workers is not None and not (isinstance(workers, int) and workers >= 1):
        raise InputError(f"workers = {workers!r}; expected an integer >= 1", key="--workers")
    out_dir = Path(out_dir) if out_dir is not None else default_out_dir(study)
    table = Table(out_dir / TABLE_NAME, study.columns)
    table.open(resume=resume)
    todo = pending_cases(study, table.path) if resume else cases(study)
    resolve_runner(study)  # fail early, here, on a runner that cannot be imported
    if not todo:
        return table.path
    bar = _progress(len(todo), progress)
    try:
        if scheduler == "serial":
            for case in todo:
                table.append(_guarded(run_case, study, case, out_dir))
                bar.update(1)
        else:
            _run_on_dask(study, todo, out_dir, table, bar, scheduler, workers, retries)
    finally:
        bar.close()
    return table.path


def pending_cases(study: Study, table_path) -> list:
    """Cases of the study not yet finished (status "ok") in the table at table_path.
    Raises InputError when a finished row's parameters differ from the study's case."""
    done = {r["case"]: r for r in read_table(table_path)} if Path(table_path).exists() else {}
    todo = []
    for case in cases(study):
        row = done.get(case["case"])
        if row is None or row.get("status") != "ok":
            todo.append(case)
            continue
        expected = {"seed": case["seed"], **case["params"]}
        for key, value in expected.items():
            if _parse(_format(value)) != row.get(key):
                raise InputError(f"case {case['case']} in the table has {key} = "
                                 f"{row.get(key)!r}, the study gives {value!r}: the study "
                                 "changed; use another --out", file=table_path, key=key)
    return todo


def _guarded(function, study, case, out_dir):
    try:
        return function(study, case, out_dir)
    except Exception as error:  # noqa: BLE001 - recorded in the table, the study goes on
        return _error_row(study, case, error)


def _error_row(study, case, error):
    message = f"error: {type(error).__name__}: {error}".replace("\n", " ")[:300]
    row = {"case": case["case"], "seed": case["seed"], **case["params"]}
    row.update({q: math.nan for q in study.quantities})
    row.update(status=message, wall_time=math.nan)
    return row


def _progress(total, enabled):
    from tqdm import tqdm
    return tqdm(total=total, unit="case", desc="study", disable=not enabled, smoothing=0.1)


def _run_on_dask(study, todo, out_dir, table, bar, scheduler, workers, retries):
    from distributed import Client, as_completed

    from .parallel import local_cluster
    cluster = None
    if scheduler is None:
        # one single-threaded process per core (run_case sets Numba's threads to one)
        cluster = local_cluster(workers)
        client = Client(cluster)
    elif isinstance(scheduler, str):
        try:
            client = Client(scheduler, timeout="30s")
        except OSError as error:
            raise InputError(f"cannot reach the Dask scheduler {scheduler!r} ({error})",
                             key="--scheduler") from None
    else:
        client = scheduler
    try:
        futures = {}
        for case in todo:
            future = client.submit(_run_case_task, study, case, str(out_dir), retries=retries,
                                   key=f"bondem-case-{study.path.stem}-{case['case']}-"
                                       f"{time.time_ns()}", pure=False)
            futures[future] = case
        for future in as_completed(futures):
            case = futures[future]
            try:
                row = future.result()
            except Exception as error:  # noqa: BLE001 - a case that failed after retries
                row = _error_row(study, case, error)
            table.append(row)
            bar.update(1)
            future.release()
    finally:
        if cluster is not None or isinstance(scheduler, str):
            client.close()
        if cluster is not None:
            cluster.close()

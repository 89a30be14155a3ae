"""Calibration: bond parameters from the macro properties a user measured.

A calibration file names a lab spec (docs/lab.md), the unknown parameters (any dotted key
of the spec, with bounds), the targets (a lab test's number with its relative
uncertainty) and a budget of simulations. The search is optuna's TPE sampler (seeded, so
the same file gives the same trials), asked for batches of trials that run as a Dask
ensemble. The first trial sits at the middle of the bounds. The second is the scaling rules'
guess from it: macro E is proportional to the bond modulus, and strengths to the bond
strengths at fixed ratios. Every finished trial is a row of ``calibration.csv``. A killed
calibration replays the same sampler over that table and runs only what is missing, so it
ends with the same result.

What is identifiable is reported two ways:
- the spread of the parameter sets consistent with the targets (every target within its
  uncertainty);
- the linearised uncertainty of each parameter at the best set, from finite differences
  of the predictions. A parameter the targets do not constrain gets an uncertainty larger
  than its range.
"""
from __future__ import annotations

import csv
import json
import math
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .analysis.calibration import percent
from .errors import InputError, decode_text, unknown_key
from .parallel import local_cluster, single_threaded

MODULUS_TARGETS = ("young_modulus_secant", "young_modulus_tangent")
STRENGTH_TARGETS = ("ucs", "tensile_strength", "peak_deviator_stress", "breakage_force",
                    "peak_stress", "crack_initiation_stress")


class CalibrationFailed(RuntimeError):
    """The targets cannot be met within the bounds (the message says which and by how
    much)."""


@dataclass
class Parameter:
    """One unknown: ``key`` a dotted lab-spec key, bounds ``low`` < ``high``, ``log``:
    searched on a log scale."""
    key: str
    low: float
    high: float
    log: bool = False

    def unit(self, value):
        """Position of ``value`` in [0, 1] over the bounds (log-scaled if log)."""
        if self.log:
            return (math.log(value) - math.log(self.low)) / (math.log(self.high)
                                                              - math.log(self.low))
        return (value - self.low) / (self.high - self.low)

    def middle(self):
        return math.sqrt(self.low * self.high) if self.log else 0.5 * (self.low + self.high)


@dataclass
class Target:
    """A measured property: ``name`` a number of the lab test ``test`` (see docs/lab.md),
    its ``value`` (SI units) and relative uncertainty ``tolerance``."""
    name: str
    test: str
    value: float
    tolerance: float


@dataclass
class Calibration:
    """A loaded calibration file."""
    path: Path
    spec: Path
    parameters: list
    targets: list
    budget: int = 24
    batch: int = 4
    seed: int = 0
    check_seeds: list = field(default_factory=list)
    text: str = ""
    test_overrides: dict = field(default_factory=dict)   # {test: {spec key: value}}
    rate_check: bool = True   # the best set's tests again at half the strain rate

    @property
    def tests(self):
        return sorted({t.test for t in self.targets})

    @property
    def warnings(self):
        """Messages about a file that is legal but cannot do all it asks (empty: none)."""
        if len(self.targets) >= len(self.parameters):
            return []
        return [f"{len(self.targets)} target(s) for {len(self.parameters)} parameters: at "
                f"most {len(self.targets)} combination(s) of the parameters can be fixed, "
                "and every parameter in a combination the targets leave free is reported "
                "not identifiable; add targets or calibrate fewer parameters"]


PARAMETER_KEYS = ("low", "high", "log")
TARGET_KEYS = ("test", "value", "tolerance")
TOP_KEYS = ("spec", "budget", "batch", "seed", "check_seeds", "rate_check", "parameters",
            "targets", "tests")


def _number(table, key, where, path, positive=True):
    value = table.get(key)
    if not (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value) and (value > 0 if positive else True)):
        raise InputError(f"value {value!r}: expected a {'positive ' if positive else ''}"
                         "number", file=path, key=f"{where}.{key}")
    return float(value)


def load_calibration(path) -> Calibration:
    """Read and check a calibration file (TOML, docs/calibration.md)."""
    from .lab import TESTS
    path = Path(path)
    try:
        text = decode_text(path.read_bytes(), path)
    except OSError as error:
        raise InputError(f"cannot read the calibration file ({error.strerror})", file=path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"not valid TOML: {error}", file=path)
    for key in data:
        if key not in TOP_KEYS:
            raise InputError(unknown_key(key, TOP_KEYS), file=path,
                             key=key)
    if not isinstance(data.get("spec"), str):
        raise InputError("missing: the lab spec file (docs/lab.md)", file=path, key="spec")
    spec = (path.parent / data["spec"]).resolve()
    if not spec.is_file():
        raise InputError(f"value {data['spec']!r}: no such file", file=path, key="spec")
    parameters = []
    for key, table in (data.get("parameters") or {}).items():
        where = f"parameters.{key}"
        if not isinstance(table, dict) or any(k not in PARAMETER_KEYS for k in table):
            raise InputError(f"expected a table of {', '.join(PARAMETER_KEYS)}", file=path,
                             key=where)
        log = bool(table.get("log", False))
        low = _number(table, "low", where, path, positive=log)
        high = _number(table, "high", where, path, positive=log)
        if not high > low:
            raise InputError(f"high {high!r} must exceed low {low!r}", file=path,
                             key=f"{where}.high")
        parameters.append(Parameter(key, low, high, log))
    if not parameters:
        raise InputError("no parameters to calibrate", file=path, key="parameters")
    targets = []
    for name, table in (data.get("targets") or {}).items():
        where = f"targets.{name}"
        if not isinstance(table, dict) or any(k not in TARGET_KEYS for k in table):
            raise InputError(f"expected a table of {', '.join(TARGET_KEYS)}", file=path,
                             key=where)
        if table.get("test") not in TESTS:
            raise InputError(f"value {table.get('test')!r}; allowed: {', '.join(TESTS)}",
                             file=path, key=f"{where}.test")
        value = _number(table, "value", where, path, positive=False)
        tolerance = _number(table, "tolerance", where, path)
        if value == 0.0:
            raise InputError("a target of 0 has no relative uncertainty", file=path,
                             key=f"{where}.value")
        targets.append(Target(name, table["test"], value, tolerance))
    if not targets:
        raise InputError("no targets", file=path, key="targets")
    budget = data.get("budget", 24)
    batch = data.get("batch", 4)
    seed = data.get("seed", 0)
    for key, value, low in (("budget", budget, 3), ("batch", batch, 1), ("seed", seed, 0)):
        if not isinstance(value, int) or isinstance(value, bool) or value < low:
            raise InputError(f"value {value!r}: expected an integer >= {low}", file=path,
                             key=key)
    seeds = data.get("check_seeds", [])
    if not (isinstance(seeds, list) and all(isinstance(s, int) and s >= 0 for s in seeds)):
        raise InputError(f"value {seeds!r}: expected a list of integers >= 0", file=path,
                             key="check_seeds")
    rate_check = data.get("rate_check", True)
    if not isinstance(rate_check, bool):
        raise InputError(f"value {rate_check!r}: expected true or false", file=path,
                         key="rate_check")
    tests = data.get("tests", {})
    if not isinstance(tests, dict) or any(k not in TESTS or not isinstance(v, dict)
                                          for k, v in tests.items()):
        raise InputError(f"expected tables named after tests ({', '.join(TESTS)}) of spec "
                         "keys and values, e.g. [tests.brazilian] with "
                         '"specimen.shape" = "disc"', file=path, key="tests")
    calibration = Calibration(path, spec, parameters, targets, budget, batch, seed, seeds,
                              text, tests, rate_check)
    # the spec must load with every parameter at its middle: the keys exist and are valid
    from .lab.spec import load_spec
    for test in calibration.tests:
        load_spec(spec, {**tests.get(test, {}), **{p.key: p.middle() for p in parameters}})
    return calibration


def evaluate(spec, test, overrides):
    """Run lab ``test`` on the spec with ``overrides`` {key: value}; returns its numbers.
    (A module-level function: what the Dask workers run.)"""
    from .lab import RUNNERS
    from .lab.spec import load_spec
    specimen, settings, _ = load_spec(spec, overrides)
    result = RUNNERS[test](specimen, settings)
    if result.no_failure is not None:
        # its strengths are NaN: the trial failed for a strength target, and says why
        return {**result.numbers, "no_failure": result.no_failure}
    return result.numbers


def misfit(calibration, predictions):
    """Sum over the targets of ((prediction - value) / (tolerance value))^2; inf when a
    prediction is missing or not finite."""
    total = 0.0
    for t in calibration.targets:
        p = predictions.get(t.name)
        if p is None or not math.isfinite(p):
            return math.inf
        total += ((p - t.value) / (t.tolerance * abs(t.value))) ** 2
    return total


def consistent(calibration, predictions):
    """True when every target lies within its uncertainty."""
    return all(t.name in predictions and math.isfinite(predictions[t.name])
               and abs(predictions[t.name] - t.value) <= t.tolerance * abs(t.value)
               for t in calibration.targets)


def scaled_guess(calibration, params, predictions):
    """The scaling rules' guess from one trial: every bond modulus times E_target / E,
    every bond strength times the mean ratio of the strength targets to their
    predictions, clipped to the bounds (other parameters kept)."""
    modulus = [t.value / predictions[t.name] for t in calibration.targets
               if t.name in MODULUS_TARGETS and predictions.get(t.name)]
    strength = [t.value / predictions[t.name] for t in calibration.targets
                if t.name in STRENGTH_TARGETS and predictions.get(t.name)]
    guess = {}
    for p in calibration.parameters:
        value = params[p.key]
        last = p.key.rsplit(".", 1)[-1]
        if "bond_material" in p.key and last == "young_modulus" and modulus:
            value *= float(np.mean(modulus))
        elif "bond_material" in p.key and last.endswith("_strength") and strength:
            value *= float(np.mean(strength))
        guess[p.key] = min(max(value, p.low), p.high)
    return guess


def reachable(calibration, params, predictions):
    """Messages for targets the scaling rules say the bounds cannot reach (empty: none)."""
    problems = []
    for names, ending in ((MODULUS_TARGETS, "young_modulus"), (STRENGTH_TARGETS,
                                                                "_strength")):
        keys = [p for p in calibration.parameters if "bond_material" in p.key
                and p.key.rsplit(".", 1)[-1].endswith(ending)]
        if not keys:
            continue
        # all such parameters at their bounds together scale the property by these factors
        low = min(p.low / params[p.key] for p in keys)
        high = max(p.high / params[p.key] for p in keys)
        for t in calibration.targets:
            got = predictions.get(t.name)
            if t.name in names and got:
                lo, hi = sorted((got * low, got * high))
                if not lo * (1 - t.tolerance) <= t.value <= hi * (1 + t.tolerance):
                    problems.append(f"{t.name} = {t.value:.4g} lies outside what the "
                                    f"bounds of {', '.join(p.key for p in keys)} reach "
                                    f"({lo:.4g} to {hi:.4g}, by the scaling rule)")
    return problems


class Table:
    """calibration.csv: one row per finished trial (trial, each parameter, each test's
    targets' predictions, misfit)."""

    def __init__(self, path, calibration):
        self.path = Path(path)
        self.calibration = calibration
        self.columns = (["trial", *[p.key for p in calibration.parameters],
                         *[t.name for t in calibration.targets], "misfit"])

    def read(self):
        """{trial: row dict of floats} of the rows already there."""
        if not self.path.is_file():
            return {}
        if b"\n" not in self.path.read_bytes():
            return {}      # killed before its header was whole
        rows = {}
        with open(self.path, newline="") as handle:
            reader = csv.reader(handle)
            header = next(reader, None)
            if header != self.columns:
                raise InputError("holds another calibration's table (its columns differ); "
                                 "run afresh with --overwrite", file=self.path)
            for line in reader:
                if len(line) != len(self.columns):
                    continue   # a row cut by a kill
                row = dict(zip(self.columns, (float(v) for v in line)))
                rows[int(row["trial"])] = row
        return rows

    def start(self):
        """Write the header of a new table; on an old one, drop a last row cut by a kill
        (the next row would be appended to it, and both would be lost to ``read``)."""
        text = self.path.read_bytes() if self.path.is_file() else b""
        if b"\n" in text:
            if not text.endswith(b"\n"):
                with open(self.path, "rb+") as handle:
                    handle.truncate(text.rfind(b"\n") + 1)
            return
        with open(self.path, "w", newline="") as handle:    # new, or its header was cut
            csv.writer(handle).writerow(self.columns)

    def append(self, trial, params, predictions, value):
        row = {"trial": trial, **params, **{t.name: predictions.get(t.name, math.nan)
                                            for t in self.calibration.targets},
               "misfit": value}
        with open(self.path, "a", newline="") as handle:
            csv.writer(handle).writerow([repr(float(row[c])) for c in self.columns])
            handle.flush()
        return row


class _Evaluator:
    """Runs trials serially or on Dask: {trial: params} -> {trial: predictions}."""

    def __init__(self, calibration, scheduler, workers):
        self.calibration = calibration
        self.client = self.cluster = None
        self.errors = {}    # trial: the first failure's message
        self.numbers = {}   # the last run()'s {(trial, test): numbers}
        # keep(path): from then on each finished run's numbers are kept in that JSON file,
        # and a run already there is not run again (the runs after the trials, which the
        # table does not hold, survive a kill)
        self.kept_path = None
        self.kept = {}
        # log(path): each run this evaluator makes becomes a row of that CSV (RUN_COLUMNS):
        # where the calibration's time goes
        self.log_path = None
        if scheduler == "serial":
            return
        from distributed import Client
        if scheduler is None:
            self.cluster = local_cluster(workers)
            self.client = Client(self.cluster)
        elif isinstance(scheduler, str):
            try:
                self.client = Client(scheduler, timeout="30s")
            except OSError as error:
                raise InputError(f"cannot reach the Dask scheduler {scheduler!r} ({error})",
                                 key="--scheduler") from None
        else:
            self.client = scheduler

    def keep(self, path):
        """Keep finished runs in ``path`` (JSON) and take those already there."""
        self.kept_path = Path(path)
        try:
            self.kept = json.loads(self.kept_path.read_text())
        except (OSError, ValueError):
            self.kept = {}   # none yet, or cut by a kill: those runs are simply redone

    def log(self, path):
        """Append a row per finished run to ``path`` (CSV, RUN_COLUMNS)."""
        self.log_path = Path(path)
        if not self.log_path.is_file() or b"\n" not in self.log_path.read_bytes():
            self.log_path.write_text(",".join(RUN_COLUMNS) + "\n")

    def _logged(self, trial, test, numbers):
        if self.log_path is None:
            return
        row = [trial, test, *(numbers.get(k, math.nan) for k in RUN_COLUMNS[2:-1]),
               "error" if "error" in numbers else
               "no failure" if "no_failure" in numbers else "ok"]
        with open(self.log_path, "a", newline="") as handle:
            csv.writer(handle).writerow(row)

    def _kept(self, key, numbers):
        if self.kept_path is None or "error" in numbers:
            return
        names = {t.name for t in self.calibration.targets}
        self.kept[key] = {k: v for k, v in numbers.items()
                          if k in names or k == "no_failure" or k.startswith("rate_change_")}
        partial = self.kept_path.with_suffix(".tmp")
        partial.write_text(json.dumps(_clean(self.kept)))
        partial.replace(self.kept_path)

    def run(self, jobs):
        """jobs: {trial: overrides}; returns {trial: predictions of the targets}."""
        cal = self.calibration
        work = {(trial, test): {**cal.test_overrides.get(test, {}), **overrides}
                for trial, overrides in jobs.items() for test in cal.tests}
        keys = {item: json.dumps([item[1], sorted(merged.items())])
                for item, merged in work.items()}
        done = {item: self.kept[keys[item]] for item in work if keys[item] in self.kept}
        todo = {item: merged for item, merged in work.items() if item not in done}
        if self.client is None:
            for (trial, test), merged in todo.items():
                done[(trial, test)] = _safe(cal.spec, test, merged)
                self._kept(keys[(trial, test)], done[(trial, test)])
                self._logged(trial, test, done[(trial, test)])
        else:
            futures = {item: self.client.submit(single_threaded, _safe, cal.spec, item[1],
                                                merged, pure=False)
                       for item, merged in todo.items()}
            for item, future in futures.items():
                done[item] = future.result()
                self._kept(keys[item], done[item])
                self._logged(*item, done[item])
        self.numbers = done
        out = {}
        for trial in jobs:
            predictions = {}
            for t in cal.targets:
                numbers = done[(trial, t.test)]
                value = numbers.get(t.name, math.nan)
                predictions[t.name] = float(value) if value is not None else math.nan
                if "error" in numbers:
                    self.errors.setdefault(trial, numbers["error"])
                elif "no_failure" in numbers and not math.isfinite(predictions[t.name]):
                    self.errors.setdefault(trial, f"{t.test}: {numbers['no_failure']}, so "
                                                  f"no {t.name}: a failed trial")
            out[trial] = predictions
        return out

    def close(self):
        if self.client is not None and self.cluster is not None:
            self.client.close()
            self.cluster.close()


# calibration_runs.csv: trial (negative: the identifiability and seed runs, and
# RATE_TRIAL), test, the run's wall seconds on its worker (the specimen's packing
# included; the rate check's: both of its runs), its steps (the rate check's: of its run
# at the rate), particles and time step (s), and how it ended (ok, no failure, error)
RUN_COLUMNS = ("trial", "test", "run_seconds", "steps", "n_particles", "time_step", "end")


def _safe(spec, test, overrides):
    """evaluate(), with a failed run (a specimen that cannot be packed, a blow-up) as no
    numbers: the trial then has an infinite misfit. Adds ``run_seconds``, the run's wall
    time (s)."""
    started = time.perf_counter()
    try:
        numbers = evaluate(spec, test, overrides)
    except Exception as error:  # noqa: BLE001 - any failure of one trial is its result
        numbers = {"error": f"{test}: {type(error).__name__}: {error}"}
    return {**numbers, "run_seconds": time.perf_counter() - started}


def run_calibration(calibration, out_dir, *, scheduler="serial", workers=None,
                    resume=False, stop_after=None, progress=None, stage=None):
    """Run a Calibration (or a calibration file) into ``out_dir``: calibration.csv (every
    trial), calibration.json (the best set, the consistent sets, identifiability,
    predictions over seeds) and figures. scheduler: "serial" (this process), None (a
    LocalCluster of ``workers`` processes) or a scheduler address; resume: continue from
    the table there; stop_after: stop after this many trials (a planned interruption);
    progress(done, budget, misfit) after each trial; stage(text) when the runs after the
    trials begin (identifiability, seeds).
    Returns the summary dict; raises CalibrationFailed when no trial meets the targets."""
    import optuna
    started = time.perf_counter()
    if not isinstance(calibration, Calibration):
        calibration = load_calibration(calibration)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    table = Table(out_dir / "calibration.csv", calibration)
    if table.path.exists() and not resume:
        raise InputError("holds a calibration table; give --resume to continue it or "
                         "--overwrite to start afresh", file=out_dir, key="--out")
    have = table.read() if resume else {}
    if not resume:
        # a fresh table: runs kept or logged for an earlier one (its spec may have
        # changed since) must not stand in for this calibration's
        for name in ("calibration_checks.json", "calibration_runs.csv"):
            (out_dir / name).unlink(missing_ok=True)
    table.start()
    import warnings
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    sampler = optuna.samplers.TPESampler(seed=calibration.seed, n_startup_trials=4,
                                         multivariate=True)
    study = optuna.create_study(sampler=sampler, direction="minimize")
    distributions = {p.key: optuna.distributions.FloatDistribution(p.low, p.high, log=p.log)
                     for p in calibration.parameters}
    evaluator = _Evaluator(calibration, scheduler, workers)
    evaluator.log(out_dir / "calibration_runs.csv")
    rows = {}
    finished = 0
    middle = {p.key: p.middle() for p in calibration.parameters}
    try:
        while finished < calibration.budget:
            if stop_after is not None and finished >= stop_after:
                return None
            if finished == 0:
                study.enqueue_trial(middle)
            elif finished == 1:
                first = {t.name: rows[0][t.name] for t in calibration.targets}
                if not math.isfinite(rows[0]["misfit"]):
                    why = evaluator.errors.get(0) or "no numbers for " + ", ".join(
                        n for n, v in first.items() if not math.isfinite(v))
                    raise CalibrationFailed(
                        "the first trial (every parameter at the middle of its bounds) "
                        f"failed, so the scaling rules have nothing to scale: {why}")
                problems = reachable(calibration, middle, first)
                if problems:
                    raise CalibrationFailed("the targets cannot be met: "
                                            + "; ".join(problems))
                study.enqueue_trial(scaled_guess(calibration, middle, first))
            size = 1 if finished < 2 else min(calibration.batch,
                                              calibration.budget - finished)
            trials = [study.ask(distributions) for _ in range(size)]
            if stop_after is not None:
                trials_run = trials[:stop_after - finished]
            else:
                trials_run = trials
            todo = {t.number: t.params for t in trials_run if t.number not in have}
            results = evaluator.run(todo) if todo else {}
            for trial in trials_run:
                n = trial.number
                if n in have:
                    predictions = {t.name: have[n][t.name] for t in calibration.targets}
                else:
                    predictions = results[n]
                value = misfit(calibration, predictions)
                if n not in have:
                    table.append(n, trial.params, predictions, value)
                rows[n] = {"trial": n, **trial.params, **predictions, "misfit": value}
                study.tell(trial, value if math.isfinite(value) else 1e300)
                finished += 1
                if progress is not None:
                    progress(finished, calibration.budget, value)
            if len(trials_run) < len(trials):
                return None   # the planned interruption fell within this batch
        if not any(math.isfinite(r["misfit"]) for r in rows.values()):
            # only a Calibration made in Python with a budget of 1 gets here: from the
            # second trial on, a first trial without numbers stops the calibration
            first = next(iter(evaluator.errors.values()), "no numbers came back")
            raise CalibrationFailed(f"every trial failed; the first: {first}")
        evaluator.keep(out_dir / "calibration_checks.json")
        summary = summarise(calibration, rows, evaluator, stage)
    finally:
        evaluator.close()
    summary["time"] = {"wall_seconds": time.perf_counter() - started,
                       **run_times(out_dir / "calibration_runs.csv")}
    (out_dir / "calibration.json").write_text(json.dumps(_clean(summary), indent=2) + "\n")
    from .analysis.calibration import write_figures, write_page
    write_figures(calibration, rows, summary, out_dir)
    write_page(calibration, summary, out_dir)
    if not summary["consistent"]:
        best = summary["best"]
        misses = ", ".join(f"{t.name} by {100 * (best['predictions'][t.name] / t.value - 1):+.1f} %"
                           f" (tolerance {percent(t.tolerance)})"
                           for t in calibration.targets)
        raise CalibrationFailed(f"no parameter set of {calibration.budget} trials meets "
                                f"every target within its uncertainty; the best misses "
                                f"{misses}. Widen the bounds, raise the budget or check "
                                f"that the targets agree with each other")
    return summary


def run_times(path):
    """Where a calibration's time went, from its calibration_runs.csv ``path``: the runs'
    summed wall seconds (on their workers), by test and for the trials, the checks after
    them, and the runs that ended without a failure (at their strain limit); steps alike."""
    with open(path, newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r.get("end")]

    def total(chosen):
        return {"runs": len(chosen),
                "seconds": sum(float(r["run_seconds"]) for r in chosen),
                "steps": sum(float(r["steps"]) for r in chosen if r["steps"] != "nan")}
    return {"runs": total(rows), "trials": total([r for r in rows if int(r["trial"]) >= 0]),
            "checks": total([r for r in rows if int(r["trial"]) < 0]),
            "no_failure": total([r for r in rows if r["end"] == "no failure"]),
            "by_test": {t: total([r for r in rows if r["test"] == t])
                        for t in sorted({r["test"] for r in rows})}}


def _clean(value):
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def linearised_uncertainty(jacobian, null=1e-12):
    """Each parameter's linearised standard uncertainty, in units of its range, from the
    Jacobian ``jacobian`` [targets, parameters] of the predictions (in units of each
    target's tolerance) against the parameters (in units of their ranges): the diagonal of
    (J^T J)^-1. A direction the targets cannot fix (an eigenvalue of J^T J at most ``null``
    times the largest) has infinite variance, so every parameter with weight in it gets an
    infinite uncertainty; a pseudo-inverse would drop that direction and call the
    parameters in it exactly known."""
    jacobian = np.asarray(jacobian, dtype=float)
    n = jacobian.shape[1]
    if n == 0:
        return np.zeros(0)
    eigenvalues, vectors = np.linalg.eigh(jacobian.T @ jacobian)
    top = float(eigenvalues.max(initial=0.0))
    free = eigenvalues <= null * top if top > 0.0 else np.ones(n, dtype=bool)
    weight = vectors ** 2                       # [parameter, direction], rows sum to 1
    variance = weight[:, ~free] @ (1.0 / eigenvalues[~free])
    # round-off leaves ~1e-32 of weight in a free direction a parameter has no part in
    variance[weight[:, free].sum(axis=1) > 1e-9] = math.inf
    return np.sqrt(variance)


RATE_TRIAL = -200   # the rate check's trial number in calibration_runs.csv


def summarise(calibration, rows, evaluator, stage=None):
    """Best set, consistent sets, identifiability (spread and linearised uncertainty) and
    the best set's predictions over the check seeds and, with ``rate_check``, how far its
    strengths and moduli move at half the strain rate; stage(text) is told each phase."""
    stage = stage or (lambda text: None)
    names = [t.name for t in calibration.targets]
    order = sorted(rows.values(), key=lambda r: r["misfit"])
    best = order[0]
    params = {p.key: best[p.key] for p in calibration.parameters}
    good = [r for r in order if consistent(calibration, r)]
    identifiability = {}
    warnings = list(calibration.warnings)
    # linearised: predictions / (tolerance value) against the parameters' unit scale
    steps = {}
    jobs = {}
    for k, p in enumerate(calibration.parameters):
        u = p.unit(params[p.key])
        h = 0.05 if u < 0.95 else -0.05
        steps[p.key] = h
        moved = dict(params)
        moved[p.key] = (math.exp(math.log(p.low) + (u + h) * (math.log(p.high)
                                                               - math.log(p.low)))
                        if p.log else p.low + (u + h) * (p.high - p.low))
        jobs[-(k + 1)] = moved
    base = {t.name: best[t.name] for t in calibration.targets}
    tests = len(calibration.tests)
    stage(f"identifiability: {len(jobs) * tests} runs, each parameter moved by 5 % of its "
          f"range")
    moved = evaluator.run(jobs)
    jacobian = np.zeros((len(names), len(calibration.parameters)))
    for k, p in enumerate(calibration.parameters):
        for j, t in enumerate(calibration.targets):
            jacobian[j, k] = ((moved[-(k + 1)][t.name] - base[t.name])
                              / (t.tolerance * abs(t.value)) / steps[p.key])
    jacobian = np.where(np.isfinite(jacobian), jacobian, 0.0)   # a failed run: no information
    info = jacobian.T @ jacobian
    eigen = np.linalg.eigvalsh(info) if info.size else np.zeros(0)
    uncertainty = linearised_uncertainty(jacobian)
    for k, p in enumerate(calibration.parameters):
        sigma = float(uncertainty[k])
        values = [r[p.key] for r in good]
        spread = (max(p.unit(v) for v in values) - min(p.unit(v) for v in values)
                  if len(values) >= 2 else math.nan)
        identifiable = sigma < 0.25
        identifiability[p.key] = {
            "best": params[p.key], "uncertainty_of_range": sigma,
            "consistent_spread_of_range": spread, "identifiable": identifiable,
            "consistent_low": min(values) if values else math.nan,
            "consistent_high": max(values) if values else math.nan,
            "verdict": (f"identified: the targets fix it to +-{percent(sigma)} of its range"
                        if identifiable else
                        "not identifiable: the targets leave it free over its range"
                        if not math.isfinite(sigma) or sigma > 1.0 else
                        f"weakly identified: +-{percent(sigma)} of its range")}
    seeds = {}
    if calibration.check_seeds:
        stage(f"seed scatter: {len(calibration.check_seeds) * tests} runs on specimen seeds "
              f"{calibration.check_seeds}")
        runs = evaluator.run({-(100 + k): {**params, "specimen.seed": s}
                              for k, s in enumerate(calibration.check_seeds)})
        for t in calibration.targets:
            values = [runs[-(100 + k)][t.name] for k in range(len(calibration.check_seeds))]
            values.append(best[t.name])
            seeds[t.name] = {"mean": float(np.mean(values)), "std": float(np.std(values)),
                             "values": values}
            for seed, value in zip(calibration.check_seeds, values):
                off = value / t.value - 1.0 if math.isfinite(value) else math.nan
                if not abs(off) <= t.tolerance:
                    warnings.append(
                        f"{t.name} on specimen seed {seed}: {value:.4g}, {off:+.1%} off the "
                        f"target {t.value:.4g} (tolerance {percent(t.tolerance)}): the best "
                        "set meets the target on one specimen only; the scatter between "
                        "specimens is larger than the tolerance (a larger specimen, or a "
                        "wider tolerance)" if math.isfinite(value) else
                        f"{t.name} on specimen seed {seed}: the run failed")
    rate = {}
    if calibration.rate_check:
        from .lab.procedures import RATE_MODULUS_TOLERANCE, RATE_STRENGTH_TOLERANCE
        stage(f"rate: the best set's {tests} test(s) again at half the strain rate")
        evaluator.run({RATE_TRIAL: {**params, "test.rate_check": "repeat"}})
        for test in calibration.tests:
            numbers = evaluator.numbers[(RATE_TRIAL, test)]
            rate[test] = {name: numbers.get(f"rate_change_{name}", math.nan)
                          for name in ("strength", "modulus")}
            for name, limit in (("strength", RATE_STRENGTH_TOLERANCE),
                                ("modulus", RATE_MODULUS_TOLERANCE)):
                change = rate[test][name]
                if math.isfinite(change) and abs(change) > limit:
                    warnings.append(
                        f"{test}: at half the strain rate the best set's {name} moved by "
                        f"{100 * change:+.3g} % (more than {100 * limit:g} %): the targets "
                        "are met at a rate that is not quasi-static for these bonds; leave "
                        '"test.rate_rule" at its default "bonds" or set a lower '
                        '"test.strain_rate" for the tests (docs/lab.md, Rate)')
    return {"best": {"trial": int(best["trial"]), "parameters": params,
                     "predictions": base, "misfit": best["misfit"]},
            "targets": {t.name: {"test": t.test, "value": t.value,
                                 "tolerance": t.tolerance} for t in calibration.targets},
            "consistent": [{"trial": int(r["trial"]),
                            "parameters": {p.key: r[p.key] for p in calibration.parameters},
                            "predictions": {n: r[n] for n in names}} for r in good],
            "identifiability": identifiability,
            "information_eigenvalues": eigen.tolist(),
            "seed_scatter": seeds, "rate_change": rate, "trials": len(rows),
            "warnings": warnings,
            "failed": {int(k): v for k, v in evaluator.errors.items() if k >= 0},
            # the rate check runs each test twice (at the rate and at half of it)
            "simulations": (len(rows) + len(calibration.parameters)
                            + len(calibration.check_seeds)
                            + 2 * calibration.rate_check) * len(calibration.tests)}

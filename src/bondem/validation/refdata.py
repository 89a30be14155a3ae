"""Reference runs from the shared reference-data directory (MUSEN and other codes).

Layout (see that directory's README): one folder per reference, each with a SCENE.md that
gives every parameter (SI) and the meaning of each column of its data files, and the
tolerances. ``discover`` finds the folders; every folder found becomes a row of this
case, so new data appears in the table as soon as it is added. A folder is compared
automatically when it also holds ``compare.toml``:

    scene = "scene.toml"                # a bondem scene (needs bondem.scene.load_scene)
    [[compare]]
    file = "musen_tip.csv"              # reference data (CSV with a header line)
    time_column = "time"
    column = "tip_y"                    # the reference column
    quantity = "particles/position"     # results path in bondem's results file
    index = [20, 1]                     # particle (and component) compared
    tolerance = 1e-6                    # relative to the largest |reference|

Folders without it are listed as "skipped: no compare.toml (needs a runner)". With no
folder at all the case reports that there are no reference runs.
"""
import csv
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .core import CaseResult, Row, case, compare, compare_exact, info, skipped


@dataclass
class ReferenceRun:
    """A folder of reference data: name, path, first line of SCENE.md, data files and the
    parsed compare.toml (empty when absent)."""
    name: str
    path: Path
    title: str
    data_files: list
    spec: dict = field(default_factory=dict)


def reference_directory(p=None, key="search"):
    """The reference-data directory (Path) of parameter ``key`` ("search": exact solutions
    and other codes, $BONDEM_REFDATA if set; "musen_runs": runs of the real MUSEN;
    "packaged": those shipped with bondem), or None when none exists."""
    if key == "search" and os.environ.get("BONDEM_REFDATA"):
        return Path(os.environ["BONDEM_REFDATA"])
    if key != "search" and os.environ.get("BONDEM_REFDATA"):
        return None     # a test's own reference folder replaces all of them
    if key == "packaged":
        return PACKAGED_RUNS
    repository = Path(__file__).resolve().parents[3]
    default = {"search": ["../shared/refdata"], "musen_runs": ["../shared/musen-runs"]}[key]
    for candidate in (p or {}).get(key, default):
        for base in (repository, Path.cwd()):
            path = base / candidate
            if path.is_dir():
                return path
    return None


def discover(directory):
    """Every reference folder (with a SCENE.md) under ``directory``, sorted by name."""
    runs = []
    if directory is None or not Path(directory).is_dir():
        return runs
    for folder in sorted(Path(directory).iterdir()):
        scene = folder / "SCENE.md"
        if not (folder.is_dir() and scene.is_file()):
            continue
        lines = [x.strip("# ").strip() for x in scene.read_text().splitlines() if x.strip()]
        spec = {}
        if (folder / "compare.toml").is_file():
            with open(folder / "compare.toml", "rb") as handle:
                spec = tomllib.load(handle)
        data = sorted(x.name for x in folder.iterdir()
                      if x.is_file() and x.name not in ("SCENE.md", "compare.toml"))
        runs.append(ReferenceRun(folder.name, folder, lines[0] if lines else folder.name,
                                 data, spec))
    return runs


def read_columns(path):
    """A CSV file with a header line as {column: float array}."""
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        columns = {name: [] for name in reader.fieldnames}
        for record in reader:
            for name in columns:
                columns[name].append(float(record[name]))
    return {k: np.asarray(v) for k, v in columns.items()}


# Runs of the real MUSEN made for bondem's own models (Kelvin bonds), shipped with it.
PACKAGED_RUNS = Path(__file__).resolve().parents[1] / "data" / "validation" / "musen-runs"

QUANTITIES = ("particles/position", "particles/velocity", "particles/angular_velocity")
SPEC_NOTE = ("SPEC mode differs from MUSEN by design: exact rotations and SPEC section 1's "
             "start-up, where MUSEN re-orthogonalises nothing and starts with a prediction "
             "step, and the Hertz-Mindlin differences C1-C11 (docs/musen_compat.md); these "
             "tolerances hold for --compat musen")


def compare_run(run, compat, compat_only=False):
    """Rows for one reference folder that has a compare.toml: one simulation, run once
    through every time any ``[[compare]]`` item needs, then one row per results quantity
    (the item farthest from its tolerance among all items of that quantity). A folder of
    MUSEN-compatible tolerances (``compat_only``) gives info rows in SPEC mode."""
    try:
        from bondem.scene import load_scene
    except ImportError:
        return [skipped(f"refdata:{run.name}", run.title, "scene loader not available")]
    from bondem import Simulation
    scene = load_scene(run.path / run.spec["scene"])
    if scene.simulation_options.get("musen_compat", False):
        compat_only = False   # a MUSEN-compatible scene: its tolerances hold in every mode
    options = dict(scene.simulation_options)
    options["musen_compat"] = compat == "musen" or options.get("musen_compat", False)
    sim = Simulation(scene.model, scene.state.copy(), **options)
    items = run.spec.get("compare", [])
    for item in items:
        if item["quantity"] not in QUANTITIES:
            raise ValueError(f"compare.toml: quantity {item['quantity']!r}; allowed: "
                             f"{', '.join(QUANTITIES)}")
    tables = {name: read_columns(run.path / name) for name in {i["file"] for i in items}}
    times = sorted({float(t) for i in items for t in tables[i["file"]][i["time_column"]]})
    snapshots = {}
    for t in times:
        sim.run(until=t)
        state = sim.state
        snapshots[t] = {"particles/position": state.position.copy(),
                        "particles/velocity": state.velocity.copy(),
                        "particles/angular_velocity": state.angular_velocity.copy()}
    worst = {}   # quantity -> (deviation / tolerance, row fields)
    for item in items:
        data = tables[item["file"]]
        reference = data[item["column"]]
        index = tuple(item["index"])
        item_times = data[item["time_column"]]
        values = np.array([snapshots[float(t)][item["quantity"]][index] for t in item_times])
        # an item's own "scale" (the quantity's largest value in the run): a column that
        # stays near zero by symmetry would otherwise magnify round-off
        scale = item.get("scale") or np.abs(reference).max() or 1.0
        deviation = np.abs(values - reference) / scale
        k = int(np.argmax(deviation))
        ratio = float(deviation[k]) / item["tolerance"]
        if item["quantity"] not in worst or ratio > worst[item["quantity"]][0]:
            worst[item["quantity"]] = (ratio, item, item_times[k], reference[k] / scale,
                                       values[k] / scale)
    rows = _break_rows(run, sim, compat, compat_only)
    for quantity in QUANTITIES:
        if quantity not in worst:
            continue
        _, item, t, reference, value = worst[quantity]
        count = sum(1 for i in items if i["quantity"] == quantity)
        label = (f"{quantity}: {count} columns, worst {item['column']} at t = {t:.4g} s "
                 "(/ max |reference|)")
        if compat_only and compat != "musen":
            rows.append(info(f"refdata:{run.name}", label, reference, value, SPEC_NOTE,
                             absolute=True))
        else:
            rows.append(compare(f"refdata:{run.name}", label, reference, value,
                                item["tolerance"], absolute=True))
    return rows


def _break_rows(run, sim, compat, compat_only):
    """A row for ``musen_breaks.csv`` (bond, i, j, break_time: MUSEN's time at the start of
    the step in which the bond broke, 6 digits): how many bonds break in the same step."""
    path = run.path / "musen_breaks.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as handle:
        records = list(csv.DictReader(handle))
    if not records:
        return []     # a run without bonds
    dt = sim.time_step
    bondem_time = sim.state.bond_break_time
    same = 0
    for record in records:
        k = int(record["bond"])
        theirs = float(record["break_time"]) if record["break_time"].strip() else np.nan
        ours = float(bondem_time[k])
        if np.isnan(theirs) and np.isnan(ours):
            same += 1
        elif np.isfinite(theirs) and np.isfinite(ours):
            # both record the time at the start of the step in which the bond broke
            same += int(round(theirs / dt)) == int(round(ours / dt))
    label = f"bonds breaking in the same step as in MUSEN, or intact in both (of {len(records)})"
    if compat_only and compat != "musen":
        return [info(f"refdata:{run.name}", label, len(records), same, SPEC_NOTE)]
    return [compare_exact(f"refdata:{run.name}", label, len(records), same)]


@case("refdata", quick=True)
def run(p, compat, quick=False):
    """Reference runs from the reference-data folders: ``search`` (exact solutions and
    other codes), ``musen_runs`` and ``packaged`` (runs of the real MUSEN, whose tolerances
    hold for --compat musen: info rows in SPEC mode unless the scene itself is MUSEN-
    compatible). One row per folder and quantity."""
    rows: list[Row] = []
    for key, compat_only in (("search", False), ("musen_runs", True), ("packaged", True)):
        directory = reference_directory(p, key)
        runs = discover(directory)
        if not runs:
            if key == "search":
                rows.append(skipped("refdata", "reference runs of other codes",
                                    f"none found in {Path(directory).resolve()}"
                                    if directory is not None
                                    else "none installed: set BONDEM_REFDATA to a folder "
                                    "of them to compare (docs/validation.md); the real "
                                    "MUSEN's runs shipped with bondem are the rows below"))
            continue
        for r in runs:
            if not r.spec:
                rows.append(skipped(f"refdata:{r.name}", r.title,
                                    f"no compare.toml (needs a runner); data: "
                                    f"{', '.join(r.data_files) or 'none'}"))
                continue
            if quick and not r.spec.get("quick", True):
                rows.append(skipped(f"refdata:{r.name}", r.title,
                                    "a long run (compare.toml: quick = false): left out of "
                                    "--quick"))
                continue
            try:
                rows.extend(compare_run(r, compat, compat_only))
            except Exception as error:  # a broken folder is a failed row, not a crash
                rows.append(Row(f"refdata:{r.name}", r.title, "", f"error: {error}", None,
                                None, False, f"compare.toml could not be run: {error}"))
    return CaseResult(rows)

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

from .core import CaseResult, Row, case, compare, skipped


@dataclass
class ReferenceRun:
    """A folder of reference data: name, path, first line of SCENE.md, data files and the
    parsed compare.toml (empty when absent)."""
    name: str
    path: Path
    title: str
    data_files: list
    spec: dict = field(default_factory=dict)


def reference_directory(p=None):
    """The reference-data directory (Path) or None when none exists."""
    if os.environ.get("BONDEM_REFDATA"):
        return Path(os.environ["BONDEM_REFDATA"])
    repository = Path(__file__).resolve().parents[3]
    for candidate in (p or {}).get("search", ["../shared/refdata"]):
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


def compare_run(run, compat):
    """Rows for one reference folder that has a compare.toml."""
    try:
        from bondem.scene import load_scene
    except ImportError:
        return [skipped(f"refdata:{run.name}", run.title, "scene loader not available")]
    from bondem import Simulation
    # Scene API of the scene issue: .model, .state, .simulation_options (Simulation kwargs).
    scene = load_scene(run.path / run.spec["scene"])
    options = dict(scene.simulation_options)
    options["musen_compat"] = compat == "musen" or options.get("musen_compat", False)
    state = scene.state
    sim = Simulation(scene.model, state, **options)
    rows = []
    for item in run.spec.get("compare", []):
        data = read_columns(run.path / item["file"])
        times = data[item["time_column"]]
        reference = data[item["column"]]
        index = tuple(item["index"])
        values = []
        for t in times:
            sim.run(until=t)
            array = {"particles/position": state.position,
                     "particles/velocity": state.velocity,
                     "particles/angular_velocity": state.angular_velocity}[item["quantity"]]
            values.append(array[index])
        values = np.asarray(values)
        scale = np.abs(reference).max() or 1.0
        worst = int(np.argmax(np.abs(values - reference)))
        rows.append(compare(f"refdata:{run.name}", f"{item['column']} (max deviation at "
                            f"t = {times[worst]:.4g} s)", reference[worst] / scale,
                            values[worst] / scale, item["tolerance"], absolute=True))
    return rows


@case("refdata", quick=True)
def run(p, compat, quick=False):
    """Reference runs from the shared reference-data folder (one row per folder)."""
    directory = reference_directory(p)
    runs = discover(directory)
    if not runs:
        where = directory if directory is not None else "../shared/refdata"
        return CaseResult([skipped("refdata", "reference runs",
                                   f"none found in {where}")])
    rows: list[Row] = []
    for r in runs:
        if not r.spec:
            rows.append(skipped(f"refdata:{r.name}", r.title,
                                f"no compare.toml (needs a runner); data: "
                                f"{', '.join(r.data_files) or 'none'}"))
        else:
            try:
                rows.extend(compare_run(r, compat))
            except Exception as error:  # a broken folder is a failed row, not a crash
                rows.append(Row(f"refdata:{r.name}", r.title, "", f"error: {error}", None,
                                None, False, f"compare.toml could not be run: {error}"))
    return CaseResult(rows)

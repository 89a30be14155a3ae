"""Key numbers and time series of a run, gathered from the other analysis modules."""
from __future__ import annotations

import numpy as np

from .breakage import MODES, broken_series, first_break_time
from .energy import energy_balance
from .fields import field_series
from .fragments import fragment_series
from .results import Results
from .walls import wall_curve


UNITS = {"frames": "frames", "final_time": "s", "particles": "particles",
         "bonds": "bonds", "intact_bond_fraction": "of all bonds", "fragments": "fragments",
         "fragments_multi": "fragments of 2+ particles",
         "largest_fragment_fraction": "of the total mass", "first_break_time": "s",
         "peak_wall_force": "N", "displacement_at_peak_force": "m",
         "plate_gap_at_peak_force": "m", "plate_force_mismatch": "of the peak force",
         "energy_balance_error": "of the reference energy", "energy_reference": "J",
         "field_force_total": "N", "field_force_mean": "N per particle",
         "weight_carried_by_fields": "of the moving particles' weight"}
UNITS.update({f"broken_{name}": "bonds" for name in MODES})


def format_number(key, value):
    """``value`` of key number ``key`` rounded to 4 significant digits with its unit."""
    if value is None:
        return "n/a"
    unit = UNITS.get(key, "")
    if isinstance(value, float):
        return f"{value:.4g} {unit}".strip()
    return f"{value} {unit}".strip()


def analyze(results):
    """All analyses of an open ``Results``: {"fragments", "broken", "energy", "wall",
    "fields"} (see ``fragment_series``, ``broken_series``, ``energy_balance``,
    ``wall_curve``, ``field_series``; energy, wall and fields are None when the file has
    no such data)."""
    return {"fragments": fragment_series(results), "broken": broken_series(results),
            "energy": energy_balance(results), "wall": wall_curve(results),
            "fields": field_series(results)}


def key_numbers(results, data=None):
    """The numbers a person reads first, as a flat dict of plain Python values: frames,
    final_time (s), particles, bonds, intact_bond_fraction, broken_<mode> counts,
    fragments, fragments_multi (2+ particles), largest_fragment_fraction,
    first_break_time (s), peak_wall_force (N), displacement_at_peak_force (m, the
    decrease of the plate gap between two plates), plate_gap_at_peak_force (m),
    plate_force_mismatch (-, up to the peak), energy_balance_error (max |residual| /
    reference, -), energy_reference (J); with a fluid or a rotating frame, at the last
    frame: field_force_total (N, |sum of the fields' forces|), field_force_mean (N, per
    particle) and weight_carried_by_fields (-, ``field_series``)."""
    data = analyze(results) if data is None else data
    fragments, broken = data["fragments"], data["broken"]
    last = -1 if results.n_frames else None
    numbers = {"frames": results.n_frames,
               "final_time": float(results.time[-1]) if last is not None else None,
               "particles": results.n_particles, "bonds": results.n_bonds}
    if last is not None:
        numbers["intact_bond_fraction"] = (1.0 - float(broken["fraction"][-1])
                                           if results.n_bonds else None)
        for name in MODES:
            numbers[f"broken_{name}"] = int(broken[name][-1])
        numbers["fragments"] = int(fragments["fragments"][-1])
        numbers["fragments_multi"] = int(fragments["fragments_multi"][-1])
        numbers["largest_fragment_fraction"] = float(fragments["largest_fraction"][-1])
        numbers["first_break_time"] = first_break_time(results)
    wall, energy = data["wall"], data["energy"]
    numbers["peak_wall_force"] = wall["peak_force"] if wall else None
    numbers["displacement_at_peak_force"] = (wall["displacement_at_peak_force"]
                                             if wall else None)
    if wall and wall["partner"] is not None:
        numbers["plate_gap_at_peak_force"] = wall["gap_at_peak_force"]
        numbers["plate_force_mismatch"] = wall["force_mismatch"]
    numbers["energy_balance_error"] = energy["max_relative_error"] if energy else None
    numbers["energy_reference"] = energy["reference"] if energy else None
    fields = data.get("fields")
    if fields is not None and last is not None:
        numbers["field_force_total"] = float(np.linalg.norm(fields["total"][-1]))
        numbers["field_force_mean"] = float(fields["mean"][-1])
        if fields["weight_carried"] is not None:
            numbers["weight_carried_by_fields"] = float(fields["weight_carried"][-1])
    return numbers


def time_series(data):
    """Columns of one table, one row per frame: time, fragment and breakage counts,
    largest fragment fraction, every energy term, stored/work/losses/residual and the
    relative error, wall displacement and force, the fields' total force (N) and mean per
    particle and the weight they carry. {column: (F,) array}."""
    fragments, broken = data["fragments"], data["broken"]
    columns = {"time": fragments["time"], "fragments": fragments["fragments"],
               "fragments_multi": fragments["fragments_multi"],
               "largest_fragment_fraction": fragments["largest_fraction"],
               "broken": broken["broken"], "broken_fraction": broken["fraction"]}
    for name in MODES:
        columns[f"broken_{name}"] = broken[name]
    energy = data["energy"]
    if energy:
        for name, values in sorted(energy["terms"].items()):
            columns[f"energy_{name}"] = values
        for name in ("stored", "work", "losses", "residual", "relative_error"):
            columns[f"energy_{name}"] = energy[name]
    wall = data["wall"]
    if wall:
        columns["wall_displacement"] = wall["displacement"]
        columns["wall_force"] = wall["force"]
        if wall["partner"] is not None:
            columns["plate_gap"] = wall["gap"]
            columns["wall_force_loading"] = wall["force_wall"]
            columns["wall_force_partner"] = wall["force_partner"]
    fields = data.get("fields")
    if fields is not None:
        for k, axis in enumerate("xyz"):
            columns[f"field_force_{axis}"] = fields["total"][:, k]
        columns["field_force_mean"] = fields["mean"]
        if fields["weight_carried"] is not None:
            columns["weight_carried_by_fields"] = fields["weight_carried"]
    return columns


def summarize(path):
    """Key numbers of results file ``path`` (see ``key_numbers``)."""
    with Results(path) as results:
        return key_numbers(results)


def write_table(columns, path):
    """Write ``columns`` ({name: (F,)}) as CSV with a header line."""
    names = list(columns)
    table = np.column_stack([np.asarray(columns[n], dtype=np.float64) for n in names]) \
        if names else np.zeros((0, 0))
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.10g")

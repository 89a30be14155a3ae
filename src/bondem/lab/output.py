"""A lab test's files: lab.csv (the curve), lab.json (numbers with units, settings, notes)
and the figures (stress-strain, volumetric strain, cracks against strain, the specimen
coloured by broken bonds)."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

STRESS = {"ucs": "axial_stress", "triaxial": "deviator_stress", "brazilian": "tensile_stress",
          "tension": "tensile_stress", "agglomerate": "force"}
STRAIN = {"ucs": "axial_strain", "triaxial": "axial_strain", "brazilian": "platen_strain",
          "tension": "axial_strain", "agglomerate": "displacement"}
CAPTIONS = {
    "stress_strain": "Stress against axial strain: from the gauge bands of the specimen's own "
                     "particles (solid) and from the platen gap (dashed); the peak is marked.",
    "volumetric": "Volumetric strain (compaction positive) against axial strain.",
    "cracks": "Broken bonds by mode against the platen (or grip) strain, which only grows "
              "(the gauge strain turns back after the peak).",
    "ae": "Acoustic emission: AE events (cracks grouped in space and time) against the "
          "platen strain, and the number of events of at least each magnitude with the "
          "b-value's Gutenberg-Richter line.",
    "specimen": "The specimen at the end of the test, projected on the x-z plane; particles "
                "coloured by the number of their bonds that broke.",
}


def _json_value(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return None if not math.isfinite(value) else float(value)
    if isinstance(value, dict):
        return {k: _json_value(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_value(v) for v in value]
    return value


def write_result(result, out_dir, figures=True):
    """Write lab.csv, lab.json and (figures=True) the PNG figures of ``result`` into
    ``out_dir``; returns {name: path}."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {}
    columns = list(result.curve)
    path = out_dir / "lab.csv"
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([f"{c} ({result.units.get(c) or '1'})" for c in columns])
        for k in range(len(result.curve[columns[0]]) if columns else 0):
            writer.writerow([repr(float(result.curve[c][k])) for c in columns])
    paths["csv"] = path
    path = out_dir / "lab.json"
    path.write_text(json.dumps(_json_value({
        "test": result.test, "numbers": result.numbers,
        "units": {k: result.units.get(k, "") for k in result.numbers},
        "settings": result.settings, "notes": result.notes,
        "failed": result.no_failure is None, "no_failure": result.no_failure,
        # the report (analysis/report.py, a layer below the lab) reads them from here
        "captions": CAPTIONS}), indent=2) + "\n")
    paths["json"] = path
    for name, table in (("cracks", result.cracks), ("ae", result.ae)):
        if table is not None:
            paths[name + "_csv"] = _write_table(out_dir / f"lab_{name}.csv", table)
    if figures:
        for name, fig in build_lab_figures(result).items():
            target = out_dir / f"lab_{name}.png"
            fig.savefig(target, dpi=100)
            import matplotlib.pyplot as plt
            plt.close(fig)
            paths[name] = target
    return paths


def _write_table(path, table):
    """{column: (K,) array} as CSV with units in the header (lab/cracks.py's UNITS)."""
    from .cracks import UNITS
    columns = list(table)
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([f"{c} ({UNITS.get(c) or '1'})" for c in columns])
        for k in range(len(table[columns[0]]) if columns else 0):
            writer.writerow([repr(float(table[c][k])) for c in columns])
    return path


def build_lab_figures(result):
    """{name: matplotlib Figure} of a LabResult (see CAPTIONS)."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    curve, test = result.curve, result.test
    stress_key, strain_key = STRESS[test], STRAIN[test]
    figures = {}
    if not curve:
        return figures
    scale = 1.0 if test == "agglomerate" else 1e-6
    unit = "N" if test == "agglomerate" else "MPa"
    strain_scale = 1e3 if test == "agglomerate" else 100.0
    strain_unit = "mm" if test == "agglomerate" else "%"
    fig, ax = plt.subplots(figsize=(6, 4))
    x, y = curve[strain_key] * strain_scale, curve[stress_key] * scale
    ax.plot(x, y, "-", label="gauge" if strain_key == "axial_strain" else strain_key)
    if strain_key == "axial_strain":
        ax.plot(curve["platen_strain"] * strain_scale, y, "--",
                label="platens" if test != "tension" else "grips")
    k = int(np.argmax(y))
    ax.plot([x[k]], [y[k]], "o", color="C3", label=f"peak {y[k]:.4g} {unit}")
    ax.set_xlabel(f"{strain_key.replace('_', ' ')} ({strain_unit})")
    ax.set_ylabel(f"{stress_key.replace('_', ' ')} ({unit})")
    ax.legend()
    fig.tight_layout()
    figures["stress_strain"] = fig
    if "volumetric_strain" in curve:
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.plot(curve["axial_strain"] * 100, curve["volumetric_strain"] * 100)
        ax.set_xlabel("axial strain (%)")
        ax.set_ylabel("volumetric strain (%)")
        fig.tight_layout()
        figures["volumetric"] = fig
    fig, ax = plt.subplots(figsize=(6, 4))
    platen = curve["platen_strain"] * 100.0
    grip = "grip" if test == "tension" else "platen"
    for mode in ("tension", "compression", "shear"):
        ax.plot(platen, curve[f"broken_{mode}"], label=mode)
    ax.set_xlabel(f"{grip} strain (%)")
    ax.set_ylabel("broken bonds")
    ax.legend()
    fig.tight_layout()
    figures["cracks"] = fig
    if result.ae is not None and "ae_events" in curve:
        from .cracks import b_value
        fig, (left, right) = plt.subplots(1, 2, figsize=(9, 4))
        left.plot(platen, curve["ae_events"])
        left.set_xlabel(f"{grip} strain (%)")
        left.set_ylabel("AE events")
        magnitudes = np.sort(result.ae["magnitude"][np.isfinite(result.ae["magnitude"])])
        if magnitudes.size:
            at_least = np.arange(magnitudes.size, 0, -1)
            right.semilogy(magnitudes, at_least, ".", label="events")
            b = b_value(magnitudes)
            if b == b:
                line = magnitudes.size * 10.0 ** (-b * (magnitudes - magnitudes[0]))
                right.semilogy(magnitudes, line, "-", label=f"b = {b:.3g}")
            right.legend()
        right.set_xlabel("magnitude")
        right.set_ylabel("events of at least this magnitude")
        fig.tight_layout()
        figures["ae"] = fig
    if result.position is not None:
        fig, ax = plt.subplots(figsize=(5, 5))
        counts = np.zeros(result.position.shape[0])
        broken = result.bonds[result.broken]
        np.add.at(counts, broken.ravel(), 1.0)
        order = np.argsort(result.position[:, 1])
        points = ax.scatter(result.position[order, 0] * 1e3, result.position[order, 2] * 1e3,
                            c=counts[order], s=8, cmap="viridis")
        fig.colorbar(points, ax=ax, label="broken bonds of the particle")
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("z (mm)")
        fig.tight_layout()
        figures["specimen"] = fig
    return figures

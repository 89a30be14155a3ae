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
    "fragments": "Fragment size distribution by mass (a fragment's size: the diameter of "
                 "the sphere of its particles' volume): the mass fraction passing each size, "
                 "the mass per logarithmic size class, and the number of fragments (of two or "
                 "more particles, and all of them with the loose particles) against the "
                 "energy the plates applied.",
    "ae": "Acoustic emission: AE events (cracks grouped in space and time) against the "
          "platen strain, and the number of events of at least each magnitude with the "
          "b-value's Gutenberg-Richter line.",
    "specimen": "The specimen at the end of the test in 3D and its slice through the middle "
                "(one particle diameter either side of the x-z plane through the particles' "
                "median y, which fragments flown off do not move); "
                "each particle coloured by the mode in which most of its broken bonds broke "
                "(grey: none broke); in the slice, the contact forces between its particles "
                "as lines as wide as the force (force chains).",
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
    for name, table in (("cracks", result.cracks), ("ae", result.ae),
                        ("fragments", result.fragments)):
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
    units = {**UNITS, "mass": "kg", "size": "m"}   # any other column: "1"
    columns = list(table)
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([f"{c} ({units.get(c) or '1'})" for c in columns])
        for k in range(len(table[columns[0]]) if columns else 0):
            writer.writerow([repr(float(table[c][k])) for c in columns])
    return path


def build_lab_figures(result):
    """{name: matplotlib Figure} of a LabResult (see CAPTIONS)."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import matplotlib.ticker
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
    if result.fragments is not None and "applied_energy" in curve:
        from .measure import passing
        table = result.fragments
        fig, (left, middle, right) = plt.subplots(1, 3, figsize=(12, 4))
        size, fraction = passing(table["size"], table["mass"])
        left.step(size * 1e3, fraction, where="post")
        left.set_xscale("log")
        left.set_xlabel("fragment size (mm)")
        left.set_ylabel("mass fraction passing")
        edges = np.geomspace(size.min() * 0.99, size.max() * 1.01, 12)
        middle.hist(table["size"] * 1e3, bins=edges * 1e3, weights=table["mass"]
                    / table["mass"].sum())
        middle.set_xscale("log")
        for ax in (left, middle):   # plain numbers on the log axis, no crowded minor labels
            ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        middle.set_xlabel("fragment size (mm)")
        middle.set_ylabel("mass fraction per size class")
        right.plot(curve["applied_energy"] * 1e3, curve["fragments_multi"],
                   label="of 2+ particles")
        right.plot(curve["applied_energy"] * 1e3, curve["fragments"], "--",
                   label="all, loose particles included")
        right.set_xlabel("applied energy (mJ)")
        right.set_ylabel("fragments")
        right.legend()
        fig.tight_layout()
        figures["fragments"] = fig
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
        figures["specimen"] = _failure_picture(result, plt)
    return figures


MODE_COLOURS = {0: "0.8", 1: "tab:blue", 2: "tab:orange", 3: "tab:red"}
MODE_NAMES = {0: "intact", 1: "tension", 2: "compression", 3: "shear"}


def particle_modes(n, bonds, break_mode):
    """(N,) int: for each particle the mode (1 tension, 2 compression, 3 shear) in which
    most of its broken bonds broke (the lower mode when tied), 0 when none broke."""
    counts = np.zeros((n, 4))
    broken = np.flatnonzero(np.asarray(break_mode) > 0)
    for end in (0, 1):
        np.add.at(counts, (bonds[broken, end], break_mode[broken]), 1.0)
    counts[:, 0] = 0.0
    mode = np.argmax(counts, axis=1)
    mode[counts.sum(axis=1) == 0.0] = 0
    return mode


def _failure_picture(result, plt):
    """The failure picture: the specimen in 3D and a middle slice, by crack mode."""
    position = result.position * 1e3
    mode = (particle_modes(position.shape[0], result.bonds, result.break_mode)
            if result.break_mode is not None else np.zeros(position.shape[0], int))
    colours = np.array([MODE_COLOURS[int(m)] for m in range(4)], dtype=object)[mode]
    fig = plt.figure(figsize=(10, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.scatter(position[:, 0], position[:, 1], position[:, 2], c=list(colours), s=6,
               depthshade=True)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.set_box_aspect(np.ptp(position, axis=0) + 1e-12)
    cut = fig.add_subplot(1, 2, 2)
    # the median, not the middle of the range: a few fragments flown off after the
    # peak moved the range's middle off the specimen (a 20 mm Brazilian disc's slice
    # held 20 stray particles)
    middle = float(np.median(position[:, 1]))
    diameter = 2e3 * float(np.mean(result.radius)) if result.radius is not None else \
        0.05 * float(np.ptp(position[:, 1]) or 1.0)
    near = np.abs(position[:, 1] - middle) <= diameter
    for m in range(4):
        pick = near & (mode == m)
        if np.any(pick):
            cut.scatter(position[pick, 0], position[pick, 2], c=MODE_COLOURS[m], s=12,
                        label=MODE_NAMES[m])
    contacts = result.contacts
    if contacts is not None and contacts["i"].size:
        # the force chains in the slice: particle pairs both in it, width by force
        i, j = contacts["i"], contacts["j"]
        pair = (j >= 0)
        pair[pair] &= near[i[pair]] & near[j[pair]]
        if np.any(pair):
            magnitude = np.linalg.norm(contacts["force"][pair], axis=1)
            width = 0.3 + 3.0 * magnitude / magnitude.max()
            from matplotlib.collections import LineCollection
            segments = np.stack([position[i[pair]][:, [0, 2]], position[j[pair]][:, [0, 2]]],
                                axis=1)
            cut.add_collection(LineCollection(segments, linewidths=width, colors="k",
                                              alpha=0.6, label="contact forces"))
    cut.set_aspect("equal")
    cut.set_xlabel("x (mm)")
    cut.set_ylabel("z (mm)")
    cut.set_title("slice through the middle")
    cut.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return fig

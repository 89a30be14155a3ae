"""Figures of a run (matplotlib, Agg backend: no display needed), saved as PNG and PDF.

Each figure is built from a plain data dict returned by the analysis functions (tests
check those dicts, not pixels): ``build_figures`` returns {name: (Figure, data)}.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import EllipseCollection  # noqa: E402
from matplotlib.ticker import (FormatStrFormatter, LogLocator, MaxNLocator,  # noqa: E402
                               NullFormatter)

from .breakage import MODES, radial_breakage  # noqa: E402
from .fragments import count_distribution, frame_fragments, size_distribution  # noqa: E402
from .summary import analyze  # noqa: E402

MODE_COLOURS = {"tension": "tab:red", "compression": "tab:blue", "shear": "tab:green",
                "unknown": "tab:gray"}
VIEWS = {"xz": (0, 2, 1), "xy": (0, 1, 2), "yz": (1, 2, 0)}  # (horizontal, vertical, depth)


def plot_fragments(series):
    """Fragment count and largest-fragment mass fraction against time."""
    fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
    t = series["time"] * 1e3
    ax.step(t, series["fragments"], where="post", color="tab:blue", label="all fragments")
    ax.step(t, series["fragments_multi"], where="post", color="tab:cyan", ls="--",
            label="fragments of 2+ particles")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("fragments")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    right = ax.twinx()
    right.step(t, series["largest_fraction"], where="post", color="tab:red",
               label="largest fragment")
    right.set_ylabel("largest fragment mass fraction", color="tab:red")
    right.set_ylim(0, 1.05)
    lines = ax.get_lines() + right.get_lines()
    ax.legend(lines, [x.get_label() for x in lines], loc="center right", fontsize=8)
    return fig


def plot_breakage(series):
    """Broken bonds against time, by mode."""
    fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
    t = series["time"] * 1e3
    ax.step(t, series["broken"], where="post", color="k", label="all")
    for name in (*MODES, "unknown"):
        if np.any(series[name]):
            ax.step(t, series[name], where="post", color=MODE_COLOURS[name], label=name)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("broken bonds")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.legend(fontsize=8)
    return fig


def plot_energy(balance):
    """Energy terms, the balance's stored/work/losses and its relative residual."""
    fig, (ax, low) = plt.subplots(2, 1, figsize=(6, 5.5), sharex=True, layout="constrained",
                                  height_ratios=(3, 1))
    t = balance["time"] * 1e3
    for name, values in sorted(balance["terms"].items()):
        if np.any(values):
            ax.plot(t, values, lw=1, label=name.replace("_", " "))
    ax.plot(t, balance["stored"], "k", lw=2, label="stored")
    ax.plot(t, balance["stored"] - balance["work"] + balance["losses"], "k:", lw=2,
            label="stored - work + losses")
    ax.set_ylabel("energy (J)")
    ax.legend(fontsize=7, ncol=2)
    low.plot(t, balance["relative_error"] * 100, color="tab:purple")
    low.set_ylabel("residual (%)")
    low.set_xlabel("time (ms)")
    return fig


def plot_fields(series):
    """The fields' (fluid, rotating frame) total force on the particles per axis and
    the mean per particle against time; with gravity, the share of the weight carried."""
    rows = 2 if series["weight_carried"] is not None else 1
    fig, axes = plt.subplots(rows, 1, figsize=(6, 2.6 + 1.9 * rows), sharex=True,
                             layout="constrained", squeeze=False)
    ax = axes[0, 0]
    t = series["time"] * 1e3
    for k, axis in enumerate("xyz"):
        ax.plot(t, series["total"][:, k], lw=1.2, label=f"total {axis}")
    ax.plot(t, series["mean"], "k--", lw=1, label="mean |F| per particle")
    ax.set_ylabel("fluid/field force (N)")
    ax.legend(fontsize=7, ncol=2)
    if rows == 2:
        low = axes[1, 0]
        low.plot(t, series["weight_carried"], color="tab:purple")
        low.axhline(1.0, color="0.6", lw=0.8, ls=":")
        low.set_ylabel("weight carried (-)")
    axes[-1, 0].set_xlabel("time (ms)")
    return fig


def plot_wall(curve):
    """Wall force against displacement (the decrease of the plate gap when two plates
    press the body; time for a wall that stays) with the first breakage and the peak."""
    fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
    moved = np.any(curve["displacement"] != 0)
    x = curve["displacement"] * 1e3 if moved else curve["time"] * 1e3
    if curve["partner"] is not None:
        ax.plot(x, curve["force_wall"], color="tab:blue", lw=0.8,
                label=f"wall {curve['wall']} (loading)")
        ax.plot(x, curve["force_partner"], color="tab:green", lw=0.8,
                label=f"wall {curve['partner']}")
        ax.plot(x, curve["force"], color="k", label="mean of both")
    else:
        ax.plot(x, curve["force"], color="k")
    # the peak of the per-step history, which may fall between two frames
    peak_x = (curve["displacement_at_peak_force"] if moved else curve["peak_time"]) * 1e3
    ax.plot(peak_x, curve["peak_force"], "v", color="tab:red", ms=9,
            label=f"peak {curve['peak_force']:.3g} N")
    first = curve["first_break_index"]
    if first is not None:
        ax.plot(x[first], curve["force"][first], "o", color="tab:orange", ms=8,
                label="first broken bond")
    if not moved:
        ax.set_xlabel("time (ms)")
    elif curve["partner"] is not None:
        ax.set_xlabel("displacement: decrease of the plate gap (mm)")
    else:
        ax.set_xlabel(f"travel of wall {curve['wall']} (mm)")
    ax.set_ylabel("compressive force (N)" if moved else f"|force| on wall {curve['wall']} (N)")
    ax.legend(fontsize=8)
    return fig


def plot_size_distribution(data):
    """Fragment sizes at one frame: cumulative mass fraction against fragment mass (sieve
    curve) and the number of fragments against particles per fragment."""
    fig, (ax, right) = plt.subplots(1, 2, figsize=(8, 3.6), layout="constrained")
    ax.step(np.r_[data["masses"][:1], data["masses"]], np.r_[0.0, data["cumulative"]],
            where="post", color="tab:blue", marker=".")
    ax.set_xscale("log")
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("fragment mass (kg)")
    ax.set_ylabel("cumulative mass fraction")
    if data["particles"].max() > 20:
        # bars of equal width on the log axis, ticks at the decades written as integers
        # (integer ticks on a log axis crowd and overlap)
        x = np.asarray(data["particles"], dtype=np.float64)
        right.bar(x / 1.25, data["number"], width=x * (1.25 - 1 / 1.25), align="edge",
                  color="tab:orange", edgecolor="k")
        right.set_xscale("log")
        right.xaxis.set_major_locator(LogLocator(base=10))
        right.xaxis.set_major_formatter(FormatStrFormatter("%d"))
        right.xaxis.set_minor_formatter(NullFormatter())
    else:
        right.bar(data["particles"], data["number"], color="tab:orange", edgecolor="k")
        right.xaxis.set_major_locator(MaxNLocator(integer=True))
    right.set_xlabel("particles per fragment")
    right.set_ylabel("fragments")
    right.yaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(f"t = {data['time'] * 1e3:.4g} ms, {len(data['masses'])} fragments",
                 fontsize=9)
    return fig


def plot_radial(radial):
    """Fraction of bonds broken in each radial shell of the body at t = 0."""
    fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
    edges = radial["edges"]
    ax.bar(edges[:-1], np.nan_to_num(radial["broken_fraction"]), width=np.diff(edges),
           align="edge", color="tab:orange", edgecolor="k")
    ax.set_xlabel("bond position r / R (centre of mass to outer radius, t = 0)")
    ax.set_ylabel("fraction of bonds broken")
    ax.set_xlim(0, 1)
    return fig


def body_picture_data(results, frame, view="xz"):
    """Discs of the body projected on a plane: {"time": s, "x", "y": (N,) m projected
    centres, "radius": (N,) m, "depth": (N,) m, "labels": (N,) fragment ids,
    "n_fragments", "view"}."""
    fragments = frame_fragments(results, frame)
    position = np.asarray(results.frame("particles/position", frame), dtype=np.float64)
    h, v, d = VIEWS[view]
    return {"time": fragments["time"], "x": position[:, h], "y": position[:, v],
            "depth": position[:, d], "radius": results.radius, "labels": fragments["labels"],
            "n_fragments": len(fragments["counts"]), "sizes": fragments["counts"],
            "view": view}


def fragment_colours(labels, sizes):
    """RGBA per particle: a distinct colour per fragment (tab10 cycle, 0 = largest),
    light grey for particles that are fragments on their own."""
    palette = [c for i, c in enumerate(plt.get_cmap("tab10").colors) if i != 7]  # no grey
    colours = np.array([(*palette[k % len(palette)], 1.0) for k in labels])
    alone = sizes[labels] == 1
    colours[alone] = (0.75, 0.75, 0.75, 1.0)
    return colours


def plot_bodies(pictures):
    """The body at several frames side by side, discs to scale, fragments coloured;
    far particles drawn first so near ones cover them."""
    fig, axes = plt.subplots(1, len(pictures), figsize=(3.6 * len(pictures), 3.8),
                             layout="constrained", squeeze=False)
    for ax, pic in zip(axes[0], pictures):
        order = np.argsort(pic["depth"])[::-1]
        colours = fragment_colours(pic["labels"], pic["sizes"])[order]
        # mm: metres gave tick labels like 0.0125 that ran into each other
        x, y = 1e3 * pic["x"], 1e3 * pic["y"]
        diameter = 2e3 * pic["radius"][order]
        ax.add_collection(EllipseCollection(
            diameter, diameter, np.zeros(len(order)), units="xy",
            offsets=np.column_stack([x[order], y[order]]),
            offset_transform=ax.transData, facecolors=colours, edgecolors="k",
            linewidths=0.3))
        pad = 1e3 * pic["radius"].max() if len(order) else 1.0
        ax.update_datalim([(x.min() - pad, y.min() - pad), (x.max() + pad, y.max() + pad)])
        ax.margins(0.0)
        ax.autoscale_view()
        # equal scales by widening the data range, not by shrinking the axes: fragments
        # spread along one axis drew as a thin strip
        ax.set_aspect("equal", adjustable="datalim")
        ax.xaxis.set_major_locator(MaxNLocator(nbins=4))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=5))
        ax.set_title(f"t = {pic['time'] * 1e3:.4g} ms, {pic['n_fragments']} fragments",
                     fontsize=9)
        ax.set_xlabel(f"{pic['view'][0]} (mm)")
        ax.set_ylabel(f"{pic['view'][1]} (mm)")
    return fig


def build_figures(results, frames=(0, -1), view="xz", data=None):
    """Every figure that applies to an open ``Results``: {name: (Figure, data)} with
    names fragments, breakage, energy (if /energy), wall (if walls), fields (if field
    forces: a fluid or a rotating frame), size_distribution,
    radial (if bonds), bodies (at ``frames``, projected on ``view``)."""
    data = analyze(results) if data is None else data
    figures = {"fragments": (plot_fragments(data["fragments"]), data["fragments"])}
    if results.n_bonds:
        figures["breakage"] = (plot_breakage(data["broken"]), data["broken"])
        radial = radial_breakage(results)
        figures["radial"] = (plot_radial(radial), radial)
    if data["energy"] is not None:
        figures["energy"] = (plot_energy(data["energy"]), data["energy"])
    if data["wall"] is not None:
        figures["wall"] = (plot_wall(data["wall"]), data["wall"])
    if data.get("fields") is not None:
        figures["fields"] = (plot_fields(data["fields"]), data["fields"])
    last = frame_fragments(results, -1)
    masses, cumulative = size_distribution(last["masses"], last["total_mass"])
    particles, number = count_distribution(last["counts"])
    sizes = {"time": last["time"], "masses": masses, "cumulative": cumulative,
             "counts": last["counts"], "particles": particles, "number": number}
    figures["size_distribution"] = (plot_size_distribution(sizes), sizes)
    pictures = [body_picture_data(results, f, view) for f in frames]
    figures["bodies"] = (plot_bodies(pictures), pictures)
    return figures


def save_figures(figures, out_dir, formats=("png", "pdf")):
    """Save each figure as out_dir/<name>.<format>; returns {name: [paths]} and closes
    the figures."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = {}
    for name, (fig, _) in figures.items():
        written[name] = []
        for fmt in formats:
            path = out_dir / f"{name}.{fmt}"
            fig.savefig(path, dpi=120)
            written[name].append(path)
        plt.close(fig)
    return written

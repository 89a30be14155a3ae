"""Figures and the HTML page of a calibration (``bondem calibrate``)."""
from __future__ import annotations

import base64
import html
import math
from pathlib import Path

import numpy as np

CAPTIONS = {
    "calibration_targets": "Each target's prediction by the best parameter set over the "
                           "target (1 = met), with the scatter over the check seeds and the "
                           "target's uncertainty (band).",
    "calibration_parameters": "Every trial's parameters (pairwise), coloured by log10 of the "
                              "misfit (dark: far from the targets); the sets consistent with "
                              "all targets are circled. Diagonal: trials per bin of each "
                              "parameter's bounds, the consistent ones in green.",
}


def percent(fraction):
    """A fraction as a percentage with two significant digits: 0.0024 -> '0.24 %'."""
    return f"{100.0 * fraction:.2g} %"


def write_figures(calibration, rows, summary, out_dir):
    """calibration_targets.png and calibration_parameters.png in ``out_dir``."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    out_dir = Path(out_dir)
    targets = calibration.targets
    fig, ax = plt.subplots(figsize=(6, 3.5))
    best = summary["best"]["predictions"]
    scatter = summary.get("seed_scatter", {})
    for k, t in enumerate(targets):
        ax.fill_between([k - 0.4, k + 0.4], 1 - t.tolerance, 1 + t.tolerance, color="0.85")
        ratio = best[t.name] / t.value if best[t.name] is not None else math.nan
        error = scatter.get(t.name, {}).get("std", 0.0) / abs(t.value)
        ax.errorbar([k], [ratio], yerr=[error], fmt="o", color="C0", capsize=4)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(range(len(targets)), [t.name.replace("_", " ") for t in targets],
                  rotation=15)
    ax.set_ylabel("prediction / target")
    fig.tight_layout()
    fig.savefig(out_dir / "calibration_targets.png", dpi=100)
    plt.close(fig)
    params = calibration.parameters
    n = len(params)
    fig, axes = plt.subplots(n, n, figsize=(2.2 * n + 1, 2.2 * n + 1), squeeze=False)
    values = {p.key: np.array([r[p.key] for r in rows.values()]) for p in params}
    misfit = np.array([r["misfit"] for r in rows.values()])
    colour = np.log10(np.clip(np.where(np.isfinite(misfit), misfit, 1e6), 1e-6, 1e6))
    good = {c["trial"] for c in summary["consistent"]}
    mask = np.array([int(r["trial"]) in good for r in rows.values()])
    from matplotlib.ticker import NullFormatter
    for i, pi in enumerate(params):
        for j, pj in enumerate(params):
            ax = axes[i, j]
            if i == j:
                # bins over the parameter's bounds, spaced as it is searched
                bins = (np.geomspace(pi.low, pi.high, 13) if pi.log
                        else np.linspace(pi.low, pi.high, 13))
                ax.hist(values[pi.key], bins=bins, color="0.6", label="trials")
                ax.hist(values[pi.key][mask], bins=bins, color="C2", label="consistent")
            else:
                ax.scatter(values[pj.key], values[pi.key], c=colour, s=12, cmap="viridis_r")
                ax.scatter(values[pj.key][mask], values[pi.key][mask], s=40,
                           facecolors="none", edgecolors="C3")
            for p, axis, setter in ((pj, ax.xaxis, ax.set_xscale),
                                    (pi, ax.yaxis, ax.set_yscale)):
                if p.log and not (i == j and axis is ax.yaxis):
                    setter("log")
                    axis.set_minor_formatter(NullFormatter())   # the decades only
            ax.tick_params(labelsize=7)
            if i == n - 1:
                ax.set_xlabel(pj.key.rsplit(".", 2)[-1], fontsize=8)
            if j == 0:
                ax.set_ylabel(pi.key.rsplit(".", 2)[-1] if i else
                              f"{pi.key.rsplit('.', 2)[-1]}\n(trials)", fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "calibration_parameters.png", dpi=90)
    plt.close(fig)


def write_page(calibration, summary, out_dir):
    """calibration.html: the best set, identifiability, targets against predictions and
    the figures, self-contained."""
    from .report import _table
    out_dir = Path(out_dir)
    best = summary["best"]
    rows = [(k, v, info["verdict"]) for k, v, info in
            ((k, best["parameters"][k], summary["identifiability"][k])
             for k in best["parameters"])]
    target_rows = []
    for t in calibration.targets:
        spread = summary["seed_scatter"].get(t.name, {})
        target_rows.append((t.name, t.test, t.value, f"+-{percent(t.tolerance)}",
                            best["predictions"][t.name],
                            spread.get("std", "n/a") if spread else "n/a"))
    figures = "".join(
        f'<figure id="{name}"><img alt="{name}" src="data:image/png;base64,'
        f'{base64.b64encode((out_dir / f"{name}.png").read_bytes()).decode("ascii")}">'
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        for name, caption in CAPTIONS.items() if (out_dir / f"{name}.png").is_file())
    warnings = "".join(f'<p class="warning"><b>Warning:</b> {html.escape(w)}</p>\n'
                       for w in summary.get("warnings", []))
    timing = summary.get("time")
    took = (f" in {timing['wall_seconds']:.0f} s ({timing['runs']['seconds']:.0f} s of "
            f"runs, calibration_runs.csv)" if timing else "")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>bondem calibration</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:auto;padding:1em}}
table{{border-collapse:collapse}}td{{border:1px solid #ccc;padding:2px 8px}}
img{{max-width:100%}}</style></head><body>
<h1>Calibration: {html.escape(calibration.path.name)}</h1>
<p>{summary['trials']} trials, {summary['simulations']} simulations{took}; best trial
{best['trial']} (misfit {best['misfit']:.3g}); {len(summary['consistent'])} parameter sets
meet every target within its uncertainty.</p>
{warnings}<h2 id="best">Best parameters and what the targets fix</h2>
{_table(rows, ("parameter", "best", "identifiability"))}
<h2 id="targets">Targets and predictions</h2>
{_table(target_rows, ("target", "test", "value", "uncertainty", "predicted",
                      "scatter over seeds (std)"))}
<h2>Figures</h2>{figures}</body></html>
"""
    (out_dir / "calibration.html").write_text(page, encoding="utf-8")

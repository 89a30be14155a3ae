"""One lab test on several specimens of a spec (a seed each: several agglomerates, or
several rock samples), run as a Dask ensemble: each run's numbers, their mean, standard
deviation and coefficient of variation, and for agglomerates every run's fragment size
distribution in one figure."""
from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np

from ..parallel import local_cluster, single_threaded

SHOWN = ("ucs", "tensile_strength", "peak_deviator_stress", "breakage_force",
         "breakage_energy", "fragment_size_d50", "young_modulus_secant", "poisson_ratio",
         "strain_at_peak", "fragments", "fragments_multi", "largest_fragment_fraction",
         "broken_bonds_final", "n_particles", "n_bonds")


def ensemble(function, items, *, scheduler="serial", workers=None):
    """[function(*item) for item in items], on Dask: scheduler "serial" (this process),
    None (a LocalCluster of ``workers`` processes, default one per item up to the cores)
    or a scheduler address. ``function`` must be a module-level function."""
    items = list(items)
    if scheduler == "serial":
        return [function(*item) for item in items]
    from distributed import Client
    cluster = None
    if scheduler is None:
        cluster = local_cluster(workers or min(len(items), os.cpu_count() or 1))
        client = Client(cluster)
    else:
        client = Client(scheduler, timeout="30s")
    try:
        futures = [client.submit(single_threaded, function, *item, pure=False)
                   for item in items]
        return [f.result() for f in futures]
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _one(spec, test, overrides, seed):
    """Test ``test`` of the spec's specimen made with ``seed``: its numbers, the reason it
    has no strength (or None) and its fragments (agglomerate)."""
    from .procedures import RUNNERS
    from .spec import load_spec
    specimen, settings, _ = load_spec(spec, {**(overrides or {}), "specimen.seed": seed})
    result = RUNNERS[test](specimen, settings)
    fragments = ({k: v.tolist() for k, v in result.fragments.items()}
                 if result.fragments is not None else None)
    return {"seed": seed, "numbers": result.numbers, "no_failure": result.no_failure,
            "fragments": fragments}


def summarise(runs):
    """{name: {"mean", "std" (sample standard deviation), "cv" (std / |mean|), "count"}}
    over the runs' finite numbers among SHOWN; the runs that did not fail are left out of
    their strengths (NaN there)."""
    out = {}
    for name in SHOWN:
        values = np.array([r["numbers"].get(name, math.nan) for r in runs], dtype=float)
        values = values[np.isfinite(values)]
        if values.size == 0:
            continue
        mean = float(values.mean())
        std = float(values.std(ddof=1)) if values.size > 1 else math.nan
        out[name] = {"mean": mean, "std": std, "count": int(values.size),
                     "cv": std / abs(mean) if mean else math.nan}
    return out


def run_series(spec, test, seeds, *, overrides=None, scheduler="serial", workers=None):
    """Test ``test`` on the spec's specimen for each seed of ``seeds``; returns {"runs":
    [per seed: seed, numbers, no_failure, fragments], "summary": summarise(runs)}."""
    seeds = [int(s) for s in seeds]
    runs = ensemble(_one, [(str(spec), test, overrides, s) for s in seeds],
                    scheduler=scheduler, workers=workers)
    return {"test": test, "runs": runs, "summary": summarise(runs)}


def write_series(series, out_dir):
    """series.csv (one row per seed), series.json (runs and summary) and, for
    agglomerates, lab_series_fragments.png (each run's mass fraction passing against the
    fragment size) in ``out_dir``; returns {name: path}."""
    from .measure import passing
    from .output import _json_value
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"csv": out_dir / "series.csv", "json": out_dir / "series.json"}
    columns = [n for n in SHOWN if any(n in r["numbers"] for r in series["runs"])]
    with open(paths["csv"], "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["seed", *columns, "failed"])
        for r in series["runs"]:
            writer.writerow([r["seed"], *(repr(float(r["numbers"].get(c, math.nan)))
                                          for c in columns), r["no_failure"] is None])
    paths["json"].write_text(json.dumps(_json_value(series), indent=2) + "\n")
    if any(r["fragments"] for r in series["runs"]):
        import matplotlib
        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        for r in series["runs"]:
            if r["fragments"]:
                size, fraction = passing(r["fragments"]["size"], r["fragments"]["mass"])
                ax.step(size * 1e3, fraction, where="post", label=f"seed {r['seed']}")
        ax.set_xscale("log")
        ax.set_xlabel("fragment size (mm)")
        ax.set_ylabel("mass fraction passing")
        ax.legend(fontsize=8)
        fig.tight_layout()
        paths["figure"] = out_dir / "lab_series_fragments.png"
        fig.savefig(paths["figure"], dpi=100)
        plt.close(fig)
    return paths

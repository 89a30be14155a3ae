"""The Mohr-Coulomb envelope of a specimen: triaxial tests at several confining stresses
(a Dask ensemble, or one after the other), and the cohesion and friction angle of the
straight line through their peaks.

Mohr-Coulomb in principal stresses: sigma_1 = 2 c cos(phi) / (1 - sin(phi))
+ sigma_3 (1 + sin(phi)) / (1 - sin(phi)). A least-squares line sigma_1 = a + b sigma_3
through the peaks gives sin(phi) = (b - 1) / (b + 1) and c = a (1 - sin(phi)) /
(2 cos(phi)); its R^2 says how straight the envelope is.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

COLUMNS = ("confining_stress", "peak_stress", "peak_deviator_stress", "strain_at_peak",
           "young_modulus_secant", "confining_stress_error_final", "broken_bonds_final",
           "n_particles")


def mohr_coulomb(sigma3, sigma1):
    """{"cohesion": Pa, "friction_angle": degrees, "r_squared", "intercept": Pa,
    "slope"} of the least-squares line sigma_1 = intercept + slope sigma_3 through the
    peak stresses (Pa; at least two distinct sigma_3). A slope of 1 (to round-off: 1e-9)
    is a material without friction (Tresca: phi = 0, c = (sigma_1 - sigma_3) / 2); NaN
    angle and cohesion when the slope is below it (no Mohr-Coulomb line)."""
    sigma3, sigma1 = np.asarray(sigma3, float), np.asarray(sigma1, float)
    if sigma3.size < 2 or np.ptp(sigma3) == 0.0:
        raise ValueError("a Mohr-Coulomb envelope needs at least two confining stresses")
    slope, intercept = np.polyfit(sigma3, sigma1, 1)
    fitted = intercept + slope * sigma3
    total = float(np.sum((sigma1 - sigma1.mean()) ** 2))
    r_squared = 1.0 - float(np.sum((sigma1 - fitted) ** 2)) / total if total > 0 else 1.0
    out = {"intercept": float(intercept), "slope": float(slope), "r_squared": r_squared,
           "cohesion": math.nan, "friction_angle": math.nan}
    if slope >= 1.0 - 1e-9:
        sine = max(0.0, (slope - 1.0) / (slope + 1.0))
        phi = math.asin(sine)
        out["friction_angle"] = math.degrees(phi)
        out["cohesion"] = float(intercept * (1.0 - sine) / (2.0 * math.cos(phi)))
    return out


def _one(spec, overrides, sigma3):
    """One triaxial test of the spec at confining stress sigma3 (Pa): its numbers (a
    module-level function: what the Dask workers run)."""
    from .procedures import triaxial
    from .spec import load_spec
    changes = {**(overrides or {}), "test.confining_stress": float(sigma3)}
    specimen, settings, _ = load_spec(spec, changes)
    result = triaxial(specimen, settings)
    numbers = {k: result.numbers.get(k, math.nan) for k in COLUMNS}
    numbers["no_failure"] = result.no_failure
    return numbers


def run_envelope(spec, pressures, *, overrides=None, scheduler="serial", workers=None):
    """Triaxial tests of lab spec ``spec`` at each confining stress of ``pressures`` (Pa)
    and their Mohr-Coulomb fit. scheduler: "serial" (this process), None (a LocalCluster
    of ``workers`` processes) or a Dask scheduler address. Returns {"tests": [numbers per
    pressure], "fit": mohr_coulomb(...) of the tests that failed, "failed": the
    pressures whose specimen did not fail (no peak) and why, "spec", "spec_text",
    "overrides": what ran (for the report)}."""
    from .series import ensemble
    pressures = [float(p) for p in pressures]
    tests = ensemble(_one, [(str(spec), overrides, p) for p in pressures],
                     scheduler=scheduler, workers=workers)
    failed = {p: t["no_failure"] for p, t in zip(pressures, tests) if t["no_failure"]}
    good = [t for t in tests if not t["no_failure"]]
    if len(good) < 2:
        raise ValueError("fewer than two confining stresses gave a failure, so there is "
                         "no envelope: " + "; ".join(f"{p:.4g} Pa: {why}"
                                                     for p, why in failed.items()))
    fit = mohr_coulomb([t["confining_stress"] for t in good],
                       [t["peak_stress"] for t in good])
    return {"tests": tests, "fit": fit, "failed": failed, "spec": str(spec),
            "spec_text": Path(spec).read_text() if Path(spec).is_file() else None,
            "overrides": dict(overrides or {})}


def write_envelope(summary, out_dir):
    """envelope.csv (one row per test), envelope.json (the fit and the tests) and
    lab_envelope.png (Mohr circles at the peaks and the envelope) in ``out_dir``;
    returns {name: path}."""
    from .output import _json_value
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"csv": out_dir / "envelope.csv", "json": out_dir / "envelope.json",
             "figure": out_dir / "lab_envelope.png"}
    with open(paths["csv"], "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        for t in summary["tests"]:
            writer.writerow([repr(float(t[k])) for k in COLUMNS])
    paths["json"].write_text(json.dumps(_json_value({
        "fit": summary["fit"], "tests": summary["tests"],
        "failed": {str(k): v for k, v in summary["failed"].items()},
        **{k: summary[k] for k in ("spec", "spec_text", "overrides") if k in summary},
        "units": {"cohesion": "Pa", "friction_angle": "degree", "intercept": "Pa",
                  "slope": "1", "r_squared": "1"}}), indent=2) + "\n")
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    top = 0.0
    for t in summary["tests"]:
        if t["no_failure"]:
            continue
        s3, s1 = t["confining_stress"] * 1e-6, t["peak_stress"] * 1e-6
        angle = np.linspace(0.0, math.pi, 100)
        centre, radius = 0.5 * (s1 + s3), 0.5 * (s1 - s3)
        ax.plot(centre + radius * np.cos(angle), radius * np.sin(angle), "-")
        top = max(top, s1)
    fit = summary["fit"]
    if math.isfinite(fit["friction_angle"]):
        sigma = np.linspace(0.0, top, 50)
        ax.plot(sigma, fit["cohesion"] * 1e-6 + sigma * math.tan(math.radians(
            fit["friction_angle"])), "k--", label=f"c = {fit['cohesion'] * 1e-6:.3g} MPa, "
            f"phi = {fit['friction_angle']:.3g} deg, R^2 = {fit['r_squared']:.3f}")
        ax.legend()
    ax.set_xlabel("normal stress (MPa)")
    ax.set_ylabel("shear stress (MPa)")
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(paths["figure"], dpi=100)
    plt.close(fig)
    return paths

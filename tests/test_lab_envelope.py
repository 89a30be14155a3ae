"""The Mohr-Coulomb envelope: the fit against the criterion's closed form, and
``bondem lab envelope`` on a parallel-bonded cylinder (examples/lab_parallel.toml) (its friction angle makes the bonds'
shear strength grow with confinement) as a Dask ensemble."""
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.lab.envelope import mohr_coulomb

# a simple cubic lattice of touching spheres (docs/lab.md's closed forms)
LATTICE = """
[specimen]
lattice = [3, 3, 6]
radius = 1e-3
diameter_ratio = 0.5
[specimen.material]
density = 2500.0
young_modulus = 1e8
[specimen.bond_material]
young_modulus = 1e8
normal_strength = 1e6
tangential_strength = 1e6
"""
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "lab_parallel.toml"


def test_the_fit_returns_the_criterions_cohesion_and_angle():
    cohesion, phi = 2.5e6, math.radians(33.0)
    sigma3 = np.array([0.0, 1e6, 3e6, 7e6])
    sigma1 = (2 * cohesion * math.cos(phi) / (1 - math.sin(phi))
              + sigma3 * (1 + math.sin(phi)) / (1 - math.sin(phi)))
    fit = mohr_coulomb(sigma3, sigma1)
    assert fit["cohesion"] == pytest.approx(cohesion, rel=1e-9)
    assert fit["friction_angle"] == pytest.approx(33.0, rel=1e-9)
    assert fit["r_squared"] == pytest.approx(1.0, abs=1e-12)
    # on the envelope: the Mohr circle of each test touches tau = c + sigma tan(phi)
    centre, radius = 0.5 * (sigma1 + sigma3), 0.5 * (sigma1 - sigma3)
    np.testing.assert_allclose(radius, (cohesion + centre * math.tan(phi)) * math.cos(phi),
                               rtol=1e-9)
    noisy = mohr_coulomb(sigma3, sigma1 * np.array([1.0, 1.05, 0.97, 1.0]))
    assert noisy["r_squared"] < 0.999
    flat = mohr_coulomb(sigma3, 5e6 + 0.5 * sigma3)      # slope below 1: no friction
    assert math.isnan(flat["friction_angle"]) and math.isnan(flat["cohesion"])
    with pytest.raises(ValueError, match="two confining"):
        mohr_coulomb([1e6, 1e6], [3e6, 3.1e6])


def test_envelope_of_a_parallel_bonded_cylinder_is_a_straight_line(tmp_path):
    spec = EXAMPLE   # the README's and docs/lab.md's example
    out = tmp_path / "env"
    result = CliRunner().invoke(main, ["lab", "envelope", str(spec), "--out", str(out),
                                       "--confining", "2e5", "--confining", "6e5",
                                       "--confining", "1.2e6", "--workers", "2",
                                       # the fast rate: 1/16 the default's steps
                                       "--set", "test.rate_rule=wave"])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "envelope.json").read_text())
    assert saved["overrides"] == {"test.rate_rule": "wave"}
    fit, tests = saved["fit"], saved["tests"]
    assert fit["r_squared"] > 0.98
    assert 5.0 < fit["friction_angle"] < 60.0 and fit["cohesion"] > 0.0
    peaks = [t["peak_stress"] for t in tests]
    assert peaks == sorted(peaks) and all(t["no_failure"] is None for t in tests)
    # the fit is the one of its own table's peaks
    again = mohr_coulomb([t["confining_stress"] for t in tests], peaks)
    assert again["cohesion"] == pytest.approx(fit["cohesion"], rel=1e-12)
    assert (out / "lab_envelope.png").is_file() and (out / "envelope.csv").is_file()
    assert "friction angle" in result.output
    # the report of the folder the command names: the fit and its spec
    assert result.output.endswith(f"next: bondem report {out}\n")
    assert saved["spec"] == str(spec) and saved["spec_text"] == spec.read_text()
    report = CliRunner().invoke(main, ["report", str(out)])
    assert report.exit_code == 0, report.output
    assert f"{fit['cohesion']:.4g}" in (out / "envelope_report.html").read_text()


def test_an_envelope_without_failures_is_refused(tmp_path):
    spec = tmp_path / "lattice.toml"
    spec.write_text(LATTICE.replace("[3, 3, 6]", '[6, 6, 12]\nshape = "cylinder"')
                    + "[test]\nmax_strain = 0.0005\n")
    result = CliRunner().invoke(main, ["lab", "envelope", str(spec), "--scheduler", "serial",
                                       "--confining", "1e4", "--confining", "2e4"])
    assert result.exit_code == 2
    assert "fewer than two confining stresses gave a failure" in result.output
    assert "did not fail" in result.output
    result = CliRunner().invoke(main, ["lab", "envelope", str(spec), "--confining", "1e4"])
    assert result.exit_code == 2 and "--confining" in result.output


def test_series_statistics_are_the_sample_mean_and_deviation():
    from bondem.lab.series import summarise
    runs = [{"numbers": {"ucs": v, "n_particles": 10}} for v in (1.0, 2.0, 4.0)]
    runs.append({"numbers": {"ucs": math.nan, "n_particles": 10}})   # did not fail
    out = summarise(runs)
    assert out["ucs"]["count"] == 3
    assert out["ucs"]["mean"] == pytest.approx(7.0 / 3.0, rel=1e-15)
    assert out["ucs"]["std"] == pytest.approx(math.sqrt(((1 - 7 / 3) ** 2 + (2 - 7 / 3) ** 2
                                                         + (4 - 7 / 3) ** 2) / 2), rel=1e-12)
    assert out["ucs"]["cv"] == pytest.approx(out["ucs"]["std"] / (7.0 / 3.0), rel=1e-15)
    assert out["n_particles"]["std"] == 0.0


def test_a_series_of_seeds_from_the_command_line(tmp_path):
    """A lattice is the same for every seed: the series' runs agree, with no scatter, at
    the lattice's closed-form strength sigma_b A_b / a^2."""
    spec = tmp_path / "lattice.toml"
    spec.write_text(LATTICE)
    out = tmp_path / "series"
    result = CliRunner().invoke(main, ["lab", "tension", str(spec), "--seed", "1", "--seed",
                                       "2", "--scheduler", "serial", "--out", str(out)])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "series.json").read_text())
    assert [r["seed"] for r in saved["runs"]] == [1, 2]
    strength = saved["summary"]["tensile_strength"]
    assert strength["std"] == 0.0 and strength["count"] == 2
    assert strength["mean"] == pytest.approx(1e6 * math.pi * 0.25e-6 / 4e-6, rel=0.02)
    rows = (out / "series.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith("seed,")
    assert "tensile strength:" in result.output and "Pa" in result.output

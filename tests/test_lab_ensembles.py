"""The lab's ensembles without their simulations (bondem.lab.envelope, bondem.lab.series):
the runners replaced by tests of known outcome, so that what is read off the runs (a
Mohr-Coulomb fit, a series' statistics) and what is written (CSV, JSON, the figures'
data) is checked against definitions: Mohr circles through (sigma_3, 0) and
(sigma_1, 0), tangent to the fitted envelope; sample statistics; sieve curves."""
import csv
import json
import math

import matplotlib.figure
import numpy as np
import pytest

from bondem.lab import envelope, series

COHESION, PHI = 4e6, math.radians(31.0)


def peak(sigma3):
    """sigma_1 (Pa) on the Mohr-Coulomb line of COHESION and PHI."""
    s = math.sin(PHI)
    return 2 * COHESION * math.cos(PHI) / (1 - s) + sigma3 * (1 + s) / (1 - s)


@pytest.fixture
def figures(monkeypatch):
    """Every figure saved, kept for its data (and still written)."""
    saved = []
    original = matplotlib.figure.Figure.savefig

    def keep(self, *args, **kwargs):
        saved.append(self)
        return original(self, *args, **kwargs)
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", keep)
    return saved


@pytest.fixture
def triaxials(monkeypatch):
    """envelope's runner replaced: a test at sigma_3 peaks on the line, except at 5 MPa,
    whose specimen does not fail; the calls are recorded."""
    calls = []

    def one(spec, overrides, sigma3):
        calls.append((spec, overrides, sigma3))
        failed = "no peak before max_strain" if sigma3 == 5e6 else None
        numbers = {k: float(len(calls)) for k in envelope.COLUMNS}
        numbers.update(confining_stress=sigma3, peak_stress=math.nan if failed else
                       peak(sigma3), no_failure=failed)
        numbers["peak_deviator_stress"] = numbers["peak_stress"] - sigma3
        return numbers
    monkeypatch.setattr(envelope, "_one", one)
    return calls


def test_an_envelope_fits_the_tests_that_failed(tmp_path, triaxials, figures):
    summary = envelope.run_envelope(tmp_path / "spec.toml", [1e6, 3, 5e6, 12e6],
                                    overrides={"test.samples": 50})
    assert triaxials == [(str(tmp_path / "spec.toml"), {"test.samples": 50}, p)
                         for p in (1e6, 3.0, 5e6, 12e6)]
    assert all(isinstance(p, float) for _, _, p in triaxials)
    fit = summary["fit"]
    assert fit["cohesion"] == pytest.approx(COHESION, rel=1e-9)
    assert fit["friction_angle"] == pytest.approx(31.0, rel=1e-9)
    assert summary["failed"] == {5e6: "no peak before max_strain"}
    assert [t["confining_stress"] for t in summary["tests"]] == [1e6, 3.0, 5e6, 12e6]

    paths = envelope.write_envelope(summary, tmp_path / "out")
    with open(paths["csv"]) as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == list(envelope.COLUMNS) and len(rows) == 5
    assert float(rows[4][0]) == 12e6 and float(rows[4][1]) == peak(12e6)
    assert rows[3][1] == "nan"
    data = json.loads(paths["json"].read_text())
    assert data["failed"] == {"5000000.0": "no peak before max_strain"}
    assert data["fit"]["cohesion"] == pytest.approx(COHESION, rel=1e-9)
    assert data["tests"][2]["peak_stress"] is None   # NaN written as null
    assert data["units"] == {"cohesion": "Pa", "friction_angle": "degree",
                             "intercept": "Pa", "slope": "1", "r_squared": "1"}
    assert paths["figure"].stat().st_size > 1000
    (ax,) = figures[-1].axes
    *circles, line = ax.lines
    assert len(circles) == 3   # the failed tests'
    tan = math.tan(PHI)
    for circle, sigma3 in zip(circles, (1e6, 3.0, 12e6)):
        x, y = circle.get_data()
        assert x.min() == pytest.approx(sigma3 * 1e-6, abs=1e-9)
        assert x.max() == pytest.approx(peak(sigma3) * 1e-6, rel=1e-9)
        radius, centre = y.max(), 0.5 * (x.max() + x.min())
        assert radius == pytest.approx(0.5 * (x.max() - x.min()), rel=1e-3)
        assert np.all(y >= 0.0)
        # tangent to the envelope tau = c + sigma tan(phi) (in MPa)
        assert (COHESION * 1e-6 + centre * tan) * math.cos(PHI) == pytest.approx(
            0.5 * (x.max() - x.min()), rel=1e-9)
    x, y = line.get_data()
    assert x[0] == 0.0 and x[-1] == pytest.approx(peak(12e6) * 1e-6, rel=1e-12)
    np.testing.assert_allclose(y, COHESION * 1e-6 + x * tan, rtol=1e-9)
    assert line.get_label() == "c = 4 MPa, phi = 31 deg, R^2 = 1.000"
    assert ax.get_xlabel() == "normal stress (MPa)"
    assert ax.get_ylabel() == "shear stress (MPa)"


def test_an_envelope_of_fewer_than_two_failures_is_refused(tmp_path, triaxials):
    with pytest.raises(ValueError) as error:
        envelope.run_envelope(tmp_path / "spec.toml", [5e6, 2e6])
    assert str(error.value) == ("fewer than two confining stresses gave a failure, so "
                                "there is no envelope: 5e+06 Pa: no peak before max_strain")


def test_an_envelope_without_friction_is_drawn_without_its_line(tmp_path, figures):
    tests = [{**{k: 1.0 for k in envelope.COLUMNS}, "confining_stress": s3,
              "peak_stress": 5e6 + 0.5 * s3, "no_failure": None} for s3 in (1e6, 4e6)]
    summary = {"tests": tests, "fit": envelope.mohr_coulomb([1e6, 4e6], [5.5e6, 7e6]),
               "failed": {}}
    envelope.write_envelope(summary, tmp_path)
    (ax,) = figures[-1].axes
    assert len(ax.lines) == 2 and ax.get_legend() is None


@pytest.fixture
def seeds(monkeypatch):
    """series' runner replaced: seed s gives a UCS of s MPa (seed 3 does not fail) and
    fragments of sizes 1, 2 and s mm."""
    calls = []

    def one(spec, test, overrides, seed):
        calls.append((spec, test, overrides, seed))
        failed = "no peak" if seed == 3 else None
        numbers = {"ucs": math.nan if failed else seed * 1e6, "n_particles": 100,
                   "fragments": 2 * seed}
        fragments = {"size": [1e-3, seed * 1e-3, 2e-3], "mass": [1.0, 2.0, 1.0]}
        return {"seed": seed, "numbers": numbers, "no_failure": failed,
                "fragments": fragments if seed != 5 else None}
    monkeypatch.setattr(series, "_one", one)
    return calls


def test_a_series_runs_each_seed_and_summarises_the_failures(tmp_path, seeds, figures):
    out = series.run_series(tmp_path / "spec.toml", "ucs", ["4", 3, 9, 5],
                            overrides={"test.samples": 40})
    assert seeds == [(str(tmp_path / "spec.toml"), "ucs", {"test.samples": 40}, s)
                     for s in (4, 3, 9, 5)]
    assert out["test"] == "ucs" and [r["seed"] for r in out["runs"]] == [4, 3, 9, 5]
    ucs = out["summary"]["ucs"]
    mean = 6e6
    std = math.sqrt(((4e6 - mean) ** 2 + (9e6 - mean) ** 2 + (5e6 - mean) ** 2) / 2)
    assert ucs["count"] == 3 and ucs["mean"] == pytest.approx(mean, rel=1e-15)
    assert ucs["std"] == pytest.approx(std, rel=1e-12)
    assert ucs["cv"] == pytest.approx(std / mean, rel=1e-12)
    assert out["summary"]["fragments"]["count"] == 4
    assert "tensile_strength" not in out["summary"]

    paths = series.write_series(out, tmp_path / "out")
    with open(paths["csv"]) as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["seed", "ucs", "fragments", "n_particles", "failed"]
    assert rows[1] == ["4", "4000000.0", "8.0", "100.0", "True"]
    assert rows[2] == ["3", "nan", "6.0", "100.0", "False"]
    data = json.loads(paths["json"].read_text())
    assert data["runs"][1]["numbers"]["ucs"] is None
    assert data["summary"]["ucs"]["mean"] == pytest.approx(mean, rel=1e-15)
    (ax,) = figures[-1].axes
    assert [line.get_label() for line in ax.lines] == ["seed 4", "seed 3", "seed 9"]
    for line, seed in zip(ax.lines, (4, 3, 9)):
        x, y = line.get_data()
        order = np.argsort([1.0, seed, 2.0], kind="stable")
        np.testing.assert_allclose(x, np.array([1.0, seed, 2.0])[order], rtol=1e-12)
        np.testing.assert_allclose(y, np.cumsum(np.array([1.0, 2.0, 1.0])[order]) / 4.0)
        assert line.get_drawstyle() == "steps-post"
    assert ax.get_xscale() == "log"
    assert ax.get_xlabel() == "fragment size (mm)"
    assert ax.get_ylabel() == "mass fraction passing"
    assert paths["figure"].name == "lab_series_fragments.png"


def test_a_series_without_fragments_has_no_figure(tmp_path):
    runs = [{"seed": 1, "numbers": {"ucs": 1e6}, "no_failure": None, "fragments": None},
            {"seed": 2, "numbers": {"ucs": 3e6}, "no_failure": None, "fragments": None}]
    out = {"test": "ucs", "runs": runs, "summary": series.summarise(runs)}
    paths = series.write_series(out, tmp_path)
    assert sorted(paths) == ["csv", "json"] and not (tmp_path / "lab_series_fragments.png"
                                                     ).exists()
    assert out["summary"]["ucs"]["std"] == pytest.approx(math.sqrt(2e12), rel=1e-12)


def test_statistics_of_one_run_and_of_a_zero_mean():
    one = series.summarise([{"numbers": {"ucs": 2e6}}])["ucs"]
    assert one["count"] == 1 and one["mean"] == 2e6
    assert math.isnan(one["std"]) and math.isnan(one["cv"])
    zero = series.summarise([{"numbers": {"poisson_ratio": v}} for v in (-0.1, 0.1)])
    assert zero["poisson_ratio"]["mean"] == 0.0 and math.isnan(zero["poisson_ratio"]["cv"])
    negative = series.summarise([{"numbers": {"poisson_ratio": v}} for v in (-0.1, -0.3)])
    assert negative["poisson_ratio"]["cv"] == pytest.approx(math.sqrt(0.02) / 0.2,
                                                            rel=1e-12)


def test_the_ensemble_runs_in_this_process_in_order():
    assert series.ensemble(pow, [(2, 3), (3, 2), (5, 0)]) == [8, 9, 1]

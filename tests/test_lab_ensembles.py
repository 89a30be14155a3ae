"""The lab's ensembles without their simulations (bondem.lab.envelope, bondem.lab.series):
the runners replaced by tests of known outcome, so that what is read off the runs (a
Mohr-Coulomb fit, a series' statistics) and what is written (CSV, JSON, the figures'
data) is checked against definitions: Mohr circles through (sigma_3, 0) and
(sigma_1, 0), tangent to the fitted envelope; sample statistics; sieve curves."""
import csv
import json
import math
import struct

import matplotlib.figure
import numpy as np
import pytest

from bondem.lab import envelope, procedures, series
from bondem.lab import spec as spec_module

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


def png_size(path):
    """(width, height) in pixels of a PNG file (its IHDR chunk)."""
    return struct.unpack(">II", path.read_bytes()[16:24])


def test_the_fit_by_its_definitions():
    s = math.sin(PHI)
    sigma3 = np.array([0.5e6, 2e6, 7e6, 11e6])
    fit = envelope.mohr_coulomb(sigma3, [peak(x) for x in sigma3])
    assert set(fit) == {"cohesion", "friction_angle", "r_squared", "intercept", "slope"}
    assert fit["intercept"] == pytest.approx(2 * COHESION * math.cos(PHI) / (1 - s),
                                             rel=1e-9)
    assert fit["slope"] == pytest.approx((1 + s) / (1 - s), rel=1e-12)
    # R^2 of a least-squares line is the squared correlation coefficient
    scattered = np.array([peak(x) for x in sigma3]) * [1.0, 1.04, 0.97, 1.01]
    assert envelope.mohr_coulomb(sigma3, scattered)["r_squared"] == pytest.approx(
        np.corrcoef(sigma3, scattered)[0, 1] ** 2, rel=1e-12)
    # a few pascals of scatter about a flat line: still its own R^2, not 1
    tiny = 5e6 + np.array([0.0, 0.3, 0.1, 0.2])
    assert envelope.mohr_coulomb(sigma3, tiny)["r_squared"] == pytest.approx(
        np.corrcoef(sigma3, tiny)[0, 1] ** 2, rel=1e-6)
    # no scatter at all about a flat line: a perfect fit (and no friction)
    flat = envelope.mohr_coulomb(sigma3, np.full(4, 5e6))
    assert flat["r_squared"] == 1.0 and math.isnan(flat["friction_angle"])
    # a weak friction angle (10 degrees: slope 1.42) and none at all (Tresca: slope 1 to
    # round-off, phi = 0, c = (sigma_1 - sigma_3) / 2)
    s10 = math.sin(math.radians(10.0))
    weak = envelope.mohr_coulomb(sigma3, 1e6 + sigma3 * (1 + s10) / (1 - s10))
    assert weak["friction_angle"] == pytest.approx(10.0, rel=1e-9)
    for sigma3 in ([0.5e6, 2e6, 7e6, 11e6], [1e5, 3e5, 6e5], [1.3e6, 2.9e6, 4.1e6]):
        tresca = envelope.mohr_coulomb(sigma3, np.array(sigma3) + 8e6)
        assert tresca["friction_angle"] == pytest.approx(0.0, abs=1e-6)
        assert tresca["cohesion"] == pytest.approx(4e6, rel=1e-9)
    with pytest.raises(ValueError) as error:
        envelope.mohr_coulomb([2e6], [9e6])
    assert str(error.value) == "a Mohr-Coulomb envelope needs at least two confining stresses"


def test_one_triaxial_of_the_envelope(tmp_path, monkeypatch):
    calls = []

    class Result:
        numbers = {"confining_stress": 2e6, "peak_stress": 9e6, "n_particles": 512,
                   "unrelated": 1.0}
        no_failure = "no peak"

    def load(spec, overrides):
        calls.append(("load", spec, overrides))
        return "specimen", "settings", "text"

    def triaxial(specimen, settings):
        calls.append(("triaxial", specimen, settings))
        return Result()
    monkeypatch.setattr(spec_module, "load_spec", load)
    monkeypatch.setattr(procedures, "triaxial", triaxial)
    numbers = envelope._one("a.toml", {"test.samples": 9}, 2_000_000)
    assert calls == [("load", "a.toml", {"test.samples": 9,
                                         "test.confining_stress": 2e6}),
                     ("triaxial", "specimen", "settings")]
    assert isinstance(calls[0][2]["test.confining_stress"], float)
    assert list(numbers) == [*envelope.COLUMNS, "no_failure"]
    assert numbers["peak_stress"] == 9e6 and numbers["n_particles"] == 512
    assert math.isnan(numbers["strain_at_peak"]) and numbers["no_failure"] == "no peak"
    calls.clear()
    envelope._one("a.toml", None, 1e6)
    assert calls[0] == ("load", "a.toml", {"test.confining_stress": 1e6})


def test_an_envelope_of_two_weak_tests_passes_its_scheduler_on(tmp_path, monkeypatch,
                                                              figures):
    seen = {}

    def ensemble(function, items, *, scheduler="serial", workers=None):
        seen.update(scheduler=scheduler, workers=workers)
        return [{**{k: 1.0 for k in envelope.COLUMNS}, "confining_stress": p,
                 "peak_stress": 50e3 + 3.0 * p, "no_failure": None}
                for _, _, p in items]
    monkeypatch.setattr(series, "ensemble", ensemble)
    summary = envelope.run_envelope("s.toml", [10e3, 40e3], scheduler="tcp://h:8786",
                                    workers=3)
    assert seen == {"scheduler": "tcp://h:8786", "workers": 3}
    # sigma_1 = 50 kPa + 3 sigma_3: sin(phi) = 1/2, c = 50 kPa / (2 sqrt 3)
    assert summary["fit"]["friction_angle"] == pytest.approx(30.0, rel=1e-9)
    paths = envelope.write_envelope(summary, tmp_path / "a" / "b")
    assert [paths[k].name for k in ("csv", "json", "figure")] == [
        "envelope.csv", "envelope.json", "lab_envelope.png"]
    assert paths["json"].read_text().startswith('{\n  "fit": {\n    "intercept"')
    assert png_size(paths["figure"]) == (600, 400)
    (ax,) = figures[-1].axes
    *circles, line = ax.lines
    # a weak material (kPa): the envelope drawn to its largest peak, 0.17 MPa
    assert line.get_data()[0][-1] == pytest.approx(0.17, rel=1e-12)
    assert line.get_linestyle() == "--" and line.get_color() == "k"
    assert all(len(c.get_data()[0]) >= 100 for c in circles)


def test_an_envelope_refused_lists_every_test_that_did_not_fail(monkeypatch):
    monkeypatch.setattr(series, "ensemble", lambda function, items, **kw: [
        {"confining_stress": p, "peak_stress": 1.0, "no_failure": f"why {k}"}
        for k, (_, _, p) in enumerate(items)])
    with pytest.raises(ValueError) as error:
        envelope.run_envelope("s.toml", [1e6, 2.5e6])
    assert str(error.value).endswith("envelope: 1e+06 Pa: why 0; 2.5e+06 Pa: why 1")


class FakeDask:
    """Stands in for ``distributed``: records the cluster and client made, runs each
    submitted call at once."""

    def __init__(self):
        self.log = []

    def LocalCluster(self, **kwargs):
        self.log.append(("cluster", kwargs))
        return self

    def Client(self, address, **kwargs):
        self.log.append(("client", address if address is not self else "cluster", kwargs))
        return self

    def submit(self, function, *args, **kwargs):
        self.log.append(("submit", function.__name__, args, kwargs))
        outcome = function(*args)
        return type("Future", (), {"result": lambda _: outcome})()

    def close(self):
        self.log.append(("close",))


def test_the_ensemble_on_dask_one_single_threaded_process_per_run(monkeypatch):
    import os
    import sys
    fake = FakeDask()
    monkeypatch.setitem(sys.modules, "distributed", fake)
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    assert series.ensemble(pow, [(2, 3), (3, 2), (5, 0)], scheduler=None) == [8, 9, 1]
    # a worker process per run up to the cores, each with one thread, and each run with
    # one Numba thread whatever the worker imported first: the runs do not share cores; a run is not pure (two seeds' equal arguments are two
    # runs); the cluster made here is closed after
    assert fake.log == [
        ("cluster", {"n_workers": 3, "threads_per_worker": 1, "processes": True,
                     "dashboard_address": None,
                     "env": {"OMP_NUM_THREADS": "1"}}),
        ("client", "cluster", {}),
        ("submit", "single_threaded", (pow, 2, 3), {"pure": False}),
        ("submit", "single_threaded", (pow, 3, 2), {"pure": False}),
        ("submit", "single_threaded", (pow, 5, 0), {"pure": False}),
        ("close",), ("close",)]
    fake.log.clear()
    series.ensemble(pow, [(2, 1)] * 12, scheduler=None)
    assert fake.log[0][1]["n_workers"] == 8
    fake.log.clear()
    series.ensemble(pow, [(2, 1)] * 12, scheduler=None, workers=5)
    assert fake.log[0][1]["n_workers"] == 5
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    fake.log.clear()
    series.ensemble(pow, [(2, 1)] * 3, scheduler=None)
    assert fake.log[0][1]["n_workers"] == 1
    # a scheduler's address: a client of it, nothing of ours to close but the client
    fake.log.clear()
    assert series.ensemble(pow, [(2, 2)], scheduler="tcp://h:8786") == [4]
    assert fake.log == [("client", "tcp://h:8786", {"timeout": "30s"}),
                        ("submit", "single_threaded", (pow, 2, 2), {"pure": False}),
                        ("close",)]
    # a run that raises still closes the client and the cluster
    fake.log.clear()
    with pytest.raises(ZeroDivisionError):
        series.ensemble(divmod, [(1, 0)], scheduler=None)
    assert fake.log[-2:] == [("close",), ("close",)]


def test_one_run_of_a_series(monkeypatch):
    calls = []

    class Result:
        numbers = {"ucs": 3e6}
        no_failure = None
        fragments = {"size": np.array([1e-3, 2e-3]), "mass": np.array([1.0, 3.0])}

    def load(spec, overrides):
        calls.append(("load", spec, overrides))
        return "specimen", "settings", "text"
    monkeypatch.setattr(spec_module, "load_spec", load)
    monkeypatch.setitem(procedures.RUNNERS, "ucs",
                        lambda specimen, settings: calls.append(("ucs", specimen, settings))
                        or Result())
    run = series._one("a.toml", "ucs", {"test.samples": 5}, 7)
    assert calls == [("load", "a.toml", {"test.samples": 5, "specimen.seed": 7}),
                     ("ucs", "specimen", "settings")]
    assert run == {"seed": 7, "numbers": {"ucs": 3e6}, "no_failure": None,
                   "fragments": {"size": [1e-3, 2e-3], "mass": [1.0, 3.0]}}
    assert type(run["fragments"]["size"]) is list
    Result.fragments, Result.no_failure = None, "no peak"
    calls.clear()
    run = series._one("a.toml", "ucs", None, 2)
    assert calls[0] == ("load", "a.toml", {"specimen.seed": 2})
    assert run["fragments"] is None and run["no_failure"] == "no peak"


def test_a_series_passes_its_scheduler_on_and_writes_runs_missing_a_number(
        tmp_path, monkeypatch, figures):
    seen = {}

    def ensemble(function, items, *, scheduler="serial", workers=None):
        seen.update(scheduler=scheduler, workers=workers)
        return [{"seed": s, "numbers": {"ucs": 2e6} if s == 1 else {"fragments": 4},
                 "no_failure": None, "fragments": {"size": [1e-3], "mass": [1.0]}}
                for _, _, _, s in items]
    monkeypatch.setattr(series, "ensemble", ensemble)
    out = series.run_series("s.toml", "agglomerate", [1, 2], scheduler=None, workers=2)
    assert seen == {"scheduler": None, "workers": 2}
    paths = series.write_series(out, tmp_path / "a" / "b")
    assert [paths[k].name for k in ("csv", "json", "figure")] == [
        "series.csv", "series.json", "lab_series_fragments.png"]
    rows = list(csv.reader(paths["csv"].open()))
    assert rows[1:] == [["1", "2000000.0", "nan", "True"], ["2", "nan", "4.0", "True"]]
    assert paths["json"].read_text().startswith('{\n  "test": "agglomerate",\n  "runs"')
    assert png_size(paths["figure"]) == (600, 400)
    (ax,) = figures[-1].axes
    assert [t.get_fontsize() for t in ax.get_legend().get_texts()] == [8.0, 8.0]

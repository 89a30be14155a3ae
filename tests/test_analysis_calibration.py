"""The calibration's figures and page (analysis/calibration.py) against what they show:
each figure read back from its artists (a target's band at 1 +- its tolerance and its
prediction over the target with the seeds' scatter; every trial in the parameter plots at
its values, coloured by log10 of its misfit, the consistent ones circled, histograms
over bins spaced as each parameter is searched, log axes for log parameters) and the
HTML parsed back (tables, warnings escaped, the PNGs embedded byte for byte)."""
import math
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from bondem.analysis.calibration import CAPTIONS, percent, write_figures, write_page
from bondem.calibrate import Calibration, Parameter, Target
from test_analysis_report import Page

matplotlib.use("Agg")

E_KEY = "specimen.bond_material.young_modulus"
S_KEY = "specimen.bond_material.normal_strength"
R_KEY = "specimen.bond_materials.rock.poisson_ratio"     # a name of four parts


def _calibration(tmp_path):
    return Calibration(tmp_path / "rock <1>.toml", tmp_path / "spec.toml",
                       [Parameter(E_KEY, 2e7, 2e9, log=True), Parameter(S_KEY, 3e5, 3e7,
                                                                        log=True),
                        Parameter(R_KEY, 0.1, 0.4)],
                       [Target("young_modulus_secant", "ucs", 5.6e8, 0.03),
                        Target("tensile_strength", "brazilian", 1.2e7, 0.05),
                        Target("poisson_ratio", "ucs", -0.25, 0.2)])


ROWS = {
    0: {"trial": 0.0, E_KEY: 2e8, S_KEY: 3e6, R_KEY: 0.25, "misfit": 3.2e3},
    1: {"trial": 1.0, E_KEY: 7e8, S_KEY: 2.4e7, R_KEY: 0.25, "misfit": 1.5e-3},
    2: {"trial": 2.0, E_KEY: 6.9e8, S_KEY: 2.5e7, R_KEY: 0.13, "misfit": 0.4},
    3: {"trial": 3.0, E_KEY: 3e7, S_KEY: 4e5, R_KEY: 0.39, "misfit": math.inf},
    4: {"trial": 4.0, E_KEY: 1.9e9, S_KEY: 3.1e5, R_KEY: 0.31, "misfit": 2e-9},
    5: {"trial": 5.0, E_KEY: 9e8, S_KEY: 1e7, R_KEY: 0.2, "misfit": 4e9},
}
SUMMARY = {
    "best": {"trial": 1, "misfit": 1.5e-3,
             "parameters": {E_KEY: 7e8, S_KEY: 2.4e7, R_KEY: 0.25},
             "predictions": {"young_modulus_secant": 5.7e8, "tensile_strength": 1.14e7,
                             "poisson_ratio": None}},
    "consistent": [{"trial": 1}, {"trial": 2}],
    "seed_scatter": {"young_modulus_secant": {"std": 1.12e7}},
    "identifiability": {E_KEY: {"verdict": "identified: +-0.58 %"},
                        S_KEY: {"verdict": "weakly identified: +-30 % of its range"},
                        R_KEY: {"verdict": "not identifiable"}},
    "trials": 5, "simulations": 16,
    "warnings": ["a < b & c", "seed 2 failed"],
}


@pytest.fixture
def drawn(tmp_path, monkeypatch):
    """The figures write_figures saves, kept open for reading."""
    figures = {}
    save = Figure.savefig

    def keep(self, path, **kwargs):
        figures[Path(path).stem] = (self, kwargs)
        return save(self, path, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    write_figures(_calibration(tmp_path), ROWS, SUMMARY, tmp_path)
    return figures, tmp_path


def test_percent_has_two_significant_digits():
    assert [percent(x) for x in (0.0024, 0.03, 0.125, 1.5, 0.005793)] == \
        ["0.24 %", "3 %", "12 %", "1.5e+02 %", "0.58 %"]


def test_targets_figure_shows_each_prediction_over_its_target(drawn):
    figures, folder = drawn
    fig, kwargs = figures["calibration_targets"]
    assert kwargs == {"dpi": 100}
    assert tuple(fig.get_size_inches()) == (6.0, 3.5)
    (ax,) = fig.axes
    bands = [c for c in ax.collections if c.get_paths() and not hasattr(c, "get_segments")]
    assert len(bands) == 3
    for k, (band, tolerance) in enumerate(zip(bands, (0.03, 0.05, 0.2))):
        vertices = band.get_paths()[0].vertices
        assert vertices[:, 0].min() == pytest.approx(k - 0.4)
        assert vertices[:, 0].max() == pytest.approx(k + 0.4)
        assert vertices[:, 1].min() == pytest.approx(1 - tolerance)
        assert vertices[:, 1].max() == pytest.approx(1 + tolerance)
        assert to_rgba(band.get_facecolor()[0]) == to_rgba("0.85")
    points = [line for line in ax.lines if line.get_marker() == "o"]
    ratios = [float(p.get_ydata()[0]) for p in points]
    assert [float(p.get_xdata()[0]) for p in points] == [0.0, 1.0, 2.0]
    assert ratios[:2] == pytest.approx([5.7 / 5.6, 1.14 / 1.2], rel=1e-14)
    assert math.isnan(ratios[2])                         # no prediction
    assert all(to_rgba(p.get_color()) == to_rgba("C0") for p in points)
    # the error bar of the first target: its seeds' std over |target|
    bars = [c for c in ax.collections if hasattr(c, "get_segments")]
    first = bars[0].get_segments()[0]
    assert first[:, 1] == pytest.approx([5.7 / 5.6 - 1.12e7 / 5.6e8,
                                         5.7 / 5.6 + 1.12e7 / 5.6e8], rel=1e-12)
    assert [s.get_segments()[0][1, 1] - s.get_segments()[0][0, 1] for s in bars[1:2]] == [0]
    # caps 4 points wide: drawn as markers 8 points across
    caps = [line for line in ax.lines if line.get_marker() == "_"]
    assert len(caps) == 6 and {c.get_markersize() for c in caps} == {8.0}
    (unity,) = [line for line in ax.lines if list(line.get_ydata()) == [1.0, 1.0]]
    assert to_rgba(unity.get_color()) == to_rgba("k") and unity.get_linewidth() == 0.8
    assert [t.get_text() for t in ax.get_xticklabels()] == [
        "young modulus secant", "tensile strength", "poisson ratio"]
    assert ax.get_xticklabels()[0].get_rotation() == 15
    assert ax.get_ylabel() == "prediction / target"
    assert (folder / "calibration_targets.png").stat().st_size > 1000


def test_parameter_figure_shows_every_trial_and_the_consistent_ones(drawn):
    figures, folder = drawn
    fig, kwargs = figures["calibration_parameters"]
    assert kwargs == {"dpi": 90}
    assert tuple(fig.get_size_inches()) == pytest.approx((7.6, 7.6))
    axes = np.array(fig.axes).reshape(3, 3)
    values = {key: np.array([r[key] for r in ROWS.values()]) for key in (E_KEY, S_KEY, R_KEY)}
    keys = [E_KEY, S_KEY, R_KEY]
    consistent = np.array([False, True, True, False, False, False])
    # inf as 1e6, 2e-9 clipped at 1e-6 and 4e9 at 1e6
    colour = np.log10([3.2e3, 1.5e-3, 0.4, 1e6, 1e-6, 1e6])
    for i in range(3):
        for j in range(3):
            ax = axes[i, j]
            if i == j:
                low, high = [(2e7, 2e9), (3e5, 3e7), (0.1, 0.4)][i]
                edges = (np.geomspace(low, high, 13) if i < 2 else np.linspace(low, high, 13))
                every, good = ax.containers
                np.testing.assert_allclose([p.get_x() for p in every], edges[:-1], rtol=1e-12)
                assert [p.get_height() for p in every] == list(
                    np.histogram(values[keys[i]], edges)[0])
                assert [p.get_height() for p in good] == list(
                    np.histogram(values[keys[i]][consistent], edges)[0])
                assert to_rgba(every[0].get_facecolor()) == to_rgba("0.6")
                assert to_rgba(good[0].get_facecolor()) == to_rgba("C2")
                assert ax.get_xscale() == ("log" if i < 2 else "linear")
                assert ax.get_yscale() == "linear"
            else:
                trials, circles = ax.collections
                np.testing.assert_array_equal(trials.get_offsets(),
                                              np.column_stack([values[keys[j]],
                                                               values[keys[i]]]))
                np.testing.assert_allclose(trials.get_array(), colour, rtol=1e-12)
                assert trials.get_cmap().name == "viridis_r"
                np.testing.assert_array_equal(
                    circles.get_offsets(),
                    np.column_stack([values[keys[j]], values[keys[i]]])[consistent])
                assert circles.get_facecolor().shape[0] == 0 or \
                    circles.get_facecolor()[0][3] == 0.0
                assert to_rgba(circles.get_edgecolor()[0]) == to_rgba("C3")
                assert list(circles.get_sizes()) == [40.0]
                assert list(trials.get_sizes()) == [12.0]
                assert ax.get_xscale() == ("log" if j < 2 else "linear")
                assert ax.get_yscale() == ("log" if i < 2 else "linear")
            assert ax.get_xlabel() == (["young_modulus", "normal_strength", "poisson_ratio"][j]
                                       if i == 2 else "")
            if i == 2:
                assert ax.xaxis.label.get_fontsize() == 8
            if j == 0:
                assert ax.yaxis.label.get_fontsize() == 8
            assert {t.get_fontsize() for t in ax.xaxis.get_ticklabels()} == {7}
            expected = ("" if j else "young_modulus\n(trials)" if i == 0 else
                        ["young_modulus", "normal_strength", "poisson_ratio"][i])
            assert ax.get_ylabel() == expected
    # only the decades are labelled on a log axis
    for axis in (axes[1, 0].xaxis, axes[0, 1].yaxis, axes[0, 0].xaxis, axes[1, 2].yaxis):
        assert type(axis.get_minor_formatter()).__name__ == "NullFormatter"
    assert (folder / "calibration_parameters.png").stat().st_size > 1000


def test_one_parameter_is_one_histogram(tmp_path, monkeypatch):
    figures = {}
    monkeypatch.setattr(Figure, "savefig",
                        lambda self, path, **kw: figures.setdefault(Path(path).stem, self))
    calibration = _calibration(tmp_path)
    calibration.parameters = calibration.parameters[2:]
    summary = {k: v for k, v in SUMMARY.items() if k != "seed_scatter"}   # no check seeds
    write_figures(calibration, ROWS, summary, tmp_path)
    bars = [c for c in figures["calibration_targets"].axes[0].collections
            if hasattr(c, "get_segments")]
    assert [s.get_segments()[0][1, 1] - s.get_segments()[0][0, 1] for s in bars[:2]] == [0, 0]
    fig = figures["calibration_parameters"]
    assert len(fig.axes) == 1 and tuple(fig.get_size_inches()) == pytest.approx((3.2, 3.2))
    assert fig.axes[0].get_ylabel() == "poisson_ratio\n(trials)"
    assert fig.axes[0].get_xlabel() == "poisson_ratio"


def test_the_page_holds_the_best_set_the_targets_and_the_figures(drawn):
    _, folder = drawn
    calibration = _calibration(folder)
    write_page(calibration, SUMMARY, folder)
    text = (folder / "calibration.html").read_text(encoding="utf-8")
    page = Page(text)
    assert page.title == "bondem calibration"
    assert page.headings[0] == ("h1", "Calibration: rock <1>.toml")
    assert "<h1>Calibration: rock &lt;1&gt;.toml</h1>" in text
    assert "5 trials, 16 simulations; best trial\n1 (misfit 0.0015); 2 parameter sets\n" \
           "meet every target within its uncertainty." in text
    assert '<p class="warning"><b>Warning:</b> a &lt; b &amp; c</p>\n' \
           '<p class="warning"><b>Warning:</b> seed 2 failed</p>\n' in text
    best, targets = page.tables.values()
    assert best == [["parameter", "best", "identifiability"],
                    [E_KEY, "7e+08", "identified: +-0.58 %"],
                    [S_KEY, "2.4e+07", "weakly identified: +-30 % of its range"],
                    [R_KEY, "0.25", "not identifiable"]]
    assert targets == [["target", "test", "value", "uncertainty", "predicted",
                        "scatter over seeds (std)"],
                       ["young_modulus_secant", "ucs", "5.6e+08", "+-3 %", "5.7e+08",
                        "1.12e+07"],
                       ["tensile_strength", "brazilian", "1.2e+07", "+-5 %", "1.14e+07", "n/a"],
                       ["poisson_ratio", "ucs", "-0.25", "+-20 %", "None", "n/a"]]
    assert [h for h in page.headings if h[0] == "h2"] == [
        ("h2", "Best parameters and what the targets fix"), ("h2", "Targets and predictions"),
        ("h2", "Figures")]
    assert [(f[0], f[1], f[3]) for f in page.figures] == [
        (name, name, caption) for name, caption in CAPTIONS.items()]
    for name, _, png, _ in page.figures:
        assert png == (folder / f"{name}.png").read_bytes()
    assert text.count("</figure><figure") == 1 and "</figure></body>" in text


def test_a_page_without_figures_or_warnings(tmp_path):
    calibration = _calibration(tmp_path)
    summary = {k: v for k, v in SUMMARY.items() if k != "warnings"}
    summary["consistent"] = []
    summary["seed_scatter"] = {"tensile_strength": {}, "young_modulus_secant": {"mean": 1.0}}
    write_page(calibration, summary, tmp_path)
    text = (tmp_path / "calibration.html").read_text(encoding="utf-8")
    page = Page(text)
    assert page.figures == [] and "warning" not in text
    assert "0 parameter sets\nmeet every target" in text
    # with the runs' times: the wall time and the runs' sum
    summary["time"] = {"wall_seconds": 388.3, "runs": {"runs": 16, "seconds": 707.4}}
    write_page(calibration, summary, tmp_path)
    assert "5 trials, 16 simulations in 388 s (707 s of runs, calibration_runs.csv); best" \
        in (tmp_path / "calibration.html").read_text(encoding="utf-8")
    assert [row[5] for row in list(page.tables.values())[1][1:]] == ["n/a"] * 3
    (tmp_path / "calibration_parameters.png").write_bytes(b"\x89PNG only this one")
    write_page(calibration, summary, tmp_path)
    page = Page((tmp_path / "calibration.html").read_text(encoding="utf-8"))
    assert [(f[0], f[2]) for f in page.figures] == [("calibration_parameters",
                                                     b"\x89PNG only this one")]

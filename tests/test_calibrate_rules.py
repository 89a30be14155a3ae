"""Calibration's logic against its definitions, on a lab in closed form (no simulation):
E = 0.8 E_bond and tensile strength = 0.5 sigma_bond, with the truth far from the middle
of the bounds (E_bond at 77 % of its log range, sigma_bond at 95 %, where the finite
difference steps down). The first trial sits at the bounds' (geometric) middle, the
second is the scaling rules' guess, exact for this lab; the linearised uncertainty is
the closed form of a forward difference over 5 % of a log range; a table cut by a kill
resumes; the file's errors name the key. Every message is compared whole."""
import csv
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import bondem.analysis.calibration as pages
import bondem.calibrate as calibrate
from bondem.calibrate import (Calibration, CalibrationFailed, Parameter, Table, Target,
                              consistent, load_calibration, misfit, reachable,
                              run_calibration, scaled_guess, summarise)
from bondem.errors import InputError
from bondem.parallel import single_threaded

E_KEY = "specimen.bond_material.young_modulus"
S_KEY = "specimen.bond_material.normal_strength"
T_KEY = "specimen.bond_material.tangential_strength"
TRUE_E, TRUE_S = 7e8, 2.4e7               # Pa: u = 0.772 and 0.9515 of the log ranges
SPEC = """
[specimen]
lattice = [3, 3, 4]
radius = 1e-3
[specimen.material]
density = 2500.0
young_modulus = 1e8
[specimen.bond_material]
young_modulus = 1e8
normal_strength = 1e6
tangential_strength = 1e6
"""
FILE = """spec = "lattice.toml"
budget = 5
batch = 2
seed = 3
[parameters."specimen.bond_material.young_modulus"]
low = 2e7
high = 2e9
log = true
[parameters."specimen.bond_material.normal_strength"]
low = 3e5
high = 3e7
log = true
[parameters."specimen.bond_material.tangential_strength"]
low = 3e5
high = 3e7
log = true
[targets.young_modulus_secant]
test = "tension"
value = 5.6e8
tolerance = 0.03
[targets.tensile_strength]
test = "tension"
value = 1.2e7
tolerance = 0.05
"""


def closed_form_lab(spec, test, overrides):
    """The lab's numbers for a tension test of the lattice: E = 0.8 E_bond, strength =
    0.5 sigma_bond (the tangential strength plays no part in tension)."""
    if Path(spec).name != "lattice.toml" or test != "tension":
        raise ValueError(f"the lab was given {spec!r} and {test!r}")
    return {"young_modulus_secant": 0.8 * overrides[E_KEY],
            "tensile_strength": 0.5 * overrides[S_KEY], "poisson_ratio": 0.2}


@pytest.fixture
def folder(tmp_path, monkeypatch):
    (tmp_path / "lattice.toml").write_text(SPEC)
    (tmp_path / "calib.toml").write_text(FILE)
    monkeypatch.setattr(calibrate, "evaluate", closed_form_lab)
    # the figures and page are analysis/calibration.py's (test_analysis_calibration.py):
    # here only what they are given
    drawn.clear()
    monkeypatch.setattr(pages, "write_figures", lambda *args: drawn.append(("figures", args)))
    monkeypatch.setattr(pages, "write_page", lambda *args: drawn.append(("page", args)))
    return tmp_path


drawn = []


def _calibration(parameters, targets, **kwargs):
    """A Calibration for the stand-in labs below, which have no rate check to run unless
    asked (``rate_check``)."""
    return Calibration(__file__, __file__, parameters, targets,
                       **{"rate_check": False, **kwargs})


# ---------------------------------------------------------------- definitions

def test_a_parameters_place_in_its_bounds():
    linear = Parameter("a", 2.0, 7.0)
    assert linear.unit(3.0) == 0.2 and linear.middle() == 4.5
    log = Parameter("b", 3e5, 3e7, log=True)
    assert log.unit(3e6) == pytest.approx(0.5, rel=1e-14)
    assert log.unit(2.4e7) == pytest.approx(math.log(80.0) / math.log(100.0), rel=1e-14)
    assert log.middle() == pytest.approx(3e6, rel=1e-15)


def test_misfit_sums_the_squared_errors_in_tolerances():
    cal = _calibration([Parameter("a", 0.0, 1.0)],
                       [Target("ucs", "ucs", 5e6, 0.1), Target("poisson_ratio", "ucs", -0.2,
                                                                0.25)])
    # (5.3e6 - 5e6) / 5e5 = 0.6 and (-0.23 + 0.2) / 0.05 = -0.6: |value| in the tolerance
    assert misfit(cal, {"ucs": 5.3e6, "poisson_ratio": -0.23}) == pytest.approx(0.72,
                                                                              rel=1e-12)
    assert misfit(cal, {"ucs": 5.3e6}) == math.inf
    assert misfit(cal, {"ucs": 5.3e6, "poisson_ratio": math.nan}) == math.inf
    assert misfit(cal, {"ucs": math.inf, "poisson_ratio": -0.2}) == math.inf


def test_consistent_means_every_target_within_its_relative_uncertainty():
    cal = _calibration([Parameter("a", 0.0, 1.0)],
                       [Target("ucs", "ucs", 4.0, 0.125), Target("poisson_ratio", "ucs",
                                                                 -2.0, 0.25)])
    assert consistent(cal, {"ucs": 4.5, "poisson_ratio": -2.5})       # both at the edge
    assert consistent(cal, {"ucs": 3.5, "poisson_ratio": -1.5})
    assert not consistent(cal, {"ucs": 4.5000001, "poisson_ratio": -2.0})
    assert not consistent(cal, {"ucs": 4.0, "poisson_ratio": -1.4999999})
    assert not consistent(cal, {"ucs": 4.0})
    assert not consistent(cal, {"ucs": 4.0, "poisson_ratio": math.nan})


def _scaling_case():
    parameters = [Parameter(E_KEY, 2e7, 2e9, log=True), Parameter(S_KEY, 3e5, 3e7, log=True),
                  Parameter(T_KEY, 3e5, 1e7, log=True),
                  Parameter("specimen.material.young_modulus", 1e8, 1e10, log=True),
                  Parameter("specimen.bond_material.poisson_ratio", 0.1, 0.4)]
    targets = [Target("young_modulus_secant", "ucs", 5.6e8, 0.03),
               Target("ucs", "ucs", 1.2e7, 0.05),
               Target("crack_initiation_stress", "ucs", 4.5e6, 0.1),
               Target("poisson_ratio", "ucs", 0.25, 0.1)]
    params = {p.key: p.middle() for p in parameters}
    predictions = {"young_modulus_secant": 1.6e8, "ucs": 1.5e6,
                   "crack_initiation_stress": 6e5, "poisson_ratio": 0.3}
    return _calibration(parameters, targets), params, predictions


def test_scaling_rules_guess_moduli_and_strengths_from_one_trial():
    """E_bond times E_target / E (3.5); every bond strength times the mean of the strength
    targets' ratios ((8 + 7.5) / 2 = 7.75), clipped to its bounds; the particles' modulus
    and the bond's Poisson ratio kept."""
    cal, params, predictions = _scaling_case()
    guess = scaled_guess(cal, params, predictions)
    assert guess[E_KEY] == pytest.approx(7e8, rel=1e-14)
    assert guess[S_KEY] == pytest.approx(3e6 * 7.75, rel=1e-14)
    assert guess[T_KEY] == 1e7                     # sqrt(3e12) x 7.75 = 1.34e7, clipped
    assert guess["specimen.material.young_modulus"] == params[
        "specimen.material.young_modulus"]
    assert guess["specimen.bond_material.poisson_ratio"] == 0.25
    # a prediction of zero (or none) scales nothing; a guess below the bounds is clipped
    cal.targets[0] = Target("young_modulus_secant", "ucs", 1e6, 0.03)
    guess = scaled_guess(cal, params, {**predictions, "ucs": 0.0})
    assert guess[E_KEY] == 2e7 and guess[S_KEY] == pytest.approx(3e6 * 7.5, rel=1e-14)
    unscaled = scaled_guess(cal, params, {"young_modulus_secant": None})
    assert unscaled == {p.key: params[p.key] for p in cal.parameters}


def test_reachable_by_the_scaling_rule():
    """With every modulus (strength) parameter at its bounds the macro E (strength) can
    move between prediction x min(low / value) and x max(high / value) over those
    parameters; a target further than its tolerance beyond is named."""
    cal, params, predictions = _scaling_case()
    assert reachable(cal, params, predictions) == []
    # E: 1.6e8 x [0.1, 10] = [1.6e7, 1.6e9]; 1.6e9 x 1.03 = 1.648e9 is the last reachable
    cal.targets[0] = Target("young_modulus_secant", "ucs", 1.647e9, 0.03)
    assert reachable(cal, params, predictions) == []
    # strengths: the lowest factor from the normal strength's linear bounds (1e5 / 6.55e6),
    # the highest from the tangential strength's log bounds (sqrt(1e7 / 3e5) = 5.77)
    cal.parameters[1] = Parameter(S_KEY, 1e5, 1.3e7)
    params[S_KEY] = 6.55e6
    cal.targets[1] = Target("ucs", "ucs", 9.09e6, 0.05)
    cal.targets[2] = Target("crack_initiation_stress", "ucs", 6e5 * 1e5 / 6.55e6 * 0.91, 0.1)
    assert reachable(cal, params, predictions) == []
    cal.targets[0] = Target("young_modulus_secant", "ucs", 1.65e9, 0.03)
    cal.targets[1] = Target("ucs", "ucs", 9.2e6, 0.05)
    cal.targets[2] = Target("crack_initiation_stress", "ucs", 6e5 * 1e5 / 6.55e6 * 0.89, 0.1)
    assert reachable(cal, params, predictions) == [
        "young_modulus_secant = 1.65e+09 lies outside what the bounds of "
        "specimen.bond_material.young_modulus reach (1.6e+07 to 1.6e+09, by the scaling "
        "rule)",
        "ucs = 9.2e+06 lies outside what the bounds of specimen.bond_material."
        "normal_strength, specimen.bond_material.tangential_strength reach (2.29e+04 to "
        "8.66e+06, by the scaling rule)",
        "crack_initiation_stress = 8153 lies outside what the bounds of specimen."
        "bond_material.normal_strength, specimen.bond_material.tangential_strength reach "
        "(9160 to 3.464e+06, by the scaling rule)"]
    # a negative prediction scales to a sorted range
    cal.targets = [Target("young_modulus_secant", "ucs", -1e9, 0.03)]
    assert reachable(cal, params, {"young_modulus_secant": -1.6e8}) == []
    cal.targets = [Target("young_modulus_secant", "ucs", -1.7e9, 0.03)]
    assert reachable(cal, params, {"young_modulus_secant": -1.6e8}) == [
        "young_modulus_secant = -1.7e+09 lies outside what the bounds of "
        "specimen.bond_material.young_modulus reach (-1.6e+09 to -1.6e+07, by the scaling "
        "rule)"]
    without = _calibration([Parameter("specimen.material.young_modulus", 1e8, 1e10)],
                           cal.targets)
    assert reachable(without, {"specimen.material.young_modulus": 1e9},
                     {"young_modulus_secant": 1.0}) == []


def test_linearised_summary_of_a_lab_in_closed_form():
    """Targets y = v (1 + k (x - x_best)) of three parameters x on [0, 1] (u = x), k =
    1/2, 1/3 and 1/15, tolerance 0.1: dy/du in tolerances is k / 0.1, so the uncertainties
    are 0.2 (identified), 0.3 (weakly) and 1.5 (not identifiable)."""
    params = [Parameter("x1", 0.0, 1.0), Parameter("x2", 0.0, 1.0),
              Parameter("x3", 0.0, 1.0)]
    targets = [Target("ucs", "ucs", 3e6, 0.1), Target("young_modulus_secant", "ucs", 2e9, 0.1),
               Target("poisson_ratio", "brazilian", 0.2, 0.1)]
    cal = _calibration(params, targets, check_seeds=[4, 9])

    class Lab:
        errors = {5: "ucs: boom", -1: "not a trial"}

        def run(self, jobs):
            out = {}
            for trial, p in jobs.items():
                seed = {4: 1.0, 9: 1.2}.get(p.get("specimen.seed"), 1.0)
                out[trial] = {"ucs": 3e6 * (1 + 0.5 * (p["x1"] - 0.2)) * seed,
                              "young_modulus_secant": 2e9 * (1 + (p["x2"] - 0.97) / 3),
                              "poisson_ratio": 0.2 * (1 + (p["x3"] - 0.4) / 15)
                              if seed == 1.0 else math.nan}
            return out

    lab = Lab()
    best = {"x1": 0.2, "x2": 0.97, "x3": 0.4}      # x2 near its top: the step goes down
    second = {"x1": 0.21, "x2": 0.9, "x3": 0.1}
    rows = {7: {"trial": 7, **best, **lab.run({0: best})[0], "misfit": 0.0},
            3: {"trial": 3, **second, **lab.run({0: second})[0], "misfit": 0.5},
            4: {"trial": 4, **best, "ucs": 9e9, "young_modulus_secant": 2e9,
                "poisson_ratio": 0.2, "misfit": 9.0}}
    stages = []
    summary = summarise(cal, rows, lab, stages.append)
    verdict = summary["identifiability"]
    assert verdict["x1"]["uncertainty_of_range"] == pytest.approx(0.2, rel=1e-9)
    assert verdict["x2"]["uncertainty_of_range"] == pytest.approx(0.3, rel=1e-9)
    assert verdict["x3"]["uncertainty_of_range"] == pytest.approx(1.5, rel=1e-9)
    assert [verdict[k]["identifiable"] for k in ("x1", "x2", "x3")] == [True, False, False]
    assert verdict["x1"]["verdict"] == "identified: the targets fix it to +-20 % of its range"
    assert verdict["x2"]["verdict"] == "weakly identified: +-30 % of its range"
    assert verdict["x3"]["verdict"] == \
        "not identifiable: the targets leave it free over its range"
    np.testing.assert_allclose(summary["information_eigenvalues"],
                               [1 / 1.5 ** 2, 1 / 0.3 ** 2, 1 / 0.2 ** 2], rtol=1e-9)
    # the consistent sets: trials 7 and 3 (trial 4 misses the UCS), best first
    assert [c["trial"] for c in summary["consistent"]] == [7, 3]
    assert verdict["x2"]["consistent_spread_of_range"] == pytest.approx(0.07, rel=1e-12)
    assert verdict["x2"]["consistent_low"] == 0.9 and verdict["x2"]["consistent_high"] == 0.97
    assert summary["best"] == {"trial": 7, "parameters": best, "misfit": 0.0,
                               "predictions": {t.name: rows[7][t.name] for t in targets}}
    # seeds 4 and 9 and the best's own specimen: the population scatter of the three
    ucs = summary["seed_scatter"]["ucs"]
    assert ucs["values"] == pytest.approx([3e6, 3.6e6, 3e6], rel=1e-14)
    assert ucs["std"] == pytest.approx(math.sqrt(2 / 9) * 6e5, rel=1e-12)
    assert ucs["mean"] == pytest.approx(3.2e6, rel=1e-12)
    assert summary["warnings"] == [
        "ucs on specimen seed 9: 3.6e+06, +20.0% off the target 3e+06 (tolerance 10 %): "
        "the best set meets the target on one specimen only; the scatter between specimens "
        "is larger than the tolerance (a larger specimen, or a wider tolerance)",
        "poisson_ratio on specimen seed 9: the run failed"]
    assert summary["failed"] == {5: "ucs: boom"}
    assert summary["trials"] == 3 and summary["simulations"] == (3 + 3 + 2) * 2
    assert stages == ["identifiability: 6 runs, each parameter moved by 5 % of its range",
                      "seed scatter: 4 runs on specimen seeds [4, 9]"]


def test_a_consistent_set_alone_has_no_spread():
    params = [Parameter("x1", 1.0, 100.0, log=True)]
    cal = _calibration(params, [Target("ucs", "ucs", 3e6, 0.1)])

    class Lab:
        errors = {}

        def run(self, jobs):
            return {k: {"ucs": 3e6 * p["x1"] / 10} for k, p in jobs.items()}

    rows = {0: {"trial": 0, "x1": 10.0, "ucs": 3e6, "misfit": 0.0}}
    verdict = summarise(cal, rows, Lab())["identifiability"]["x1"]
    assert math.isnan(verdict["consistent_spread_of_range"])
    # dy/du over 5 % of two decades, in tolerances: 3e6 (10^0.1 - 1) / 0.05 / 3e5
    assert verdict["uncertainty_of_range"] == pytest.approx(0.05 * 0.1 / (10 ** 0.1 - 1),
                                                            rel=1e-9)
    assert summarise(cal, rows, Lab())["warnings"] == []


def test_fewer_targets_than_parameters_is_a_warning():
    cal = _calibration([Parameter("a", 0, 1), Parameter("b", 0, 1), Parameter("c", 0, 1)],
                       [Target("ucs", "ucs", 1.0, 0.1), Target("poisson_ratio", "ucs", 0.2,
                                                               0.1)])
    assert cal.warnings == [
        "2 target(s) for 3 parameters: at most 2 combination(s) of the parameters can be "
        "fixed, and every parameter in a combination the targets leave free is reported "
        "not identifiable; add targets or calibrate fewer parameters"]
    cal.parameters = cal.parameters[:2]
    assert cal.warnings == []
    assert _calibration(cal.parameters, cal.targets + [Target("x", "brazilian", 1, 1)]
                        ).tests == ["brazilian", "ucs"]


def test_clean_numbers_for_json():
    assert calibrate._clean({"a": (np.float64(1.5), np.int64(3), math.inf),
                             "b": [math.nan, {"c": np.float32(0.25)}], "d": "text"}) == \
        {"a": [1.5, 3, None], "b": [None, {"c": 0.25}], "d": "text"}
    assert type(calibrate._clean(np.int64(3))) is int


# ---------------------------------------------------------------- the table

def test_the_table_keeps_each_trial_exactly_and_passes_over_a_cut_row(tmp_path):
    cal = _calibration([Parameter(E_KEY, 2e7, 2e9, log=True)],
                       [Target("ucs", "ucs", 1e6, 0.1), Target("poisson_ratio", "ucs", 0.2,
                                                               0.1)])
    table = Table(tmp_path / "t.csv", cal)
    assert table.read() == {}
    table.start()
    table.start()                                  # a second start keeps the file
    row = table.append(0, {E_KEY: 1 / 3 * 1e9}, {"ucs": 1.1e6}, 0.01)
    assert row == {"trial": 0, E_KEY: 1 / 3 * 1e9, "ucs": 1.1e6,
                   "poisson_ratio": pytest.approx(math.nan, nan_ok=True), "misfit": 0.01}
    table.append(1, {E_KEY: 2e8}, {"ucs": 9e5, "poisson_ratio": 0.21}, math.inf)
    with open(table.path, "a") as handle:
        handle.write("2.0,3e8,1.0")                # cut by a kill
    rows = Table(tmp_path / "t.csv", cal).read()
    assert list(rows) == [0, 1]
    assert rows[0][E_KEY] == 1 / 3 * 1e9 and math.isnan(rows[0]["poisson_ratio"])
    assert rows[1] == {"trial": 1.0, E_KEY: 2e8, "ucs": 9e5, "poisson_ratio": 0.21,
                       "misfit": math.inf}
    header = f"trial,{E_KEY},ucs,poisson_ratio,misfit"
    assert table.path.read_text().splitlines()[0] == header
    # resumed, the table first drops the cut row: the next row starts a line of its own
    whole = table.path.read_text()
    table.start()
    assert table.path.read_text() == whole[:whole.rindex("\n") + 1]
    table.append(2, {E_KEY: 3e8}, {"ucs": 1e6, "poisson_ratio": 0.2}, 0.0)
    assert sorted(Table(table.path, cal).read()) == [0, 1, 2]
    # a header cut by a kill is written again
    table.path.write_text(header[:9])
    table.start()
    assert table.path.read_text().splitlines() == [header] and table.read() == {}


def test_another_calibrations_table_is_refused(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("trial,x,misfit\n0.0,1.0,2.0\n")
    cal = _calibration([Parameter("y", 0, 1)], [Target("ucs", "ucs", 1.0, 0.1)])
    with pytest.raises(InputError) as error:
        Table(path, cal).read()
    assert str(error.value) == (f"{path}: holds another calibration's table (its columns "
                                "differ); run afresh with --overwrite")


# ---------------------------------------------------------------- a whole calibration

def test_the_second_trial_is_the_scaling_rules_and_hits_the_truth(folder):
    progress, stages = [], []
    summary = run_calibration(folder / "calib.toml", folder / "out",
                              progress=lambda *a: progress.append(a), stage=stages.append)
    lines = (folder / "out" / "calibration.csv").read_text().splitlines()
    assert lines[0] == ("trial," + ",".join([E_KEY, S_KEY, T_KEY]) +
                        ",young_modulus_secant,tensile_strength,misfit")
    rows = [[float(x) for x in line.split(",")] for line in lines[1:]]
    assert [r[0] for r in rows] == [0, 1, 2, 3, 4]
    # trial 0 at the geometric middle of each log range
    assert rows[0][1:4] == pytest.approx([2e8, 3e6, 3e6], rel=1e-14)
    assert rows[0][4:6] == pytest.approx([1.6e8, 1.5e6], rel=1e-14)
    # trial 1: E_bond x 5.6e8 / 1.6e8, strengths x 1.2e7 / 1.5e6, exact for this lab
    assert rows[1][1:4] == pytest.approx([TRUE_E, TRUE_S, TRUE_S], rel=1e-14)
    for r in rows:
        assert 2e7 <= r[1] <= 2e9 and 3e5 <= r[2] <= 3e7 and 3e5 <= r[3] <= 3e7
        expected = ((r[4] - 5.6e8) / (0.03 * 5.6e8)) ** 2 + ((r[5] - 1.2e7) / 6e5) ** 2
        assert r[6] == pytest.approx(expected, rel=1e-12, abs=1e-20)
    assert [p[:2] for p in progress] == [(k, 5) for k in range(1, 6)]
    assert [p[2] for p in progress] == [r[6] for r in rows]
    assert summary["best"]["trial"] == 1
    assert summary["best"]["parameters"] == pytest.approx(
        {E_KEY: TRUE_E, S_KEY: TRUE_S, T_KEY: TRUE_S}, rel=1e-14)
    # forward difference over 5 % of two log decades at E (u = 0.77), backward at the
    # strength (u = 0.95): sigma = 0.05 tol / |10^(+-0.1) - 1|
    verdict = summary["identifiability"]
    assert verdict[E_KEY]["uncertainty_of_range"] == pytest.approx(
        0.05 * 0.03 / (10 ** 0.1 - 1), rel=1e-9)
    assert verdict[S_KEY]["uncertainty_of_range"] == pytest.approx(
        0.05 * 0.05 / (1 - 10 ** -0.1), rel=1e-9)
    assert math.isinf(verdict[T_KEY]["uncertainty_of_range"])
    assert verdict[E_KEY]["verdict"] == \
        "identified: the targets fix it to +-0.58 % of its range"
    assert stages == ["identifiability: 3 runs, each parameter moved by 5 % of its range",
                      "rate: the best set's 1 test(s) again at half the strain rate"]
    written = json.loads((folder / "out" / "calibration.json").read_text())
    assert written["best"]["trial"] == 1
    assert written["identifiability"][T_KEY]["uncertainty_of_range"] is None
    assert written["simulations"] == 5 + 3 + 2     # the rate check: two runs of the test


def test_each_test_gets_its_own_keys(folder):
    calls = []

    def lab(spec, test, overrides):
        calls.append((test, dict(overrides)))
        return closed_form_lab(spec, test, overrides)

    calibrate.evaluate = lab                         # restored by the fixture's monkeypatch
    text = (FILE.replace("budget = 5", "budget = 3")
            + '[tests.tension]\n"test.strain_rate" = 0.02\n')
    (folder / "calib.toml").write_text(text)
    run_calibration(folder / "calib.toml", folder / "out")
    # 3 trials, 3 moved parameters and the rate check
    assert len(calls) == 3 + 3 + 1 and all(test == "tension" for test, _ in calls)
    assert all(o["test.strain_rate"] == 0.02 and E_KEY in o for _, o in calls)
    assert calls[0][1][E_KEY] == pytest.approx(2e8, rel=1e-14)


def test_a_killed_calibration_and_a_cut_row_resume_to_the_same_table(folder):
    whole = run_calibration(folder / "calib.toml", folder / "whole")
    out = folder / "cut"
    assert run_calibration(folder / "calib.toml", out, stop_after=3) is None
    assert len((out / "calibration.csv").read_text().splitlines()) == 4
    with pytest.raises(InputError) as error:
        run_calibration(folder / "calib.toml", out)
    assert str(error.value) == (f"{out}: --out: holds a calibration table; give --resume "
                                "to continue it or --overwrite to start afresh")
    with open(out / "calibration.csv", "a") as handle:
        handle.write("3.0,1.5e8,2")                  # the kill fell within a row
    resumed = run_calibration(folder / "calib.toml", out, resume=True)
    assert resumed["best"] == whole["best"]
    assert resumed["identifiability"] == whole["identifiability"]
    # the table holds every trial once more: a further resume runs nothing
    rows = Table(out / "calibration.csv", load_calibration(folder / "calib.toml")).read()
    assert sorted(rows) == [0, 1, 2, 3, 4]
    whole_rows = Table(folder / "whole" / "calibration.csv",
                       load_calibration(folder / "calib.toml")).read()
    assert rows == whole_rows
    calibrate.evaluate = None                        # nothing may run now
    again = run_calibration(folder / "calib.toml", out, resume=True)
    assert again["best"] == whole["best"]


def test_targets_beyond_the_bounds_fail_with_the_scaling_rules_range(folder):
    text = FILE.replace("value = 5.6e8", "value = 1.7e9")
    (folder / "calib.toml").write_text(text)
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(folder / "calib.toml", folder / "out")
    assert str(error.value) == (
        "the targets cannot be met: young_modulus_secant = 1.7e+09 lies outside what the "
        f"bounds of {E_KEY} reach (1.6e+07 to 1.6e+09, by the scaling rule)")


def test_a_first_trial_that_fails_stops_with_its_own_reason(folder):
    def broken(spec, test, overrides):
        raise RuntimeError("the specimen could not be packed")

    calibrate.evaluate = broken
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(folder / "calib.toml", folder / "out")
    assert str(error.value) == (
        "the first trial (every parameter at the middle of its bounds) failed, so the "
        "scaling rules have nothing to scale: tension: RuntimeError: the specimen could "
        "not be packed")
    calibrate.evaluate = lambda spec, test, o: {"young_modulus_secant": 1.6e8}
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(folder / "calib.toml", folder / "out2")
    assert str(error.value).endswith("nothing to scale: no numbers for tensile_strength")


def test_targets_the_trials_cannot_meet_end_with_what_the_best_misses(folder):
    """The lab's strength saturates at 2 MPa: the scaling rule thinks 12 MPa reachable,
    no trial gets there, and the message gives the best set's misses."""
    calibrate.evaluate = lambda spec, test, o: {
        "young_modulus_secant": 0.8 * o[E_KEY],
        "tensile_strength": 0.5 * min(o[S_KEY], 4e6)}
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(folder / "calib.toml", folder / "out")
    best = json.loads((folder / "out" / "calibration.json").read_text())["best"]
    e, s = best["predictions"]["young_modulus_secant"], best["predictions"]["tensile_strength"]
    assert s <= 2e6
    assert str(error.value) == (
        f"no parameter set of 5 trials meets every target within its uncertainty; the best "
        f"misses young_modulus_secant by {100 * (e / 5.6e8 - 1):+.1f} % (tolerance 3 %), "
        f"tensile_strength by {100 * (s / 1.2e7 - 1):+.1f} % (tolerance 5 %). Widen the "
        "bounds, raise the budget or check that the targets agree with each other")


def test_a_lab_number_the_target_names_is_taken_not_another(folder):
    """A trial whose run reports no_failure and a NaN strength is a failed trial with the
    lab's reason."""
    calibrate.evaluate = lambda spec, test, o: {
        "young_modulus_secant": 0.8 * o[E_KEY], "tensile_strength": math.nan,
        "no_failure": "the specimen did not fail before the strain limit"}
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(folder / "calib.toml", folder / "out")
    assert str(error.value).endswith(
        "nothing to scale: tension: the specimen did not fail before the strain limit, so "
        "no tensile_strength: a failed trial")


# ---------------------------------------------------------------- the file

def test_a_file_of_defaults(folder):
    text = "\n".join(line for line in FILE.splitlines()
                     if not line.startswith(("budget", "batch", "seed")))
    (folder / "calib.toml").write_text(text)
    cal = load_calibration(folder / "calib.toml")
    assert (cal.budget, cal.batch, cal.seed, cal.check_seeds, cal.test_overrides) == \
        (24, 4, 0, [], {})
    assert cal.spec == (folder / "lattice.toml").resolve() and cal.text == text
    assert [(p.key, p.low, p.high, p.log) for p in cal.parameters] == [
        (E_KEY, 2e7, 2e9, True), (S_KEY, 3e5, 3e7, True), (T_KEY, 3e5, 3e7, True)]
    assert [(t.name, t.test, t.value, t.tolerance) for t in cal.targets] == [
        ("young_modulus_secant", "tension", 5.6e8, 0.03),
        ("tensile_strength", "tension", 1.2e7, 0.05)]
    linear = text.replace("low = 2e7\nhigh = 2e9\nlog = true", "low = -1\nhigh = 2e9")
    (folder / "calib.toml").write_text(linear)
    assert load_calibration(folder / "calib.toml").parameters[0] == \
        Parameter(E_KEY, -1.0, 2e9, False)


E_TABLE = f"parameters.{E_KEY}"
BAD_FILES = [
    ("budget = 5", "budgets = 5", "budgets",
     "unknown key 'budgets'; did you mean 'budget'? allowed: spec, budget, batch, seed, "
     "check_seeds, rate_check, parameters, targets, tests"),
    ('spec = "lattice.toml"', "", "spec", "missing: the lab spec file (docs/lab.md)"),
    ('spec = "lattice.toml"', 'spec = "none.toml"', "spec", "value 'none.toml': no such file"),
    ("low = 2e7", "lo = 2e7", E_TABLE, "expected a table of low, high, log"),
    ("low = 2e7", "low = 0", f"{E_TABLE}.low", "value 0: expected a positive number"),
    ("low = 2e7", 'low = "2e7"', f"{E_TABLE}.low", "value '2e7': expected a positive number"),
    ("high = 2e9", "high = true", f"{E_TABLE}.high", "value True: expected a positive number"),
    ("high = 2e9", "high = nan", f"{E_TABLE}.high", "value nan: expected a positive number"),
    ("high = 2e9", "high = 2e7", f"{E_TABLE}.high", "high 20000000.0 must exceed low "
                                                    "20000000.0"),
    ('test = "tension"', 'test = "shear"', "targets.young_modulus_secant.test",
     "value 'shear'; allowed: ucs, triaxial, brazilian, tension, agglomerate"),
    ("tolerance = 0.03", "tolerance = 0", "targets.young_modulus_secant.tolerance",
     "value 0: expected a positive number"),
    ("value = 5.6e8", "value = 0.0", "targets.young_modulus_secant.value",
     "a target of 0 has no relative uncertainty"),
    ("value = 5.6e8", 'value = "big"', "targets.young_modulus_secant.value",
     "value 'big': expected a number"),
    ("tolerance = 0.03", "tolerance = 0.03\nunit = 1", "targets.young_modulus_secant",
     "expected a table of test, value, tolerance"),
    ("budget = 5", "budget = 2", "budget", "value 2: expected an integer >= 3"),
    ("budget = 5", "budget = 3.5", "budget", "value 3.5: expected an integer >= 3"),
    ("batch = 2", "batch = 0", "batch", "value 0: expected an integer >= 1"),
    ("batch = 2", "batch = true", "batch", "value True: expected an integer >= 1"),
    ("seed = 3", "seed = -1", "seed", "value -1: expected an integer >= 0"),
    ("seed = 3", "seed = 3\ncheck_seeds = [1, -2]", "check_seeds",
     "value [1, -2]: expected a list of integers >= 0"),
    ("seed = 3", "seed = 3\ncheck_seeds = 4", "check_seeds",
     "value 4: expected a list of integers >= 0"),
    ("seed = 3", "seed = 3\ntests = 1", "tests",
     "expected tables named after tests (ucs, triaxial, brazilian, tension, agglomerate) of "
     'spec keys and values, e.g. [tests.brazilian] with "specimen.shape" = "disc"'),
    ("seed = 3", "seed = 3\n[tests.shear]\nx = 1", "tests",
     "expected tables named after tests (ucs, triaxial, brazilian, tension, agglomerate) of "
     'spec keys and values, e.g. [tests.brazilian] with "specimen.shape" = "disc"'),
    ("seed = 3", "seed = 3\ntests = { ucs = 1 }", "tests",
     "expected tables named after tests (ucs, triaxial, brazilian, tension, agglomerate) of "
     'spec keys and values, e.g. [tests.brazilian] with "specimen.shape" = "disc"'),
]


@pytest.mark.parametrize("old, new, key, message", BAD_FILES)
def test_a_bad_file_names_the_key(folder, old, new, key, message):
    path = folder / "calib.toml"
    path.write_text(FILE.replace(old, new, 1))
    with pytest.raises(InputError) as error:
        load_calibration(path)
    assert (error.value.file, error.value.key, error.value.reason) == (path, key, message)


@pytest.mark.parametrize("cut, key, message", [
    ("[parameters.", "parameters", "no parameters to calibrate"),
    ("[targets.", "targets", "no targets")])
def test_a_file_without_parameters_or_targets(folder, cut, key, message):
    lines = FILE.splitlines()
    kept, skipping = [], False
    for line in lines:
        if line.startswith("["):
            skipping = line.startswith(cut)
        if not skipping:
            kept.append(line)
    path = folder / "calib.toml"
    path.write_text("\n".join(kept) + "\n")
    with pytest.raises(InputError) as error:
        load_calibration(path)
    assert (error.value.file, error.value.key, error.value.reason) == (path, key, message)


def test_unreadable_files_are_named(folder):
    missing = folder / "none.toml"
    with pytest.raises(InputError) as error:
        load_calibration(missing)
    assert str(error.value) == f"{missing}: cannot read the calibration file (No such file " \
        "or directory)"
    bad = folder / "calib.toml"
    bad.write_text("budget = \n")
    with pytest.raises(InputError) as error:
        load_calibration(bad)
    assert error.value.file == bad and error.value.reason.startswith("not valid TOML: ")


def test_a_parameter_the_spec_does_not_have_is_refused_at_loading(folder):
    path = folder / "calib.toml"
    path.write_text(FILE.replace(f'[parameters."{T_KEY}"]',
                                 '[parameters."specimen.bond_material.strenght"]'))
    with pytest.raises(InputError) as error:
        load_calibration(path)
    assert "strenght" in str(error.value)


# ---------------------------------------------------------------- second round

def test_the_figures_and_page_get_the_calibration_rows_and_summary(folder):
    summary = run_calibration(folder / "calib.toml", folder / "a" / "b")   # made, parents too
    (kind, args), (page, page_args) = drawn
    assert (kind, page) == ("figures", "page")
    calibration, rows, given, out = args
    assert calibration.path == folder / "calib.toml" and sorted(rows) == [0, 1, 2, 3, 4]
    assert given is summary and out == folder / "a" / "b"
    assert page_args == (calibration, summary, folder / "a" / "b")
    text = (out / "calibration.json").read_text()
    assert text.startswith('{\n  "best": {\n    "trial": 1,') and text.endswith("}\n")
    assert json.loads((out / "calibration_checks.json").read_text())   # the moved runs


def test_batches_after_the_two_first_trials(folder, monkeypatch):
    sizes = []
    run = calibrate._Evaluator.run

    def counted(self, jobs):
        sizes.append(len(jobs))
        return run(self, jobs)

    monkeypatch.setattr(calibrate._Evaluator, "run", counted)
    (folder / "calib.toml").write_text(FILE.replace("budget = 5", "budget = 8")
                                       .replace("batch = 2", "batch = 3"))
    run_calibration(folder / "calib.toml", folder / "out")
    # then one run per parameter moved, then the best set's rate check
    assert sizes == [1, 1, 3, 3, 3, 1]


def test_log_bounds_are_searched_on_a_log_scale(folder, monkeypatch):
    """The sampler is given each parameter's bounds and scale: a log parameter's trials
    are drawn from a log-uniform distribution over its bounds."""
    import optuna
    studies = []
    create = optuna.create_study
    monkeypatch.setattr(optuna, "create_study",
                        lambda **kwargs: studies.append(create(**kwargs)) or studies[-1])
    text = FILE.replace(f'[parameters."{T_KEY}"]\nlow = 3e5\nhigh = 3e7\nlog = true',
                        '[parameters."specimen.bond_material.poisson_ratio"]\nlow = 0.1\n'
                        'high = 0.4')
    (folder / "calib.toml").write_text(text)
    run_calibration(folder / "calib.toml", folder / "out")
    (study,) = studies
    assert study.direction == optuna.study.StudyDirection.MINIMIZE
    for trial in study.trials:
        assert trial.distributions == {
            E_KEY: optuna.distributions.FloatDistribution(2e7, 2e9, log=True),
            S_KEY: optuna.distributions.FloatDistribution(3e5, 3e7, log=True),
            "specimen.bond_material.poisson_ratio":
                optuna.distributions.FloatDistribution(0.1, 0.4, log=False)}
    # the misfits told: each trial's own, as the table has them
    rows = Table(folder / "out" / "calibration.csv", load_calibration(folder / "calib.toml")
                 ).read()
    assert [t.value for t in study.trials] == [rows[k]["misfit"] for k in range(5)]


def test_a_calibration_leaves_the_processes_warnings_shown(folder):
    run_calibration(folder / "calib.toml", folder / "out")
    with warnings.catch_warnings(record=True) as seen:
        warnings.warn("shown after a calibration (a warning of its own)", UserWarning)
    assert len(seen) == 1


def test_every_missing_number_of_the_first_trial_is_named(folder):
    calibrate.evaluate = lambda spec, test, o: {"poisson_ratio": 0.2}
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(folder / "calib.toml", folder / "out")
    assert str(error.value).endswith(
        "nothing to scale: no numbers for young_modulus_secant, tensile_strength")


def test_every_unreachable_target_is_named(folder):
    (folder / "calib.toml").write_text(FILE.replace("value = 5.6e8", "value = 1.7e9")
                                       .replace("value = 1.2e7", "value = 2e7"))
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(folder / "calib.toml", folder / "out")
    assert str(error.value) == (
        "the targets cannot be met: young_modulus_secant = 1.7e+09 lies outside what the "
        f"bounds of {E_KEY} reach (1.6e+07 to 1.6e+09, by the scaling rule); "
        "tensile_strength = 2e+07 lies outside what the bounds of "
        f"{S_KEY}, {T_KEY} reach (1.5e+05 to 1.5e+07, by the scaling rule)")


def test_reachability_of_strengths_alone_and_at_its_exact_edges():
    """Strength parameters without a modulus one are still checked; a target at exactly
    the tolerance beyond the scaled range (binary-exact numbers) is reachable."""
    params = [Parameter("specimen.bond_material.normal_strength", 1.0, 4.0)]
    middle = {params[0].key: 2.0}              # factors 0.5 and 2: the range [1, 4]
    for value, problems in ((0.5, 0), (6.0, 0), (0.49, 1), (6.01, 1)):
        cal = _calibration(params, [Target("ucs", "ucs", value, 0.5)])
        assert len(reachable(cal, middle, {"ucs": 2.0})) == problems, value


def _evaluator_case(tmp_path):
    cal = _calibration([Parameter(E_KEY, 2e7, 2e9, log=True)],
                       [Target("young_modulus_secant", "tension", 5.6e8, 0.03),
                        Target("tensile_strength", "tension", 1.2e7, 0.05)])
    cal.spec = tmp_path / "lattice.toml"
    return cal


def test_kept_runs_hold_the_targets_numbers_and_are_not_run_again(tmp_path, monkeypatch):
    calls = []

    def lab(spec, test, o):
        calls.append(o[E_KEY])
        if o[E_KEY] == 9e8:
            raise RuntimeError("blew up")
        return {"young_modulus_secant": 0.8 * o[E_KEY], "poisson_ratio": 0.2,
                "tensile_strength": math.nan if o[E_KEY] == 3e8 else 1e7,
                **({"no_failure": "did not fail"} if o[E_KEY] == 3e8 else {})}

    monkeypatch.setattr(calibrate, "evaluate", lab)
    cal = _evaluator_case(tmp_path)
    first = calibrate._Evaluator(cal, "serial", None)
    first.keep(tmp_path / "kept.json")
    jobs = {-1: {E_KEY: 2e8}, -2: {E_KEY: 3e8}, -3: {E_KEY: 9e8}}
    got = first.run(jobs)
    assert got[-1] == {"young_modulus_secant": 1.6e8, "tensile_strength": 1e7}
    assert first.errors == {-2: "tension: did not fail, so no tensile_strength: a failed "
                                "trial", -3: "tension: RuntimeError: blew up"}
    kept = json.loads((tmp_path / "kept.json").read_text())
    assert sorted(kept.values(), key=len) == [      # no error kept, only the targets' numbers
        {"young_modulus_secant": 1.6e8, "tensile_strength": 1e7},
        {"young_modulus_secant": 2.4e8, "tensile_strength": None, "no_failure": "did not fail"}]
    assert not (tmp_path / "kept.tmp").exists()
    second = calibrate._Evaluator(cal, "serial", None)
    second.keep(tmp_path / "kept.json")
    calls.clear()
    again = second.run(jobs)
    assert calls == [9e8]                          # only the failed run again
    assert again[-1] == got[-1] and again[-2]["young_modulus_secant"] == 2.4e8
    assert math.isnan(again[-2]["tensile_strength"])   # kept as null, read as NaN
    # a run is kept by its test and overrides: another value is another run
    assert second.run({-4: {E_KEY: 2.5e8}})[-4]["young_modulus_secant"] == 2e8
    broken = calibrate._Evaluator(cal, "serial", None)
    (tmp_path / "cut.json").write_text('{"["tension", [')
    broken.keep(tmp_path / "cut.json")
    assert broken.kept == {}


class _Future:
    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


class _Client:
    """Stands in for a Dask client: runs what is submitted at once."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs, self.submitted, self.closed = args, kwargs, [], False

    def submit(self, function, *args, **kwargs):
        self.submitted.append((function, args, kwargs))
        return _Future(function(*args))

    def close(self):
        self.closed = True


def test_a_dask_client_runs_the_same_trials(folder):
    serial = run_calibration(folder / "calib.toml", folder / "serial")
    client = _Client()
    on_dask = run_calibration(folder / "calib.toml", folder / "dask", scheduler=client)
    assert on_dask["best"] == serial["best"]
    assert on_dask["identifiability"] == serial["identifiability"]
    assert len(client.submitted) == 5 + 3 + 1
    function, args, kwargs = client.submitted[0]
    # each run with one Numba thread, on a worker whatever it imported first
    assert function is single_threaded and kwargs == {"pure": False}
    assert args[0] is calibrate._safe
    assert args[1] == (folder / "lattice.toml").resolve() and args[2] == "tension"
    assert args[3][E_KEY] == pytest.approx(2e8, rel=1e-14)
    assert client.closed is False                 # the user's client stays open


def test_a_local_cluster_of_single_threaded_workers(folder, monkeypatch):
    import os

    import distributed
    made = []

    class Cluster(_Client):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)

    clients = []

    class Client(_Client):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            clients.append(self)

    monkeypatch.setattr(distributed, "LocalCluster", Cluster)
    monkeypatch.setattr(distributed, "Client", Client)
    run_calibration(folder / "calib.toml", folder / "out", scheduler=None, workers=3)
    (cluster,), (client,) = made, clients
    assert cluster.kwargs == {"n_workers": 3, "threads_per_worker": 1, "processes": True,
                              "dashboard_address": None,
                              "env": {"OMP_NUM_THREADS": "1"}}
    assert client.args == (cluster,) and len(client.submitted) == 9
    assert cluster.closed and client.closed
    monkeypatch.setattr(os, "cpu_count", lambda: 5)
    run_calibration(folder / "calib.toml", folder / "out2", scheduler=None)
    assert made[1].kwargs["n_workers"] == 5
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    run_calibration(folder / "calib.toml", folder / "out3", scheduler=None)
    assert made[2].kwargs["n_workers"] == 1


def test_a_scheduler_address_and_one_that_cannot_be_reached(folder, monkeypatch):
    import distributed
    clients = []

    class Client(_Client):
        def __init__(self, *args, **kwargs):
            if args[0] == "tcp://nowhere:1":
                raise OSError("Timed out trying to connect")
            super().__init__(*args, **kwargs)
            clients.append(self)

    monkeypatch.setattr(distributed, "Client", Client)
    run_calibration(folder / "calib.toml", folder / "out", scheduler="tcp://there:8786")
    assert clients[0].args == ("tcp://there:8786",) and clients[0].kwargs == {"timeout": "30s"}
    assert len(clients[0].submitted) == 9 and clients[0].closed is False
    with pytest.raises(InputError) as error:
        run_calibration(folder / "calib.toml", folder / "out2", scheduler="tcp://nowhere:1")
    assert (error.value.key, error.value.reason) == (
        "--scheduler", "cannot reach the Dask scheduler 'tcp://nowhere:1' (Timed out trying "
                       "to connect)")


def test_evaluate_runs_the_lab_test_on_the_spec_with_the_overrides(tmp_path, monkeypatch):
    from bondem.lab import RUNNERS
    (tmp_path / "lattice.toml").write_text(SPEC)
    seen = []

    class Result:
        numbers = {"young_modulus_secant": 1.5e8, "tensile_strength": math.nan}
        no_failure = None

    def tension(specimen, settings):
        seen.append((specimen, settings))
        return Result

    monkeypatch.setitem(RUNNERS, "tension", tension)
    numbers = calibrate.evaluate(tmp_path / "lattice.toml", "tension",
                                 {E_KEY: 3e8, "test.strain_rate": 0.02})
    assert numbers is Result.numbers or numbers == Result.numbers
    ((specimen, settings),) = seen
    assert specimen.bond_materials[0].young_modulus == 3e8
    assert specimen.position.shape == (36, 3) and settings.strain_rate == 0.02
    Result.no_failure = "the specimen did not fail"
    assert calibrate.evaluate(tmp_path / "lattice.toml", "tension", {})["no_failure"] == \
        "the specimen did not fail"


def test_summary_moves_each_parameter_by_five_percent_of_its_range():
    """The runs for the Jacobian: one parameter at a time, 5 % of its range up (down from
    95 % of it on), on a log scale for a log parameter; a moved run that failed gives no
    information about its parameter."""
    params = [Parameter("a", 2.0, 7.0), Parameter("b", 1e3, 1e5, log=True),
              Parameter("c", -3.0, 1.0)]
    targets = [Target("ucs", "ucs", 4.0, 0.125), Target("poisson_ratio", "ucs", 0.25, 0.125)]
    cal = _calibration(params, targets)
    moved = {}

    class Lab:
        errors = {0: "ucs: the first", 3: "ucs: another", -1: "a moved run"}

        def run(self, jobs):
            moved.update(jobs)
            return {k: {"ucs": 4.0 + p["a"] - 3.0,
                        "poisson_ratio": 0.25 + 0.025 * math.log10(p["b"] / 1e4)
                        if p["c"] == 0.9 else math.nan}
                    for k, p in jobs.items()}

    best = {"a": 3.0, "b": 1e4, "c": 0.9}
    rows = {2: {"trial": 2, **best, "ucs": 4.0, "poisson_ratio": 0.25, "misfit": 0.0},
            5: {"trial": 5, "a": 3.4, "b": 2e4, "c": 0.0, "ucs": 4.5, "poisson_ratio": 0.28125,
                "misfit": 1.0}}
    summary = summarise(cal, rows, Lab())
    assert moved[-1] == {"a": pytest.approx(3.25, rel=1e-14), "b": 1e4, "c": 0.9}
    assert moved[-2] == {"a": 3.0, "b": pytest.approx(1e4 * 10 ** 0.1, rel=1e-14), "c": 0.9}
    assert moved[-3] == {"a": 3.0, "b": 1e4, "c": pytest.approx(0.7, rel=1e-14)}  # u = 0.975
    verdict = summary["identifiability"]
    # ucs moves 0.25 (half a tolerance) per 5 % of a's range: sigma = 0.05 / 0.5 = 0.1;
    # the Poisson ratio 0.0025 (0.08 tolerances) per 5 % of b's two decades: 0.625
    assert verdict["a"]["uncertainty_of_range"] == pytest.approx(0.1, rel=1e-9)
    assert verdict["b"]["uncertainty_of_range"] == pytest.approx(0.625, rel=1e-9)
    assert math.isinf(verdict["c"]["uncertainty_of_range"])     # its moved run failed
    assert verdict["a"]["best"] == 3.0 and verdict["b"]["best"] == 1e4
    assert summary["failed"] == {0: "ucs: the first", 3: "ucs: another"}
    # both rows are consistent (trial 5 at exactly its tolerances)
    assert summary["consistent"] == [
        {"trial": 2, "parameters": best, "predictions": {"ucs": 4.0, "poisson_ratio": 0.25}},
        {"trial": 5, "parameters": {"a": 3.4, "b": 2e4, "c": 0.0},
         "predictions": {"ucs": 4.5, "poisson_ratio": 0.28125}}]
    assert summary["targets"] == {"ucs": {"test": "ucs", "value": 4.0, "tolerance": 0.125},
                                  "poisson_ratio": {"test": "ucs", "value": 0.25,
                                                    "tolerance": 0.125}}


def test_a_seed_at_exactly_its_tolerance_is_no_warning():
    cal = _calibration([Parameter("a", 0.0, 1.0)], [Target("ucs", "ucs", 4.0, 0.125)],
                       check_seeds=[1])

    class Lab:
        errors = {}

        def run(self, jobs):
            return {k: {"ucs": 4.5 if p.get("specimen.seed") == 1 else 4.0 + p["a"]}
                    for k, p in jobs.items()}

    rows = {0: {"trial": 0, "a": 0.0, "ucs": 4.0, "misfit": 0.0}}
    assert summarise(cal, rows, Lab())["warnings"] == []


def test_linearised_uncertainty_in_closed_form():
    from bondem.calibrate import linearised_uncertainty
    # J^T J = [[4, 2], [2, 2]], its inverse's diagonal (1/2, 1)
    np.testing.assert_allclose(linearised_uncertainty([[2.0, 1.0], [0.0, 1.0]]),
                               [math.sqrt(0.5), 1.0], rtol=1e-12)
    # the same at a scale far below 1: the null space is relative to the largest
    np.testing.assert_allclose(linearised_uncertainty(np.array([[2.0, 1.0], [0.0, 1.0]])
                                                      * 1e-7),
                               [math.sqrt(0.5) * 1e7, 1e7], rtol=1e-9)
    # a direction 1e-14 as informative as the other is none
    sigma = linearised_uncertainty([[1e3, 0.0], [0.0, 1e-4]])
    assert sigma[0] == pytest.approx(1e-3, rel=1e-12) and math.isinf(sigma[1])
    assert np.all(np.isinf(linearised_uncertainty(np.zeros((2, 3)))))
    assert linearised_uncertainty(np.zeros((2, 0))).shape == (0,)


def test_more_file_rules(folder):
    path = folder / "calib.toml"
    ratio = "specimen.bond_material.poisson_ratio"
    path.write_text(FILE.replace(f'[parameters."{T_KEY}"]\nlow = 3e5\nhigh = 3e7\nlog = true',
                                 f'[parameters."{ratio}"]\nlow = -0.4\nhigh = -0.1')
                    .replace("seed = 3", "seed = 3\ncheck_seeds = [0, 3]"))
    cal = load_calibration(path)
    assert cal.parameters[2] == Parameter(ratio, -0.4, -0.1, False)
    assert cal.check_seeds == [0, 3] and cal.path == path
    path.write_bytes(FILE.encode("latin-1") + "# Größe\n".encode("latin-1"))
    with pytest.raises(InputError) as error:
        load_calibration(path)
    assert error.value.file == path
    # a test's own keys are checked with the spec when the file is read
    path.write_text(FILE + '[tests.tension]\n"test.strain_rate" = -1.0\n')
    with pytest.raises(InputError) as error:
        load_calibration(path)
    assert "strain_rate" in str(error.value)


def test_a_table_killed_in_its_header_or_with_a_bad_middle_row(tmp_path):
    cal = _calibration([Parameter("a", 0.0, 1.0)], [Target("ucs", "ucs", 1.0, 0.1)])
    path = tmp_path / "t.csv"
    path.write_text("")
    assert Table(path, cal).read() == {}
    path.write_text("tri")
    assert Table(path, cal).read() == {}
    path.write_text("trial,a,ucs,misfit\n0.0,0.5,1.0,0.0\n1.0,0.2\n2.0,0.4,1.1,1.0\n")
    assert sorted(Table(path, cal).read()) == [0, 2]


def test_the_sampler_learns_from_the_misfits_it_is_told(folder):
    """After the scaling rules' exact guess, the sampler is told each trial's misfit and
    draws near the best: its later trials lie far closer to the truth than draws from the
    prior (log-uniform over two decades: a median of |log10(E / E_true)| about 0.66;
    0.15 to 0.27 over five sampler seeds)."""
    (folder / "calib.toml").write_text(FILE.replace("budget = 5", "budget = 40")
                                       .replace("batch = 2", "batch = 4"))
    run_calibration(folder / "calib.toml", folder / "out")
    rows = Table(folder / "out" / "calibration.csv",
                 load_calibration(folder / "calib.toml")).read()
    late = np.array([rows[k][E_KEY] for k in range(20, 40)])
    assert np.median(np.abs(np.log10(late / TRUE_E))) < 0.4


def test_runs_kept_on_dask_are_not_run_again(folder):
    run_calibration(folder / "calib.toml", folder / "dask", scheduler=_Client())
    whole = json.loads((folder / "dask" / "calibration.json").read_text())
    calibrate.evaluate = None                        # nothing may run now
    again = run_calibration(folder / "calib.toml", folder / "dask", scheduler=_Client(),
                            resume=True)
    again = json.loads(json.dumps(calibrate._clean(again)))
    # the same runs (their log kept), in this session's wall time
    del again["time"]["wall_seconds"], whole["time"]["wall_seconds"]
    assert again == whole


def test_a_single_trial_that_failed(folder):
    """A Calibration made in Python may ask for one trial: when it fails, that is the
    message (a file asks for at least three, and the second stops at a failed first)."""
    calibration = load_calibration(folder / "calib.toml")
    calibration.budget = 1
    calibrate.evaluate = lambda spec, test, o: {"young_modulus_secant": 1.6e8}
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(calibration, folder / "out")
    assert str(error.value) == "every trial failed; the first: no numbers came back"

    def broken(spec, test, overrides):
        raise RuntimeError("no specimen")

    calibrate.evaluate = broken
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(calibration, folder / "out2")
    assert str(error.value) == \
        "every trial failed; the first: tension: RuntimeError: no specimen"


def test_each_run_is_logged_with_its_time_and_steps(folder, monkeypatch):
    """calibration_runs.csv: a row per run (the trials', then the checks' with negative
    trial numbers), its steps and wall seconds; calibration.json's "time" sums them."""
    def lab(spec, test, overrides):
        numbers = closed_form_lab(spec, test, overrides)
        if overrides[E_KEY] > 1.5e9:
            raise RuntimeError("blew up")
        # a stand-in step count that depends on the run: 1e-3 strength over stiffness
        return {**numbers, "steps": round(1e3 * overrides[S_KEY] / overrides[E_KEY])}

    monkeypatch.setattr(calibrate, "evaluate", lab)
    summary = run_calibration(folder / "calib.toml", folder / "out")
    with open(folder / "out" / "calibration_runs.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == calibrate.RUN_COLUMNS
    trials = [r for r in rows if int(r["trial"]) >= 0]
    assert [int(r["trial"]) for r in trials] == list(range(5))
    assert len(rows) == 5 + 3 + 1      # 5 trials, 3 identifiability runs, the rate check
    table = {int(float(r["trial"])): r for r in csv.DictReader(
        open(folder / "out" / "calibration.csv", newline=""))}
    steps = 0
    for row in trials:
        params = table[int(row["trial"])]
        if float(params[E_KEY]) > 1.5e9:
            assert row["end"] == "error" and row["steps"] == "nan"
        else:
            expected = round(1e3 * float(params[S_KEY]) / float(params[E_KEY]))
            assert row["end"] == "ok" and float(row["steps"]) == expected
            steps += expected
        assert float(row["run_seconds"]) >= 0.0
    time_ = summary["time"]
    assert time_["trials"]["runs"] == 5 and time_["checks"]["runs"] == 4
    assert time_["trials"]["steps"] == steps
    assert time_["runs"]["seconds"] == pytest.approx(
        sum(float(r["run_seconds"]) for r in rows), rel=1e-12)
    assert time_["by_test"]["tension"]["runs"] == 9
    assert time_["wall_seconds"] >= time_["runs"]["seconds"]   # serial: one after another


def test_a_fresh_table_does_not_take_an_earlier_calibrations_kept_runs(folder):
    run_calibration(folder / "calib.toml", folder / "out")
    kept = folder / "out" / "calibration_checks.json"
    first = json.loads((folder / "out" / "calibration.json").read_text())
    # an earlier calibration's identifiability runs with other numbers, kept
    stale = {key: {name: 3.0 * value for name, value in numbers.items()}
             for key, numbers in json.loads(kept.read_text()).items()}
    kept.write_text(json.dumps(stale))
    (folder / "out" / "calibration.csv").unlink()   # what --overwrite does
    again = json.loads(json.dumps(calibrate._clean(
        run_calibration(folder / "calib.toml", folder / "out"))))
    assert again["identifiability"] == first["identifiability"]


def test_the_best_set_is_run_again_at_half_the_strain_rate(folder, monkeypatch):
    """The lab's numbers depend on the strain rate when it is not quasi-static: the best
    set's tests run with rate_check = "repeat", and a strength or modulus that moves by
    more than the lab's 2 % or 0.5 % is a warning with its number."""
    asked = []

    def lab(spec, test, overrides):
        numbers = closed_form_lab(spec, test, overrides)
        if overrides.get("test.rate_check") == "repeat":
            asked.append(overrides)
            numbers.update(rate_change_strength=-0.068, rate_change_modulus=0.004)
        return numbers

    monkeypatch.setattr(calibrate, "evaluate", lab)
    summary = run_calibration(folder / "calib.toml", folder / "out")
    best = summary["best"]["parameters"]
    assert asked == [{**best, "test.rate_check": "repeat"}]
    assert summary["rate_change"] == {"tension": {"strength": -0.068, "modulus": 0.004}}
    assert summary["warnings"][1:] == [
        "tension: at half the strain rate the best set's strength moved by -6.8 % (more "
        "than 2 %): the targets are met at a rate that is not quasi-static for these "
        'bonds; leave "test.rate_rule" at its default "bonds" or set a lower '
        '"test.strain_rate" for the tests (docs/lab.md, Rate)']
    # kept for a resume, which does not run it again
    calibrate.evaluate = None
    again = run_calibration(folder / "calib.toml", folder / "out", resume=True)
    assert again["rate_change"] == summary["rate_change"]
    assert again["warnings"] == summary["warnings"]
    # off: not run
    (folder / "calib2.toml").write_text("rate_check = false\n" + FILE)
    monkeypatch.setattr(calibrate, "evaluate", lab)
    asked.clear()
    summary = run_calibration(folder / "calib2.toml", folder / "out2")
    assert asked == [] and summary["rate_change"] == {} and len(summary["warnings"]) == 1
    assert summary["simulations"] == 5 + 3
    (folder / "calib3.toml").write_text("rate_check = 1\n" + FILE)
    with pytest.raises(InputError) as error:
        load_calibration(folder / "calib3.toml")
    assert "rate_check" in str(error.value) and "true or false" in str(error.value)

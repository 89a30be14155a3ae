"""Calibration recovers known bond parameters from the macro properties they produce.

The specimen is a 3 x 3 x 6 simple cubic lattice in direct tension. Its E is set by the
bond modulus alone and its strength by the bonds' normal strength alone, so both are
identifiable. The tangential strength does not act in pure tension and must be reported
as not identifiable. A calibration killed mid-way resumes to the same result.
Unreachable targets fail with a message, not a silent best effort.
"""
import json
import math

import numpy as np

import pytest
from click.testing import CliRunner

from bondem.calibrate import CalibrationFailed, load_calibration, run_calibration
from bondem.cli import main
from bondem.errors import InputError
from bondem.lab import RUNNERS
from bondem.lab.spec import load_spec

TRUE_MODULUS, TRUE_STRENGTH = 2e8, 3e6
SPEC = """
[specimen]
lattice = [3, 3, 6]
radius = 1e-3
diameter_ratio = 0.8
[specimen.material]
density = 2500.0
young_modulus = 1e8
[specimen.bond_material]
young_modulus = 1e8
normal_strength = 1e6
tangential_strength = 1e6
[test]
rate_rule = "wave"            # the default "bonds" takes up to 300x the steps in the bounds
"""
CALIBRATION = """
spec = "lattice.toml"
budget = {budget}
batch = 3
seed = 1
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
value = {modulus!r}
tolerance = 0.03
[targets.tensile_strength]
test = "tension"
value = {strength!r}
tolerance = 0.03
"""


@pytest.fixture(scope="module")
def truth(tmp_path_factory):
    """The lattice's E and tensile strength at the true parameters, from the lab."""
    folder = tmp_path_factory.mktemp("calibration")
    (folder / "lattice.toml").write_text(SPEC)
    specimen, settings, _ = load_spec(folder / "lattice.toml", {
        "specimen.bond_material.young_modulus": TRUE_MODULUS,
        "specimen.bond_material.normal_strength": TRUE_STRENGTH})
    numbers = RUNNERS["tension"](specimen, settings).numbers
    return folder, numbers["young_modulus_secant"], numbers["tensile_strength"]


def _file(folder, name, **values):
    path = folder / name
    path.write_text(CALIBRATION.format(**values))
    return path


@pytest.fixture(scope="module")
def whole(truth):
    folder, modulus, strength = truth
    path = _file(folder, "calib.toml", budget=6, modulus=modulus, strength=strength)
    stages = []
    summary = run_calibration(path, folder / "whole", stage=stages.append)
    return path, summary, stages


def test_recovers_the_identifiable_parameters_and_says_which_is_not(whole):
    _, summary, stages = whole
    # the runs after the trials are announced (the progress bar is full by then)
    assert stages == ["identifiability: 3 runs, each parameter moved by 5 % of its range",
                      "rate: the best set's 1 test(s) again at half the strain rate"]
    # the lattice in tension is quasi-static at its rate: within the lab's 2 % and 0.5 %
    change = summary["rate_change"]["tension"]
    assert abs(change["strength"]) < 0.02 and abs(change["modulus"]) < 0.005
    assert not [w for w in summary["warnings"] if "half the strain rate" in w]
    best = summary["best"]["parameters"]
    assert best["specimen.bond_material.young_modulus"] == pytest.approx(TRUE_MODULUS,
                                                                         rel=0.03)
    assert best["specimen.bond_material.normal_strength"] == pytest.approx(TRUE_STRENGTH,
                                                                           rel=0.03)
    verdict = summary["identifiability"]
    assert verdict["specimen.bond_material.young_modulus"]["identifiable"]
    assert verdict["specimen.bond_material.normal_strength"]["identifiable"]
    assert not verdict["specimen.bond_material.tangential_strength"]["identifiable"]
    assert "not identifiable" in verdict["specimen.bond_material.tangential_strength"][
        "verdict"]
    assert summary["consistent"] and summary["trials"] == 6
    # two targets cannot fix three parameters, and the summary says so
    assert any("2 target(s) for 3 parameters" in w for w in summary["warnings"])


def test_a_killed_calibration_resumes_to_the_same_result(whole, truth):
    path, summary, _ = whole
    folder = truth[0]
    out = folder / "cut"
    assert run_calibration(path, out, stop_after=3) is None     # mid-way through a batch
    rows = (out / "calibration.csv").read_text().splitlines()
    assert len(rows) == 1 + 3
    with pytest.raises(InputError, match="--resume"):
        run_calibration(path, out)
    resumed = run_calibration(path, out, resume=True)
    assert (out / "calibration.csv").read_text() == (folder / "whole" /
                                                    "calibration.csv").read_text()
    assert resumed["best"] == summary["best"]
    assert json.loads((out / "calibration.json").read_text())["best"]["trial"] == \
        summary["best"]["trial"]


def test_the_runs_after_the_trials_survive_a_kill(whole, truth, monkeypatch):
    """The identifiability runs are kept as they finish (calibration_checks.json): a
    calibration killed after them resumes without running anything again, and one whose
    kept runs were lost runs exactly those again."""
    import bondem.calibrate as calibrate
    path, summary, _ = whole
    out = truth[0] / "whole"
    kept = json.loads((out / "calibration_checks.json").read_text())
    assert len(kept) == 4     # one run per parameter and the rate check, one test
    calls = []
    real = calibrate._safe
    monkeypatch.setattr(calibrate, "_safe", lambda *a: calls.append(a) or real(*a))
    again = run_calibration(path, out, resume=True)
    assert calls == [] and again["identifiability"] == summary["identifiability"]
    (out / "calibration_checks.json").unlink()
    again = run_calibration(path, out, resume=True)
    assert len(calls) == 4 and again["identifiability"] == summary["identifiability"]
    assert again["rate_change"] == summary["rate_change"]


def test_unreachable_targets_fail_with_a_message(truth):
    folder, modulus, strength = truth
    path = _file(folder, "far.toml", budget=4, modulus=modulus * 100, strength=strength)
    with pytest.raises(CalibrationFailed, match="young_modulus_secant .* outside what the "
                                                "bounds"):
        run_calibration(path, folder / "far")
    run = CliRunner().invoke(main, ["calibrate", str(path), "--scheduler", "serial",
                                    "--out", str(folder / "far_cli")])
    assert run.exit_code == 1 and "calibration failed" in run.output


def test_contradictory_targets_end_with_what_the_best_set_misses(truth):
    """A lattice's E and strength come from separate parameters, but a tensile strength
    with only one strength parameter held fixed below it cannot be met."""
    folder, modulus, strength = truth
    path = _file(folder, "contra.toml", budget=4, modulus=modulus, strength=strength)
    text = path.read_text().replace('low = 3e5\nhigh = 3e7\nlog = true\n[parameters."'
                                    'specimen.bond_material.tangential_strength"]',
                                    'low = 3e5\nhigh = 1e6\nlog = true\n[parameters."'
                                    'specimen.bond_material.tangential_strength"]')
    path.write_text(text)
    with pytest.raises(CalibrationFailed, match="tensile_strength"):
        run_calibration(path, folder / "contra")


def test_bad_calibration_files_name_the_key(truth, tmp_path):
    folder = truth[0]
    good = CALIBRATION.format(budget=4, modulus=1e7, strength=1e5)
    for change, key in (('budget = 4', 'budget = 1'), ('test = "tension"', 'test = "x"'),
                        ('low = 2e7', 'low = -2e7')):
        path = folder / "bad.toml"
        path.write_text(good.replace(change, key, 1))
        with pytest.raises(InputError) as error:
            load_calibration(path)
        assert error.value.key in ("budget", "targets.young_modulus_secant.test",
                                   'parameters.specimen.bond_material.young_modulus.low')


def test_runs_as_a_dask_ensemble_from_the_command_line(truth):
    folder, modulus, strength = truth
    path = _file(folder, "dask.toml", budget=3, modulus=modulus, strength=strength)
    run = CliRunner().invoke(main, ["calibrate", str(path), "--workers", "2",
                                    "--out", str(folder / "dask")])
    assert run.exit_code == 0, run.output
    summary = json.loads((folder / "dask" / "calibration.json").read_text())
    assert summary["trials"] == 3
    best = summary["best"]["parameters"]["specimen.bond_material.young_modulus"]
    assert best == pytest.approx(TRUE_MODULUS, rel=0.03)    # the scaling rules' guess
    assert (folder / "dask" / "calibration.html").stat().st_size > 1000


def test_the_worked_example_file_loads():
    from pathlib import Path
    example = Path(__file__).resolve().parents[1] / "examples" / "calibration_rock.toml"
    calibration = load_calibration(example)
    assert calibration.tests == ["brazilian", "ucs"]
    assert len(calibration.parameters) == 4 and len(calibration.targets) == 4


def test_a_failed_first_trial_fails_with_its_own_error(truth, monkeypatch):
    """The first trial's run blows up: the calibration stops with that run's error, not
    with the scaling rule's 'nan to nan' taken from its missing numbers."""
    import bondem.calibrate as calibrate
    folder, modulus, strength = truth
    path = _file(folder, "fails.toml", budget=4, modulus=modulus, strength=strength)
    monkeypatch.setattr(calibrate, "_safe", lambda spec, test, overrides: {
        "error": f"{test}: SimulationBlowUp: a particle left the domain"})
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(path, folder / "fails")
    message = str(error.value)
    assert "first trial" in message and "a particle left the domain" in message
    assert "nan" not in message


def test_a_trial_whose_specimen_did_not_fail_is_a_failed_trial(truth):
    """A tension test stopped at its strain limit (0.1 %, below the lattice's failure
    strain sigma_b / E_b = 1.5 %) has no tensile strength: the first trial fails with the
    lab's reason instead of scaling the largest stress reached as if it were one."""
    folder, modulus, strength = truth
    (folder / "short.toml").write_text(SPEC + "max_strain = 0.001\n")   # in [test]
    path = folder / "short_calib.toml"
    path.write_text(CALIBRATION.format(budget=4, modulus=modulus, strength=strength)
                    .replace('"lattice.toml"', '"short.toml"'))
    with pytest.raises(CalibrationFailed) as error:
        run_calibration(path, folder / "short")
    message = str(error.value)
    assert "first trial" in message and "did not fail" in message
    assert "strain limit" in message and "no tensile_strength: a failed trial" in message


def test_linearised_uncertainty_of_a_combination_the_targets_cannot_split():
    """Targets in tolerances y1 = 2 u1 + u2 and y2 = 5 u3 (u: each parameter's place in
    its range): u1 and u2 enter only as one combination, so both are free along
    (1, -2, 0); u3 is fixed to 1/5 of its range by one tolerance of y2."""
    from bondem.calibrate import linearised_uncertainty
    sigma = linearised_uncertainty([[2.0, 1.0, 0.0], [0.0, 0.0, 5.0]])
    assert math.isinf(sigma[0]) and math.isinf(sigma[1])
    assert sigma[2] == pytest.approx(0.2, rel=1e-12)


def test_linearised_uncertainty_is_the_scatter_of_the_least_squares_fit():
    """By definition: the standard deviation of the parameters fitted by least squares
    to targets with unit (one tolerance) Gaussian noise."""
    from bondem.calibrate import linearised_uncertainty
    jacobian = np.array([[2.0, 1.0, 0.0], [0.0, 1.0, 0.5], [1.0, 0.0, 3.0],
                         [0.3, -0.7, 0.2]])
    noise = np.random.default_rng(7).standard_normal((4, 40000))
    fitted = np.linalg.lstsq(jacobian, noise, rcond=None)[0]
    np.testing.assert_allclose(linearised_uncertainty(jacobian), fitted.std(axis=1),
                               rtol=0.02)


class _LinearLab:
    """Stands in for the lab: E = 1e9 Pa (a + b), UCS = 1e6 Pa c, and on specimen seed 2
    the UCS comes out 14 % higher (a specimen's scatter)."""
    errors = {}

    @staticmethod
    def predict(params):
        ucs = 1e6 * params["c"] * (1.14 if params.get("specimen.seed") == 2 else 1.0)
        return {"young_modulus_secant": 1e9 * (params["a"] + params["b"]), "ucs": ucs}

    def run(self, jobs):
        return {trial: self.predict(params) for trial, params in jobs.items()}


def test_summary_reports_free_combinations_and_seed_scatter(tmp_path):
    """a and b enter only as a + b: both not identifiable (one target, two unknowns), c
    identified to +-1/22.5 of its range (dUCS/du_c = 9e6 Pa = 22.5 tolerances); a seed
    whose UCS misses the target by more than its tolerance is named."""
    from bondem.calibrate import Calibration, Parameter, Target, summarise
    calibration = Calibration(tmp_path / "c.toml", tmp_path / "spec.toml",
                              [Parameter("a", 0.1, 1.0), Parameter("b", 0.2, 2.0),
                               Parameter("c", 1.0, 10.0)],
                              [Target("young_modulus_secant", "ucs", 1e9, 0.05),
                               Target("ucs", "ucs", 4e6, 0.1)], check_seeds=[1, 2],
                              rate_check=False)
    lab = _LinearLab()
    best = {"a": 0.3, "b": 0.7, "c": 4.0}
    rows = {0: {"trial": 0, **best, **lab.predict(best), "misfit": 0.0}}
    summary = summarise(calibration, rows, lab)
    verdict = summary["identifiability"]
    assert not verdict["a"]["identifiable"] and not verdict["b"]["identifiable"]
    assert "not identifiable" in verdict["a"]["verdict"]
    assert verdict["c"]["uncertainty_of_range"] == pytest.approx(1 / 22.5, rel=1e-9)
    assert "+-4.4 %" in verdict["c"]["verdict"]
    warnings = summary["warnings"]
    assert any("2 target(s) for 3 parameters" in w for w in warnings)
    (seed,) = [w for w in warnings if "seed" in w]
    assert "ucs on specimen seed 2" in seed and "+14.0%" in seed

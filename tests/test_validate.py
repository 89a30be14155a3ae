"""``bondem validate``: the quick suite passes through the command line, the table lists
every quick case, a wrong reference makes rows fail (exit status 1), reference-data
folders appear as cases, and the report files are written."""
import csv
import math
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.validation import load_cases, load_parameters, run_suite
from bondem.validation import bond_models, refdata, strength, wave


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("validation")
    result = CliRunner().invoke(main, ["validate", "--quick", "--out", str(out)])
    return result, out


def test_quick_suite_passes_and_lists_every_quick_case(quick_run):
    result, out = quick_run
    assert result.exit_code == 0, result.output
    quick = [c.name for c in load_cases().values() if c.quick]
    assert {"two_particle", "cantilever", "wave", "strength", "rotation", "contact",
            "refdata"} <= set(quick)
    lines = result.output.splitlines()
    for name in quick:
        assert any(line.startswith(name) for line in lines), name
    assert " FAIL" not in result.output
    with open(out / "validation.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert {r["case"] for r in rows} >= set(quick)
    assert all(r["pass"] in ("pass", "skip", "info") for r in rows)
    # The physics cases really compared numbers (not only skipped rows).
    compared = [r for r in rows if r["pass"] == "pass" and r["error"]]
    assert len(compared) >= 15
    markdown = (out / "validation.md").read_text().splitlines()
    assert sum(line.endswith("| pass |") and not line.startswith("| case")
               for line in markdown) == sum(r["pass"] == "pass" for r in rows)
    assert list(out.glob("*.png"))


def test_wrong_reference_fails_and_exits_1(monkeypatch):
    # The reference stiffness 10 % too high: frequencies 4.9 % off, beyond 0.2 %.
    right = wave._stiffness
    monkeypatch.setattr(wave, "_stiffness", lambda p: 1.1 * right(p))
    result = CliRunner().invoke(main, ["validate", "--quick", "--case", "wave"])
    assert result.exit_code == 1, result.output
    assert "FAIL" in result.output
    rows = run_suite(quick=True, cases=["wave"])
    assert rows and all(r.passed is False for r in rows)
    assert all(abs(r.error) > 0.04 for r in rows)


def test_unknown_case_is_bad_input():
    result = CliRunner().invoke(main, ["validate", "--case", "nope"])
    assert result.exit_code == 2
    assert "--case" in result.output and "two_particle" in result.output


def test_reference_folders_appear_as_cases(tmp_path, monkeypatch):
    monkeypatch.setenv("BONDEM_REFDATA", str(tmp_path))
    assert run_suite(cases=["refdata"])[0].note.startswith("none found")
    folder = tmp_path / "musen_beam"
    folder.mkdir()
    (folder / "SCENE.md").write_text("# MUSEN cantilever\n\nparameters ...\n")
    (folder / "tip.csv").write_text("time,tip_y\n0,0\n")
    rows = run_suite(cases=["refdata"])
    assert [r.case for r in rows] == ["refdata:musen_beam"]
    assert rows[0].quantity == "MUSEN cantilever" and rows[0].passed is None
    assert "tip.csv" in rows[0].note
    assert refdata.read_columns(folder / "tip.csv")["tip_y"].tolist() == [0.0]


def test_musen_compat_switches_the_start_up_increment():
    # In MUSEN-compatible mode the prediction step adds a full dt and t = 0 is evaluated
    # twice: the closed forms use (m + 2) instead of SPEC mode's m. The stress-at-break
    # rows (tolerance 1e-6) pass only if the simulation really switched.
    result = CliRunner().invoke(main, ["validate", "--compat", "musen", "--case", "strength"])
    assert result.exit_code == 0, result.output
    assert "MUSEN-compatible" in result.output
    table = [line for line in result.output.splitlines() if line.startswith("strength  ")]
    assert len(table) == 12 and all(line.rstrip().endswith("pass") for line in table)
    spec = load_parameters("strength")
    assert all(r.passed for r in strength.run(spec, None).rows)


class _NumpyHertz:
    """A plain NumPy Hertz law with Tsuji damping for two spheres (normal only): stands in
    for bondem.contacts so that the contact case's measurement is tested before that
    module exists."""

    def accumulate(self, model, state, force, moment, increment_dt):
        import math

        import numpy as np
        material = model.materials[0]
        r = state.position[1] - state.position[0]
        distance = np.linalg.norm(r)
        radius = model.radius[0]
        overlap = 2 * radius - distance
        if overlap <= 0:
            return
        n = r / distance
        e_star = material.young_modulus / (2 * (1 - material.poisson_ratio ** 2))
        r_star, m_star = radius / 2, model.mass[0] / 2
        e = material.restitution
        beta = math.log(e) / math.sqrt(math.log(e) ** 2 + math.pi ** 2) if e < 1 else 0.0
        stiffness = 2 * e_star * math.sqrt(r_star * overlap)
        rate = -np.dot(state.velocity[1] - state.velocity[0], n)  # overlap rate
        f = (4 / 3) * e_star * math.sqrt(r_star) * overlap ** 1.5 \
            - 2 * math.sqrt(5 / 6) * beta * math.sqrt(stiffness * m_star) * rate
        force[0] -= f * n
        force[1] += f * n


def test_contact_case_measures_restitution_and_contact_time(monkeypatch):
    import sys
    import types

    import bondem
    fake = types.ModuleType("bondem.contacts")
    fake.ContactSettings = lambda model: model
    monkeypatch.setitem(sys.modules, "bondem.contacts", fake)
    original = bondem.Simulation

    def simulation(model, state, *, contact=None, **options):
        assert contact == "hertz_mindlin"
        return original(model, state, laws=[_NumpyHertz()], **options)
    monkeypatch.setattr(bondem, "Simulation", simulation)
    rows = run_suite(cases=["contact"])
    assert len(rows) == 4 and all(r.passed for r in rows), rows
    assert abs(rows[0].bondem - 1.0) < 0.01 and abs(rows[2].bondem - 0.5) < 0.01


def test_reference_folder_with_compare_toml_is_run_and_compared(tmp_path, monkeypatch):
    # A free sphere moving at 0.5 m/s: x = 0.5 t exactly. A stand-in scene loader (the
    # scene module's API: .model, .state, .simulation_options) feeds the runner.
    import sys
    import types

    import bondem
    fake = types.ModuleType("bondem.scene")

    def load_scene(path):
        material = bondem.Material(density=2500.0, young_modulus=1e8)
        model, state = bondem.make_system([[0.0, 0.0, 0.0]], 1e-3, material,
                                          velocity=[[0.5, 0.0, 0.0]])
        return types.SimpleNamespace(model=model, state=state,
                                     simulation_options={"time_step": 1e-6})
    fake.load_scene = load_scene
    monkeypatch.setitem(sys.modules, "bondem.scene", fake)
    monkeypatch.setenv("BONDEM_REFDATA", str(tmp_path))
    for name, factor in (("good", 1.0), ("bad", 1.01)):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "SCENE.md").write_text(f"# free flight ({name})\n")
        (folder / "scene.toml").write_text("")
        (folder / "x.csv").write_text("time,x\n" + "".join(
            f"{t},{0.5 * t * factor}\n" for t in (1e-4, 2e-4, 3e-4)))
        (folder / "compare.toml").write_text(
            'scene = "scene.toml"\n[[compare]]\nfile = "x.csv"\ntime_column = "time"\n'
            'column = "x"\nquantity = "particles/position"\nindex = [0, 0]\n'
            'tolerance = 1e-9\n')
    rows = {r.case: r for r in run_suite(cases=["refdata"])}
    assert rows["refdata:good"].passed is True
    assert rows["refdata:bad"].passed is False
    assert abs(rows["refdata:bad"].error) > 5e-3


def test_every_compare_item_sees_its_own_times(tmp_path, monkeypatch):
    """Two [[compare]] items over the same times (x and y of a particle in free flight,
    x = 0.5 t, y = -2 t): the second item must see the state at each of its times, not the
    state the first item's run ended in."""
    import sys
    import types

    import bondem
    fake = types.ModuleType("bondem.scene")

    def load_scene(path):
        material = bondem.Material(density=2500.0, young_modulus=1e8)
        model, state = bondem.make_system([[0.0, 0.0, 0.0]], 1e-3, material,
                                          velocity=[[0.5, -2.0, 0.0]])
        return types.SimpleNamespace(model=model, state=state,
                                     simulation_options={"time_step": 1e-6})
    fake.load_scene = load_scene
    monkeypatch.setitem(sys.modules, "bondem.scene", fake)
    monkeypatch.setenv("BONDEM_REFDATA", str(tmp_path))
    folder = tmp_path / "flight"
    folder.mkdir()
    (folder / "SCENE.md").write_text("# free flight\n")
    (folder / "scene.toml").write_text("")
    (folder / "xy.csv").write_text("time,x,y\n" + "".join(
        f"{t},{0.5 * t},{-2.0 * t}\n" for t in (1e-4, 2e-4, 3e-4)))
    items = "".join(f'[[compare]]\nfile = "xy.csv"\ntime_column = "time"\ncolumn = "{c}"\n'
                    f'quantity = "particles/position"\nindex = [0, {k}]\ntolerance = 1e-9\n'
                    for k, c in enumerate("xy"))
    (folder / "compare.toml").write_text('scene = "scene.toml"\n' + items)
    rows = run_suite(cases=["refdata"])
    assert len(rows) == 1 and rows[0].passed is True, rows
    assert "2 columns" in rows[0].quantity


MUSEN_RUNS = Path(__file__).resolve().parents[2] / "shared" / "musen-runs"


@pytest.mark.skipif(not MUSEN_RUNS.is_dir(), reason="no ../shared/musen-runs")
def test_real_musen_runs_pass_in_compat_mode_and_are_info_in_spec_mode():
    """The four runs of the real MUSEN 1.70.0: positions, velocities and spins within
    their tolerances and every bond breaking in MUSEN's step, with --compat musen."""
    rows = [r for r in run_suite(cases=["refdata"], compat="musen")
            if r.case.startswith("refdata:")]
    names = {r.case for r in rows}
    assert {"refdata:two_bonded", "refdata:cluster", "refdata:breaking_combined",
            "refdata:breaking_separate"} <= names
    assert all(r.passed is True for r in rows), [r for r in rows if not r.passed]
    # runs whose bondem scene is MUSEN-compatible itself (the Kelvin run, the external
    # force fields) are compared in either mode; the others are information in SPEC mode
    compat_scenes = {f"refdata:{run.name}" for run in refdata.discover(refdata.PACKAGED_RUNS)
                     if "compare" in run.spec and tomllib.loads(
                         (run.path / run.spec["scene"]).read_text())["simulation"].get(
                         "musen_compat", False)}
    assert {"refdata:kelvin_cluster", "refdata:viscous_field",
            "refdata:centrifugal_casting"} <= compat_scenes
    spec = [r for r in run_suite(cases=["refdata"])
            if r.case in names and r.case not in compat_scenes]
    assert spec and all(r.passed is None and r.note.startswith("info") for r in spec)


def test_real_musen_kelvin_run_passes_in_both_modes():
    """The packaged run of the real MUSEN 1.70.0 with ModelSBKelvin (a MUSEN-compatible
    scene, so compared in either mode): 5 of 54 bonds break in MUSEN's step, positions,
    velocities and spins within 1e-6 of the largest value (measured 1e-12)."""
    (kelvin,) = [r for r in refdata.discover(refdata.PACKAGED_RUNS)
                 if r.name == "kelvin_cluster"]
    for compat in ("musen", None):
        rows = refdata.compare_run(kelvin, compat, compat_only=True)
        assert len(rows) == 4 and all(r.passed is True for r in rows), rows
        worst = max(abs(r.error) for r in rows if "particles/" in r.quantity)
        assert worst < 1e-10, rows


def test_bond_model_rows_pass_and_fail_when_the_reference_is_wrong():
    """The bond_models case: its 12 rows pass in both modes; told a friction angle of 30
    degrees while the bonds have 35, its three Mohr-Coulomb rows fail (the rows can fail)."""
    spec = load_parameters("bond_models")
    for compat in (None, "musen"):
        rows = bond_models.run(spec, compat).rows
        assert len(rows) == 12 and all(r.passed for r in rows), rows
    real = bond_models.compare

    def wrong(case, quantity, reference, value, tolerance, **kw):
        if "Mohr-Coulomb" in kw.get("note", ""):
            normal = float(quantity.split("under ")[1].split(" Pa")[0])
            reference = 2e5 + normal * math.tan(math.radians(30.0))
        return real(case, quantity, reference, value, tolerance, **kw)
    bond_models.compare = wrong
    try:
        rows = bond_models.run(spec, None).rows
    finally:
        bond_models.compare = real
    failed = [r for r in rows if r.passed is False]
    assert len(failed) == 3 and all("shear stress at break" in r.quantity for r in failed)


@pytest.mark.parametrize("name", ["plastic_cluster", "creep_cluster", "weakening_cluster",
                                  "aerogel_cluster", "linear_plastic_cluster",
                                  "concrete_cluster"])
def test_real_musen_plastic_runs_pass_in_compat_mode_and_are_info_in_spec_mode(name):
    """The packaged runs of the real MUSEN 1.74.2 with ModelSBElasticPerfectlyPlastic,
    ModelSBCreep, ModelSBWeakening (factor 0), ModelSBAerogel, ModelSBLinearPlastic
    (which MUSEN runs as its elastic bond at E > 2 Pa) and ModelSBPlasticConcrete (its
    defects reproduced, the cluster flying apart): with --compat musen
    positions, velocities and spins within 1e-10 of the largest value (measured 2.5e-12,
    7.2e-13, 1.9e-12, 5.3e-12) and every bond that breaks (by strain; 16 by MUSEN's stress test) in MUSEN's
    step; SPEC mode's rows are information (MUSEN's tangential cap differs by design)."""
    (run,) = [r for r in refdata.discover(refdata.PACKAGED_RUNS) if r.name == name]
    rows = refdata.compare_run(run, "musen", compat_only=True)
    assert len(rows) == 4 and all(r.passed is True for r in rows), rows
    assert max(abs(r.error) for r in rows if "particles/" in r.quantity) < 1e-10, rows
    spec = refdata.compare_run(run, None, compat_only=True)
    assert len(spec) == 4 and all(r.passed is None for r in spec), spec


def test_an_installed_bondem_names_no_folder_it_does_not_have(monkeypatch):
    """Without ../shared (a pip install): the reference row says how to add reference runs,
    not a path of our repository; the MUSEN rows that are information in SPEC mode are
    explained, with the command that checks them."""
    real = refdata.reference_directory
    monkeypatch.setattr(refdata, "reference_directory",
                        lambda p=None, key="search": None if key != "packaged"
                        else real(p, key))
    (row,) = [r for r in run_suite(cases=["refdata"], quick=True) if r.case == "refdata"]
    assert "shared" not in row.note and "BONDEM_REFDATA" in row.note
    result = CliRunner().invoke(main, ["validate", "--quick", "--case", "refdata"])
    assert result.exit_code == 0, result.output
    assert "shared" not in result.output
    assert "'bondem validate --compat musen' reproduces MUSEN" in result.output

"""Mutation testing of bondem's Python modules with mutmut (issue 43, docs/testing.md).

    python scripts/mutate.py src/bondem/analysis/walls.py            # one module, its tests
    python scripts/mutate.py src/bondem/calibrate.py tests/test_calibrate.py
    python scripts/mutate.py --all                                   # every module in MODULES

mutmut (3.x) runs in a scratch copy of the repository, with the module as the only one
mutated and its tests (MODULES, or those given) as the only ones run. The script prints
each surviving mutant and the score, killed / (killed + survived); a timeout counts as
killed and a mutant no test reaches as survived. It is not part of CI: a module takes
minutes to hours.

The Python that runs it needs bondem's dependencies, pytest and mutmut, but not bondem
itself: an installed bondem (an editable install above all) would be imported instead of
the mutated copy. ``--make-venv DIR`` makes such an environment:

    python scripts/mutate.py --make-venv ~/.cache/bondem-mutation
    ~/.cache/bondem-mutation/bin/python scripts/mutate.py src/bondem/analysis/walls.py

Numba kernels are not mutated this way (mutmut's trampolines cannot be compiled); the
loop bodies and physics have a planted-bug table of their own in docs/testing.md.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# module -> the tests that guard it (run for every mutant: keep them fast). mutmut forks a
# process per mutant; under GNU OpenMP's threading layer Numba's parallel kernels in a
# forked child ended every such run "suspicious" (io/lammps.py's export tests, which load
# scene files: 399 of 660 mutants), which the score counts as survivors. The runs below
# use the workqueue layer, under which those tests run (the same module: no suspicious).
MODULES = {
    "src/bondem/analysis/walls.py": ["tests/test_analysis_walls.py"],
    "src/bondem/analysis/energy.py": ["tests/test_analysis_walls.py"],
    "src/bondem/analysis/fragments.py": ["tests/test_analysis_fragments.py"],
    "src/bondem/analysis/breakage.py": ["tests/test_analysis_fragments.py"],
    "src/bondem/timestep.py": ["tests/test_timestep.py"],
    "src/bondem/io/csv_files.py": ["tests/test_csv_files.py"],
    # the closed-form lab's tests: test_calibrate.py runs specimens (a minute a mutant)
    "src/bondem/calibrate.py": ["tests/test_calibrate_rules.py"],
    "src/bondem/io/protowire.py": ["tests/test_protowire.py"],
    "src/bondem/io/checkpoint.py": ["tests/test_checkpoint.py"],
    "src/bondem/io/_h5guard.py": ["tests/test_h5guard.py"],
    "src/bondem/io/vtk.py": ["tests/test_vtk_export.py", "tests/test_vtk_format.py",
                             "tests/test_vtk.py::test_bond_stresses_closed_form"],
    "src/bondem/io/grid_files.py": ["tests/test_grid_files.py"],
    "src/bondem/expression.py": ["tests/test_expression.py"],
    "src/bondem/analysis/fields.py": ["tests/test_analysis_fields.py"],
    "src/bondem/analysis/results.py": ["tests/test_analysis_results.py",
                                       "tests/test_analysis_summary.py"],
    "src/bondem/analysis/summary.py": ["tests/test_analysis_summary.py",
                                       "tests/test_analysis_walls.py",
                                       "tests/test_analysis_fields.py"],
    "src/bondem/lab/measure.py": ["tests/test_lab_measure.py"],
    "src/bondem/lab/spec.py": ["tests/test_lab_spec.py"],
    "src/bondem/lab/envelope.py": [
        "tests/test_lab_ensembles.py",
        "tests/test_lab_envelope.py::test_the_fit_returns_the_criterions_cohesion_and_angle"],
    "src/bondem/lab/cracks.py": [
        "tests/test_lab_ae.py",
        "tests/test_lab_cracks.py::test_magnitude_is_kanamoris_energy_magnitude",
        "tests/test_lab_cracks.py::test_b_value_of_a_gutenberg_richter_sample",
        "tests/test_lab_cracks.py::test_cracks_group_by_distance_and_time",
        "tests/test_lab_cracks.py::test_crack_damage_is_where_the_volume_turns_to_dilatancy"],
    "src/bondem/lab/series.py": [
        "tests/test_lab_ensembles.py",
        "tests/test_lab_envelope.py::test_series_statistics_are_the_sample_mean_and_deviation"],
    "src/bondem/lab/membrane.py": ["tests/test_lab_membrane.py"],
    "src/bondem/lab/output.py": ["tests/test_lab_output.py"],
    "src/bondem/analysis/report.py": ["tests/test_analysis_report.py"],
    "src/bondem/analysis/figures.py": ["tests/test_analysis_figures.py"],
    "src/bondem/analysis/calibration.py": ["tests/test_analysis_calibration.py"],
    "src/bondem/walls.py": ["tests/test_wall_objects.py"],
    "src/bondem/study.py": ["tests/test_study_rules.py"],
    "src/bondem/lab/specimen.py": ["tests/test_lab_specimen.py"],
    "src/bondem/lab/procedures.py": ["tests/test_lab_procedure_rules.py",
                                     "tests/test_lab_cracks.py", "tests/test_lab_ae.py"],
    "src/bondem/scene.py": ["tests/test_scene_rules.py"],
    "src/bondem/io/results.py": ["tests/test_results_writer.py", "tests/test_results.py"],
    "src/bondem/io/musen_text.py": ["tests/test_musen_text_rules.py"],
    "src/bondem/io/musen_mdem.py": ["tests/test_musen_mdem_rules.py"],
    "src/bondem/physics/bond_models.py": ["tests/test_bond_model_rules.py"],
    "src/bondem/physics/bond_elastic.py": ["tests/test_bond_model_rules.py"],
    "src/bondem/physics/bond_kelvin.py": ["tests/test_bond_model_rules.py"],
    "src/bondem/physics/bond_plastic.py": ["tests/test_bond_model_rules.py"],
    "src/bondem/physics/bond_parallel.py": ["tests/test_bond_model_rules.py"],
    "src/bondem/physics/bond_concrete.py": ["tests/test_bond_model_rules.py"],
    "src/bondem/physics/bond_weakening.py": ["tests/test_bond_model_rules.py"],
    # the tests that run LAMMPS itself skip where it is not installed
    "src/bondem/io/lammps.py": ["tests/test_lammps_deck.py", "tests/test_lammps_export.py"],
}
COPIED = ["tests/", "examples/", "docs/", "README.md", "benchmarks/", "scripts/"]


def make_venv(folder):
    """A virtual environment with bondem's dependencies, its test extras and mutmut."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    project = data["project"]
    requirements = project["dependencies"] + project["optional-dependencies"]["test"]
    subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True)
    subprocess.run([str(Path(folder) / "bin" / "python"), "-m", "pip", "install", "-q",
                    *requirements, "mutmut>=3.8"], check=True)


def mutate(module, tests, keep=False):
    """Run mutmut on ``module`` (a path below src/) with ``tests``; returns
    (killed, survived, surviving mutant names)."""
    try:
        import bondem  # noqa: F401
        raise SystemExit("bondem is importable in this Python; run the script with a "
                         "Python that lacks it (--make-venv)")
    except ImportError:
        pass
    work = Path(tempfile.mkdtemp(prefix="bondem-mutate-"))
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    for name in files:
        target = work / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target)
    others = [name for name in files if name.startswith("src/") and name.endswith(".py")
              and name != module]
    config = ("\n[tool.mutmut]\n"
              f"paths_to_mutate = [\"src/\"]\n"
              f"do_not_mutate = {json.dumps(others)}\n"
              f"tests_dir = {json.dumps(tests)}\n"
              f"also_copy = {json.dumps(COPIED)}\n"
              "pytest_add_cli_args = [\"-p\", \"no:cacheprovider\", \"-o\", \"addopts=\"]\n")
    with open(work / "pyproject.toml", "a") as handle:
        handle.write(config)
    # the mutated package, made by mutmut: the folder must exist when Python starts, or
    # the import system remembers it as missing
    (work / "mutants" / "src").mkdir(parents=True)
    # Numba's workqueue threading layer survives mutmut's fork per mutant; GNU OpenMP's
    # (the default where it is installed) does not, and every mutant whose tests reach a
    # parallel kernel ended "suspicious"
    env = dict(os.environ, PYTHONPATH=str(work / "mutants" / "src"), NUMBA_NUM_THREADS="1",
               NUMBA_THREADING_LAYER="workqueue")
    subprocess.run([sys.executable, "-m", "mutmut", "run"], cwd=work, env=env)
    subprocess.run([sys.executable, "-m", "mutmut", "export-cicd-stats"], cwd=work, env=env,
                   capture_output=True)
    stats = json.loads((work / "mutants" / "mutmut-cicd-stats.json").read_text())
    listing = subprocess.run([sys.executable, "-m", "mutmut", "results"], cwd=work, env=env,
                             capture_output=True, text=True).stdout
    # a suspicious mutant (its tests hung or crashed: a Simulation in a forked child)
    # proves nothing: it counts as a survivor, listed, so that such a score is not trusted
    survivors = [line.split(":")[0].strip() for line in listing.splitlines()
                 if line.strip().endswith(("survived", "no tests", "suspicious"))]
    killed = stats["killed"] + stats.get("timeout", 0)
    survived = (stats["survived"] + stats.get("no_tests", 0)
                + stats.get("suspicious", 0))
    if stats.get("suspicious"):
        print(f"{stats['suspicious']} suspicious mutants (counted as survivors): the "
              f"tests of {module} run a Simulation, which mutmut's forked children cannot")
    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    else:
        print(f"kept: {work} (mutmut show NAME there)")
    return killed, survived, survivors


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("module", nargs="?", help="a module below src/bondem")
    parser.add_argument("tests", nargs="*", help="its tests [default: MODULES]")
    parser.add_argument("--all", action="store_true", help="every module in MODULES")
    parser.add_argument("--keep", action="store_true", help="keep the scratch copy")
    parser.add_argument("--make-venv", metavar="DIR", help="make the environment and stop")
    args = parser.parse_args()
    if args.make_venv:
        make_venv(args.make_venv)
        return
    jobs = (list(MODULES.items()) if args.all else
            [(args.module, args.tests or MODULES.get(args.module))])
    if not jobs or jobs[0][0] is None or jobs[0][1] is None:
        parser.error("give a module (and its tests if it is not in MODULES), or --all")
    rows = []
    for module, tests in jobs:
        killed, survived, survivors = mutate(module, tests, args.keep)
        total = killed + survived
        rows.append((module, killed, total))
        for name in survivors:
            print(f"survived: {name}")
        print(f"{module}: {killed} of {total} mutants killed "
              f"({100.0 * killed / max(total, 1):.1f} %)")
    if len(rows) > 1:
        for module, killed, total in rows:
            print(f"| {module} | {killed} / {total} | {100.0 * killed / max(total, 1):.1f} % |")


if __name__ == "__main__":
    main()

""".mdem files of the real MUSEN: ``bondem import musen FILE.mdem [--results]``.

tests/data/musen_mdem holds one run made twice by the real cmusen, 1.70.0 (commit 1547403)
and 1.74.2, both built with shared/tools/musen/build_musen.sh: scene.txt (nine spheres,
four breakable solid bonds, a plane of two triangles rising at 0.2 m/s, Hertz-Mindlin
contacts) imported from text, simulated for 8e-4 s with a save every 1e-4 s, and exported
to text at 17 digits (script_170.txt, script_174.txt: IMPORT_FROM_TEXT, SIMULATOR,
EXPORT_TO_TEXT). scene_174.mdem is the scene as IMPORT_FROM_TEXT wrote it.
"""
import gzip
import os
import json
import random
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.errors import InputError
from bondem.io.musen_mdem import (MdemFile, block_size, break_modes, import_mdem,
                                  import_mdem_results, musen_release)
from bondem.io.musen_text import import_musen, read_series

DATA = Path(__file__).parent / "data" / "musen_mdem"
RUNS = {"170": "1.70.0", "174": "1.74.2"}
SCENE_FILES = ("scene.toml", "particles.csv", "bonds.csv", "walls_0.stl")


def export_series(path):
    """MUSEN's text export as {object id: (type, geometry, activity, [(time, {command:
    values})])}; every number as MUSEN wrote it (17 digits)."""
    objects, _ = read_series(gzip.open(path, "rt"))
    return {i: (o[0], o[1], o[3], o[4]) for i, o in objects.items()}


def test_block_sizes_follow_musens_table():
    # MDEMFile.cpp's table: 4, 4, 8, 12, 16, 24, 32, 48, 64, 96, 128 KB
    assert [block_size(k, 4096) // 1024 for k in range(11)] == [4, 4, 8, 12, 16, 24, 32,
                                                                48, 64, 96, 128]


@pytest.mark.parametrize("version", sorted(RUNS))
def test_mdem_scene_equals_the_text_import_of_the_same_scene(tmp_path, version):
    """The scene, models and settings of MUSEN's result file import to the same bytes
    as the text scene with its cmusen script."""
    mdem = MdemFile(DATA / f"result_{version}.mdem")
    assert mdem.version == 2
    assert musen_release(mdem) == RUNS[version]
    path, notes = import_mdem(DATA / f"result_{version}.mdem", tmp_path / "mdem")
    text, text_notes = import_musen(DATA / "scene.txt", tmp_path / "text",
                                    DATA / f"script_{version}.txt",
                                    musen_version=RUNS[version])
    for name in SCENE_FILES:
        assert (path.parent / name).read_bytes() == (text.parent / name).read_bytes(), name
    assert notes == text_notes
    assert f'musen_version = "{RUNS[version]}"' in path.read_text()


def test_a_scene_file_without_models_imports_with_musens_defaults(tmp_path):
    """IMPORT_FROM_TEXT's own file: no models or time step yet; the elastic bond and no
    contacts, as the text file without a script."""
    path, _ = import_mdem(DATA / "scene_174.mdem", tmp_path / "mdem")
    text, _ = import_musen(DATA / "scene.txt", tmp_path / "text")
    for name in ("particles.csv", "bonds.csv", "walls_0.stl"):
        assert (path.parent / name).read_bytes() == (text.parent / name).read_bytes(), name


@pytest.mark.parametrize("version", sorted(RUNS))
def test_mdem_results_equal_musens_text_export_at_every_time_point(tmp_path, version):
    results, notes = import_mdem_results(DATA / f"result_{version}.mdem", tmp_path)
    export = export_series(DATA / f"export_{version}.txt.gz")
    spheres = sorted(i for i, o in export.items() if o[0] == 1)
    bonds = sorted(i for i, o in export.items() if o[0] == 9)
    walls = sorted(i for i, o in export.items() if o[0] == 14)
    with h5py.File(results, "r") as f:
        time = f["time"][:]
        expected_time = [t for t, _ in export[spheres[0]][3]]
        assert time.tolist() == expected_time and len(time) == 9
        for row, ident in enumerate(spheres):
            points = export[ident][3]
            for frame, (_, values) in enumerate(points):
                for command, name in ((12, "position"), (15, "velocity"),
                                      (16, "angular_velocity"), (20, "force")):
                    assert f[f"particles/{name}"][frame, row].tolist() == values[command], \
                        (ident, frame, name)
        # bonds: MUSEN's own forces, its tangential overlaps (1.74: code 45, 1.70: the
        # angular velocity it is stored in) and total torques, and the break times
        overlap = 45 if version == "174" else 16
        broken = 0
        for row, ident in enumerate(bonds):
            _, _, (begin, end), points = export[ident]
            for frame, (t, values) in enumerate(points):
                intact = begin <= t <= end
                assert bool(f["bonds/active"][frame, row]) == intact
                if intact:
                    assert f["bonds/force"][frame, row].tolist() == values[20]
                    assert f["musen/bond_tangential_overlap"][frame, row].tolist() \
                        == values[overlap]
                else:
                    assert not f["bonds/force"][frame, row].any()
                if version == "174":
                    assert f["musen/bond_total_torque"][frame, row] == values[43][0]
            if end < time[-1]:
                broken += 1
                # MUSEN exports activity intervals with 6 digits
                assert f["bonds/break_time"][row] == pytest.approx(end, rel=5e-6, abs=0)
                assert f["bonds/break_mode"][row] in (1, 2, 3)
            else:
                assert np.isnan(f["bonds/break_time"][row])
                assert f["bonds/break_mode"][row] == 0
        assert broken >= 2   # the run breaks bonds: the test sees both branches
        # the plane: the sum of its two triangles' forces (on the wall), its travel
        for frame in range(len(time)):
            total = np.sum([export[w][3][frame][1][20] for w in walls], axis=0)
            assert np.array_equal(f["walls/force"][frame, 0], total)
        rise = f["walls/position"][:, 0, 2] - f["walls/position"][0, 0, 2]
        corners = [[values[44] if version == "174" else values[12] + values[31][:3]
                    + values[16] for _, values in export[w][3]] for w in walls]
        centroid_z = np.mean(np.array(corners)[:, :, 2::3], axis=(0, 2))
        np.testing.assert_allclose(rise, centroid_z - centroid_z[0], rtol=1e-12, atol=0)
        # 0.2 m/s from frame to frame (MUSEN saves the plane one step of 1e-7 s ahead)
        np.testing.assert_allclose(np.diff(rise[1:]), 0.2 * np.diff(time[1:]), rtol=1e-8)
        assert abs(rise[1] - 0.2 * time[1]) <= 0.2 * 1e-7 * 1.000001
        assert f.attrs["musen_version"] == RUNS[version]
    assert any("break modes inferred" in n for n in notes)


def test_break_modes_follow_the_larger_stress_fraction():
    axis = np.array([[0.6, 0.8, 0.0]] * 4)
    side = np.array([0.8, -0.6, 0.0])
    area = np.full(4, 2e-7)
    sigma, tau = np.full(4, 2e6), np.full(4, 3e6)
    force = np.array([0.3 * axis[0],                   # pulls i toward j: 1.5 MPa
                      -0.3 * axis[0],                  # pushes: compression
                      0.3 * axis[0] + 0.5 * side,      # 2.5 MPa of 3 > 1.5 of 2 in tension
                      0.3 * axis[0] + 0.4 * side])     # 2.0 of 3 < 1.5 of 2: tension
    assert break_modes(force, axis, area, sigma, tau).tolist() == [1, 2, 3, 1]


def test_results_import_feeds_analyze_report_and_vtk(tmp_path):
    runner = CliRunner()
    out = tmp_path / "run"
    result = runner.invoke(main, ["import", "musen", str(DATA / "result_174.mdem"),
                                  "--out", str(out), "--results"])
    assert result.exit_code == 0, result.output
    export = export_series(DATA / "export_174.txt.gz")
    ends = [o[2][1] for o in export.values() if o[0] == 9]
    result = runner.invoke(main, ["analyze", str(out / "results.h5")])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "results_analysis" / "summary.json").read_text())
    broken = summary["broken_tension"] + summary["broken_compression"] \
        + summary["broken_shear"]
    assert broken == sum(1 for e in ends if e < 8e-4) == 3
    assert summary["intact_bond_fraction"] == 0.25
    assert summary["peak_wall_force"] > 0.0
    for command in (["report", str(out / "results.h5")],
                    ["export", "vtk", str(out / "results.h5"), "--out", str(tmp_path / "vtk")]):
        result = runner.invoke(main, command)
        assert result.exit_code == 0, (command, result.output)
    # a second import into the same folder would replace the results: refused
    result = runner.invoke(main, ["import", "musen", str(DATA / "result_174.mdem"),
                                  "--out", str(out), "--results"])
    assert result.exit_code == 2 and "results.h5" in result.output


def test_damaged_truncated_and_foreign_files_end_in_one_line_errors(tmp_path):
    """Three hundred damaged variants of a real file: each imports or raises InputError
    naming the file, never anything else. Every truncated file is refused (each block's
    zlib checksum is read); changed bytes pass only where the file holds no data (its
    headers' unused room, the free end of a block)."""
    raw = (DATA / "result_174.mdem").read_bytes()
    rng = random.Random(7)
    foreign = [b"", b"MUSEN", raw[:64], raw[:2000], (DATA / "scene.txt").read_bytes(),
               bytes(4096)]
    truncated = [raw[:rng.randrange(len(raw))] for _ in range(80)]
    changed = []
    for _ in range(220):
        data = bytearray(raw)
        for _ in range(rng.choice((1, 4, 30))):
            data[rng.randrange(len(data))] = rng.randrange(256)
        changed.append(bytes(data))

    def refused(data, k):
        path = tmp_path / f"case{k}.mdem"
        path.write_bytes(data)
        try:
            import_mdem(path, tmp_path / f"out{k}")
        except InputError as error:
            assert str(path) in str(error) and "\n" not in str(error)
            return True
        return False

    assert all(refused(data, k) for k, data in enumerate(foreign + truncated))
    assert sum(refused(data, 1000 + k) for k, data in enumerate(changed)) >= 180
    result = CliRunner().invoke(main, ["import", "musen", str(tmp_path / "case0.mdem"),
                                       "--out", str(tmp_path / "o")])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


# script.txt run by the real cmusen 1.74.2: musen_breaking.mdem from the whole script,
# musen_adhesive.mdem from its jobs 3 and 4 alone: in one cmusen run, the second
# simulation also keeps the first one's Hertz-Mindlin contact models active (measured:
# 1.3e-5 m apart after 2e-4 s; the same models in both jobs: equal to the job alone)
JOBS = DATA / "jobs"


def mdem_frames(path, n):
    """(time (F,), positions (F,n,3), velocities (F,n,3)) of a MUSEN result file's first
    n objects."""
    points = list(MdemFile(path).time_points())
    time = np.array([t for t, _ in points])
    get = [[[[p.get(name, {}).get(a, 0.0) for a in "xyz"] for p in values[:n]]
            for _, values in points] for name in ("coord", "vel")]
    return time, np.array(get[0]), np.array(get[1])


def copy_jobs(folder):
    folder.mkdir()
    (folder / "scene.txt").write_bytes((DATA / "scene.txt").read_bytes())
    for name in ("scene2.txt", "script.txt"):
        (folder / name).write_bytes((JOBS / name).read_bytes())
    return folder / "script.txt"


def test_a_cmusen_script_runs_to_the_real_cmusen_runs_of_it(tmp_path):
    """Two scenes imported, each simulated with other models (Hertz-Mindlin with
    breaking bonds and STOP_CRITERION BROKEN_BONDS 1; JKR with an unbreakable bond), and a
    text export: bondem's runs follow cmusen's runs of the jobs to round-off, and stop at
    the saved frame where MUSEN stopped."""
    from bondem.musen_jobs import run_script
    script = copy_jobs(tmp_path / "jobs")
    written = run_script(script, echo=lambda line: None)
    assert sorted(written) == [1, 2, 3, 4, 5]
    for name in ("breaking", "adhesive"):
        time, position, velocity = mdem_frames(JOBS / f"musen_{name}.mdem", 9)
        with h5py.File(tmp_path / "jobs" / "work" / name / "results.h5", "r") as f:
            ours = f["time"][:]
            if name == "breaking":
                # MUSEN saves once more a step after its stop: the frames before agree
                assert time[-1] - time[-2] == pytest.approx(1e-7, rel=1e-6)
                time, position, velocity = time[:-1], position[:-1], velocity[:-1]
                broken = (~f["bonds/active"][:]).sum(axis=1)
                assert broken[-1] > 1 >= broken[-2] and ours[-1] < 5e-4 - 1e-5
            np.testing.assert_allclose(ours, time, rtol=1e-12, atol=0)
            scale = np.abs(velocity).max()
            assert np.abs(f["particles/position"][:] - position).max() < 1e-16
            assert np.abs(f["particles/velocity"][:] - velocity).max() < 1e-11 * scale
    export = (tmp_path / "jobs" / "work" / "adhesive.txt").read_text()
    assert export.startswith("0 0 1 1 5 0.0005")


def test_a_script_on_dask_equals_its_jobs_run_one_by_one(tmp_path):
    """The two simulations read only the imported scenes: with two workers they run side
    by side (Dask); each equals, bit for bit, the same job run alone (bondem import musen
    of its scene with the job's keys as its script, then bondem run)."""
    from bondem.musen_jobs import read_jobs, run_script
    script = copy_jobs(tmp_path / "jobs")
    run_script(script, workers=2, echo=lambda line: None)
    runner = CliRunner()
    jobs = read_jobs(script)
    texts = {job.result: job.source for job in jobs if job.component == "IMPORT_FROM_TEXT"}
    simulations = [job for job in jobs if job.component == "SIMULATOR"]
    assert len(simulations) == 2 and len({texts[j.source] for j in simulations}) == 2
    for job in simulations:
        alone = tmp_path / f"alone{job.number}"
        alone.mkdir()
        (alone / "script.txt").write_text("".join(f"{k} {v}\n" for k, v in job.keys.items()))
        result = runner.invoke(main, ["import", "musen", str(texts[job.source]), "--script",
                                      str(alone / "script.txt"), "--out", str(alone)])
        assert result.exit_code == 0, result.output
        result = runner.invoke(main, ["run", str(alone / "scene.toml"), "--out",
                                      str(alone), "--no-progress"])
        assert result.exit_code == 0, result.output
        with h5py.File(alone / "results.h5", "r") as a, \
                h5py.File(job.result.with_suffix("") / "results.h5", "r") as b:
            for name in ("time", "particles/position", "particles/velocity",
                         "bonds/active", "bonds/force", "walls/force"):
                assert np.array_equal(a[name][:], b[name][:]), (job.number, name)


@pytest.mark.parametrize("change, message", [
    (("COMPONENT SIMULATOR", "COMPONENT SIMULATE", 1), "component 'SIMULATE'"),
    (("SOURCE_FILE scene.txt", "SOURCE_FILE missing.txt", 1), "does not exist"),
    (("COMPONENT EXPORT_TO_TEXT", "COMPONENT RESULTS_ANALYZER", 1),
     "RESULTS_ANALYZER is not run"),
    (("COMPONENT EXPORT_TO_TEXT", "COMPONENT PACKAGE_GENERATOR", 1),
     "PACKAGE_GENERATOR reads a .mdem file"),
    (("COMPONENT EXPORT_TO_TEXT", "COMPONENT BONDS_GENERATOR", 1), "reads a scene"),
    (("SOURCE_FILE work/adhesive.mdem", "SOURCE_FILE work/scene_t0.mdem", 1),
     "EXPORT_TO_TEXT exports a run"),
])
def test_bad_scripts_stop_before_anything_runs(tmp_path, change, message):
    script = copy_jobs(tmp_path / "jobs")
    script.write_text(script.read_text().replace(*change))
    result = CliRunner().invoke(main, ["run", str(script)])
    assert result.exit_code == 2, result.output
    assert message in result.output and str(script) in result.output
    assert not (tmp_path / "jobs" / "work").exists()


EXPORTED = DATA / "exported"   # exported.mdem: read by cmusen 1.70.0 and 1.74.2


def mdem_content(path):
    """A .mdem file's decoded content: its storage (blocks' placement left out) and
    time points."""
    mdem = MdemFile(path)
    storage = {k: v for k, v in mdem.storage.items() if k != "data_blocks"}
    return storage, list(mdem.time_points())


def test_exported_mdem_round_trips_and_the_real_musen_reads_it(tmp_path):
    """MUSEN's run imported (results.h5), exported again as .mdem: the export holds what
    the file cmusen read holds (tests/data/musen_mdem/exported/exported.mdem, whose text
    export by cmusen 1.70.0 and 1.74.2 is stored beside it), and those texts give back
    every frame of the results to 17 digits; the export imports back to the same
    results."""
    run = tmp_path / "run"
    import_mdem_results(DATA / "result_174.mdem", run)
    result = CliRunner().invoke(main, ["export", "musen", str(run / "results.h5"), "--out",
                                       str(tmp_path / "exported.mdem")])
    assert result.exit_code == 0, result.output
    assert mdem_content(tmp_path / "exported.mdem") == mdem_content(EXPORTED / "exported.mdem")
    script = (tmp_path / "exported_script.txt").read_text()
    assert "SOURCE_FILE ./exported.mdem" in script and "MODEL_SB ModelSBElastic" in script
    back = tmp_path / "back"
    import_mdem_results(tmp_path / "exported.mdem", back)
    with h5py.File(run / "results.h5", "r") as a, h5py.File(back / "results.h5", "r") as b:
        for name in ("time", "particles/position", "particles/velocity",
                     "particles/angular_velocity", "bonds/active", "bonds/break_time",
                     "bonds/pairs", "bonds/diameter", "particles/radius"):
            assert np.array_equal(a[name][:], b[name][:], equal_nan=True), name
        for version in RUNS:
            export = export_series(EXPORTED / f"cmusen_text_{version}.txt.gz")
            spheres = sorted(i for i, o in export.items() if o[0] == 1)
            assert len(spheres) == a["particles/radius"].shape[0]
            for row, ident in enumerate(spheres):
                assert export[ident][1][0] == a["particles/radius"][row]
                for frame, (t, values) in enumerate(export[ident][3]):
                    assert t == a["time"][frame]
                    assert values[12] == a["particles/position"][frame, row].tolist()
                    assert values[15] == a["particles/velocity"][frame, row].tolist()
            bonds = sorted(i for i, o in export.items() if o[0] == 9)
            for row, ident in enumerate(bonds):
                end = export[ident][2][1]
                expected = a["bonds/break_time"][row]
                assert (end == 1e300) if np.isnan(expected) else \
                    end == pytest.approx(expected, rel=5e-6, abs=0)


@pytest.mark.skipif(not os.environ.get("BONDEM_CMUSEN"),
                    reason="needs a cmusen (BONDEM_CMUSEN=path; shared/tools/musen)")
def test_the_real_musen_simulates_an_exported_run_as_bondem_does(tmp_path):
    """cmusen (1.74.2) runs the exported .mdem with its script; it follows bondem's own
    run of the same scene in MUSEN-compatible mode."""
    import subprocess
    script = copy_jobs(tmp_path / "jobs")
    from bondem.musen_jobs import run_script
    run_script(script, echo=lambda line: None)
    results = tmp_path / "jobs" / "work" / "adhesive" / "results.h5"
    result = CliRunner().invoke(main, ["export", "musen", str(results), "--out",
                                       str(tmp_path / "x" / "adhesive.mdem")])
    assert result.exit_code == 0, result.output
    subprocess.run([os.environ["BONDEM_CMUSEN"], "-t=1", "-s=adhesive_script.txt"],
                   cwd=tmp_path / "x", check=True, capture_output=True)
    time, position, _ = mdem_frames(tmp_path / "x" / "adhesive_result.mdem", 9)
    with h5py.File(results, "r") as f:
        np.testing.assert_allclose(time, f["time"][:], rtol=1e-12)
        assert np.abs(position - f["particles/position"][:]).max() < 1e-16


def test_a_bonds_generator_job_makes_musens_bonds(tmp_path):
    """IMPORT_FROM_TEXT, BONDS_GENERATOR (two generators given by the script: surfaces 0
    to 0.3 mm apart with 0.4 mm bonds, 2 to 3 mm apart with 0.3 mm bonds; the scene's own
    bonds removed) and SIMULATOR, run by the real cmusen 1.74.2 (bondgen/musen_run.mdem)
    and by bondem: the same four bonds, and trajectories to round-off."""
    from bondem.musen_jobs import run_script
    folder = tmp_path / "bondgen"
    folder.mkdir()
    (tmp_path / "scene.txt").write_bytes((DATA / "scene.txt").read_bytes())
    (folder / "script.txt").write_bytes((DATA / "bondgen" / "script.txt").read_bytes())
    run_script(folder / "script.txt", echo=lambda line: None)
    bonds = (folder / "work" / "run" / "bonds.csv").read_text().split()
    # scene.txt: surfaces of 2-3 0.264 mm, 4-5 0.055 mm, 6-7 0.0002 mm, 3-4 2.62 mm apart
    assert bonds == ["i,j,diameter,material", "2,3,0.0004,bond", "4,5,0.0004,bond",
                     "6,7,0.0004,bond", "3,4,0.0003,bond"]
    time, position, velocity = mdem_frames(DATA / "bondgen" / "musen_run.mdem", 9)
    with h5py.File(folder / "work" / "run" / "results.h5", "r") as f:
        np.testing.assert_allclose(f["time"][:], time, rtol=1e-12, atol=0)
        assert np.abs(f["particles/position"][:] - position).max() < 1e-16
        assert np.abs(f["particles/velocity"][:] - velocity).max() \
            < 1e-11 * np.abs(velocity).max()
        assert (~f["bonds/active"][-1]).sum() == 3   # the run breaks bonds


def test_a_package_generator_job_fills_musens_volume_with_musens_counts(tmp_path):
    """packing/packing.mdem (written by bondem, read by cmusen 1.74.2): a 4 x 3 x 5 mm box
    to fill at porosity 0.6 with a mixture of 0.4 mm (number fraction 0.6) and 0.6 mm
    (0.4) spheres moving down at 0.1 m/s. MUSEN's counts, floor((1 - 0.6) V f_i /
    sum_k f_k pi d_k^3 / 6) = 220 and 146, are what cmusen made (musen_packed.mdem); bondem
    packs the same numbers inside the box, the scene's own nine spheres kept."""
    from bondem.musen_jobs import run_script
    folder = tmp_path / "packing"
    folder.mkdir()
    for name in ("packing.mdem", "script.txt"):
        (folder / name).write_bytes((DATA / "packing" / name).read_bytes())
    run_script(folder / "script.txt", echo=lambda line: None)
    volume = 4e-3 * 3e-3 * 5e-3
    mean = 0.6 * np.pi / 6 * 4e-4 ** 3 + 0.4 * np.pi / 6 * 6e-4 ** 3
    expected = [int(0.4 * volume / mean * 0.6), int(0.4 * volume / mean * 0.4)]
    musen = scene_spheres(MdemFile(DATA / "packing" / "musen_packed.mdem"))
    assert [sum(1 for o in musen if o.geometry[0] == r) for r in (2e-4, 3e-4)] == expected
    rows = np.genfromtxt(folder / "work" / "fall" / "particles.csv", delimiter=",",
                         names=True, dtype=None, encoding="utf-8")
    new = rows[9:]
    assert [int(np.sum(new["radius"] == r)) for r in (2e-4, 3e-4)] == expected
    assert set(new["material"]) == {"solid"} and np.all(new["vz"] == -0.1)
    centre, half = np.array([0.0, 0.02, 0.005]), np.array([2e-3, 1.5e-3, 2.5e-3])
    for axis, name in enumerate("xyz"):
        assert np.all(np.abs(new[name] - centre[axis]) <= half[axis] - new["radius"] + 1e-9)
    assert len(rows) == 9 + sum(expected)


def scene_spheres(mdem):
    from bondem.io.musen_mdem import scene_of
    return [o for o in scene_of(mdem).objects.values() if o.type == 1]


@pytest.mark.parametrize("line", ["BOND_GEN_MAXDIST 0 3e-4", "BOND_GEN_MAXDIST 1 far",
                                  "BOND_GEN_DIAMETER 1"])
def test_bad_generator_lines_name_the_job_and_key(tmp_path, line):
    folder = tmp_path / "bondgen"
    folder.mkdir()
    (tmp_path / "scene.txt").write_bytes((DATA / "scene.txt").read_bytes())
    script = (DATA / "bondgen" / "script.txt").read_text()
    (folder / "script.txt").write_text(script.replace("BOND_GEN_MAXDIST 1 3e-4", line))
    result = CliRunner().invoke(main, ["run", str(folder / "script.txt")])
    assert result.exit_code == 2, result.output
    assert "job 2" in result.output and line.split()[0] in result.output
    assert not (folder / "work").exists()


@pytest.mark.parametrize("line, message", [
    ("PACK_GEN_POROSITY 1 1.5", "porosity in (0, 1)"),
    ("PACK_GEN_VELOCITY 1 0.0 -0.1", "velocity 3 numbers"),
    ("PACK_GEN_MIXTURE 1 sand", "'sand' is not in the file"),
    ("PACK_GEN_POROSITY 1 0.05", "package generator"),   # more than the packer can place
])
def test_bad_package_generator_lines_name_the_job(tmp_path, line, message):
    folder = tmp_path / "packing"
    folder.mkdir()
    (folder / "packing.mdem").write_bytes((DATA / "packing" / "packing.mdem").read_bytes())
    script = (DATA / "packing" / "script.txt").read_text()
    (folder / "script.txt").write_text(script.replace("PACK_GEN_POROSITY 1 0.6", line))
    result = CliRunner().invoke(main, ["run", str(folder / "script.txt")])
    assert result.exit_code == 2, result.output
    assert "job 1" in result.output and message in result.output
    assert not (folder / "work" / "fall").exists()


def test_the_bond_generator_takes_the_pairs_whose_surfaces_lie_within_its_range():
    """MUSEN's rule: a bond between two spheres whose surfaces are min to max apart, no
    thicker than either; pairs just inside the range's ends are bonded, pairs just
    outside are not."""
    from bondem.io.musen_text import (BOND_GENERATOR, MusenObject, MusenScene,
                                      generate_bonds)
    scene = MusenScene()
    gaps = [0.9e-4, 1.1e-4, 2.9e-4, 3.1e-4]     # between sphere pairs along x
    x = 0.0
    for k, gap in enumerate(gaps):
        scene.objects[2 * k] = MusenObject(2 * k, 1, [5e-4, 5e-4], "a",
                                           coordinates=(x, 0.0, 0.0), time=0.0)
        scene.objects[2 * k + 1] = MusenObject(2 * k + 1, 1, [4e-4, 4e-4], "a",
                                               coordinates=(x + 9e-4 + gap, 0.0, 0.0),
                                               time=0.0)
        x += 0.01
    made = generate_bonds(scene, [dict(BOND_GENERATOR, compound="b", min_distance=1e-4,
                                       max_distance=3e-4, diameter=1e-3)])
    bonds = [o for o in scene.objects.values() if o.type == 9]
    assert made == 2 and sorted((o.geometry[0], o.geometry[1]) for o in bonds) == [
        (2.0, 3.0), (4.0, 5.0)]
    assert all(o.geometry[2] == 8e-4 for o in bonds)   # capped by the smaller sphere
    assert [o.geometry[3] for o in bonds] == pytest.approx([9e-4 + 1.1e-4, 9e-4 + 2.9e-4],
                                                           rel=1e-12)

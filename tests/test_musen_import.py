"""MUSEN scenes in and out: ``bondem import musen`` and ``bondem export musen``.

References: runs of the real MUSEN 1.70.0 (the packaged Kelvin run; ../shared/musen-runs
when present). A MUSEN text scene and its cmusen script, imported, run in the imported
scene's MUSEN-compatible mode, reproduce MUSEN's own trajectories to round-off; an
exported run imports back to the same scene; what cannot be mapped is named.
"""
import csv
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import bondem
from bondem.cli import main
from bondem.errors import InputError
from bondem.io.musen_text import import_musen
from bondem.scene import load_scene

KELVIN = (Path(bondem.__file__).parent / "data" / "validation" / "musen-runs"
          / "kelvin_cluster")
SHARED = Path(__file__).resolve().parents[2] / "shared" / "musen-runs"


def musen_particles(folder):
    with open(folder / "musen_particles.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    time = np.array([float(r["time"]) for r in rows])
    n = (len(rows[0]) - 1) // 9
    position = np.array([[[float(r[f"{a}{k}"]) for a in "xyz"] for k in range(n)]
                         for r in rows])
    velocity = np.array([[[float(r[f"v{a}{k}"]) for a in "xyz"] for k in range(n)]
                         for r in rows])
    return time, position, velocity


def run_imported(folder, tmp_path, musen_version="1.70.0"):
    """Import a reference folder's MUSEN scene and script (made with MUSEN 1.70.0 unless
    ``musen_version`` says otherwise) and follow MUSEN's saved frames."""
    scene_path, notes = import_musen(folder / "musen_scene.txt", tmp_path / "scene",
                                     folder / "musen_script.txt", musen_version=musen_version)
    scene = load_scene(scene_path)
    assert scene.simulation_options["musen_compat"] is True
    sim = bondem.Simulation(scene.model, scene.state, **scene.simulation_options)
    time, position, velocity = musen_particles(folder)
    worst_x = worst_v = 0.0
    for t, x, v in zip(time, position, velocity):
        sim.run(until=t)
        worst_x = max(worst_x, np.abs(sim.state.position - x).max()
                      / np.abs(position - position[0]).max())
        worst_v = max(worst_v, np.abs(sim.state.velocity - v).max() / np.abs(velocity).max())
    return sim, worst_x, worst_v, notes


def test_imported_kelvin_scene_reproduces_the_real_musen_run(tmp_path):
    sim, worst_x, worst_v, notes = run_imported(KELVIN, tmp_path)
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    material = sim.model.bond_materials[0]
    assert (material.model, material.viscosity, material.breakage) == ("kelvin", 2.0,
                                                                        "combined")
    assert np.sum(~sim.state.bond_active) == 5          # as in MUSEN (musen_breaks.csv)
    assert any("MUSEN's defaults" in note for note in notes)   # no interaction line


def test_imported_plastic_scene_reproduces_the_real_musen_run(tmp_path):
    """MUSEN 1.74.2's ModelSBElasticPerfectlyPlastic: its MODEL_SB_PARAMS and the bond
    material's YIELD_STRENGTH (property 15) become the elastic_plastic bond's keys, and
    the imported scene follows MUSEN's run, the strain break included."""
    sim, worst_x, worst_v, _ = run_imported(KELVIN.parent / "plastic_cluster", tmp_path,
                                            musen_version="1.74.2")
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    material = sim.model.bond_materials[0]
    assert (material.model, material.yield_strength, material.compressive_yield_ratio,
            material.tangential_yield, material.fracture_strain,
            material.compressive_fracture_strain, material.normal_strength) == (
        "elastic_plastic", 1.5e5, 1.3, True, 0.02, 0.03, float("inf"))
    assert np.flatnonzero(~sim.state.bond_active).tolist() == [23]   # musen_breaks.csv


def test_imported_creep_scene_reproduces_the_real_musen_run(tmp_path):
    """MUSEN 1.74.2's ModelSBCreep with FRACTURE_BY_STRESS 1: the creep parameters, the
    yield strength and the strengths (read because of that switch) become the creep
    bond's keys; the imported scene follows MUSEN's run and its 16 breaks."""
    folder = KELVIN.parent / "creep_cluster"
    sim, worst_x, worst_v, _ = run_imported(folder, tmp_path, musen_version="1.74.2")
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    material = sim.model.bond_materials[0]
    assert (material.model, material.creep_rate, material.creep_exponent,
            material.yield_strength, material.compressive_fracture_strain,
            material.normal_strength) == ("creep", 1e-4, 0.8, 2e5, float("inf"), 2.6e5)
    with open(folder / "musen_breaks.csv", newline="") as handle:
        broken = [int(r["bond"]) for r in csv.DictReader(handle) if r["break_time"].strip()]
    assert np.flatnonzero(~sim.state.bond_active).tolist() == broken and len(broken) == 16


def test_imported_weakening_scene_reproduces_the_real_musen_run(tmp_path):
    """MUSEN 1.74.2's ModelSBWeakening: BREAKAGE_STRAIN with COMPRESSIVE_BREAK 1 becomes
    fracture strains eps_b and 2 eps_b, WEAKENING_FACTOR and YIELD_STRENGTH their keys;
    the imported scene follows MUSEN's run and its 11 breaks; exported again, MUSEN's
    words come back."""
    folder = KELVIN.parent / "weakening_cluster"
    sim, worst_x, worst_v, _ = run_imported(folder, tmp_path, musen_version="1.74.2")
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    material = sim.model.bond_materials[0]
    assert (material.model, material.yield_strength, material.fracture_strain,
            material.compressive_fracture_strain, material.weakening_factor) == (
        "weakening", 5e4, 0.002, 0.004, 0.0)
    with open(folder / "musen_breaks.csv", newline="") as handle:
        broken = [int(r["bond"]) for r in csv.DictReader(handle) if r["break_time"].strip()]
    assert np.flatnonzero(~sim.state.bond_active).tolist() == broken and len(broken) == 11
    from bondem.io.musen_text import write_script
    scene = {"simulation": {"end_time": 1e-5},
             "bond_materials": {"b": {"model": "weakening", "young_modulus": 1e8,
                                      "fracture_strain": 0.002,
                                      "compressive_fracture_strain": 0.005,
                                      "weakening_factor": 0.25}}}
    notes = write_script(scene, 1e-7, "scene.txt", tmp_path / "script.txt")
    assert ("MODEL_SB_PARAMS CONSIDER_BREAKAGE 1 COMPRESSIVE_BREAK 1 BREAKAGE_STRAIN 0.002 "
            "WEAKENING_FACTOR 0.25") in (tmp_path / "script.txt").read_text()
    assert any("twice the tensile fracture strain" in note for note in notes)


def test_imported_aerogel_scene_reproduces_the_real_musen_run(tmp_path):
    """MUSEN 1.74.2's ModelSBAerogel: its seven parameters become the aerogel bond's keys
    and the imported scene follows MUSEN's run, its 9 breaks included."""
    folder = KELVIN.parent / "aerogel_cluster"
    sim, worst_x, worst_v, _ = run_imported(folder, tmp_path, musen_version="1.74.2")
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    material = sim.model.bond_materials[0]
    assert (material.model, material.compressive_plastic_strain,
            material.tensile_plastic_strain, material.compressive_softness,
            material.tensile_softness, material.tensile_break_strain,
            material.compressive_hardness, material.tensile_hardness) == (
        "aerogel", 8e-4, 1e-3, -1.0, 0.5, 1.3e-3, 0.2, 0.3)
    with open(folder / "musen_breaks.csv", newline="") as handle:
        broken = [int(r["bond"]) for r in csv.DictReader(handle) if r["break_time"].strip()]
    assert np.flatnonzero(~sim.state.bond_active).tolist() == broken and len(broken) == 9


def test_musen_linear_plastic_bond_imports_as_the_elastic_bond_it_is(tmp_path):
    """MUSEN 1.74.2's ModelSBLinearPlastic with E > 2 Pa is its elastic bond: imported as
    bondem's elastic bond (with a note) it follows MUSEN's run and its 36 breaks; with a
    bond modulus of 2 Pa or less (where MUSEN uses KLoad, KUnload) it is refused."""
    folder = KELVIN.parent / "linear_plastic_cluster"
    sim, worst_x, worst_v, notes = run_imported(folder, tmp_path, musen_version="1.74.2")
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    assert sim.model.bond_materials[0].model == "elastic"
    assert any("ModelSBLinearPlastic" in note for note in notes)
    assert int(np.sum(~sim.state.bond_active)) == 36
    text = (folder / "musen_scene.txt").read_text().replace(" 7 100000000.0 ", " 7 1.5 ")
    (tmp_path / "soft.txt").write_text(text)
    with pytest.raises(InputError, match="<= 2 Pa"):
        import_musen(tmp_path / "soft.txt", tmp_path / "soft", folder / "musen_script.txt")


def test_imported_concrete_scene_reproduces_musens_defective_run(tmp_path):
    """MUSEN 1.74.2's ModelSBPlasticConcrete with its YIELD_STRENGTH: imported, it is
    bondem's concrete bond with MUSEN's fixed ratios, and in the imported scene's
    MUSEN-compatible mode it follows MUSEN's run, flying apart as MUSEN's does."""
    folder = KELVIN.parent / "concrete_cluster"
    sim, worst_x, worst_v, _ = run_imported(folder, tmp_path, musen_version="1.74.2")
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    material = sim.model.bond_materials[0]
    assert (material.model, material.yield_strength, material.tensile_yield_ratio,
            material.tensile_softening, material.compressive_hardening,
            material.tensile_failure) == ("concrete", 2e5, 0.7, 0.3, 0.5, True)
    assert int(np.sum(~sim.state.bond_active)) == 29
    assert np.abs(sim.state.velocity).max() > 10.0       # MUSEN's repulsive bonds


def test_an_exported_plastic_run_names_the_model_and_its_parameters(tmp_path):
    """``bondem export musen`` of an elastic-plastic run writes MUSEN's model, its
    parameters (no compressive fracture: 0) and the yield strength; imported back, the
    bond material is the same."""
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material,vx,vy,vz\n"
                                            "0,0,0,1e-3,glass,0,0,0\n"
                                            "2e-3,0,0,1e-3,glass,0.1,0,0\n")
    (tmp_path / "bonds.csv").write_text("i,j,diameter,material\n0,1,1e-3,binder\n")
    (tmp_path / "scene.toml").write_text(
        '[simulation]\nend_time = 1e-5\ntime_step = 1e-7\nsave_every = 5e-6\n'
        'contact_model = "none"\n[materials.glass]\ndensity = 2500.0\n'
        'young_modulus = 1e8\n[bond_materials.binder]\nyoung_modulus = 1e8\n'
        'model = "elastic_plastic"\nyield_strength = 1.2e5\n'
        'compressive_yield_ratio = 1.7\ntangential_yield = false\n'
        'fracture_strain = 0.05\n[particles]\nfile = "particles.csv"\n'
        '[bonds]\nfile = "bonds.csv"\n')
    runner = CliRunner()
    done = runner.invoke(main, ["run", str(tmp_path / "scene.toml")])
    assert done.exit_code == 0, done.output
    out = tmp_path / "musen" / "scene.txt"
    result = runner.invoke(main, ["export", "musen", str(tmp_path / "scene" / "results.h5"),
                                  "--out", str(out)])
    assert result.exit_code == 0, result.output
    script = out.with_name("scene_script.txt").read_text()
    assert "MODEL_SB ModelSBElasticPerfectlyPlastic" in script
    assert ("MODEL_SB_PARAMS FRACTURE_STRAIN_TENSION 0.05 FRACTURE_STRAIN_COMPRESSION 0 "
            "TANGENTIAL_YIELD 0 RATIO_COMPR_TENSILE_YIELD 1.7") in script
    bond_line = [line for line in out.read_text().splitlines()
                 if line.startswith("32 ") and " 15 " in line]
    assert len(bond_line) == 1 and bond_line[0].endswith(" 15 120000.0")
    scene_path, _ = import_musen(out, tmp_path / "back", out.with_name("scene_script.txt"))
    back = load_scene(scene_path).model.bond_materials[0]
    assert (back.model, back.yield_strength, back.compressive_yield_ratio,
            back.tangential_yield, back.fracture_strain, back.compressive_fracture_strain) \
        == ("elastic_plastic", 1.2e5, 1.7, False, 0.05, float("inf"))


def test_a_bond_model_without_a_musen_counterpart_is_refused_by_name(tmp_path):
    """The parallel bond is bondem's own: exporting its run names the model, not a
    KeyError."""
    from bondem.errors import InputError as Error
    from bondem.io.musen_text import write_script
    scene = {"simulation": {"end_time": 1e-5},
             "bond_materials": {"rock": {"model": "parallel", "young_modulus": 1e9}}}
    with pytest.raises(Error, match="'parallel' has no MUSEN counterpart"):
        write_script(scene, 1e-7, "scene.txt", tmp_path / "script.txt")


@pytest.mark.skipif(not SHARED.is_dir(), reason="no ../shared/musen-runs")
@pytest.mark.parametrize("run", ["breaking_combined", "breaking_separate", "two_bonded",
                                 "cluster"])
def test_imported_shared_runs_reproduce_the_real_musen(tmp_path, run):
    sim, worst_x, worst_v, _ = run_imported(SHARED / run, tmp_path)
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    with open(SHARED / run / "musen_breaks.csv", newline="") as handle:
        breaks = [r["break_time"] for r in csv.DictReader(handle)]
    assert int(np.sum(~sim.state.bond_active)) == sum(1 for b in breaks if b.strip())


@pytest.mark.parametrize("run", ["contacts", "moving_wall", "rotating_wall",
                                 "contacts_1.74.2", "jkr_cluster", "vdw_cluster",
                                 "popov_cluster"])
def test_imported_contact_scenes_reproduce_the_real_musen(tmp_path, run):
    """MUSEN's text scenes with contacts: the plane becomes a two-triangle mesh wall (the
    moving one with its velocity, the turning one with its spin), the contacts MUSEN's
    Hertz-Mindlin of the release that made the run; trajectories to round-off
    (docs/musen_compat.md, Contacts). contacts_1.74.2 is MUSEN 1.74.2's text (every
    object's activity written out), imported with the default release; so are the
    clusters of 1.74.2's JKR and van der Waals models, whose surface energy (property 11)
    becomes the material's surface_energy or Hamaker constant 24 pi Dmin^2 w."""
    if run.endswith("1.74.2") or run.endswith("_cluster"):
        sim, worst_x, worst_v, notes = run_imported(KELVIN.parent / run, tmp_path,
                                                    musen_version="1.74.2")
        assert sim.musen_version == "1.74.2"
    else:
        sim, worst_x, worst_v, notes = run_imported(KELVIN.parent / run, tmp_path)
    assert worst_x < 1e-11 and worst_v < 1e-10, (worst_x, worst_v)
    assert sim.walls and sim.contacts.musen_compat
    assert not any("Hertz-Mindlin" in note or "motion" in note for note in notes), notes
    if run == "moving_wall":
        assert sim.walls[0].position(1e-3)[2] == pytest.approx(0.5e-3)


def test_geometry_motion_is_mapped_or_named():
    from bondem.io.musen_text import wall_motion
    interval = "0 1 0 0 0.5 0 0 0 0 0 0"
    assert wall_motion(f"1 1 {interval}", 1e-3) == ({"velocity": [0.0, 0.0, 0.5]}, None)
    keys, note = wall_motion("1 2 0 1e-3 0 0 1 0 0 0 0 0 0 2e-3 3e-3 0 0 -1 0 0 0 0 0 0",
                             5e-3)
    assert note is None and keys["velocity_profile"] == [
        [0.0, 0, 0, 0], [0.0, 0, 0, 0], [0.0, 0, 0, 1], [1e-3, 0, 0, 1], [1e-3, 0, 0, 0],
        [2e-3, 0, 0, 0], [2e-3, 0, 0, -1], [3e-3, 0, 0, -1], [3e-3, 0, 0, 0]]
    keys, note = wall_motion("1 1 0 1 0 0 0 1 2 3 0 0 10", 1e-3)
    assert keys == {"angular_velocity": [0.0, 0.0, 10.0], "rotation_center": [1.0, 2.0, 3.0]}
    assert note is None        # one axis: checked against MUSEN (rotating_wall)
    keys, note = wall_motion("1 1 0 1 0 0 0 0 0 0 1 0 10", 1e-3)
    assert keys["angular_velocity"] == [1.0, 0.0, 10.0] and "Euler" in note
    assert wall_motion("2 1 5 0 0 0 1 0 0 0 0 0 0", 1.0)[1].startswith("its force")
    assert wall_motion("0 0", 1.0) == ({}, None)


def test_export_then_import_gives_the_same_scene(tmp_path):
    scene_path, _ = import_musen(KELVIN / "musen_scene.txt", tmp_path / "a",
                                 KELVIN / "musen_script.txt")
    text = scene_path.read_text()
    scene_path.write_text(text.replace("save_every = 2.5e-05", "save_every = 1e-06")
                          .replace("end_time = 0.0005", "end_time = 2e-06"))
    runner = CliRunner()
    done = runner.invoke(main, ["run", str(scene_path)])
    assert done.exit_code == 0, done.output
    results = tmp_path / "a" / "scene" / "results.h5"
    done = runner.invoke(main, ["export", "musen", str(results), "--out",
                                str(tmp_path / "musen.txt")])
    assert done.exit_code == 0, done.output
    script = tmp_path / "musen_script.txt"
    assert "MODEL_SB ModelSBKelvin" in script.read_text()
    assert "MODEL_SB_PARAMS CONSIDER_BREAKAGE 1 MU 2.0" in script.read_text()
    done = runner.invoke(main, ["import", "musen", str(tmp_path / "musen.txt"), "--script",
                                str(script), "--out", str(tmp_path / "b")])
    assert done.exit_code == 0, done.output
    # the printed next step puts the results beside the imported files, not in b/scene/
    (next_step,) = [line for line in done.output.splitlines() if line.startswith("next: ")]
    import shlex
    words = shlex.split(next_step[len("next: "):].split("   (")[0])
    assert CliRunner().invoke(main, words[1:] + ["--no-progress"]).exit_code == 0
    assert (tmp_path / "b" / "results.h5").is_file() and not (tmp_path / "b" / "scene").exists()
    for name in ("scene.toml", "particles.csv", "bonds.csv"):
        assert (tmp_path / "a" / name).read_text() == (tmp_path / "b" / name).read_text(), \
            name


def test_what_cannot_be_mapped_is_named_and_bad_lines_are_errors(tmp_path):
    lines = (KELVIN / "musen_scene.txt").read_text().splitlines()
    lines.append("34 mix mix 1 solid 0.001 0.001 1")
    lines.append("0 900 1 10 5 0 1 0.001 0.002 23 bond")   # a liquid bond
    (tmp_path / "in.txt").write_text("\n".join(lines) + "\n")
    _, notes = import_musen(tmp_path / "in.txt", tmp_path / "out",
                            KELVIN / "musen_script.txt")
    assert any("mixture" in n for n in notes) and any("liquid bond" in n for n in notes)
    lines[3] = lines[3].replace("0.001", "0.0o1", 1)
    (tmp_path / "bad.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="line 4") as error:
        import_musen(tmp_path / "bad.txt", tmp_path / "out2")
    assert "bad.txt" in str(error.value)


def test_walls_become_mesh_walls(tmp_path):
    text = (KELVIN / "musen_scene.txt").read_text().splitlines()
    n = 27 + 54
    text += [f"0 {n} 1 14 5 23 solid 2 0 12 -0.02 -0.02 -0.01 31 0.02 -0.02 -0.01 0 "
             "16 0.02 0.02 -0.01",
             f"0 {n + 1} 1 14 5 23 solid 2 0 12 -0.02 -0.02 -0.01 31 0.02 0.02 -0.01 0 "
             "16 -0.02 0.02 -0.01",
             "25 plane plane 0 0 0 0", f"27 2 {n} {n + 1}"]
    (tmp_path / "walls.txt").write_text("\n".join(text) + "\n")
    scene_path, _ = import_musen(tmp_path / "walls.txt", tmp_path / "out",
                                 KELVIN / "musen_script.txt")
    scene = load_scene(scene_path)
    (wall,) = scene.simulation_options["walls"]
    assert len(wall.triangles) == 2
    assert np.allclose(wall.vertices[:, 2], -0.01)


WALL_SCENE = """
[simulation]
end_time = 1e-5            # 33.3 steps of 3e-7 s: bondem runs 33
time_step = 3e-7
save_every = 3e-6
contact_model = "hertz_mindlin"
[materials.glass]
density = 2500.0
young_modulus = 1e8
[materials.steel]
density = 7800.0
young_modulus = 2e9
[bond_materials.binder]
young_modulus = 1e8
normal_strength = 1e6
tangential_strength = 1e6
[particles]
file = "particles.csv"
[bonds]
file = "bonds.csv"
[[walls]]
type = "plane"
point = [0.0013, -0.0007, -0.0011]
normal = [0.2, 0.3, 0.9]
material = "steel"
[[walls]]
type = "mesh"
file = "roof.stl"
material = "steel"
"""


def test_export_with_plane_and_mesh_walls_imports_back(tmp_path):
    """A scene with a tilted plane and a mesh wall, run, exported and imported: every
    number is plain text MUSEN reads (no 'np.float64('), the plane becomes two triangles in
    its plane, the mesh comes back vertex for vertex, and MUSEN's script runs as many
    steps as bondem did (end time not a whole number of steps)."""
    import trimesh
    vertices = np.array([[-3e-3, -3e-3, 2.5e-3], [3e-3, -3e-3, 2.7e-3],
                         [3e-3, 3e-3, 2.9e-3], [-3e-3, 3e-3, 2.6e-3]])
    trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], process=False).export(
        tmp_path / "roof.stl")
    (tmp_path / "particles.csv").write_text(
        "x,y,z,radius,material\n0,0,0,0.001,glass\n0.002,0,0,0.001,glass\n")
    (tmp_path / "bonds.csv").write_text("i,j,diameter,material\n0,1,0.001,binder\n")
    (tmp_path / "scene.toml").write_text(WALL_SCENE)
    runner = CliRunner()
    done = runner.invoke(main, ["run", str(tmp_path / "scene.toml")])
    assert done.exit_code == 0, done.output
    out = tmp_path / "musen.txt"
    done = runner.invoke(main, ["export", "musen", str(tmp_path / "scene" / "results.h5"),
                                "--out", str(out)])
    assert done.exit_code == 0, done.output
    assert "np." not in out.read_text()
    # MUSEN 1.74.2 reads it too: every object has its activity interval (1.74 makes one
    # without it inactive) and every result file a folder (1.74 fails on a bare name)
    objects = [line.split() for line in out.read_text().splitlines() if line.startswith("0 ")]
    assert objects and all("24" in words[:16] for words in objects)
    walls = [w for w in objects if w[3] == "14"]
    assert len(walls) == 2 + 2 and all(w[w.index("23") + 2:w.index("23") + 5] ==
                                       ["24", "0", "1e+300"] for w in walls)
    script = (tmp_path / "musen_script.txt").read_text()
    assert "RESULT_FILE ./result.mdem" in script and "SOURCE_FILE ./scene_t0.mdem" in script
    end = float(script.split("END_TIME ")[1].split()[0])
    assert end == pytest.approx(32.5 * 3e-7, rel=1e-12)   # MUSEN stops once it reaches it
    scene_path, _ = import_musen(out, tmp_path / "back", tmp_path / "musen_script.txt")
    scene = load_scene(scene_path)
    assert scene.end_time == pytest.approx(33 * 3e-7, rel=1e-12)
    plane, mesh = scene.simulation_options["walls"]
    normal = np.array([0.2, 0.3, 0.9]) / np.linalg.norm([0.2, 0.3, 0.9])
    assert len(plane.triangles) == 2
    # the import keeps walls as STL files: float32, 6e-8 of the plane's 8 mm corners
    np.testing.assert_allclose((plane.vertices - [0.0013, -0.0007, -0.0011]) @ normal, 0.0,
                               atol=1e-9)
    assert sorted(map(tuple, mesh.vertices)) == sorted(map(tuple, vertices.astype(np.float32)
                                                           .astype(float)))


def test_adhesive_contact_models_are_written_as_musens(tmp_path):
    """export musen: JKR runs as ModelPPJKR / ModelPWJKR, van der Waals as
    ModelPPHertzMindlinVdW with MUSEN's Hertz-Mindlin walls, a liquid bridge (no MUSEN
    counterpart here) as Hertz-Mindlin with a note; the surface energy (property 11) is
    the JKR w, and for van der Waals A / (24 pi Dmin^2) with Dmin = 7.5e-10 m, which the
    import turns back into the same Hamaker constant."""
    from bondem.io import musen_text
    for model, pp, pw, note in (("jkr", "ModelPPJKR", "ModelPWJKR", False),
                                ("vdw", "ModelPPHertzMindlinVdW", "ModelPWHertzMindlin", False),
                                ("liquid_bridge", "ModelPPHertzMindlin", "ModelPWHertzMindlin",
                                 True)):
        path = tmp_path / f"{model}.txt"
        notes = musen_text.write_script({"simulation": {"contact_model": model,
                                                        "end_time": 1e-6}}, 1e-7, "s.txt", path)
        lines = path.read_text().splitlines()
        assert f"MODEL_PP {pp}" in lines and f"MODEL_PW {pw}" in lines
        assert any(model in n for n in notes) == note, notes
    assert musen_text.musen_surface_energy("jkr", {"surface_energy": 0.7}) == {11: 0.7}
    w = musen_text.musen_surface_energy("vdw", {"hamaker_constant": 3e-20})[11]
    assert w == pytest.approx(3e-20 / (24 * math.pi * 7.5e-10 ** 2), rel=1e-15, abs=0.0)
    assert musen_text.bondem_adhesion("vdw", {11: w})["hamaker_constant"] == pytest.approx(
        3e-20, rel=1e-15, abs=0.0)
    assert musen_text.bondem_adhesion("hertz_mindlin", {11: w}) == {}

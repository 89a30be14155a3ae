"""MUSEN's text format and cmusen scripts on constructed files, without a run: what each
command of a line means (MUSENDefinitions.h ETXTCommands), what each script key becomes
in a bondem scene and back, MUSEN's defaults where a file leaves a value out, and every
setting bondem cannot map named in a note. tests/test_musen_import.py checks the same
code against real MUSEN runs."""
import math
import tomllib

import h5py
import numpy as np
import pytest

from bondem.errors import InputError
from bondem.io import musen_text as mt
from bondem.io.musen_text import (MusenObject, MusenScene, export_lines, export_musen,
                                  generate_bonds, generate_package, import_musen,
                                  musen_fluid, package_volume, read_script, read_series,
                                  read_text, simulator_keys, to_bondem, wall_groups,
                                  wall_motion, write_script)
from bondem.physics.contact_hertz_musen import MUSEN_VDW_DMIN, MUSEN_VERSION

# sphere 0 has two time points (the first is the scene's); sphere 1's contact radius is
# not its radius; wall 3 is written as MUSEN 1.70 does (its corners in 12, 31 and 16),
# wall 4 as 1.71 on (command 44)
TEXT = """\
0 0 1 1 5 0.001 0.001 23 glass 24 0 1e+300 2 0 12 0.001 0.002 0.003 15 0.1 0 0 16 0 0 5 \
2 1e-3 12 0.0011 0.002 0.003 15 0.2 0 0 16 0 0 6
0 1 1 1 5 0.0012 0.0013 23 steel 24 0 1e+300 2 0 12 0.0031 0.002 0.003 15 0 0 0 16 0 0 0

0 2 1 9 5 0 1 0.0005 0.0021 23 binder 24 0 1e+300 2 0 12 0 0 0
0 3 1 14 23 steel 24 0 1e+300 2 0 12 0 0 0 31 0.01 0 0 0 16 0 0.01 0
0 4 1 14 23 steel 2 0 44 0 0 0.001 0.01 0 0.001 0 0.01 0.001
22 -0.01 -0.01 -0.01 0.02 0.02 0.02
32 glass glass 0 2500 7 1e8 10 0.3
32 steel steel 0 7800 7 2e9
32 binder binder 7 5e7 8 1e6 9 2e6 10 0.25
33 glass glass 200 0.7 201 0.4 202 0.01
33 steel glass 200 0.6
25 lid geometry1
26 1 1 0 1e-3 0 0 -0.01 0 0 0 0 0 0
27 1 3
40 whatever
29 0
29 1
99 7
"""
SCRIPT = """\
JOB
COMPONENT IMPORT_FROM_TEXT
SOURCE_FILE scene.txt

JOB
COMPONENT SIMULATOR
simulation_step 3e-7
END_TIME 1e-5
SAVING_STEP 2e-6
EXT_ACCEL 0 0 -9.81
MODEL_PP ModelPPHertzMindlin
MODEL_PW ModelPWJKR
CONNECTED_PP_CONTACT 0
STOP_CRITERION BROKEN_BONDS 5
VARIABLE_TIME_STEP 1
VERLET_AUTO 1
"""


def write(folder, name, text):
    path = folder / name
    path.write_text(text)
    return path


def test_a_text_file_is_read_command_by_command(tmp_path):
    scene = read_text(write(tmp_path, "scene.txt", TEXT))
    sphere, other, bond, old, new = (scene.objects[k] for k in range(5))
    assert (sphere.type, sphere.geometry, sphere.compound, sphere.active) == (
        1, [0.001, 0.001], "glass", (0.0, 1e300))
    assert (sphere.time, sphere.times) == (0.0, 2)
    assert sphere.coordinates == (0.001, 0.002, 0.003)       # the first time point's
    assert sphere.velocity == (0.1, 0.0, 0.0) and sphere.angular_velocity == (0.0, 0.0, 5.0)
    assert other.geometry == [0.0012, 0.0013] and other.compound == "steel"
    assert (bond.type, bond.geometry, bond.compound) == (9, [0.0, 1.0, 0.0005, 0.0021], "binder")
    assert (old.coordinates, old.quaternion, old.angular_velocity) == (
        (0.0, 0.0, 0.0), (0.01, 0.0, 0.0, 0.0), (0.0, 0.01, 0.0))
    assert (new.coordinates, new.quaternion, new.angular_velocity) == (
        (0.0, 0.0, 0.001), (0.01, 0.0, 0.001, 0.0), (0.0, 0.01, 0.001))
    assert new.active == (0.0, 1e300) and new.times == 1
    assert scene.domain == (-0.01, -0.01, -0.01, 0.02, 0.02, 0.02) and scene.periodic is None
    assert scene.compounds == {"glass": {0: 2500.0, 7: 1e8, 10: 0.3},
                               "steel": {0: 7800.0, 7: 2e9},
                               "binder": {7: 5e7, 8: 1e6, 9: 2e6, 10: 0.25}}
    assert scene.interactions == {("glass", "glass"): {200: 0.7, 201: 0.4, 202: 0.01},
                                  ("glass", "steel"): {200: 0.6}}
    assert scene.geometries == [["lid", "geometry1", "1 1 0 1e-3 0 0 -0.01 0 0 0 0 0 0", [3]]]
    assert scene.unmapped == ["line 18: command 29 (anisotropy)",
                              "line 19: command 99 (unknown)"]
    assert scene.multispheres == []


def test_periodic_boundaries_and_geometries_without_names(tmp_path):
    scene = read_text(write(tmp_path, "a.txt", "28 1 1 0 1 -1 -2 -3 1 2 3\n25\n26 0 0\n27 2 4 5.0 9\n"
                                               "26 1 2\n30 0\n34 1\n"))
    assert scene.periodic == (True, True, False, True, (-1.0, -2.0, -3.0), (1.0, 2.0, 3.0))
    assert scene.geometries == [["", "", "1 2", [4, 5]]]
    assert scene.unmapped == ["line 7: command 34 (mixture)"]
    scene = read_text(write(tmp_path, "b.txt", "26 1 1\n27 1 3\n25 one\n"))
    assert scene.unmapped == ["line 1: command 26 (unknown)", "line 2: command 27 (unknown)"]
    assert scene.geometries == [["one", "", "", []]]


@pytest.mark.parametrize("line, message", [
    ("x 1", "line 1: expected a command id, got 'x'"),
    ("22 0 0 0 1 1 a", "line 1: expected 6 numbers after command 22, got '0 0 0 1 1 a'"),
    ("32 glass", "line 1: compound line: expected KEY NAME [ID VALUE]..."),
    ("0 5 12 0 0 0", "line 1: an object line needs '0 ID 1 TYPE' first"),
    ("0 5 1 7 5 1 2", "line 1: object type 7: unknown"),
    ("0 5 1 1 77 1", "line 1: unknown object command 77"),
    ("0 5 1 1 q", "line 1: expected a command id, got 'q'"),
    ("0 5 1 1 12 0 0 z", "line 1: expected 3 numbers after command 12, got '0 0 z'"),
])
def test_bad_lines_are_named(tmp_path, line, message):
    path = write(tmp_path, "bad.txt", line + "\n")
    with pytest.raises(InputError) as error:
        read_text(path)
    assert str(error.value) == f"{path}: {message}"


def test_a_binary_file_is_not_text(tmp_path):
    path = tmp_path / "scene.mdem"
    path.write_bytes(b"\x89\xff\xfe binary")
    with pytest.raises(InputError) as error:
        read_text(path)
    assert str(error.value) == f"{path}: not a MUSEN text file (not text)"


def test_a_series_keeps_every_time_point():
    objects, scene = read_series(TEXT.splitlines())
    kind, geometry, compound, activity, points = objects[0]
    assert (kind, geometry, compound, activity) == (1, [0.001, 0.001], "glass", (0.0, 1e300))
    assert points == [(0.0, {12: [0.001, 0.002, 0.003], 15: [0.1, 0.0, 0.0],
                             16: [0.0, 0.0, 5.0]}),
                      (1e-3, {12: [0.0011, 0.002, 0.003], 15: [0.2, 0.0, 0.0],
                              16: [0.0, 0.0, 6.0]})]
    assert objects[2][:4] == (9, [0.0, 1.0, 0.0005, 0.0021], "binder", (0.0, 1e300))
    assert objects[4] == (14, [], "steel", (0.0, 1e300),
                          [(0.0, {44: [0.0, 0.0, 0.001, 0.01, 0.0, 0.001, 0.0, 0.01, 0.001]})])
    assert scene[0] == ["22", "-0.01", "-0.01", "-0.01", "0.02", "0.02", "0.02"]
    assert len(scene) == 13 and ["99", "7"] in scene


def test_a_script_is_the_simulator_jobs_keys(tmp_path):
    keys = read_script(write(tmp_path, "s.txt", SCRIPT))
    assert keys["COMPONENT"] == "SIMULATOR" and keys["SIMULATION_STEP"] == "3e-7"
    assert keys["EXT_ACCEL"] == "0 0 -9.81" and "SOURCE_FILE" not in keys
    assert read_script(write(tmp_path, "t.txt", "end_time  2e-3 \nMODEL_SB\n\n")) == {
        "END_TIME": "2e-3", "MODEL_SB": ""}
    # without a SIMULATOR job: the keys before the first job
    assert read_script(write(tmp_path, "u.txt", "END_TIME 1\nJOB\nCOMPONENT IMPORT\n")) == {
        "END_TIME": "1"}
    assert mt._params("mu 2 Consider_breakage 0 odd") == {"MU": 2.0, "CONSIDER_BREAKAGE": 0.0}


def test_numbers_between_the_model_parameters_and_musen():
    assert mt._from_musen(0.0, "number", True) == math.inf
    assert mt._from_musen(0.0, "number", False) == 0.0
    assert mt._from_musen(2.5, "number", True) == 2.5
    assert mt._from_musen(1.0, "bool", False) is True
    assert mt._from_musen(0.0, "bool", True) is False
    assert mt._to_musen(math.inf, True) == "0" and mt._to_musen(math.inf, False) == "inf"
    assert mt._to_musen(True, True) == "1" and mt._to_musen(False, False) == "0"
    assert mt._to_musen(0.1, True) == "0.1" and mt._to_musen(3, False) == "3.0"


def interval(begin, end, velocity=(0, 0, 0), centre=(0, 0, 0), spin=(0, 0, 0)):
    return " ".join(str(v) for v in (begin, end, *velocity, *centre, *spin))


def test_geometry_motions_become_wall_keys_or_notes():
    static = "its force-dependent motion is not mapped (the wall is static)"
    assert wall_motion("", 1.0) == ({}, None) and wall_motion("0 1", 1.0) == ({}, None)
    assert wall_motion("1 0", 1.0) == ({}, None) and wall_motion("a b", 1.0) == ({}, None)
    assert wall_motion("2 1 " + interval(0, 1, (1, 0, 0)), 1.0) == ({}, static)
    assert wall_motion("1 2 " + interval(0, 1, (1, 0, 0)), 1.0) == ({}, static)
    assert wall_motion("1 1 " + interval(0, 1), 1.0) == ({}, None)
    assert wall_motion("1 1 " + interval(0, 2, (0, -0.1, 0)), 2.0) == (
        {"velocity": [0.0, -0.1, 0.0]}, None)
    assert wall_motion("1 1 " + interval(-1, 3, (0, -0.1, 0)), 2.0)[0] == {
        "velocity": [0.0, -0.1, 0.0]}
    # an interval that ends before the run: a profile that stops the wall
    assert wall_motion("1 1 " + interval(0, 1, (0.5, 0, 0)), 2.0) == ({"velocity_profile": [
        [0.0] * 4, [0.0] * 4, [0.0, 0.5, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]},
        None)
    # two intervals given out of order, the second overlapping the first
    keys, note = wall_motion("1 2 " + interval(2, 4, (0, 0, 1)) + " "
                             + interval(1, 3, (0, 2, 0)), 5.0)
    assert note is None and keys["velocity_profile"] == [
        [0.0] * 4, [1.0, 0, 0, 0], [1.0, 0, 2.0, 0], [3.0, 0, 2.0, 0], [3.0, 0, 0, 0],
        [3.0, 0, 0, 0], [3.0, 0, 0, 1.0], [4.0, 0, 0, 1.0], [4.0, 0, 0, 0]]
    assert wall_motion("1 1 " + interval(0, 2, spin=(0, 0, 3), centre=(1, 2, 3)), 2.0) == (
        {"angular_velocity": [0.0, 0.0, 3.0], "rotation_center": [1.0, 2.0, 3.0]}, None)
    keys, note = wall_motion("1 1 " + interval(0, 2, spin=(1, 0, 3)), 2.0)
    assert keys == {"angular_velocity": [1.0, 0.0, 3.0], "rotation_center": [0.0] * 3}
    assert note == ("its rotation about a skew axis is mapped (angular_velocity, "
                    "rotation_center); MUSEN turns it each step by Euler angles x, y, z of w "
                    "dt, not about the axis: O(dt^2) apart per step")
    turned = "its rotation is not mapped (the wall is static)"
    assert wall_motion("1 1 " + interval(0, 2, (1, 0, 0), spin=(0, 0, 3)), 2.0) == ({}, turned)
    assert wall_motion("1 1 " + interval(0, 1, spin=(0, 0, 3)), 2.0) == ({}, turned)
    assert wall_motion("1 1 " + interval(0.5, 2, spin=(0, 0, 3)), 2.0) == ({}, turned)
    assert wall_motion("1 2 " + interval(0, 2, spin=(0, 0, 3)) + " "
                       + interval(0, 2, (1, 0, 0)), 2.0) == ({}, turned)


def imported(tmp_path, text=TEXT, script=SCRIPT, **kwargs):
    """(scene table, particles.csv lines, bonds.csv lines, notes) of an import."""
    scene = read_text(write(tmp_path, "scene.txt", text))
    keys = read_script(write(tmp_path, "script.txt", script)) if script is not None else None
    notes = to_bondem(scene, keys, tmp_path / "out", **kwargs)
    out = tmp_path / "out"
    return (tomllib.loads((out / "scene.toml").read_text()),
            (out / "particles.csv").read_text().splitlines(),
            (out / "bonds.csv").read_text().splitlines(), notes)


def test_an_import_maps_every_setting_it_can_and_names_the_others(tmp_path):
    data, particles, bonds, notes = imported(tmp_path)
    assert data["materials"] == {
        "glass": {"density": 2500.0, "young_modulus": 1e8, "poisson_ratio": 0.3,
                  "restitution": 0.7, "friction": 0.4, "rolling_friction": 0.01},
        "steel": {"density": 7800.0, "young_modulus": 2e9, "poisson_ratio": 0.2,
                  "restitution": 0.6, "friction": 0.45, "rolling_friction": 0.05}}
    assert data["bond_materials"] == {"binder": {
        "young_modulus": 5e7, "poisson_ratio": 0.25, "normal_strength": 1e6,
        "tangential_strength": 2e6, "breakage": "combined"}}
    assert particles == ["x,y,z,radius,material,vx,vy,vz,wx,wy,wz",
                         "0.001,0.002,0.003,0.001,glass,0.1,0.0,0.0,0.0,0.0,5.0",
                         "0.0031,0.002,0.003,0.0012,steel,0.0,0.0,0.0,0.0,0.0,0.0"]
    assert bonds == ["i,j,diameter,material", "0,1,0.0005,binder"]
    assert data["particles"] == {"file": "particles.csv"} and data["bonds"] == {
        "file": "bonds.csv"}
    simulation = data["simulation"]
    # END_TIME 1e-5 is 33.3 steps of 3e-7 s: MUSEN runs 34
    assert simulation == {"end_time": 34 * 3e-7, "time_step": 3e-7, "musen_compat": True,
                          "musen_version": MUSEN_VERSION, "save_every": 2e-6,
                          "gravity": [0.0, 0.0, -9.81], "contact_model": "hertz_mindlin",
                          "bonded_contacts": False, "box_low": [-0.01] * 3,
                          "box_high": [0.02] * 3, "stop_broken_bonds": 5}
    assert data["walls"] == [{"type": "mesh", "file": "walls_0.stl", "material": "steel",
                              "velocity": [0.0, 0.0, -0.01]},
                             {"type": "mesh", "file": "walls_1.stl", "material": "steel"}]
    import trimesh
    lid = trimesh.load(tmp_path / "out" / "walls_0.stl")
    np.testing.assert_allclose(np.sort(lid.vertices, axis=0),
                               [[0, 0, 0], [0, 0, 0], [0.01, 0.01, 0]], atol=1e-12)
    assert notes == [
        "line 18: command 29 (anisotropy)", "line 19: command 99 (unknown)",
        "interaction steel-steel not given: MUSEN's defaults (restitution 0.6, friction "
        "0.45, rolling friction 0.05)",
        "interaction glass-steel: restitution 0.6 is not the mean of the pure pairs (0.65), "
        "which bondem uses",
        "sphere 1: contact radius 0.0013 differs from its radius; bondem uses the radius",
        "contact model ModelPWJKR: bondem's walls follow 'hertz_mindlin' as MUSEN's "
        "ModelPWHertzMindlin",
        "VARIABLE_TIME_STEP: bondem's step is fixed (SIMULATION_STEP)",
        "VERLET_AUTO 1: no counterpart (bondem's contact list: docs/musen_migration.md)"]


def test_an_import_without_a_script_takes_musens_defaults(tmp_path):
    text = "\n".join(line for line in TEXT.splitlines() if not line.startswith(("32 steel",
                                                                               "33 steel")))
    text = text.replace("32 glass glass 0 2500 7 1e8 10 0.3", "32 glass glass")
    text = text.replace("23 steel", "23 glass")
    data, _, _, notes = imported(tmp_path, text, None)
    assert data["simulation"] == {"end_time": 1e-3, "time_step": "auto", "musen_compat": True,
                                  "musen_version": MUSEN_VERSION, "contact_model": "none",
                                  "box_low": [-0.01] * 3, "box_high": [0.02] * 3}
    assert data["materials"]["glass"] == {"density": 1000.0, "young_modulus": 1e9,
                                          "poisson_ratio": 0.2, "restitution": 0.7,
                                          "friction": 0.4, "rolling_friction": 0.01}
    assert not any("interaction" in n for n in notes)
    data, _, _, _ = imported(tmp_path, text, "END_TIME 1e-5\nSIMULATION_STEP 3e-7\n",
                             end_time=2e-5, musen_version="1.70.0")
    assert data["simulation"]["end_time"] == 2e-5          # given: not rounded to steps
    assert data["simulation"]["musen_version"] == "1.70.0"
    data, _, _, _ = imported(tmp_path, text, "END_TIME 1e-5\n")
    assert data["simulation"]["end_time"] == 1e-5 and data["simulation"]["time_step"] == "auto"
    data, _, _, _ = imported(tmp_path, text, "MODEL_PP ModelPPJKR\n")
    assert data["simulation"]["bonded_contacts"] is True     # MUSEN's default with contacts
    assert data["simulation"]["contact_model"] == "jkr"


@pytest.mark.parametrize("criterion, breakage", [("0", "none"), ("1", "combined"),
                                                 ("2", "separate"), ("7", "combined")])
def test_the_break_criterion(tmp_path, criterion, breakage):
    data, _, _, _ = imported(tmp_path, script=f"MODEL_SB_PARAMS CONSIDER_BREAKAGE {criterion}\n")
    assert data["bond_materials"]["binder"]["breakage"] == breakage


BOND_TEXT = """\
0 0 1 1 5 0.001 0.001 23 glass 2 0 12 0 0 0
0 1 1 1 5 0.001 0.001 23 glass 2 0 12 0.002 0 0
0 2 1 9 5 0 1 0.0005 0.002 23 binder 2 0 12 0 0 0
32 glass glass 0 2500 7 1e8
32 binder binder 7 5e7 8 1e6 9 2e6 15 3e6
"""


def bond_import(tmp_path, model, params="", text=BOND_TEXT):
    data, _, _, notes = imported(tmp_path, text,
                                 f"MODEL_SB {model}\nMODEL_SB_PARAMS {params}\n")
    return data["bond_materials"]["binder"], notes


def test_each_bond_model_takes_its_parameters(tmp_path):
    plastic, _ = bond_import(tmp_path, "ModelSBElasticPerfectlyPlastic",
                             "fracture_strain_tension 0.2 FRACTURE_STRAIN_COMPRESSION 0 "
                             "TANGENTIAL_YIELD 1")
    assert plastic == {"young_modulus": 5e7, "poisson_ratio": 0.2, "breakage": "none",
                       "model": "elastic_plastic", "yield_strength": 3e6,
                       "fracture_strain": 0.2, "compressive_fracture_strain": math.inf,
                       "tangential_yield": True}
    creep, _ = bond_import(tmp_path, "ModelSBCreep", "FRACTURE_BY_STRESS 1 "
                                                     "CREEP_PARAMATER_A 0.5")
    assert creep["model"] == "creep" and creep["breakage"] == "combined"
    assert (creep["normal_strength"], creep["tangential_strength"]) == (1e6, 2e6)
    assert (creep["creep_rate"], creep["creep_exponent"]) == (0.5, 0.01)
    creep, _ = bond_import(tmp_path, "ModelSBCreep")
    assert creep["breakage"] == "none" and "normal_strength" not in creep
    kelvin, _ = bond_import(tmp_path, "ModelSBKelvin", "MU 1e-3")
    assert kelvin["viscosity"] == 1e-3 and kelvin["max_damping_ratio"] == 0.5
    weak, _ = bond_import(tmp_path, "ModelSBWeakening", "BREAKAGE_STRAIN 0.3 "
                                                        "COMPRESSIVE_BREAK 1")
    assert (weak["fracture_strain"], weak["compressive_fracture_strain"]) == (0.3, 0.6)
    elastic, notes = bond_import(tmp_path, "ModelSBLinearPlastic")
    assert "model" not in elastic and elastic["normal_strength"] == 1e6
    assert notes[1:] == ["ModelSBLinearPlastic: MUSEN runs it as its elastic bond when the bond "
                     "Young's modulus exceeds 2 Pa (KLoad, KUnload unused): imported as the "
                     "elastic bond"]
    with pytest.raises(InputError) as error:
        bond_import(tmp_path, "ModelSBLinearPlastic", text=BOND_TEXT.replace("7 5e7", "7 2"))
    assert str(error.value) == (
        "MODEL_SB: solid bond model ModelSBLinearPlastic with bond Young's modulus <= 2 Pa "
        "(compound 'binder'): its loading and unloading branches are not available in bondem")
    with pytest.raises(InputError) as error:
        bond_import(tmp_path, "ModelSBFoo")
    assert str(error.value) == ("MODEL_SB: solid bond model ModelSBFoo: not available in "
                                "bondem (allowed: " + ", ".join(mt.BOND_MODELS) + ")")
    # without bonds the script's bond model does not matter
    data, _, bonds, _ = imported(tmp_path, BOND_TEXT.replace("0 2 1 9", "0 2 1 10"),
                                 "MODEL_SB ModelSBFoo\n")
    assert bonds == ["i,j,diameter,material"] and "bonds" not in data


def test_bonds_of_an_import_and_what_is_left_out(tmp_path):
    text = BOND_TEXT.replace("0.0005 0.002 23 binder 2 0", "0.0005 0.0025 23 binder 24 0 "
                                                          "1e+300 2 0")
    text += ("0 3 1 9 5 0 1 0.0004 0.002 23 binder 24 0 0 2 0 12 0 0 0\n"
             "0 4 1 10 5 0 1 0.0004 0.002 23 binder\n")
    data, _, bonds, notes = imported(tmp_path, text, None)
    assert bonds == ["i,j,diameter,material", "0,1,0.0005,binder"]
    assert notes == ["object 4: liquid bond not mapped",
                     "interaction glass-glass not given: MUSEN's defaults (restitution 0.6, "
                     "friction 0.45, rolling friction 0.05)",
                     "1 solid bonds already broken at t = 0 s: left out",
                     "a bond's initial length differs from its particles' distance at the "
                     "start; bondem takes the distance"]
    with pytest.raises(InputError) as error:
        imported(tmp_path, BOND_TEXT.replace("5 0 1 0.0005", "5 0 7 0.0005"), None)
    assert str(error.value) == "solid bond 2: particle 0 or 7 is no sphere"
    with pytest.raises(InputError) as error:
        imported(tmp_path, BOND_TEXT.replace("32 binder", "32 glue"), None)
    assert str(error.value) == "compound 'binder' is used but not defined (command 32)"
    with pytest.raises(InputError) as error:
        imported(tmp_path, BOND_TEXT.replace("32 glass", "32 sand"), None)
    assert str(error.value) == "compound 'glass' is used but not defined (command 32)"
    with pytest.raises(InputError) as error:
        imported(tmp_path, "0 2 1 9 5 0 1 0.0005 0.002 23 binder\n", None)
    assert str(error.value) == "no spheres (object type 1) in the MUSEN file"


def test_the_scene_starts_at_its_earliest_sphere(tmp_path):
    text = BOND_TEXT.replace("23 glass 2 0 12 0 0 0", "23 glass 2 0.5 12 0 0 0")
    text = text.replace("23 glass 2 0 12 0.002", "23 glass 2 0.25 12 0.002")
    text += "0 3 1 9 5 0 1 0.0004 0.002 23 binder 24 0 0.25 2 0 12 0 0 0\n"
    text += "0 5 1 9 5 0 1 0.0004 0.002 23 binder 24 0 0.3 2 0 12 0 0 0\n"
    _, _, bonds, notes = imported(tmp_path, text, None)
    assert len(bonds) == 3 and "1 solid bonds already broken at t = 0.25 s: left out" in notes


def test_multispheres_become_clumps_without_their_inner_bonds(tmp_path):
    scene = read_text(write(tmp_path, "scene.txt", BOND_TEXT + "0 3 1 1 5 0.001 0.001 23 glass "
                                                               "2 0 12 0 0.002 0\n"))
    scene.multispheres = [[0, 1, 0, 9], [3], [1, 3]]
    notes = to_bondem(scene, None, tmp_path / "out")
    rows = (tmp_path / "out" / "particles.csv").read_text().splitlines()
    assert rows[0].endswith(",clump") and [r.rsplit(",", 1)[1] for r in rows[1:]] == [
        "0", "0", "-1"]
    assert (tmp_path / "out" / "bonds.csv").read_text() == "i,j,diameter,material\n"
    assert notes[1:] == [
        "1 multisphere(s) imported as rigid clumps (MUSEN 1.74.2 stores them but its "
        "simulator moves their spheres as free particles: drop the clump column of "
        "particles.csv to match it)",
        "2 multisphere(s) with fewer than two spheres of the scene left out",
        "1 solid bonds within a multisphere: left out (a clump is rigid)"]
    index = {0: 0, 1: 1, 3: 2, 4: 3, 5: 4}
    assert mt._clumps_of([[0, 1], [3, 4, 5], [4, 0]], index, []) == {0: 0, 1: 0, 3: 1, 4: 1,
                                                                      5: 1}


def test_periodic_boundaries_stop_criteria_and_fluids(tmp_path):
    text = TEXT.replace("22 -0.01", "28 1 0 1 0 -1 -2 -3 1 2 3\n22 -0.01")
    data, _, _, notes = imported(tmp_path, text, "STOP_CRITERION none\n")
    assert data["simulation"]["periodic"] == [False, True, False]
    assert (data["simulation"]["box_low"], data["simulation"]["box_high"]) == (
        [-1.0, -2.0, -3.0], [1.0, 2.0, 3.0])
    assert "stop_broken_bonds" not in data["simulation"]
    assert not any("STOP_CRITERION" in n for n in notes)
    data, _, _, _ = imported(tmp_path, TEXT.replace("22 -0.01", "28 0 1 1 1 -1 -2 -3 1 2 3\n"
                                                               "22 -0.01"), None)
    assert "periodic" not in data["simulation"]
    assert data["simulation"]["box_low"] == [-0.01] * 3
    data, _, _, notes = imported(tmp_path, script="STOP_CRITERION TIME 3\n")
    assert "STOP_CRITERION TIME 3: unknown (MUSEN has NONE and BROKEN_BONDS N); the run ends "\
           "at END_TIME" in notes
    for bad in ("BROKEN_BONDS", "BROKEN_BONDS many"):
        with pytest.raises(InputError) as error:
            imported(tmp_path, script=f"STOP_CRITERION {bad}\n")
        assert str(error.value) == (f"STOP_CRITERION: expected BROKEN_BONDS and a number of "
                                    f"bonds, got {bad!r}")
    data, _, _, notes = imported(tmp_path, script="MODEL_EF ModelEFViscousField\n"
                                                  "MODEL_EF_PARAMS MEDIUM_DENSITY 2.0\n"
                                                  "MODEL_PP ModelPPFoo\nVERLET_COEF 3\n")
    assert data["fluid"] == {"density": 2.0, "viscosity": 1.34e-5 * 2.0,
                             "drag": "musen_viscous", "buoyancy": False}
    assert "contact model ModelPPFoo: not available; Hertz-Mindlin is used" in notes
    assert data["simulation"]["contact_model"] == "hertz_mindlin"
    assert "VERLET_COEF 3: no counterpart (bondem's contact list: docs/musen_migration.md)" \
        in notes
    data, _, _, notes = imported(tmp_path, script="MODEL_EF ModelEFMagnetic\n")
    assert "fluid" not in data
    assert "external force model ModelEFMagnetic: not mapped (no such field in bondem)" in notes


def test_external_force_models_are_fluids():
    assert musen_fluid({}) == (None, None)
    assert musen_fluid({"MODEL_EF": "ModelEFViscousField"}) == (
        {"density": 1.28, "viscosity": 1.34e-5 * 1.28, "drag": "musen_viscous",
         "buoyancy": False}, None)
    assert musen_fluid({"MODEL_EF": "ModelEFCentrifugalCasting",
                        "MODEL_EF_PARAMS": "ROTATION_VELOCITY 12 LIQUID_VISCOSITY 0.01 "
                                           "OTHER 5"}) == (
        {"density": 1000.0, "viscosity": 0.01, "drag": "musen_centrifugal", "buoyancy": False,
         "spin": [0.0, 12.0, 0.0]}, None)


def test_adhesion_goes_through_musens_surface_properties():
    w = 0.05
    assert mt.musen_surface_energy("jkr", {"surface_energy": w}) == {11: w}
    assert mt.musen_surface_energy("popov_jkr", {"surface_energy": w}) == {13: w}
    assert mt.musen_surface_energy("jkr", {}) == {11: 0.0}
    hamaker = 1e-19
    vdw = mt.musen_surface_energy("vdw", {"hamaker_constant": hamaker})
    assert vdw == {11: hamaker / (24 * math.pi * MUSEN_VDW_DMIN * MUSEN_VDW_DMIN)}
    assert mt.musen_surface_energy("hertz_mindlin", {"surface_energy": w}) == {}
    assert mt.bondem_adhesion("jkr", {11: w}) == {"surface_energy": w}
    assert mt.bondem_adhesion("popov_jkr", {13: w, 11: 1.0}) == {"surface_energy": w}
    assert mt.bondem_adhesion("popov_jkr", {11: w}) == {}
    assert mt.bondem_adhesion("jkr", {}) == {} and mt.bondem_adhesion("none", {11: w}) == {}
    assert mt.bondem_adhesion("vdw", vdw)["hamaker_constant"] == pytest.approx(hamaker,
                                                                               rel=1e-15, abs=0)


def test_an_imported_adhesive_material(tmp_path):
    text = TEXT.replace("32 glass glass 0 2500", "32 glass glass 11 0.04 0 2500")
    data, _, _, _ = imported(tmp_path, text, "MODEL_PP ModelPPJKR\nMODEL_PW ModelPWJKR\n")
    assert data["materials"]["glass"]["surface_energy"] == 0.04
    assert "surface_energy" not in data["materials"]["steel"]


def test_walls_are_grouped_by_geometry():
    scene = MusenScene()
    for k in (3, 5, 6, 8):
        scene.objects[k] = MusenObject(k, mt.TRIANGULAR_WALL)
    scene.objects[1] = MusenObject(1, mt.SPHERE)
    scene.geometries = [["", "key", "1 0", [5, 9]], ["named", "k2", "", [6]],
                        ["empty", "k3", "", [9]]]
    assert wall_groups(scene) == [("key", [5], "1 0"), ("named", [6], ""),
                                  ("walls", [3, 8], "")]
    scene.geometries = []
    assert wall_groups(scene) == [("walls", [3, 5, 6, 8], "")]


def test_import_musen_names_the_file(tmp_path):
    text = write(tmp_path, "scene.txt", TEXT)
    script = write(tmp_path, "script.txt", SCRIPT)
    path, notes = import_musen(text, tmp_path / "imported", script)
    assert path == tmp_path / "imported" / "scene.toml" and path.is_file()
    assert len(notes) == 8
    with pytest.raises(InputError) as error:
        import_musen(text, tmp_path / "x", musen_version="1.69")
    assert str(error.value) == "--musen-version: value '1.69'; allowed: " + ", ".join(
        mt.MUSEN_VERSIONS)
    with pytest.raises(InputError) as error:
        import_musen(tmp_path / "none.txt", tmp_path / "x")
    assert str(error.value) == f"{tmp_path / 'none.txt'}: no such file"
    empty = write(tmp_path, "empty.txt", "22 0 0 0 1 1 1\n")
    with pytest.raises(InputError) as error:
        import_musen(empty, tmp_path / "x")
    assert str(error.value) == f"{empty}: no spheres (object type 1) in the MUSEN file"
    with pytest.raises(InputError) as error:
        import_musen(text, tmp_path / "x", write(tmp_path, "bad.txt", "MODEL_SB ModelSBFoo\n"))
    assert str(error.value).startswith(f"{text}: MODEL_SB: solid bond model ModelSBFoo")
    path, _ = import_musen(text, tmp_path / "plain")
    assert tomllib.loads(path.read_text())["simulation"]["end_time"] == 1e-3


def test_a_scenes_cmusen_keys():
    dt = 3e-7
    keys, notes = simulator_keys({}, dt)
    assert keys == {"SIMULATOR_TYPE": "CPU", "MODEL_SB": "ModelSBElastic",
                    "MODEL_SB_PARAMS": "CONSIDER_BREAKAGE 1",
                    "MODEL_PP": "ModelPPHertzMindlin", "MODEL_PW": "ModelPWHertzMindlin",
                    "CONNECTED_PP_CONTACT": "0", "SIMULATION_STEP": "3e-07",
                    "END_TIME": repr(3332.5 * dt), "EXT_ACCEL": "0.0 0.0 0.0",
                    "VARIABLE_TIME_STEP": "0"}
    assert notes == []
    scene = {"simulation": {"end_time": 2e-5, "save_every": 1e-6, "gravity": [0, -9.81, 0],
                            "contact_model": "jkr", "bonded_contacts": True, "damping": 0.1},
             "bond_materials": {"b": {"breakage": "separate"}},
             "walls": [{"velocity": [0, 0, 1], "own_friction": False},
                       {"velocity_profile": [[0, 0, 0, 0]]},
                       {"servo": {"target_force": 1.0}, "own_friction": True}]}
    keys, notes = simulator_keys(scene, 1e-7)
    assert keys["MODEL_SB_PARAMS"] == "CONSIDER_BREAKAGE 2"
    assert (keys["MODEL_PP"], keys["MODEL_PW"], keys["CONNECTED_PP_CONTACT"]) == (
        "ModelPPJKR", "ModelPWJKR", "1")
    assert keys["SAVING_STEP"] == "1e-06" and keys["EXT_ACCEL"] == "0.0 -9.81 0.0"
    assert keys["END_TIME"] == repr(199.5 * 1e-7)
    assert notes == ["local damping: MUSEN has none",
                     "wall 1: its velocity_profile is not written (MUSEN moves it by a "
                     "constant velocity only; written static)",
                     "wall 2: own_friction is not written (MUSEN's interaction gets the mean "
                     "of the two materials' friction)",
                     "wall 2: its servo is not written (MUSEN moves it by a constant velocity "
                     "only; written static)"]
    keys, notes = simulator_keys({"simulation": {"contact_model": "none", "end_time": 1e-9},
                                  "bond_materials": {"b": {"breakage": "none"}}}, 1e-7)
    assert "MODEL_PP" not in keys and keys["MODEL_SB_PARAMS"] == "CONSIDER_BREAKAGE 0"
    assert keys["END_TIME"] == repr(0.5e-7)          # at least one step
    keys, notes = simulator_keys({"simulation": {"contact_model": "linear"}}, 1e-7)
    assert keys["MODEL_PP"] == "ModelPPHertzMindlin"
    assert notes == ["contact_model = 'linear': written as MUSEN's Hertz-Mindlin"]
    keys, _ = simulator_keys({"simulation": {"contact_model": "vdw"}}, 1e-7)
    assert (keys["MODEL_PP"], keys["MODEL_PW"]) == ("ModelPPHertzMindlinVdW",
                                                    "ModelPWHertzMindlin")


def test_each_bond_models_cmusen_parameters():
    keys, notes = simulator_keys({"bond_materials": {
        "a": {"model": "elastic_plastic", "fracture_strain": 0.2,
              "compressive_fracture_strain": math.inf},
        "b": {"model": "kelvin"}}}, 1e-7)
    assert keys["MODEL_SB"] == "ModelSBElasticPerfectlyPlastic"
    assert keys["MODEL_SB_PARAMS"] == ("FRACTURE_STRAIN_TENSION 0.2 "
                                       "FRACTURE_STRAIN_COMPRESSION 0 TANGENTIAL_YIELD 1 "
                                       "RATIO_COMPR_TENSILE_YIELD 1.0")
    assert notes == ["MUSEN has one solid bond model and criterion per run: the first bond "
                     "material's are written"]
    keys, _ = simulator_keys({"bond_materials": {"a": {"model": "creep",
                                                       "normal_strength": 1e6}}}, 1e-7)
    assert keys["MODEL_SB_PARAMS"].endswith(" FRACTURE_BY_STRESS 1")
    keys, _ = simulator_keys({"bond_materials": {"a": {"model": "creep"}}}, 1e-7)
    assert keys["MODEL_SB_PARAMS"].endswith(" FRACTURE_BY_STRESS 0")
    assert keys["MODEL_SB_PARAMS"].startswith("FRACTURE_STRAIN_TENSION ")
    keys, notes = simulator_keys({"bond_materials": {"a": {
        "model": "weakening", "fracture_strain": 0.1, "compressive_fracture_strain": 0.3}}},
        1e-7)
    assert keys["MODEL_SB_PARAMS"] == ("CONSIDER_BREAKAGE 1 COMPRESSIVE_BREAK 1 "
                                       "BREAKAGE_STRAIN 0.1 WEAKENING_FACTOR 0.5")
    assert notes == ["weakening bond: MUSEN breaks in compression at twice the tensile "
                     "fracture strain (0.2), not at compressive_fracture_strain 0.3"]
    keys, _ = simulator_keys({"bond_materials": {"a": {"model": "kelvin",
                                                       "viscosity": 2e-3}}}, 1e-7)
    assert keys["MODEL_SB_PARAMS"] == "CONSIDER_BREAKAGE 1 MU 0.002"
    with pytest.raises(InputError) as error:
        simulator_keys({"bond_materials": {"a": {"model": "parallel"}}}, 1e-7)
    assert str(error.value) == "model: bond model 'parallel' has no MUSEN counterpart"


def test_the_script_imports_the_text_and_simulates(tmp_path):
    notes = write_script({"simulation": {"damping": 0.2}}, 1e-6, "scene.txt",
                         tmp_path / "script.txt")
    assert notes == ["local damping: MUSEN has none"]
    lines = (tmp_path / "script.txt").read_text().splitlines()
    assert lines[:8] == ["JOB", "COMPONENT IMPORT_FROM_TEXT", "SOURCE_FILE scene.txt",
                         "RESULT_FILE ./scene_t0.mdem", "JOB", "COMPONENT SIMULATOR",
                         "SOURCE_FILE ./scene_t0.mdem", "RESULT_FILE ./result.mdem"]
    assert lines[8:] == [f"{k} {v}" for k, v in simulator_keys({}, 1e-6)[0].items()]
    assert read_script(tmp_path / "script.txt")["END_TIME"] == repr(999.5e-6)


def results_data(walls=True, broken=np.nan):
    """A results file's arrays (read_results) of two spheres, a bond and a plane wall."""
    data = {
        "materials/names": np.array(["glass", "steel"]),
        "bond_materials/names": np.array(["binder"]),
        "time": np.array([0.0, 1e-4, 2e-4]),
        "particles/radius": np.array([1e-3, 1.5e-3]),
        "particles/material": np.array([0, 1]),
        "bonds/pairs": np.array([[0, 1]]), "bonds/break_time": np.array([broken]),
        "bonds/diameter": np.array([5e-4]), "bonds/initial_length": np.array([2.5e-3]),
        "bonds/material": np.array([0]),
    }
    position = np.array([[[0.001, 0.0, 0.0], [0.0035, 0.0, 0.0]]] * 3)
    position[:, :, 1] += np.array([0.0, 1e-5, 2e-5])[:, None]
    data["particles/position"] = position
    data["particles/velocity"] = np.full((3, 2, 3), 0.1)
    data["particles/angular_velocity"] = np.full((3, 2, 3), -2.0)
    if walls:
        data["walls/position"] = np.array([[[0.0, 0.0, -0.002]], [[0.0, 0.0, -0.0019]],
                                           [[0.0, 0.0, -0.0018]]])
        data["walls/geometry/point"] = np.array([[0.0, 0.0, -0.002]])
        data["walls/geometry/normal"] = np.array([[0.0, 0.0, 2.0]])
    return data


SCENE = {"simulation": {"end_time": 2e-4},
         "materials": {"glass": {"density": 2500.0, "young_modulus": 1e8,
                                 "poisson_ratio": 0.25, "restitution": 0.7},
                       "steel": {"density": 7800.0, "young_modulus": 2e9,
                                 "friction": 0.5}},
         "bond_materials": {"binder": {"young_modulus": 5e7, "normal_strength": 1e6}},
         "walls": [{"type": "plane", "material": "steel", "velocity": [0.0, 0.0, 1.0]}]}


def test_an_export_writes_each_object_and_the_scene(tmp_path):
    lines = export_lines(results_data(), SCENE)
    assert lines[0] == ("0 0 1 1 5 0.001 0.001 23 glass 24 0 1e+300 2 0.0 12 0.001 0.0 0.0 "
                        "15 0.1 0.1 0.1 16 -2.0 -2.0 -2.0 2 0.0001 12 0.001 1e-05 0.0 15 0.1 "
                        "0.1 0.1 16 -2.0 -2.0 -2.0 2 0.0002 12 0.001 2e-05 0.0 15 0.1 0.1 0.1 "
                        "16 -2.0 -2.0 -2.0")
    assert lines[2] == ("0 2 1 9 5 0 1 0.0005 0.0025 23 binder 24 0 1e+300 2 0.0 12 0 0 0")
    assert lines[5:8] == ["25 wall0 wall0 0 0 0 0",
                          "26 1 1 0 0.0002 0.0 0.0 1.0 0.0 0.0 0.0 0.0 0.0 0.0",
                          "27 2 3 4"]
    # no box given: the particles' extent +- twice (extent + 4 r_max) = 0.017 m
    centre = 0.5 * (0.001 + 0.0035)
    assert lines[8] == "22 " + " ".join(repr(v) for v in [
        centre - 0.017, -0.017, -0.017, centre + 0.017, 0.017, 0.017])
    assert lines[9:12] == [
        "32 glass glass 0 2500.0 7 100000000.0 10 0.25",
        "32 steel steel 0 7800.0 7 2000000000.0 10 0.3",
        "32 binder binder 0 2500.0 7 50000000.0 10 0.3 8 1000000.0 9 1e+300"]
    assert lines[12:] == ["33 glass glass 200 0.7 201 0.3 202 0.0",
                          "33 glass steel 200 0.6 201 0.4 202 0.0",
                          "33 steel steel 200 0.5 201 0.5 202 0.0"]
    objects, _ = read_series(lines)
    # the plane: a square of side 2 (extent + 4 r_max) = 0.017 m about its point, moving
    corners = [objects[k][4][f][1] for k in (3, 4) for f in range(3)]
    for f, travel in enumerate((0.0, 1e-4, 2e-4)):
        a, b, c = (np.array(corners[f][key][:3]) for key in (12, 31, 16))
        np.testing.assert_allclose([a[2], b[2], c[2]], -0.002 + travel, rtol=1e-12)
        normal = np.cross(b - a, c - a)
        assert normal[2] > 0 and np.allclose(normal[:2], 0.0, atol=1e-18)
    a, b, c = (np.array(corners[0][key][:3]) for key in (12, 31, 16))
    assert sorted(np.round([np.linalg.norm(b - a), np.linalg.norm(c - b),
                            np.linalg.norm(c - a)], 12)) == [0.017, 0.017,
                                                             round(0.017 * math.sqrt(2), 12)]
    np.testing.assert_allclose((a + c) / 2, [0.0, 0.0, -0.002], atol=1e-15)


def test_an_export_of_a_broken_bond_a_box_and_every_second_frame(tmp_path):
    scene = {"simulation": {"box_low": [-1.0, -2.0, -3.0], "box_high": [1.0, 2.0, 3.0],
                            "periodic": [True, False, True], "contact_model": "jkr"},
             "materials": {"glass": {"density": 2500.0, "surface_energy": 0.05}}}
    data = results_data(walls=False, broken=1.5e-4)
    lines = export_lines(data, scene, every=2)
    assert " 24 0 0.00015 " in lines[2] and lines[0].count(" 2 ") == 2
    assert lines[3:5] == ["22 -1.0 -2.0 -3.0 1.0 2.0 3.0",
                          "28 1 1 0 1 -1.0 -2.0 -3.0 1.0 2.0 3.0"]
    assert lines[5] == "32 glass glass 0 2500.0 7 0.0 10 0.3 11 0.05"
    assert lines[6] == "32 steel steel 0 0.0 7 0.0 10 0.3 11 0.0"
    assert lines[7] == "32 binder binder 0 2500.0 7 0.0 10 0.3 8 1e+300 9 1e+300"
    assert lines[8] == "33 glass glass 200 0.5 201 0.3 202 0.0"
    plastic = {"bond_materials": {"binder": {"model": "elastic_plastic",
                                             "yield_strength": 2e6}}}
    assert export_lines(data, plastic)[-4].endswith(" 8 1e+300 9 1e+300 15 2000000.0")
    assert export_lines(data, {"bond_materials": {"binder": {"model": "elastic_plastic"}}})[
        -4].endswith(" 15 1e+300")


def test_an_exported_mesh_wall_moves_by_its_position_unless_it_turns(tmp_path):
    data = results_data(walls=False)
    data["walls/position"] = np.array([[[0.0, 0.0, 0.0]], [[0.0, 0.001, 0.0]],
                                       [[0.0, 0.002, 0.0]]])
    data["walls/geometry/mesh0/vertices"] = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0],
                                                      [0.0, 0.01, 0.0]])
    data["walls/geometry/mesh0/triangles"] = np.array([[0, 1, 2]])
    mesh = {"type": "mesh", "material": "glass"}
    objects, _ = read_series(export_lines(data, {"walls": [mesh]}))
    points = objects[3][4]
    assert [p[1][12] for p in points] == [[0.0, 0.0, 0.0], [0.0, 0.001, 0.0],
                                          [0.0, 0.002, 0.0]]
    assert points[2][1][16] == [0.0, 0.012, 0.0] and points[1][1][31][:3] == [0.01, 0.001, 0.0]
    turning = {**mesh, "angular_velocity": [0.0, 0.0, 2.0], "rotation_center": [1.0, 2.0, 3.0]}
    lines = export_lines(data, {"walls": [turning], "simulation": {"end_time": 1.0}})
    objects, _ = read_series(lines)
    assert [p[1][12] for p in objects[3][4]] == [[0.0, 0.0, 0.0]] * 3
    assert "26 1 1 0 1.0 0.0 0.0 0.0 1.0 2.0 3.0 0.0 0.0 2.0" in lines


def test_export_musen_writes_the_text_and_its_script(tmp_path):
    data = results_data(walls=False)
    path = tmp_path / "results.h5"
    with h5py.File(path, "w") as f:
        for name, value in data.items():
            if value.dtype.kind == "U":
                f[name] = value.astype(h5py.string_dtype())
            else:
                f[name] = value
        f.attrs["scene"] = "[simulation]\nend_time = 2e-4\n"
        f.attrs["time_step"] = 1e-6
    text, script, notes = export_musen(path, tmp_path / "out" / "run.txt", every=2)
    assert text == tmp_path / "out" / "run.txt" and script == tmp_path / "out" / "run_script.txt"
    assert notes == []
    assert text.read_text() == "\n".join(export_lines(data, {"simulation": {"end_time": 2e-4}},
                                                      2)) + "\n"
    assert read_script(script)["END_TIME"] == repr(199.5e-6)
    assert "SOURCE_FILE run.txt" in script.read_text()


def sphere(ident, position, radius, compound="glass"):
    return MusenObject(ident, mt.SPHERE, [radius, radius], compound, time=0.0,
                       coordinates=tuple(position), times=1)


GENERATOR = {**mt.BOND_GENERATOR, "active": True, "compound": "binder", "min_distance": 0.0,
             "max_distance": 2e-4, "diameter": 1.5e-3}


def test_the_bond_generator_bonds_pairs_within_its_gaps(tmp_path):
    scene = MusenScene()
    for k, (x, r) in enumerate([(0.0, 1e-3), (2.1e-3, 1e-3), (4.25e-3, 1e-3), (7.0e-3, 5e-4)]):
        scene.objects[k + 10] = sphere(k + 10, (x, 0.0, 0.0), r, "glass" if k < 2 else "sand")
    scene.objects[3] = MusenObject(3, mt.SOLID_BOND, [10.0, 13.0, 1e-4, 1e-3], "old")
    scene.objects[5] = MusenObject(5, mt.SOLID_BOND, [10.0, 11.0, 1e-4, 1e-3], "old")
    assert generate_bonds(scene, [GENERATOR]) == 2
    bonds = {k: o for k, o in scene.objects.items() if o.type == mt.SOLID_BOND}
    # the freed ids first; gaps 1e-4 and 1.5e-4 in, 1.25e-3 out
    assert sorted(bonds) == [3, 5]
    made = sorted((o.geometry for o in bonds.values()), key=lambda g: g[0])
    np.testing.assert_allclose(made, [[10.0, 11.0, 1.5e-3, 2.1e-3], [11.0, 12.0, 1.5e-3, 2.15e-3]],
                               rtol=1e-12)
    assert {o.compound for o in bonds.values()} == {"binder"} and bonds[3].time == 0.0
    # no second bond between two particles, unless overlay; one of each compound list
    more = {**GENERATOR, "compound": "glue", "diameter": 5e-3}
    assert generate_bonds(scene, [GENERATOR, more]) == 2
    assert generate_bonds(scene, [GENERATOR, {**more, "overlay": True}]) == 4
    made = {tuple(o.geometry[:3]) for o in scene.objects.values() if o.compound == "glue"}
    assert made == {(10.0, 11.0, 2e-3), (11.0, 12.0, 2e-3)}       # at most both diameters
    assert max(scene.objects) == 15
    assert generate_bonds(scene, [{**GENERATOR, "compounds": (["glass"], ["sand"])}]) == 1
    assert generate_bonds(scene, [{**GENERATOR, "compounds": (["sand"], ["glass"])}]) == 1
    assert generate_bonds(scene, [{**GENERATOR, "compounds": (["glass"], ["glass"])}]) == 1
    assert generate_bonds(scene, [{**GENERATOR, "min_distance": 1.2e-4}]) == 1
    assert generate_bonds(scene, [{**GENERATOR, "max_distance": 1.2e-4}]) == 1
    assert generate_bonds(scene, [{**GENERATOR, "active": False}]) == 0
    assert not any(o.type == mt.SOLID_BOND for o in scene.objects.values())
    assert generate_bonds(MusenScene(), [GENERATOR]) == 0


def box_mesh(low, high):
    import trimesh
    box = trimesh.creation.box(extents=np.subtract(high, low))
    box.apply_translation(np.add(low, high) / 2)
    return box.triangles


def test_musens_analysis_volumes_as_containers():
    triangles = box_mesh([0.0, 0.0, 0.0], [0.02, 0.04, 0.06])
    volume = {"name": "v", "triangles": triangles, "rotation": np.eye(3)}
    box, fill = package_volume({**volume, "shape": 1, "sizes": [0.02, 0.04, 0.06]})
    np.testing.assert_allclose(box.low, [0.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(box.high, [0.02, 0.04, 0.06], rtol=1e-14)
    assert fill == pytest.approx(0.02 * 0.04 * 0.06, rel=1e-14)
    ball, fill = package_volume({**volume, "shape": 0, "sizes": [0.01]})
    assert ball.radius == 0.01 and fill == pytest.approx(4 / 3 * math.pi * 1e-6, rel=1e-14)
    np.testing.assert_allclose(ball.center, [0.01, 0.02, 0.03], rtol=1e-14)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    tube, fill = package_volume({**volume, "shape": 2, "sizes": [0.01, 0.04],
                                 "rotation": turn})
    np.testing.assert_allclose(tube.axis, [0.0, -1.0, 0.0], atol=1e-15)
    assert (tube.radius, tube.height) == (0.01, 0.04)
    assert fill == pytest.approx(math.pi * 1e-4 * 0.04, rel=1e-14)
    turned, fill = package_volume({**volume, "shape": 1, "sizes": [0.02, 0.04, 0.06],
                                   "rotation": turn})
    assert type(turned).__name__ == "MeshVolume"
    assert fill == pytest.approx(0.02 * 0.04 * 0.06, rel=1e-9)
    hollow, fill = package_volume({**volume, "shape": 3, "sizes": [0.02, 0.01]})
    assert fill == pytest.approx(4 / 3 * math.pi * (0.02 ** 3 - 0.01 ** 3), rel=1e-14)
    _, fill = package_volume({**volume, "shape": 3, "sizes": [0.02]})
    assert fill == pytest.approx(0.02 * 0.04 * 0.06, rel=1e-9)
    with pytest.raises(InputError) as error:
        package_volume({**volume, "triangles": np.zeros((0, 3, 3))})
    assert str(error.value) == "analysis volume 'v' has no mesh"


def test_the_package_generator_counts_as_musen(tmp_path):
    volume = {"name": "v", "triangles": box_mesh([0.0, 0.0, 0.0], [0.006, 0.006, 0.006]),
              "rotation": np.eye(3), "shape": 1, "sizes": [0.006, 0.006, 0.006]}
    # fractions (compound, diameter, contact diameter, fraction): a zero one is skipped
    mixture = {"fractions": [("glass", 1e-3, 1e-3, 0.75), ("sand", 6e-4, 7e-4, 0.25),
                             ("none", 5e-4, 5e-4, 0.0)]}
    generator = {"name": "g", "volume": volume, "mixture": mixture, "porosity": 0.7,
                 "max_overlap": 1e-6, "velocity": (0.0, 0.0, -0.1)}
    scene = MusenScene()
    scene.objects[4] = sphere(4, (1.0, 1.0, 1.0), 1e-3)
    made, notes = generate_package(scene, generator, seed=1)
    mean = 0.75 * math.pi / 6 * 1e-9 + 0.25 * math.pi / 6 * 6e-4 ** 3
    solid = 0.3 * 0.006 ** 3
    counts = [int(solid / mean * 0.75), int(solid / mean * 0.25)]
    assert made == sum(counts)
    assert notes == ["package generator 'g': contact diameters other than the diameters are "
                     "kept but not used by bondem"]
    new = [scene.objects[k] for k in range(5, 5 + made)]
    assert [o.compound for o in new] == ["glass"] * counts[0] + ["sand"] * counts[1]
    assert [o.geometry for o in new[-1:]] == [[3e-4, 3.5e-4]]
    assert new[0].geometry == [5e-4, 5e-4] and new[0].velocity == (0.0, 0.0, -0.1)
    position = np.array([o.coordinates for o in new])
    assert position.min() > 0.0 and position.max() < 0.006
    assert generate_package(MusenScene(), {**generator, "mixture": {"fractions": []}}) == (0, [])
    for missing in ("volume", "mixture"):
        with pytest.raises(InputError) as error:
            generate_package(MusenScene(), {**generator, missing: None})
        assert str(error.value) == f"package generator 'g': its {missing} is not in the file"


def test_musens_defaults_and_the_scripts_edge_cases(tmp_path):
    text = (BOND_TEXT.replace("32 binder binder 7 5e7 8 1e6 9 2e6 15 3e6", "32 binder binder")
            + "33 glass glass 200 0.7\n33 glass sand 200 0.1\n")
    data, _, _, notes = imported(tmp_path, text, None)
    assert data["bond_materials"]["binder"] == {
        "young_modulus": 1e9, "poisson_ratio": 0.2, "normal_strength": 1e7,
        "tangential_strength": 1e7, "breakage": "combined"}
    glass = data["materials"]["glass"]
    assert (glass["restitution"], glass["friction"], glass["rolling_friction"]) == (
        0.7, 0.45, 0.05)
    assert not any("sand" in n for n in notes)    # a compound no object uses
    # END_TIME a whole number of steps: that many, not one more
    dt = 3e-7
    assert (34 * dt) / dt == 34.0
    data, _, _, _ = imported(tmp_path, text, f"END_TIME {34 * dt!r}\nSIMULATION_STEP {dt!r}\n"
                                             "EXT_ACCEL 0 0 -9.81 5\nVARIABLE_TIME_STEP\n"
                                             "MODEL_PP ModelPPHertzMindlin\n"
                                             "CONNECTED_PP_CONTACT 1\n")
    assert data["simulation"]["end_time"] == 34 * dt
    assert data["simulation"]["gravity"] == [0.0, 0.0, -9.81]
    assert data["simulation"]["bonded_contacts"] is True
    _, _, _, notes = imported(tmp_path, text, "VARIABLE_TIME_STEP\nMODEL_PP "
                                              "ModelPPHertzMindlin\n")
    assert not any("VARIABLE_TIME_STEP" in n or "walls follow" in n for n in notes)
    # the mixed pair's restitution a hair off the mean of the pure pairs is named
    mean = 0.5 * (0.7 + 0.6)
    text = TEXT.replace("33 steel glass 200 0.6", f"33 steel glass 200 {mean * (1 + 1e-10)!r}"
                        "\n33 steel steel 200 0.6")
    _, _, _, notes = imported(tmp_path, text, None)
    assert any(n.startswith("interaction glass-steel: restitution") for n in notes)


def test_a_plane_facing_x_is_a_square_in_its_plane(tmp_path):
    data = results_data()
    data["walls/geometry/point"] = np.array([[0.004, 0.001, -0.002]])
    data["walls/geometry/normal"] = np.array([[-3.0, 0.0, 0.0]])
    data["walls/position"] = np.repeat(data["walls/geometry/point"][None], 3, axis=0)
    objects, _ = read_series(export_lines(data, {"walls": [{"type": "plane",
                                                            "material": "glass"}]}))
    corners = []
    for k in (3, 4):
        point = objects[k][4][0][1]
        a, b, c = (np.array(point[key][:3]) for key in (12, 31, 16))
        normal = np.cross(b - a, c - a)
        assert normal[0] < 0 and np.allclose(normal[1:], 0.0, atol=1e-18)
        corners += [a, b, c]
    corners = np.unique(np.round(corners, 15), axis=0)
    assert corners.shape == (4, 3)
    np.testing.assert_allclose(corners[:, 0], 0.004, rtol=1e-12)
    np.testing.assert_allclose(np.sort(np.abs(corners[:, 1:] - [0.001, -0.002]).ravel()),
                               [0.0085] * 8, rtol=1e-12)

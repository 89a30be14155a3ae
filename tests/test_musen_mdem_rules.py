""".mdem files on constructed contents, without MUSEN or a run: the block layout of
MUSEN's MDEMFile.h, a property's value at MUSEN's normal point (273.15 K, 101325 Pa) for
each correlation, the scene, script and generators a file's messages say, a file written
by bondem read back to the scene it was written from, and a one-line error for every
kind of damage. tests/test_musen_mdem.py checks the same code on real MUSEN files."""
import math
import struct
import types
import zlib

import h5py
import numpy as np
import pytest

from bondem.errors import InputError
from bondem.io import musen_mdem as mm
from bondem.io.musen_mdem import (MdemFile, block_size, bond_generators, break_modes,
                                  export_mdem, import_mdem, import_mdem_results, mdem_storage,
                                  musen_release, object_geometry, package_generators,
                                  package_tables, property_value, scene_of, script_of,
                                  write_mdem)
from bondem.io.musen_text import read_script, read_text
from bondem.io.protowire import encode
from test_musen_text_rules import TEXT, results_data

T, P = 273.15, 101325.0


def test_blocks_grow_as_musens_table():
    c = 4096
    assert [block_size(k, c) // c for k in range(12)] == [1, 1, 2, 3, 4, 6, 8, 12, 16, 24,
                                                          32, 48]
    assert block_size(0, 512) == 512


def correlation(kind, parameters, t=(0.0, 500.0), p=(0.0, 1e6)):
    return {"t1": t[0], "t2": t[1], "p1": p[0], "p2": p[1], "corType": kind,
            "parameter": parameters}


def test_a_property_is_its_correlation_at_musens_normal_point():
    assert property_value({"correlation": [correlation(0, [2.5])]}) == 2.5
    assert property_value({"correlation": [correlation(1, [1.0, 2e-6, 3e-3])]}) == \
        T * 3e-3 + P * 2e-6 + 1.0
    assert property_value({"correlation": [correlation(2, [1.0, 20.0, 5.0])]}) == \
        math.exp(1.0 + 20.0 / (T + 5.0))
    assert property_value({"correlation": [correlation(3, [2.0, 0.5])]}) == 2.0 * T ** 0.5
    assert property_value({"correlation": [correlation(1, [4.0])]}) == 4.0
    assert math.isnan(property_value({"correlation": [correlation(9, [1.0])]}))
    assert math.isnan(property_value({}))
    # the first correlation whose interval holds the point; the bounds belong to it
    skipped = [correlation(0, [1.0], t=(300.0, 400.0)), correlation(0, [2.0], p=(0.0, 1e5)),
               correlation(0, [3.0], t=(T, T), p=(P, P)), correlation(0, [4.0])]
    assert property_value({"correlation": skipped}) == 3.0
    assert property_value({"correlation": [{"corType": 0, "parameter": [1.0],
                                            "t2": 500.0, "p2": 1e6}]}) == 1.0
    assert math.isnan(property_value({"correlation": [{"parameter": [1.0]}]}))
    assert math.isnan(property_value({"correlation": [correlation(0, [1.0], t=(274, 500))]}))
    assert math.isnan(property_value({"correlation": [correlation(0, [1.0], p=(0, 1e5))]}))
    assert math.isnan(property_value({"correlation": [correlation(0, [1.0], p=(2e5, 3e5))]}))
    assert math.isnan(property_value({"correlation": [correlation(0, [1.0], t=(0, 270))]}))


def test_an_objects_geometry_from_its_encoded_properties():
    sphere = {"type": 1, "encoded_properties": struct.pack("<2d", 1e-3, 1.1e-3)}
    assert object_geometry(sphere, 2) == [1e-3, 1.1e-3]
    for kind in (9, 13):
        bond = {"type": kind, "encoded_properties": struct.pack("<2I2d", 3, 7, 5e-4, 2e-3)}
        assert object_geometry(bond, 2) == [3.0, 7.0, 5e-4, 2e-3]
    assert object_geometry({"type": 14}, 2) == []
    assert object_geometry({"type": 1, "encoded_properties": b"0.001 0.0011"}, 1) == [
        0.001, 0.0011]
    for bad in ({"id": 4, "type": 1, "encoded_properties": b"\0" * 8},
                {"id": 5, "type": 9, "encoded_properties": b"\0" * 16},
                {"type": 7, "encoded_properties": b"\0" * 16}):
        with pytest.raises(ValueError) as error:
            object_geometry(bad, 2)
        size = len(bad["encoded_properties"])
        assert str(error.value) == (f"object {bad.get('id', 0)}: {size} bytes of geometry for "
                                    f"type {bad['type']}")


def fake(modules=None, info=None, points=(), version=2):
    """What the readers take of an MdemFile."""
    return types.SimpleNamespace(modules=modules or {}, info=info or {}, version=version,
                                 path="x.mdem", time_points=lambda: iter(points))


def test_the_release_follows_the_model_manager():
    assert musen_release(fake({"model_manager": {"models": []}})) == "1.74.2"
    assert musen_release(fake({"model_manager": {"version": 1}})) == "1.74.2"
    assert musen_release(fake({"model_manager": {"sb_model": {}}})) == "1.70.0"
    assert musen_release(fake()) == "1.70.0"


def test_a_files_simulator_and_models_as_script_keys():
    simulator = {"simulation_step": 1e-7, "saving_step": 1e-5, "end_time": 1e-3,
                 "external_acceleration": {"z": -9.81}, "flexible_time_step": True,
                 "verlet_dist_coeff": 3.0, "verlet_auto_adjust": False}
    manager = {"models": [{"path": "C:\\musen\\ModelSBElastic.dll", "params": " CONSIDER_BREAKAGE 2 "},
                          {"path": "ModelPPHertzMindlin", "params": ""},
                          {"path": "ModelPWHertzMindlin"}, {"path": ""},
                          {"path": "ModelEFViscousField", "params": "MEDIUM_DENSITY 2"},
                          {"path": "ModelHTPPConduction"}, {"path": "ModelLBCapilarViscous"}],
               "pp_model": {"path": "ModelPPJKR", "params": "X 1"},
               "connected_pp_contact": True}
    info = {"stop_criteria": {"types": [0, 1], "max_broken_bonds": 7}}
    assert script_of(fake({"simulator": simulator, "model_manager": manager}, info)) == {
        "SIMULATION_STEP": "1e-07", "SAVING_STEP": "1e-05", "END_TIME": "0.001",
        "EXT_ACCEL": "0.0 0.0 -9.81", "VARIABLE_TIME_STEP": "1", "VERLET_COEF": "3.0",
        "VERLET_AUTO": "0", "MODEL_SB": "ModelSBElastic",
        "MODEL_SB_PARAMS": "CONSIDER_BREAKAGE 2", "MODEL_PP": "ModelPPHertzMindlin",
        "MODEL_PW": "ModelPWHertzMindlin", "MODEL_EF": "ModelEFViscousField",
        "MODEL_EF_PARAMS": "MEDIUM_DENSITY 2", "MODEL_HT_PP": "ModelHTPPConduction",
        "MODEL_LB": "ModelLBCapilarViscous", "CONNECTED_PP_CONTACT": "1",
        "STOP_CRITERION": "BROKEN_BONDS 7"}
    # MUSEN's defaults: no keys for them; a file without a simulator module keeps Verlet
    # adjustment off
    assert script_of(fake({"simulator": {"verlet_dist_coeff": 2.0,
                                         "verlet_auto_adjust": True}})) == {
        "EXT_ACCEL": "0.0 0.0 0.0", "VARIABLE_TIME_STEP": "0"}
    assert script_of(fake({"simulator": {}}))["VERLET_AUTO"] == "0"
    assert "VERLET_AUTO" not in script_of(fake())
    old = script_of(fake({"model_manager": {"pp_model": {"path": "ModelPPJKR",
                                                         "params": "X 1"},
                                            "sb_model": {"path": ""}}},
                         {"stop_criteria": {"types": [0]}}))
    assert (old["MODEL_PP"], old["MODEL_PP_PARAMS"], old["CONNECTED_PP_CONTACT"]) == (
        "ModelPPJKR", "X 1", "0")
    assert "MODEL_SB" not in old and "STOP_CRITERION" not in old


def motion(kind, *intervals):
    return {"type": kind, "intervals": list(intervals)}


def test_geometry_motions_as_musens_text():
    assert mm._motion_text({}) == "0 0" and mm._motion_text(motion(1)) == "0 0"
    assert mm._motion_text(motion(0, {"limit1": 1.0})) == "0 0"
    one = {"limit1": 0.5, "limit2": 1.5, "velocity": {"x": 1.0}, "rot_center": {"y": 2.0},
           "rot_velocity": {"z": 3.0}, "limit_type": 4}
    assert mm._motion_text(motion(1, one, {})) == (
        "1 2 0.5 1.5 1.0 0.0 0.0 0.0 2.0 0.0 0.0 0.0 3.0 "
        "0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0")
    assert mm._motion_text(motion(2, one)) == ("2 1 0.5 4 1.0 0.0 0.0 0.0 2.0 0.0 0.0 0.0 "
                                               "3.0")
    assert mm.vector(None) == (0.0, 0.0, 0.0) and mm.vector(None, (1, 2, 3)) == (1, 2, 3)
    assert mm.vector({"y": 2.0}) == (0.0, 2.0, 0.0)


def test_a_written_file_reads_back_as_the_text_it_was_written_from(tmp_path):
    keys = {"SIMULATION_STEP": "2e-07", "END_TIME": "1e-05", "SAVING_STEP": "1e-06",
            "EXT_ACCEL": "0 0 -9.81", "MODEL_SB": "ModelSBKelvin", "MODEL_SB_PARAMS": "MU 2",
            "MODEL_PP": "ModelPPHertzMindlin", "MODEL_PW": "ModelPWHertzMindlin",
            "CONNECTED_PP_CONTACT": "0"}
    # (wall 4's corners in MUSEN 1.71's command 44 are not what export_lines writes)
    lines = [line for line in TEXT.replace("\\\n", "").splitlines()
             if line and not line.startswith(("29", "99", "40", "0 4 "))]
    lines.append("28 1 1 0 0 -0.01 -0.01 -0.01 0.02 0.02 0.02")
    storage, points = mdem_storage(lines, keys)
    assert [t for t, _ in points] == [0.0, 1e-3]
    write_mdem(tmp_path / "a.mdem", storage, points)
    mdem = MdemFile(tmp_path / "a.mdem")
    mdem.check()
    assert (mdem.version, mdem.cluster) == (2, 4096)
    read = scene_of(mdem)
    (tmp_path / "a.txt").write_text("\n".join(lines) + "\n")
    text = read_text(tmp_path / "a.txt")
    for ident, obj in text.objects.items():
        got = read.objects[ident]
        assert (got.type, got.geometry, got.compound, got.active) == (
            obj.type, obj.geometry, obj.compound, obj.active), ident
        assert (got.coordinates, got.velocity, got.angular_velocity) == (
            obj.coordinates, obj.velocity, obj.angular_velocity), ident
        assert got.time == 0.0 and got.times == 1
    assert read.objects[0].quaternion == (0.0, 1.0, 0.0, 0.0)    # a new sphere's
    assert read.objects[3].quaternion == (0.01, 0.0, 0.0, 0.0)
    assert read.domain == text.domain
    assert read.periodic == (True, True, False, False, (-0.01,) * 3, (0.02,) * 3)
    # the compounds with MUSEN's defaults for what the text leaves out
    assert read.compounds["steel"] == {**mm.COMPOUND_DEFAULTS, 0: 7800.0, 7: 2e9}
    assert read.compounds["glass"][10] == 0.3 and read.compounds["glass"][11] == 1.0
    assert read.interactions[("glass", "glass")] == {**mm.INTERACTION_DEFAULTS, 200: 0.7,
                                                     201: 0.4, 202: 0.01}
    # every pair of compounds gets an interaction, MUSEN's defaults where none is given
    assert read.interactions[("binder", "steel")] == mm.INTERACTION_DEFAULTS
    assert read.interactions[("glass", "steel")] == {**mm.INTERACTION_DEFAULTS, 200: 0.6}
    assert len(read.interactions) == 6
    assert read.geometries == [["lid", "geometry1", "1 1 0.0 0.001 0.0 0.0 -0.01 0.0 0.0 "
                                "0.0 0.0 0.0 0.0", [3]]]
    assert read.unmapped == [] and read.multispheres == []
    script = script_of(mdem)
    assert script == {"SIMULATION_STEP": "2e-07", "SAVING_STEP": "1e-06",
                      "END_TIME": "1e-05", "EXT_ACCEL": "0.0 0.0 -9.81",
                      "VARIABLE_TIME_STEP": "0", "MODEL_SB": "ModelSBKelvin",
                      "MODEL_SB_PARAMS": "MU 2", "MODEL_PP": "ModelPPHertzMindlin",
                      "MODEL_PW": "ModelPWHertzMindlin", "CONNECTED_PP_CONTACT": "0"}
    assert musen_release(mdem) == "1.74.2"
    manager = mdem.modules["model_manager"]
    assert manager["sb_model"] == {"key": "ModelSBKelvin", "path": "ModelSBKelvin",
                                   "params": "MU 2"}
    simulator = mdem.modules["simulator"]
    assert (simulator["simulation_step"], simulator["saving_step"], simulator["end_time"]) == (
        2e-7, 1e-6, 1e-5)
    times = [t for t, _ in mdem.time_points()]
    assert times == [0.0, 1e-3]
    second = list(mdem.time_points())[1][1]
    assert mm.vector(second[0]["coord"]) == (0.0011, 0.002, 0.003)
    assert mm.vector(second[0]["angle_vel"]) == (0.0, 0.0, 6.0)
    assert second[1] == {"quaternion": {"q1": 1.0}}  # sphere 1 has no second time point
    assert mm.vector(second[3]["coord"]) == (0.0, 0.0, 0.0) and "quaternion" in second[3]


def test_defaults_of_a_file_written_without_script_keys(tmp_path):
    storage, points = mdem_storage(["0 0 1 1 5 0.001 0.001 23 glass 2 0.5 12 0 0 0",
                                    "32 glass glass"], {})
    simulator = storage["modules_data"]["simulator"]
    assert (simulator["end_time"], simulator["simulation_step"], simulator["saving_step"]) == (
        0.5, 1e-7, 1e-3)
    assert storage["modules_data"]["model_manager"]["connected_pp_contact"] is True
    assert storage["modules_data"]["model_manager"]["models"] == []
    assert storage["info"]["end_time"] == 0.5 and storage["info"]["savedTimePoints"] == [0.5]
    storage, _ = mdem_storage([], {"END_TIME": "2e-3"})
    assert storage["info"]["end_time"] == 0.0 and storage["info"]["particles"] == []
    assert storage["modules_data"]["simulator"]["saving_step"] == 2e-3
    write_mdem(tmp_path / "empty.mdem", storage, [])
    mdem = MdemFile(tmp_path / "empty.mdem")
    assert list(mdem.time_points()) == [] and len(mdem.blocks) == 1


def test_scene_details_only_a_file_holds(tmp_path):
    info = {"particles": [{"id": 0, "type": 1, "compound": "glass",
                           "encoded_properties": struct.pack("<2d", 1e-3, 1e-3),
                           "activity_end": 5.0},
                          {"id": 1, "type": 0}, {"id": 2, "type": 1, "compound": "glass",
                                                 "encoded_properties": struct.pack(
                                                     "<2d", 2e-3, 2e-3)}],
            "periodic_conditions_vel": {"x": 0.1},
            "real_geometry_v0": [{"name": "old lid", "key": "k", "planes": [4.0],
                                  "tdVal": [{"time": 0.0}]},
                                 {"name": "still", "key": "k2"}],
            "analysis_volume": [{}, {}], "analysis_volume_v0": [b"x"],
            "multispheres": [{"id": [0, 2]}, {}],
            "simulation_volume_max": {"x": 1.0}}
    materials = {"compound": [{"uniqueKey": "glass",
                               "constProperty": [{"propertyType": 0, "value": 2500.0},
                                                 {"propertyType": 7, "value": 1.0}],
                               "property": [{"propertyType": 7,
                                             "correlation": [correlation(0, [1e8])]}]}],
                 "interaction": [{"compoundKey1": "z", "compoundKey2": "a",
                                  "property": [{"propertyType": 200,
                                                "correlation": [correlation(0, [0.5])]}]}]}
    points = [(0.25, [{"coord": {"x": 1.0}}])]
    scene = scene_of(fake({"materials_database": materials}, info, points))
    assert sorted(scene.objects) == [0, 2]
    assert scene.objects[0].active == (0.0, 5.0) and scene.objects[0].time == 0.25
    assert scene.objects[0].coordinates == (1.0, 0.0, 0.0)
    assert scene.objects[2].coordinates == (0.0, 0.0, 0.0) and scene.objects[2].time == 0.25
    assert scene.domain == (0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    assert scene.periodic == (False, False, False, False, (0.0,) * 3, (0.0,) * 3)
    assert scene.compounds == {"glass": {0: 2500.0, 7: 1e8}}
    assert scene.interactions == {("a", "z"): {200: 0.5}}
    assert scene.geometries == [["old_lid", "k", "", [4]], ["still", "k2", "", []]]
    assert scene.multispheres == [[0, 2], []]
    assert scene.unmapped == [
        "periodic boundaries: moving boundaries are not mapped",
        "geometry old lid: the motion of an old-format geometry is not mapped (the wall is "
        "static)",
        "2 analysis volume(s) not mapped", "1 analysis volume(s) not mapped"]
    bad = {"particles": [{"id": 3, "type": 1, "encoded_properties": b"\0" * 3}]}
    with pytest.raises(InputError) as error:
        scene_of(fake(info=bad))
    assert str(error.value) == "x.mdem: damaged object (object 3: 3 bytes of geometry for type 1)"
    text = {"particles": [{"id": 3, "type": 1, "encoded_properties": b"0.002 0.0025"}]}
    assert scene_of(fake(info=text, version=1)).objects[3].geometry == [0.002, 0.0025]
    assert scene_of(fake()).domain is None


def test_the_generators_a_file_keeps():
    triangle = {"vert1": {"x": 1.0}, "vert2": {"y": 1.0}, "vert3": {"z": 1.0}}
    info = {"analysis_volume": [
        {"base_geometry": {"name": "cube", "key": "K1", "shape": 1, "sizes": [1.0, 2.0, 3.0],
                           "rotation": {"v1": {"y": 1.0}, "v2": {"x": -1.0},
                                        "v3": {"z": 1.0}}},
         "triangles": [triangle, triangle]},
        {"base_geometry": {"name": "ball", "key": "K2"}}]}
    materials = {"mixture": [{"uniqueKey": "M1", "mixtureName": "mix", "fraction": [
        {"compoundKey": "glass", "diameter": 1e-3, "contact_diameter": 1.1e-3,
         "fraction": 0.25}, {}]}]}
    modules = {"materials_database": materials, "package_generator": {"generators": [
        {"volume_active": True, "volume_name": "g", "volume_key": "K1", "mixture_key": "mix",
         "porosity": 0.4, "max_overlap": 1e-5, "init_velocity": {"z": -1.0},
         "inside_geometry": True}, {"volume_key": "none"}]},
        "bonds_generator": {"generators": [
            {"activity": True, "name": "b", "material_key": "binder", "min_length": 1e-5,
             "max_length": 2e-4, "property1": 5e-4, "allow_overlap": True,
             "compound_specific": True, "partner_compounds1": ["a"],
             "partner_compounds2": ["b", "c"]},
            {"partner_compounds1": ["a"]}]}}
    mdem = fake(modules, info)
    volumes, mixtures = package_tables(mdem)
    cube = volumes["K1"]
    assert volumes["cube"] is cube and volumes["ball"] is volumes["K2"]
    assert (cube["name"], cube["shape"], cube["sizes"]) == ("cube", 1, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(cube["rotation"], [[0, 1, 0], [-1, 0, 0], [0, 0, 1]])
    np.testing.assert_array_equal(cube["triangles"][1], [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert cube["triangles"].shape == (2, 3, 3)
    ball = volumes["K2"]
    assert (ball["shape"], ball["sizes"], ball["triangles"].shape) == (0, [], (0, 3, 3))
    np.testing.assert_array_equal(ball["rotation"], np.eye(3))
    assert mixtures["M1"] is mixtures["mix"]
    assert mixtures["mix"]["fractions"] == [("glass", 1e-3, 1.1e-3, 0.25), ("", 0.0, 0.0, 0.0)]
    first, second = package_generators(mdem)
    assert first["volume"]["name"] == "cube" and first["mixture"]["key"] == "M1"
    assert {k: v for k, v in first.items() if k not in ("volume", "mixture")} == {
        "active": True, "name": "g", "porosity": 0.4, "max_overlap": 1e-5,
        "velocity": (0.0, 0.0, -1.0), "inside_geometry": True}
    assert second == {"active": False, "name": "", "volume": None, "mixture": None,
                      "porosity": 0.0, "max_overlap": 0.0, "velocity": (0.0, 0.0, 0.0),
                      "inside_geometry": False}
    assert bond_generators(mdem) == [
        {"active": True, "name": "b", "compound": "binder", "min_distance": 1e-5,
         "max_distance": 2e-4, "diameter": 5e-4, "overlay": True,
         "compounds": (["a"], ["b", "c"])},
        {"active": False, "name": "", "compound": "", "min_distance": 0.0,
         "max_distance": 0.0, "diameter": 0.0, "overlay": False, "compounds": None}]
    assert package_generators(fake()) == [] and bond_generators(fake()) == []


def test_break_modes_follow_the_larger_fraction_of_strength():
    axis = np.array([[1.0, 0.0, 0.0]] * 4)
    area = np.full(4, 2.0)
    # normal stress F_n / A against sigma_n, tangential |F_t| / A against tau
    force = np.array([[4.0, 1.0, 0.0], [-4.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 0.0]])
    modes = break_modes(force, axis, area, np.full(4, 1.0), np.full(4, 1.0))
    assert modes.tolist() == [1, 2, 3, 1] and modes.dtype == np.int8
    # a weak shear strength turns the first into shear: 1/(2*0.2) = 2.5 > 4/(2*1) = 2
    assert break_modes(force[:1], axis[:1], area[:1], np.ones(1), np.full(1, 0.2)).tolist() == [3]
    assert break_modes(force[:1], axis[:1], area[:1], np.ones(1), np.full(1, 0.3)).tolist() == [1]


def test_rows_of_a_time_dependent_property():
    values = [{"coord": {"x": 1.0}, "total_torque": 2.0, "quaternion": {"q0": 0.5, "q3": 1.0}},
              {}]
    np.testing.assert_array_equal(mm._rows(values, "coord", (3,)), [[1, 0, 0], [0, 0, 0]])
    np.testing.assert_array_equal(mm._rows(values, "total_torque", ()), [2.0, 0.0])
    np.testing.assert_array_equal(mm._rows(values, "quaternion", (4,)), [[0.5, 0, 0, 1],
                                                                         [0, 0, 0, 0]])


def good_file(tmp_path, lines=None, keys=None):
    lines = lines or [line for line in TEXT.replace("\\\n", "").splitlines()
                      if line and not line.startswith(("29", "99", "40"))]
    storage, points = mdem_storage(lines, keys or {})
    path = tmp_path / "good.mdem"
    write_mdem(path, storage, points)
    return path


def damaged(tmp_path, raw, name="bad.mdem"):
    path = tmp_path / name
    path.write_bytes(raw)
    with pytest.raises(InputError) as error:
        MdemFile(path).check()
    text = str(error.value)
    assert text.startswith(f"{path}: ")
    return text[len(str(path)) + 2:]


def test_every_kind_of_damage_is_one_line(tmp_path):
    raw = good_file(tmp_path).read_bytes()
    assert damaged(tmp_path, raw[:mm.HEADER + 2 * mm.THREAD_HEADER - 1]) == \
        "too short for a .mdem file (no headers)"
    headers_only = raw[:mm.HEADER + 2 * mm.THREAD_HEADER]
    assert damaged(tmp_path, b"\0\0\0\0" + raw[4:]) == \
        "not a MUSEN .mdem file (no 0x12345678 signature)"
    assert damaged(tmp_path, raw[:4] + struct.pack("<I", 3) + raw[8:]) == \
        ".mdem format version 3; readable: 1 and 2 (MUSEN 1.70.0 to 1.74.2)"
    for threads, cluster in ((1, 4096), (2, 0), (2, 4000)):
        text = damaged(tmp_path, raw[:8] + struct.pack("<2I", threads, cluster) + raw[16:])
        assert text == f"damaged header ({threads} threads, cluster {cluster} bytes)"
    assert damaged(tmp_path, headers_only) == "truncated (a block lies past the end of the file)"
    # the first thread's data: its zlib stream cut or flipped
    info = mm.HEADER + 2 * mm.THREAD_HEADER
    size = struct.unpack_from("<Q", raw, mm.HEADER + 64)[0]
    cut = bytearray(raw)
    struct.pack_into("<Q", cut, mm.HEADER + 64, size - 5)
    assert damaged(tmp_path, bytes(cut)) == \
        "the simulation info is truncated (its zlib stream ends early)"
    flipped = bytearray(raw)
    flipped[info + 2:info + 12] = b"\xff" * 10
    assert damaged(tmp_path, bytes(flipped)) == \
        "the simulation info is damaged (its zlib stream does not inflate)"
    # a time block said to lie beyond the file
    far = storage_file(tmp_path, {"info": {}, "data_blocks": [{"offset_in_file": 1 << 40,
                                                               "size": 10}]})
    with pytest.raises(InputError) as error:
        MdemFile(far).check()
    assert str(error.value) == f"{far}: truncated (a block lies past the end of the file)"
    # a zero block offset: the block is missing
    missing = bytearray(raw)
    struct.pack_into("<Q", missing, mm.HEADER + 80, 0)
    assert damaged(tmp_path, bytes(missing)) == \
        "truncated (a block lies past the end of the file)"
    # a time block: flipped bytes in the second thread's first block
    second = struct.unpack_from("<Q", raw, mm.HEADER + mm.THREAD_HEADER + 80)[0]
    timed = bytearray(raw)
    timed[second + 2:second + 12] = b"\xff" * 10
    assert damaged(tmp_path, bytes(timed)).startswith("time block 0 is ")
    with pytest.raises(InputError) as error:
        MdemFile(tmp_path / "nothing.mdem")
    assert str(error.value) == f"{tmp_path / 'nothing.mdem'}: cannot read: No such file or " \
                               "directory"


def storage_file(tmp_path, storage, raw_info=None, name="s.mdem"):
    """A file whose simulation info is ``storage`` encoded (or the bytes raw_info)."""
    write_mdem(tmp_path / name, {"info": {}}, [])
    raw = bytearray((tmp_path / name).read_bytes())
    data = zlib.compress(raw_info if raw_info is not None else
                         encode(storage, "ProtoSimulationStorage", mm.TABLES))
    start = mm.HEADER + 2 * mm.THREAD_HEADER
    offsets = struct.unpack_from(f"<{mm.BLOCKS_PER_THREAD}Q", raw, mm.HEADER + 80)
    room = sum(block_size(k, mm.CLUSTER) for k, at in enumerate(offsets) if at)
    assert len(data) <= room and offsets[0] == start
    raw[start:start + len(data)] = data
    struct.pack_into("<Q", raw, mm.HEADER + 64, len(data))
    (tmp_path / name).write_bytes(bytes(raw))
    return tmp_path / name


def test_a_file_without_time_blocks_or_with_a_bad_message(tmp_path):
    path = storage_file(tmp_path, {"info": {}})
    with pytest.raises(InputError) as error:
        MdemFile(path)
    assert str(error.value) == f"{path}: no time-dependent blocks (not a finished MUSEN save)"
    path = storage_file(tmp_path, None, raw_info=b"\x0a\x05ab")
    with pytest.raises(InputError) as error:
        MdemFile(path)
    assert str(error.value).startswith(f"{path}: the simulation info is damaged (")
    # a block stored raw (MUSEN's kProtoBuf format) and an empty one are read too
    point = encode({"time": 0.5, "particles": [{"coord": {"x": 2.0}}]}, "ProtoTimePoint",
                   mm.TABLES)
    body = b"\x12" + mm.varint(len(point)) + point
    storage = {"info": {}, "data_blocks": [{"size": 0}, {"offset_in_file": 0,
                                                         "size": len(body), "format": 1}]}
    path = storage_file(tmp_path, storage, name="raw.mdem")
    raw = bytearray(path.read_bytes())
    second = struct.unpack_from("<Q", raw, mm.HEADER + mm.THREAD_HEADER + 80)[0]
    raw[second:second + len(body)] = body
    struct.pack_into("<Q", raw, mm.HEADER + mm.THREAD_HEADER + 64, len(body))
    path.write_bytes(bytes(raw))
    mdem = MdemFile(path)
    mdem.check()
    assert [(t, mm.vector(p[0]["coord"])) for t, p in mdem.time_points()] == [
        (0.5, (2.0, 0.0, 0.0))]


def test_import_mdem_writes_the_scene_in_the_files_release(tmp_path):
    keys = {"SIMULATION_STEP": "2e-07", "END_TIME": "1e-05", "MODEL_SB": "ModelSBElastic"}
    path = good_file(tmp_path, keys=keys)
    scene, notes = import_mdem(path, tmp_path / "out")
    assert scene == tmp_path / "out" / "scene.toml"
    import tomllib
    data = tomllib.loads(scene.read_text())
    assert data["simulation"]["musen_version"] == "1.74.2"
    assert data["simulation"]["end_time"] == pytest.approx(50 * 2e-7, rel=1e-12, abs=0)
    assert data["simulation"]["box_low"] == [-0.01] * 3
    assert data["materials"]["steel"]["poisson_ratio"] == 0.2     # MUSEN's default
    assert "sphere 1: contact radius 0.0013 differs from its radius; bondem uses the radius" \
        in notes and not any(n.startswith(".mdem format") for n in notes)
    scene, _ = import_mdem(path, tmp_path / "old", end_time=3e-5, musen_version="1.70.0")
    data = tomllib.loads(scene.read_text())
    assert (data["simulation"]["musen_version"], data["simulation"]["end_time"]) == (
        "1.70.0", 3e-5)
    bad = good_file(tmp_path, keys={"MODEL_SB": "ModelSBFoo"})
    with pytest.raises(InputError) as error:
        import_mdem(bad, tmp_path / "x")
    assert str(error.value).startswith(f"{bad}: MODEL_SB: solid bond model ModelSBFoo")
    # format 1 (MUSEN before 1.70): geometries as text
    lines = [line for line in TEXT.replace("\\\n", "").splitlines()
             if line.startswith(("0 0 ", "0 1 ", "32 "))]
    storage, points = mdem_storage(lines, keys)
    for particle in storage["info"]["particles"]:
        particle["encoded_properties"] = " ".join(
            repr(v) for v in struct.unpack("<2d", particle["encoded_properties"])).encode()
    write_mdem(tmp_path / "v1.mdem", storage, points)
    raw = bytearray((tmp_path / "v1.mdem").read_bytes())
    struct.pack_into("<I", raw, 4, 1)
    (tmp_path / "v1.mdem").write_bytes(bytes(raw))
    scene, notes = import_mdem(tmp_path / "v1.mdem", tmp_path / "v1")
    assert notes[-1] == ".mdem format version 1"
    assert "0.0031,0.002,0.003,0.0012,steel" in (tmp_path / "v1" / "particles.csv").read_text()


RUN = """\
0 0 1 1 5 0.001 0.001 23 glass 24 0 1e+300 2 0 12 0 0 0 15 0 0 0 16 0 0 0 \
2 1e-5 12 0 0 0 15 0.1 0 0 16 0 0 1 2 2e-5 12 0 0 -1e-6 15 0.2 0 0 16 0 0 2
0 1 1 1 5 0.001 0.001 23 glass 24 0 1e+300 2 0 12 0.002 0 0 2 1e-5 12 0.002 0 0 \
2 2e-5 12 0.002 0 1e-6
0 2 1 9 5 0 1 0.0005 0.002 23 binder 24 0 1e-5 2 0 12 0 0 0
0 3 1 14 23 glass 24 0 1e+300 2 0 12 -1 -1 -0.002 31 1 -1 -0.002 0 16 0 1 -0.002
0 4 1 9 5 0 1 0.0005 0.002 23 binder 24 0 0 2 0 12 0 0 0
32 glass glass 0 2500 7 1e8 10 0.3
32 binder binder 7 5e7 8 1e6 9 1e6 10 0.3
33 glass glass 200 0.5 201 0.3 202 0.0
"""


def test_a_finished_runs_results_become_a_results_file(tmp_path):
    storage, points = mdem_storage(RUN.replace("\\\n", "").splitlines(),
                                   {"SIMULATION_STEP": "1e-7", "END_TIME": "2e-5",
                                    "MODEL_PP": "ModelPPHertzMindlin",
                                    "MODEL_PW": "ModelPWHertzMindlin"})
    # MUSEN's own loads at each time point: the bond's force, a wall triangle's force
    # the bond pulls particle 0 toward 1 at first (tension), then pushes it (compression)
    for k, (t, objects) in enumerate(points):
        objects[2]["force"] = {"x": (3.0, -6.0, 9.0)[k], "y": 0.5}
        objects[2]["total_torque"] = 0.25 * k
        objects[2]["angle_vel"] = {"z": 1e-9 * k}
        objects[3]["force"] = {"z": -2.0 * k}
        objects[0]["force"] = {"x": 1.0 * k}
        # the wall's three corners move up by 1, 2 and 3 x 1e-4 m per time point
        objects[3]["coord"] = {"x": -1.0, "y": -1.0, "z": -0.002 + 1e-4 * k}
        objects[3]["quaternion"] = {"q0": 1.0, "q1": -1.0, "q2": -0.002 + 2e-4 * k}
        objects[3]["angle_vel"] = {"y": 1.0, "z": -0.002 + 3e-4 * k}
    write_mdem(tmp_path / "run.mdem", storage, points)
    results, notes = import_mdem_results(tmp_path / "run.mdem", tmp_path / "out")
    assert results == tmp_path / "out" / "results.h5"
    assert notes[-1] == ("bond moments are not in a .mdem file (NaN); break modes inferred "
                         "from each bond's last saved force")
    with h5py.File(results) as f:
        assert f["time"][()].tolist() == [0.0, 1e-5, 2e-5]
        np.testing.assert_array_equal(f["particles/position"][2], [[0, 0, -1e-6],
                                                                   [0.002, 0, 1e-6]])
        np.testing.assert_array_equal(f["particles/velocity"][1, 0], [0.1, 0, 0])
        np.testing.assert_array_equal(f["particles/angular_velocity"][2, 0], [0, 0, 2])
        np.testing.assert_array_equal(f["particles/force"][2, 0], [2.0, 0, 0])
        # active up to and at the end of its activity interval; the bond already broken
        # at the first time point is left out
        assert f["bonds/active"][()].tolist() == [[True], [True], [False]]
        np.testing.assert_array_equal(f["bonds/force"][:, 0], [[3.0, 0.5, 0], [-6.0, 0.5, 0],
                                                               [0, 0, 0]])
        assert f["bonds/break_time"][()].tolist() == [1e-5]
        # its last saved force pushed particle 0 away from 1 and sheared little
        assert f["bonds/break_mode"][()].tolist() == [2]
        assert np.all(np.isnan(f["bonds/normal_moment"][()]))
        assert np.all(np.isnan(f["bonds/tangential_moment"][()]))
        np.testing.assert_array_equal(f["walls/force"][:, 0], [[0, 0, 0], [0, 0, -2.0],
                                                               [0, 0, -4.0]])
        travel = f["walls/position"][:, 0] - f["walls/position"][0, 0]
        np.testing.assert_allclose(travel[:, 2], [0.0, 2e-4, 4e-4], rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(travel[:, :2], 0.0, atol=1e-15)
        from bondem.scene import load_scene
        start = load_scene(tmp_path / "out" / "scene.toml").make_simulation().wall_positions()
        np.testing.assert_array_equal(f["walls/position"][0], start)
        assert f.attrs["scene_name"] == "scene.toml"
        assert f.attrs["scene"] == (tmp_path / "out" / "scene.toml").read_text()
        others = [k for k in f["energy"] if not k.startswith("kinetic")]
        assert others and all(np.isnan(f[f"energy/{k}"][()]).all() for k in others)
        assert np.all(np.isnan(f["walls/torque"][()]))
        np.testing.assert_array_equal(f["musen/bond_total_torque"][()], [[0.0], [0.25], [0.5]])
        assert f["musen/bond_tangential_overlap"][2, 0].tolist() == [0.0, 0.0, 2e-9]
        assert f["musen/bond_tangential_overlap"].attrs["unit"] == "m"
        assert f["musen/bond_total_torque"].attrs["unit"] == "N m"
        assert f.attrs["source"] == "MUSEN .mdem (format 2): run.mdem"
        assert f.attrs["musen_version"] == "1.74.2"
        mass = 2500 * 4 / 3 * math.pi * 1e-9
        inertia = 0.4 * mass * 1e-6
        assert f["energy/kinetic_translational"][2] == pytest.approx(0.5 * mass * 0.04,
                                                                     rel=1e-12, abs=0)
        assert f["energy/kinetic_rotational"][1] == pytest.approx(0.5 * inertia, rel=1e-12, abs=0)
    results, notes = import_mdem_results(tmp_path / "run.mdem", tmp_path / "old",
                                         musen_version="1.70.0")
    with h5py.File(results) as f:
        assert f.attrs["musen_version"] == "1.70.0"
    import tomllib
    assert tomllib.loads((tmp_path / "old" / "scene.toml").read_text())["simulation"][
        "musen_version"] == "1.70.0"
    # a time point that stops short of the walls and bonds: they read as absent
    del points[-1][1][2:]
    write_mdem(tmp_path / "short.mdem", storage, points)
    results, _ = import_mdem_results(tmp_path / "short.mdem", tmp_path / "short")
    with h5py.File(results) as f:
        assert f["walls/force"][2, 0].tolist() == [0.0, 0.0, 0.0]
        assert f["particles/position"][2, 1].tolist() == [0.002, 0, 1e-6]


def test_an_exported_mdem_holds_the_results_and_a_script(tmp_path):
    data = results_data(walls=False)
    data["particles/clump"] = np.array([0, 0])
    path = tmp_path / "results.h5"
    with h5py.File(path, "w") as f:
        for name, value in data.items():
            f[name] = value.astype(h5py.string_dtype()) if value.dtype.kind == "U" else value
        f.attrs["scene"] = "[simulation]\nend_time = 2e-4\n"
        f.attrs["time_step"] = 1e-6
    out, script, notes = export_mdem(path, tmp_path / "out" / "run.mdem", every=2)
    assert notes == ["1 clumps written as multispheres (MUSEN 1.74.2's simulator moves their "
                     "spheres as free particles)"]
    mdem = MdemFile(out)
    mdem.check()
    assert [t for t, _ in mdem.time_points()] == [0.0, 2e-4]
    assert scene_of(mdem).multispheres == [[0, 1]]
    keys = read_script(script)
    assert keys["SOURCE_FILE"] == "./run.mdem" and keys["RESULT_FILE"] == "./run_result.mdem"
    assert keys["END_TIME"] == repr(199.5e-6)
    assert script_of(mdem)["SIMULATION_STEP"] == "1e-06"
    del data["particles/clump"]


def test_a_written_file_holds_what_musens_simulator_reads(tmp_path):
    """What MUSEN's text import makes of a scene (its defaults for what text cannot say:
    a solid compound by 'bondem', an unrotated geometry of scale 1, the simulator's
    settings), read back from the file bondem writes."""
    lines = ["0 0 1 1 5 0.001 0.001 23 glass 24 0.5 2.5 2 0 12 0.001 0.002 0.003",
             "0 1 1 14 23 steel 24 0 1e+300 2 0 12 0 0 0 31 0.01 0.02 0.03 0.04 16 0 0.01 0",
             "0 2 1 14 23 steel 24 0 1e+300 2 0 12 0 0 1 31 0.01 0 1 0 16 0 0.01 1",
             "22 -1 -2 -3 4 5 6", "28 1 0 1 1 -0.1 -0.2 -0.3 0.4 0.5 0.6",
             "32 glass Glass 0 2500", "32 steel Steel 7 2e9",
             "25 lid key1",
             "26 1 2 0 1e-3 1 2 3 4 5 6 7 8 9 1e-3 2e-3 -1 -2 -3 -4 -5 -6 -7 -8 -9",
             "27 2 1 2"]
    keys = {"MODEL_SB": "ModelSBElastic", "MODEL_SB_PARAMS": "CONSIDER_BREAKAGE 0",
            "MODEL_PP": "ModelPPJKR", "MODEL_PW": "ModelPWJKR", "END_TIME": "2e-3"}
    storage, points = mdem_storage(lines, keys)
    write_mdem(tmp_path / "w.mdem", storage, points)
    mdem = MdemFile(tmp_path / "w.mdem")
    info, modules = mdem.info, mdem.modules
    assert info["version"] == 1 and info["savedTimePoints"] == [0.0]
    sphere = info["particles"][0]
    assert (sphere["activity_start"], sphere["activity_end"]) == (0.5, 2.5)
    assert info["simulation_volume_min"] == {"x": -1.0, "y": -2.0, "z": -3.0}
    assert info["simulation_volume_max"] == {"x": 4.0, "y": 5.0, "z": 6.0}
    assert (info["periodic_conditions_enabled"], info.get("periodic_conditions_x", False),
            info["periodic_conditions_y"], info["periodic_conditions_z"]) == (
        True, False, True, True)
    assert info["periodic_conditions_min"] == {"x": -0.1, "y": -0.2, "z": -0.3}
    assert info["periodic_conditions_max"] == {"x": 0.4, "y": 0.5, "z": 0.6}
    geometry = info["real_geometry"][0]
    assert geometry["version"] == 1 and geometry["planes"] == [1, 2]
    base = geometry["base_geometry"]
    assert (base["version"], base["name"], base["key"], base["scaling"]) == (
        1, "lid", "key1", 1.0)
    assert base["rotation"] == {"v1": {"x": 1.0}, "v2": {"y": 1.0}, "v3": {"z": 1.0}}
    motion = base["motion"]
    assert motion["type"] == 1 and len(motion["intervals"]) == 2
    second = motion["intervals"][1]
    assert (second["limit1"], second["limit2"]) == (1e-3, 2e-3)
    assert second["velocity"] == {"x": -1.0, "y": -2.0, "z": -3.0}
    assert second["rot_center"] == {"x": -4.0, "y": -5.0, "z": -6.0}
    assert second["rot_velocity"] == {"x": -7.0, "y": -8.0, "z": -9.0}
    assert motion["intervals"][0]["rot_velocity"] == {"x": 7.0, "y": 8.0, "z": 9.0}
    compounds = {c["uniqueKey"]: c for c in modules["materials_database"]["compound"]}
    assert compounds["glass"]["compoundName"] == "Glass"
    assert (compounds["steel"]["authorName"], compounds["steel"]["phase"]) == ("bondem", 2)
    simulator = modules["simulator"]
    assert {k: simulator[k] for k in ("simulator_type", "max_cells_number",
                                      "verlet_dist_coeff", "verlet_auto_adjust",
                                      "part_move_limit", "time_step_factor", "end_time")} == {
        "simulator_type": 1, "max_cells_number": 50, "verlet_dist_coeff": 2.0,
        "verlet_auto_adjust": True, "part_move_limit": 1e-8, "time_step_factor": 1.01,
        "end_time": 2e-3}
    manager = modules["model_manager"]
    assert manager["version"] == 1 and manager["connected_pp_contact"] is True
    assert manager["models"] == [
        {"key": "ModelSBElastic", "path": "ModelSBElastic", "params": "CONSIDER_BREAKAGE 0"},
        {"key": "ModelPPJKR", "path": "ModelPPJKR"}, {"key": "ModelPWJKR", "path": "ModelPWJKR"}]
    assert manager["pp_model"] == {"key": "ModelPPJKR", "path": "ModelPPJKR"}
    assert manager["pw_model"] == {"key": "ModelPWJKR", "path": "ModelPWJKR"}
    _, objects = next(mdem.time_points())
    assert objects[1]["quaternion"] == {"q0": 0.01, "q1": 0.02, "q2": 0.03, "q3": 0.04}
    assert objects[2]["angle_vel"] == {"y": 0.01, "z": 1.0}
    scene = scene_of(mdem)
    assert scene.objects[1].quaternion == (0.01, 0.02, 0.03, 0.04)
    storage, _ = mdem_storage(lines, {"CONNECTED_PP_CONTACT": "0"})
    assert storage["modules_data"]["model_manager"]["connected_pp_contact"] is False


def test_time_points_split_into_blocks_and_the_headers(tmp_path, monkeypatch):
    monkeypatch.setattr(mm, "BLOCK_LIMIT", 120)
    lines = ["0 0 1 1 5 0.001 0.001 23 glass " + " ".join(
        f"2 {k * 1e-4!r} 12 {k * 1e-6!r} 0 0 15 0.5 0 0" for k in range(12)),
             "32 glass glass 0 2500"]
    storage, points = mdem_storage(lines, {})
    write_mdem(tmp_path / "b.mdem", storage, points)
    raw = (tmp_path / "b.mdem").read_bytes()
    assert struct.unpack_from("<4I", raw) == (mm.SIGNATURE, 2, 2, mm.CLUSTER)
    assert raw[16:mm.HEADER] == b"\0" * (mm.HEADER - 16)
    for k, name in enumerate((b"simulation info", b"time-dependent")):
        at = mm.HEADER + k * mm.THREAD_HEADER
        assert raw[at:at + 64] == name.ljust(64, b"\0")
        assert struct.unpack_from("<Q", raw, at + 72)[0] == 0
        offsets = struct.unpack_from(f"<{mm.BLOCKS_PER_THREAD}Q", raw, at + 80)
        used = [o for o in offsets if o]
        assert offsets[len(used):] == (0,) * (mm.BLOCKS_PER_THREAD - len(used))
    mdem = MdemFile(tmp_path / "b.mdem")
    mdem.check()
    blocks = mdem.blocks
    assert len(blocks) >= 3
    read = list(mdem.time_points())
    assert [t for t, _ in read] == [k * 1e-4 for k in range(12)]
    assert [mm.vector(p[0]["coord"])[0] for _, p in read] == [k * 1e-6 for k in range(12)]
    offset = 0
    for block in blocks:
        assert block.get("offset_in_file", 0) == offset and block["format"] == 2
        data = mdem._thread_bytes(1, offset, block["size"])
        body = zlib.decompress(data)
        assert block["uncompressed_size"] == len(body) <= 120 + 60
        first = mm.decode(body, "ProtoBlockOfTimePoints", mm.TABLES)["time_points"][0]
        assert block.get("start_time", 0.0) == first.get("time", 0.0)
        offset += block["size"]
    assert sum(b["size"] for b in blocks) == struct.unpack_from(
        "<Q", raw, mm.HEADER + mm.THREAD_HEADER + 64)[0]
    monkeypatch.setattr(mm, "BLOCKS_PER_THREAD", 0)      # each thread needs one
    with pytest.raises(ValueError) as error:
        write_mdem(tmp_path / "big.mdem", storage, points)
    assert str(error.value) == "too much data for a .mdem file's 118 blocks"


def test_the_defaults_of_fields_a_file_leaves_out():
    """proto3 leaves zeros and empty strings out: a field that is absent is 0 or ""."""
    info = {"particles": [{"id": 0, "type": 1,
                           "encoded_properties": struct.pack("<2d", 1e-3, 1e-3)},
                          {"id": 1, "encoded_properties": b""}],
            "real_geometry": [{"base_geometry": {"name": "a lid"}}, {}],
            "real_geometry_v0": [{"tdVal": [{}]}]}
    materials = {"compound": [{"constProperty": [{"value": 2.0}, {"propertyType": 7}],
                               "property": [{"correlation": []}]}],
                 "interaction": [{"compoundKey1": "b"}, {"property": [{}]}]}
    scene = scene_of(fake({"materials_database": materials}, info))
    obj = scene.objects[0]
    assert (obj.compound, obj.active, obj.time, obj.coordinates) == ("", (0.0, 0.0), 0.0,
                                                                     (0.0, 0.0, 0.0))
    assert sorted(scene.objects) == [0]
    assert list(scene.compounds) == [""]
    props = scene.compounds[""]
    assert props[7] == 0.0 and math.isnan(props[0])     # the correlation wins
    assert list(scene.interactions) == [("", "b"), ("", "")]
    assert list(scene.interactions[("", "")]) == [0]
    assert scene.geometries == [["a_lid", "", "0 0", []], ["", "", "0 0", []], ["", "", "", []]]
    assert scene.unmapped == ["geometry : the motion of an old-format geometry is not mapped "
                              "(the wall is static)"]

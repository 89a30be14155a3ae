"""Scene files (SPEC 4) on small constructed scenes: each key's default and allowed range
as docs/scene.md gives them, checked at the bounds (the bound itself allowed or refused,
the nearest double beyond it), each bad input's message naming the file, the key, the
value and what is allowed, and the built system's values from their definitions (mass =
density 4/3 pi r^3, a profile's times, the offset added to every particle).

Fast: no simulation runs (the loaded scene is checked, not stepped); tests/test_scene.py
and tests/test_bad_files.py go through the command line."""
import copy
import math

import h5py
import numpy as np
import pytest
import tomli_w

from bondem.errors import InputError
from bondem.physics.contact_hertz_musen import MUSEN_VERSION
from bondem.scene import (DENSITY_RANGE, _guess_key, load_scene, parse_override,
                          read_toml)

# four particles, none touching: two materials, radii off any special value
PARTICLES = """x,y,z,radius,material
0.001,0.002,0.003,0.001,glass
0.0031,0.002,0.003,0.0012,glass
0.001,0.0043,0.003,0.0009,steel
0.001,0.002,0.0052,0.0011,glass
"""
BASE = {
    "simulation": {"end_time": 1e-3},
    "materials": {"glass": {"density": 2500.0, "young_modulus": 1e8, "poisson_ratio": 0.3},
                  "steel": {"density": 7800.0, "young_modulus": 2e8, "poisson_ratio": 0.28}},
    "particles": {"file": "p.csv"},
}
BINDER = {"binder": {"young_modulus": 5e7, "poisson_ratio": 0.25}}


def write(folder, data=None, particles=PARTICLES, bonds=None, text=None, name="s.toml"):
    """The scene file ``name`` in folder (from ``data``, or ``text`` as given)."""
    (folder / "p.csv").write_text(particles)
    if bonds is not None:
        (folder / "b.csv").write_text(bonds)
    path = folder / name
    path.write_text(text if text is not None else tomli_w.dumps(data or BASE))
    return path


def scene(folder, edit=None, **kwargs):
    """The scene loaded from BASE changed by ``edit`` {dotted key: value (None: removed)}."""
    data = copy.deepcopy(BASE)
    for key, value in (edit or {}).items():
        *parents, last = key.split(".")
        node = data
        for part in parents:
            node = node.setdefault(part, {})
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    return load_scene(write(folder, data, **kwargs))


def refused(folder, edit=None, **kwargs):
    """The InputError's message of a scene that must not load."""
    with pytest.raises(InputError) as error:
        scene(folder, edit, **kwargs)
    return str(error.value)


def test_a_scene_builds_its_system_and_options(tmp_path):
    s = scene(tmp_path, {"simulation.gravity": [0.5, -9.81, 0]})
    radius = np.array([1e-3, 1.2e-3, 0.9e-3, 1.1e-3])
    np.testing.assert_array_equal(s.model.radius, radius)
    np.testing.assert_allclose(s.model.mass, np.array([2500, 2500, 7800, 2500]) * 4 / 3
                               * np.pi * radius ** 3, rtol=1e-14)
    assert s.model.material.tolist() == [0, 0, 1, 0]
    assert [m.name for m in s.model.materials] == ["glass", "steel"]
    assert s.model.materials[1].young_modulus == 2e8
    assert s.model.gravity.tolist() == [0.5, -9.81, 0.0] and s.model.damping == 0.0
    assert s.model.n_bonds == 0 and not any(s.model.periodic)
    assert s.end_time == 1e-3 and s.save_every == 1e-5          # end_time / 100
    assert s.backend == "cpu" and s.checkpoint_minutes == 10.0
    assert s.stop_broken_bonds is None and s.warnings == []
    assert s.path == tmp_path / "s.toml" and s.text == tomli_w.dumps(
        {**BASE, "simulation": {"end_time": 1e-3, "gravity": [0.5, -9.81, 0]}})
    options = s.simulation_options
    assert {k: options[k] for k in ("time_step", "safety_factor", "force_time_step",
                                    "musen_compat", "musen_version")} == {
        "time_step": "auto", "safety_factor": 0.2, "force_time_step": False,
        "musen_compat": False, "musen_version": MUSEN_VERSION}
    contact = options["contact"]
    assert (contact.model, contact.bonded_pairs, contact.rolling_resistance) == (
        "hertz_mindlin", False, True)
    assert "walls" not in options and "backend" not in options and "flow" not in options
    assert s.data["simulation"] == {
        "end_time": 1e-3, "time_step": "auto", "save_every": 1e-5,
        "gravity": [0.5, -9.81, 0.0], "backend": "cpu", "safety_factor": 0.2,
        "force_time_step": False, "musen_compat": False, "musen_version": MUSEN_VERSION,
        "damping": 0.0, "periodic": [False, False, False], "box_low": None,
        "box_high": None, "contact_model": "hertz_mindlin", "bonded_contacts": False,
        "rolling_resistance": True, "checkpoint_minutes": 10.0, "max_steps": 1e9,
        "stop_broken_bonds": None}
    assert s.data["particles"] == {"file": "p.csv", "generator": None,
                                   "velocity": [0.0] * 3, "angular_velocity": [0.0] * 3,
                                   "offset": [0.0] * 3}
    assert s.data["walls"] == [] and s.data["bond_materials"] == {}
    for key, value in BASE["materials"]["steel"].items():     # the given values kept
        assert s.data["materials"]["steel"][key] == value
    assert s.data["materials"]["glass"]["density"] == 2500.0


def test_options_given_reach_the_simulation(tmp_path):
    s = scene(tmp_path, {"simulation.contact_model": "none", "simulation.backend": "gpu",
                         "simulation.save_every": 2e-5, "simulation.stop_broken_bonds": 0,
                         "simulation.checkpoint_minutes": 0.0, "simulation.damping": 0.05,
                         "simulation.safety_factor": 0.35, "simulation.musen_compat": True})
    assert "contact" not in s.simulation_options
    assert s.simulation_options["backend"] == "gpu" and s.backend == "gpu"
    assert s.simulation_options["safety_factor"] == 0.35
    assert s.simulation_options["musen_compat"] is True
    assert s.save_every == 2e-5 and s.stop_broken_bonds == 0 and s.checkpoint_minutes == 0.0
    assert s.model.damping == 0.05
    s = scene(tmp_path, {"simulation.contact_model": "linear",
                         "simulation.bonded_contacts": True,
                         "simulation.rolling_resistance": False})
    contact = s.simulation_options["contact"]
    assert (contact.model, contact.bonded_pairs, contact.rolling_resistance) == (
        "linear", True, False)


# key, a value at or inside the bound that loads, a value beyond it and the message's range
BOUNDS = [
    ("simulation.safety_factor", 1.0, 0.0, "(0.0, 1.0]"),
    ("simulation.safety_factor", 1e-3, 1.0000000000000002, "(0.0, 1.0]"),
    ("simulation.damping", 0.0, -1e-300, "[0.0, 1.0)"),
    ("simulation.damping", 0.9999999999999999, 1.0, "[0.0, 1.0)"),
    ("simulation.checkpoint_minutes", 0.0, -5e-324, "[0.0, inf)"),
    ("simulation.max_steps", math.inf, 0.0, "(0.0, inf]"),
    ("simulation.end_time", 1e-3, 0.0, "(0.0, inf)"),
    ("simulation.end_time", 1e-3, math.inf, "(0.0, inf)"),
]


@pytest.mark.parametrize("key, good, bad, allowed", BOUNDS)
def test_numbers_are_checked_at_their_bounds(tmp_path, key, good, bad, allowed):
    assert scene(tmp_path, {key: good}).data["simulation"][key.split(".")[1]] == good
    assert refused(tmp_path, {key: bad}) == (
        f"{tmp_path / 's.toml'}: {key}: value {float(bad)!r} is outside the allowed range "
        f"{allowed}")


def test_each_kind_of_value_is_refused_with_what_it_must_be(tmp_path):
    where = f"{tmp_path / 's.toml'}: simulation."
    cases = [
        ("safety_factor", True, "value True: expected a number in (0.0, 1.0]"),
        ("safety_factor", "0.2", "value '0.2': expected a number in (0.0, 1.0]"),
        ("safety_factor", math.nan, "value nan is outside the allowed range (0.0, 1.0]"),
        ("damping", 10 ** 400, "value of 401 digits is outside the allowed range [0.0, 1.0)"),
        ("stop_broken_bonds", 1.5, "value 1.5: expected an integer >= 0"),
        ("stop_broken_bonds", -1, "value -1: expected an integer >= 0"),
        ("stop_broken_bonds", True, "value True: expected an integer >= 0"),
        ("musen_compat", 1, "value 1: expected true or false"),
        ("backend", 3, "value 3: expected a string"),
        ("backend", "tpu", "value 'tpu'; allowed: 'cpu', 'gpu'"),
        ("time_step", "fast", 'value \'fast\': expected "auto" or a number of seconds > 0'),
        ("time_step", True, 'value True: expected "auto" or a number of seconds > 0'),
        ("time_step", 0.0, "value 0.0 is outside the allowed range (0.0, inf)"),
        ("time_step", -1, "value -1.0 is outside the allowed range (0.0, inf)"),
        ("gravity", [0.0, -9.81], "value [0.0, -9.81]: expected three finite numbers [x, y, z]"),
        ("gravity", [0.0, math.inf, 0.0],
         "value [0.0, inf, 0.0]: expected three finite numbers [x, y, z]"),
        ("gravity", [0, True, 0], "value [0, True, 0]: expected three finite numbers [x, y, z]"),
        ("gravity", "down", "value 'down': expected three finite numbers [x, y, z]"),
        ("periodic", [True, 1, False],
         "value [True, 1, False]: expected true/false or three of them [x, y, z]"),
        ("periodic", [True, False],
         "value [True, False]: expected true/false or three of them [x, y, z]"),
        ("periodic", "x", "value 'x': expected true/false or three of them [x, y, z]"),
        ("end_tme", 1.0, "unknown key 'end_tme'; did you mean 'end_time'? allowed: "
                         "end_time, time_step, save_every, gravity, backend, safety_factor, "
                         "force_time_step, musen_compat, musen_version, damping, periodic, "
                         "box_low, box_high, contact_model, bonded_contacts, "
                         "rolling_resistance, checkpoint_minutes, max_steps, "
                         "stop_broken_bonds"),
    ]
    for key, value, message in cases:
        text = refused(tmp_path, {f"simulation.{key}": value})
        assert text == where + key + ": " + message, key
    assert refused(tmp_path, {"simulation.end_time": None}) == \
        where + "end_time: missing required key"
    assert scene(tmp_path, {"simulation.stop_broken_bonds": 0}).stop_broken_bonds == 0
    assert scene(tmp_path, {"simulation.gravity": [1, 0, 0]}).model.gravity.dtype == float
    assert scene(tmp_path, {"simulation.time_step": 1e-9}).simulation_options[
        "time_step"] == 1e-9


def test_tables_are_required_and_known(tmp_path):
    file = tmp_path / "s.toml"
    for name in ("simulation", "materials", "particles"):
        data = {k: v for k, v in BASE.items() if k != name}
        with pytest.raises(InputError) as error:
            load_scene(write(tmp_path, data))
        assert str(error.value) == f"{file}: {name}: missing required table"
    with pytest.raises(InputError) as error:
        load_scene(write(tmp_path, {**BASE, "simulatoin": {}}))
    assert str(error.value).startswith(f"{file}: simulatoin: unknown key 'simulatoin'; did "
                                       "you mean 'simulation'? allowed: simulation, materials,")
    with pytest.raises(InputError) as error:
        load_scene(write(tmp_path, text="simulation = 3\n[materials]\n[particles]\n"))
    assert str(error.value) == f"{file}: simulation: expected a table, got 3"
    assert refused(tmp_path, {"materials": {}}) == \
        f"{file}: materials: at least one particle material is needed"
    with pytest.raises(InputError) as error:
        load_scene(write(tmp_path, {**BASE, "materials": 2}))
    assert str(error.value) == f"{file}: materials: expected tables [materials.NAME]"
    assert refused(tmp_path, {"materials.glass.density": None}) == \
        f"{file}: materials.glass.density: missing required key"
    assert refused(tmp_path, {"walls": {"type": "plane"}}) == \
        f"{file}: walls: expected an array of tables [[walls]]"


def test_scene_file_errors_name_the_file(tmp_path):
    with pytest.raises(InputError) as error:
        load_scene(tmp_path / "missing.toml")
    assert str(error.value) == (f"{tmp_path / 'missing.toml'}: cannot read the scene file "
                                "(No such file or directory)")
    bad = write(tmp_path, text="[simulation\n")
    with pytest.raises(InputError) as error:
        load_scene(bad)
    assert str(error.value).startswith(f"{bad}: not valid TOML: ")
    with pytest.raises(InputError) as error:
        read_toml(tmp_path / "missing.toml", what="study file")
    assert "cannot read the study file" in str(error.value)


def test_a_walls_own_friction_is_true_or_false(tmp_path):
    wall = {"type": "plane", "point": [0, 0, -0.001], "normal": [0, 0, 1],
            "material": "steel"}
    assert load_scene(write(tmp_path, {**BASE, "walls": [wall]})).simulation_options[
        "walls"][0].own_friction is False
    path = write(tmp_path, {**BASE, "walls": [{**wall, "own_friction": 1}]})
    with pytest.raises(InputError) as error:
        load_scene(path)
    assert error.value.key == "walls.0.own_friction"
    assert str(error.value) == f"{path}: walls.0.own_friction: value 1: expected true or false"


def test_overrides_reach_every_kind_of_table(tmp_path):
    path = write(tmp_path, {**BASE, "walls": [{"type": "plane", "point": [0, 0, -0.001],
                                              "normal": [0, 0, 1], "material": "steel"}]})
    s = load_scene(path, {"simulation.end_time": 2e-3, "walls.0.velocity": [0, 0, 0.01],
                          "materials.steel.density": 7000.0, "fluid.density": 1.2})
    assert s.end_time == 2e-3 and s.model.materials[1].density == 7000.0
    assert s.data["walls"][0]["velocity"] == [0.0, 0.0, 0.01]
    assert "density = 7000.0" in s.text and "[fluid]" in s.text
    assert path.read_text() == tomli_w.dumps({**BASE, "walls": [{
        "type": "plane", "point": [0, 0, -0.001], "normal": [0, 0, 1], "material": "steel"}]})
    data, text = read_toml(path, {"walls.0": {"type": "plane"}})
    assert data["walls"][0] == {"type": "plane"} and "point" not in text
    for key, message in (
            ("walls.1.velocity", "walls.1: index '1' must be in [0, 0]"),
            ("walls.x.velocity", "walls.x: index 'x' must be in [0, 0]"),
            ("walls.-1", "walls.-1: index '-1' must be in [0, 0]"),
            ("simulation.end_time.x",
             "simulation.end_time.x: override 'simulation.end_time.x': parent is not a table"),
            ("simulation.end_time.x.y", "simulation.end_time.x.y: override "
                                        "'simulation.end_time.x.y': simulation.end_time.x "
                                        "is not a table")):
        with pytest.raises(InputError) as error:
            load_scene(path, {key: 1.0})
        assert str(error.value) == f"{path}: {message}", key
    assert parse_override(" simulation.end_time = 1e-3 ") == ("simulation.end_time", 1e-3)
    assert parse_override("simulation.backend=gpu") == ("simulation.backend", "gpu")
    assert parse_override("walls.0.velocity=[0, 0, 1]") == ("walls.0.velocity", [0, 0, 1])
    assert parse_override("a=b=c") == ("a", "b=c")
    with pytest.raises(InputError) as error:
        parse_override("end_time")
    assert str(error.value) == "--set: 'end_time' is not KEY=VALUE"
    with pytest.raises(InputError) as error:
        parse_override(" =3", file="study.toml")
    assert str(error.value) == ("study.toml: ' =3': empty key before '='; give KEY=VALUE, "
                                "e.g. simulation.end_time=1e-3")


def test_densities_outside_solids_are_warned_about(tmp_path):
    low, high = DENSITY_RANGE
    assert (low, high) == (10.0, 25000.0)
    for density in (low, high):
        assert scene(tmp_path, {"materials.glass.density": density}).warnings == []
    for density, text in ((2.5, "2.5"), (2.5e6, "2.5e+06"), (np.nextafter(high, 1e9), "2.5e+04")):
        warnings = scene(tmp_path, {"materials.glass.density": float(density)}).warnings
        assert warnings == [
            f"{tmp_path / 's.toml'}: materials.glass.density: {text} kg/m^3 is outside the "
            "densities of solids (10 to 25000 kg/m^3): g/cm^3 (x 1000) or another unit "
            "instead of kg/m^3?"]


def test_periodic_axes_need_a_box_that_holds_the_particles(tmp_path):
    file = tmp_path / "s.toml"
    assert refused(tmp_path, {"simulation.periodic": [False, True, False],
                              "simulation.box_low": [-1, -1, -1]}) == \
        f"{file}: simulation.periodic: periodic axes need simulation.box_low and " \
        "simulation.box_high"
    s = scene(tmp_path, {"simulation.periodic": True, "simulation.box_low": [-0.02, -0.01, 0],
                         "simulation.box_high": [0.013, 0.02, 0.03]})
    assert s.model.periodic.tolist() == [True] * 3
    np.testing.assert_allclose(s.model.box_length, [0.033, 0.03, 0.03], rtol=1e-14)
    # cut-off 2 r_max + skin, skin a fifth of the mean radius: 2.4e-3 + 0.21e-3 m
    cutoff = 2 * 1.2e-3 + 0.2 * 1.05e-3
    text = refused(tmp_path, {"simulation.periodic": [False, False, True],
                              "simulation.box_low": [-1, -1, 0.0009],
                              "simulation.box_high": [1, 1, 0.0009 + 2 * cutoff * 0.999]})
    assert text == (f"{file}: simulation.box_high: the periodic box is "
                    f"{2 * cutoff * 0.999:.4g} m long in z, less than twice the contact "
                    f"cut-off 2 r_max + skin = {cutoff:.4g} m; allowed box_high - box_low >= "
                    f"{2 * cutoff:.4g} m")
    s = scene(tmp_path, {"simulation.periodic": [False, False, True],
                         "simulation.box_low": [-1, -1, 0.0009],
                         "simulation.box_high": [1, 1, 0.0009 + 2 * cutoff * 1.001]})
    assert s.model.periodic.tolist() == [False, False, True]
    assert scene(tmp_path, {"simulation.contact_model": "none",
                            "simulation.periodic": [False, False, True],
                            "simulation.box_low": [-1, -1, 0.0009],
                            "simulation.box_high": [1, 1, 0.006]}).model.box_length[2] == \
        pytest.approx(0.0051, rel=1e-12)
    text = refused(tmp_path, {"simulation.box_low": [0.0, 0.0021, 0.0],
                              "simulation.box_high": [1, 1, 1]})
    assert text == (f"{file}: simulation.box_low: 3 of 4 particles lie outside the domain at "
                    "t = 0 (particle 0 at [0.001, 0.002, 0.003] m); allowed: box_low <= x <= "
                    "box_high")
    text = refused(tmp_path, {"simulation.box_high": [1, 1, 0.005]})
    assert text == (f"{file}: simulation.box_high: 1 of 4 particles lie outside the domain "
                    "at t = 0 (particle 3 at [0.001, 0.002, 0.0052] m); allowed: box_low <= "
                    "x <= box_high")
    assert scene(tmp_path, {"simulation.box_low": [0.001, 0.002, 0.003],
                            "simulation.box_high": [0.0031, 0.0043, 0.0052]}).model.n_particles \
        == 4
    text = refused(tmp_path, {"simulation.periodic": [True, False, False],
                              "simulation.box_low": [0.05, -1, -1],
                              "simulation.box_high": [-0.05, 1, 1]})
    assert text.startswith(f"{file}: simulation.box_high: box_low/box_high")


def test_the_initial_velocities_must_be_finite_and_resolvable(tmp_path):
    file = tmp_path / "s.toml"
    assert refused(tmp_path, {"particles.velocity": [1e200, 0, 0]}) == (
        f"{file}: particles.velocity: the initial kinetic energy is not finite: velocities "
        "out of any physical range")
    # a step of 2^-20 s and the smallest radius 0.0009 m: at most 0.0009 * 2^20 m/s
    step, r_min = 2.0 ** -20, 0.0009
    edit = {"simulation.time_step": step, "simulation.force_time_step": True,
            "simulation.contact_model": "none", "simulation.end_time": 1e-3}
    limit = r_min / step
    assert scene(tmp_path, {**edit, "particles.velocity": [0, -limit, 0]}).state.velocity[
        0, 1] == -limit
    text = refused(tmp_path, {**edit, "particles.velocity": [0, -2 * limit, 0]})
    assert text == (f"{file}: particles.velocity: a particle at {2 * limit:.3g} m/s moves 2 "
                    f"radii per time step ({step:.4g} s); allowed up to {limit:.4g} m/s")
    g = r_min / step ** 2
    assert scene(tmp_path, {**edit, "simulation.gravity": [0, 0, -g]}).model.gravity[2] == -g
    text = refused(tmp_path, {**edit, "simulation.gravity": [3 * g, 0, 0]})
    assert text == (f"{file}: simulation.gravity: value {3 * g:.3g} m/s^2 moves a particle 3 "
                    f"radii in one time step ({step:.4g} s); allowed up to {g:.4g} m/s^2")


PLANE = {"type": "plane", "point": [0.0, 0.0, -0.0005], "normal": [0.0, 0.0, 2.0],
         "material": "steel"}


def walls(folder, *tables, edit=None):
    return scene(folder, {"walls": [dict(t) if isinstance(t, dict) else t for t in tables],
                          **(edit or {})})


def test_plane_walls_and_their_motions(tmp_path):
    s = walls(tmp_path, {**PLANE, "velocity": [0.0, 0.0, 0.01]},
              {**PLANE, "point": [0, 0, 0.01], "normal": [0, 0, -1],
               "velocity_profile": [[0.0, 0, 0, 0], [1e-5, 0, 0, -0.02]]},
              {**PLANE, "point": [0, 0.01, 0], "normal": [0, -1, 0], "material": "glass",
               "servo": {"target_stress": 2e5, "area": 1e-4, "gain": 1e-5,
                         "max_velocity": 0.05, "integral_time": 1e-6}})
    first, profile, servo = s.simulation_options["walls"]
    np.testing.assert_array_equal(first.normal, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(first.velocity, [0.0, 0.0, 0.01])
    assert first.material.name == "steel" and servo.material.name == "glass"
    np.testing.assert_allclose(profile.velocity_at(5e-6), [0, 0, -0.01], rtol=1e-12)
    np.testing.assert_array_equal(profile.velocity_at(2e-5), [0, 0, -0.02])
    motion = servo.motion
    assert (motion.target_stress, motion.area, motion.target_force) == (2e5, 1e-4, None)
    assert (motion.gain, motion.max_velocity) == (1e-5, 0.05)
    assert motion.tolerance == 0.01 and motion.integral_time == 1e-6
    assert s.data["walls"][2]["servo"] == {"target_stress": 2e5, "area": 1e-4, "gain": 1e-5,
                                           "max_velocity": 0.05, "tolerance": 0.01,
                                           "integral_time": 1e-6}
    assert [w["index"] for w in s.data["walls"]] == [0, 1, 2]
    assert s.data["walls"][0]["velocity_profile"] is None
    assert s.data["walls"][1]["velocity_profile"] == [[0.0] * 4, [1e-5, 0.0, 0.0, -0.02]]


def test_bad_walls_are_named_by_their_index(tmp_path):
    file = tmp_path / "s.toml"
    servo = {"target_force": 1.0, "gain": 1e-5, "max_velocity": 0.05}
    cases = [
        ([3], "walls.0: expected a table"),
        ([{**PLANE, "type": "sphere"}], "walls.0.type: value 'sphere'; allowed: 'plane', 'mesh'"),
        ([{**PLANE, "material": "iron"}],
         "walls.0.material: value 'iron' is not defined; defined materials: glass, steel"),
        ([{**PLANE, "normal": [0, 0, 0]}],
         "walls.0.normal: value [0, 0, 0]: the normal must be a non-zero vector"),
        ([PLANE, {**PLANE, "velocity": [0, 0, 1e-3], "servo": servo}],
         "walls.1.servo: give one of velocity, velocity_profile, servo; got velocity, servo"),
        ([{**PLANE, "velocity_profile": [[0.0, 0, 0, 0]], "servo": servo}],
         "walls.0.servo: give one of velocity, velocity_profile, servo; got "
         "velocity_profile, servo"),
        ([{**PLANE, "velocity": [1e-3, 0, 0], "velocity_profile": [[0.0, 0, 0, 0]]}],
         "walls.0.velocity_profile: give one of velocity, velocity_profile, servo; got "
         "velocity, velocity_profile"),
        ([{**PLANE, "servo": {**servo, "target_stress": 5.0, "area": 1.0}}],
         "walls.0.servo.target_force: give exactly one of target_force (N) or target_stress "
         "(Pa)"),
        ([{**PLANE, "servo": {"gain": 1e-5, "max_velocity": 0.05}}],
         "walls.0.servo.target_force: give exactly one of target_force (N) or target_stress "
         "(Pa)"),
        ([{**PLANE, "servo": {"target_stress": 5.0, "gain": 1e-5, "max_velocity": 0.05}}],
         "walls.0.servo.area: target_stress needs the area (m^2) it acts on"),
        ([{**PLANE, "servo": {**servo, "tolerance": 0.0}}],
         "walls.0.servo.tolerance: value 0.0 is outside the allowed range (0.0, 1.0]"),
        ([{**PLANE, "servo": 2}], "walls.0.servo: value 2: expected a table"),
        ([{**PLANE, "velocity_profile": []}],
         "walls.0.velocity_profile: value []: expected rows [time (s), vx, vy, vz (m/s)]"),
        ([{**PLANE, "velocity_profile": [[0.0, 0, 0]]}],
         "walls.0.velocity_profile: value [[0.0, 0, 0]]: expected rows [time (s), vx, vy, "
         "vz (m/s)]"),
        ([{**PLANE, "velocity_profile": [[0.0, 0, 0, math.nan]]}],
         "walls.0.velocity_profile: value [[0.0, 0, 0, nan]]: expected rows [time (s), vx, "
         "vy, vz (m/s)]"),
        ([{**PLANE, "velocity_profile": [[1e-6, 0, 0, 0]]}],
         "walls.0.velocity_profile: times [1e-06]: the first must be 0 s and none may "
         "decrease"),
        ([{**PLANE, "velocity_profile": [[0, 0, 0, 0], [2e-6, 0, 0, 0], [1e-6, 0, 0, 0]]}],
         "walls.0.velocity_profile: times [0.0, 2e-06, 1e-06]: the first must be 0 s and none "
         "may decrease"),
        ([{"type": "mesh", "file": "no.stl", "material": "steel"}],
         "walls.0.file: value 'no.stl': no such file"),
        ([{**PLANE, "file": "no.stl"}], "walls.0.file: unknown key 'file'; allowed: type, "
                                        "point, normal, material, velocity, velocity_profile, "
                                        "servo, own_friction"),
    ]
    for tables, message in cases:
        with pytest.raises(InputError) as error:
            walls(tmp_path, *tables)
        assert str(error.value) == f"{file}: {message}", message
    # a profile may hold a velocity for a while: equal times are a jump
    s = walls(tmp_path, {**PLANE, "velocity_profile": [[0, 0, 0, 0], [1e-6, 0, 0, 0],
                                                       [1e-6, 0, 0, 1e-3]]})
    assert len(s.simulation_options["walls"]) == 1


def test_a_mesh_wall_reads_its_file_scaled(tmp_path):
    import trimesh
    box = trimesh.creation.box(extents=(10.0, 10.0, 1.0))
    box.apply_translation((0.0, 0.0, 20.0))     # mm, above the particles
    box.export(tmp_path / "lid.stl")
    s = walls(tmp_path, {"type": "mesh", "file": "lid.stl", "material": "glass",
                         "scale": 1e-3, "angular_velocity": [0.0, 0.0, 2.0],
                         "rotation_center": [0.0, 0.0, 0.02]})
    wall = s.simulation_options["walls"][0]
    np.testing.assert_allclose(wall.vertices.min(axis=0), [-0.005, -0.005, 0.0195], rtol=1e-12)
    assert wall.angular_velocity.tolist() == [0.0, 0.0, 2.0]
    assert s.data["walls"][0]["file"] == str((tmp_path / "lid.stl").resolve())
    (tmp_path / "bad.stl").write_text("solid nothing\nendsolid\n")
    with pytest.raises(InputError) as error:
        walls(tmp_path, {"type": "mesh", "file": "bad.stl", "material": "glass"})
    assert str(error.value).startswith(f"{tmp_path / 's.toml'}: walls.0.file: cannot read the "
                                       "mesh '")
    # a wall that turns 2 rad/s at 5e-3 * sqrt(2) m from its axis moves at most 1.4e-2 m/s
    step = 2.0 ** -20
    edit = {"simulation.time_step": step, "simulation.force_time_step": True,
            "simulation.end_time": 1e-3}
    too_fast = {"type": "mesh", "file": "lid.stl", "material": "glass", "scale": 1e-3,
                "angular_velocity": [0.0, 0.0, 0.0009 / step / 0.005 * 1.01],
                "rotation_center": [0.0, 0.0, 0.02]}
    with pytest.raises(InputError) as error:
        walls(tmp_path, too_fast, edit=edit)
    assert str(error.value) == (f"{tmp_path / 's.toml'}: walls.0.angular_velocity: the wall "
                                f"moves 1.01 particle radii per time step ({step:.4g} s); "
                                "allowed up to one")


def test_a_sliding_wall_may_move_up_to_one_radius_a_step(tmp_path):
    step, r_min = 2.0 ** -20, 0.0009
    edit = {"simulation.time_step": step, "simulation.force_time_step": True,
            "simulation.end_time": 1e-3}
    assert walls(tmp_path, {**PLANE, "velocity": [0, 0, r_min / step]}, edit=edit)
    with pytest.raises(InputError) as error:
        walls(tmp_path, PLANE, {**PLANE, "velocity_profile": [[0.0, 0, 0, 0],
                                                              [1e-6, 2.5 * r_min / step, 0, 0]]},
              edit=edit)
    assert str(error.value) == (f"{tmp_path / 's.toml'}: walls.1.velocity: the wall moves 2.5 "
                                f"particle radii per time step ({step:.4g} s); allowed up to "
                                "one")


def test_time_steps_are_checked_against_the_stable_one_and_the_run(tmp_path):
    from bondem.timestep import stable_time_step, time_scales
    file = tmp_path / "s.toml"
    s = scene(tmp_path)
    critical = min(time_scales(s.model, False).values())
    auto, cause = stable_time_step(s.model, 0.2, False)
    assert scene(tmp_path, {"simulation.time_step": critical}).simulation_options[
        "time_step"] == critical
    beyond = float(np.nextafter(critical, 1.0))
    assert refused(tmp_path, {"simulation.time_step": beyond}) == (
        f"{file}: simulation.time_step: value {beyond!r} s exceeds the stable limit "
        f"{critical:.4g} s; allowed (0, {critical:.4g}] or set force_time_step = true")
    assert scene(tmp_path, {"simulation.time_step": 2 * critical,
                            "simulation.force_time_step": True})
    assert refused(tmp_path, {"simulation.end_time": auto * 0.99}) == (
        f"{file}: materials: the stable time step {auto:.4g} s (limited by {cause}) is longer "
        f"than the whole run (simulation.end_time = {auto * 0.99:.4g} s): a density, modulus "
        "or particle size is out of range, or end_time too short")
    # a run of fewer than 100 steps saves every step; save_every given is checked
    s = scene(tmp_path, {"simulation.end_time": auto * 1.5})
    assert s.save_every == auto and s.data["simulation"]["save_every"] == auto
    assert scene(tmp_path, {"simulation.end_time": auto * 300}).save_every == auto * 3
    assert scene(tmp_path, {"simulation.save_every": auto}).save_every == auto
    short = auto * 0.999
    assert refused(tmp_path, {"simulation.save_every": short}) == (
        f"{file}: simulation.save_every: value {short!r} s is shorter than the time step "
        f"{auto:.4g} s; allowed [{auto:.4g}, end_time]")
    steps = 1e-3 / auto
    limit = float(math.floor(steps))
    assert refused(tmp_path, {"simulation.max_steps": limit}) == (
        f"{file}: simulation.end_time: value 0.001 s is {steps:.3g} steps of {auto:.4g} s "
        f"(the stable step, limited by {cause}), more than simulation.max_steps = "
        f"{limit:.3g}; shorten the run or raise max_steps")
    assert scene(tmp_path, {"simulation.max_steps": float(math.ceil(steps))})
    assert refused(tmp_path, {"simulation.max_steps": 10.0, "simulation.time_step": 1e-7}) \
        == (f"{file}: simulation.end_time: value 0.001 s is 1e+04 steps of 1e-07 s, more "
            "than simulation.max_steps = 10; shorten the run or raise max_steps")


def test_a_bond_limited_step_blames_the_bonds(tmp_path):
    file = tmp_path / "s.toml"
    stiff = {"binder": {"young_modulus": 1e12, "poisson_ratio": 0.25}}
    bonds = "i,j,diameter,material\n0,1,0.0005,binder\n"
    text = refused(tmp_path, {"bond_materials": stiff, "bonds": {"file": "b.csv"},
                              "simulation.end_time": 1e-30}, bonds=bonds)
    assert text.startswith(f"{file}: bonds: the stable time step ")
    assert "(limited by bond" in text
    text = refused(tmp_path, {"simulation.end_time": 1e-30})
    assert text.startswith(f"{file}: materials: the stable time step ")


def test_particles_from_a_file_with_offset_and_velocity(tmp_path):
    rows = PARTICLES.splitlines()
    table = "\n".join([rows[0] + ",vx,vy,vz,wx,wy,wz,fixed"]
                      + [r + f",{k},0,-1,0,{2 * k},0,{k % 2}" for k, r in enumerate(rows[1:])])
    s = scene(tmp_path, {"particles.offset": [0.01, -0.02, 0.0],
                         "particles.velocity": [0.0, 0.5, 0.0],
                         "particles.angular_velocity": [3.0, 0.0, 0.0]}, particles=table)
    np.testing.assert_allclose(s.state.position[1], [0.0131, -0.018, 0.003], rtol=1e-14)
    np.testing.assert_array_equal(s.state.velocity[:, 0], [0, 1, 2, 3])
    np.testing.assert_array_equal(s.state.velocity[:, 1], [0.5] * 4)
    np.testing.assert_array_equal(s.state.angular_velocity[2], [3.0, 4.0, 0.0])
    assert s.model.fixed.tolist() == [False, True, False, True]
    file = tmp_path / "s.toml"
    assert refused(tmp_path, {"particles.generator": {"shape": "box"}}) == (
        f"{file}: particles: give exactly one of particles.file or particles.generator")
    assert refused(tmp_path, {"particles.file": None}) == (
        f"{file}: particles: give exactly one of particles.file or particles.generator")
    assert refused(tmp_path, particles=PARTICLES.replace("steel", "iron")) == (
        f"{file}: particles.material: p.csv line 4: material 'iron' is not defined; "
        "defined materials: glass, steel")
    assert refused(tmp_path, particles=PARTICLES + "0.1,0.1,0.1,-1,glass\n") == (
        f"{file}: particles.file: {tmp_path / 'p.csv'}: radius: line 6: '-1'; allowed: a "
        "finite number > 0")
    text = refused(tmp_path, {"particles.offset": [0.0, 0.0, 9000.0]})
    far = 9000.0052
    assert text == (f"{file}: particles.offset: particles lie {far:.3g} m from the origin, "
                    f"more than 1e+07 times the smallest radius (0.0009 m): double precision "
                    "cannot resolve their contacts and bonds there; move the scene near the "
                    "origin")
    assert scene(tmp_path, {"particles.offset": [0.0, 0.0, 8990.0]}).model.n_particles == 4
    far = PARTICLES.replace("0.0052", "9200.0")
    assert refused(tmp_path, particles=far).startswith(
        f"{file}: particles.file: particles lie 9.2e+03 m from the origin")


def test_a_radius_a_million_times_below_the_median_is_refused(tmp_path):
    median = 1.05e-3    # of 1e-3, 1.1e-3, 1.2e-3 and the tiny one
    rows = PARTICLES.replace("0.0009,steel", f"{median / 1e6 * 0.99!r},steel")
    text = refused(tmp_path, particles=rows)
    assert text == (f"{tmp_path / 's.toml'}: particles.file: p.csv line 4: radius "
                    f"{median / 1e6 * 0.99!r} m is less than 1/1e+06 of the median radius "
                    f"{median:.4g} m; allowed [{median / 1e6:.3g}, ...] m")


def test_coincident_and_overlapping_particles(tmp_path):
    file = tmp_path / "s.toml"
    repeated = PARTICLES + "0.0031,0.002,0.003,0.0012,glass\n"
    assert refused(tmp_path, particles=repeated) == (
        f"{file}: particles.file: p.csv line 3 and p.csv line 6: particles 1 and 4 are at the "
        "same place [0.0031, 0.002, 0.003] m (a repeated row?); 1 such pair(s)")
    # particle 4 overlaps particle 0 by 0.4 of the smaller radius (1e-3): 2 - 0.4 apart
    deep = PARTICLES + "0.001,0.002,0.0014,0.001,glass\n"
    s = scene(tmp_path, particles=deep)
    assert s.warnings == [
        f"{file}: particles.file: 1 unbonded particle pair(s) overlap by more than 25% of the "
        "smaller radius at t = 0 (the most: p.csv line 2 and p.csv line 6, 40%); their "
        "contact forces will throw them apart. Check the positions and radii, or bond them"]
    assert scene(tmp_path, {"simulation.contact_model": "none"}, particles=deep).warnings == []
    # 24 % is not deep
    mild = PARTICLES + "0.001,0.002,0.00124,0.001,glass\n"
    assert scene(tmp_path, particles=mild).warnings == []
    bonded = {"bond_materials": BINDER, "bonds": {"file": "b.csv"}}
    bonds = "i,j,diameter,material\n0,4,0.0005,binder\n"
    assert scene(tmp_path, bonded, particles=deep, bonds=bonds).warnings == []
    assert len(scene(tmp_path, {**bonded, "simulation.bonded_contacts": True},
                     particles=deep, bonds=bonds).warnings) == 1
    bonds = "i,j,diameter,material\n0,1,0.0005,binder\n"     # another pair bonded
    assert len(scene(tmp_path, bonded, particles=deep, bonds=bonds).warnings) == 1


def test_units_slips_are_warned_about(tmp_path):
    file = tmp_path / "s.toml"
    # bonded particles 0 and 4 overlap by 1.5 radii
    rows = PARTICLES + "0.001,0.002,0.0035,0.001,glass\n"
    bonded = {"bond_materials": BINDER, "bonds": {"file": "b.csv"},
              "simulation.contact_model": "none"}
    s = scene(tmp_path, bonded, particles=rows, bonds="i,j,diameter,material\n0,4,5e-4,binder\n"
              "0,1,5e-4,binder\n")
    hint = "radii or positions in the wrong unit (all lengths are in m)?"
    assert s.warnings == [f"{file}: particles.file: 1 of 2 bonded pairs overlap by more than "
                          f"the smaller radius at t = 0 (the most: p.csv line 2 and p.csv "
                          f"line 6, 1.5 radii): {hint}"]
    # radii given in mm: spacing 2 mm, radius 1.0 (m)
    mm = "x,y,z,radius,material\n" + "".join(f"{0.002 * k},0,0,1.0,glass\n" for k in range(5))
    s = scene(tmp_path, {"simulation.contact_model": "none", "simulation.end_time": 1.0},
              particles=mm)
    assert s.warnings == [f"{file}: particles.file: the particles' median spacing 0.002 m is "
                          f"less than half their median radius 1 m: {hint}"]
    # a plane 0.3 radii below particle 3's centre (radius 1.1e-3): overlaps by 1.3 radii
    s = walls(tmp_path, {**PLANE, "point": [0.0, 0.0, 0.0052 - 0.33e-3]})
    assert s.warnings == [f"{file}: walls.0: 1 particle(s) overlap the wall by more than 25% "
                          f"of their radius at t = 0 (the first: p.csv line 5); the wall will "
                          f"throw them off. Move the wall or the particles, or: {hint}"]
    s = walls(tmp_path, {**PLANE, "point": [0.0, 0.0, 0.0052 - 1.1e-3 * 0.76]})
    assert s.warnings == []
    s = walls(tmp_path, {**PLANE, "point": [0.0, 0.0, 0.0052 - 1.1e-3 * 0.74]})
    assert "walls.0: 1 particle(s)" in s.warnings[0] and "(the first: p.csv line 5)" in \
        s.warnings[0]


BONDS = "i,j,diameter,material\n0,1,0.0005,binder\n0,2,0.0004,cement\n"
TWO_BINDERS = {**BINDER, "cement": {"young_modulus": 9e7, "poisson_ratio": 0.2}}


def test_bonds_from_a_file(tmp_path):
    s = scene(tmp_path, {"bond_materials": TWO_BINDERS, "bonds": {"file": "b.csv"}},
              bonds=BONDS)
    assert s.model.bond_pairs.tolist() == [[0, 1], [0, 2]]
    assert s.model.bond_diameter.tolist() == [0.0005, 0.0004]
    assert s.model.bond_material.tolist() == [0, 1]
    np.testing.assert_allclose(s.model.bond_initial_length, [0.0021, 0.0023], rtol=1e-12)
    assert s.model.bond_materials[1].young_modulus == 9e7
    assert [m.name for m in s.model.bond_materials] == ["binder", "cement"]


@pytest.mark.parametrize("rows, message", [
    ("0,4,0.0005,binder\n", "b.csv line 3: bond 1 joins particles [0, 4]; indices must lie "
                            "in [0, 3]"),
    ("1,0,0.0005,binder\n", "b.csv line 3: particles [0, 1] are bonded more than once "
                            "(duplicate of bond 0)"),
    ("2,3,0.0023,binder\n", "b.csv line 3: bond 1 has diameter 0.0023 m, wider than both its "
                            "particles; allowed [1.8e-09, 0.0022] m"),
    ("2,3,1.7e-09,binder\n", "b.csv line 3: bond 1 has diameter 1.7e-09 m, less than 1/1e+06 "
                             "of its particles'; allowed [1.8e-09, 0.0022] m"),
    ("2,3,0.0005,glue\n", "b.csv line 3: bond material 'glue' is not defined; defined: binder"),
])
def test_bad_bonds_name_their_line(tmp_path, rows, message):
    text = refused(tmp_path, {"bond_materials": BINDER, "bonds": {"file": "b.csv"}},
                   bonds="i,j,diameter,material\n0,1,0.0005,binder\n" + rows)
    key = "bonds.material" if "glue" in rows else "bonds.file"
    assert text == f"{tmp_path / 's.toml'}: {key}: {message}"


def test_bond_diameters_at_their_bounds_load(tmp_path):
    for diameter in (0.0022, 1.8e-9):
        s = scene(tmp_path, {"bond_materials": BINDER, "bonds": {"file": "b.csv"}},
                  bonds=f"i,j,diameter,material\n2,3,{diameter!r},binder\n")
        assert s.model.bond_diameter.tolist() == [diameter]


def test_bonds_from_gaps(tmp_path):
    file = tmp_path / "s.toml"
    gap = {"bond_materials": BINDER, "simulation.contact_model": "none"}
    s = scene(tmp_path, {**gap, "bonds": {"max_gap": 1.5e-4, "diameter_ratio": 0.5,
                                          "material": "binder"}})
    # gaps: 0-1 -1e-4 (they overlap), 0-3 1e-4, 0-2 4e-4; the others farther apart
    assert sorted(map(sorted, s.model.bond_pairs.tolist())) == [[0, 1], [0, 3]]
    # half the smaller particle's diameter
    np.testing.assert_allclose(s.model.bond_diameter, [1e-3, 1e-3], rtol=1e-12)
    s = scene(tmp_path, {**gap, "bonds": {"max_gap": 0.0, "diameter": 3e-4,
                                          "material": "binder"}})
    assert s.model.bond_pairs.tolist() == [[0, 1]] and s.model.bond_diameter.tolist() == [3e-4]
    s = scene(tmp_path, {**gap, "bonds": {"max_gap": 4.1e-4, "diameter_ratio": 0.25,
                                          "material": "binder", "max_per_particle": 2}})
    assert s.model.n_bonds == 2
    cases = [
        ({"max_gap": 1e-4, "file": "b.csv"}, "bonds", "give exactly one of bonds.file or "
                                                      "bonds.max_gap"),
        ({"diameter": 1e-4}, "bonds", "give exactly one of bonds.file or bonds.max_gap"),
        ({"file": "b.csv", "diameter": 1e-4}, "bonds.diameter",
         "only used with bonds.max_gap (bonds.csv has its own columns)"),
        ({"file": "b.csv", "material": "binder"}, "bonds.material",
         "only used with bonds.max_gap (bonds.csv has its own columns)"),
        ({"file": "b.csv", "max_per_particle": 3}, "bonds.max_per_particle",
         "only used with bonds.max_gap (bonds.csv has its own columns)"),
        ({"file": "b.csv", "diameter_ratio": 0.5}, "bonds.diameter_ratio",
         "only used with bonds.max_gap (bonds.csv has its own columns)"),
        ({"max_gap": 1e-4, "diameter": 1e-4}, "bonds.material",
         "missing required key (with bonds.max_gap)"),
        ({"max_gap": 1e-4, "material": "binder"}, "bonds.diameter",
         "give exactly one of bonds.diameter or bonds.diameter_ratio"),
        ({"max_gap": 1e-4, "material": "binder", "diameter": 1e-4, "diameter_ratio": 0.5},
         "bonds.diameter", "give exactly one of bonds.diameter or bonds.diameter_ratio"),
        ({"max_gap": 1e-4, "material": "glue", "diameter": 1e-4}, "bonds.material",
         "bond material 'glue' is not defined; defined: binder"),
        ({"max_gap": 1e-4, "material": "binder", "diameter_ratio": 1.5},
         "bonds.diameter_ratio", "value 1.5 is outside the allowed range (0.0, 1.0]"),
        ({"max_gap": 1e-4, "material": "binder", "diameter": 1e-4, "max_per_particle": 0},
         "bonds.max_per_particle", "value 0: expected an integer >= 1"),
    ]
    for bonds, key, message in cases:
        assert refused(tmp_path, {**gap, "bonds": bonds}, bonds=BONDS) == \
            f"{file}: {key}: {message}", message
    assert refused(tmp_path, {"bonds": {"file": "b.csv"}}, bonds=BONDS) == (
        f"{file}: bonds.material: b.csv line 2: bond material 'binder' is not defined; "
        "defined: (none)")
    assert refused(tmp_path, {"bonds": {"max_gap": 1e-4, "diameter": 1e-4,
                                        "material": "binder"}}) == (
        f"{file}: bonds.material: bond material 'binder' is not defined; defined: (none)")


def test_bond_materials_of_another_model_name_the_key(tmp_path):
    binder = {"binder": {"young_modulus": 5e7, "poisson_ratio": 0.25,
                         "friction_angle": 30.0}}
    text = refused(tmp_path, {"bond_materials": binder})
    assert text.startswith(f"{tmp_path / 's.toml'}: bond_materials.binder.friction_angle: "
                           "friction_angle = 30.0 needs model = ")
    assert refused(tmp_path, {"bond_materials": 3}) == (
        f"{tmp_path / 's.toml'}: bond_materials: expected tables [bond_materials.NAME]")


def test_make_systems_errors_get_the_scenes_keys():
    assert _guess_key("bonds: bond 3 joins ...") == "bonds"
    assert _guess_key("bond_diameter: bond 0 has diameter") == "bonds.diameter"
    assert _guess_key("radius: particle 2 has radius") == "particles.radius"
    assert _guess_key("damping: 1.5") == "simulation.damping"
    assert _guess_key("box_low/box_high: must") == "simulation.box_high"
    assert _guess_key("periodic: needs") == "simulation.periodic"
    assert _guess_key("velocity: shape") == "velocity"


def test_a_fluid_with_a_velocity_formula_or_local_voidage(tmp_path):
    file = tmp_path / "s.toml"
    fluid = {"density": 1.2, "viscosity": 1.8e-5, "drag": "stokes"}
    s = scene(tmp_path, {"fluid": {**fluid, "velocity": ["0.5 * z", 0.0, "2 * t"]}})
    flow = s.simulation_options["flow"]
    assert s.model.acting_fields == ["fluid"] and flow.velocity is not None
    assert s.data["simulation"]["end_time"] == 1e-3
    assert refused(tmp_path, {"fluid": {**fluid, "velocity": ["z", 0.0]}}) == (
        f"{file}: fluid.velocity: expected 3 components (numbers or formulas of x, y, z, t), "
        "got 2")
    assert refused(tmp_path, {"fluid": {**fluid, "velocity": ["import os", 0, 0]}}) == (
        f"{file}: fluid.velocity: formula 'import os': not an expression (invalid syntax)")
    from bondem.physics.field_fluid import fluid_array
    np.testing.assert_array_equal(s.model.fields["fluid"], fluid_array(
        density=1.2, viscosity=1.8e-5, drag="stokes", buoyancy=True))   # formula: no base
    assert refused(tmp_path, {"fluid": {"velocity": ["z", 0, 0]}}) == (
        f"{file}: fluid.drag: a velocity formula or a local voidage acts through the drag; "
        "allowed: one of " + ", ".join(d for d in __import__(
            "bondem.physics.field_fluid", fromlist=["DRAG_LAWS"]).DRAG_LAWS if d != "none"))
    grid = {"low": [0.0, 0.0, 0.0], "high": [0.01, 0.01, 0.01], "cells": [2, 3, 4]}
    s = scene(tmp_path, {"fluid": {**fluid, "voidage": "local", "voidage_grid": grid}})
    flow = s.simulation_options["flow"]
    assert flow.voidage_floor == 0.2 and flow.velocity is None
    s = scene(tmp_path, {"fluid": {**fluid, "voidage": "local",
                                   "voidage_grid": {**grid, "floor": 0.35}}})
    assert s.simulation_options["flow"].voidage_floor == 0.35
    assert refused(tmp_path, {"fluid": {**fluid, "voidage": "local"}}) == (
        f"{file}: fluid.voidage_grid: voidage = \"local\" needs fluid.voidage_grid = {{low = "
        "[x, y, z], high = [x, y, z], cells = [nx, ny, nz]} (m, m, integers >= 1)")
    assert refused(tmp_path, {"fluid": {**fluid, "voidage_grid": grid}}) == (
        f"{file}: fluid.voidage_grid: a voidage grid needs voidage = \"local\"")
    flat = {**grid, "high": [0.01, 0.0, 0.01]}
    assert refused(tmp_path, {"fluid": {**fluid, "voidage": "local", "voidage_grid": flat}}) \
        == (f"{file}: fluid.voidage_grid.high: high [0.01, 0.0, 0.01] must exceed low "
            "[0.0, 0.0, 0.0] on every axis")
    for cells in ([2, 0, 4], [2, 3], [2, 3.0, 4], [True, 3, 4]):
        assert refused(tmp_path, {"fluid": {**fluid, "voidage": "local",
                                            "voidage_grid": {**grid, "cells": cells}}}) == (
            f"{file}: fluid.voidage_grid.cells: value {cells!r}: expected 3 integers >= 1 "
            "[nx, ny, nz]")
    s = scene(tmp_path, {"fluid": {**fluid, "velocity": [0.0, 0.0, 0.3]}})
    assert "flow" not in s.simulation_options
    assert refused(tmp_path, {"fluid": {"viscosity": -1.0}}) == (
        f"{file}: fluid.viscosity: value -1.0 is outside the allowed range [0.0, inf)")
    assert refused(tmp_path, {"fluid": {"drag": "stokes"}}).startswith(f"{file}: fluid.")
    assert refused(tmp_path, {"fluid": {"velocity_file": "u.vti", "density": 1.0}}) == (
        f"{file}: fluid.velocity_file: no such file {str(tmp_path / 'u.vti')!r}")


def test_a_rotating_frame_table(tmp_path):
    s = scene(tmp_path, {"frame": {"angular_velocity": [0.0, 0.0, 3.0],
                                   "center": [0.001, 0.0, 0.0]}})
    assert s.model.acting_fields == ["frame"]
    assert refused(tmp_path, {"frame": {"spin": [0, 0, 1]}}).startswith(
        f"{tmp_path / 's.toml'}: frame.spin: unknown key 'spin'")


def test_clumps_from_the_particle_file(tmp_path):
    rows = PARTICLES.splitlines()
    table = "\n".join([rows[0] + ",clump"] + [r + f",{c}" for r, c in
                                              zip(rows[1:], (0, 0, -1, 1))])
    file = tmp_path / "s.toml"
    assert refused(tmp_path, {"simulation.contact_model": "none"}, particles=table) == (
        f"{file}: particles.file.clump: p.csv line 5: clump 1 has one particle; a clump needs "
        "at least 2 (give a free sphere clump -1)")
    table = "\n".join([rows[0] + ",clump"] + [r + f",{c}" for r, c in
                                              zip(rows[1:], (1, 1, -1, 1))])
    assert refused(tmp_path, {"simulation.contact_model": "none"}, particles=table) == (
        f"{file}: particles.file.clump: clump 0 has no particle; number the clumps 0, 1, 2, "
        "... without gaps")
    table = "\n".join([rows[0] + ",clump"] + [r + f",{c}" for r, c in
                                              zip(rows[1:], (0, 0, -1, 0))])
    s = scene(tmp_path, {"simulation.contact_model": "none"}, particles=table)
    assert s.model.n_clumps == 1 and s.model.clump_of.tolist() == [0, 0, -1, 0]
    # the union's volume: the three spheres less the lens where particles 0 and 1 overlap
    r1, r2, d = 1e-3, 1.2e-3, 0.0021
    lens = np.pi * (r1 + r2 - d) ** 2 * (d * d + 2 * d * (r1 + r2) - 3 * (r1 - r2) ** 2) / (12 * d)
    mass = 2500 * (4 / 3 * np.pi * (1e-3 ** 3 + 1.2e-3 ** 3 + 1.1e-3 ** 3) - lens)
    assert s.model.clump_mass[0] == pytest.approx(mass, rel=1e-4)     # a voxel sum
    table = "\n".join([rows[0] + ",clump"] + [r + ",-1" for r in rows[1:]])
    assert scene(tmp_path, particles=table).model.n_clumps == 0


def test_a_clump_generators_keys_and_ranges(tmp_path):
    file = tmp_path / "s.toml"
    base = {"shape": "box", "low": [0, 0, 0], "high": [0.01, 0.01, 0.01], "material": "glass",
            "clump": {"centres": [[0, 0, 0], [0.0005, 0, 0]], "radii": [0.0005, 0.0004]}}

    def generator(**edit):
        table = {**base, **edit}
        return refused(tmp_path, {"particles.file": None,
                                  "particles.generator": {k: v for k, v in table.items()
                                                          if v is not None}})
    assert generator(particle_radius=1e-3) == (
        f"{file}: particles.generator.particle_radius: unknown key 'particle_radius'; allowed: "
        + ", ".join(sorted(set(__import__("bondem.generate", fromlist=["x"])._GENERATOR_KEYS)
                           - {"particle_radius", "size_distribution"}
                           | {"clump", "compact"}))
        + " (a clump generator packs the clump given; its radii are the clump's)")
    assert generator(colour="red").startswith(
        f"{file}: particles.generator.colour: unknown key 'colour'; allowed: ")
    assert not generator(colour="red").endswith("its radii are the clump's)")
    shapes = "expected a table {centres = [[x, y, z], ...], radii = [...]} (m) or {file = " \
             "\"grain.stl\", spheres = n, scale = s, resolution = r} (an STL filled with spheres)"
    assert generator(clump={"centres": [[0, 0, 0]]}) == \
        f"{file}: particles.generator.clump: {shapes}"
    assert generator(clump=3) == f"{file}: particles.generator.clump: {shapes}"
    assert generator(clump={"file": "g.stl", "colour": 1}) == \
        f"{file}: particles.generator.clump: {shapes}"
    assert generator(clump={"centres": [[0, 0, 0]], "radii": [-1.0]}).startswith(
        f"{file}: particles.generator.clump: ")
    assert generator(clump={"file": "g.stl"}) == (
        f"{file}: particles.generator.clump.file: no such file: {tmp_path / 'g.stl'}")
    for key, value, allowed in (("compact", 0.49, "[0.5, 1]"), ("compact", 1.01, "[0.5, 1]"),
                                ("compact", True, "[0.5, 1]"),
                                ("solids_fraction", 0.0, "(0, 0.66)"),
                                ("solids_fraction", 0.66, "(0, 0.66)"),
                                ("max_overlap", 0.0, "(0, 0.05]"),
                                ("max_overlap", 0.051, "(0, 0.05]")):
        assert generator(**{key: value}) == (
            f"{file}: particles.generator.{key}: {value!r}; allowed range {allowed}"), key
    for seed in (-1, 1.5, True):
        assert generator(seed=seed) == (f"{file}: particles.generator.seed: {seed!r}; "
                                        "allowed: an integer >= 0")
    for material in (None, "", 3):
        assert generator(material=material) == (
            f"{file}: particles.generator.material: {material!r}; give the name of a particle "
            "material")
    assert generator(material="iron") == (
        f"{file}: particles.generator.material: material 'iron' is not defined; defined "
        "materials: glass, steel")


def test_a_clump_filled_into_a_mesh_checks_its_numbers(tmp_path):
    import trimesh
    trimesh.creation.icosphere(radius=1.0).export(tmp_path / "g.stl")
    file = tmp_path / "s.toml"
    base = {"shape": "box", "low": [0, 0, 0], "high": [0.01, 0.01, 0.01], "material": "glass"}

    def mesh(**clump):
        return refused(tmp_path, {"particles.file": None, "particles.generator": {
            **base, "clump": {"file": "g.stl", **clump}}})
    for name, value, allowed in (("spheres", 1, "[2, 1000]"), ("spheres", 1001, "[2, 1000]"),
                                 ("spheres", 2.0, "[2, 1000]"), ("resolution", 7, "[8, 200]"),
                                 ("resolution", 201, "[8, 200]"),
                                 ("resolution", True, "[8, 200]")):
        assert mesh(**{name: value}) == (
            f"{file}: particles.generator.clump.{name}: {value!r}; allowed: an integer in "
            f"{allowed}"), name
    for scale in (0.0, -1.0, math.inf, "mm"):
        assert mesh(scale=scale) == (
            f"{file}: particles.generator.clump.scale: {scale!r}; allowed: a number > 0")
    (tmp_path / "g.stl").write_text("solid x\nendsolid x\n")
    assert mesh().startswith(f"{tmp_path / 'g.stl'}: particles.generator.clump.file: cannot "
                             "fill it with spheres: ")


def test_generated_particles_fill_their_box_moved_by_the_offset(tmp_path):
    generator = {"shape": "box", "low": [0.0, 0.0, 0.0], "high": [0.01, 0.008, 0.006],
                 "particle_radius": 6e-4, "solids_fraction": 0.3, "seed": 3,
                 "material": "steel"}
    s = scene(tmp_path, {"particles.file": None, "particles.generator": generator,
                         "particles.offset": [0.1, 0.0, -0.05],
                         "particles.velocity": [0.0, 0.2, 0.0]})
    n = s.model.n_particles
    volume = 0.01 * 0.008 * 0.006
    assert abs(n * 4 / 3 * np.pi * 6e-4 ** 3 / volume - 0.3) < 0.05
    position = s.state.position
    assert np.all(position >= [0.1 + 6e-4 * 0.99, 6e-4 * 0.99, -0.05 + 6e-4 * 0.99])
    assert np.all(position <= [0.11 - 6e-4 * 0.99, 0.008 - 6e-4 * 0.99, -0.044 - 6e-4 * 0.99])
    assert s.model.radius.tolist() == [6e-4] * n and s.model.material.tolist() == [1] * n
    assert np.all(s.state.velocity == [0.0, 0.2, 0.0]) and s.model.fixed.sum() == 0
    assert s.warnings == [] and s.data["particles"]["generator"]["seed"] == 3
    # a plane through the generated box names the first particle by its index
    lowest = int(np.argmin(position[:, 2]))
    wall = {**PLANE, "point": [0.0, 0.0, float(position[:, 2].min()) + 1e-4]}
    s = scene(tmp_path, {"particles.file": None, "particles.generator": generator,
                         "particles.offset": [0.1, 0.0, -0.05], "walls": [wall]})
    assert s.warnings[0].startswith(f"{tmp_path / 's.toml'}: walls.0: ")
    first = min(k for k in range(n) if position[k, 2] < float(position[:, 2].min()) + 1e-4
                + 0.75 * 6e-4 - 1e-12)
    assert f"(the first: particle {first})" in s.warnings[0] and lowest >= first
    assert refused(tmp_path, {"particles.file": None, "particles.generator": {
        **generator, "material": "iron"}}) == (
        f"{tmp_path / 's.toml'}: particles.generator.material: material 'iron' is not "
        "defined; defined materials: glass, steel")
    assert refused(tmp_path, {"particles.colour": "red"}).startswith(
        f"{tmp_path / 's.toml'}: particles.colour: unknown key 'colour'")


TEMPLATE = {"centres": [[0.0, 0.0, 0.0], [0.0005, 0.0, 0.0]], "radii": [0.0005, 0.0004]}


def test_a_clump_generator_packs_rigid_clumps_of_the_template(tmp_path):
    generator = {"shape": "box", "low": [0.0, 0.0, 0.0], "high": [0.006, 0.006, 0.006],
                 "material": "glass", "clump": TEMPLATE, "solids_fraction": 0.3, "seed": 2}
    edit = {"particles.file": None, "particles.generator": generator,
            "particles.offset": [0.02, 0.0, 0.0]}
    s = scene(tmp_path, edit)
    model = s.model
    c = model.n_clumps
    assert c >= 2 and model.n_particles == 2 * c
    assert sorted(np.bincount(model.clump_of).tolist()) == [2] * c
    assert sorted(set(model.radius.tolist())) == [0.0004, 0.0005]
    # mass: the density times the union of the two spheres (their lens counted once)
    r1, r2, d = 0.0005, 0.0004, 0.0005
    lens = np.pi * (r1 + r2 - d) ** 2 * (d * d + 2 * d * (r1 + r2) - 3 * (r1 - r2) ** 2) / (12 * d)
    union = 4 / 3 * np.pi * (r1 ** 3 + r2 ** 3) - lens
    np.testing.assert_allclose(model.clump_mass, 2500 * union, rtol=2e-3)
    members = [np.flatnonzero(model.clump_of == k) for k in range(c)]
    for k, m in enumerate(members):      # the centre of mass between the members, offset
        centre = s.state.clump_position[k]
        assert np.linalg.norm(s.state.position[m] - centre, axis=1).max() < 0.0005
        assert 0.02 < centre[0] < 0.026
    heavy = scene(tmp_path, {**edit, "materials.glass.density": 5000.0}).model
    np.testing.assert_allclose(heavy.clump_mass, 2 * model.clump_mass, rtol=1e-14)
    np.testing.assert_allclose(heavy.clump_inertia, 2 * model.clump_inertia, rtol=1e-14)
    np.testing.assert_array_equal(scene(tmp_path, edit).state.position, s.state.position)


def test_a_clump_filled_into_a_mesh_loads(tmp_path):
    import trimesh
    trimesh.creation.icosphere(radius=1.0).export(tmp_path / "g.stl")
    generator = {"shape": "box", "low": [0.0, 0.0, 0.0], "high": [0.008, 0.008, 0.008],
                 "material": "glass", "solids_fraction": 0.2,
                 "clump": {"file": "g.stl", "spheres": 3, "scale": 1e-3, "resolution": 12}}
    s = scene(tmp_path, {"particles.file": None, "particles.generator": generator})
    assert s.model.n_clumps >= 1 and s.model.radius.max() <= 1e-3 * (1 + 1e-9)
    sizes = np.bincount(s.model.clump_of)
    assert 2 <= sizes.min() and sizes.max() <= 3


def test_a_rigid_clumps_members_and_bonds(tmp_path):
    """Members of one clump never touch each other (no overlap warning, no bond between
    them); a free sphere or another clump's member does."""
    rows = PARTICLES.splitlines()
    extra = ["0.001,0.002,0.0014,0.001,glass",      # 4: deep in 0
             "0.0031,0.002,0.0012,0.001,steel",     # 5: deep in 1
             "0.001,0.0043,0.0016,0.0009,glass"]    # 6: deep in 2
    clump = (0, -1, 1, -1, 0, 1, -1)
    table = "\n".join([rows[0] + ",clump"] + [r + f",{k}" for r, k in
                                              zip(rows[1:] + extra, clump)])
    s = scene(tmp_path, particles=table)
    assert s.warnings[0].startswith(f"{tmp_path / 's.toml'}: particles.file: 2 unbonded "
                                    "particle pair(s) overlap")
    assert s.model.n_clumps == 2
    s = scene(tmp_path, {"bond_materials": BINDER, "simulation.contact_model": "none",
                         "bonds": {"max_gap": 1e-4, "diameter": 2e-4, "material": "binder"}},
              particles=table)
    pairs = {tuple(sorted(p)) for p in s.model.bond_pairs.tolist()}
    assert (0, 4) not in pairs and (2, 5) not in pairs and (1, 5) in pairs and (0, 1) in pairs


def test_a_bond_excuses_only_its_own_pair_from_the_overlap_warning(tmp_path):
    rows = PARTICLES + "0.00205,0.002,0.003,0.0005,glass\n"    # 4: deep in 0 and in 1
    s = scene(tmp_path, {"bond_materials": BINDER, "bonds": {"file": "b.csv"}}, particles=rows,
              bonds="i,j,diameter,material\n0,4,0.0002,binder\n")
    assert len(s.warnings) == 1 and "1 unbonded particle pair(s)" in s.warnings[0]
    assert "(the most: p.csv line 3 and p.csv line 6, 130%)" in s.warnings[0]


def test_two_particles_are_checked_like_many(tmp_path):
    file = tmp_path / "s.toml"
    two = "x,y,z,radius,material\n0.001,0.002,0.003,0.001,glass\n0.001,0.002,0.003,0.001,glass\n"
    assert refused(tmp_path, particles=two).startswith(
        f"{file}: particles.file: p.csv line 2 and p.csv line 3: particles 0 and 1 are at the "
        "same place")
    mm = "x,y,z,radius,material\n0.0,0,0,1.0,glass\n0.4,0,0,1.0,glass\n"
    s = scene(tmp_path, {"simulation.contact_model": "none", "simulation.end_time": 1.0},
              particles=mm)
    assert len(s.warnings) == 1 and "median spacing 0.4 m" in s.warnings[0]


@pytest.mark.parametrize("spacing, warned", [(0.4, True), (0.6, False)])
def test_the_median_spacing_is_to_the_nearest_neighbour(tmp_path, spacing, warned):
    rows = "x,y,z,radius,material\n" + "".join(f"{spacing * k!r},0,0,1.0,glass\n"
                                               for k in range(5))
    s = scene(tmp_path, {"simulation.contact_model": "none", "simulation.end_time": 1.0},
              particles=rows)
    assert any("median spacing" in w for w in s.warnings) == warned


def test_a_mesh_wall_cutting_a_particle_is_warned_about(tmp_path):
    import trimesh
    box = trimesh.creation.box(extents=(10.0, 10.0, 2.0))
    box.apply_translation((0.0, 0.0, 4.9 + 1.0))         # mm: bottom face at z = 4.9 mm
    box.export(tmp_path / "lid.stl")
    s = walls(tmp_path, {"type": "mesh", "file": "lid.stl", "material": "glass",
                         "scale": 1e-3})
    assert s.warnings == [
        f"{tmp_path / 's.toml'}: walls.0: 1 particle(s) overlap the wall by more than 25% of "
        "their radius at t = 0 (the first: p.csv line 5); the wall will throw them off. Move "
        "the wall or the particles, or: radii or positions in the wrong unit (all lengths "
        "are in m)?"]


def test_walls_are_checked_where_they_stand_at_t0(tmp_path):
    wall = {**PLANE, "point": [0.0, 0.0, 0.0052 - 0.33e-3], "velocity": [0.0, 0.0, -0.01]}
    assert len(walls(tmp_path, wall).warnings) == 1


def test_a_velocity_file_sets_the_fluids_grid(tmp_path):
    velocity = np.zeros((2, 3, 2, 3))
    velocity[..., 0] = 0.25
    with h5py.File(tmp_path / "u.h5", "w") as f:
        f["velocity"] = velocity
        f["velocity"].attrs["origin"] = [0.0, -0.01, 0.0]
        f["velocity"].attrs["spacing"] = [0.01, 0.01, 0.01]
    fluid = {"density": 1.2, "viscosity": 1.8e-5, "drag": "stokes", "velocity_file": "u.h5"}
    s = scene(tmp_path, {"fluid": fluid})
    np.testing.assert_array_equal(s.model.flow, velocity)
    np.testing.assert_array_equal(s.model.flow_box, [0.0, -0.01, 0.0, 0.01, 0.01, 0.01])
    with h5py.File(tmp_path / "u.h5", "r+") as f:
        f["velocity"].attrs["spacing"] = [0.01, 0.0, 0.01]
    text = refused(tmp_path, {"fluid": fluid})
    assert text.startswith(f"{tmp_path / 'u.h5'}: fluid.velocity_file: ")
    assert "spacing" in text


def test_exact_bounds_of_the_run_and_the_step(tmp_path, monkeypatch):
    file = tmp_path / "s.toml"
    auto = scene(tmp_path).simulation_options  # "auto"
    from bondem.timestep import stable_time_step
    step, cause = stable_time_step(scene(tmp_path).model, 0.2, False)
    s = scene(tmp_path, {"simulation.end_time": step})       # one step: allowed
    assert s.save_every == step and auto["time_step"] == "auto"
    edit = {"simulation.time_step": 2.0 ** -20, "simulation.end_time": 2.0 ** -10}
    assert scene(tmp_path, {**edit, "simulation.max_steps": 1024.0})
    assert refused(tmp_path, {**edit, "simulation.max_steps": 1023.0}).startswith(
        f"{file}: simulation.end_time: value 0.0009765625 s is 1.02e+03 steps")
    # a particle exactly FAR_IN_RADII smallest radii from the origin is resolved
    far = 1e7 * 0.0009
    rows = PARTICLES + f"0.0,0.0,{far!r},0.001,glass\n"
    assert scene(tmp_path, {"simulation.contact_model": "none"}, particles=rows)
    rows = PARTICLES + f"0.0,0.0,{float(np.nextafter(far, 1e9))!r},0.001,glass\n"
    assert "double precision cannot resolve" in refused(
        tmp_path, {"simulation.contact_model": "none"}, particles=rows)
    import bondem.timestep
    for bad, where in ((math.nan, "bonds"), (0.0, "materials"), (math.inf, "materials")):
        monkeypatch.setattr(bondem.timestep, "stable_time_step",
                            lambda model, factor, compat, bad=bad, where=where: (
                                bad, "bond_axial" if where == "bonds" else "rayleigh"))
        cause = "bond_axial" if where == "bonds" else "rayleigh"
        assert refused(tmp_path) == (
            f"{file}: {where}: the stable time step is {bad!r} s (limited by {cause}): a "
            "bond diameter, modulus or particle size is out of any physical range")


def test_the_smallest_of_several_tiny_radii_is_named(tmp_path):
    median = float(np.median([1e-3, 1.2e-3, 5e-10, 2e-10, 1.1e-3]))
    rows = PARTICLES.replace("0.0009,steel", "5e-10,steel") + "0.009,0.009,0.009,2e-10,glass\n"
    text = refused(tmp_path, particles=rows)
    assert text.startswith(f"{tmp_path / 's.toml'}: particles.file: p.csv line 6: radius 2e-10 "
                           f"m is less than 1/1e+06 of the median radius {median:.4g} m")
    exact = float(np.median([1e-3, 1.2e-3, 0.0, 1.1e-3]))      # the median with any tiny one
    tiny = exact / 1e6
    rows = PARTICLES.replace("0.0009,steel", f"{tiny!r},steel")
    assert float(np.median([1e-3, 1.2e-3, tiny, 1.1e-3])) / 1e6 == tiny
    s = scene(tmp_path, {"simulation.contact_model": "none", "simulation.end_time": 1e-8},
              particles=rows)
    assert s.model.radius[2] == tiny


def test_options_that_only_musen_compat_refuses(tmp_path):
    kelvin = {"glue": {"young_modulus": 5e7, "poisson_ratio": 0.25, "model": "kelvin",
                       "viscosity": 1e-6, "breakage": "separate"}}
    assert scene(tmp_path, {"bond_materials": kelvin}).model is not None
    assert refused(tmp_path, {"bond_materials": kelvin, "simulation.musen_compat": True}) == (
        f"{tmp_path / 's.toml'}: bond_materials.glue.breakage: musen_compat: MUSEN's Kelvin "
        "bond breaks by the combined criterion only; breakage = 'separate' is bondem's "
        "(docs/bond_kelvin.md)")


def test_make_simulation_gives_each_run_walls_of_its_own(tmp_path):
    servo = {"target_force": 1.0, "gain": 1e-5, "max_velocity": 0.05}
    s = walls(tmp_path, {**PLANE, "servo": servo}, {**PLANE, "point": [0, 0, 0.01],
                                                    "normal": [0, 0, -1]})
    first, second = s.make_simulation(), s.make_simulation()
    assert len(first.walls) == 2 and first.walls[0] is not second.walls[0]
    assert first.walls[0].motion is not s.simulation_options["walls"][0].motion
    first.walls[0].motion.travel = 1e-3
    assert second.walls[0].motion.travel == 0.0 == s.simulation_options["walls"][0].motion.travel
    assert first.state is not s.state and first.model is s.model
    np.testing.assert_array_equal(first.state.position, s.state.position)
    state = s.state.copy()
    assert s.make_simulation(state).state is state
    assert s.make_simulation().contacts is not None


def test_more_bond_file_rules(tmp_path):
    file = tmp_path / "s.toml"
    bonded = {"bond_materials": TWO_BINDERS, "bonds": {"file": "b.csv"}}
    assert refused(tmp_path, bonded, bonds="i,j,diameter,material\n0,1,x,binder\n") == (
        f"{file}: bonds.file: {tmp_path / 'b.csv'}: diameter: line 2: 'x' is not a number")
    # a repeated particle row bonded to its twin: the bond has no length
    twin = PARTICLES + "0.0031,0.002,0.003,0.0012,glass\n"
    assert refused(tmp_path, bonded, particles=twin,
                   bonds="i,j,diameter,material\n0,1,0.0005,binder\n1,4,0.0005,binder\n") == (
        f"{file}: bonds.file: b.csv line 3: bond 1 joins particles [1, 4] at the same "
        "position (initial length 0, must be > 0)")
    # the first pair bonded twice in sorted order, named at its last repetition
    assert refused(tmp_path, bonded, bonds="i,j,diameter,material\n0,2,0.0005,binder\n"
                   "2,3,0.0005,binder\n3,2,0.0005,binder\n2,3,0.0005,binder\n") == (
        f"{file}: bonds.file: b.csv line 5: particles [2, 3] are bonded more than once "
        "(duplicate of bond 1)")
    low = 2.0 / 1e6 * 0.0009
    s = scene(tmp_path, bonded, bonds=f"i,j,diameter,material\n2,3,{low!r},binder\n")
    assert s.model.bond_diameter.tolist() == [low]
    assert refused(tmp_path, bonded, bonds="i,j,diameter,material\n2,3,0.0005,glue\n") == (
        f"{file}: bonds.material: b.csv line 2: bond material 'glue' is not defined; defined: "
        "binder, cement")
    # generated bonds are checked by the same rules, named by the table
    assert refused(tmp_path, {"bond_materials": BINDER, "simulation.contact_model": "none",
                              "bonds": {"max_gap": 1.5e-4, "diameter": 0.0025,
                                        "material": "binder"}}) == (
        f"{file}: bonds: bond 0 has diameter 0.0025 m, wider than both its particles; "
        "allowed [2e-09, 0.0024] m")


def test_more_value_rules(tmp_path):
    file = tmp_path / "s.toml"
    assert scene(tmp_path, {"simulation.time_step": "auto"}).simulation_options[
        "time_step"] == "auto"
    fluid = {"density": 1.2, "viscosity": 1.8e-5, "drag": "stokes", "voidage": "local",
             "voidage_grid": {"low": [0, 0, 0], "high": [0.01, 0.01, 0.01], "cells": [1, 1, 1]}}
    assert scene(tmp_path, {"fluid": fluid}).simulation_options["flow"] is not None
    assert refused(tmp_path, {"fluid": {"drag": "stokes"}}) == (
        f"{file}: fluid.viscosity: drag = 'stokes' needs viscosity > 0 (Pa s)")
    generator = {"shape": "box", "low": [0, 0, 0], "material": "glass",
                 "particle_radius": 1e-4}
    assert refused(tmp_path, {"particles.file": None, "particles.generator": generator}) == (
        f"{file}: particles.generator.high: None is not a list of three numbers")
    clump = {"shape": "box", "low": [0, 0, 0], "material": "glass", "clump": TEMPLATE}
    assert refused(tmp_path, {"particles.file": None, "particles.generator": clump}) == (
        f"{file}: particles.generator.high: None is not a list of three numbers")
    bad = {**clump, "high": [0.006] * 3, "clump": {"centres": [[0, 0, 0]], "radii": [-1.0]}}
    assert refused(tmp_path, {"particles.file": None, "particles.generator": bad}) == (
        f"{file}: particles.generator.clump: member centres must be finite and radii > 0 (m)")
    rows = PARTICLES.splitlines()
    mixed = "\n".join([rows[0] + ",clump"] + [r + f",{k}" for r, k in
                                              zip(rows[1:], (-1, 0, 0, -1))])
    assert refused(tmp_path, {"simulation.contact_model": "none"}, particles=mixed) == (
        f"{file}: particles.file.clump: clump 0: its members have materials [0, 1]; a clump "
        "has one material")


def test_a_clump_generators_bounds_and_its_packing(tmp_path):
    from bondem.clumps import ClumpTemplate, pack_clumps
    from bondem.generate import Box
    generator = {"shape": "box", "low": [0.0, 0.0, 0.0], "high": [0.006, 0.006, 0.006],
                 "material": "glass", "clump": TEMPLATE, "solids_fraction": 0.3}
    edit = {"particles.file": None, "particles.generator": generator,
            "particles.offset": [0.02, 0.0, 0.0]}
    s = scene(tmp_path, edit)
    packed = pack_clumps(Box([0.0] * 3, [0.006] * 3),
                         ClumpTemplate(TEMPLATE["centres"], TEMPLATE["radii"]), 1.0,
                         solids_fraction=0.3, seed=0, compact=1.0, max_overlap=1e-3)
    np.testing.assert_array_equal(s.model.clump_mass, 2500 * packed["mass"])
    np.testing.assert_array_equal(s.state.clump_position, packed["centre"] + [0.02, 0, 0])
    # the principal moments of the packed clumps' inertia tensors
    np.testing.assert_allclose(np.sort(s.model.clump_inertia, axis=1),
                               np.sort(np.linalg.eigvalsh(2500 * packed["inertia"]), axis=1),
                               rtol=1e-9)
    for key, value in (("max_overlap", 0.05), ("compact", 0.5), ("compact", 1.0)):
        assert scene(tmp_path, {**edit, "particles.generator": {**generator, key: value,
                                                                "solids_fraction": 0.1}})


def test_a_mesh_clump_in_metres_needs_no_scale(tmp_path):
    import trimesh
    trimesh.creation.icosphere(radius=1e-3).export(tmp_path / "g.stl")
    generator = {"shape": "box", "low": [0.0, 0.0, 0.0], "high": [0.008, 0.008, 0.008],
                 "material": "glass", "solids_fraction": 0.2,
                 "clump": {"file": "g.stl", "spheres": 3, "resolution": 12}}
    s = scene(tmp_path, {"particles.file": None, "particles.generator": generator})
    assert s.model.n_clumps >= 1 and s.model.radius.max() <= 1e-3 * (1 + 1e-9)


def test_a_kinetic_energy_just_below_the_largest_double(tmp_path):
    # a 1.3 kg sphere at 1e154 m/s: m v^2 = 1.3e308, below the largest double (1.8e308),
    # so the run is refused for its step, not for its energy (1.5 m v^2 or m v^3 would
    # overflow)
    rows = ("x,y,z,radius,material,vx,vy,vz\n0.0,0,0,0.05,glass,1e154,0,0\n"
            "0.2,0,0,0.05,glass,0,0,0\n")
    text = refused(tmp_path, particles=rows)
    assert text.startswith(f"{tmp_path / 's.toml'}: particles.velocity: a particle at 1e+154 "
                           "m/s moves ")


def test_a_periodic_box_of_exactly_twice_the_cutoff(tmp_path):
    cutoff = 2.0 * 1.2e-3 + 0.2 * float(np.mean([1e-3, 1.2e-3, 0.9e-3, 1.1e-3]))
    s = scene(tmp_path, {"simulation.periodic": [False, False, True],
                         "simulation.box_low": [-1.0, -1.0, 0.0],
                         "simulation.box_high": [1.0, 1.0, 2.0 * cutoff]})
    assert s.model.box_length[2] == 2.0 * cutoff


@pytest.mark.parametrize("gap, warned", [(0.4, True), (0.6, False)])
def test_the_spacing_is_to_each_particles_nearest_neighbour(tmp_path, gap, warned):
    # pairs of particles 3 m apart: each one's nearest neighbour is its partner
    rows = "x,y,z,radius,material\n" + "".join(
        f"{3.0 * k + d!r},0,0,1.0,glass\n" for k in range(3) for d in (0.0, gap))
    s = scene(tmp_path, {"simulation.contact_model": "none", "simulation.end_time": 1.0},
              particles=rows)
    assert any("median spacing" in w for w in s.warnings) == warned


def test_files_that_are_not_utf8_or_not_a_grid(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(b"[simulation]\nend_time = 1e-3 # \xe9\n")
    with pytest.raises(InputError) as error:
        load_scene(path)
    assert str(error.value) == (f"{path}: line 2: byte 0xe9 is not UTF-8 text; save the file "
                                "as UTF-8")
    with h5py.File(tmp_path / "u.h5", "w") as f:
        f["velocity"] = np.zeros((2, 2, 2, 3))
    fluid = {"density": 1.2, "viscosity": 1.8e-5, "drag": "stokes", "velocity_file": "u.h5"}
    assert refused(tmp_path, {"fluid": fluid}) == (
        f"{tmp_path / 'u.h5'}: fluid.velocity_file: no attribute 'origin' (3 numbers, m)")


def test_a_mesh_wall_moves_as_its_table_says(tmp_path):
    import trimesh
    box = trimesh.creation.box(extents=(10.0, 10.0, 1.0))
    box.apply_translation((0.0, 0.0, 20.0))
    box.export(tmp_path / "lid.stl")
    lid = {"type": "mesh", "file": "lid.stl", "material": "glass", "scale": 1e-3}
    s = walls(tmp_path, {**lid, "velocity": [0.0, 0.0, -0.01]},
              {**lid, "velocity_profile": [[0.0, 0, 0, 0], [1e-4, 0, 0, -0.02]]})
    first, second = s.simulation_options["walls"]
    assert first.velocity_at(1.0).tolist() == [0.0, 0.0, -0.01]
    np.testing.assert_allclose(second.velocity_at(5e-5), [0, 0, -0.01], rtol=1e-12)

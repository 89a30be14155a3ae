"""Scene loading (SPEC 4): a valid scene gives the right Model/State; every bad input
gives exit status 2 and one line naming the file and the key (SPEC 5)."""
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.scene import load_scene, parse_override
from scenetools import cube_scene


def test_valid_scene_builds_model(tmp_path):
    """Reference: the lattice written by cube_scene (27 particles, 54 bonds, L0 = 2 r)."""
    scene = load_scene(cube_scene(tmp_path))
    model, state = scene.model, scene.state
    assert model.n_particles == 27 and model.n_bonds == 54
    np.testing.assert_allclose(model.bond_initial_length, 2e-3, rtol=1e-12)
    np.testing.assert_allclose(model.mass, 2500.0 * 4 / 3 * np.pi * 1e-9, rtol=1e-12)
    np.testing.assert_array_equal(model.gravity, [0.0, 0.0, -9.81])
    assert model.bond_materials[0].normal_strength == 3e5
    assert scene.end_time == 2e-4 and scene.save_every == 2e-5
    # velocities from the CSV columns: x-layers at -0.4, 0, +0.4 m/s
    np.testing.assert_allclose(np.unique(state.velocity[:, 0]), [-0.4, 0.0, 0.4], atol=1e-15)
    assert scene.simulation_options["time_step"] == "auto"


def test_overrides_change_values_and_text(tmp_path):
    path = cube_scene(tmp_path)
    scene = load_scene(path, {"simulation.end_time": 1e-4, "materials.glass.density": 2000.0,
                              "particles.velocity": [0.0, 0.0, 1.0]})
    assert scene.end_time == 1e-4
    np.testing.assert_allclose(scene.model.mass, 2000.0 * 4 / 3 * np.pi * 1e-9, rtol=1e-12)
    np.testing.assert_allclose(scene.state.velocity[:, 2], 1.0)
    assert "density = 2000.0" in scene.text and "end_time = 0.0001" in scene.text
    # the text after overrides loads back to the same scene
    (tmp_path / "again.toml").write_text(scene.text)
    again = load_scene(tmp_path / "again.toml")
    np.testing.assert_array_equal(again.model.mass, scene.model.mass)
    assert parse_override("simulation.time_step=1e-7") == ("simulation.time_step", 1e-7)
    assert parse_override("simulation.backend=cpu") == ("simulation.backend", "cpu")


def _replace(path, old, new):
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))


BAD_SCENES = [
    # (description, edit of the scene text or a CSV file, key expected in the message)
    ("unknown key", ("scene.toml", "end_time = ", "end_tme = 1.0\nend_time = "),
     "simulation.end_tme"),
    ("unknown table", ("scene.toml", "[materials.glass]", "[material.glass]\n[materials.glass]"),
     "material"),
    ("wrong type", ("scene.toml", "end_time = 0.0002", 'end_time = "soon"'),
     "simulation.end_time"),
    ("negative density", ("scene.toml", "density = 2500.0", "density = -2500.0"),
     "materials.glass.density"),
    ("Poisson ratio 0.5", ("scene.toml", "poisson_ratio = 0.3\n\n[bond", "poisson_ratio = 0.5\n\n[bond"),
     "materials.glass.poisson_ratio"),
    ("Poisson ratio -1", ("scene.toml", "poisson_ratio = 0.3\nnormal", "poisson_ratio = -1.0\nnormal"),
     "bond_materials.binder.poisson_ratio"),
    ("missing material", ("particles.csv", ",glass,", ",steel,"), "particles.material"),
    ("missing bond material", ("bonds.csv", "binder", "glue"), "bonds.material"),
    ("bond index out of range", ("bonds.csv", "\n0,1,", "\n0,27,"), "bonds.file"),
    ("duplicate bond", ("bonds.csv", "i,j,diameter,material\n",
                        "i,j,diameter,material\n1,0,0.001,binder\n"), "bonds.file"),
    ("bonded particles at zero distance", ("particles.csv", "\n0.0,0.0,0.002,",
                                           "\n0.0,0.0,0.0,"), "bonds.file"),
    ("missing required key", ("scene.toml", "young_modulus = 1e8\npoisson_ratio = 0.3\n\n[bond",
                              "poisson_ratio = 0.3\n\n[bond"), "materials.glass.young_modulus"),
    ("bad breakage", ("scene.toml", "tangential_strength = 300000.0",
                      'tangential_strength = 300000.0\nbreakage = "sometimes"'),
     "bond_materials.binder.breakage"),
    ("bad backend", ("scene.toml", 'time_step = "auto"', 'time_step = "auto"\nbackend = "tpu"'),
     "simulation.backend"),
    ("negative time step", ("scene.toml", 'time_step = "auto"', "time_step = -1e-6"),
     "simulation.time_step"),
    ("time step above the stable limit", ("scene.toml", 'time_step = "auto"', "time_step = 1e-3"),
     "simulation.time_step"),
    ("gravity not a vector", ("scene.toml", "gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, -9.81]"),
     "simulation.gravity"),
    ("missing CSV file", ("scene.toml", 'file = "bonds.csv"', 'file = "nobonds.csv"'), "bonds.file"),
    ("CSV missing column", ("particles.csv", "x,y,z,radius,", "x,y,zz,radius,"), "particles.file"),
    ("CSV not a number", ("particles.csv", "\n0.0,0.0,0.002,", "\n0.0,0.0,abc,"), "particles.file"),
    ("wall without material", ("scene.toml", "[bonds]",
                               '[[walls]]\ntype = "plane"\npoint = [0.0, 0.0, 0.0]\n'
                               'normal = [0.0, 0.0, 1.0]\nmaterial = "steel"\n\n[bonds]'),
     "walls.0.material"),
    ("bad contact model", ("scene.toml", 'contact_model = "none"', 'contact_model = "glue"'),
     "simulation.contact_model"),
    ("periodic without box", ("scene.toml", 'contact_model = "none"',
                              'contact_model = "none"\nperiodic = [true, false, false]'),
     "simulation.periodic"),
    ("box high below low", ("scene.toml", 'contact_model = "none"',
                            'contact_model = "none"\nbox_low = [0.0, 0.0, 0.0]\n'
                            'box_high = [1.0, -1.0, 1.0]'), "simulation.box_high"),
    ("save_every below the time step", ("scene.toml", "save_every = 2e-05",
                                        "save_every = 1e-9"), "simulation.save_every"),
    ("restitution above 1", ("scene.toml", "density = 2500.0", "density = 2500.0\nrestitution = 1.5"),
     "materials.glass.restitution"),
]


@pytest.mark.parametrize("what, edit, key", BAD_SCENES, ids=[c[0] for c in BAD_SCENES])
def test_bad_input_exit_2_names_key(tmp_path, what, edit, key):
    path = cube_scene(tmp_path)
    name, old, new = edit
    _replace(tmp_path / name, old, new)
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 2, (what, result.output)
    message = result.stderr.strip()
    assert "\n" not in message and "Traceback" not in result.output
    assert str(path) in message and key in message, message


def test_missing_scene_file_and_bad_override(tmp_path):
    result = CliRunner().invoke(main, ["info", str(tmp_path / "none.toml")])
    assert result.exit_code == 2 and "none.toml" in result.stderr
    path = cube_scene(tmp_path)
    result = CliRunner().invoke(main, ["run", str(path), "--set", "materials.glass.density=-1"])
    assert result.exit_code == 2 and "materials.glass.density" in result.stderr


def test_info_reports_counts_mass_step(tmp_path):
    """Reference: total mass 27 m, stable step = 0.2 x the bond axial time scale
    sqrt(m_red L0 / (E A_b)) for this lattice (bond-limited)."""
    result = CliRunner().invoke(main, ["info", str(cube_scene(tmp_path))])
    assert result.exit_code == 0, result.output
    mass = 2500.0 * 4 / 3 * np.pi * 1e-9
    step = 0.2 * np.sqrt(0.5 * mass * 2e-3 / (1e8 * np.pi * 0.25e-6))
    assert "27" in result.output and "54" in result.output
    assert f"{27 * mass:.6g} kg" in result.output
    assert f"{step:.4g} s" in result.output and "bond_axial" in result.output


GENERATED = """\
[simulation]
end_time = 1e-4
contact_model = "none"

[materials.glass]
density = 2500.0
young_modulus = 1e8

[bond_materials.binder]
young_modulus = 1e8

[particles]
generator = {shape = "sphere", radius = 2e-3, particle_radius = 0.3e-3, seed = 1, material = "glass"}
velocity = [0.0, 0.0, -1.0]

[bonds]
max_gap = 2e-5
diameter_ratio = 0.5
material = "binder"
"""


def test_generated_particles_and_bonds(tmp_path):
    """Reference: brute force over all pairs (scipy cKDTree) for the bonds from max_gap;
    every particle inside the 2 mm sphere."""
    pytest.importorskip("bondem.generate")
    from scipy.spatial import cKDTree
    (tmp_path / "gen.toml").write_text(GENERATED)
    scene = load_scene(tmp_path / "gen.toml")
    model, state = scene.model, scene.state
    assert model.n_particles > 50
    assert np.all(np.linalg.norm(state.position, axis=1) + model.radius <= 2e-3 * (1 + 1e-9))
    np.testing.assert_array_equal(state.velocity, np.tile([0.0, 0.0, -1.0], (model.n_particles, 1)))
    pairs = cKDTree(state.position).query_pairs(0.6e-3 + 2e-5, output_type="ndarray")
    gap = np.linalg.norm(state.position[pairs[:, 0]] - state.position[pairs[:, 1]], axis=1) - 0.6e-3
    expected = {tuple(p) for p in np.sort(pairs[gap <= 2e-5], axis=1).tolist()}
    assert {tuple(p) for p in np.sort(model.bond_pairs, axis=1).tolist()} == expected
    np.testing.assert_allclose(model.bond_diameter, 0.3e-3, rtol=1e-12)


def test_bonds_from_gap_match_lattice_bonds(tmp_path):
    """Reference: the cube lattice's 54 nearest-neighbour bonds written to bonds.csv; with
    max_gap = 1 nm the generated bonds must be the same pairs."""
    path = cube_scene(tmp_path)
    from_file = load_scene(path).model
    _replace(path, 'file = "bonds.csv"', 'max_gap = 1e-9\ndiameter = 1e-3\nmaterial = "binder"')
    generated = load_scene(path).model
    key = lambda pairs: {tuple(p) for p in np.sort(pairs, axis=1).tolist()}  # noqa: E731
    assert key(generated.bond_pairs) == key(from_file.bond_pairs)
    np.testing.assert_array_equal(generated.bond_diameter, 1e-3)


def test_walls_from_scene(tmp_path):
    """A plane and an STL mesh wall (a 1 cm box written by trimesh) become bondem.walls
    objects with the scene's material, velocity and scale."""
    walls = pytest.importorskip("bondem.walls")
    import trimesh
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(tmp_path / "box.stl")
    path = cube_scene(tmp_path, extra="""
        [[walls]]
        type = "plane"
        point = [0.0, 0.0, -0.01]
        normal = [0.0, 0.0, 2.0]
        material = "glass"
        velocity = [0.0, 0.0, 0.5]

        [[walls]]
        type = "mesh"
        file = "box.stl"
        material = "glass"
        scale = 0.01
        rotation_center = [0.0, 0.0, 0.05]
        """)
    _replace(path, "[particles]", "[particles]\noffset = [0.0, 0.0, 0.05]")
    scene = load_scene(path)
    plane, mesh = scene.simulation_options["walls"]
    assert isinstance(plane, walls.PlaneWall) and isinstance(mesh, walls.MeshWall)
    sim = scene.make_simulation()
    np.testing.assert_allclose(sim.wall_positions()[0], [0.0, 0.0, -0.01])
    assert len(sim.walls) == 2
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 0 and "walls:           2" in result.output
    _replace(path, 'file = "box.stl"', 'file = "nobox.stl"')
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 2 and "walls.1.file" in result.stderr


def test_first_hour_inputs(tmp_path):
    """A short run without save_every gets a frame every step (the docs' rounded default);
    diameter_ratio above 1, --checkpoint-minutes nan and --out '' are exit 2 naming the key."""
    from pathlib import Path

    from click.testing import CliRunner

    from bondem.cli import main
    from bondem.scene import load_scene
    impact = Path(__file__).resolve().parents[1] / "examples" / "impact.toml"
    text = "\n".join(line for line in impact.read_text().splitlines()
                     if not line.startswith("save_every"))
    short = tmp_path / "short.toml"
    short.write_text(text.replace("end_time = 1.0e-3", "end_time = 2e-5"))
    scene = load_scene(short)
    dt = scene.make_simulation().time_step
    assert 2e-5 / 100 < dt <= scene.save_every <= 2e-5
    runner = CliRunner()
    cases = [(["--set", "bonds.diameter_ratio=5"], "bonds.diameter_ratio"),
             (["--checkpoint-minutes", "nan"], "--checkpoint-minutes"),
             (["--out", ""], "--out")]
    for extra, key in cases:
        args = ["run", str(impact), "--no-progress"] + extra
        if "--out" not in extra:
            args += ["--out", str(tmp_path / "o")]
        result = runner.invoke(main, args)
        assert result.exit_code == 2 and key in result.stderr, (extra, result.output)
        assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_a_units_slip_is_warned_about_at_load_time(tmp_path):
    """CSV radii of 1.0 m at 2 mm spacing (mm meant as m): every bonded pair overlaps by
    ~500 radii and the spacing is 1/500 of a radius; a plane and a mesh triangle cut
    through the bottom layer (centres 0.5 mm from them, radius 1 mm: 50 % deep). Each is
    a warning naming what to check; the same scene with its walls 1.2 mm off (20 %) and
    mm radii warns of nothing."""
    import trimesh
    corners = np.array([[-0.05, -0.05, 0.0], [0.05, -0.05, 0.0], [0.0, 0.05, 0.0]])
    walls = """
        [[walls]]
        type = "plane"
        point = [0.0, 0.0, -{gap}]
        normal = [0.0, 0.0, 1.0]
        material = "glass"

        [[walls]]
        type = "mesh"
        file = "roof.stl"
        material = "glass"
        """
    path = cube_scene(tmp_path, end_time=0.1, save_every=0.01, extra=walls.format(gap=1.2e-3))
    top = 4e-3 + 1.2e-3
    trimesh.Trimesh(corners + [0.0, 0.0, top], [[0, 1, 2]], process=False).export(
        tmp_path / "roof.stl")
    assert load_scene(path).warnings == []
    path.write_text(path.read_text().replace("-1.2e-3", "-0.0005")
                    .replace("-0.0012", "-0.0005"))
    trimesh.Trimesh(corners + [0.0, 0.0, 4.5e-3], [[0, 1, 2]], process=False).export(
        tmp_path / "roof.stl")
    warnings = load_scene(path).warnings
    assert len(warnings) == 2, warnings
    assert "walls.0: 9 particle(s) overlap the wall" in warnings[0]
    assert "walls.1: 9 particle(s) overlap the wall" in warnings[1]
    csv = tmp_path / "particles.csv"
    csv.write_text(csv.read_text().replace(",0.001,glass,", ",1.0,glass,"))
    warnings = load_scene(path).warnings
    assert any("54 of 54 bonded pairs overlap by more than the smaller radius" in w
               and "particles.csv line" in w and "wrong unit" in w for w in warnings)
    assert any("median spacing 0.002 m is less than half their median radius 1 m" in w
               for w in warnings)
    result = CliRunner().invoke(main, ["info", str(path)])
    assert "wrong unit" in result.stderr
    path.write_text(path.read_text().replace("density = 2500.0", "density = 2.5"))
    (warning,) = [w for w in load_scene(path).warnings if "density" in w]
    assert "materials.glass.density: 2.5 kg/m^3" in warning and "g/cm^3" in warning

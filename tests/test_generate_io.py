"""CSV particle/bond files (SPEC 4) and the ``bondem generate`` command."""
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.errors import InputError
from bondem.generate import coordination_number
from bondem.io.csv_files import read_bonds, read_particles, write_bonds, write_particles


def test_particle_and_bond_csv_round_trip_exactly(tmp_path):
    rng = np.random.default_rng(0)
    position = rng.normal(size=(50, 3)) * 1e-3
    radius = rng.uniform(1e-4, 2e-4, 50)
    velocity = rng.normal(size=(50, 3))
    spin = rng.normal(size=(50, 3))
    names = np.where(np.arange(50) % 2, "glass", "steel")
    write_particles(tmp_path / "p.csv", position, radius, names, velocity, spin)
    data = read_particles(tmp_path / "p.csv")
    assert np.array_equal(np.stack([data["x"], data["y"], data["z"]], 1), position)
    assert np.array_equal(data["radius"], radius)
    assert np.array_equal(np.stack([data["vx"], data["vy"], data["vz"]], 1), velocity)
    assert np.array_equal(np.stack([data["wx"], data["wy"], data["wz"]], 1), spin)
    assert data["material"].tolist() == names.tolist()

    write_particles(tmp_path / "q.csv", position, radius, "glass")
    assert "vx" not in read_particles(tmp_path / "q.csv")
    assert (tmp_path / "q.csv").read_text().splitlines()[0] == "x,y,z,radius,material"

    pairs = np.array([[0, 1], [2, 7], [3, 49]])
    diameter = np.array([1e-4, 1.5e-4, 0.3333e-4])
    write_bonds(tmp_path / "b.csv", pairs, diameter, "binder")
    bonds = read_bonds(tmp_path / "b.csv", n_particles=50)
    assert np.array_equal(np.stack([bonds["i"], bonds["j"]], 1), pairs)
    assert np.array_equal(bonds["diameter"], diameter)
    assert bonds["material"].tolist() == ["binder"] * 3


@pytest.mark.parametrize("text, key, where", [
    ("x,y,z,radius,material\n0,0,0,1e-3,glass\n0,zero,0,1e-3,glass\n", "y", "line 3"),
    ("x,y,z,radius,material\n0,0,0,-1e-3,glass\n", "radius", "line 2"),
    ("x,y,radius,material\n0,0,1e-3,glass\n", "z", "missing column"),
    ("x,y,z,radius,material,vx\n0,0,0,1e-3,glass,1\n", None, "vx,vy,vz"),
    ("x,y,z,radius,material,colour\n0,0,0,1e-3,glass,red\n", "colour", "unknown column"),
    ("x,y,z,radius,material\n0,0,0,1e-3\n", None, "line 2: 4 values"),
])
def test_bad_particle_files_name_line_and_column(tmp_path, text, key, where):
    path = tmp_path / "p.csv"
    path.write_text(text)
    with pytest.raises(InputError) as error:
        read_particles(path)
    assert error.value.key == key and where in str(error.value) and "p.csv" in str(error.value)


def test_bad_bond_files(tmp_path):
    path = tmp_path / "b.csv"
    path.write_text("i,j,diameter,material\n0,1,1e-4,binder\n1,5,1e-4,binder\n")
    with pytest.raises(InputError, match="line 3: index 5") as error:
        read_bonds(path, n_particles=3)
    assert error.value.key == "j"
    path.write_text("i,j,diameter,material\n0,-1,1e-4,binder\n")
    with pytest.raises(InputError, match="line 2"):
        read_bonds(path)


def test_cli_writes_readable_files(tmp_path):
    out = tmp_path / "body"
    result = CliRunner().invoke(main, [
        "generate", "--shape", "sphere", "--size", "4e-3", "--radius", "2.5e-4",
        "--solids-fraction", "0.5", "--max-gap", "1e-5", "--bond-diameter-ratio", "0.5",
        "--seed", "1", "--material", "glass", "--bond-material", "binder", "--out", str(out)])
    assert result.exit_code == 0, result.output
    particles = read_particles(out / "particles.csv")
    n = particles["radius"].size
    assert abs(n - 0.5 * 8 ** 3) <= 0.5  # (R / r)^3 particles fill the fraction
    bonds = read_bonds(out / "bonds.csv", n_particles=n)
    assert f"particles: {n}" in result.output and f"bonds: {bonds['i'].size}" in result.output
    cn = coordination_number(np.stack([bonds["i"], bonds["j"]], 1), n)
    assert f"coordination number: {cn:.3f}" in result.output
    assert set(bonds["material"]) == {"binder"} and set(particles["material"]) == {"glass"}
    # reach: |x| + r <= R
    reach = np.sqrt(particles["x"] ** 2 + particles["y"] ** 2 + particles["z"] ** 2)
    assert np.all(reach + particles["radius"] <= 2e-3 * (1 + 1e-12))


def test_cli_from_scene_and_bad_input(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text("""
[particles]
generator = {shape = "box", size = [4e-3, 3e-3, 3e-3], particle_radius = 2.5e-4, solids_fraction = 0.5, seed = 4, material = "glass"}
[bonds]
max_gap = 2e-5
diameter = 1e-4
material = "binder"
max_per_particle = 4
""")
    result = CliRunner().invoke(main, ["generate", "--from-scene", str(scene), "--out",
                                       str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    bonds = read_bonds(tmp_path / "out" / "bonds.csv")
    assert np.bincount(np.r_[bonds["i"], bonds["j"]]).max() <= 4
    assert np.all(bonds["diameter"] == 1e-4)

    scene.write_text('[particles]\ngenerator = {shape = "box", size = 4e-3, '
                     'particle_radius = 2.5e-4, solids_fraction = 0.95, material = "glass"}\n')
    result = CliRunner().invoke(main, ["generate", "--from-scene", str(scene)])
    assert result.exit_code == 2
    assert "particles.generator.solids_fraction" in result.output

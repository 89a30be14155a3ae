"""Particle and bond CSV files (bondem.io.csv_files, SPEC 4) against the format: what is
written reads back to the same doubles, columns come in any order, blank lines are
skipped without losing the line count, and each defect is named by file, line, column
and the allowed values, in the whole message."""
import numpy as np
import pytest

from bondem.errors import InputError
from bondem.io.csv_files import (float_text, read_bonds, read_particles, write_bonds,
                                 write_particles)


def write(tmp_path, text, name="p.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_written_particles_read_back_to_the_same_doubles(tmp_path):
    rng = np.random.default_rng(4)
    position = rng.normal(size=(5, 3)) * [1e-3, 2e-4, 7.0]
    radius = rng.uniform(1e-5, 1e-3, 5)
    velocity = rng.normal(size=(5, 3))
    spin = rng.normal(size=(5, 3)) * 1e3
    path = tmp_path / "p.csv"
    write_particles(path, position, radius, ["glass", "steel", "glass", "a b", "c"],
                    velocity=velocity, angular_velocity=spin, clump=[0, 0, -1, 1, 1])
    data = read_particles(path)
    for k, name in enumerate("xyz"):
        np.testing.assert_array_equal(data[name], position[:, k])
        np.testing.assert_array_equal(data["v" + name], velocity[:, k])
        np.testing.assert_array_equal(data["w" + name], spin[:, k])
    np.testing.assert_array_equal(data["radius"], radius)
    assert data["material"].tolist() == ["glass", "steel", "glass", "a b", "c"]
    assert data["material"].dtype == object
    assert data["clump"].tolist() == [0, 0, -1, 1, 1] and data["clump"].dtype == np.int64
    assert data["line"].tolist() == [2, 3, 4, 5, 6]
    assert path.read_text().splitlines()[0] == "x,y,z,radius,material,vx,vy,vz,wx,wy,wz,clump"


def test_a_spin_without_velocity_writes_zero_velocities_and_one_name_serves_all(tmp_path):
    path = tmp_path / "p.csv"
    write_particles(path, [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]], 0.5, "glass",
                    angular_velocity=[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    assert path.read_text() == ("x,y,z,radius,material,vx,vy,vz,wx,wy,wz\n"
                                "0.0,1.0,2.0,0.5,glass,0.0,0.0,0.0,1.0,2.0,3.0\n"
                                "3.0,4.0,5.0,0.5,glass,0.0,0.0,0.0,4.0,5.0,6.0\n")
    write_particles(path, [[0.1, 0.2, 0.3]], [1e-3], ["x"], velocity=[[1.5, 0, 0]])
    assert path.read_text() == "x,y,z,radius,material,vx,vy,vz\n0.1,0.2,0.3,0.001,x,1.5,0.0,0.0\n"
    write_particles(path, [[0.1, 0.2, 0.3]], [1e-3], ["x"])
    assert path.read_text() == "x,y,z,radius,material\n0.1,0.2,0.3,0.001,x\n"


def test_written_bonds_read_back(tmp_path):
    path = tmp_path / "b.csv"
    write_bonds(path, [[0, 3], [2, 1]], [1.2345678901234567e-4, 2e-4], "binder")
    assert path.read_text() == "i,j,diameter,material\n0,3,0.00012345678901234567,binder\n" \
                               "2,1,0.0002,binder\n"
    data = read_bonds(path, n_particles=4)
    assert data["i"].tolist() == [0, 2] and data["j"].tolist() == [3, 1]
    assert data["i"].dtype == np.int64
    assert data["diameter"].tolist() == [1.2345678901234567e-4, 2e-4]
    assert data["material"].tolist() == ["binder", "binder"]
    assert float_text(np.float64(0.1)) == "0.1" and float_text(3) == "3.0"


def test_columns_in_any_order_spaces_and_blank_lines(tmp_path):
    path = write(tmp_path, "\ufeffmaterial, radius ,z,y,x,fixed\n"
                           "glass, 1e-3 ,3,2,1,1\n\n , ,\nsteel,2e-3,6,5,4,0\n")
    data = read_particles(path)
    assert data["x"].tolist() == [1.0, 4.0] and data["z"].tolist() == [3.0, 6.0]
    assert data["radius"].tolist() == [1e-3, 2e-3]
    assert data["material"].tolist() == ["glass", "steel"]
    assert data["fixed"].tolist() == [True, False] and data["fixed"].dtype == np.bool_
    assert data["line"].tolist() == [2, 5]
    # an empty clump cell is a free sphere
    data = read_particles(write(tmp_path, "x,y,z,radius,material,clump\n0,0,0,1,a,\n"
                                          "0,0,3,1,a,4\n"))
    assert data["clump"].tolist() == [-1, 4]


HEADER = "x,y,z,radius,material\n"
PARTICLE_DEFECTS = [
    ("", "empty file; expected a header line x,y,z,radius,material", None),
    ("x,y,z,radius,material,colour\n", "line 1: unknown column 'colour'; allowed: "
     "clump, fixed, material, radius, vx, vy, vz, wx, wy, wz, x, y, z", "colour"),
    ("x,y,z,radius,material,fixd\n", "line 1: unknown column 'fixd'; did you mean "
     "'fixed'? allowed: clump, fixed, material, radius, vx, vy, vz, wx, wy, wz, x, y, z",
     "fixd"),
    ("x,y,z,radius,material,x\n", "line 1: the column 'x' appears 2 times; give each "
     "column once", "x"),
    ("x,y,radius,material\n", "line 1: missing column 'z'; the header must name "
     "x,y,z,radius,material", "z"),
    ("x,y,z,radius,material,vx,vz\n", "line 1: columns vx,vy,vz come together; found only "
     "vx,vz", None),
    (HEADER, "no particle rows", None),
    (HEADER + "0,0,0,1,a\n\n0,0,0,1\n", "line 4: 4 values, the header has 5", None),
    (HEADER + "0,0,0,1,\n", "line 2: empty material name", "material"),
    (HEADER + "0,0,zero,1,a\n", "line 2: 'zero' is not a number", "z"),
    (HEADER + "0,nan,0,1,a\n", "line 2: 'nan'; allowed: a finite number", "y"),
    (HEADER + "0,0,0,-1e-3,a\n", "line 2: '-1e-3'; allowed: a finite number > 0", "radius"),
    (HEADER + "0,0,0,0,a\n", "line 2: '0'; allowed: a finite number > 0", "radius"),
    (HEADER + "0,0,0,inf,a\n", "line 2: 'inf'; allowed: a finite number > 0", "radius"),
    ("x,y,z,radius,material,fixed\n0,0,0,1,a,2\n", "line 2: '2'; allowed: 0 or 1", "fixed"),
    ("x,y,z,radius,material,fixed\n0,0,0,1,a,true\n", "line 2: 'true'; allowed: 0 or 1",
     "fixed"),
    ("x,y,z,radius,material,clump\n0,0,0,1,a,-2\n", "line 2: '-2'; allowed: a clump index "
     ">= 0, or -1 (or empty) for a free sphere", "clump"),
    ("x,y,z,radius,material,clump\n0,0,0,1,a,1.5\n", "line 2: '1.5'; allowed: a clump "
     "index >= 0, or -1 (or empty) for a free sphere", "clump"),
    ("x,y,z,radius,material,clump\n0,0,0,1,a,4611686018427387904\n",
     "line 2: '4611686018427387904'; allowed: a clump index >= 0, or -1 (or empty) for a "
     "free sphere", "clump"),
]


@pytest.mark.parametrize("text, message, key", PARTICLE_DEFECTS)
def test_a_particle_file_defect_names_file_line_and_column(tmp_path, text, message, key):
    path = write(tmp_path, text)
    with pytest.raises(InputError) as error:
        read_particles(path)
    assert error.value.key == key and error.value.file == str(path)
    assert error.value.reason == message


def test_the_largest_clump_index_and_a_missing_or_foreign_file(tmp_path):
    data = read_particles(write(tmp_path, "x,y,z,radius,material,clump\n"
                                          "0,0,0,1,a,4611686018427387903\n"))
    assert data["clump"].tolist() == [2 ** 62 - 1]
    with pytest.raises(InputError) as error:
        read_particles(tmp_path / "none.csv")
    assert error.value.reason == "cannot open: No such file or directory"
    assert error.value.file == str(tmp_path / "none.csv")
    path = tmp_path / "latin.csv"
    path.write_bytes(HEADER.encode() + b"0,0,0,1,caf\xe9\n")
    with pytest.raises(InputError) as error:
        read_particles(path)
    assert error.value.reason == "line 2: byte 0xe9 is not UTF-8 text; save the file as UTF-8"
    assert error.value.file == str(path)


BOND_HEADER = "i,j,diameter,material\n"
BOND_DEFECTS = [
    (BOND_HEADER + "0,1.0,1e-3,b\n", "line 2: '1.0' is not an integer index >= 0", "j"),
    (BOND_HEADER + "-1,1,1e-3,b\n", "line 2: -1 is not an integer index in [0, 2^62)", "i"),
    (BOND_HEADER + "0,4611686018427387904,1e-3,b\n",
     "line 2: 4611686018427387904 is not an integer index in [0, 2^62)", "j"),
    (BOND_HEADER + "0,46116860184273879040000,1e-3,b\n",
     "line 2: 46116860184273879040... is not an integer index in [0, 2^62)", "j"),
    # up to 20 characters shown whole
    (BOND_HEADER + "0,46116860184273879040,1e-3,b\n",
     "line 2: 46116860184273879040 is not an integer index in [0, 2^62)", "j"),
    (BOND_HEADER + "0,461168601842738790400,1e-3,b\n",
     "line 2: 46116860184273879040... is not an integer index in [0, 2^62)", "j"),
    (BOND_HEADER + "0,1,1e-3,b\n\n2,2,1e-3,b\n", "line 4: i = j = 2", "j"),
    (BOND_HEADER + "0,1,1e-3,b\n1,5,1e-3,b\n", "line 3: index 5 is outside [0, 4] (rows of "
     "the particle file)", "j"),
    (BOND_HEADER + "0,1,1e-3,b\n5,1,1e-3,b\n", "line 3: index 5 is outside [0, 4] (rows of "
     "the particle file)", "i"),
    (BOND_HEADER + "0,1,0.0,b\n", "line 2: '0.0'; allowed: a finite number > 0", "diameter"),
    ("i,j,diameter\n", "line 1: missing column 'material'; the header must name "
     "i,j,diameter,material", "material"),
]


@pytest.mark.parametrize("text, message, key", BOND_DEFECTS)
def test_a_bond_file_defect_names_file_line_and_column(tmp_path, text, message, key):
    path = write(tmp_path, text, "b.csv")
    with pytest.raises(InputError) as error:
        read_bonds(path, n_particles=5)
    assert error.value.key == key and error.value.file == str(path)
    assert error.value.reason == message


def test_bond_indices_are_checked_only_against_a_given_particle_count(tmp_path):
    path = write(tmp_path, BOND_HEADER + "0,4,1e-3,b\n4,9,1e-3,b\n", "b.csv")
    assert read_bonds(path)["j"].tolist() == [4, 9]
    # the last row of five particles is index 4
    assert read_bonds(write(tmp_path, BOND_HEADER + "0,4,1e-3,b\n", "c.csv"),
                      n_particles=5)["j"].tolist() == [4]


def test_a_bond_file_without_rows_and_large_indices(tmp_path):
    data = read_bonds(write(tmp_path, BOND_HEADER, "b.csv"))
    assert {k: (v.dtype, v.size) for k, v in data.items()} == {
        "i": (np.int64, 0), "j": (np.int64, 0), "diameter": (np.float64, 0),
        "material": (object, 0), "line": (np.int64, 0)}
    data = read_bonds(write(tmp_path, BOND_HEADER + "200,299,1e-3,b\n", "c.csv"),
                      n_particles=300)
    assert data["i"].tolist() == [200] and data["j"].tolist() == [299]


def test_files_are_written_with_unix_line_ends_and_integer_rows(tmp_path):
    # pairs as a float array (as np.loadtxt gives them) are written as integer rows;
    # one diameter serves every bond
    path = tmp_path / "b.csv"
    write_bonds(path, np.array([[0.0, 1.0], [1.0, 2.0], [2.0, 3.0]]), 1e-4, ["a", "b", "c"])
    assert path.read_bytes() == (b"i,j,diameter,material\n0,1,0.0001,a\n1,2,0.0001,b\n"
                                 b"2,3,0.0001,c\n")
    assert read_bonds(path, n_particles=4)["j"].tolist() == [1, 2, 3]
    path = tmp_path / "p.csv"
    write_particles(path, [[0, 1, 2]], [1], ["\u00e9"], velocity=[[1, 0, 0]],
                    angular_velocity=[[0, 0, 3]])
    assert path.read_bytes() == ("x,y,z,radius,material,vx,vy,vz,wx,wy,wz\n"
                                 "0.0,1.0,2.0,1.0,\u00e9,1.0,0.0,0.0,0.0,0.0,3.0\n"
                                 ).encode("utf-8")

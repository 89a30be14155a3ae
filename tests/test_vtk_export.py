"""ParaView export (bondem.io.vtk.export_vtk) of a results file written by hand, read back
with VTK's own reader: every array equals what the file holds or its definition (speed
|v|, the fragments of the intact bonds, a broken bond drawn at the midpoint of the last
frame it was intact, also when that frame is not written, a wall contact drawn one radius
against its force, a plane as a square about the particles' centroid, a turning mesh),
and the .pvd index lists each file with its frame's time."""
import math
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

from bondem.io.vtk import export_vtk, plane_square

vtk = pytest.importorskip("vtk")
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402

TIMES = np.array([0.0, 1e-3, 2e-3, 3e-3])
RADIUS = np.array([1e-3, 2e-3, 1.5e-3, 1e-3])
MASS = np.array([1.0, 8.0, 3.4, 1.0]) * 1e-5
PAIRS = np.array([[0, 1], [1, 2], [2, 3]])
ACTIVE = np.array([[1, 1, 1], [1, 1, 1], [1, 0, 1], [1, 0, 0]], dtype=bool)
MESH = {"vertices": np.array([[0.0, 0, 0], [1e-2, 0, 0], [0, 1e-2, 0]]) + [5e-3, 0, 0],
        "triangles": np.array([[0, 1, 2]])}


def write_results(path, fragments=None):
    rng = np.random.default_rng(5)
    frames, n, b = len(TIMES), 4, 3
    position = np.array([[0.0, 0, 0], [3e-3, 0, 0], [6.5e-3, 1e-3, 0], [9e-3, 1e-3, 0]])
    # drifting at (1, 0.5, -0.2) m/s, each particle jittered
    position = (position + TIMES[:, None, None] * [[1.0, 0.5, -0.2]]
                + rng.normal(scale=1e-5, size=(frames, n, 3)))
    with h5py.File(path, "w") as f:
        f["time"] = TIMES
        f["particles/radius"] = RADIUS
        f["particles/mass"] = MASS
        f["particles/material"] = np.array([0, 1, 0, 1], dtype=np.int32)
        f["particles/position"] = position
        f["particles/velocity"] = rng.normal(size=(frames, n, 3))
        f["particles/angular_velocity"] = rng.normal(size=(frames, n, 3))
        f["particles/force"] = rng.normal(size=(frames, n, 3))
        f["particles/field_force"] = rng.normal(size=(frames, n, 3))
        f["bonds/pairs"] = PAIRS
        f["bonds/diameter"] = np.array([1e-3, 2e-3, 1.5e-3])
        f["bonds/material"] = np.array([0, 1, 0], dtype=np.int32)
        f["bonds/break_mode"] = np.array([0, 1, 3], dtype=np.int8)
        f["bonds/active"] = ACTIVE
        f["bonds/force"] = rng.normal(size=(frames, b, 3))
        f["bonds/normal_moment"] = rng.normal(size=(frames, b, 3)) * 1e-3
        f["bonds/tangential_moment"] = rng.normal(size=(frames, b, 3)) * 1e-3
        # contacts: one pair in frame 0, none in frame 1, a pair and a wall contact
        # (with wall 1) in frame 2, one wall contact (wall 0) in frame 3
        f["contacts/end"] = np.array([1, 1, 3, 4])
        f["contact_rows/i"] = np.array([0, 1, 3, 2])
        f["contact_rows/j"] = np.array([1, 2, -2, -1])
        f["contact_rows/force"] = np.array([[1.0, 0, 0], [0, 2.0, 0], [0, 0, -3.0],
                                            [0, 4.0, 0]])
        g = f.create_group("walls/geometry")
        g["type"] = np.array([0, 1])
        g["point"] = np.array([[0.0, -5e-3, 0], [0, 0, 0]])
        g["normal"] = np.array([[0.0, 1, 0], [0, 0, 1]])
        g["velocity"] = np.array([[0.0, 1.0, 0], [0, 0, 0.5]])
        g["angular_velocity"] = np.array([[0.0, 0, 0], [0, 0, 100.0]])
        g["rotation_center"] = np.array([[0.0, 0, 0], [5e-3, 0, 0]])
        g["mesh1/vertices"] = MESH["vertices"]
        g["mesh1/triangles"] = MESH["triangles"]
        f["walls/force"] = rng.normal(size=(frames, 2, 3))
        if fragments is not None:
            f["particles/fragment"] = fragments
    return path, position


def read(path):
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def point_array(data, name):
    return vtk_to_numpy(data.GetPointData().GetArray(name))


def cell_array(data, name):
    return vtk_to_numpy(data.GetCellData().GetArray(name))


def test_the_particles_and_the_index(tmp_path):
    path, position = write_results(tmp_path / "results.h5")
    pvd = export_vtk(path)
    assert pvd == tmp_path / "vtk" / "results.pvd"
    entries = [(float(d.get("timestep")), d.get("part"), d.get("file"))
               for d in ET.parse(pvd).getroot().iter("DataSet")]
    assert entries[:4] == [(0.0, "0", "particles_000000.vtp"), (0.0, "1", "bonds_000000.vtp"),
                           (0.0, "3", "contacts_000000.vtp"), (0.0, "2", "walls_000000.vtp")]
    assert len(entries) == 16 and entries[-1] == (3e-3, "2", "walls_000003.vtp")
    with h5py.File(path) as f:
        velocity = f["particles/velocity"][2]
        spin = f["particles/angular_velocity"][2]
        force = f["particles/force"][2]
        field = f["particles/field_force"][2]
    data = read(tmp_path / "vtk" / "particles_000002.vtp")
    assert data.GetNumberOfPoints() == 4 and data.GetNumberOfVerts() == 4
    np.testing.assert_array_equal(vtk_to_numpy(data.GetPoints().GetData()), position[2])
    np.testing.assert_array_equal(point_array(data, "radius"), RADIUS)
    np.testing.assert_array_equal(point_array(data, "velocity"), velocity)
    np.testing.assert_allclose(point_array(data, "speed"), np.linalg.norm(velocity, axis=1),
                               rtol=1e-15)
    np.testing.assert_array_equal(point_array(data, "angular_velocity"), spin)
    np.testing.assert_array_equal(point_array(data, "material"), [0, 1, 0, 1])
    np.testing.assert_array_equal(point_array(data, "force"), force)
    np.testing.assert_allclose(point_array(data, "force_magnitude"),
                               np.linalg.norm(force, axis=1), rtol=1e-15)
    np.testing.assert_array_equal(point_array(data, "field_force"), field)
    # frame 2: bond 1 broken: {0, 1} (9e-5 kg) and {2, 3} (4.4e-5 kg); heaviest first
    np.testing.assert_array_equal(point_array(data, "fragment"), [0, 0, 1, 1])
    # frame 3: bond 2 also broken: {0, 1}, {2} (3.4e-5), {3}
    np.testing.assert_array_equal(point_array(read(tmp_path / "vtk" / "particles_000003.vtp"),
                                              "fragment"), [0, 0, 1, 2])
    assert data.GetPointData().GetArray("clump") is None


def test_broken_bonds_are_drawn_where_they_broke(tmp_path):
    path, position = write_results(tmp_path / "results.h5")
    export_vtk(path, tmp_path / "every2", every=2)
    assert sorted(p.name for p in (tmp_path / "every2").glob("bonds_*")) == [
        "bonds_000000.vtp", "bonds_000002.vtp"]
    with h5py.File(path) as f:
        force = f["bonds/force"][2]
    data = read(tmp_path / "every2" / "bonds_000002.vtp")
    # bond 1 (broken by frame 2) a vertex at its midpoint in frame 1, not written here
    assert data.GetNumberOfVerts() == 1 and data.GetNumberOfLines() == 2
    points = vtk_to_numpy(data.GetPoints().GetData())
    np.testing.assert_allclose(points[4], 0.5 * (position[1, 1] + position[1, 2]),
                               rtol=1e-15)
    np.testing.assert_array_equal(cell_array(data, "bond"), [1, 0, 2])
    np.testing.assert_array_equal(cell_array(data, "active"), [0, 1, 1])
    # bond 2's recorded mode shows only once it is broken
    np.testing.assert_array_equal(cell_array(data, "break_mode"), [1, 0, 0])
    np.testing.assert_array_equal(cell_array(data, "material"), [1, 0, 0])
    np.testing.assert_array_equal(cell_array(data, "force"), force[[1, 0, 2]])
    np.testing.assert_allclose(cell_array(data, "force_magnitude"),
                               np.linalg.norm(force[[1, 0, 2]], axis=1), rtol=1e-15)
    # the normal stress of intact bond 0: F . n / A + |M_t| R / I
    with h5py.File(path) as f:
        moment_t = f["bonds/tangential_moment"][2][0]
    n = position[2, 1] - position[2, 0]
    n /= np.linalg.norm(n)
    r = 0.5e-3
    sigma = force[0] @ n / (math.pi * r * r) + np.linalg.norm(moment_t) * r / (math.pi * r ** 4 / 4)
    assert cell_array(data, "normal_stress")[1] == pytest.approx(sigma, rel=1e-12)
    export_vtk(path, tmp_path / "all")
    data = read(tmp_path / "all" / "bonds_000003.vtp")
    points = vtk_to_numpy(data.GetPoints().GetData())
    np.testing.assert_allclose(points[4:], [0.5 * (position[1, 1] + position[1, 2]),
                                            0.5 * (position[2, 2] + position[2, 3])],
                               rtol=1e-15)
    np.testing.assert_array_equal(cell_array(data, "break_mode"), [1, 3, 0])


def test_contact_lines_and_walls(tmp_path):
    path, position = write_results(tmp_path / "results.h5")
    export_vtk(path, tmp_path / "out")
    data = read(tmp_path / "out" / "contacts_000002.vtp")
    assert data.GetNumberOfLines() == 2
    points = vtk_to_numpy(data.GetPoints().GetData())
    # a pair from centre to centre; a wall contact (wall 1) from the centre one radius
    # against its force (-z: the wall lies above)
    np.testing.assert_array_equal(points[[0, 2]], position[2, [1, 2]])
    np.testing.assert_array_equal(points[1], position[2, 3])
    np.testing.assert_allclose(points[3], position[2, 3] + [0, 0, 1e-3], rtol=1e-15)
    np.testing.assert_array_equal(cell_array(data, "wall"), [-1, 1])
    np.testing.assert_array_equal(cell_array(data, "force_magnitude"), [2.0, 3.0])
    assert read(tmp_path / "out" / "contacts_000001.vtp").GetNumberOfLines() == 0
    # frame 0's one pair, from the start of the rows
    data = read(tmp_path / "out" / "contacts_000000.vtp")
    assert data.GetNumberOfLines() == 1
    np.testing.assert_array_equal(cell_array(data, "force_magnitude"), [1.0])
    assert cell_array(read(tmp_path / "out" / "contacts_000003.vtp"), "wall").tolist() == [0]

    with h5py.File(path) as f:
        wall_force = f["walls/force"][3]
    data = read(tmp_path / "out" / "walls_000003.vtp")
    assert data.GetNumberOfPolys() == 2
    np.testing.assert_array_equal(cell_array(data, "wall"), [0, 1])
    np.testing.assert_array_equal(cell_array(data, "force"), wall_force)
    points = vtk_to_numpy(data.GetPoints().GetData())
    # the plane moved at 1 m/s along y for 3 ms: a square about the particles' centroid
    # at t = 0, side 1.5 times the diagonal of their box grown by the largest radius
    start = position[0]
    side = 1.5 * np.linalg.norm(np.ptp(start, axis=0) + 2 * RADIUS.max())
    square = plane_square([0, -5e-3 + 3e-3, 0], [0, 1, 0], start.mean(axis=0), side)
    np.testing.assert_allclose(points[:4], square, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(points[:4, 1], -2e-3, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(points[1] - points[0]), side, rtol=1e-12)
    # the mesh: turned by 100 rad/s x 3 ms about z through (5 mm, 0, 0), lifted 1.5 mm
    angle = 0.3
    turn = np.array([[math.cos(angle), -math.sin(angle), 0],
                     [math.sin(angle), math.cos(angle), 0], [0, 0, 1]])
    expected = [5e-3, 0, 1.5e-3] + (MESH["vertices"] - [5e-3, 0, 0]) @ turn.T
    np.testing.assert_allclose(points[4:], expected, rtol=1e-12, atol=1e-15)
    # recorded wall positions move the walls instead of their velocity
    with h5py.File(path, "a") as f:
        f["walls/position"] = np.zeros((4, 2, 3)) + [[[0, 7e-3, 0], [5e-3, 0, -1e-3]]]
    export_vtk(path, tmp_path / "moved")
    points = vtk_to_numpy(read(tmp_path / "moved" / "walls_000003.vtp").GetPoints().GetData())
    np.testing.assert_allclose(points[:4, 1], 7e-3, rtol=1e-12)
    np.testing.assert_allclose(points[4:, 2], -1e-3, rtol=1e-12)


def test_fragments_and_clumps_from_the_file_or_its_sidecar(tmp_path):
    given = np.array([[3, 2, 1, 0]] * 4)
    path, _ = write_results(tmp_path / "r.h5", fragments=given)
    with h5py.File(path, "a") as f:
        f["particles/clump"] = np.array([0, 0, -1, -1], dtype=np.int32)
    export_vtk(path, tmp_path / "a")
    data = read(tmp_path / "a" / "particles_000001.vtp")
    np.testing.assert_array_equal(point_array(data, "fragment"), [3, 2, 1, 0])
    np.testing.assert_array_equal(point_array(data, "clump"), [0, 0, -1, -1])
    # one fragment id per particle for every frame, in the analysis' sidecar
    path, _ = write_results(tmp_path / "s.h5")
    with h5py.File(tmp_path / "s.fragments.h5", "w") as f:
        f["particles/fragment"] = np.array([7, 7, 8, 9])
    export_vtk(path, tmp_path / "b")
    data = read(tmp_path / "b" / "particles_000003.vtp")
    np.testing.assert_array_equal(point_array(data, "fragment"), [7, 7, 8, 9])
    # a sidecar without fragments: computed from the bonds
    with h5py.File(tmp_path / "s.fragments.h5", "w") as f:
        f["other"] = np.zeros(1)
    export_vtk(path, tmp_path / "c")
    np.testing.assert_array_equal(
        point_array(read(tmp_path / "c" / "particles_000003.vtp"), "fragment"), [0, 0, 1, 2])

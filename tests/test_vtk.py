"""ParaView export read back with VTK's own XML reader: point and cell counts, and values
equal to the results file; bond stresses against SPEC 2's formulas on hand-made bonds."""
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.io.results import read_results
from bondem.analysis.fragments import fragment_labels
from bondem.io.vtk import bond_stresses
from bondem.runner import run_scene
from bondem.scene import load_scene
from scenetools import cube_scene

vtk = pytest.importorskip("vtk")
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402


def _read(path):
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def test_bond_stresses_closed_form():
    """Bond along x, L = 2 mm, d_b = 1 mm: sigma = F_n/A + |M_t| R/I (tension +),
    tau = |F_t|/A + |M_n| R/J."""
    radius = 0.5e-3
    area, second, polar = np.pi * radius**2, np.pi * radius**4 / 4, np.pi * radius**4 / 2
    position = np.array([[0.0, 0, 0], [2e-3, 0, 0], [0, 2e-3, 0]])
    pairs = np.array([[0, 1], [0, 2]])
    force = np.array([[3.0, 4.0, 0.0], [0.0, -2.0, 0.0]])   # bond 1 compressed along y
    normal_moment = np.array([[1e-3, 0, 0], [0, 0, 0.0]])
    tangential_moment = np.array([[0, 2e-3, 0], [0, 0, 0.0]])
    sigma, tau = bond_stresses(position, pairs, np.full(2, 2 * radius), force,
                               normal_moment, tangential_moment)
    np.testing.assert_allclose(sigma, [3.0 / area + 2e-3 * radius / second, -2.0 / area],
                               rtol=1e-12)
    np.testing.assert_allclose(tau, [4.0 / area + 1e-3 * radius / polar, 0.0], rtol=1e-12,
                               atol=1e-9)


def test_export_reads_back(tmp_path):
    """Particles, bonds and walls read back with VTK's reader equal the results file; broken
    bonds are vertices at their break position, never lines across the gap."""
    wall = """
    [[walls]]
    type = "plane"
    point = [0.0, 0.0, -2e-3]
    normal = [0.0, 0.0, 1.0]
    material = "glass"
    velocity = [0.0, 0.0, 1.0]
    """
    scene = load_scene(cube_scene(tmp_path, end_time=1e-4, extra=wall))
    results = run_scene(scene, tmp_path / "out", progress=False)
    # a fragment id per particle and frame, as the analysis writes it
    with h5py.File(results, "a") as f:
        frames, n = f["particles/position"].shape[:2]
        f.create_dataset("particles/fragment", data=np.tile(np.arange(n) % 3, (frames, 1)))
    result = CliRunner().invoke(main, ["export", "vtk", str(results)])
    assert result.exit_code == 0, result.output
    folder = tmp_path / "out" / "vtk"
    r = read_results(results)
    F, N, B = r["time"].shape[0], r["particles/radius"].shape[0], r["bonds/pairs"].shape[0]

    collection = ET.parse(folder / "results.pvd").getroot().find("Collection")
    entries = collection.findall("DataSet")
    assert len(entries) == 4 * F   # particles, bonds, walls and contacts per frame
    np.testing.assert_array_equal(sorted({float(e.get("timestep")) for e in entries}), r["time"])

    k = F - 1
    particles = _read(folder / f"particles_{k:06d}.vtp")
    assert particles.GetNumberOfPoints() == N and particles.GetNumberOfVerts() == N
    data = particles.GetPointData()
    np.testing.assert_array_equal(vtk_to_numpy(particles.GetPoints().GetData()),
                                  r["particles/position"][k])
    np.testing.assert_array_equal(vtk_to_numpy(data.GetArray("radius")), r["particles/radius"])
    np.testing.assert_array_equal(vtk_to_numpy(data.GetArray("velocity")),
                                  r["particles/velocity"][k])
    np.testing.assert_allclose(vtk_to_numpy(data.GetArray("speed")),
                               np.linalg.norm(r["particles/velocity"][k], axis=1), rtol=1e-15)
    np.testing.assert_array_equal(vtk_to_numpy(data.GetArray("force")),
                                  r["particles/force"][k])
    assert np.any(r["particles/force"][k] != 0)
    np.testing.assert_array_equal(vtk_to_numpy(data.GetArray("fragment")), np.arange(N) % 3)

    # the contact forces as lines, read back by VTK: one per touching contact
    end = r["contacts/end"]
    busiest = int(np.argmax(np.diff(np.r_[0, end])))
    lines = _read(folder / f"contacts_{busiest:06d}.vtp")
    rows = slice(int(end[busiest - 1]) if busiest else 0, int(end[busiest]))
    force = r["contact_rows/force"][rows]
    assert lines.GetNumberOfLines() == force.shape[0]   # (tests/test_contact_output.py: some)
    np.testing.assert_array_equal(vtk_to_numpy(lines.GetCellData().GetArray("force")), force)
    np.testing.assert_allclose(
        vtk_to_numpy(lines.GetCellData().GetArray("force_magnitude")),
        np.linalg.norm(force, axis=1), rtol=1e-15)

    bonds = _read(folder / f"bonds_{k:06d}.vtp")
    active = r["bonds/active"][k]
    assert 0 < active.sum() < B
    assert bonds.GetNumberOfCells() == B
    assert bonds.GetNumberOfLines() == active.sum()
    assert bonds.GetNumberOfVerts() == B - active.sum()
    cells = bonds.GetCellData()
    order = vtk_to_numpy(cells.GetArray("bond"))
    assert sorted(order.tolist()) == list(range(B))
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetArray("active")).astype(bool),
                                  active[order])
    lines = vtk_to_numpy(bonds.GetLines().GetConnectivityArray()).reshape(-1, 2)
    np.testing.assert_array_equal(lines, r["bonds/pairs"][active])
    # a broken bond sits where it broke: the midpoint of its particles in its last intact
    # frame, which is inside the body at t = 0, not stretched across the gap
    mode = vtk_to_numpy(cells.GetArray("break_mode"))
    np.testing.assert_array_equal(mode, np.where(active, 0, r["bonds/break_mode"])[order])
    assert np.all(mode[~active[order]] == 1)               # these break in tension
    points = vtk_to_numpy(bonds.GetPoints().GetData())
    vertex_ids = vtk_to_numpy(bonds.GetVerts().GetConnectivityArray())
    pairs = r["bonds/pairs"]
    for cell, point in zip(order[:len(vertex_ids)], vertex_ids):
        last = np.flatnonzero(r["bonds/active"][:, cell])[-1]
        middle = 0.5 * (r["particles/position"][last][pairs[cell, 0]]
                        + r["particles/position"][last][pairs[cell, 1]])
        np.testing.assert_allclose(points[point], middle, rtol=1e-15, atol=0)
    sigma, tau = bond_stresses(r["particles/position"][k], pairs, r["bonds/diameter"],
                               r["bonds/force"][k], r["bonds/normal_moment"][k],
                               r["bonds/tangential_moment"][k])
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetArray("normal_stress")), sigma[order])
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetArray("shear_stress")), tau[order])
    assert np.all(sigma[~active] == 0) and np.any(sigma != 0)

    # the plane as a square at its position at that time, with the wall's force
    walls = _read(folder / f"walls_{k:06d}.vtp")
    assert walls.GetNumberOfPolys() == 1 and walls.GetNumberOfPoints() == 4
    corners = vtk_to_numpy(walls.GetPoints().GetData())
    np.testing.assert_allclose(corners[:, 2], -2e-3 + 1.0 * r["time"][k], rtol=1e-12)
    np.testing.assert_allclose(vtk_to_numpy(walls.GetCellData().GetArray("force"))[0],
                               r["walls/force"][k][0])

    # fragment ids from the analysis' sidecar file when the results file has none
    with h5py.File(results, "a") as f:
        del f["particles/fragment"]
    with h5py.File(results.with_name("results.fragments.h5"), "w") as f:
        f.create_dataset("particles/fragment", data=np.tile(np.arange(N) % 5, (F, 1)))
    result = CliRunner().invoke(main, ["export", "vtk", str(results), "--out",
                                       str(tmp_path / "vtk2"), "--every", "2"])
    assert result.exit_code == 0, result.output
    assert len(list((tmp_path / "vtk2").glob("particles_*.vtp"))) == (F + 1) // 2
    data = _read(tmp_path / "vtk2" / "particles_000002.vtp").GetPointData()
    np.testing.assert_array_equal(vtk_to_numpy(data.GetArray("fragment")), np.arange(N) % 5)

    # and computed from the intact bonds when neither has them: the x-layers come apart
    results.with_name("results.fragments.h5").unlink()
    result = CliRunner().invoke(main, ["export", "vtk", str(results), "--out",
                                       str(tmp_path / "vtk3")])
    assert result.exit_code == 0, result.output
    fragment = vtk_to_numpy(_read(tmp_path / "vtk3" / f"particles_{k:06d}.vtp")
                            .GetPointData().GetArray("fragment"))
    _, expected = fragment_labels(pairs, active, N, r["particles/mass"])
    np.testing.assert_array_equal(fragment, expected)
    assert len(set(fragment.tolist())) == 3


def test_mesh_wall_moves_and_turns_in_the_export(tmp_path):
    """A one-triangle mesh turning about z at 100 rad/s: the exported vertices are the
    initial ones turned by 100 t about the rotation centre, moved with the velocity."""
    from bondem.io.vtk import walls_polydata
    vertices = np.array([[1e-3, 0, 0], [0, 1e-3, 0], [0, 0, 1e-3]])
    geometry = {"type": np.array([1]), "velocity": np.array([[0.0, 0.0, 0.5]]),
                "angular_velocity": np.array([[0.0, 0.0, 100.0]]),
                "rotation_center": np.zeros((1, 3)), "point": np.zeros((1, 3)),
                "normal": np.zeros((1, 3)),
                "mesh0": {"vertices": vertices, "triangles": np.array([[0, 1, 2]])}}
    t = np.pi / 200                    # a quarter turn
    poly = walls_polydata(geometry, t, np.array([[1.0, 2.0, 3.0]]), np.zeros(3), 1.0)
    poly.write(tmp_path / "w.vtp")
    mesh = _read(tmp_path / "w.vtp")
    got = vtk_to_numpy(mesh.GetPoints().GetData())
    expected = np.array([[0, 1e-3, 0], [-1e-3, 0, 0], [0, 0, 1e-3]]) + [0, 0, 0.5 * t]
    np.testing.assert_allclose(got, expected, atol=1e-15)
    assert mesh.GetNumberOfPolys() == 1


def test_export_bad_file_is_input_error(tmp_path):
    (tmp_path / "x.h5").write_text("not hdf5")
    result = CliRunner().invoke(main, ["export", "vtk", str(tmp_path / "x.h5")])
    assert result.exit_code == 2 and "x.h5" in result.stderr and "RESULTS" in result.stderr

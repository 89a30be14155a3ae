"""ParaView export read back with VTK's own XML reader: point and cell counts, and values
equal to the results file; bond stresses against SPEC 2's formulas on hand-made bonds."""
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main
from bondem.io.results import read_results
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
    scene = load_scene(cube_scene(tmp_path, end_time=1e-4))
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
    assert len(entries) == 2 * F
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
    np.testing.assert_array_equal(vtk_to_numpy(data.GetArray("fragment")), np.arange(N) % 3)

    bonds = _read(folder / f"bonds_{k:06d}.vtp")
    assert bonds.GetNumberOfPoints() == N and bonds.GetNumberOfLines() == B
    lines = vtk_to_numpy(bonds.GetLines().GetConnectivityArray()).reshape(-1, 2)
    np.testing.assert_array_equal(lines, r["bonds/pairs"])
    cells = bonds.GetCellData()
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetArray("active")).astype(bool),
                                  r["bonds/active"][k])
    assert 0 < r["bonds/active"][k].sum() < B
    sigma, tau = bond_stresses(r["particles/position"][k], r["bonds/pairs"],
                               r["bonds/diameter"], r["bonds/force"][k],
                               r["bonds/normal_moment"][k], r["bonds/tangential_moment"][k])
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetArray("normal_stress")), sigma)
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetArray("shear_stress")), tau)
    assert np.all(sigma[~r["bonds/active"][k]] == 0) and np.any(sigma != 0)

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


def test_export_bad_file_is_input_error(tmp_path):
    (tmp_path / "x.h5").write_text("not hdf5")
    result = CliRunner().invoke(main, ["export", "vtk", str(tmp_path / "x.h5")])
    assert result.exit_code == 2 and "x.h5" in result.stderr and "RESULTS" in result.stderr

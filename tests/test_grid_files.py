"""A fluid's velocity grid from VTK files (io/grid_files.py): files written by VTK's own
writers (XML image data in every data mode, encoding, compression, header width and byte
order; legacy structured points, ASCII and BINARY; point and cell data) read back to the
values and node positions they were written with; a scene takes a .vti as it takes an
HDF5 file; broken files are errors naming the file and what is wrong.
"""
import numpy as np
import pytest

from bondem.errors import InputError
from bondem.io.grid_files import read_flow_grid
from bondem.scene import load_scene

vtk = pytest.importorskip("vtk")
from vtk.util.numpy_support import numpy_to_vtk  # noqa: E402

DIMS = (4, 3, 5)                       # nodes along x, y, z: all different
ORIGIN = (-1.5e-3, 0.25e-3, 2e-3)      # m
SPACING = (0.5e-3, 0.75e-3, 0.4e-3)    # m


def field(shape):
    """A velocity (nx, ny, nz, 3) m/s whose every value differs, and its flat x-fastest
    (VTK) order."""
    rng = np.random.default_rng(5)
    grid = rng.uniform(-1.0, 1.0, (*shape, 3))
    return grid, grid.transpose(2, 1, 0, 3).reshape(-1, 3)


def image(cells=False, name="U", extra=True):
    data = vtk.vtkImageData()
    data.SetDimensions(*DIMS)
    data.SetOrigin(*ORIGIN)
    data.SetSpacing(*SPACING)
    shape = tuple(d - 1 for d in DIMS) if cells else DIMS
    grid, flat = field(shape)
    array = numpy_to_vtk(flat.copy(), deep=1)
    array.SetName(name)
    target = data.GetCellData() if cells else data.GetPointData()
    target.AddArray(array)
    if extra:   # a scalar beside it (pressure) must not be taken
        pressure = numpy_to_vtk(np.arange(len(flat), dtype=float), deep=1)
        pressure.SetName("p")
        target.AddArray(pressure)
    return data, grid


XML_MODES = {
    "ascii": dict(mode=0),
    "binary": dict(mode=1, compressed=False),
    "binary_zlib": dict(mode=1, compressed=True),
    "appended_raw": dict(mode=2, compressed=False),
    "appended_raw_zlib": dict(mode=2, compressed=True),
    "appended_base64": dict(mode=2, compressed=False, encode=True),
    "appended_base64_zlib_uint64": dict(mode=2, compressed=True, encode=True, uint64=True),
    "binary_uint64_big_endian": dict(mode=1, compressed=False, uint64=True, big=True),
    "binary_zlib_small_blocks": dict(mode=1, compressed=True, block=64),
}


def write_vti(path, data, mode, compressed=False, encode=False, uint64=False, big=False,
              block=None):
    writer = vtk.vtkXMLImageDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(data)
    writer.SetDataMode(mode)
    if not compressed:
        writer.SetCompressorTypeToNone()
    else:
        writer.SetCompressorTypeToZLib()
    if block:
        writer.SetBlockSize(block)
    writer.SetEncodeAppendedData(encode)
    if uint64:
        writer.SetHeaderTypeToUInt64()
    if big:
        writer.SetByteOrderToBigEndian()
    assert writer.Write() == 1


@pytest.mark.parametrize("mode", XML_MODES)
@pytest.mark.parametrize("cells", [False, True])
def test_vti_files_of_every_kind_read_back(tmp_path, mode, cells):
    data, grid = image(cells)
    write_vti(tmp_path / "flow.vti", data, **XML_MODES[mode])
    velocity, origin, spacing = read_flow_grid(tmp_path / "flow.vti")
    np.testing.assert_array_equal(velocity, grid, strict=False)
    np.testing.assert_array_equal(spacing, SPACING)
    # cell values sit at the cell centres
    expected = np.array(ORIGIN) + (0.5 * np.array(SPACING) if cells else 0.0)
    np.testing.assert_allclose(origin, expected, rtol=1e-15, atol=0)


@pytest.mark.parametrize("binary", [False, True])
@pytest.mark.parametrize("cells", [False, True])
def test_legacy_structured_points_read_back(tmp_path, binary, cells):
    data, grid = image(cells, name="velocity")
    writer = vtk.vtkStructuredPointsWriter()
    writer.SetFileName(str(tmp_path / "flow.vtk"))
    writer.SetInputData(data)
    if binary:
        writer.SetFileTypeToBinary()
    writer.SetFileVersion(42)
    assert writer.Write() == 1
    velocity, origin, spacing = read_flow_grid(tmp_path / "flow.vtk")
    # ASCII keeps VTK's default printing precision
    np.testing.assert_allclose(velocity, grid, rtol=0, atol=0 if binary else 1e-6)
    np.testing.assert_allclose(spacing, SPACING, rtol=1e-6)
    expected = np.array(ORIGIN) + (0.5 * np.array(SPACING) if cells else 0.0)
    np.testing.assert_allclose(origin, expected, rtol=1e-6)


def test_a_scene_flow_file_in_vti_drives_as_the_hdf5_one(tmp_path):
    import h5py
    data, grid = image()
    write_vti(tmp_path / "flow.vti", data, mode=2, compressed=True)
    with h5py.File(tmp_path / "flow.h5", "w") as f:
        f["velocity"] = grid
        f["velocity"].attrs["origin"] = ORIGIN
        f["velocity"].attrs["spacing"] = SPACING
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,1e-3,3e-3,1e-4,glass\n")
    models = []
    for name in ("flow.vti", "flow.h5"):
        (tmp_path / "scene.toml").write_text(SCENE.format(file=name))
        models.append(load_scene(tmp_path / "scene.toml").model)
    np.testing.assert_array_equal(models[0].flow, models[1].flow)
    np.testing.assert_array_equal(models[0].flow_box, models[1].flow_box)


SCENE = """
[simulation]
end_time = 1e-3
[materials.glass]
density = 2500.0
young_modulus = 1e9
poisson_ratio = 0.3
[particles]
file = "particles.csv"
[fluid]
density = 1000.0
viscosity = 1e-3
drag = "stokes"
velocity_file = "{file}"
"""


def test_broken_vtk_files_are_named(tmp_path):
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-4,glass\n")
    (tmp_path / "scene.toml").write_text(SCENE.format(file="flow.vti"))
    data, _ = image()
    good = tmp_path / "good.vti"
    write_vti(good, data, mode=0)
    text = good.read_text()
    turned = text.replace('Direction="1 0 0 0 1 0 0 0 1"', 'Direction="0 1 0 -1 0 0 0 0 1"')
    assert turned != text
    data2, _ = image(extra=False)
    two = vtk.vtkImageData()
    two.DeepCopy(data2)
    twin = numpy_to_vtk(np.zeros((int(np.prod(DIMS)), 3)), deep=1)
    twin.SetName("W")
    two.GetPointData().AddArray(twin)
    two.GetPointData().GetArray("U").SetName("V")
    write_vti(tmp_path / "two.vti", two, mode=0)
    cases = [
        ("<VTKFile", "not a VTK XML file"),
        (text.replace('"ImageData"', '"PolyData"').replace("<ImageData", "<PolyData")
         .replace("</ImageData>", "</PolyData>"), "not VTK image data"),
        (turned, "a turned grid"),
        (text.replace('NumberOfComponents="3"', 'NumberOfComponents="1"'),
         "no 3-component point or cell array"),
        (text.replace('WholeExtent="0 3 0 2 0 4"', 'WholeExtent="0 3 0 2 0 5"'),
         "need 216"),
        ((tmp_path / "two.vti").read_text(), "several 3-component PointData arrays (V, W)"),
    ]
    for content, message in cases:
        (tmp_path / "flow.vti").write_text(content)
        with pytest.raises(InputError) as error:
            load_scene(tmp_path / "scene.toml")
        assert error.value.key == "fluid.velocity_file", content[:80]
        assert message in str(error.value) and "flow.vti" in str(error.value)
    (tmp_path / "flow.vtk").write_text("# vtk DataFile Version 4.2\nx\nASCII\n"
                                       "DATASET RECTILINEAR_GRID\n")
    with pytest.raises(InputError, match="allowed: STRUCTURED_POINTS"):
        read_flow_grid(tmp_path / "flow.vtk")
    (tmp_path / "flow.vtk").write_text("not vtk\n\n\n\n\n")
    with pytest.raises(InputError, match="not a legacy VTK file"):
        read_flow_grid(tmp_path / "flow.vtk")

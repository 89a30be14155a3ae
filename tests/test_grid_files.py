"""A fluid's velocity grid from VTK files (io/grid_files.py): files written by VTK's own
writers (XML image data in every data mode, encoding, compression, header width and byte
order; legacy structured points, ASCII and BINARY; point and cell data) read back to the
values and node positions they were written with; a scene takes a .vti as it takes an
HDF5 file; broken files are errors naming the file and what is wrong.
"""
import re

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


def expect(path, message, key="fluid.velocity_file", named=None):
    """read_flow_grid(path) fails with exactly ``message`` about file ``named`` (default
    the file itself) under ``key``."""
    with pytest.raises(InputError) as error:
        read_flow_grid(path, key=key)
    assert str(error.value) == f"{named or path}: {key}: {message}"


def test_every_defect_has_its_message(tmp_path):
    """Each broken file of each kind, read under a key of the caller's choosing."""
    import h5py
    key = "fluids.flow"
    expect(tmp_path / "none.vti", f"no such file {str(tmp_path / 'none.vti')!r}", key)
    h5 = tmp_path / "flow.h5"
    with h5py.File(h5, "w") as f:
        f["speed"] = np.zeros((2, 2, 2, 3))
    expect(h5, "no dataset 'velocity' (nx, ny, nz, 3) m/s", key)
    for missing in ("origin", "spacing"):
        with h5py.File(h5, "w") as f:
            f["velocity"] = np.zeros((2, 2, 2, 3))
            for name in {"origin", "spacing"} - {missing}:
                f.attrs[name] = [0.0, 0.0, 0.0]
        expect(h5, f"no attribute {missing!r} (3 numbers, m)", key)
    with h5py.File(h5, "w") as f:   # on the file, not the dataset: read as well
        f["velocity"] = np.ones((2, 3, 2, 3))
        f.attrs["origin"] = [1.0, 2.0, 3.0]
        f.attrs["spacing"] = [0.1, 0.2, 0.3]
    velocity, origin, spacing = read_flow_grid(h5)
    assert velocity.shape == (2, 3, 2, 3) and list(origin) == [1.0, 2.0, 3.0]
    assert list(spacing) == [0.1, 0.2, 0.3]
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(InputError) as error:
        read_flow_grid(tmp_path / "text.h5", key=key)
    text = str(error.value)
    assert text.startswith(f"{tmp_path / 'text.h5'}: {key}: not an HDF5 file (")
    assert text.endswith("); allowed: .h5/.hdf5, .vti, .vtk")

    data, _ = image()
    write_vti(tmp_path / "good.vti", data, mode=0)
    good = (tmp_path / "good.vti").read_text()
    vti = tmp_path / "bad.vti"
    cases = [
        (good.replace('WholeExtent="0 3 0 2 0 4"', 'WholeExtent="0 3 0 2"'),
         "WholeExtent: expected 6 numbers, got '0 3 0 2'"),
        (good.replace('Origin="-0.0015', 'Origin="x'),
         "Origin: expected 3 numbers, got 'x 0.00025 0.002'"),
        (good.replace('WholeExtent="0 3 0 2 0 4" ', ''),
         "WholeExtent: expected 6 numbers, got ''"),
        (good.replace('Spacing="0.0005 0.00075 0.0004"', 'Spacing="0.0005"'),
         "Spacing: expected 3 numbers, got '0.0005'"),
        (good.replace('Direction="1 0 0 0 1 0 0 0 1"', 'Direction="1 0 0"'),
         "Direction: expected 9 numbers, got '1 0 0'"),
        (good.replace('Direction="1 0 0 0 1 0 0 0 1"', 'Direction="0 1 0 -1 0 0 0 0 1"'),
         "Direction 0 1 0 -1 0 0 0 0 1: a turned grid; allowed: the identity "
         "(axis-aligned)"),
        (good.replace("</Piece>", '</Piece><Piece Extent="0 0 0 0 0 0"></Piece>'),
         "2 pieces; allowed: 1"),
        (good.replace('type="Float64" Name="U"', 'type="Float128" Name="U"'),
         "array 'U': type 'Float128'; allowed: Float32, Float64, Int8, UInt8, Int16, "
         "UInt16, Int32, UInt32, Int64, UInt64"),
        (good.replace('Name="U" NumberOfComponents="3" format="ascii"',
                      'Name="U" NumberOfComponents="3" format="hex"'),
         "array 'U': format 'hex'; allowed: ascii, binary, appended"),
        (good.replace('Name="U" NumberOfComponents="3" format="ascii"',
                      'Name="U" NumberOfComponents="3" format="appended"'),
         "array 'U': format 'appended'; allowed: ascii, binary, appended"),
        (good.replace('<VTKFile type="ImageData"', '<VTKFile compressor="vtkLZ4DataCompressor"'
                      ' type="ImageData"'),
         "compressor vtkLZ4DataCompressor: allowed none or vtkZLibDataCompressor "
         "(ParaView's default)"),
        (good.replace("<ImageData", "<RectilinearGrid").replace("</ImageData>",
                                                                "</RectilinearGrid>"),
         "not VTK image data (type 'ImageData'); allowed: ImageData (.vti)"),
        (good.replace('NumberOfComponents="3"', 'NumberOfComponents="1"'),
         "no 3-component point or cell array (the velocity, named velocity or U or u)"),
        (good.replace('WholeExtent="0 3 0 2 0 4"', 'WholeExtent="0 3 0 2 0 5"'),
         "the velocity holds 180 numbers; the grid's 4 x 3 x 6 points need 216"),
    ]
    for content, message in cases:
        vti.write_text(content)
        expect(vti, message, key)
    # an array without its numbers
    empty = re.sub(r'(format="ascii"[^>]*>)[^<]*', r"\1", good, count=1)
    vti.write_text(empty)
    expect(vti, "the velocity holds 0 numbers; the grid's 4 x 3 x 5 points need 180", key)
    # a binary array whose data are cut short
    write_vti(tmp_path / "b.vti", data, mode=1, compressed=True)
    text = (tmp_path / "b.vti").read_text()
    block = re.search(r'format="binary"[^>]*>\s*(\S+)', text).group(1)
    (tmp_path / "b.vti").write_text(text.replace(block, block[:40]))
    with pytest.raises(InputError) as error:
        read_flow_grid(tmp_path / "b.vti", key=key)
    assert str(error.value).startswith(
        f"{tmp_path / 'b.vti'}: {key}: array 'U': unreadable binary data (")

    vtk_file = tmp_path / "bad.vtk"
    head = "# vtk DataFile Version 3.0\ntitle\nASCII\nDATASET STRUCTURED_POINTS\n"
    legacy = [
        ("# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\n",
         "DATASET POLYDATA; allowed: STRUCTURED_POINTS"),
        ("vtk\n\n\n\n\n", "not a legacy VTK file (no '# vtk DataFile' line)"),
        ("# vtk DataFile\nx\nASCII\n", "not a legacy VTK file (no '# vtk DataFile' line)"),
        (head + "DIMENSIONS 2 2\n", "unreadable line 'DIMENSIONS 2 2' (expected 3 numbers)"),
        (head + "ORIGIN 0 0\n", "unreadable line 'ORIGIN 0 0' (expected 3 numbers)"),
        (head + "SPACING 1 1 1 1\n", "unreadable line 'SPACING 1 1 1 1' (expected 3 numbers)"),
        (head + "ASPECT_RATIO 1\n", "unreadable line 'ASPECT_RATIO 1' (expected 3 numbers)"),
        (head + "ORIGIN 0 0 0\nSPACING 1 1 1\n", "no DIMENSIONS line"),
        (head + "DIMENSIONS 2 2 2\nSPACING 1 1 1\n", "no ORIGIN line"),
        (head + "DIMENSIONS 2 2 2\nORIGIN 0 0 0\n", "no SPACING line"),
        (head + "DIMENSIONS 2 1 1\nORIGIN 0 0 0\nSPACING 1 1 1\nPOINT_DATA 2\n"
         "SCALARS p double 1\nLOOKUP_TABLE default\n1 2\n",
         "no 3-component point or cell data (VECTORS, the velocity, named velocity or U "
         "or u)"),
        (head + "DIMENSIONS 2 1 1\nORIGIN 0 0 0\nSPACING 1 1 1\nPOINT_DATA 2\n"
         "VECTORS a double\n1 2 3 4 5 6\nVECTORS b double\n1 2 3 4 5 6\n",
         "several 3-component PointData arrays (a, b) and none named velocity or U or u"),
        (head + "DIMENSIONS 2 1 1\nORIGIN 0 0 0\nSPACING 1 1 1\nPOINT_DATA 3\n"
         "VECTORS u double\n1 2 3 4 5 6 7 8 9\n",
         "the velocity holds 9 numbers; the grid's 2 x 1 x 1 points need 6"),
        (head + "DIMENSIONS 3 2 1\nORIGIN 0 0 0\nSPACING 1 1 1\nCELL_DATA 1\n"
         "VECTORS u double\n1 2 3\n",
         "the velocity holds 3 numbers; the grid's 2 x 1 x 1 cells need 6"),
    ]
    for content, message in legacy:
        vtk_file.write_text(content)
        expect(vtk_file, message, key)
    # the scene's key unless told otherwise
    with pytest.raises(InputError) as error:
        read_flow_grid(tmp_path / "gone.vtk")
    assert error.value.key == "fluid.velocity_file"


def legacy_values(text):
    return " ".join(repr(float(v)) for v in np.asarray(text).ravel())


@pytest.mark.parametrize("binary", [False, True])
def test_legacy_vectors_scalars_fields_and_metadata(tmp_path, binary):
    """Hand-written legacy files: the velocity as VECTORS after other arrays (NORMALS, a
    3-component SCALARS named otherwise, a FIELD block with METADATA), as a 3-component
    SCALARS named U, or in a FIELD; blank lines between blocks; ASPECT_RATIO for SPACING;
    point and cell data in one file (the point data wins); float and double."""
    import struct
    dims, origin, spacing = (3, 2, 2), (0.5, -1.0, 2.0), (0.25, 0.5, 0.125)
    grid, flat = field(dims)
    cells = np.arange(2 * 1 * 1 * 3, dtype=float)

    def block(values, kind="double"):
        values = np.asarray(values, dtype=float).ravel()
        if kind == "float":   # what a float file can hold
            values = values.astype(np.float32).astype(float)
        if binary:
            code = ">" + ("d" if kind == "double" else "f") * values.size
            return struct.pack(code, *values) + b"\n"
        return (legacy_values(values) + "\n").encode()

    def header(extra=b""):
        return (f"# vtk DataFile Version 3.0\nmade by hand\n{'BINARY' if binary else 'ASCII'}\n"
                f"DATASET STRUCTURED_POINTS\nDIMENSIONS {dims[0]} {dims[1]} {dims[2]}\n"
                f"ORIGIN {origin[0]} {origin[1]} {origin[2]}\n"
                f"ASPECT_RATIO {spacing[0]} {spacing[1]} {spacing[2]}\n").encode() + extra

    n = int(np.prod(dims))
    other = np.ones((n, 3))
    files = {
        "vectors": header(b"CELL_DATA 2\nVECTORS velocity double\n" + block(cells)
                          + f"\nPOINT_DATA {n}\nNORMALS n double\n".encode() + block(other)
                          + b"SCALARS w double 3\nLOOKUP_TABLE default\n" + block(other)
                          + b"FIELD extra 1\np 1 " + f"{n} double\n".encode()
                          + block(np.arange(n)) + b"METADATA\nINFORMATION 0\n\n"
                          + b"VECTORS velocity double\n" + block(flat)),
        "scalars": header(f"POINT_DATA {n}\nSCALARS U double 3\nLOOKUP_TABLE default\n"
                          .encode() + block(flat) + b"VECTORS w double\n" + block(other)),
        "field": header(f"POINT_DATA {n}\nFIELD FieldData 2\np 1 {n} double\n".encode()
                        + block(np.arange(n)) + b"\n" + f"u 3 {n} double\n".encode()
                        + block(flat)),
        "float": header(f"POINT_DATA {n}\nVECTORS velocity float\n".encode()
                        + block(flat, "float")),
    }
    for name, content in files.items():
        (tmp_path / f"{name}.vtk").write_bytes(content)
        velocity, o, s = read_flow_grid(tmp_path / f"{name}.vtk")
        expected = grid.astype(np.float32) if name == "float" else grid
        np.testing.assert_array_equal(velocity, expected, err_msg=name)
        assert velocity.dtype == np.float64
        np.testing.assert_array_equal(o, origin)
        np.testing.assert_array_equal(s, spacing)


def test_a_flat_grid_of_cells_and_an_extent_away_from_zero(tmp_path):
    """A 2-D image (one node along z, two along y) with cell data after another array:
    the centres move half a spacing along x and y only. An extent starting at (2, 1, 3) moves the origin by that many
    spacings. Int32 velocities are read as numbers."""
    data = vtk.vtkImageData()
    data.SetExtent(2, 5, 1, 2, 3, 3)
    data.SetOrigin(*ORIGIN)
    data.SetSpacing(*SPACING)
    grid, flat = field((3, 1, 1))
    pressure = numpy_to_vtk(np.arange(3.0), deep=1)
    pressure.SetName("p")
    data.GetCellData().AddArray(pressure)   # first: the velocity's offset is not 0
    values = numpy_to_vtk(flat.copy(), deep=1)
    values.SetName("velocity")
    data.GetCellData().AddArray(values)
    write_vti(tmp_path / "flat.vti", data, mode=2, compressed=True)
    velocity, origin, spacing = read_flow_grid(tmp_path / "flat.vti")
    np.testing.assert_array_equal(velocity, grid)
    head = (tmp_path / "flat.vti").read_bytes().split(b"<AppendedData")[0]
    assert re.search(rb'Name="velocity"[^>]*offset="[1-9]', head)
    start = np.array(ORIGIN) + np.array([2, 1, 3]) * np.array(SPACING)
    np.testing.assert_allclose(origin, start + [0.5 * SPACING[0], 0.5 * SPACING[1], 0.0],
                               rtol=1e-15)
    integers = vtk.vtkImageData()
    integers.SetDimensions(2, 2, 1)
    numbers = numpy_to_vtk(np.arange(12, dtype=np.int32).reshape(4, 3), deep=1)
    numbers.SetName("U")
    integers.GetPointData().AddArray(numbers)
    for mode, name in ((1, "i.vti"), (2, "j.vti")):
        write_vti(tmp_path / name, integers, mode=mode, compressed=mode == 2, big=True)
        velocity, _, _ = read_flow_grid(tmp_path / name)
        assert velocity.dtype == np.float64
        np.testing.assert_array_equal(velocity[1, 0, 0], [3.0, 4.0, 5.0])
        np.testing.assert_array_equal(velocity[0, 1, 0], [6.0, 7.0, 8.0])


def test_hand_written_files_use_the_formats_defaults(tmp_path):
    """VTK's defaults where a writer leaves attributes out: no Origin (0), no Spacing
    (1), no byte_order (little-endian), no header_type (UInt32), no format (ascii), no
    Name, and appended data without an encoding (raw) or offset (0)."""
    values = np.arange(2 * 3 * 1 * 3, dtype=float) * 0.5 - 2.0   # x-fastest, 2 x 3 x 1
    text = " ".join(repr(float(v)) for v in values)
    (tmp_path / "ascii.vti").write_text(
        '<?xml version="1.0"?>\n<VTKFile type="ImageData">\n'
        '<ImageData WholeExtent="0 1 0 2 0 0">\n<Piece Extent="0 1 0 2 0 0">\n'
        f'<PointData><DataArray type="Float64" NumberOfComponents="3">{text}'
        '</DataArray></PointData>\n</Piece>\n</ImageData>\n</VTKFile>\n')
    velocity, origin, spacing = read_flow_grid(tmp_path / "ascii.vti")
    assert origin.tolist() == [0.0, 0.0, 0.0] and spacing.tolist() == [1.0, 1.0, 1.0]
    np.testing.assert_array_equal(velocity[1, 2, 0], values[15:18])
    np.testing.assert_array_equal(velocity[0, 1, 0], values[6:9])
    body = values.astype("<f8").tobytes()
    (tmp_path / "raw.vti").write_bytes(
        b'<?xml version="1.0"?>\n<VTKFile type="ImageData">\n'
        b'<ImageData WholeExtent="0 1 0 2 0 0" Origin="1 2 3" Spacing="0.5 0.5 2">\n'
        b'<Piece Extent="0 1 0 2 0 0">\n'
        b'<PointData><DataArray type="Float64" Name="velocity" NumberOfComponents="3" '
        b'format="appended"/></PointData>\n</Piece>\n</ImageData>\n<AppendedData>_'
        + np.array([len(body)], "<u4").tobytes() + body + b"\n</AppendedData>\n</VTKFile>\n")
    velocity, origin, spacing = read_flow_grid(tmp_path / "raw.vti")
    assert origin.tolist() == [1.0, 2.0, 3.0] and spacing.tolist() == [0.5, 0.5, 2.0]
    np.testing.assert_array_equal(velocity[1, 2, 0], values[15:18])


def test_legacy_edges_a_last_line_without_newline_and_foreign_bytes(tmp_path):
    """A legacy file may end without a newline; its METADATA may hold non-ASCII text; a
    SCALARS line without its component count has one."""
    body = ("# vtk DataFile Version 5.1\ngrille\nASCII\nDATASET STRUCTURED_POINTS\n"
            "DIMENSIONS 2 1 1\nORIGIN 0.5 0 0\nSPACING 0.25 1 1\nPOINT_DATA 2\n"
            "SCALARS p double\nLOOKUP_TABLE default\n7 8\n"
            "METADATA\nINFORMATION 1\nNAME vitesse · m/s é\nVECTORS u double\n\n"
            "VECTORS velocity double\n1 2 3\n4 5 6")
    (tmp_path / "edge.vtk").write_bytes(body.encode("utf-8"))
    velocity, origin, spacing = read_flow_grid(tmp_path / "edge.vtk")
    np.testing.assert_array_equal(velocity[:, 0, 0], [[1, 2, 3], [4, 5, 6]])
    assert origin.tolist() == [0.5, 0.0, 0.0] and spacing.tolist() == [0.25, 1.0, 1.0]


@pytest.mark.parametrize("header", ["UInt32", "UInt64"])
def test_base64_with_the_header_encoded_apart(tmp_path, header):
    """Some writers (meshio among them) encode an uncompressed array's byte count and its
    data as two base64 strings, the first padded; VTK encodes them as one."""
    import base64
    values = np.linspace(-1.0, 2.0, 2 * 2 * 2 * 3)
    data = values.astype("<f4").tobytes()
    count = np.array([len(data)], "<u4" if header == "UInt32" else "<u8").tobytes()
    encoded = (base64.b64encode(count) + base64.b64encode(data)).decode()
    assert "=" in encoded[:12]
    (tmp_path / "apart.vti").write_text(
        f'<?xml version="1.0"?>\n<VTKFile type="ImageData" header_type="{header}" '
        'byte_order="LittleEndian">\n<ImageData WholeExtent="0 1 0 1 0 1" Origin="0 0 0" '
        'Spacing="1 1 1">\n<Piece Extent="0 1 0 1 0 1">\n<PointData>'
        f'<DataArray type="Float32" Name="U" NumberOfComponents="3" format="binary">\n'
        f'  {encoded}\n</DataArray></PointData>\n</Piece>\n</ImageData>\n</VTKFile>\n')
    velocity, _, _ = read_flow_grid(tmp_path / "apart.vti")
    expected = values.astype(np.float32).astype(float).reshape(2, 2, 2, 3)
    np.testing.assert_array_equal(velocity, expected.transpose(2, 1, 0, 3))

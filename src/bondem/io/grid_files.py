"""A fluid's velocity on a regular grid, from the files CFD codes and ParaView write:
HDF5 (a dataset ``velocity`` (nx, ny, nz, 3) m/s with attributes ``origin`` and
``spacing``), VTK XML image data (``.vti``: ascii, base64 binary or appended data, raw or
base64, uncompressed or zlib-compressed, UInt32 or UInt64 headers, either byte order) and
legacy VTK structured points (``.vtk``, ASCII or BINARY).

In a VTK file the velocity is the 3-component point array named ``velocity``, ``U``
(OpenFOAM's name) or ``u``, else the only 3-component point array; point values sit on
the nodes origin + (i, j, k) spacing. Cell data (a finite-volume solver's cell values)
is used when no point array is found: its values sit at the cell centres, origin +
(i + 1/2, j + 1/2, k + 1/2) spacing. Grids turned by a Direction other than the identity
are refused. Errors are ``InputError`` naming the file and what is wrong.
"""
from __future__ import annotations

import base64
import re
import xml.etree.ElementTree as ElementTree
import zlib
from pathlib import Path

import numpy as np

from ..errors import InputError

NAMES = ("velocity", "U", "u")
VTK_TYPES = {"Float32": "f4", "Float64": "f8", "Int8": "i1", "UInt8": "u1", "Int16": "i2",
             "UInt16": "u2", "Int32": "i4", "UInt32": "u4", "Int64": "i8", "UInt64": "u8"}
LEGACY_TYPES = {"float": "f4", "double": "f8", "int": "i4", "unsigned_int": "u4",
                "short": "i2", "unsigned_short": "u2", "long": "i8", "unsigned_long": "u8",
                "char": "i1", "unsigned_char": "u1", "vtktypeint64": "i8"}


def read_flow_grid(path, key="fluid.velocity_file"):
    """(velocity (nx, ny, nz, 3) m/s, origin (3,) m, spacing (3,) m) from ``path`` (by its
    suffix: .h5/.hdf5, .vti or .vtk; module docstring). ``key``: the scene key named in
    errors."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no such file {str(path)!r}", file=path, key=key)
    suffix = path.suffix.lower()
    if suffix == ".vti":
        return _read_vti(path, key)
    if suffix == ".vtk":
        return _read_legacy(path, key)
    return _read_hdf5(path, key)


def _read_hdf5(path, key):
    import h5py
    try:
        with h5py.File(path, "r") as f:
            if "velocity" not in f:
                raise InputError("no dataset 'velocity' (nx, ny, nz, 3) m/s", file=path,
                                 key=key)
            velocity = f["velocity"][()]
            origin = f["velocity"].attrs.get("origin", f.attrs.get("origin"))
            spacing = f["velocity"].attrs.get("spacing", f.attrs.get("spacing"))
    except OSError as error:
        raise InputError(f"not an HDF5 file ({error}); allowed: .h5/.hdf5, .vti, .vtk",
                         file=path, key=key) from None
    for name, value in (("origin", origin), ("spacing", spacing)):
        if value is None:
            raise InputError(f"no attribute {name!r} (3 numbers, m)", file=path, key=key)
    return velocity, origin, spacing


def _numbers(text, count, what, path, key):
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != count:
        raise InputError(f"{what}: expected {count} numbers, got {text!r}", file=path, key=key)
    return np.array(values)


def _pick(arrays, path, key, kind):
    """The velocity among ``arrays`` {name: (components, item)}: by name, else the only
    3-component one; None if there is none."""
    vectors = {name: item for name, (components, item) in arrays.items() if components == 3}
    for name in NAMES:
        if name in vectors:
            return vectors[name]
    if len(vectors) == 1:
        return next(iter(vectors.values()))
    if len(vectors) > 1:
        raise InputError(f"several 3-component {kind} arrays ({', '.join(vectors)}) and "
                         f"none named {' or '.join(NAMES)}", file=path, key=key)
    return None


def _grid(values, dims, origin, spacing, cells, path, key):
    """Node values (nx, ny, nz, 3) from VTK's x-fastest order; cell data moves the nodes
    to the cell centres."""
    shape = np.maximum(dims - 1, 1) if cells else dims
    count = int(np.prod(shape))
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    if values.size != 3 * count:
        raise InputError(f"the velocity holds {values.size} numbers; the grid's "
                         f"{' x '.join(str(int(s)) for s in shape)} "
                         f"{'cells' if cells else 'points'} need {3 * count}",
                         file=path, key=key)
    grid = values.reshape(int(shape[2]), int(shape[1]), int(shape[0]), 3).transpose(2, 1, 0, 3)
    if cells:
        origin = origin + 0.5 * spacing * (dims > 1)
    return np.ascontiguousarray(grid), origin, spacing


def _read_vti(path, key):
    raw = path.read_bytes()
    appended = None
    start = raw.find(b"<AppendedData")
    if start >= 0:
        tag_end = raw.index(b">", start)
        underscore = raw.index(b"_", tag_end)
        encoding = re.search(rb'encoding="(\w+)"', raw[start:tag_end])
        appended = (raw[underscore + 1:], encoding.group(1).decode() if encoding else "raw")
        raw = raw[:start] + b"</VTKFile>"
    try:
        root = ElementTree.fromstring(raw)
    except ElementTree.ParseError as error:
        raise InputError(f"not a VTK XML file ({error})", file=path, key=key) from None
    image = root.find("ImageData")
    if root.tag != "VTKFile" or image is None:
        raise InputError(f"not VTK image data (type {root.get('type')!r}); allowed: "
                         "ImageData (.vti)", file=path, key=key)
    order = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    header = order + VTK_TYPES[root.get("header_type", "UInt32")]
    compressed = root.get("compressor")
    if compressed not in (None, "vtkZLibDataCompressor"):
        raise InputError(f"compressor {compressed}: allowed none or vtkZLibDataCompressor "
                         "(ParaView's default)", file=path, key=key)
    extent = _numbers(image.get("WholeExtent", ""), 6, "WholeExtent", path, key)
    origin = _numbers(image.get("Origin", "0 0 0"), 3, "Origin", path, key)
    spacing = _numbers(image.get("Spacing", "1 1 1"), 3, "Spacing", path, key)
    direction = image.get("Direction")
    if direction is not None and not np.allclose(
            _numbers(direction, 9, "Direction", path, key), np.eye(3).ravel()):
        raise InputError(f"Direction {direction}: a turned grid; allowed: the identity "
                         "(axis-aligned)", file=path, key=key)
    pieces = image.findall("Piece")
    if len(pieces) != 1:
        raise InputError(f"{len(pieces)} pieces; allowed: 1", file=path, key=key)
    dims = (extent[1::2] - extent[0::2] + 1).astype(np.int64)
    origin = origin + extent[0::2] * spacing
    for section, cells in (("PointData", False), ("CellData", True)):
        arrays = {}
        for array in pieces[0].findall(f"{section}/DataArray"):
            arrays[array.get("Name", "")] = (int(array.get("NumberOfComponents", "1")), array)
        chosen = _pick(arrays, path, key, section)
        if chosen is not None:
            values = _vti_values(chosen, header, order, compressed, appended, path, key)
            return _grid(values, dims, origin, spacing, cells, path, key)
    raise InputError(f"no 3-component point or cell array (the velocity, named "
                     f"{' or '.join(NAMES)})", file=path, key=key)


def _vti_values(array, header, order, compressed, appended, path, key):
    """One DataArray's numbers (flat)."""
    kind = array.get("type")
    if kind not in VTK_TYPES:
        raise InputError(f"array {array.get('Name')!r}: type {kind!r}; allowed: "
                         f"{', '.join(VTK_TYPES)}", file=path, key=key)
    dtype = np.dtype(order + VTK_TYPES[kind])
    form = array.get("format", "ascii")
    try:
        if form == "ascii":
            return np.array((array.text or "").split(), dtype=np.float64)
        if form == "binary":
            return _decode(re.sub(rb"\s", b"", (array.text or "").encode()), True, header,
                           dtype, compressed)
        if form == "appended" and appended is not None:
            data, encoding = appended
            offset = int(array.get("offset", "0"))
            return _decode(data[offset:], encoding == "base64", header, dtype, compressed)
    except (ValueError, zlib.error, IndexError) as error:
        raise InputError(f"array {array.get('Name')!r}: unreadable {form} data ({error})",
                         file=path, key=key) from None
    raise InputError(f"array {array.get('Name')!r}: format {form!r}; allowed: ascii, "
                     "binary, appended", file=path, key=key)


def _decode(data, base64_encoded, header, dtype, compressed):
    """The numbers of one binary block: a header (the byte count, or for zlib the block
    count, block size, last block size and each block's compressed size) and the data,
    base64-encoded as VTK writes them (the header apart when compressed or padded)."""
    size = np.dtype(header).itemsize
    if not compressed:
        if base64_encoded:
            chars = 4 * -(-size // 3)
            count = int(np.frombuffer(base64.b64decode(data[:chars])[:size], header, 1)[0])
            if data[chars - 1:chars] == b"=":   # the header encoded apart (padded)
                body = base64.b64decode(data[chars:chars + 4 * -(-count // 3)])[:count]
            else:
                body = base64.b64decode(data[:4 * -(-(size + count) // 3)])[size:size + count]
        else:
            count = int(np.frombuffer(data[:size], header, 1)[0])
            body = data[size:size + count]
        return np.frombuffer(body, dtype).astype(np.float64)
    if base64_encoded:
        first = base64.b64decode(data[:4 * -(-3 * size // 3)])
        blocks = int(np.frombuffer(first, header, 1)[0])
        head_bytes = (3 + blocks) * size
        chars = 4 * -(-head_bytes // 3)
        head = np.frombuffer(base64.b64decode(data[:chars])[:head_bytes], header)
        total = int(head[3:].sum())
        stream = base64.b64decode(data[chars:chars + 4 * -(-total // 3)])
    else:
        blocks = int(np.frombuffer(data[:size], header, 1)[0])
        head = np.frombuffer(data[:(3 + blocks) * size], header)
        stream = data[(3 + blocks) * size:]
    out, position = [], 0
    for length in head[3:].astype(np.int64):
        out.append(zlib.decompress(stream[position:position + length]))
        position += length
    return np.frombuffer(b"".join(out), dtype).astype(np.float64)


def _read_legacy(path, key):
    raw = path.read_bytes()
    lines = raw.split(b"\n")
    if len(lines) < 5 or not lines[0].startswith(b"# vtk DataFile"):
        raise InputError("not a legacy VTK file (no '# vtk DataFile' line)", file=path,
                         key=key)
    binary = lines[2].strip().upper() == b"BINARY"
    position = len(lines[0]) + len(lines[1]) + len(lines[2]) + 3
    dims = origin = spacing = None
    section, count, arrays = None, 0, {"PointData": {}, "CellData": {}}

    def next_line():
        nonlocal position
        end = raw.find(b"\n", position)
        end = len(raw) if end < 0 else end
        text = raw[position:end].decode("ascii", "replace").strip()
        position = end + 1
        return text

    def next_words():
        """The next line's words, past blank lines and METADATA blocks (which end at a
        blank line)."""
        while position < len(raw):
            words = next_line().split()
            if words and words[0].upper() == "METADATA":
                while position < len(raw) and next_line():
                    pass
            elif words:
                return words
        return []

    def values(n, kind):
        nonlocal position
        dtype = np.dtype(">" + LEGACY_TYPES.get(kind.lower(), "f4"))
        if binary:
            out = np.frombuffer(raw, dtype, n, position).astype(np.float64)
            position += n * dtype.itemsize
            return out
        out = []
        while len(out) < n and position < len(raw):
            out += next_line().split()
        return np.array(out[:n], dtype=np.float64)

    while position < len(raw):
        words = next_words()
        if not words:
            continue
        word = words[0].upper()
        try:
            if word == "DATASET" and words[1].upper() != "STRUCTURED_POINTS":
                raise InputError(f"DATASET {words[1]}; allowed: STRUCTURED_POINTS",
                                 file=path, key=key)
            if word in ("DIMENSIONS", "ORIGIN", "SPACING", "ASPECT_RATIO") \
                    and len(words) != 4:
                raise ValueError("expected 3 numbers")
            if word == "DIMENSIONS":
                dims = np.array([int(w) for w in words[1:4]], dtype=np.int64)
            elif word == "ORIGIN":
                origin = np.array([float(w) for w in words[1:4]])
            elif word in ("SPACING", "ASPECT_RATIO"):
                spacing = np.array([float(w) for w in words[1:4]])
            elif word in ("POINT_DATA", "CELL_DATA"):
                section = "PointData" if word == "POINT_DATA" else "CellData"
                count = int(words[1])
            elif word == "VECTORS":
                arrays[section][words[1]] = (3, values(3 * count, words[2]))
            elif word == "SCALARS":
                components = int(words[3]) if len(words) > 3 else 1
                next_line()   # LOOKUP_TABLE
                arrays[section][words[1]] = (components, values(components * count,
                                                                words[2]))
            elif word == "FIELD":
                for _ in range(int(words[2])):
                    name, components, tuples, kind = next_words()[:4]
                    arrays[section][name] = (int(components),
                                             values(int(components) * int(tuples), kind))
            elif word in ("NORMALS",):
                values(3 * count, words[2])
        except InputError:
            raise
        except (IndexError, ValueError, TypeError) as error:
            raise InputError(f"unreadable line {' '.join(words)!r} ({error})", file=path,
                             key=key) from None
    for name, value in (("DIMENSIONS", dims), ("ORIGIN", origin), ("SPACING", spacing)):
        if value is None:
            raise InputError(f"no {name} line", file=path, key=key)
    for section, cells in (("PointData", False), ("CellData", True)):
        chosen = _pick(arrays[section], path, key, section)
        if chosen is not None:
            return _grid(chosen, dims, origin, spacing, cells, path, key)
    raise InputError(f"no 3-component point or cell data (VECTORS, the velocity, named "
                     f"{' or '.join(NAMES)})", file=path, key=key)

"""The ParaView files' bytes against VTK's XML file format (docs.vtk.org, "VTK File
Formats": appended raw data, UInt64 headers, zlib-compressed blocks of 32 KiB), read by a
reader written here from that definition rather than by VTK's, which forgives a wrong
offset or header. And the export's cases the scene tests do not reach: other dtypes and
byte orders in the results file, arrays of several blocks, planes and meshes in any order,
a bond across a periodic face, clumps, masses that order the fragments differently from
their sizes, files without the optional datasets, a file of no frames."""
import math
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from bondem.io.vtk import (bond_stresses, bonds_polydata, contacts_polydata, export_vtk,
                           particles_polydata, walls_polydata)

TYPES = {"Float64": "<f8", "Float32": "<f4", "Int64": "<i8", "Int32": "<i4", "UInt8": "u1",
         "Int8": "i1"}
MARK = b'<AppendedData encoding="raw">\n_'
TAIL = b"\n</AppendedData>\n</VTKFile>\n"
BLOCK = 32768


def read_vtp(path):
    """{"counts": Piece's attributes, "points", "point_data", "cell_data": {name: (type,
    values)}, "cells": {kind: (connectivity, offsets)}} of a .vtp file with appended raw
    data, checking the layout: each array's blocks where its offset says, one after the
    other, to the end of the data."""
    raw = Path(path).read_bytes()
    head, mark, data = raw.partition(MARK)
    assert mark and data.endswith(TAIL)
    data = data[:-len(TAIL)]
    root = ET.fromstring(head.decode("ascii") + '<AppendedData encoding="raw"/></VTKFile>')
    assert root.attrib == {"type": "PolyData", "version": "1.0", "byte_order": "LittleEndian",
                           "header_type": "UInt64", "compressor": "vtkZLibDataCompressor"}
    spans = []

    def decode(element):
        offset = int(element.get("offset"))
        blocks, block, last = (int(v) for v in np.frombuffer(data, "<u8", 3, offset))
        assert block == BLOCK and (blocks > 0 or last == 0)
        sizes = np.frombuffer(data, "<u8", blocks, offset + 24)
        start = offset + 24 + 8 * blocks
        chunks = []
        for k, size in enumerate(sizes):
            chunk = zlib.decompress(data[start:start + int(size)])
            assert len(chunk) == (BLOCK if k < blocks - 1 else last)
            chunks.append(chunk)
            start += int(size)
        spans.append((offset, start))
        values = np.frombuffer(b"".join(chunks), TYPES[element.get("type")])
        components = int(element.get("NumberOfComponents"))
        return element.get("type"), (values.reshape(-1, components) if components > 1
                                     else values)

    piece = root.find("PolyData/Piece")
    out = {"counts": {k: int(v) for k, v in piece.attrib.items()},
           "points": decode(piece.find("Points/DataArray")),
           "point_data": {e.get("Name"): decode(e) for e in piece.find("PointData")},
           "cell_data": {e.get("Name"): decode(e) for e in piece.find("CellData")},
           "cells": {}}
    for kind in ("Verts", "Lines", "Polys"):
        element = piece.find(kind)
        if element is not None:
            parts = {e.get("Name"): decode(e) for e in element}
            assert parts["connectivity"][0] == parts["offsets"][0] == "Int64"
            out["cells"][kind] = (parts["connectivity"][1], parts["offsets"][1])
    spans.sort()
    assert spans[0][0] == 0 and spans[-1][1] == len(data)
    assert all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
    return out


def cells(out, kind):
    """Each cell's point ids, from its connectivity and offsets."""
    connectivity, offsets = out["cells"][kind]
    return np.split(connectivity, offsets[:-1])


def test_several_blocks_other_dtypes_and_byte_orders_are_written_as_documented(tmp_path):
    """3000 particles: 72 kB of positions in three 32 KiB blocks; positions and radii in
    float32,
    velocities big-endian, materials int64, fragments int32, clumps int16: written as
    Float64, Int32 and Int64, little-endian, with the same values."""
    rng = np.random.default_rng(3)
    n = 3000
    position = (rng.normal(size=(n, 3)) * 1e-2).astype(np.float32)
    radius = rng.uniform(1e-4, 2e-4, n).astype(np.float32)
    velocity = rng.normal(size=(n, 3)).astype(">f8")
    spin = rng.normal(size=(n, 3)).astype(np.float32)
    material = rng.integers(0, 3, n).astype(np.int64)
    fragment = rng.integers(0, 50, n).astype(np.int32)
    clump = rng.integers(-1, 9, n).astype(np.int16)
    force = rng.normal(size=(n, 3)).astype(np.float32) * 1e-3
    field = rng.normal(size=(n, 3)).astype(">f8") * 1e-3
    particles_polydata(position, radius, velocity, spin, material, fragment, force, field,
                       clump).write(tmp_path / "p.vtp")
    out = read_vtp(tmp_path / "p.vtp")
    assert out["counts"] == {"NumberOfPoints": n, "NumberOfVerts": n, "NumberOfLines": 0,
                             "NumberOfStrips": 0, "NumberOfPolys": 0}
    assert out["points"][0] == "Float64"
    np.testing.assert_array_equal(out["points"][1], position)
    expected = {"radius": ("Float64", radius), "velocity": ("Float64", velocity),
                "speed": ("Float64", np.linalg.norm(velocity, axis=1)),
                "angular_velocity": ("Float64", spin), "material": ("Int32", material),
                "force": ("Float64", force),
                # in double precision, from the force as written
                "force_magnitude": ("Float64", np.linalg.norm(force.astype(float), axis=1)),
                "field_force": ("Float64", field), "fragment": ("Int64", fragment),
                "clump": ("Int64", clump)}
    assert list(out["point_data"]) == list(expected)
    for name, (kind, values) in expected.items():
        assert out["point_data"][name][0] == kind, name
        np.testing.assert_allclose(out["point_data"][name][1], values, rtol=1e-15,
                                   err_msg=name)
    assert [c.tolist() for c in cells(out, "Verts")[:3]] == [[0], [1], [2]]
    assert cells(out, "Verts")[-1].tolist() == [n - 1]
    # the optional arrays are left out when not given
    particles_polydata(position[:2], radius[:2], velocity[:2], spin[:2],
                       material[:2]).write(tmp_path / "q.vtp")
    assert list(read_vtp(tmp_path / "q.vtp")["point_data"]) == [
        "radius", "velocity", "speed", "angular_velocity", "material"]


def test_bonds_by_default_broken_at_their_midpoint_with_mode_zero(tmp_path):
    """Five particles off the origin, four bonds of which 1 and 3 are broken: without a
    break point or modes given, the broken ones are vertices at their particles' midpoint
    (points 5 and 6) with mode 0, the intact ones lines; cell data in the cell order
    (vertices first), with the documented types."""
    position = np.array([[1.0, 2, 3], [1.5, 2, 3], [1.5, 2.5, 3], [2, 2.5, 3.5],
                         [2.5, 2, 3]]) * 1e-3
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    active = np.array([1, 0, 1, 0], dtype=np.int8)
    force = (np.arange(12).reshape(4, 3) * 1e-3).astype(np.float32)
    sigma = np.array([1e6, -2e6, 3e6, 4e6], dtype=np.float32)
    tau = np.array([5e5, 6e5, 7e5, 8e5], dtype=np.float32)
    bonds_polydata(position, pairs, active, force, sigma, tau).write(tmp_path / "b.vtp")
    out = read_vtp(tmp_path / "b.vtp")
    assert out["counts"]["NumberOfPoints"] == 7
    np.testing.assert_allclose(out["points"][1][5:], [[1.5e-3, 2.25e-3, 3e-3],
                                                      [2.25e-3, 2.25e-3, 3.25e-3]],
                               rtol=1e-15)
    assert [c.tolist() for c in cells(out, "Verts")] == [[5], [6]]
    assert [c.tolist() for c in cells(out, "Lines")] == [[0, 1], [2, 3]]
    order = [1, 3, 0, 2]
    data = out["cell_data"]
    assert {k: v[0] for k, v in data.items()} == {
        "bond": "Int64", "active": "UInt8", "break_mode": "Int8", "force": "Float64",
        "force_magnitude": "Float64", "normal_stress": "Float64", "shear_stress": "Float64"}
    assert data["bond"][1].tolist() == order and data["active"][1].tolist() == [0, 0, 1, 1]
    assert data["break_mode"][1].tolist() == [0, 0, 0, 0]
    np.testing.assert_array_equal(data["force"][1], force[order])
    np.testing.assert_array_equal(data["normal_stress"][1], sigma[order])
    np.testing.assert_array_equal(data["shear_stress"][1], tau[order])
    # given modes and materials (int64 in, Int8 and Int32 out); an intact bond shows 0
    bonds_polydata(position, pairs, active, force, sigma, tau,
                   break_mode=np.array([3, 1, 2, 3], dtype=np.int64),
                   material=np.array([4, 5, 6, 7], dtype=np.int64)).write(tmp_path / "m.vtp")
    data = read_vtp(tmp_path / "m.vtp")["cell_data"]
    assert data["break_mode"][0] == "Int8" and data["break_mode"][1].tolist() == [1, 3, 0, 0]
    assert data["material"][0] == "Int32" and data["material"][1].tolist() == [5, 7, 4, 6]


def test_contact_lines_point_from_centre_to_centre_or_towards_the_wall(tmp_path):
    """Four particles; contacts: 2-0 (a pair with particle 0), 1 with wall 0 (j = -1),
    3 with wall 5 (j = -6: more walls than particles), 2 with wall 1 at zero force.
    Forces of mN (below 1 N). Each contact is a line k -> K + k."""
    position = np.array([[1.0, 0, 0], [2, 0, 0], [3, 1, 0], [4, 1, 1]]) * 1e-3
    radius = np.array([0.4, 0.5, 0.6, 0.7]) * 1e-3
    i, j = np.array([2, 1, 3, 2]), np.array([0, -1, -6, -2])
    force = np.array([[3e-3, 4e-3, 0], [0, 0, -2e-3], [0, 6e-3, 8e-3], [0, 0, 0]],
                     dtype=np.float32)
    contacts_polydata(position, radius, i, j, force).write(tmp_path / "c.vtp")
    out = read_vtp(tmp_path / "c.vtp")
    assert [c.tolist() for c in cells(out, "Lines")] == [[0, 4], [1, 5], [2, 6], [3, 7]]
    points = out["points"][1]
    np.testing.assert_array_equal(points[:4], position[i])
    np.testing.assert_array_equal(points[4], position[0])
    # a wall contact: one radius from the centre against the force on the particle
    np.testing.assert_allclose(points[5], position[1] + [0, 0, 0.5e-3], rtol=1e-7)
    np.testing.assert_allclose(points[6], position[3] - np.array([0, 0.6, 0.8]) * radius[3],
                               rtol=1e-7)
    np.testing.assert_array_equal(points[7], position[2])   # no force: no direction
    data = out["cell_data"]
    assert {k: v[0] for k, v in data.items()} == {"force": "Float64",
                                                  "force_magnitude": "Float64",
                                                  "wall": "Int32"}
    np.testing.assert_array_equal(data["force"][1], force)
    np.testing.assert_allclose(data["force_magnitude"][1], [5e-3, 2e-3, 1e-2, 0.0],
                               rtol=1e-7)
    assert data["wall"][1].tolist() == [-1, 0, 5, 1]
    # a single particle against a wall: its line ends one radius towards the wall
    contacts_polydata(position[:1], radius[:1], np.array([0]), np.array([-1]),
                      np.array([[0.0, -3e-3, 0]])).write(tmp_path / "one.vtp")
    np.testing.assert_allclose(read_vtp(tmp_path / "one.vtp")["points"][1],
                               [position[0], position[0] + [0, 0.4e-3, 0]], rtol=1e-12)
    contacts_polydata(position, radius, np.zeros(0, int), np.zeros(0, int),
                      np.zeros((0, 3))).write(tmp_path / "none.vtp")
    out = read_vtp(tmp_path / "none.vtp")
    assert out["counts"]["NumberOfPoints"] == 0 and out["counts"]["NumberOfLines"] == 0
    assert out["points"][1].shape == (0, 3)


def _geometry():
    """A plane along -x (normal given as (-2, 0, 0)), a mesh of two triangles, then an
    oblique plane (normal 3 x (0.48, 0.6, 0.64)) and a plane along z, as the results file
    stores them."""
    mesh = np.array([[0.0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0], [1e-3, 1e-3, 0]]) + [0, 0, 4e-3]
    return {"type": np.array([0, 1, 0, 0]),
            "point": np.array([[6e-3, 1e-3, 0], [0, 0, 0], [0, 0, -2e-3], [0, 0, 9e-3]]),
            "normal": np.array([[-2.0, 0, 0], [0, 0, 1], [1.44, 1.8, 1.92], [0, 0, 1]]),
            "velocity": np.array([[-1.0, 0, 0], [0, 0, 0.5], [0, 0, 0], [0, 0, 0]]),
            "angular_velocity": np.zeros((4, 3)),
            "rotation_center": np.array([[0.0, 0, 0], [5e-4, 5e-4, 4e-3], [0, 0, 0],
                                         [0, 0, 0]]),
            "mesh1": {"vertices": mesh, "triangles": np.array([[0, 1, 2], [1, 3, 2]])}}


def test_planes_and_meshes_in_any_order(tmp_path):
    """Plane, mesh, plane, plane at t = 2 ms: each plane a square of the given side
    centred on the projection of the centre, in its plane, moved with its velocity; the
    mesh's triangles at its moved vertices; each polygon's wall and force."""
    geometry, centre, side = _geometry(), np.array([1e-3, 2e-3, 3e-3]), 5e-3
    force = np.array([[1e-3, 0, 0], [0, 2e-3, 0], [0, 0, 3e-3], [0, 0, -4e-3]],
                     dtype=np.float32)
    walls_polydata(geometry, 2e-3, force, centre, side).write(tmp_path / "w.vtp")
    out = read_vtp(tmp_path / "w.vtp")
    polygons, points = cells(out, "Polys"), out["points"][1]
    assert [len(p) for p in polygons] == [4, 3, 3, 4, 4]
    assert out["counts"]["NumberOfPoints"] == 16
    for k, (point, normal) in ((0, ([4e-3, 1e-3, 0], [-1.0, 0, 0])),
                               (3, ([0, 0, -2e-3], [0.48, 0.6, 0.64])),
                               (4, ([0, 0, 9e-3], [0, 0, 1.0]))):
        corners = points[polygons[k]]
        normal = np.asarray(normal)
        # in the plane, centred on the centre's projection, a square of the given side
        np.testing.assert_allclose((corners - point) @ normal, 0.0, atol=1e-15)
        middle = centre - ((centre - point) @ normal) * normal
        np.testing.assert_allclose(corners.mean(axis=0), middle, rtol=1e-12, atol=1e-15)
        edges = np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1)
        np.testing.assert_allclose(edges, side, rtol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(corners[2] - corners[0]), side * math.sqrt(2),
                                   rtol=1e-12)
    lifted = geometry["mesh1"]["vertices"] + [0, 0, 1e-3]
    np.testing.assert_allclose(points[polygons[1]], lifted[[0, 1, 2]], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(points[polygons[2]], lifted[[1, 3, 2]], rtol=1e-12, atol=1e-18)
    data = out["cell_data"]
    assert data["wall"][0] == "Int64" and data["wall"][1].tolist() == [0, 1, 1, 2, 3]
    assert data["force"][0] == "Float64"
    np.testing.assert_array_equal(data["force"][1], force[[0, 1, 1, 2, 3]])
    # recorded reference points move the walls: a plane's is its point, a mesh's its
    # centre of rotation (here 1 mm above where it started, and 2 mm along x)
    recorded = np.array([[5e-3, 1e-3, 0], [2.5e-3, 5e-4, 5e-3], [0, 0, -2e-3], [0, 0, 9e-3]])
    walls_polydata(geometry, 2e-3, force, centre, side, recorded).write(tmp_path / "r.vtp")
    out = read_vtp(tmp_path / "r.vtp")
    polygons, points = cells(out, "Polys"), out["points"][1]
    moved = geometry["mesh1"]["vertices"] + [2e-3, 0, 1e-3]
    np.testing.assert_allclose(points[polygons[1]], moved[[0, 1, 2]], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(points[polygons[0]][:, 0], 5e-3, rtol=1e-12)
    # no walls at all: an empty file
    empty = {key: value[:0] for key, value in geometry.items() if key != "mesh1"}
    walls_polydata(empty, 0.0, np.zeros((0, 3)), centre, side).write(tmp_path / "e.vtp")
    out = read_vtp(tmp_path / "e.vtp")
    assert out["counts"]["NumberOfPoints"] == 0 and out["counts"]["NumberOfPolys"] == 0
    assert out["cell_data"]["wall"][1].shape == (0,)


def _results(path, *, frames=3, periodic=False, extras=True):
    """Four particles in a row along x at 1.5 mm spacing from x = 1 mm, bonds 0-1, 1-2,
    2-3 (bond 1 broken from frame 0, bond 2 from frame 2), masses that make {2, 3} the
    heaviest piece; with ``periodic``, particle 3 sits across the face of a 5 mm box."""
    x = np.array([1.0, 2.5, 4.0, 5.5]) * 1e-3
    if periodic:
        x[3] = 0.5e-3           # its bond with particle 2 crosses the face at x = 5 mm
    position = np.zeros((frames, 4, 3))
    position[:, :, 0] = x
    position[:, :, 1] = 2e-3 + np.arange(frames)[:, None] * 1e-4
    active = np.ones((frames, 3), dtype=bool)
    active[:, 1] = False
    active[2:, 2] = False
    rng = np.random.default_rng(9)
    with h5py.File(path, "w") as f:
        f["time"] = np.arange(frames) * 1e-3
        f["particles/radius"] = np.full(4, 5e-4)
        f["particles/material"] = np.zeros(4, np.int32)
        if extras:
            f["particles/mass"] = np.array([1.0, 1.0, 3.0, 4.0]) * 1e-6
        f["particles/position"] = position
        f["particles/velocity"] = rng.normal(size=(frames, 4, 3))
        f["particles/angular_velocity"] = rng.normal(size=(frames, 4, 3))
        f["bonds/pairs"] = np.array([[0, 1], [1, 2], [2, 3]])
        f["bonds/diameter"] = np.full(3, 4e-4)
        if extras:
            f["bonds/break_mode"] = np.array([0, 1, 3], np.int8)
        f["bonds/active"] = active
        f["bonds/force"] = np.tile([[2e-3, 0, 0]], (frames, 3, 1))
        f["bonds/normal_moment"] = np.zeros((frames, 3, 3))
        f["bonds/tangential_moment"] = np.zeros((frames, 3, 3))
        if periodic:
            f.attrs["box_length"] = np.array([5e-3, 4e-3, 4e-3])
            f.attrs["periodic"] = np.array([True, False, False])
    return path, position


def _pvd(entries):
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    lines += [f'    <DataSet timestep="{t!r}" group="" part="{part}" file="{name}"/>'
              for t, part, name in entries]
    return "\n".join(lines + ["  </Collection>", "</VTKFile>", ""])


def test_a_minimal_file_its_index_and_a_bond_broken_from_the_start(tmp_path):
    """A file without masses, break modes, forces, contacts or walls: the index lists
    particles and bonds only, written whole; no force arrays; the modes are 0; the bond
    broken at frame 0 is a vertex at its midpoint of frame 0; fragments ordered by count
    without masses. Exported twice into a folder three levels down."""
    path, position = _results(tmp_path / "r.h5", frames=2, extras=False)
    out_dir = tmp_path / "a" / "b" / "c"
    for _ in range(2):
        pvd = export_vtk(path, out_dir)
    assert pvd.read_text() == _pvd([(0.0, 0, "particles_000000.vtp"),
                                    (0.0, 1, "bonds_000000.vtp"),
                                    (1e-3, 0, "particles_000001.vtp"),
                                    (1e-3, 1, "bonds_000001.vtp")])
    particles = read_vtp(out_dir / "particles_000000.vtp")
    assert list(particles["point_data"]) == ["radius", "velocity", "speed",
                                             "angular_velocity", "material", "fragment"]
    # {0, 1} and {2, 3}: equal counts, equal (unit) masses: the order connected_components
    # gives
    assert particles["point_data"]["fragment"][1].tolist() == [0, 0, 1, 1]
    bonds = read_vtp(out_dir / "bonds_000000.vtp")
    np.testing.assert_allclose(bonds["points"][1][4], 0.5 * (position[0, 1] + position[0, 2]),
                               rtol=1e-15)
    assert bonds["cell_data"]["break_mode"][1].tolist() == [0, 0, 0]
    # no frames: an index without data sets
    with h5py.File(path, "a") as f:
        for name in ("time", "particles/position", "particles/velocity",
                     "particles/angular_velocity", "bonds/active", "bonds/force",
                     "bonds/normal_moment", "bonds/tangential_moment"):
            data = f[name][()]
            del f[name]
            f[name] = data[:0]
    assert export_vtk(path, tmp_path / "none").read_text() == _pvd([])


def test_masses_clumps_and_periodic_bonds(tmp_path):
    """The heaviest fragment gets id 0 whatever its count; a clump's members are one
    fragment; the stresses of a bond across a periodic face use the minimum image: the
    bond 2-3 points along +x across the face at 5 mm, and the force (2 mN, 0, 0) on
    particle 2 pulls it (by the raw difference it would point along -x, compressed)."""
    path, position = _results(tmp_path / "p.h5", periodic=True)
    export_vtk(path, tmp_path / "out")
    frame = read_vtp(tmp_path / "out" / "particles_000001.vtp")
    # {0, 1} of 2e-6 kg, {2, 3} of 7e-6 kg: the heavier first
    assert frame["point_data"]["fragment"][1].tolist() == [1, 1, 0, 0]
    # frame 2: bond 2 broken too: {3} 4e-6, {2} 3e-6, {0, 1} 2e-6 kg
    frame = read_vtp(tmp_path / "out" / "particles_000002.vtp")
    assert frame["point_data"]["fragment"][1].tolist() == [2, 2, 1, 0]
    bonds = read_vtp(tmp_path / "out" / "bonds_000001.vtp")
    area = math.pi * 2e-4 ** 2
    assert bonds["cell_data"]["bond"][1].tolist() == [1, 0, 2]
    np.testing.assert_allclose(bonds["cell_data"]["normal_stress"][1],
                               2e-3 / area, rtol=1e-12)
    np.testing.assert_allclose(bonds["cell_data"]["shear_stress"][1], 0.0, atol=1e-9)
    with h5py.File(path, "a") as f:
        f["particles/clump"] = np.array([-1, 0, 0, -1], dtype=np.int32)
    export_vtk(path, tmp_path / "clumps")
    frame = read_vtp(tmp_path / "clumps" / "particles_000002.vtp")
    # {0, 1, 2} joined by bond 0 and the clump (5e-6 kg), {3} (4e-6 kg)
    assert frame["point_data"]["fragment"][1].tolist() == [0, 0, 0, 1]
    assert frame["point_data"]["clump"][1].tolist() == [-1, 0, 0, -1]


def test_bond_stresses_of_one_bond_no_bond_and_a_bond_of_zero_length():
    """One bond along y of 0.4 mm diameter pulled by (1, 2, 0) mN: sigma = F_y / A,
    tau = |F_x| / A; no bonds: empty arrays; coincident particles (no axis): the force
    counts as shear only, never NaN."""
    position = np.array([[1e-3, 1e-3, 1e-3], [1e-3, 2e-3, 1e-3], [1e-3, 2e-3, 1e-3]])
    area = math.pi * 2e-4 ** 2
    force = np.array([[1e-3, 2e-3, 0.0]])
    zero = np.zeros((1, 3))
    sigma, tau = bond_stresses(position, np.array([[0, 1]]), np.array([4e-4]), force, zero,
                               zero)
    assert sigma.tolist() == pytest.approx([2e-3 / area], rel=1e-12)
    assert tau.tolist() == pytest.approx([1e-3 / area], rel=1e-12)
    sigma, tau = bond_stresses(position, np.zeros((0, 2), int), np.zeros(0), np.zeros((0, 3)),
                               np.zeros((0, 3)), np.zeros((0, 3)))
    assert sigma.shape == tau.shape == (0,)
    sigma, tau = bond_stresses(position, np.array([[1, 2]]), np.array([4e-4]), force, zero,
                               zero)
    assert sigma.tolist() == [0.0]
    assert tau.tolist() == pytest.approx([math.sqrt(5e-6) / area], rel=1e-12)

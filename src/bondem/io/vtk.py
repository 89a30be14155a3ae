"""ParaView export of a results file: particles, bonds and walls as one .vtp each per
frame, and a .pvd series index with the times.

Written as VTK XML PolyData (appended raw binary, zlib-compressed blocks, the layout of
VTK's own vtkXMLPolyDataWriter; https://docs.vtk.org/en/latest/design_documents/
VTKFileFormats.html), with NumPy and the standard library, so that bondem does not need
the 0.5 GB ``vtk`` package; the tests read the files back with VTK's reader.

Particles: points with point data radius (m), velocity (m/s), speed (|v|, m/s),
angular_velocity (rad/s), force (N, the load of the last force evaluation, when the
results file has /particles/force) and force_magnitude (N), field_force (N, a fluid's and a
rotating frame's, when the results have it), material, and fragment (the
fragment id: from /particles/fragment, the analysis' sidecar ``<stem>.fragments.h5``, or
computed here from the intact bonds and the clumps; 0 is the heaviest fragment), and
with clumps "clump" (each member's clump, -1 for a free sphere: the members are the
particles, so ParaView's sphere glyphs draw each clump's true shape).

Bonds: one cell per bond. An intact bond is a line between its particles; a broken bond
is a vertex at its break position (the midpoint of its particles in the last frame where
it was intact), so no line spans particles that have flown apart. Cell data: bond (index),
active (0/1), break_mode (0 intact, 1 tension, 2 compression, 3 shear), material, force
(N, F_n + F_t on particle i), force_magnitude (N), normal_stress and shear_stress (Pa):
    normal_stress = (F . n) / A_b + |M_t| R_b / I   (positive in tension, SPEC 2)
    shear_stress  = |F_t| / A_b + |M_n| R_b / J
with F_t = F - (F . n) n, n along the bond by the minimum image (periodic boxes).

Walls (when the results file has /walls/geometry): each plane as a finite square (side
1.5 times the diagonal of the particles' bounding box at t = 0, centred on the point of
the plane nearest their centroid), each mesh as its triangles, both moved with the wall
(translation, and rotation about the mesh's centre). Cell data: wall (index), force (N,
total force on that wall).

Whatever the results file stores, the arrays are written little-endian as Float64
(points, every float), Int32 (material, a contact's wall), Int64 (fragment, clump, bond,
a polygon's wall, cell connectivity and offsets), UInt8 (active) and Int8 (break_mode).

Open ``results.pvd`` in ParaView (Glyph the particles with a Sphere, scale array
"radius", scale factor 2).
"""
from __future__ import annotations

import zlib
from contextlib import ExitStack
from pathlib import Path
from xml.sax.saxutils import quoteattr

import h5py
import numpy as np

from ..model import bond_separation
from .results import open_results

VTK_TYPES = {np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
             np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32",
             np.dtype(np.uint8): "UInt8", np.dtype(np.int8): "Int8"}
BLOCK = 1 << 15  # bytes per compressed block, as VTK's writer


def _compressed(data: bytes) -> bytes:
    """vtkZLibDataCompressor layout with UInt64 headers: [blocks, block size, size of the
    last block, compressed sizes...] then the compressed blocks."""
    blocks = [data[k:k + BLOCK] for k in range(0, len(data), BLOCK)]
    packed = [zlib.compress(b, 6) for b in blocks]
    last = len(blocks[-1]) if blocks else 0
    header = np.array([len(blocks), BLOCK, last] + [len(p) for p in packed], dtype="<u8")
    return header.tobytes() + b"".join(packed)


class _PolyData:
    """Collects the arrays of one .vtp file and writes it."""

    def __init__(self, points):
        self.points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        self.cells = {}          # "Verts" | "Lines" | "Polys" -> (connectivity, offsets)
        self.point_data = []     # (name, array)
        self.cell_data = []

    def set_cells(self, kind, connectivity, sizes):
        """Cells of ``kind`` (Verts, Lines or Polys), each of ``sizes[k]`` point ids."""
        sizes = np.asarray(sizes, dtype=np.int64)
        self.cells[kind] = (np.asarray(connectivity, dtype=np.int64).reshape(-1),
                            np.cumsum(sizes))

    def write(self, path):
        blobs, offset = [], 0
        pieces = []

        def data_array(name, values):
            nonlocal offset
            values = np.ascontiguousarray(values)
            kind = VTK_TYPES[values.dtype]
            components = values.shape[1] if values.ndim == 2 else 1
            blob = _compressed(values.astype(values.dtype.newbyteorder("<")).tobytes())
            name_attr = f' Name="{name}"' if name else ""
            text = (f'<DataArray type="{kind}"{name_attr} NumberOfComponents="{components}" '
                    f'format="appended" offset="{offset}"/>')
            blobs.append(blob)
            offset += len(blob)
            return text

        counts = {k: (len(self.cells[k][1]) if k in self.cells else 0)
                  for k in ("Verts", "Lines", "Polys")}
        pieces.append(f'<Piece NumberOfPoints="{self.points.shape[0]}" '
                      f'NumberOfVerts="{counts["Verts"]}" NumberOfLines="{counts["Lines"]}" '
                      f'NumberOfStrips="0" NumberOfPolys="{counts["Polys"]}">')
        for tag, arrays in (("PointData", self.point_data), ("CellData", self.cell_data)):
            pieces.append(f"<{tag}>")
            pieces += [data_array(name, values) for name, values in arrays]
            pieces.append(f"</{tag}>")
        pieces.append("<Points>" + data_array("", self.points) + "</Points>")
        for kind in ("Verts", "Lines", "Polys"):
            if kind in self.cells:
                connectivity, offsets = self.cells[kind]
                pieces.append(f"<{kind}>" + data_array("connectivity", connectivity)
                              + data_array("offsets", offsets) + f"</{kind}>")
        head = ('<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0" '
                'byte_order="LittleEndian" header_type="UInt64" '
                'compressor="vtkZLibDataCompressor">\n<PolyData>\n' + "\n".join(pieces)
                + '\n</Piece>\n</PolyData>\n<AppendedData encoding="raw">\n_')
        with open(path, "wb") as handle:
            handle.write(head.encode("ascii"))
            for blob in blobs:
                handle.write(blob)
            handle.write(b"\n</AppendedData>\n</VTKFile>\n")


def bond_stresses(position, pairs, diameter, force, normal_moment, tangential_moment,
                  box_length=None, periodic=None):
    """(normal_stress, shear_stress) in Pa of each bond (B,), SPEC 2 with the sign of
    the normal force: positive in tension. position (N,3) m; pairs (B,2); diameter (B,) m;
    force, normal_moment, tangential_moment (B,3) N, N m on particle i; box_length (3,) m
    and periodic (3,) bool: the bond axis by the minimum image across periodic faces."""
    if pairs.shape[0] == 0:
        return np.zeros(0), np.zeros(0)
    separation = bond_separation(position, pairs, box_length, periodic)
    length = np.linalg.norm(separation, axis=1)
    normal = separation / np.where(length > 0, length, 1.0)[:, None]
    radius = 0.5 * diameter
    area = np.pi * radius ** 2
    second_moment = 0.25 * np.pi * radius ** 4
    polar_moment = 0.5 * np.pi * radius ** 4
    axial = np.einsum("ij,ij->i", force, normal)
    tangential = force - axial[:, None] * normal
    sigma = axial / area + np.linalg.norm(tangential_moment, axis=1) * radius / second_moment
    tau = (np.linalg.norm(tangential, axis=1) / area
           + np.linalg.norm(normal_moment, axis=1) * radius / polar_moment)
    return sigma, tau


def particles_polydata(position, radius, velocity, angular_velocity, material, fragment=None,
                       force=None, field_force=None, clump=None):
    """Particles as vertices with their point data (see the module docstring); clump:
    each particle's clump (-1 free), shown as "clump" (colour by it: the grains)."""
    n = position.shape[0]
    poly = _PolyData(position)
    poly.set_cells("Verts", np.arange(n), np.ones(n))
    velocity = np.asarray(velocity, np.float64)
    poly.point_data += [("radius", np.asarray(radius, np.float64)),
                        ("velocity", velocity),
                        ("speed", np.linalg.norm(velocity, axis=1)),
                        ("angular_velocity", np.asarray(angular_velocity, np.float64)),
                        ("material", np.asarray(material, np.int32))]
    if force is not None:
        force = np.asarray(force, np.float64)
        poly.point_data += [("force", force),
                            ("force_magnitude", np.linalg.norm(force, axis=1))]
    if field_force is not None:
        poly.point_data.append(("field_force", np.asarray(field_force, np.float64)))
    if fragment is not None:
        poly.point_data.append(("fragment", np.asarray(fragment, np.int64)))
    if clump is not None:
        poly.point_data.append(("clump", np.asarray(clump, np.int64)))
    return poly


def bonds_polydata(position, pairs, active, force, normal_stress, shear_stress,
                   break_point=None, break_mode=None, material=None):
    """Bonds: intact ones as lines between their particles, broken ones as vertices at
    ``break_point`` (B,3) m (see the module docstring); cell data in cell order (VTK puts
    vertices before lines; the ``bond`` array gives each cell's bond index)."""
    b = pairs.shape[0]
    active = np.asarray(active, dtype=bool)
    broken = np.flatnonzero(~active)
    intact = np.flatnonzero(active)
    n = position.shape[0]
    if break_point is None:
        break_point = 0.5 * (position[pairs[:, 0]] + position[pairs[:, 1]])
    poly = _PolyData(np.concatenate([position, break_point[broken]]))
    poly.set_cells("Verts", n + np.arange(broken.size), np.ones(broken.size))
    poly.set_cells("Lines", pairs[intact], np.full(intact.size, 2))
    order = np.concatenate([broken, intact]).astype(np.int64)
    mode = np.zeros(b, np.int8) if break_mode is None else np.asarray(break_mode, np.int8)
    force = np.asarray(force, np.float64)
    poly.cell_data += [("bond", order), ("active", active[order].astype(np.uint8)),
                       ("break_mode", np.where(active, 0, mode)[order].astype(np.int8)),
                       ("force", force[order]),
                       ("force_magnitude", np.linalg.norm(force, axis=1)[order]),
                       ("normal_stress", np.asarray(normal_stress, np.float64)[order]),
                       ("shear_stress", np.asarray(shear_stress, np.float64)[order])]
    if material is not None:
        poly.cell_data.append(("material", np.asarray(material, np.int32)[order]))
    return poly


def contacts_polydata(position, radius, i, j, force):
    """Contact forces as lines, for force chains: a particle pair from centre to centre, a
    wall contact from the particle's centre one radius against its force (towards the
    wall); cell data force (N, on particle i), force_magnitude and wall (-1 for pairs,
    else the wall's index)."""
    force = np.asarray(force, np.float64)   # a float32 floor of 1e-300 would be 0
    wall = j < 0
    other = np.where(wall, 0, j)
    magnitude = np.linalg.norm(force, axis=1)
    unit = force / np.maximum(magnitude, 1e-300)[:, None]
    end = np.where(wall[:, None], position[i] - radius[i][:, None] * unit, position[other])
    k = i.shape[0]
    poly = _PolyData(np.concatenate([position[i], end]) if k else np.zeros((0, 3)))
    poly.set_cells("Lines", np.column_stack([np.arange(k), k + np.arange(k)]),
                   np.full(k, 2))
    poly.cell_data += [("force", force),
                       ("force_magnitude", magnitude),
                       ("wall", np.where(wall, -1 - j, -1).astype(np.int32))]
    return poly


def plane_square(point, normal, center, side):
    """Four corners (4,3) m of a square of ``side`` (m) in the plane through ``point``
    with ``normal``, centred on the projection of ``center`` onto the plane."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    middle = center - np.dot(center - point, normal) * normal
    helper = np.eye(3)[np.argmin(np.abs(normal))]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    h = 0.5 * side
    return np.array([middle - h * u - h * v, middle + h * u - h * v,
                     middle + h * u + h * v, middle - h * u + h * v])


def walls_polydata(geometry, time, force, center, side, position=None):
    """Walls at ``time`` (s) from the results file's /walls/geometry group (see
    ``bondem.io.results.write_wall_geometry``); force (W,3) N; center (3,) m and side (m)
    of the planes' squares; position: the walls' reference points (W,3) m recorded at that
    time (velocity profiles and servos move walls in ways the geometry's t = 0 velocity does
    not tell), else they move at that velocity."""
    from ..walls import rotation_matrix
    points, connectivity, sizes, owner = [], [], [], []
    count = 0
    for w in range(geometry["type"].shape[0]):
        start = geometry["point" if geometry["type"][w] == 0 else "rotation_center"][w]
        moved = (geometry["velocity"][w] * time if position is None
                 else np.asarray(position[w]) - start)
        if geometry["type"][w] == 0:
            corners = plane_square(geometry["point"][w] + moved,
                                   geometry["normal"][w], center, side)
            points.append(corners)
            connectivity.append(count + np.arange(4))
            sizes.append([4])
            owner.append([w])
            count += 4
        else:
            group = geometry[f"mesh{w}"]
            rotation = rotation_matrix(geometry["angular_velocity"][w], time)
            c0 = geometry["rotation_center"][w]
            vertices = c0 + moved + (group["vertices"] - c0) @ rotation.T
            triangles = group["triangles"]
            points.append(vertices)
            connectivity.append(count + triangles.reshape(-1))
            sizes.append(np.full(triangles.shape[0], 3))
            owner.append(np.full(triangles.shape[0], w))
            count += vertices.shape[0]
    poly = _PolyData(np.concatenate(points) if points else np.zeros((0, 3)))
    poly.set_cells("Polys", np.concatenate(connectivity) if connectivity else [],
                   np.concatenate(sizes) if sizes else [])
    owner = np.concatenate(owner).astype(np.int64) if owner else np.zeros(0, np.int64)
    poly.cell_data += [("wall", owner), ("force", np.asarray(force, np.float64)[owner])]
    return poly


def _read_geometry(f):
    """/walls/geometry as a dict of arrays (and mesh groups), or None."""
    if "walls/geometry" not in f:
        return None
    group = f["walls/geometry"]
    out = {name: group[name][()] for name in group if isinstance(group[name], h5py.Dataset)}
    for name in group:
        if isinstance(group[name], h5py.Group):
            out[name] = {k: group[name][k][()] for k in group[name]}
    return out


def export_vtk(results_path, out_dir=None, *, every=1) -> Path:
    """Write ParaView files for every ``every``-th frame of a results file.

    out_dir: default ``<results folder>/vtk``. Writes particles_NNNNNN.vtp,
    bonds_NNNNNN.vtp, walls_NNNNNN.vtp (with walls), contacts_NNNNNN.vtp (the contact
    forces as lines, ``contacts_polydata``) and results.pvd (part 0 particles, part 1
    bonds, part 2 walls, part 3 contacts, with the frame times in s). Returns the .pvd
    path.
    """
    from ..analysis.fragments import fragment_labels
    results_path = Path(results_path)
    out_dir = Path(out_dir) if out_dir is not None else results_path.parent / "vtk"
    out_dir.mkdir(parents=True, exist_ok=True)
    entries = []
    # fragment ids: in the results file, or in the analysis' sidecar when the results
    # file could not be written (e.g. still open in a running simulation), else computed
    sidecar_path = results_path.with_name(results_path.stem + ".fragments.h5")
    with ExitStack() as stack:
        sidecar = (stack.enter_context(h5py.File(sidecar_path, "r"))
                   if sidecar_path.is_file() else None)
        f = stack.enter_context(open_results(results_path))
        times = f["time"][()]
        radius = f["particles/radius"][()]
        material = f["particles/material"][()]
        mass = f["particles/mass"][()] if "particles/mass" in f else None
        clump = f["particles/clump"][()].astype(np.int64) if "particles/clump" in f else None
        pairs = f["bonds/pairs"][()].astype(np.int64).reshape(-1, 2)
        diameter = f["bonds/diameter"][()]
        bond_material = f["bonds/material"][()] if "bonds/material" in f else None
        break_mode = (f["bonds/break_mode"][()] if "bonds/break_mode" in f
                      else np.zeros(pairs.shape[0], np.int8))
        box_length = f.attrs.get("box_length")
        periodic = f.attrs.get("periodic")
        fragment = (f["particles/fragment"] if "particles/fragment" in f
                    else sidecar["particles/fragment"] if sidecar is not None
                    and "particles/fragment" in sidecar else None)
        has_force = "particles/force" in f
        has_field = "particles/field_force" in f
        geometry = _read_geometry(f)
        n = radius.shape[0]
        start = f["particles/position"][0] if times.shape[0] else np.zeros((n, 3))
        center = start.mean(axis=0) if n else np.zeros(3)
        side = 1.5 * float(np.linalg.norm(np.ptp(start, axis=0) + 2 * radius.max(initial=0)))
        break_point = np.full((pairs.shape[0], 3), np.nan)
        stride = max(1, int(every))
        for k in range(times.shape[0]):
            # break points are tracked at every frame, also those not written
            position = f["particles/position"][k]
            active = f["bonds/active"][k].astype(bool)
            middle = 0.5 * (position[pairs[:, 0]] + position[pairs[:, 1]])
            if k == 0:
                break_point[:] = middle
            else:
                break_point[active] = middle[active]
            if k % stride:
                continue
            if fragment is not None:
                frag = fragment[k] if fragment.ndim == 2 else fragment[()]
            else:
                frag = fragment_labels(pairs, active, n, mass, clump)[1]
            particles = particles_polydata(
                position, radius, f["particles/velocity"][k],
                f["particles/angular_velocity"][k], material, frag,
                f["particles/force"][k] if has_force else None,
                f["particles/field_force"][k] if has_field else None, clump)
            name = f"particles_{k:06d}.vtp"
            particles.write(out_dir / name)
            entries.append((times[k], 0, name))
            force = f["bonds/force"][k]
            sigma, tau = bond_stresses(position, pairs, diameter, force,
                                       f["bonds/normal_moment"][k],
                                       f["bonds/tangential_moment"][k], box_length, periodic)
            bonds = bonds_polydata(position, pairs, active, force, sigma, tau, break_point,
                                   break_mode, bond_material)
            name = f"bonds_{k:06d}.vtp"
            bonds.write(out_dir / name)
            entries.append((times[k], 1, name))
            if "contacts/end" in f:
                end = f["contacts/end"]
                start, stop = (int(end[k - 1]) if k else 0), int(end[k])
                lines = contacts_polydata(position, radius,
                                          f["contact_rows/i"][start:stop],
                                          f["contact_rows/j"][start:stop],
                                          f["contact_rows/force"][start:stop])
                name = f"contacts_{k:06d}.vtp"
                lines.write(out_dir / name)
                entries.append((times[k], 3, name))
            if geometry is not None and geometry["type"].shape[0]:
                walls = walls_polydata(geometry, times[k], f["walls/force"][k], center, side,
                                       f["walls/position"][k] if "walls/position" in f
                                       else None)
                name = f"walls_{k:06d}.vtp"
                walls.write(out_dir / name)
                entries.append((times[k], 2, name))
    pvd = out_dir / "results.pvd"
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    lines += [f'    <DataSet timestep="{float(t)!r}" group="" part="{part}" '
              f'file={quoteattr(name)}/>'
              for t, part, name in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    pvd.write_text("\n".join(lines))
    return pvd

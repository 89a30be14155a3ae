"""ParaView export of a results file: one particles and one bonds .vtp per frame and a
.pvd series index with the times.

Particles are points with point data radius (m), velocity (m/s), angular_velocity
(rad/s), material and, when the results file has /particles/fragment, fragment.
Bonds are lines between their particles' positions with cell data active (0/1),
force (N, F_n + F_t on particle i), normal_stress and shear_stress (Pa):
    normal_stress = (F . n) / A_b + |M_t| R_b / I   (positive in tension, SPEC 2)
    shear_stress  = |F_t| / A_b + |M_n| R_b / J
with F_t = F - (F . n) n. Open ``results.pvd`` in ParaView (glyph the particles with
"radius" as scale array, Sphere glyph, scale factor 2). Fragment ids come from
/particles/fragment, (F,N) or (N,), in the results file or in the analysis' sidecar
``<stem>.fragments.h5``.
"""
from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from xml.sax.saxutils import quoteattr

import h5py
import numpy as np


def bond_stresses(position, pairs, diameter, force, normal_moment, tangential_moment):
    """(normal_stress, shear_stress) in Pa of each bond (B,), SPEC 2 with the sign of
    the normal force: positive in tension. position (N,3) m; pairs (B,2); diameter (B,) m;
    force, normal_moment, tangential_moment (B,3) N, N m on particle i."""
    if pairs.shape[0] == 0:
        return np.zeros(0), np.zeros(0)
    separation = position[pairs[:, 1]] - position[pairs[:, 0]]
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


def _array(name, values, dtype=None):
    from vtk.util.numpy_support import numpy_to_vtk
    values = np.ascontiguousarray(values if dtype is None else values.astype(dtype))
    array = numpy_to_vtk(values, deep=True)
    array.SetName(name)
    return array


def _points(position):
    import vtk
    points = vtk.vtkPoints()
    points.SetData(_array("position", np.asarray(position, dtype=np.float64)))
    return points


def _write(polydata, path):
    import vtk
    writer = vtk.vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(polydata)
    writer.SetDataModeToAppended()
    writer.EncodeAppendedDataOff()
    writer.SetCompressorTypeToZLib()
    if not writer.Write():
        raise OSError(f"VTK could not write {path}")


def particles_polydata(position, radius, velocity, angular_velocity, material, fragment=None):
    """vtkPolyData of particles as vertices with their point data."""
    import vtk
    n = position.shape[0]
    poly = vtk.vtkPolyData()
    poly.SetPoints(_points(position))
    vertices = vtk.vtkCellArray()
    offsets = np.arange(n + 1, dtype=np.int64)
    vertices.SetData(_array("offsets", offsets),
                     _array("connectivity", np.arange(n, dtype=np.int64)))
    poly.SetVerts(vertices)
    data = poly.GetPointData()
    data.AddArray(_array("radius", radius, np.float64))
    data.AddArray(_array("velocity", velocity, np.float64))
    data.AddArray(_array("angular_velocity", angular_velocity, np.float64))
    data.AddArray(_array("material", material, np.int32))
    if fragment is not None:
        data.AddArray(_array("fragment", fragment, np.int64))
    data.SetActiveScalars("radius")
    data.SetActiveVectors("velocity")
    return poly


def bonds_polydata(position, pairs, active, force, normal_stress, shear_stress):
    """vtkPolyData of bonds as lines between particle positions with their cell data."""
    import vtk
    poly = vtk.vtkPolyData()
    poly.SetPoints(_points(position))
    lines = vtk.vtkCellArray()
    b = pairs.shape[0]
    lines.SetData(_array("offsets", np.arange(0, 2 * b + 1, 2, dtype=np.int64)),
                  _array("connectivity", pairs.reshape(-1).astype(np.int64)))
    poly.SetLines(lines)
    data = poly.GetCellData()
    data.AddArray(_array("active", active, np.uint8))
    data.AddArray(_array("force", force, np.float64))
    data.AddArray(_array("normal_stress", normal_stress, np.float64))
    data.AddArray(_array("shear_stress", shear_stress, np.float64))
    return poly


def export_vtk(results_path, out_dir=None, *, every=1) -> Path:
    """Write ParaView files for every ``every``-th frame of a results file.

    out_dir: default ``<results folder>/vtk``. Writes particles_NNNNNN.vtp,
    bonds_NNNNNN.vtp and results.pvd (both series, part 0 particles, part 1 bonds, with
    the frame times in s). Returns the .pvd path.
    """
    results_path = Path(results_path)
    out_dir = Path(out_dir) if out_dir is not None else results_path.parent / "vtk"
    out_dir.mkdir(parents=True, exist_ok=True)
    entries = []
    # fragment ids: in the results file, or in the analysis' sidecar when the results
    # file could not be written (e.g. still open in a running simulation)
    sidecar_path = results_path.with_name(results_path.stem + ".fragments.h5")
    with ExitStack() as stack:
        sidecar = (stack.enter_context(h5py.File(sidecar_path, "r"))
                   if sidecar_path.is_file() else None)
        f = stack.enter_context(h5py.File(results_path, "r", swmr=True))
        times = f["time"][()]
        radius = f["particles/radius"][()]
        material = f["particles/material"][()]
        pairs = f["bonds/pairs"][()]
        diameter = f["bonds/diameter"][()]
        fragment = (f["particles/fragment"] if "particles/fragment" in f
                    else sidecar["particles/fragment"] if sidecar is not None
                    and "particles/fragment" in sidecar else None)
        for k in range(0, times.shape[0], max(1, int(every))):
            position = f["particles/position"][k]
            frag = None
            if fragment is not None:
                frag = fragment[k] if fragment.ndim == 2 else fragment[()]
            particles = particles_polydata(position, radius, f["particles/velocity"][k],
                                           f["particles/angular_velocity"][k], material, frag)
            name = f"particles_{k:06d}.vtp"
            _write(particles, out_dir / name)
            entries.append((times[k], 0, name))
            force = f["bonds/force"][k]
            normal_moment = f["bonds/normal_moment"][k]
            tangential_moment = f["bonds/tangential_moment"][k]
            sigma, tau = bond_stresses(position, pairs, diameter, force, normal_moment,
                                       tangential_moment)
            bonds = bonds_polydata(position, pairs, f["bonds/active"][k], force, sigma, tau)
            name = f"bonds_{k:06d}.vtp"
            _write(bonds, out_dir / name)
            entries.append((times[k], 1, name))
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

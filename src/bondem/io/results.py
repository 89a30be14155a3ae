"""Results file (HDF5, SPEC section 6), written one frame at a time.

Layout (F frames, N particles, B bonds, W walls; every dataset has a ``unit`` attribute):
```
/time (F,) s
/particles/radius (N,) m, material (N,) index into /materials/names, mass (N,) kg,
           position, velocity, angular_velocity (F,N,3) m, m/s, rad/s
/bonds/pairs (B,2), diameter (B,) m, initial_length (B,) m, material (B,) index into
       /bond_materials/names, active (F,B) bool, break_time (B,) s (NaN while intact),
       break_mode (B,) int8 (0 intact, 1 tension, 2 compression, 3 shear),
       force (F,B,3) N (F_n + F_t on particle i), normal_moment, tangential_moment
       (F,B,3) N m (on particle i); all three zero for broken bonds
/walls/force, torque, position (F,W,3) N, N m, m
/walls/geometry/ type (W,) 0 plane 1 mesh, point, normal, velocity, angular_velocity,
       rotation_center (W,3) m, -, m/s, rad/s, m at t = 0; meshN/vertices (V,3) m and
       meshN/triangles (T,3) for mesh wall N (for the ParaView export)
/particles/force (F,N,3) N: the particles' loads of the last force evaluation
/energy/<term> (F,) J: Simulation.energy_terms()
/materials/names, /bond_materials/names
attrs on /: scene (the scene text), scene_name, bondem_version, backend, time_step (s),
periodic (3,) bool, box_length (3,) m (periodic cell; 1 along other axes), ...
```
The file is opened with ``libver="latest"``, all datasets are created first and then SWMR
mode is switched on, so readers can follow a running simulation with
``h5py.File(path, "r", swmr=True)``. Each frame is appended and flushed; a killed run
leaves a file that opens and holds every frame flushed so far.
"""
from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from ..model import bond_separation

FRAME_CHUNK_ROWS = 65536  # rows of (N,3)/(B,3) per chunk: ~1.5 MB, bounded for big runs
UNITS = {
    "time": "s", "particles/radius": "m", "particles/material": "1", "particles/mass": "kg",
    "particles/position": "m", "particles/velocity": "m/s",
    "particles/angular_velocity": "rad/s", "bonds/pairs": "1", "bonds/diameter": "m",
    "bonds/initial_length": "m", "bonds/material": "1", "bonds/active": "1",
    "bonds/break_time": "s", "bonds/break_mode": "1", "bonds/force": "N",
    "bonds/normal_moment": "N m", "bonds/tangential_moment": "N m", "walls/force": "N",
    "walls/torque": "N m", "walls/position": "m", "particles/force": "N",
}


def bond_forces(model, state):
    """F_n + F_t on particle i of every bond (B,3) in N, zero for broken bonds.

    F_n = E A_b (L - L0) / L0 n (SPEC 2), recomputed from the positions; F_t is the
    accumulated tangential force of the state."""
    pairs = model.bond_pairs
    if pairs.shape[0] == 0:
        return np.zeros((0, 3))
    separation = bond_separation(state.position, pairs, model.box_length, model.periodic)
    length = np.linalg.norm(separation, axis=1)
    young = model.bond_material_table()["young_modulus"][model.bond_material]
    area = np.pi * (0.5 * model.bond_diameter) ** 2
    l0 = model.bond_initial_length
    normal = (young * area * (length - l0) / (l0 * length))[:, None] * separation
    force = normal + state.bond_tangential_force
    force[~state.bond_active] = 0.0
    return force


def _intact_only(vectors, active):
    """A broken bond applies no load: its (stale) history is recorded as zero."""
    out = vectors.copy()
    out[~active] = 0.0
    return out


def _wall_array(sim, name, n_walls):
    value = getattr(sim, name, None)
    if value is None or n_walls == 0:
        return np.zeros((n_walls, 3))
    value = value() if callable(value) else value
    return np.asarray(value, dtype=np.float64).reshape(n_walls, 3)


def _host(array):
    """A NumPy copy of a host or device (N,3) array."""
    return array.copy_to_host() if hasattr(array, "copy_to_host") else np.asarray(array)


def write_wall_geometry(f, walls):
    """/walls/geometry of PlaneWall / MeshWall objects at t = 0 (see the module docstring)."""
    from ..walls import MeshWall
    group = f.create_group("walls/geometry")
    w = len(walls)
    group["type"] = np.array([1 if isinstance(x, MeshWall) else 0 for x in walls], np.int8)
    zero = np.zeros(3)
    for name, unit, get in (
            ("point", "m", lambda x: getattr(x, "point", zero)),
            ("normal", "1", lambda x: getattr(x, "normal", zero)),
            ("velocity", "m/s", lambda x: x.velocity),
            ("angular_velocity", "rad/s", lambda x: x.angular_velocity),
            ("rotation_center", "m", lambda x: getattr(x, "rotation_center", zero))):
        group[name] = np.array([get(x) for x in walls], dtype=np.float64).reshape(w, 3)
        group[name].attrs["unit"] = unit
    for k, x in enumerate(walls):
        if isinstance(x, MeshWall):
            group[f"mesh{k}/vertices"] = x.vertices
            group[f"mesh{k}/vertices"].attrs["unit"] = "m"
            group[f"mesh{k}/triangles"] = x.triangles


def count_walls(sim):
    """Number of walls of a Simulation (0 when it has none)."""
    return len(getattr(sim, "walls", None) or ())


class ResultsWriter:
    """Append frames of a Simulation to an HDF5 results file (SPEC 6).

    path: the file (created, or with ``resume_frames`` reopened and truncated to that
    many frames); scene_text: the scene TOML; scene_name: the scene's folder and file;
    backend: "cpu" | "gpu"; time_step: s.
    """

    def __init__(self, path, sim, *, scene_text="", backend="cpu", material_names=None,
                 bond_material_names=None, resume_frames=None, compression="gzip",
                 scene_name=""):
        self.path = Path(path)
        self.n_walls = count_walls(sim)
        self._datasets = None
        self._break_time_written = -1
        model = sim.model
        if resume_frames is not None:
            self._reopen(resume_frames, sim.state)
            return
        self.energy_names = list(sim.energy_terms())
        n, b, w = model.n_particles, model.n_bonds, self.n_walls
        f = h5py.File(self.path, "w", libver="latest")
        self.file = f
        f.attrs["scene"] = scene_text
        f.attrs["scene_name"] = scene_name
        from .. import __version__
        f.attrs["bondem_version"] = __version__
        f.attrs["backend"] = backend
        f.attrs["time_step"] = float(sim.time_step)
        f.attrs["time_step_cause"] = str(getattr(sim, "time_step_cause", ""))
        f.attrs["n_particles"], f.attrs["n_bonds"], f.attrs["n_walls"] = n, b, w
        f.attrs["periodic"] = np.asarray(model.periodic, dtype=np.bool_)
        f.attrs["box_length"] = np.asarray(model.box_length, dtype=np.float64)
        options = dict(compression=compression, shuffle=compression is not None)

        def constant(name, data):
            data = np.asarray(data)
            f.create_dataset(name, data=data, **(options if data.size else {}))
            f[name].attrs["unit"] = UNITS.get(name, "1")

        constant("particles/radius", model.radius)
        constant("particles/material", model.material.astype(np.int32))
        constant("particles/mass", model.mass)
        constant("bonds/pairs", model.bond_pairs)
        constant("bonds/diameter", model.bond_diameter)
        constant("bonds/initial_length", model.bond_initial_length)
        constant("bonds/material", model.bond_material.astype(np.int32))
        names = material_names or [m.name for m in model.materials]
        bond_names = bond_material_names or [m.name for m in model.bond_materials]
        f.create_dataset("materials/names", data=np.array(names, dtype=h5py.string_dtype()))
        f.create_dataset("bond_materials/names",
                         data=np.array(bond_names, dtype=h5py.string_dtype()))
        # break_time/break_mode are rewritten in place at every frame.
        f.create_dataset("bonds/break_time", data=np.full(b, np.nan))
        f["bonds/break_time"].attrs["unit"] = "s"
        f.create_dataset("bonds/break_mode", data=np.zeros(b, dtype=np.int8))
        f["bonds/break_mode"].attrs["unit"] = "1"

        def frames(name, shape, dtype=np.float64, unit=None):
            rows = min(max(shape[0], 1), FRAME_CHUNK_ROWS) if shape else None
            chunks = (1, rows, *shape[1:]) if shape else (1024,)
            f.create_dataset(name, shape=(0, *shape), maxshape=(None, *[None] * len(shape)),
                             dtype=dtype, chunks=chunks, **options)
            f[name].attrs["unit"] = unit or UNITS[name]

        write_wall_geometry(f, getattr(sim, "walls", None) or ())
        frames("time", ())
        for name in ("position", "velocity", "angular_velocity", "force"):
            frames(f"particles/{name}", (n, 3))
        frames("bonds/active", (b,), dtype=np.bool_)
        for name in ("force", "normal_moment", "tangential_moment"):
            frames(f"bonds/{name}", (b, 3))
        for name in ("force", "torque", "position"):
            frames(f"walls/{name}", (w, 3))
        for name in self.energy_names:
            frames(f"energy/{name}", (), unit="J")
        f.swmr_mode = True
        self.n_frames = 0

    def _reopen(self, n_frames, state):
        have = rewrite_results(self.path, n_frames)
        if have < n_frames:
            raise ValueError(f"{self.path}: holds {have} frames, the checkpoint needs {n_frames}")
        f = h5py.File(self.path, "a", libver="latest")
        self.energy_names = list(f["energy"].keys()) if "energy" in f else []
        # breaks after the checkpoint may have been written before the interruption
        f["bonds/break_time"][...] = state.bond_break_time
        f["bonds/break_mode"][...] = state.bond_break_mode
        f.flush()
        f.swmr_mode = True
        self.file = f
        self.n_frames = n_frames

    def append(self, sim, energy=None):
        """Append the Simulation's current state as one frame and flush it to disk.
        energy: its ``energy_terms()`` if the caller has them (J), else computed here."""
        f, state, k = self.file, sim.state, self.n_frames
        # /time is written last: its length is the number of complete frames, even when
        # the process is killed in the middle of an append.
        values = {
            "particles/position": state.position,
            "particles/velocity": state.velocity,
            "particles/angular_velocity": state.angular_velocity,
            "particles/force": _host(sim.force),
            "bonds/active": state.bond_active,
            "bonds/force": bond_forces(sim.model, state),
            "bonds/normal_moment": _intact_only(state.bond_normal_moment, state.bond_active),
            "bonds/tangential_moment": _intact_only(state.bond_tangential_moment,
                                                    state.bond_active),
            "walls/force": _wall_array(sim, "wall_force", self.n_walls),
            "walls/torque": _wall_array(sim, "wall_torque", self.n_walls),
            "walls/position": _wall_array(sim, "wall_positions", self.n_walls),
        }
        energy = sim.energy_terms() if energy is None else energy
        for name in self.energy_names:
            values[f"energy/{name}"] = energy.get(name, np.nan)
        values["time"] = state.time
        if self._datasets is None:  # looking datasets up by name costs more than writing
            # (files of earlier versions have no /particles/force: resume without it)
            self._datasets = {name: f[name] for name in values if name in f}
        values = {name: values[name] for name in self._datasets}
        for name, value in values.items():
            dataset = self._datasets[name]
            dataset.resize(k + 1, axis=0)
            dataset[k] = value
        if self._break_time_written < int(np.count_nonzero(~state.bond_active)):
            f["bonds/break_time"][...] = state.bond_break_time
            f["bonds/break_mode"][...] = state.bond_break_mode
            self._break_time_written = int(np.count_nonzero(~state.bond_active))
        self.n_frames = k + 1
        f.flush()

    def close(self):
        if self.file:
            self.file.close()
            self.file = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _frame_datasets(f):
    names = []
    f.visititems(lambda name, obj: names.append(name)
                 if isinstance(obj, h5py.Dataset) and obj.maxshape[:1] == (None,) else None)
    return names


def rewrite_results(path, n_frames=None) -> int:
    """Rewrite a results file cleanly, keeping its first ``n_frames`` frames (default: all
    complete frames, the length of /time); returns the frames kept.

    A writer killed in SWMR mode leaves HDF5's "open for write" flag set: the file still
    opens with ``h5py.File(path, "r", swmr=True)`` (as ``read_results`` does), but not for
    writing nor, with plain ``h5py.File(path)``, for reading. This copies it (through
    SWMR read) into a new file, cut to the frames wanted, and atomically replaces it.
    """
    path = Path(path)
    temporary = path.with_name(path.name + ".rewrite")
    with h5py.File(path, "r", swmr=True) as source:
        complete = min(source[name].shape[0] for name in _frame_datasets(source))
        keep = complete if n_frames is None else min(n_frames, complete)
        with h5py.File(temporary, "w", libver="latest") as target:
            for key, value in source.attrs.items():
                target.attrs[key] = value
            for name in source:
                source.copy(source[name], target, name=name)
            for name in _frame_datasets(target):
                target[name].resize(keep, axis=0)
    os.replace(temporary, path)
    return keep


def read_results(path) -> dict:
    """Every dataset of a results file as NumPy arrays, keyed by path ("particles/position"),
    plus "attrs" (dict of root attributes). Opens in SWMR read mode, so it also works on a
    file that is still being written."""
    out = {}
    with h5py.File(path, "r", swmr=True) as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                data = obj[()]
                if obj.dtype.kind == "O":
                    data = np.array([v.decode() if isinstance(v, bytes) else v for v in data])
                out[name] = data
        f.visititems(visit)
        out["attrs"] = dict(f.attrs)
    return out

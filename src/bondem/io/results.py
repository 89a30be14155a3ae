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
/walls/history/ time (H,) s, force (H,W,3) N, position (H,W,3) m: every step whose wall
       forces changed (the loads evaluated at that time; not tied to the frames)
/walls/geometry/ type (W,) 0 plane 1 mesh, point, normal, velocity, angular_velocity,
       rotation_center (W,3) m, -, m/s, rad/s, m at t = 0; meshN/vertices (V,3) m and
       meshN/triangles (T,3) for mesh wall N (for the ParaView export)
/particles/force (F,N,3) N: the particles' loads of the last force evaluation
/particles/field_force (F,N,3) N: with a fluid or a rotating frame, their force on each
           particle at the frame's state (drag, buoyancy, centrifugal, Coriolis); with
           it /particles/fixed (N,) bool
/energy/<term> (F,) J: Simulation.energy_terms()
/materials/names, /bond_materials/names
attrs on /: scene (the scene text), scene_name, bondem_version, backend, time_step (s),
periodic (3,) bool, box_length (3,) m (periodic cell; 1 along other axes), gravity (3,)
m/s^2, ...
```
The file is built whole (every dataset, no frames) under a temporary name and renamed into
place; each frame then opens it in SWMR mode (``libver="latest"``), appends and closes it.
So plain ``h5py.File(path)`` opens it between frames, after the run and after a kill (a
watchman process clears the "open for write" mark of a writer killed within a frame:
``_h5guard``), and ``h5py.File(path, "r", swmr=True)`` follows a running simulation.
"""
from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from ..errors import InputError
from ..model import bond_separation
from ._h5guard import clear_open_flags

LOCK_NAME = ".bondem.lock"   # held by a run in the results file's folder (runner.py)
FRAME_CHUNK_ROWS = 65536  # rows of (N,3)/(B,3) per chunk: ~1.5 MB, bounded for big runs
UNITS = {
    "time": "s", "particles/radius": "m", "particles/material": "1", "particles/mass": "kg",
    "particles/position": "m", "particles/velocity": "m/s",
    "particles/angular_velocity": "rad/s", "bonds/pairs": "1", "bonds/diameter": "m",
    "bonds/initial_length": "m", "bonds/material": "1", "bonds/active": "1",
    "bonds/break_time": "s", "bonds/break_mode": "1", "bonds/force": "N",
    "bonds/normal_moment": "N m", "bonds/tangential_moment": "N m", "walls/force": "N",
    "walls/torque": "N m", "walls/position": "m", "particles/force": "N",
    "walls/history/time": "s", "walls/history/force": "N", "walls/history/position": "m",
    "particles/field_force": "N", "particles/fixed": "1",
    "contacts/end": "1", "contact_rows/i": "1", "contact_rows/j": "1",
    "contact_rows/force": "N",
    "particles/clump": "1", "clumps/mass": "kg", "clumps/inertia": "kg m^2",
    "clumps/position": "m", "clumps/orientation": "1", "clumps/velocity": "m/s",
    "clumps/angular_momentum": "N m s",
}
ROWS = "contact_rows/"   # the touching contacts of every frame, one after the other


def contact_rows(sim):
    """The contacts that carried a load in the last step: i (K,) particle, j (K,) the
    other particle or -1 - w for wall w, force (K,3) N on particle i (particle pairs
    first, then walls)."""
    extra = sim.state.extra
    parts = []
    if "contact_pairs" in extra and extra["contact_pairs"].shape[0]:
        force = np.asarray(extra["contact_force"])
        live = np.any(force != 0.0, axis=1)
        pairs = np.asarray(extra["contact_pairs"])[live]
        parts.append((pairs[:, 0], pairs[:, 1], force[live]))
    walls = getattr(getattr(sim, "contacts", None), "walls", None)
    if "wall_pairs" in extra and extra["wall_pairs"].shape[0] and walls is not None:
        force = np.asarray(extra["wall_force_rows"])
        live = np.any(force != 0.0, axis=1)
        pairs = np.asarray(extra["wall_pairs"])[live]
        parts.append((pairs[:, 0], -1 - np.asarray(walls.element_wall)[pairs[:, 1]],
                      force[live]))
    if not parts:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3))
    return (np.concatenate([p[0] for p in parts]).astype(np.int64),
            np.concatenate([p[1] for p in parts]).astype(np.int64),
            np.concatenate([p[2] for p in parts]).astype(np.float64))


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


def _has_fields(model):
    """Whether a field model acts on the particles (a fluid, a rotating frame)."""
    return bool(model.acting_fields)


def _field_forces(model, state):
    """(N,3) N: the field models' force on each particle (a fluid's, a frame's)."""
    from ..backends.cpu import field_force_array
    return field_force_array(model, state)


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
        self._guard = None
        self._break_time_written = -1
        if resume_frames is not None:
            self._reopen(resume_frames, sim.state)
        else:
            # Built whole in a file of its own and renamed into place: a kill at any moment
            # leaves either no results file or a complete, closed one.
            temporary = self.path.with_name(self.path.name + ".new")
            with h5py.File(temporary, "w", libver="latest") as f:
                self.energy_names = _create_layout(
                    f, sim, scene_text=scene_text, backend=backend, scene_name=scene_name,
                    material_names=material_names, bond_material_names=bond_material_names,
                    compression=compression)
            os.replace(temporary, self.path)
            self.n_frames = 0
        self._guard = _start_guard(self.path)

    def _reopen(self, n_frames, state):
        have = rewrite_results(self.path, n_frames, history_until=state.time)
        if have < n_frames:
            raise UnreadableResults(f"holds {have} frames, the checkpoint needs {n_frames}",
                                    file=str(self.path))
        with self._open() as f:
            self.energy_names = list(f["energy"].keys()) if "energy" in f else []
            # breaks after the checkpoint may have been written before the interruption
            f["bonds/break_time"][...] = state.bond_break_time
            f["bonds/break_mode"][...] = state.bond_break_mode
        self.n_frames = n_frames

    def _open(self):
        """The file opened for one frame, in SWMR mode: HDF5 then writes metadata in an
        order that keeps the file consistent at every moment. Closed after the frame, the
        file opens with plain ``h5py.File(path)`` between frames; a writer killed within a
        frame leaves the "open for write" mark, which the watchman clears. No file lock:
        a reader that holds the file open (a notebook, HDFView) must not stop the run."""
        try:
            f = h5py.File(self.path, "r+", libver="latest", locking=False)
        except TypeError:   # h5py without the locking option
            f = h5py.File(self.path, "r+", libver="latest")
        f.swmr_mode = True
        return f

    def append(self, sim, energy=None):
        """Append the Simulation's current state as one frame and flush it to disk.
        energy: its ``energy_terms()`` if the caller has them (J), else computed here."""
        self.append_wall_history(sim)
        state, k = sim.state, self.n_frames
        # /time is written last: its length is the number of complete frames, even when
        # the process is killed in the middle of an append.
        values = {
            "particles/position": state.position,
            "particles/velocity": state.velocity,
            "particles/angular_velocity": state.angular_velocity,
            "particles/force": _host(sim.force),
            "particles/field_force": (_field_forces(sim.model, state)
                                      if _has_fields(sim.model) else None),
            "bonds/active": state.bond_active,
            "clumps/position": state.clump_position,
            "clumps/orientation": state.clump_orientation,
            "clumps/velocity": state.clump_velocity,
            "clumps/angular_momentum": state.clump_angular_momentum,
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
        pull = getattr(getattr(sim, "contacts", None), "_pull_history", None)
        if getattr(sim, "backend_name", "cpu") != "cpu" and pull is not None:
            pull(state)   # the device's rows (not to_host: it books the energy counters)
        rows = contact_rows(sim)
        values["time"] = state.time
        broken = int(np.count_nonzero(~state.bond_active))
        f = self._open()
        try:
            if "contacts/end" in f:   # files of earlier versions have no contact rows
                start = int(f["contacts/end"][k - 1]) if k else 0
                for name, data in zip(("i", "j", "force"), rows):
                    dataset = f[ROWS + name]
                    dataset.resize(start + data.shape[0], axis=0)
                    dataset[start:] = data
                values["contacts/end"] = start + rows[0].shape[0]
            for name, value in values.items():
                if value is not None and name in f:   # older files lack some
                    dataset = f[name]
                    dataset.resize(k + 1, axis=0)
                    dataset[k] = value
            if self._break_time_written < broken:
                f["bonds/break_time"][...] = state.bond_break_time
                f["bonds/break_mode"][...] = state.bond_break_mode
            f.close()
        except BaseException:
            _close_quietly(f)   # the first error is the one to report, not close's
            raise
        self._break_time_written = max(self._break_time_written, broken)
        self.n_frames = k + 1

    def append_wall_history(self, sim):
        """Append the wall-load rows the Simulation recorded since the last call
        (``/walls/history``)."""
        history = getattr(sim, "wall_history", None)
        if history is None or not len(history):
            return
        self.append_wall_rows(*history.take())

    def append_wall_rows(self, time, force, position):
        """Append wall-load rows: time (H,) s, force and position (H,W,3) N, m (the
        history's time is written last, so its length counts whole rows)."""
        if time.shape[0] == 0:
            return
        f = self._open()
        try:
            if "walls/history/time" in f:   # files of earlier versions have no history
                for name, data in (("force", force), ("position", position), ("time", time)):
                    dataset = f[f"walls/history/{name}"]
                    k = dataset.shape[0]
                    dataset.resize(k + data.shape[0], axis=0)
                    dataset[k:] = data
            f.close()
        except BaseException:
            _close_quietly(f)
            raise

    def close(self):
        """Stop the watchman (the file itself is closed after every frame)."""
        guard, self._guard = self._guard, None
        if guard is not None:
            _close_quietly(guard.stdin)
            try:
                guard.wait(timeout=10)
            except Exception:  # noqa: BLE001 - a slow watchman ends on its own
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _close_quietly(handle):
    try:
        handle.close()
    except Exception:  # noqa: BLE001 - after a first error, e.g. a full disk
        pass


def _start_guard(path):
    """The watchman process of ``_h5guard`` for ``path`` (None if it cannot start): it
    clears HDF5's "open for write" mark when this process dies within a frame."""
    import subprocess
    import sys
    from . import _h5guard
    try:
        return subprocess.Popen(
            [sys.executable, "-I", "-S", _h5guard.__file__, str(Path(path).resolve())],
            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True)   # not killed with the writer's process group
    except OSError:
        return None


def _create_layout(f, sim, *, scene_text, backend, scene_name, material_names,
                   bond_material_names, compression):
    """Every dataset of an empty results file (0 frames); returns the energy terms'
    names."""
    model = sim.model
    energy_names = list(sim.energy_terms())
    n, b, w = model.n_particles, model.n_bonds, count_walls(sim)
    f.attrs["scene"] = scene_text
    f.attrs["scene_name"] = scene_name
    from .._version import __version__
    f.attrs["bondem_version"] = __version__
    f.attrs["backend"] = backend
    f.attrs["time_step"] = float(sim.time_step)
    f.attrs["time_step_cause"] = str(getattr(sim, "time_step_cause", ""))
    f.attrs["n_particles"], f.attrs["n_bonds"], f.attrs["n_walls"] = n, b, w
    f.attrs["periodic"] = np.asarray(model.periodic, dtype=np.bool_)
    f.attrs["box_length"] = np.asarray(model.box_length, dtype=np.float64)
    f.attrs["gravity"] = np.asarray(model.gravity, dtype=np.float64)
    options = dict(compression=compression, shuffle=compression is not None)

    def constant(name, data):
        data = np.asarray(data)
        f.create_dataset(name, data=data, **(options if data.size else {}))
        f[name].attrs["unit"] = UNITS.get(name, "1")

    constant("particles/radius", model.radius)
    constant("particles/material", model.material.astype(np.int32))
    constant("particles/mass", model.mass)
    if model.n_clumps:
        # each particle's clump (-1: a free sphere), the clumps' mass and principal moments
        constant("particles/clump", model.clump_of)
        constant("clumps/mass", model.clump_mass)
        constant("clumps/inertia", model.clump_inertia)
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
    if _has_fields(model):
        frames("particles/field_force", (n, 3))
        # what the report's fluid summary needs: the weight the fields may carry
        constant("particles/fixed", np.asarray(model.fixed, dtype=np.bool_))
    if model.n_clumps:
        for name, columns in (("position", 3), ("orientation", 4), ("velocity", 3),
                              ("angular_momentum", 3)):
            frames(f"clumps/{name}", (model.n_clumps, columns))
    frames("bonds/active", (b,), dtype=np.bool_)
    for name in ("force", "normal_moment", "tangential_moment"):
        frames(f"bonds/{name}", (b, 3))
    for name in ("force", "torque", "position"):
        frames(f"walls/{name}", (w, 3))
    if w:
        frames("walls/history/time", ())
        for name in ("force", "position"):
            frames(f"walls/history/{name}", (w, 3))
    for name in energy_names:
        frames(f"energy/{name}", (), unit="J")
    # the touching contacts: frame k's rows are end[k - 1]:end[k] of /contact_rows
    frames("contacts/end", (), dtype=np.int64)
    for name, shape, dtype in (("i", (), np.int64), ("j", (), np.int64),
                               ("force", (3,), np.float64)):
        f.create_dataset(ROWS + name, shape=(0, *shape), maxshape=(None, *shape),
                         dtype=dtype, chunks=(4096, *shape), **options)
        f[ROWS + name].attrs["unit"] = UNITS[ROWS + name]
    return energy_names


HISTORY = "walls/history/"


def _frame_datasets(f, history=False):
    """Names of the datasets that grow by one row per frame (history=True: the wall
    history's, which grow per step)."""
    names = []
    f.visititems(lambda name, obj: names.append(name)
                 if isinstance(obj, h5py.Dataset) and obj.maxshape[:1] == (None,)
                 and name.startswith(HISTORY) == history and not name.startswith(ROWS)
                 else None)
    return names


class UnreadableResults(InputError):
    """A results file that HDF5 cannot read (truncated, not HDF5, missing datasets)."""


def open_results(path, *, live=True):
    """``path`` opened read-only with h5py; ``live``: as an SWMR reader, which sees the
    frames a running writer appends (``refresh``) and reads while the writer is within a
    frame. The file is first opened plainly, which HDF5 refuses at once for a truncated or
    damaged file (an SWMR reader skips that check and then waits on the missing end).
    Raises UnreadableResults naming the file."""
    path = Path(path)
    try:
        try:
            plain = h5py.File(path, "r", locking=False)
        except TypeError:    # h5py without the locking option
            plain = h5py.File(path, "r")
    except OSError as error:
        if "already open for write" not in str(error):
            raise _unreadable(path, error) from None
        plain = None     # a writer is within a frame (or died there): only SWMR reads it
    if plain is not None and not (live and _writer_running(path)):
        return plain
    if plain is not None:
        plain.close()
    try:
        return h5py.File(path, "r", swmr=True)
    except OSError as error:
        raise _unreadable(path, error) from None


def _writer_running(path):
    """True if a ``bondem run`` holds the lock of the results file's folder."""
    lock = Path(path).parent / LOCK_NAME
    try:
        import fcntl
        handle = open(lock, "rb")
    except (ImportError, OSError):
        return False
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(handle, fcntl.LOCK_UN)
    return False


def _hdf5_reason(error):
    text = str(error)
    return text.split("(", 1)[1].rstrip(")") if "(" in text else text


def _unreadable(path, error, what="cannot open as HDF5"):
    path = Path(path)
    if "signature" in str(error) and path.is_file():
        # not HDF5 at all: most often a scene file given where its results were meant
        if path.suffix.lower() == ".toml":
            return UnreadableResults(
                "this is a scene file, not results: give the results file its run wrote, "
                f"{path.with_suffix('') / 'results.h5'} (bondem run {path} writes it)",
                file=str(path))
        return UnreadableResults("not a results file (not HDF5): give the results.h5 that "
                                 "bondem run wrote", file=str(path))
    return UnreadableResults(f"{what} ({_hdf5_reason(error)})", file=str(path))


def rewrite_results(path, n_frames=None, history_until=None) -> int:
    """Rewrite a results file cleanly, keeping its first ``n_frames`` frames (default: all
    complete frames, the length of /time) and the wall-history rows evaluated before
    ``history_until`` (s; default: all whole rows); returns the frames kept. Call it only when no
    writer is running (``bondem run --resume`` does, holding the folder's lock).

    First clears an "open for write" mark left by a killed writer (as ``h5clear -s``),
    then copies the file into a new one, cut to the frames wanted, and atomically
    replaces it. Raises UnreadableResults for a file that is not a readable results file.
    """
    path = Path(path)
    clear_open_flags(path)
    temporary = path.with_name(path.name + ".rewrite")
    try:
        with open_results(path, live=False) as source:
            frame_names = _frame_datasets(source)
            if "time" not in frame_names:
                raise UnreadableResults("no /time dataset (not a bondem results file)",
                                        file=str(path))
            complete = min(source[name].shape[0] for name in frame_names)
            keep = complete if n_frames is None else min(n_frames, complete)
            with h5py.File(temporary, "w", libver="latest") as target:
                for key, value in source.attrs.items():
                    target.attrs[key] = value
                for name in source:
                    source.copy(source[name], target, name=name)
                for name in _frame_datasets(target):
                    target[name].resize(keep, axis=0)
                if "contacts/end" in target:
                    end = int(target["contacts/end"][keep - 1]) if keep else 0
                    for name in ("i", "j", "force"):
                        target[ROWS + name].resize(end, axis=0)
                rows = _frame_datasets(target, history=True)
                if rows:
                    whole = min(target[name].shape[0] for name in rows)
                    if history_until is not None:
                        times = target[HISTORY + "time"][:whole]
                        whole = int(np.count_nonzero(times < history_until))
                    for name in rows:
                        target[name].resize(whole, axis=0)
    except (OSError, KeyError, RuntimeError) as error:
        temporary.unlink(missing_ok=True)
        raise _unreadable(path, error, "cannot read") from None
    os.replace(temporary, path)
    return keep


def read_results(path) -> dict:
    """Every dataset of a results file as NumPy arrays, keyed by path ("particles/position"),
    plus "attrs" (dict of root attributes). Also works on a file that is being written."""
    out = {}
    with open_results(path) as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                data = obj[()]
                if obj.dtype.kind == "O":
                    data = np.array([v.decode() if isinstance(v, bytes) else v for v in data])
                out[name] = data
        f.visititems(visit)
        out["attrs"] = dict(f.attrs)
    return out

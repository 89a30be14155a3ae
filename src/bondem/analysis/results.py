"""Read-only access to a results file (SPEC 6), also while the run is still writing it.

The writer appends one frame at a time to every per-frame dataset, in SWMR mode (HDF5
single-writer / multiple-reader), and this reads as an SWMR reader while a run writes.
A reader may therefore see a frame that is in /time but not yet in /bonds/active, or the
other way round. ``Results`` refreshes every
dataset it reads and counts only the frames present in all of them, so every analysis
sees complete frames only.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.results import open_results
from ..physics import bond_models

# Datasets with a leading frame axis; the complete-frame count is the smallest length.
PER_FRAME = ("time", "particles/position", "particles/velocity",
             "particles/angular_velocity", "bonds/active", "bonds/force",
             "walls/force", "walls/position", "walls/torque")

ENERGY_STORED = ("kinetic_translational", "kinetic_rotational", "bond_elastic",
                 "contact_elastic")
ENERGY_WORK = ("work_external", "work_walls")
ENERGY_LOSSES = ("dissipated_damping", "dissipated_contacts", "released_breakage",
                 *(m.STATE[1] for m in bond_models.MODELS if m.STATE))


def open_h5(path):
    """Open a results file for reading (``io.results.open_results``: as an SWMR reader, so
    frames a running writer appends appear on ``refresh``); InputError naming the file if
    it is missing or unreadable."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such results file", file=str(path))
    return open_results(path)


class Results:
    """A results file opened for analysis; use as a context manager.

    ``n_frames`` counts the frames complete in every per-frame dataset present, read when
    the file is opened (call ``refresh()`` to see frames written since). Frame indices
    accept negative values as in Python (-1: last complete frame).
    """

    def __repr__(self):
        if getattr(self, "file", None) is None or not self.file:
            return f"Results({str(self.path)!r}, closed)"
        t = f", t = 0 .. {float(self.time[-1]):.6g} s" if self.n_frames else ""
        intact = ""
        if self.n_frames and self.n_bonds:
            active = np.asarray(self.file["bonds/active"][self.n_frames - 1])
            intact = f", {int(active.sum())} of {self.n_bonds} bonds intact at the end"
        return (f"Results({str(self.path)!r}: {self.n_frames} frames{t}, "
                f"{self.n_particles} particles, {self.n_walls} walls{intact})")

    def __init__(self, path):
        self.path = Path(path)
        self.file = open_h5(self.path)
        try:
            for key in ("time", "particles/radius", "bonds/pairs"):
                if key not in self.file:
                    raise InputError(f"missing dataset /{key} (not a bondem results file?)",
                                     file=str(self.path), key=key)
            self.refresh()
        except Exception:
            self.file.close()
            raise

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        self.file.close()

    # -- bookkeeping -------------------------------------------------------------------
    def refresh(self):
        """Re-read dataset lengths (SWMR) and recount the complete frames."""
        lengths = []
        for key in PER_FRAME:
            if key in self.file:
                dataset = self.file[key]
                if self.file.swmr_mode:
                    dataset.refresh()
                lengths.append(dataset.shape[0])
        if "energy" in self.file:
            for dataset in self.file["energy"].values():
                if self.file.swmr_mode:
                    dataset.refresh()
                lengths.append(dataset.shape[0])
        self.n_frames = int(min(lengths))
        return self.n_frames

    def _dataset(self, key):
        dataset = self.file[key]
        if self.file.swmr_mode:
            dataset.refresh()
        return dataset

    def has(self, key):
        """True if dataset ``key`` (e.g. "walls/force") exists."""
        return key in self.file

    def frame_index(self, frame):
        """Non-negative index of ``frame`` among the complete frames; IndexError if none."""
        index = int(frame) + (self.n_frames if frame < 0 else 0)
        if not 0 <= index < self.n_frames:
            raise IndexError(f"frame {frame} out of range: {self.n_frames} complete frames")
        return index

    def frames(self, key):
        """All complete frames of the per-frame dataset ``key`` as an array (F, ...)."""
        return self._dataset(key)[: self.n_frames]

    def wall_history(self):
        """The walls' per-step history (/walls/history: every step whose wall loads
        changed, more rows than frames): (time (H,) s, force (H,W,3) N, position (H,W,3)
        m) in float64, its whole rows (the writer appends time last); None in files
        without one."""
        if "walls/history/time" not in self.file:
            return None
        count = self._dataset("walls/history/time").shape[0]
        return tuple(np.asarray(self._dataset(f"walls/history/{name}")[:count],
                                dtype=np.float64)
                     for name in ("time", "force", "position"))

    def frame(self, key, frame):
        """One frame of the per-frame dataset ``key``."""
        return self._dataset(key)[self.frame_index(frame)]

    # -- constant data -----------------------------------------------------------------
    @property
    def time(self):
        """Frame times (F,) in s."""
        return np.asarray(self.frames("time"), dtype=np.float64)

    @property
    def n_particles(self):
        return int(self.file["particles/radius"].shape[0])

    @property
    def n_bonds(self):
        return int(self.file["bonds/pairs"].shape[0])

    @property
    def radius(self):
        """Particle radii (N,) in m."""
        return np.asarray(self._dataset("particles/radius")[()], dtype=np.float64)

    @property
    def mass(self):
        """Particle masses (N,) in kg; without /particles/mass, radius^3 (relative masses,
        a uniform density: every analysis here uses mass fractions only)."""
        if "particles/mass" in self.file:
            return np.asarray(self._dataset("particles/mass")[()], dtype=np.float64)
        return self.radius ** 3

    @property
    def clump_of(self):
        """Each particle's clump (N,) int64, -1 for a free sphere; None in a file without
        clumps."""
        if "particles/clump" not in self.file:
            return None
        return np.asarray(self._dataset("particles/clump")[()], dtype=np.int64)

    @property
    def pairs(self):
        """Bond particle indices (B,2)."""
        return np.asarray(self._dataset("bonds/pairs")[()], dtype=np.int64).reshape(-1, 2)

    @property
    def break_mode(self):
        """Break mode per bond (B,) int8 (0 intact, 1 tension, 2 compression, 3 shear), as
        of the last write; None if the file does not record it."""
        if "bonds/break_mode" not in self.file:
            return None
        return np.asarray(self._dataset("bonds/break_mode")[()], dtype=np.int8)

    @property
    def break_time(self):
        """Break time per bond (B,) in s, NaN while intact; None if not recorded."""
        if "bonds/break_time" not in self.file:
            return None
        return np.asarray(self._dataset("bonds/break_time")[()], dtype=np.float64)

    def contacts(self, frame=-1):
        """The contacts that carried a load at ``frame``: {"i": (K,) particle, "j": (K,)
        the other particle or -1 - w for wall w, "force": (K,3) N on particle i}; empty
        arrays in files written before contacts were saved."""
        if "contacts/end" not in self.file:
            return {"i": np.zeros(0, np.int64), "j": np.zeros(0, np.int64),
                    "force": np.zeros((0, 3))}
        k = self.frame_index(frame)
        end = self._dataset("contacts/end")
        start, stop = (int(end[k - 1]) if k else 0), int(end[k])
        return {name: np.asarray(self._dataset(f"contact_rows/{name}")[start:stop])
                for name in ("i", "j", "force")}

    def active(self, frame=None):
        """Intact-bond flags: (B,) for one frame, (F,B) for all complete frames."""
        if self.n_bonds == 0:
            shape = (0,) if frame is not None else (self.n_frames, 0)
            return np.zeros(shape, dtype=bool)
        if frame is None:
            return np.asarray(self.frames("bonds/active"), dtype=bool)
        return np.asarray(self.frame("bonds/active", frame), dtype=bool)

    def iter_active(self, block=64):
        """Intact-bond flags of the complete frames, ``block`` frames at a time: yields
        (first frame index, (k,B) bool) so that big runs need not fit in memory."""
        for start in range(0, self.n_frames, block):
            stop = min(start + block, self.n_frames)
            if self.n_bonds == 0:
                yield start, np.zeros((stop - start, 0), dtype=bool)
            else:
                yield start, np.asarray(self._dataset("bonds/active")[start:stop], dtype=bool)

    def any_broken(self):
        """(F,) bool: some bond is broken at that frame."""
        out = np.zeros(self.n_frames, dtype=bool)
        for start, block in self.iter_active():
            out[start:start + len(block)] = ~block.all(axis=1)
        return out

    def energy(self):
        """Energy terms {name: (F,) J} from /energy, or {} if the file has none."""
        if "energy" not in self.file:
            return {}
        return {name: np.asarray(self.frames(f"energy/{name}"), dtype=np.float64)
                for name in self.file["energy"]}

    @property
    def n_walls(self):
        return int(self.file["walls/force"].shape[1]) if "walls/force" in self.file else 0

    @property
    def attrs(self):
        return dict(self.file.attrs)

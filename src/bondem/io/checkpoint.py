"""Checkpoints: the full State (every array, ``state.extra`` included, whatever their
current shapes) plus time, step and bookkeeping, written atomically.

Atomic: write a temporary file in the same folder, fsync it, ``os.replace`` it over the
old checkpoint, fsync the folder. A crash at any moment leaves either the old or the new
checkpoint, never a torn one. The State's floats are stored bit for bit (NumPy .npz,
uncompressed), which is what makes a resumed run identical to an uninterrupted one.
"""
from __future__ import annotations

import json
import os
from dataclasses import MISSING, fields
from pathlib import Path

import numpy as np

from ..model import State

FORMAT = 1


def write_checkpoint(path, state: State, *, frames: int, scene_text: str = "",
                     info: dict | None = None) -> Path:
    """Write ``state`` to ``path`` atomically.

    frames: results frames written when the state was taken (resume truncates the results
    file to this many); scene_text: the scene, so a resume against a changed scene is
    refused; info: any JSON-serialisable extras (e.g. time step, s).
    """
    path = Path(path)
    arrays, scalars, extra_kinds = {}, {}, {}
    for f in fields(State):
        value = getattr(state, f.name)
        if f.name == "extra" or value is None:
            continue  # None: an optional array not set (bond_previous_length)
        if isinstance(value, np.ndarray):
            arrays[f"state/{f.name}"] = value
        else:
            scalars[f.name] = value
    for key, value in state.extra.items():
        if isinstance(value, np.ndarray):
            extra_kinds[key] = "array"
        else:
            extra_kinds[key] = type(value).__name__
        arrays[f"extra/{key}"] = np.asarray(value)
    # float scalars go through arrays too, so their bits survive (JSON would round them).
    for name, value in scalars.items():
        arrays[f"scalar/{name}"] = np.asarray(value)
    meta = {"format": FORMAT, "frames": int(frames), "scalars": list(scalars),
            "extra": extra_kinds, "info": info or {}}
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    arrays["scene"] = np.frombuffer(scene_text.encode(), dtype=np.uint8)
    temporary = path.with_name(path.name + ".tmp")
    with open(temporary, "wb") as handle:
        np.savez(handle, **arrays)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(temporary, path)
    try:
        directory = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(directory)
        finally:
            os.close(directory)
    except OSError:
        pass  # some file systems cannot fsync a folder; the rename is still atomic
    return path


def read_checkpoint(path):
    """(state, frames, scene_text, info) from a checkpoint written by write_checkpoint."""
    with np.load(Path(path), allow_pickle=False) as data:
        meta = json.loads(bytes(data["meta"]).decode())
        if meta.get("format") != FORMAT:
            raise ValueError(f"{path}: checkpoint format {meta.get('format')!r}, "
                             f"expected {FORMAT}")
        kwargs = {}
        for f in fields(State):
            if f.name == "extra":
                continue
            if f.name in meta["scalars"]:
                kwargs[f.name] = data[f"scalar/{f.name}"].item()
            elif f"state/{f.name}" not in data and (f.default is None or
                                                    f.default_factory is not MISSING):
                continue  # optional array absent from older checkpoints: its default
            else:
                kwargs[f.name] = np.ascontiguousarray(data[f"state/{f.name}"])
        extra = {}
        for key, kind in meta["extra"].items():
            value = data[f"extra/{key}"]
            extra[key] = np.ascontiguousarray(value) if kind == "array" else value.item()
        kwargs["extra"] = extra
        scene_text = bytes(data["scene"]).decode()
    return State(**kwargs), meta["frames"], scene_text, meta["info"]

"""Broken bonds: how many over time, by mode, and where in the body they broke.

A bond counts as broken at a frame when /bonds/active is false there. Its mode (tension,
compression, shear/torsion, SPEC 2) comes from /bonds/break_mode, written as bonds break,
so it is known for every bond broken by the last complete frame. Positions are taken at
the first frame (t = 0): the radial coordinate of a bond is the distance of its centre
(the midpoint of its particles) from the body's centre of mass, divided by the body's
outer radius (largest particle distance plus that particle's radius).
"""
from __future__ import annotations

import numpy as np

from ..physics.bond_elastic import BREAK_MODE_NAMES
from .results import Results

MODES = BREAK_MODE_NAMES[1:]  # tension, compression, shear


def broken_series(results):
    """Broken bonds per frame of an open ``Results``: {"time": (F,) s, "broken": (F,),
    "fraction": (F,) broken / all bonds, "tension", "compression", "shear": (F,) counts
    by mode, "unknown": (F,) broken bonds without a recorded mode}."""
    n_bonds = results.n_bonds
    mode = results.break_mode
    if mode is None:
        mode = np.zeros(n_bonds, dtype=np.int8)
    names = ("unknown", *MODES)                  # index = mode code
    counts = np.zeros((results.n_frames, len(names)), dtype=np.int64)
    for start, block in results.iter_active():
        broken = ~block
        for code in range(len(names)):
            counts[start:start + len(block), code] = (broken & (mode == code)).sum(axis=1)
    out = {"time": results.time, "broken": counts.sum(axis=1)}
    out["fraction"] = out["broken"] / n_bonds if n_bonds else np.zeros(len(out["time"]))
    out.update({name: counts[:, code] for code, name in enumerate(names)})
    return out


def broken_bond_fraction(path, frame=-1):
    """Broken bonds over all bonds at ``frame`` of results file ``path`` (0 with no
    bonds)."""
    with Results(path) as results:
        if results.n_bonds == 0:
            return 0.0
        return float(1.0 - results.active(frame).mean())


def radial_breakage(results, frame=-1, bins=10):
    """Where bonds broke, by radial position in the body at t = 0.

    Returns {"radius": (B,) bond centre distance from the centre of mass / outer radius,
    "broken": (B,) bool at ``frame``, "mode": (B,) int8, "edges": (bins+1,) shell
    edges, "all": (bins,) bonds per shell, "broken_count": (bins,), "broken_fraction":
    (bins,) broken/all per shell (NaN where a shell holds no bond), "outer_radius": m,
    "centre": (3,) m}.
    """
    position = np.asarray(results.frame("particles/position", 0), dtype=np.float64)
    mass, radius, pairs = results.mass, results.radius, results.pairs
    centre = (mass[:, None] * position).sum(axis=0) / mass.sum()
    outer = float(np.max(np.linalg.norm(position - centre, axis=1) + radius))
    middle = 0.5 * (position[pairs[:, 0]] + position[pairs[:, 1]])
    relative = np.linalg.norm(middle - centre, axis=1) / outer
    broken = ~results.active(frame)
    mode = results.break_mode
    mode = np.zeros(len(pairs), dtype=np.int8) if mode is None else mode
    edges = np.linspace(0.0, 1.0, bins + 1)
    every, _ = np.histogram(relative, edges)
    hit, _ = np.histogram(relative[broken], edges)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(every > 0, hit / np.maximum(every, 1), np.nan)
    return {"radius": relative, "broken": broken, "mode": mode, "edges": edges,
            "all": every, "broken_count": hit, "broken_fraction": fraction,
            "outer_radius": outer, "centre": centre}


def first_break_time(results):
    """Time (s) the first bond broke: the smallest /bonds/break_time among bonds broken
    by the last complete frame (exact, from the step it broke), else the time of the
    first frame with a broken bond; None if no bond broke."""
    broken_by_frame = results.any_broken()
    if not broken_by_frame.any():
        return None
    break_time = results.break_time
    broken = ~results.active(-1)
    if break_time is not None and np.isfinite(break_time[broken]).any():
        return float(np.nanmin(break_time[broken]))
    return float(results.time[np.argmax(broken_by_frame)])

"""The crack log of a lab test and the acoustic emission read from it: pure functions of
arrays.

Every broken bond is a crack event (its time, place, mode, the loads it carried when it
broke and the elastic energy it held). Acoustic-emission (AE) events group cracks close
in space and time, after Hazzard and Young (2000, Int. J. Rock Mech. Min. Sci. 37): a
crack joins an event when it lies within ``radius`` of one of the event's cracks and
breaks within ``window`` of the event's latest crack. An event's magnitude is the energy
magnitude of Kanamori (1977), log10 E = 1.5 M + 4.8 (E in J), of the elastic energy its
bonds released; the b-value is Aki's (1965) maximum-likelihood estimate.
"""
from __future__ import annotations

import math

import numpy as np

COLUMNS = ("time", "x", "y", "z", "mode", "bond", "energy", "bond_strain",
           "normal_force", "tangential_force", "twisting_moment", "bending_moment",
           "axial_strain", "platen_strain", "event")
UNITS = {"time": "s", "x": "m", "y": "m", "z": "m", "mode": "1", "bond": "1",
         "energy": "J", "bond_strain": "1", "normal_force": "N", "tangential_force": "N",
         "twisting_moment": "N m", "bending_moment": "N m", "axial_strain": "1",
         "platen_strain": "1", "event": "1"}
MIN_EVENTS_FOR_B = 10


def magnitude(energy):
    """Energy magnitude M = (log10 E - 4.8) / 1.5 of the energy ``energy`` (J; an array
    or a number); -inf for E = 0."""
    with np.errstate(divide="ignore"):
        return (np.log10(np.asarray(energy, dtype=np.float64)) - 4.8) / 1.5


def group_events(time, position, radius, window):
    """AE event label (K,) of each of K cracks, numbered 0, 1, ... in the order the
    events start. time (K,) s, position (K,3) m; a crack joins the event of an earlier
    crack within ``radius`` (m) whose event's latest crack broke at most ``window`` (s)
    before it (the nearest such event when several qualify, the first when tied)."""
    time = np.asarray(time, dtype=np.float64)
    position = np.asarray(position, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(time, kind="stable")
    label = np.full(time.shape[0], -1, dtype=np.int64)
    latest = []          # per event: the time of its latest crack
    members = []         # per event: indices of its cracks
    open_events = []     # events whose latest crack is within the window (time order)
    for k in order:
        open_events = [e for e in open_events if time[k] - latest[e] <= window]
        best, best_d = -1, math.inf
        for e in open_events:
            d = float(np.min(np.linalg.norm(position[members[e]] - position[k], axis=1)))
            if d <= radius and d < best_d:
                best, best_d = e, d
        if best < 0:
            best = len(latest)
            latest.append(time[k])
            members.append([])
            open_events.append(best)
        members[best].append(k)
        latest[best] = time[k]   # cracks come in time order
        label[k] = best
    return label


def events(time, position, energy, label):
    """Per AE event (labels 0..E-1): {"time": start (s), "x", "y", "z": the centroid of
    its cracks (m), "cracks": count, "energy": J released, "magnitude": energy
    magnitude}."""
    n = int(label.max()) + 1 if label.size else 0
    count = np.bincount(label, minlength=n).astype(np.float64)
    start = np.full(n, np.inf)
    np.minimum.at(start, label, time)
    out = {"time": start, "cracks": count.astype(np.int64)}
    for axis, name in enumerate("xyz"):
        out[name] = (np.bincount(label, weights=position[:, axis], minlength=n)
                     / np.maximum(count, 1.0))
    out["energy"] = np.bincount(label, weights=energy, minlength=n)
    out["magnitude"] = magnitude(out["energy"])
    return out


def b_value(magnitudes, minimum=None):
    """Aki's maximum-likelihood b-value log10(e) / (mean(M) - M_min) of the magnitudes
    at or above ``minimum`` (default: the smallest); NaN with fewer than MIN_EVENTS_FOR_B
    finite magnitudes or when they are all equal."""
    m = np.asarray(magnitudes, dtype=np.float64)
    m = m[np.isfinite(m)]
    if minimum is not None:
        m = m[m >= minimum]
    if m.size < MIN_EVENTS_FOR_B:
        return math.nan
    low = float(m.min()) if minimum is None else float(minimum)
    spread = float(m.mean()) - low
    return math.log10(math.e) / spread if spread > 0.0 else math.nan


def crack_damage(stress, volumetric):
    """Crack-damage stress sigma_cd (Pa): the stress where the volumetric strain
    (compaction positive) is largest before the peak stress, the onset of dilatancy
    (Martin and Chandler 1994); NaN when it is largest at the peak itself (no
    dilatancy before it)."""
    stress, volumetric = np.asarray(stress, float), np.asarray(volumetric, float)
    if stress.size == 0:
        return math.nan
    top = int(np.argmax(stress))
    k = int(np.argmax(volumetric[:top + 1]))
    return float(stress[k]) if k < top else math.nan

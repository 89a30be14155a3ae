"""Fragments: connected components of the graph of intact bonds.

Particles are nodes, intact bonds are edges; a fragment is a connected component
(scipy.sparse.csgraph.connected_components). A particle with no intact bond is a fragment
of its own. The members of a clump (a rigid grain, bondem.clumps) are always one piece:
they are joined by edges that never break, and a fragment's count is its grains (clumps
and free spheres), not its spheres. Fragment ids are ordered by decreasing mass (0 is the largest fragment), so
that ids are stable enough from frame to frame to colour fragments in ParaView.
"""
from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .results import Results


def _clump_edges(clump_of):
    """Edges (E,2) that chain each clump's members together."""
    if clump_of is None:
        return np.zeros((0, 2), dtype=np.int64)
    clump_of = np.asarray(clump_of, dtype=np.int64)
    members = np.flatnonzero(clump_of >= 0)
    members = members[np.argsort(clump_of[members], kind="stable")]
    same = clump_of[members[1:]] == clump_of[members[:-1]]
    return np.column_stack([members[:-1][same], members[1:][same]])


def fragment_labels(pairs, active, n, mass=None, clump_of=None):
    """Fragments of ``n`` particles joined by the ``active`` bonds among ``pairs``.

    pairs: (B,2) particle indices; active: (B,) bool, intact bonds; n: particle count;
    mass: (N,) kg, optional, orders the ids by decreasing fragment mass (by particle
    count without it; ties by the smallest particle index); clump_of: (N,) each
    particle's clump (-1 free), whose members are one piece whatever the bonds.
    Returns (n_fragments, labels (N,) int64 fragment id of every particle).
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    active = np.asarray(active, dtype=bool).reshape(-1)
    if active.shape[0] != pairs.shape[0]:
        raise ValueError(f"active: length {active.shape[0]}, expected {pairs.shape[0]} "
                         "(one per bond)")
    if n == 0:
        return 0, np.zeros(0, dtype=np.int64)
    edges = np.vstack([pairs[active], _clump_edges(clump_of)])
    graph = coo_matrix((np.ones(len(edges), dtype=np.int8), (edges[:, 0], edges[:, 1])),
                       shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    weight = np.ones(n) if mass is None else np.asarray(mass, dtype=np.float64)
    size = np.bincount(labels, weights=weight, minlength=count)
    first = np.full(count, n, dtype=np.int64)
    np.minimum.at(first, labels, np.arange(n))
    order = np.lexsort((first, -size))           # largest first, then by first particle
    rank = np.empty(count, dtype=np.int64)
    rank[order] = np.arange(count)
    return int(count), rank[labels]


def fragment_sizes(labels, mass, clump_of=None):
    """Per-fragment (grain counts, masses in kg), both (n_fragments,), largest mass
    first. labels: (N,) fragment ids 0..n_fragments-1; mass: (N,) kg; clump_of: (N,)
    each particle's clump (-1 free): a clump counts as one grain (else each particle)."""
    labels = np.asarray(labels, dtype=np.int64)
    mass = np.asarray(mass, dtype=np.float64)
    grain = np.ones(labels.shape[0])
    if clump_of is not None:
        clump_of = np.asarray(clump_of, dtype=np.int64)
        inside = clump_of >= 0
        # one member of each clump counts it
        _, first = np.unique(clump_of[inside], return_index=True)
        grain[inside] = 0.0
        grain[np.flatnonzero(inside)[first]] = 1.0
    counts = np.bincount(labels, weights=grain).astype(np.int64)
    masses = np.bincount(labels, weights=mass, minlength=counts.shape[0])
    order = np.lexsort((-counts, -masses))
    return counts[order], masses[order]


def size_distribution(masses, total_mass=None):
    """Cumulative mass distribution of fragments: (fragment masses ascending in kg,
    mass fraction in fragments of that mass or smaller), the sieve curve of a breakage
    test. masses: (K,) kg; total_mass: kg, default the sum."""
    masses = np.sort(np.asarray(masses, dtype=np.float64))
    total = masses.sum() if total_mass is None else float(total_mass)
    return masses, np.cumsum(masses) / total


def count_distribution(counts):
    """Fragments by particle count: (particles per fragment ascending, number of fragments
    of that many particles). counts: (K,) particles in each fragment."""
    sizes, number = np.unique(np.asarray(counts, dtype=np.int64), return_counts=True)
    return sizes, number


def fragment_series(results):
    """Per-frame fragment statistics of an open ``Results``.

    Returns {"time": (F,) s, "fragments": (F,) count of fragments including single
    particles, "fragments_multi": (F,) fragments of 2 or more particles,
    "largest_fraction": (F,) mass of the largest fragment / total mass,
    "largest_count": (F,) particles in the largest fragment}.
    """
    pairs, mass, n = results.pairs, results.mass, results.n_particles
    clump_of = results.clump_of
    out = {"time": results.time, "fragments": [], "fragments_multi": [],
           "largest_fraction": [], "largest_count": []}
    frames = (frame for _, block in results.iter_active() for frame in block)
    for frame_active in frames:
        count, labels = fragment_labels(pairs, frame_active, n, mass, clump_of)
        counts, masses = fragment_sizes(labels, mass, clump_of)
        out["fragments"].append(count)
        out["fragments_multi"].append(int(np.count_nonzero(counts > 1)))
        # over the sum of fragment masses: exactly 1 for an intact body
        out["largest_fraction"].append(masses[0] / masses.sum() if count else 0.0)
        out["largest_count"].append(int(counts[0]) if count else 0)
    for key in ("fragments", "fragments_multi", "largest_count"):
        out[key] = np.asarray(out[key], dtype=np.int64)
    out["largest_fraction"] = np.asarray(out["largest_fraction"], dtype=np.float64)
    return out


def frame_fragments(results, frame=-1):
    """Fragments of one frame: {"time": s, "labels": (N,), "counts": (K,), "masses": (K,)
    kg, "total_mass": kg}, fragments by decreasing mass."""
    mass, clump_of = results.mass, results.clump_of
    _, labels = fragment_labels(results.pairs, results.active(frame), results.n_particles,
                                mass, clump_of)
    counts, masses = fragment_sizes(labels, mass, clump_of)
    return {"time": float(results.time[results.frame_index(frame)]), "labels": labels,
            "counts": counts, "masses": masses, "total_mass": float(masses.sum())}


def largest_fragment_fraction(path, frame=-1):
    """Mass of the largest fragment over the total mass at ``frame`` of results file
    ``path`` (1.0 for an intact body)."""
    with Results(path) as results:
        data = frame_fragments(results, frame)
    return float(data["masses"][0] / data["total_mass"])


def write_fragment_ids(path):
    """Write /particles/fragment (F,N) int32, fragment ids per frame (0 = largest), for
    ParaView. Into the results file itself when it can be opened for writing; if another
    process still writes it (SWMR writer, file locked), into the sidecar file
    ``<stem>.fragments.h5`` next to it, with /time and /particles/fragment.
    Returns the path written."""
    path = Path(path)
    with Results(path) as results:
        pairs, mass, n = results.pairs, results.mass, results.n_particles
        clump_of = results.clump_of
        time = results.time
        labels = np.zeros((len(time), n), dtype=np.int32)
        for start, block in results.iter_active():
            for k, frame_active in enumerate(block):
                labels[start + k] = fragment_labels(pairs, frame_active, n, mass,
                                                    clump_of)[1]
    try:
        target = h5py.File(path, "r+")
        sidecar = False
    except OSError:  # locked by a writer: never write into a file another process owns
        target = h5py.File(path.with_name(path.stem + ".fragments.h5"), "w")
        sidecar = True
    written = Path(target.filename)
    with target:
        if sidecar:
            target.create_dataset("time", data=time)
        group = target.require_group("particles")
        if "fragment" in group:
            del group["fragment"]
        group.create_dataset("fragment", data=labels, compression="gzip",
                             chunks=(1, max(n, 1)) if n else None)
        target["particles/fragment"].attrs["description"] = (
            "fragment id per frame and particle, 0 = largest fragment by mass")
    return written

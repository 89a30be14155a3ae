"""What a lab report reads off a test's curve: pure functions of arrays.

Conventions: stress and strain are positive in the direction the test loads (compression
for the compression tests, extension for direct tension); lateral strain is positive in
the sense Poisson's ratio counts (widening under compression, narrowing under tension), so
Poisson's ratio = lateral / axial strain; ``lateral_strain`` itself returns the widening.
"""
from __future__ import annotations

import math

import numpy as np


def gauge_groups(position, axis, fractions=(0.1, 0.25)):
    """Indices of the particles whose centres lie between fractions[0] and fractions[1]
    (inclusive) of the height from the lower and from the upper end along ``axis``:
    gauge points inside the specimen, away from the platens' contacts, whose mean
    positions give an axial strain free of platen compliance. Where a band is empty (a
    specimen of few layers), the second layer from either end, the end layers themselves
    below four layers."""
    z = position[:, axis]
    low, high = z.min(), z.max()
    h = high - low
    near = np.flatnonzero((z >= low + fractions[0] * h) & (z <= low + fractions[1] * h))
    far = np.flatnonzero((z <= high - fractions[0] * h) & (z >= high - fractions[1] * h))
    if near.size == 0 or far.size == 0:
        # h > 0 here: a single layer lies in both bands
        layer = np.round((z - low) / h, 6)
        layers = np.unique(layer)
        inner = 1 if layers.size >= 4 else 0
        near = np.flatnonzero(layer == layers[inner])
        far = np.flatnonzero(layer == layers[-1 - inner])
    return near, far


def middle_band(position, axis, fractions=(0.25, 0.75)):
    """Indices of the particles in the middle of the height (for the lateral strain)."""
    z = position[:, axis]
    low, h = z.min(), np.ptp(z)
    band = np.flatnonzero((z >= low + fractions[0] * h) & (z <= low + fractions[1] * h))
    return band if band.size >= 2 else np.arange(position.shape[0])


def gauge_length(position, near, far, axis):
    """Distance (m) between the mean positions of the two gauge groups along ``axis``."""
    return float(position[far, axis].mean() - position[near, axis].mean())


def lateral_strain(position0, position, band, axis):
    """Least-squares uniform lateral strain (extension positive) of the particles
    ``band``: sum(rho0 . (rho - rho0)) / sum(|rho0|^2), rho the position normal to
    ``axis`` relative to the band's centroid (exact for u = eps rho)."""
    lateral = [k for k in range(3) if k != axis]
    rho0 = position0[band][:, lateral]
    rho = position[band][:, lateral]
    rho0 = rho0 - rho0.mean(axis=0)
    rho = rho - rho.mean(axis=0)
    norm = float(np.sum(rho0 * rho0))
    return float(np.sum(rho0 * (rho - rho0)) / norm) if norm > 0.0 else 0.0


def peak(stress):
    """Index of the largest stress (the first where tied)."""
    return int(np.argmax(stress))


def _crossing(x, y, level, until):
    """Where y first reaches ``level`` among samples [0, until], linear between samples:
    (x there, k, f) with that x = x[k-1] + f (x[k] - x[k-1]); a curve that starts at or
    above the level reaches it at its first sample (k = 1, f = 0); (NaN, until, 0) if it
    never does."""
    if y[0] >= level:
        return x[0], 1, 0.0
    for k in range(1, until + 1):
        if y[k] >= level:
            y0, y1 = y[k - 1], y[k]   # y0 < level <= y1
            f = (level - y0) / (y1 - y0)
            return x[k - 1] + f * (x[k] - x[k - 1]), k, f
    return math.nan, until, 0.0


def moduli(strain, stress, lateral=None, fraction=0.5):
    """Young's modulus (Pa) from the pre-peak branch at ``fraction`` of the peak stress:
    secant (stress over strain there) and tangent (least-squares slope of the samples
    between fraction -/+ 0.1 of the peak), and Poisson's ratio (secant: lateral over axial
    strain there); NaN where the curve gives no such point."""
    strain, stress = np.asarray(strain, float), np.asarray(stress, float)
    out = {"young_modulus_secant": math.nan, "young_modulus_tangent": math.nan,
           "poisson_ratio": math.nan}
    if stress.size < 3 or not np.isfinite(stress).all() or stress.max() <= 0.0:
        return out
    top = peak(stress)
    level = fraction * stress[top]
    at, k, f = _crossing(strain, stress, level, top)
    if math.isfinite(at) and at != 0.0:
        out["young_modulus_secant"] = float(level / at)
    window = np.flatnonzero((stress[:top + 1] >= (fraction - 0.1) * stress[top])
                            & (stress[:top + 1] <= (fraction + 0.1) * stress[top]))
    if window.size >= 2 and np.ptp(strain[window]) > 0.0:
        out["young_modulus_tangent"] = float(np.polyfit(strain[window], stress[window], 1)[0])
    if lateral is not None and math.isfinite(at) and at != 0.0:
        lateral = np.asarray(lateral, float)
        value = lateral[k - 1] + f * (lateral[k] - lateral[k - 1])
        out["poisson_ratio"] = float(value / at)
    return out


def crack_initiation(stress, broken, fraction=0.01):
    """Stress (Pa) when the broken bonds first reach ``fraction`` of those broken at the
    peak (at least one bond); NaN when none broke before the peak."""
    stress, broken = np.asarray(stress, float), np.asarray(broken)
    top = peak(stress)
    needed = max(1, math.ceil(fraction * broken[top]))
    if broken[top] < 1:
        return math.nan
    k = int(np.argmax(broken >= needed))
    return float(stress[k])


def fragments(pairs, active, mass):
    """(fragments, those of two or more particles, mass fraction of the largest): a
    fragment is a connected component of the intact bonds, a loose particle one of its
    own (analysis.fragment_labels: the one definition of analysis, lab and report)."""
    from ..analysis.fragments import fragment_labels
    count, labels = fragment_labels(pairs, active, mass.shape[0], mass)
    sizes = np.bincount(labels, minlength=count)
    weights = np.bincount(labels, weights=mass, minlength=count)
    return count, int(np.count_nonzero(sizes >= 2)), float(weights.max() / mass.sum())


def unloading_modulus(strain, stress, loading):
    """Slope (Pa) of the first unloading branch (the first run of samples with
    ``loading`` < 0): the least-squares slope of stress against strain over the middle
    half of the stress range it unloads through (the platens' turn and return excluded);
    NaN without an unloading branch of three such samples."""
    strain, stress = np.asarray(strain, float), np.asarray(stress, float)
    down = np.flatnonzero(np.asarray(loading) < 0.0)
    if down.size == 0:
        return math.nan
    end = down[0] + int(np.argmax(np.diff(np.r_[down, down[-1] + 2]) > 1))
    branch = np.arange(down[0], end + 1)
    high, low = stress[max(down[0] - 1, 0)], float(stress[branch].min())
    band = branch[(stress[branch] >= low + 0.25 * (high - low))
                  & (stress[branch] <= high - 0.25 * (high - low))]
    if band.size < 3 or np.ptp(strain[band]) == 0.0:
        return math.nan
    return float(np.polyfit(strain[band], stress[band], 1)[0])


def fragment_table(pairs, active, radius, mass):
    """Every fragment (particles held together by intact bonds; a loose particle is one),
    largest mass first: {"particles": (K,), "mass": (K,) kg, "size": (K,) m, the
    diameter of the sphere of its particles' volume}."""
    from ..analysis.fragments import fragment_labels
    radius, mass = np.asarray(radius, float), np.asarray(mass, float)
    count, labels = fragment_labels(pairs, active, mass.shape[0], mass)
    volume = np.bincount(labels, weights=4.0 / 3.0 * math.pi * radius ** 3, minlength=count)
    return {"particles": np.bincount(labels, minlength=count).astype(np.float64),
            "mass": np.bincount(labels, weights=mass, minlength=count),
            "size": np.cbrt(6.0 * volume / math.pi)}


def passing(size, mass):
    """The fragment size distribution by mass: (sizes ascending in m, mass fraction in
    fragments of that size or smaller), the sieve curve."""
    order = np.argsort(np.asarray(size, float), kind="stable")
    mass = np.asarray(mass, float)[order]
    return np.asarray(size, float)[order], np.cumsum(mass) / mass.sum()


def size_at(size, mass, fraction=0.5):
    """Size (m) below which ``fraction`` of the mass lies (d50 at 0.5): the smallest
    fragment size whose cumulative mass fraction reaches it."""
    sizes, cumulative = passing(size, mass)
    return float(sizes[int(np.searchsorted(cumulative, fraction - 1e-12))])

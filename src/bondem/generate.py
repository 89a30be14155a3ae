"""Packings of spheres in a volume, and bonds between close particles.

Packing method: random insertion, then collective rearrangement by energy minimisation
---------------------------------------------------------------------------------------
1. Radii are drawn first (monodisperse, truncated normal or lognormal, or a size table)
   until their total volume is the requested solids fraction phi times the container
   volume V, so phi is met by construction: phi = sum(4/3 pi r_i^3) / V.
2. Centres are placed uniformly at random (seeded ``numpy.random.default_rng``) where the
   sphere lies inside the container. At phi ~ 0.6 they overlap heavily.
3. The overlaps are removed by minimising the harmonic overlap energy of soft spheres
       U = 1/2 sum_pairs max(0, r_i + r_j - d_ij)^2
         + 1/2 sum_i sum_walls max(0, r_i (1 + delta) - s_w(x_i))^2
   (s_w: distance of the centre to wall w, positive inside; delta = ``max_overlap``)
   with the FIRE algorithm (Bitzek et al., Phys. Rev. Lett. 97, 170201, 2006), the
   container acting as a hard wall (a penalty on the part of a sphere outside it). This
   is the soft-sphere route to random close packings of O'Hern, Silbert, Liu & Nagel
   (Phys. Rev. E 68, 011306, 2003) and a collective rearrangement in the sense of
   Jodrey & Tory (Phys. Rev. A 32, 2347, 1985): all spheres move at once, along the
   overlap forces, so the result is isotropic and, below the jamming fraction (~0.64
   for monodisperse spheres in bulk), free of overlaps. The minimisation stops once
   every overlap is below ``max_overlap / 2`` of the smaller radius; the walls act on
   radii inflated by ``max_overlap``, so every sphere ends strictly inside.
   Walls lower the jamming fraction: a fraction of 0.60 is reached in a sphere of
   2000 particles, but a cube needs more than ~15 diameters per edge.
   Neighbour pairs come from ``scipy.spatial.cKDTree`` with a skin (Verlet list),
   rebuilt when a sphere moved more than half the skin; the FIRE loop is a Numba kernel
   (``bondem._packing_kernels``), serial and therefore bit-reproducible for a seed.
Closed STL meshes use a signed-distance grid (exact point-triangle distances, sign from
the winding number) during the minimisation and the exact distance at the end; a sphere
found crossing the surface gets an extra wall margin and the minimisation resumes.

Bonds: every pair whose surface gap d_ij - r_i - r_j is at most ``max_gap`` (m) gets a
bond, optionally capped per particle (closest gaps first). See docs/generation.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from scipy.spatial import cKDTree

from . import _packing_kernels as K
from .errors import InputError, unknown_key

SPHERE_VOLUME = 4.0 / 3.0 * math.pi


# ----------------------------------------------------------------------------- volumes
def _vector(value, name, length=3):
    array = np.asarray(value, dtype=np.float64).reshape(-1)
    if array.shape != (length,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} = {value!r} must be {length} finite numbers")
    return array


def _positive(value, name):
    if not (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, bool) and _finite(value) and value > 0):
        raise ValueError(f"{name} = {value!r} must be a finite number > 0")
    return float(value)


_NO_GRID = np.zeros((2, 2, 2))


@dataclass(frozen=True)
class Sphere:
    """Spherical container. center: m (3,); radius: m."""
    center: tuple
    radius: float

    def __post_init__(self):
        object.__setattr__(self, "center", _vector(self.center, "center"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    @property
    def volume(self) -> float:
        """Container volume, m^3."""
        return SPHERE_VOLUME * self.radius ** 3

    def bounds(self):
        """Axis-aligned bounding box (low, high), m."""
        return self.center - self.radius, self.center + self.radius

    def _wall(self):
        return K.SPHERE, np.r_[self.center, self.radius], _NO_GRID, np.zeros(3), 1.0


@dataclass(frozen=True)
class Box:
    """Axis-aligned box container between corners low and high (m, (3,))."""
    low: tuple
    high: tuple

    def __post_init__(self):
        low, high = _vector(self.low, "low"), _vector(self.high, "high")
        if np.any(high <= low):
            raise ValueError(f"box high {high.tolist()} must exceed low {low.tolist()}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    @property
    def volume(self) -> float:
        """Container volume, m^3."""
        return float(np.prod(self.high - self.low))

    def bounds(self):
        """Axis-aligned bounding box (low, high), m."""
        return self.low.copy(), self.high.copy()

    def _wall(self):
        return K.BOX, np.r_[self.low, self.high], _NO_GRID, np.zeros(3), 1.0


@dataclass(frozen=True)
class Cylinder:
    """Cylindrical container. center: m (3,) the middle of the axis; radius, height: m;
    axis: direction of the axis (3,), normalised here."""
    center: tuple
    radius: float
    height: float
    axis: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        object.__setattr__(self, "center", _vector(self.center, "center"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))
        object.__setattr__(self, "height", _positive(self.height, "height"))
        axis = _vector(self.axis, "axis")
        norm = np.linalg.norm(axis)
        if norm == 0:
            raise ValueError("axis must not be zero")
        object.__setattr__(self, "axis", axis / norm)

    @property
    def volume(self) -> float:
        """Container volume, m^3."""
        return math.pi * self.radius ** 2 * self.height

    def bounds(self):
        """Axis-aligned bounding box (low, high), m."""
        # extent of a disc of radius R normal to a: R sqrt(1 - a_k^2) along axis k
        half = (self.radius * np.sqrt(np.clip(1 - self.axis ** 2, 0, 1))
                + 0.5 * self.height * np.abs(self.axis))
        return self.center - half, self.center + half

    def _wall(self):
        return (K.CYLINDER, np.r_[self.center, self.axis, self.radius, 0.5 * self.height],
                _NO_GRID, np.zeros(3), 1.0)


class MeshVolume:
    """Inside of a closed (watertight) triangle mesh, m. Build with ``from_stl``."""

    def __init__(self, mesh):
        if not mesh.is_watertight:
            raise ValueError("the mesh is not closed (watertight); cannot fill its inside")
        if mesh.volume < 0:
            mesh.invert()
        self.mesh = mesh
        self._triangles = np.ascontiguousarray(mesh.triangles, dtype=np.float64)
        self._grid = None

    @classmethod
    def from_stl(cls, path, scale=1.0):
        """Read an STL file; ``scale`` multiplies its coordinates to give metres."""
        import trimesh
        mesh = trimesh.load_mesh(str(path), force="mesh")
        mesh.apply_scale(float(scale))
        return cls(mesh)

    @property
    def volume(self) -> float:
        """Enclosed volume, m^3."""
        return float(self.mesh.volume)

    def bounds(self):
        """Axis-aligned bounding box (low, high), m."""
        low, high = self.mesh.bounds
        return np.array(low, dtype=float), np.array(high, dtype=float)

    def signed_distance(self, points):
        """Exact distance (m) of points (P,3) to the surface, positive inside."""
        return K.mesh_signed_distance(np.ascontiguousarray(points, dtype=np.float64),
                                      self._triangles)

    def prepare(self, spacing):
        """Signed-distance grid with the given spacing (m), exact at the nodes (trilinear
        in between; the final check uses the exact distance)."""
        low, high = self.bounds()
        low, high = low - 2 * spacing, high + 2 * spacing
        shape = np.maximum(np.ceil((high - low) / spacing).astype(int) + 1, 2)
        axes = [low[k] + spacing * np.arange(shape[k]) for k in range(3)]
        points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        grid = self.signed_distance(points).reshape(shape)
        self._grid = (np.ascontiguousarray(grid), low, float(spacing))

    def _wall(self):
        grid, origin, spacing = self._grid
        return K.GRID, np.zeros(1), grid, origin, spacing


# ----------------------------------------------------------------------------- radii
def sample_radii(target_volume, *, radius=None, radius_distribution=None, rng=None):
    """Radii (m) whose total sphere volume is closest to ``target_volume`` (m^3).

    Either ``radius`` (m, monodisperse; a 1-D array: these radii, whatever the volume)
    or ``radius_distribution``, a dict:
    ``{"type": "normal" | "lognormal", "mean": m, "std": m, "min": m, "max": m}`` (mean
    and standard deviation of the radius itself; min/max cut, default mean -/+ 3 std,
    min at least mean/10) or ``{"type": "table", "radius": [m...], "fraction": [...],
    "basis": "number" | "mass"}`` (fractions are normalised).
    """
    rng = np.random.default_rng(0) if rng is None else rng
    if (radius is None) == (radius_distribution is None):
        raise ValueError("give exactly one of radius and radius_distribution")
    if radius is not None and np.ndim(radius) == 1:   # the radii themselves
        radii = np.asarray(radius, dtype=float)
        if radii.size == 0 or not np.all(np.isfinite(radii)) or np.any(radii <= 0):
            raise ValueError("radii must be finite numbers > 0")
        _check_count(radii.size)
        return radii.copy()
    if radius is not None:
        radius = _positive(radius, "radius")
        # in logarithms: radius ** 3 overflows (1e300 m) or vanishes (1e-300 m) in doubles
        log_count = (math.log(target_volume) - math.log(SPHERE_VOLUME) - 3.0 * math.log(radius)
                     if target_volume > 0.0 else -math.inf)
        if log_count > math.log(MAX_PARTICLES) + 1.0:
            raise ValueError(f"about 10^{log_count / math.log(10.0):.0f} particles of radius "
                             f"{radius:.3g} m fill this container; at most {MAX_PARTICLES}")
        n = max(int(round(math.exp(log_count))), 1)
        _check_count(n)
        return np.full(n, radius)
    dist = dict(radius_distribution)
    kind = dist.get("type")
    if kind == "monodisperse":
        return sample_radii(target_volume, radius=dist.get("radius", dist.get("mean")), rng=rng)
    if kind == "table":
        radii = np.asarray(dist["radius"], dtype=float).reshape(-1)
        fraction = np.asarray(dist["fraction"], dtype=float).reshape(-1)
        if radii.size == 0 or radii.shape != fraction.shape or np.any(radii <= 0) \
                or np.any(fraction < 0) or fraction.sum() <= 0:
            raise ValueError("size table: radius (> 0) and fraction (>= 0, not all 0) must "
                             "be lists of equal length")
        fraction = fraction / fraction.sum()
        class_volume = SPHERE_VOLUME * radii ** 3
        basis = dist.get("basis", "number")
        if basis == "mass":   # one density: mass fraction = volume fraction
            counts = np.rint(fraction * target_volume / class_volume).astype(np.int64)
        elif basis == "number":
            total = target_volume / float(np.dot(fraction, class_volume))
            counts = np.rint(fraction * total).astype(np.int64)
        else:
            raise ValueError(f"basis = {basis!r}; allowed: 'number', 'mass'")
        _check_count(int(counts.sum()))
        out = np.repeat(radii, counts)
        if out.size == 0:
            raise ValueError("the size table gives no particle in this volume")
        return rng.permutation(out)
    if kind not in ("normal", "lognormal"):
        raise ValueError(f"type = {kind!r}; allowed: 'normal', 'lognormal', 'table', "
                         "'monodisperse'")
    mean = _positive(dist.get("mean"), "mean")
    std = dist.get("std", 0.0)
    if not (isinstance(std, (int, float)) and _finite(std) and std >= 0):
        raise ValueError(f"std = {std!r} must be a finite number >= 0")
    low = float(dist.get("min", max(mean - 3 * std, 0.1 * mean)))
    high = float(dist.get("max", mean + 3 * std))
    if not (0 < low <= mean <= high):
        raise ValueError(f"min = {low!r} and max = {high!r} must satisfy 0 < min <= mean "
                         f"({mean}) <= max")
    if std == 0:
        return sample_radii(target_volume, radius=mean, rng=rng)
    if kind == "lognormal":
        s2 = math.log(1 + (std / mean) ** 2)
        mu, sigma = math.log(mean) - 0.5 * s2, math.sqrt(s2)
    mean_volume = SPHERE_VOLUME * (mean ** 3 + 3 * mean * std ** 2)
    _check_count(int(target_volume / mean_volume))
    chunks, total = [], 0.0
    while total < target_volume:
        batch = max(int(1.2 * (target_volume - total) / mean_volume), 64)
        draw = (rng.normal(mean, std, batch) if kind == "normal"
                else rng.lognormal(mu, sigma, batch))
        draw = draw[(draw >= low) & (draw <= high)]
        chunks.append(draw)
        total += float(np.sum(SPHERE_VOLUME * draw ** 3))
    radii = np.concatenate(chunks)
    cumulative = np.cumsum(SPHERE_VOLUME * radii ** 3)
    n = int(np.searchsorted(cumulative, target_volume))
    # keep the count whose volume is closest to the target
    if n > 0 and abs(cumulative[n - 1] - target_volume) <= abs(cumulative[n] - target_volume):
        return radii[:n]
    return radii[:n + 1]


MAX_PARTICLES = 50_000_000
SKIN = 1.0  # neighbour-list skin, in units of the smallest radius


def _check_count(n):
    if n > MAX_PARTICLES:
        raise ValueError(f"{n} particles requested; at most {MAX_PARTICLES}")


# ----------------------------------------------------------------------------- packing
def pack_spheres(volume, *, radius=None, radius_distribution=None, solids_fraction=0.55,
                 seed=0, max_overlap=1e-3, max_iterations=50_000):
    """Dense random packing of spheres inside ``volume`` (Sphere, Box, Cylinder or
    MeshVolume).

    radius: m (monodisperse; an array: the radii themselves, in order) or
    radius_distribution (see ``sample_radii``);
    solids_fraction: particle volume / container volume, in (0, 0.66) (monodisperse
    spheres reach 0.62 with walls; above that the minimisation may not converge);
    seed: random seed, the same seed gives the same packing bit for bit;
    max_overlap: largest allowed overlap r_i + r_j - d_ij relative to the smaller radius.
    Returns (position (N,3) m, radius (N,) m). Raises RuntimeError when the overlaps cannot
    be removed within ``max_iterations`` FIRE steps (fraction too close to jamming).
    """
    if not isinstance(volume, (Sphere, Box, Cylinder, MeshVolume)):
        raise TypeError(f"volume must be a Sphere, Box, Cylinder or MeshVolume, not "
                        f"{type(volume).__name__}")
    if not 0 < solids_fraction < 0.66:
        raise ValueError(f"solids_fraction = {solids_fraction!r} is outside (0, 0.66)")
    if not 0 < max_overlap <= 0.05:
        raise ValueError(f"max_overlap = {max_overlap!r} is outside (0, 0.05]")
    rng = np.random.default_rng(seed)
    radii = sample_radii(solids_fraction * volume.volume, radius=radius,
                         radius_distribution=radius_distribution, rng=rng)
    if isinstance(volume, MeshVolume):
        low, high = volume.bounds()
        # grid cost is (nodes x triangles): at most ~1e5 nodes, finer than a radius
        spacing = max(0.5 * float(radii.mean()), (np.prod(high - low) / 1e5) ** (1 / 3))
        volume.prepare(spacing)
    wall = volume._wall()
    position = _random_inside(volume, wall, radii, rng)
    margin = np.zeros(radii.size)
    for _ in range(20):
        _minimise(position, radii, wall, max_overlap, max_iterations, margin)
        if not isinstance(volume, MeshVolume):
            break
        if not _mesh_correction(volume, position, radii, margin, max_overlap):
            break
    else:
        raise RuntimeError("spheres still cross the mesh surface after 20 corrections")
    return position, radii


def _random_inside(volume, wall, radii, rng):
    """Uniform random centres where each sphere lies inside the container."""
    kind, params, grid, origin, spacing = wall
    low, high = volume.bounds()
    position = np.empty((radii.size, 3))
    todo = np.arange(radii.size)
    for _ in range(1000):
        trial = low + (high - low) * rng.random((todo.size, 3))
        ok = K.penetrations(kind, params, grid, origin, spacing, trial, radii[todo]) <= 0.0
        position[todo[ok]] = trial[ok]
        todo = todo[~ok]
        if todo.size == 0:
            return position
    raise ValueError("the particles do not fit inside the volume (particle radius too "
                     "large for the container?)")


def _minimise(position, radii, wall, max_overlap, max_iterations, margin):
    """Remove the overlaps (FIRE) until they are below max_overlap / 2 and every sphere
    lies inside. (A gradual growth of the radii was tried: in small containers it did not
    raise the reachable fraction and took 1.7 times the iterations.)"""
    done, builds = _relax_to(position, radii, wall, max_overlap, max_iterations, margin)
    _minimise.stats = (done, builds)
    return done


def _relax_to(position, radii, wall, max_overlap, max_iterations, margin):
    kind, params, grid, origin, spacing = wall
    velocity = np.zeros_like(position)
    # [dt, alpha, steps since the power was negative, dt_max]; unit mass and stiffness,
    # so the stiffest mode (~12 contacts) is stable up to dt ~ 0.5
    fire = np.array([0.05, 0.1, 0.0, 0.4])
    skin = SKIN * float(radii.min())
    cutoff = 2 * float(radii.max()) + skin
    done = builds = 0
    pairs, previous = None, None
    while done < max_iterations:
        if pairs is None:
            pairs = _pairs_within(position, cutoff)
            reference = position.copy()
            builds += 1
        # pairs uninflated (the minimiser stops once overlaps < max_overlap / 2); walls
        # inflated by max_overlap so that every sphere ends strictly inside
        status, iterations, worst_pair, worst_wall = K.relax(
            position, velocity, radii, 0.0, max_overlap, margin, pairs, kind, params,
            grid, origin, spacing, reference, 0.5 * skin, 0.5 * max_overlap,
            min(STALL_CHECK, max_iterations - done), fire)
        done += iterations
        if status == K.CONVERGED:
            return done, builds
        if status == K.REBUILD:
            pairs, previous = None, None
            continue
        # a whole chunk without a rebuild: jammed when the overlaps stopped shrinking
        worst = max(worst_pair, worst_wall)
        if previous is not None and worst > 0.98 * previous:
            raise RuntimeError(_jammed(done, worst_pair, worst_wall))
        previous = worst
    raise RuntimeError(_jammed(done, worst_pair, worst_wall))


STALL_CHECK = 5000  # FIRE iterations between checks that the overlaps still shrink


def _jammed(done, worst_pair, worst_wall):
    return (f"overlaps not removed after {done} iterations (largest overlap "
            f"{worst_pair:.3g} of the radius, wall {worst_wall:.3g}): the packing jammed; "
            "lower the solids fraction or use a larger container (walls lower the jamming "
            "fraction)")


def _pairs_within(position, cutoff):
    pairs = cKDTree(position).query_pairs(cutoff, output_type="ndarray").astype(np.int64)
    # a fixed pair order makes the force sums, hence the packing, reproducible
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))] if pairs.size else \
        np.zeros((0, 2), np.int64)


def _mesh_correction(volume, position, radii, margin, max_overlap):
    """Exact check against the mesh: spheres crossing the surface get a larger wall
    margin (the grid's error there). Returns True when some sphere needed one."""
    grid, origin, spacing = volume._grid
    near = np.flatnonzero(K.penetrations(K.GRID, np.zeros(1), grid, origin, spacing,
                                         position, radii + 2 * spacing) > 0)
    if near.size == 0:
        return False
    exact = volume.signed_distance(position[near])
    deficit = radii[near] - exact
    bad = deficit > 0
    margin[near[bad]] += deficit[bad] + max_overlap * radii[near[bad]]
    return bool(bad.any())


# ----------------------------------------------------------------------------- checks
def solids_fraction(radius, container_volume):
    """Particle volume over container volume (-); radius: m, container_volume: m^3."""
    return float(np.sum(SPHERE_VOLUME * np.asarray(radius) ** 3) / container_volume)


def max_overlap(position, radius):
    """Largest overlap r_i + r_j - d_ij of any pair relative to the smaller radius (-);
    negative when no two spheres touch. position: m (N,3); radius: m (N,)."""
    radius = np.asarray(radius, dtype=float)
    pairs = cKDTree(position).query_pairs(2.1 * radius.max(), output_type="ndarray")
    if pairs.size == 0:
        return -math.inf
    i, j = pairs[:, 0], pairs[:, 1]
    d = np.linalg.norm(position[j] - position[i], axis=1)
    return float(np.max((radius[i] + radius[j] - d) / np.minimum(radius[i], radius[j])))


# ----------------------------------------------------------------------------- bonds
def bonds_from_gap(position, radius, max_gap, *, diameter=None, diameter_ratio=None,
                   max_per_particle=None, groups=None):
    """Bonds between every pair whose surface gap d_ij - r_i - r_j is at most ``max_gap``.

    position: m (N,3); radius: m (N,); max_gap: m (>= 0; overlapping pairs count);
    diameter: bond diameter, m, or diameter_ratio: times the smaller particle's diameter;
    max_per_particle: cap on bonds per particle, the closest gaps kept first (ties by
    particle indices), so the result is symmetric and deterministic; groups: (N,) ints,
    no bond between two particles of one group >= 0 (a clump's members; the cap counts
    only the bonds kept).
    Returns (pairs (B,2) int64 with i < j, sorted by i then j; diameter (B,) m).
    """
    position = np.ascontiguousarray(position, dtype=np.float64)
    radius = np.asarray(radius, dtype=np.float64)
    if not (math.isfinite(max_gap) and max_gap >= 0):
        raise ValueError(f"max_gap = {max_gap!r} must be a finite number >= 0")
    if (diameter is None) == (diameter_ratio is None):
        raise ValueError("give exactly one of diameter and diameter_ratio")
    if diameter is not None:
        _positive(diameter, "diameter")
    else:
        _positive(diameter_ratio, "diameter_ratio")
    if max_per_particle is not None and (int(max_per_particle) != max_per_particle
                                         or max_per_particle < 1):
        raise ValueError(f"max_per_particle = {max_per_particle!r} must be an integer >= 1")
    if radius.size < 2:
        pairs = np.zeros((0, 2), np.int64)
    else:
        pairs = cKDTree(position).query_pairs(2 * radius.max() + max_gap,
                                              output_type="ndarray").astype(np.int64)
    pairs = pairs.reshape(-1, 2)
    i, j = pairs[:, 0], pairs[:, 1]
    gap = np.linalg.norm(position[j] - position[i], axis=1) - radius[i] - radius[j]
    keep = gap <= max_gap
    if groups is not None and pairs.size:
        ends = np.asarray(groups)[pairs]
        keep &= (ends[:, 0] < 0) | (ends[:, 0] != ends[:, 1])
    pairs, gap = pairs[keep], gap[keep]
    if max_per_particle is not None and pairs.size:
        order = np.lexsort((pairs[:, 1], pairs[:, 0], gap))
        accepted = _greedy_cap(pairs[order], radius.size, int(max_per_particle))
        pairs = pairs[order][accepted]
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))] if pairs.size else pairs
    if diameter is not None:
        bond_diameter = np.full(pairs.shape[0], float(diameter))
    else:
        bond_diameter = 2 * diameter_ratio * np.minimum(radius[pairs[:, 0]], radius[pairs[:, 1]])
    return np.ascontiguousarray(pairs, dtype=np.int64), bond_diameter


@numba.njit(cache=True)
def _greedy_cap(pairs, n, cap):
    count = np.zeros(n, np.int64)
    accepted = np.zeros(pairs.shape[0], np.bool_)
    for b in range(pairs.shape[0]):
        i, j = pairs[b, 0], pairs[b, 1]
        if count[i] < cap and count[j] < cap:
            accepted[b] = True
            count[i] += 1
            count[j] += 1
    return accepted


def coordination_number(pairs, n):
    """Mean number of bonds per particle, 2 B / N (-)."""
    return 2.0 * len(pairs) / n if n else 0.0


# ----------------------------------------------------------------------------- scene tables
_SHAPES = ("sphere", "box", "cylinder", "mesh")
_GENERATOR_KEYS = {"shape", "center", "radius", "size", "height", "axis", "low", "high",
                   "file", "scale", "particle_radius", "size_distribution",
                   "solids_fraction", "seed", "material", "max_overlap"}
_DISTRIBUTION_KEYS = {"type", "mean", "std", "min", "max", "radius", "fraction", "basis"}


def _finite(value):
    """True for a number a double holds (an integer past 1.8e308 is not one)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _show(value):
    """``repr`` of a bad value, cut to a readable length (a 400-digit integer)."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _number(table, key, file, prefix, low, high, *, include_low=False, include_high=False,
            default=None, integer=False):
    value = table.get(key, default)
    where = f"{prefix}.{key}"
    if value is None:
        raise InputError(f"missing; give a number in {'[' if include_low else '('}{low}, "
                         f"{high}{']' if include_high else ')'}", file=file, key=where)
    ok_type = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok_type or not _finite(value) or \
            not (value >= low if include_low else value > low) or \
            not (value <= high if include_high else value < high):
        kind = "an integer" if integer else "a number"
        raise InputError(f"{_show(value)} is not {kind} in {'[' if include_low else '('}{low}, "
                         f"{high}{']' if include_high else ')'}", file=file, key=where)
    return value


def _triple(table, key, file, prefix, default=None, positive=False):
    value = table.get(key, default)
    where = f"{prefix}.{key}"
    if isinstance(value, (int, float)) and not isinstance(value, bool) and positive:
        value = [value] * 3
    if (not isinstance(value, (list, tuple)) or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and _finite(v) and (v > 0 or not positive) for v in value)):
        what = "three numbers > 0 (or one)" if positive else "a list of three numbers"
        raise InputError(f"{_show(value)} is not {what}", file=file, key=where)
    return [float(v) for v in value]


def volume_from_table(table, file="<scene>", prefix="particles.generator"):
    """The container of a generator table: shape = "sphere" (center, radius or size =
    diameter), "box" (size = edge lengths, one or three, around center; or low and high),
    "cylinder" (center, radius or size = diameter, height (default = diameter), axis) or
    "mesh" (file relative to the scene, scale). Lengths in m."""
    shape = table.get("shape")
    if shape not in _SHAPES:
        raise InputError(f"{shape!r}; allowed: " + ", ".join(repr(s) for s in _SHAPES),
                         file=file, key=f"{prefix}.shape")
    if shape == "mesh":
        path = table.get("file")
        if not isinstance(path, str):
            raise InputError(f"{path!r}; give the path of a closed STL mesh", file=file,
                             key=f"{prefix}.file")
        if file and not str(file).startswith("<"):
            path = Path(file).parent / path
        scale = _number(table, "scale", file, prefix, 0, math.inf, default=1.0)
        if not Path(path).is_file():
            raise InputError(f"{str(path)!r} does not exist", file=file, key=f"{prefix}.file")
        try:
            return MeshVolume.from_stl(path, scale)
        except ValueError as error:
            raise InputError(f"{str(path)!r}: {error}", file=file, key=f"{prefix}.file")
    center = _triple(table, "center", file, prefix, default=[0.0, 0.0, 0.0])
    if shape == "box":
        if "low" in table or "high" in table:
            low = _triple(table, "low", file, prefix)
            high = _triple(table, "high", file, prefix)
            if any(h <= lo for lo, h in zip(low, high)):
                raise InputError(f"{high!r} must exceed low = {low!r} on every axis",
                                 file=file, key=f"{prefix}.high")
            return Box(low, high)
        size = np.array(_triple(table, "size", file, prefix, positive=True))
        return Box(np.array(center) - size / 2, np.array(center) + size / 2)
    if "radius" in table:
        radius = _number(table, "radius", file, prefix, 0, math.inf)
    else:
        radius = 0.5 * _number(table, "size", file, prefix, 0, math.inf)
    if shape == "sphere":
        return Sphere(center, radius)
    height = _number(table, "height", file, prefix, 0, math.inf, default=2 * radius)
    axis = _triple(table, "axis", file, prefix, default=[0.0, 0.0, 1.0])
    if not any(axis):
        raise InputError(f"{axis!r} must not be zero", file=file, key=f"{prefix}.axis")
    return Cylinder(center, radius, height, axis)


def _distribution_from_table(table, file, prefix):
    if not isinstance(table, dict):
        raise InputError(f"{table!r} is not a table", file=file, key=prefix)
    unknown = sorted(set(table) - _DISTRIBUTION_KEYS)
    if unknown:
        raise InputError(unknown_key(unknown[0], sorted(_DISTRIBUTION_KEYS)), file=file,
                         key=f"{prefix}.{unknown[0]}")
    kind = table.get("type")
    if kind not in ("normal", "lognormal", "table"):
        raise InputError(f"{kind!r}; allowed: 'normal', 'lognormal', 'table'", file=file,
                         key=f"{prefix}.type")
    if kind == "table":
        for key in ("radius", "fraction"):
            value = table.get(key)
            if (not isinstance(value, list) or not value
                    or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                               and _finite(v) and (v > 0 if key == "radius" else v >= 0)
                               for v in value)):
                raise InputError(f"{value!r} is not a list of numbers "
                                 f"{'> 0 (m)' if key == 'radius' else '>= 0'}", file=file,
                                 key=f"{prefix}.{key}")
        if len(table["radius"]) != len(table["fraction"]) or sum(table["fraction"]) <= 0:
            raise InputError("radius and fraction must have the same length and the "
                             "fractions a positive sum", file=file, key=f"{prefix}.fraction")
        if table.get("basis", "number") not in ("number", "mass"):
            raise InputError(f"{table['basis']!r}; allowed: 'number', 'mass'", file=file,
                             key=f"{prefix}.basis")
        return dict(table)
    mean = _number(table, "mean", file, prefix, 0, math.inf)
    std = _number(table, "std", file, prefix, 0, math.inf, include_low=True)
    low = _number(table, "min", file, prefix, 0, mean, include_high=True,
                  default=max(mean - 3 * std, 0.1 * mean))
    _number(table, "max", file, prefix, mean, math.inf, include_low=True,
            default=mean + 3 * std)
    if std > 0 and low == mean == table.get("max", mean + 3 * std):
        raise InputError("min = max = mean leaves no room for the distribution", file=file,
                         key=f"{prefix}.max")
    return dict(table)


def particles_from_generator(table, file="<scene>", prefix="particles.generator"):
    """Validate a scene's ``[particles] generator = {...}`` table and pack it.

    Keys: shape and its dimensions (see ``volume_from_table``); particle_radius (m) or
    size_distribution = {type = "normal" | "lognormal", mean, std, min, max} (m) or
    {type = "table", radius = [m...], fraction = [...], basis = "number" | "mass"};
    solids_fraction in (0, 0.66), default 0.55; seed (integer >= 0, default 0);
    max_overlap in (0, 0.05], default 1e-3; material (name of a particle material).
    Returns (position (N,3) m, radius (N,) m, material_names (N,) str). Bad keys raise
    InputError naming ``particles.generator.<key>``, the value and the allowed range.
    """
    if not isinstance(table, dict):
        raise InputError(f"{table!r} is not a table", file=file, key=prefix)
    unknown = sorted(set(table) - _GENERATOR_KEYS)
    if unknown:
        raise InputError(unknown_key(unknown[0], sorted(_GENERATOR_KEYS)), file=file,
                         key=f"{prefix}.{unknown[0]}")
    volume = volume_from_table(table, file, prefix)
    if ("particle_radius" in table) == ("size_distribution" in table):
        raise InputError("give exactly one of particle_radius and size_distribution",
                         file=file, key=f"{prefix}.particle_radius")
    radius, distribution = None, None
    if "particle_radius" in table:
        radius = _number(table, "particle_radius", file, prefix, 0, math.inf)
    else:
        distribution = _distribution_from_table(table["size_distribution"], file,
                                                f"{prefix}.size_distribution")
    fraction = _number(table, "solids_fraction", file, prefix, 0, 0.66, default=0.55)
    seed = _number(table, "seed", file, prefix, 0, 2 ** 63, include_low=True, default=0,
                   integer=True)
    overlap = _number(table, "max_overlap", file, prefix, 0, 0.05, include_high=True,
                      default=1e-3)
    material = table.get("material")
    if not isinstance(material, str) or not material:
        raise InputError(f"{material!r}; give the name of a particle material", file=file,
                         key=f"{prefix}.material")
    try:
        position, radii = pack_spheres(volume, radius=radius, radius_distribution=distribution,
                                       solids_fraction=fraction, seed=seed,
                                       max_overlap=overlap)
    except (ValueError, RuntimeError) as error:
        raise InputError(str(error), file=file, key=prefix) from None
    except ArithmeticError:
        raise InputError("the container's volume overflows or vanishes in double precision: "
                         "its size is out of any physical range (lengths are in m)",
                         file=file, key=prefix) from None
    return position, radii, np.full(radii.size, material, dtype=object)


_BOND_KEYS = {"max_gap", "diameter", "diameter_ratio", "material", "max_per_particle"}


def bonds_from_table(table, position, radius, file="<scene>", prefix="bonds",
                     clump_of=None):
    """Validate a scene's generated-bonds table ``[bonds] max_gap = m, diameter = m |
    diameter_ratio = -, material = name, max_per_particle = n`` and build the bonds
    (clump_of (N,): none within a clump).
    Returns (pairs (B,2) int64, diameter (B,) m, material_names (B,) str)."""
    unknown = sorted(set(table) - _BOND_KEYS)
    if unknown:
        raise InputError(unknown_key(unknown[0], sorted(_BOND_KEYS)), file=file,
                         key=f"{prefix}.{unknown[0]}")
    max_gap = _number(table, "max_gap", file, prefix, 0, math.inf, include_low=True)
    if ("diameter" in table) == ("diameter_ratio" in table):
        raise InputError("give exactly one of diameter (m) and diameter_ratio", file=file,
                         key=f"{prefix}.diameter")
    diameter = ratio = None
    if "diameter" in table:
        diameter = _number(table, "diameter", file, prefix, 0, math.inf)
    else:
        ratio = _number(table, "diameter_ratio", file, prefix, 0, 1, include_high=True)
    cap = None
    if "max_per_particle" in table:
        cap = _number(table, "max_per_particle", file, prefix, 1, 10 ** 6, include_low=True,
                      integer=True)
    material = table.get("material")
    if not isinstance(material, str) or not material:
        raise InputError(f"{material!r}; give the name of a bond material", file=file,
                         key=f"{prefix}.material")
    pairs, diameters = bonds_from_gap(position, radius, max_gap, diameter=diameter,
                                      diameter_ratio=ratio, max_per_particle=cap,
                                      groups=clump_of)
    return pairs, diameters, np.full(len(pairs), material, dtype=object)

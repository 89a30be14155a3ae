"""Packing and bond generation (issue 5).

References: the container's analytic shape (inside), brute-force all-pairs distances
(overlaps, bonds), Monte Carlo volume integration (solids fraction), the radial
distribution function of random close packings (contact peak at 2r, O'Hern et al. 2003)
and the isotropy of contact normals (fabric tensor = I/3).
"""
import math

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from bondem import _packing_kernels as K
from bondem.errors import InputError
from bondem.generate import (Box, Cylinder, MeshVolume, Sphere, bonds_from_gap,
                             bonds_from_table, coordination_number, pack_spheres,
                             particles_from_generator, sample_radii, solids_fraction)

R = 1e-3  # particle radius, m


def brute_overlap(position, radius):
    """Largest r_i + r_j - d_ij over all pairs, relative to the smaller radius (NumPy)."""
    d = np.linalg.norm(position[:, None] - position[None], axis=-1)
    overlap = (radius[:, None] + radius[None] - d) / np.minimum(radius[:, None], radius[None])
    np.fill_diagonal(overlap, -np.inf)
    return overlap.max()


@pytest.fixture(scope="module")
def sphere_packing():
    """2000 monodisperse spheres at 0.60 in a spherical container."""
    n, fraction = 2000, 0.60
    container = Sphere((1e-3, -2e-3, 0.5e-3), (n * R ** 3 / fraction) ** (1 / 3))
    position, radius = pack_spheres(container, radius=R, solids_fraction=fraction, seed=3)
    return container, position, radius


def test_sphere_fraction_inside_and_overlap(sphere_packing):
    container, position, radius = sphere_packing
    assert radius.size == 2000
    # by construction, and measured independently by Monte Carlo (2e5 points, standard
    # error 0.0011): the fraction of the container covered by spheres
    assert abs(solids_fraction(radius, container.volume) - 0.60) < 0.01
    rng = np.random.default_rng(0)
    direction = rng.normal(size=(200_000, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    points = container.center + direction * container.radius * rng.random((200_000, 1)) ** (1 / 3)
    covered = np.isfinite(cKDTree(position).query(points, distance_upper_bound=R)[0]).mean()
    assert abs(covered - 0.60) < 0.01
    # inside: |x - c| + r <= R_container
    reach = np.linalg.norm(position - container.center, axis=1) + radius
    assert reach.max() <= container.radius * (1 + 1e-12)
    assert brute_overlap(position, radius) < 1e-3


def test_contact_peak_and_isotropy(sphere_packing):
    """g(r) of the bulk (centres >= 8 r from the wall) peaks in the bin around 2r (contacts), with
    a height > 3 times the ideal gas; contact normals have fabric tensor I/3 +- 0.03."""
    container, position, radius = sphere_packing
    depth = container.radius - np.linalg.norm(position - container.center, axis=1)
    bulk = np.flatnonzero(depth >= 4 * R + 4 * R)  # shells out to 4r stay inside
    tree = cKDTree(position)
    edges = (1.55 + 0.1 * np.arange(26)) * R
    counts = np.zeros(edges.size - 1)
    for i in bulk:
        d = np.linalg.norm(position[tree.query_ball_point(position[i], edges[-1])]
                           - position[i], axis=1)
        counts += np.histogram(d, edges)[0]
    density = radius.size / container.volume
    shell = 4 / 3 * np.pi * (edges[1:] ** 3 - edges[:-1] ** 3)
    g = counts / (bulk.size * density * shell)
    peak = np.argmax(g)
    assert edges[peak] < 2 * R < edges[peak + 1]
    assert g[peak] > 3.0
    assert g[edges[1:] < 1.96 * R].max() == 0.0  # no pair closer than contact
    pairs = tree.query_pairs(2.02 * R, output_type="ndarray")
    normal = position[pairs[:, 1]] - position[pairs[:, 0]]
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    fabric = normal.T @ normal / len(normal)
    assert np.allclose(np.linalg.eigvalsh(fabric), 1 / 3, atol=0.03)


def test_same_seed_same_packing_other_seed_differs():
    box = Box((0, 0, 0), (16 * R, 16 * R, 16 * R))
    a = pack_spheres(box, radius=R, solids_fraction=0.5, seed=7)
    b = pack_spheres(box, radius=R, solids_fraction=0.5, seed=7)
    c = pack_spheres(box, radius=R, solids_fraction=0.5, seed=8)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])


def test_box_and_tilted_cylinder():
    box = Box((0, 0, 0), (24 * R, 20 * R, 16 * R))
    position, radius = pack_spheres(box, radius=R, solids_fraction=0.55, seed=1)
    assert abs(solids_fraction(radius, box.volume) - 0.55) < 0.01
    assert np.all(position - radius[:, None] >= box.low - 1e-15)
    assert np.all(position + radius[:, None] <= box.high + 1e-15)
    assert brute_overlap(position, radius) < 1e-3

    axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    cyl = Cylinder((0, 0, 0), 8 * R, 16 * R, axis)
    position, radius = pack_spheres(cyl, radius=R, solids_fraction=0.55, seed=2)
    assert abs(solids_fraction(radius, cyl.volume) - 0.55) < 0.01
    t = position @ axis
    rho = np.linalg.norm(position - t[:, None] * axis, axis=1)
    assert np.all(rho + radius <= 8 * R * (1 + 1e-12))
    assert np.all(np.abs(t) + radius <= 8 * R * (1 + 1e-12))
    assert brute_overlap(position, radius) < 1e-3


def test_lognormal_polydisperse_in_box():
    box = Box((0, 0, 0), (20 * R, 20 * R, 20 * R))
    dist = {"type": "lognormal", "mean": R, "std": 0.25 * R, "min": 0.5 * R, "max": 2 * R}
    position, radius = pack_spheres(box, radius_distribution=dist, solids_fraction=0.58,
                                    seed=4)
    assert abs(solids_fraction(radius, box.volume) - 0.58) < 0.01
    assert radius.min() >= 0.5 * R and radius.max() <= 2 * R
    # sample mean and standard deviation of ~1000 draws (truncation is ~1e-3 of the mass)
    assert abs(radius.mean() / R - 1) < 0.03 and abs(radius.std() / (0.25 * R) - 1) < 0.1
    assert np.all(position - radius[:, None] >= -1e-15)
    assert np.all(position + radius[:, None] <= 20 * R + 1e-15)
    assert brute_overlap(position, radius) < 1e-3


def test_size_table_mass_and_number_basis():
    volume = 1e-6
    table = {"type": "table", "radius": [1e-4, 2e-4], "fraction": [0.25, 0.75],
             "basis": "mass"}
    radii = sample_radii(volume, radius_distribution=table)
    small = 4 / 3 * np.pi * np.sum(radii[radii == 1e-4] ** 3)
    large = 4 / 3 * np.pi * np.sum(radii[radii == 2e-4] ** 3)
    assert abs(small / (small + large) - 0.25) < 1e-3
    assert abs((small + large) / volume - 1) < 1e-3
    table["basis"] = "number"
    radii = sample_radii(volume, radius_distribution=table)
    assert abs(np.mean(radii == 1e-4) - 0.25) < 1e-3


def test_mesh_distance_against_box_and_packing_inside(tmp_path):
    """The mesh signed distance equals the analytic one of a box (inside: distance to the
    nearest face; outside: Euclidean distance to the box, negative)."""
    half = np.array([3.0, 2.0, 1.5])
    mesh = trimesh.creation.box(extents=2 * half)
    points = np.random.default_rng(1).uniform(-5, 5, (400, 3))
    q = np.abs(points) - half
    analytic = -(np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0))
    sd = K.mesh_signed_distance(points, np.ascontiguousarray(mesh.triangles))
    assert np.allclose(sd, analytic, atol=1e-12)

    ico = trimesh.creation.icosphere(subdivisions=2, radius=7.0)  # mm
    ico.export(tmp_path / "ball.stl")
    volume = MeshVolume.from_stl(tmp_path / "ball.stl", scale=1e-3)
    position, radius = pack_spheres(volume, radius=R, solids_fraction=0.5, seed=5)
    assert abs(solids_fraction(radius, volume.volume) - 0.5) < 0.01
    assert np.all(volume.signed_distance(position) >= radius)
    assert brute_overlap(position, radius) < 1e-3


def brute_bonds(position, radius, max_gap):
    d = np.linalg.norm(position[:, None] - position[None], axis=-1)
    gap = d - radius[:, None] - radius[None]
    i, j = np.nonzero(np.triu(gap <= max_gap, k=1))
    return np.stack([i, j], axis=1), gap[i, j]


def test_bonds_match_brute_force_and_coordination(sphere_packing):
    _, position, radius = sphere_packing
    position, radius = position[:400], radius[:400] * np.linspace(0.8, 1.0, 400)
    max_gap = 0.3 * R
    pairs, diameter = bonds_from_gap(position, radius, max_gap, diameter_ratio=0.5)
    expected, _ = brute_bonds(position, radius, max_gap)
    assert pairs.dtype == np.int64 and np.array_equal(pairs, expected)
    assert np.all(pairs[:, 0] < pairs[:, 1])
    degree = np.bincount(expected.ravel(), minlength=400)
    assert coordination_number(pairs, 400) == pytest.approx(degree.mean(), rel=1e-15)
    smaller = np.minimum(radius[pairs[:, 0]], radius[pairs[:, 1]])
    assert np.allclose(diameter, 0.5 * 2 * smaller, rtol=1e-15)
    _, fixed = bonds_from_gap(position, radius, max_gap, diameter=2e-4)
    assert np.all(fixed == 2e-4)


def test_bond_cap_keeps_closest_first(sphere_packing):
    """Greedy by gap: every dropped candidate has an end that already holds `cap` bonds,
    all with gaps no larger than the dropped one; reordering the particles changes
    nothing but the labels."""
    _, position, radius = sphere_packing
    position, radius = position[:500], radius[:500]
    cap, max_gap = 3, 0.2 * R
    pairs, _ = bonds_from_gap(position, radius, max_gap, diameter=1e-4, max_per_particle=cap)
    candidates, candidate_gap = brute_bonds(position, radius, max_gap)
    degree = np.bincount(pairs.ravel(), minlength=radius.size)
    assert degree.max() <= cap and len(pairs) < len(candidates)
    gap_of = {tuple(p): g for p, g in zip(candidates.tolist(), candidate_gap)}
    kept = {tuple(p) for p in pairs.tolist()}
    assert kept <= set(gap_of)
    for p, g in gap_of.items():
        if p in kept:
            continue
        assert any(degree[e] == cap and all(gap_of[tuple(q)] <= g for q in
                                            pairs[(pairs == e).any(axis=1)].tolist())
                   for e in p), p
    order = np.random.default_rng(0).permutation(radius.size)
    again, _ = bonds_from_gap(position[order], radius[order], max_gap, diameter=1e-4,
                              max_per_particle=cap)
    relabelled = np.sort(order[again], axis=1)
    assert {tuple(p) for p in relabelled.tolist()} == kept


@pytest.mark.parametrize("table, key", [
    ({"shape": "cone", "radius": 0.01, "particle_radius": R, "material": "glass"}, "shape"),
    ({"shape": "sphere", "radius": 0.01, "particle_radius": -R, "material": "glass"},
     "particle_radius"),
    ({"shape": "sphere", "radius": 0.01, "particle_radius": R, "material": "glass",
      "solids_fraction": 0.9}, "solids_fraction"),
    ({"shape": "sphere", "radius": 0.01, "particle_radius": R}, "material"),
    ({"shape": "sphere", "radius": 0.01, "particle_radius": R, "material": "glass",
      "colour": 3}, "colour"),
    ({"shape": "box", "size": [0.01, -0.01, 0.01], "particle_radius": R,
      "material": "glass"}, "size"),
    ({"shape": "sphere", "radius": 0.01, "material": "glass",
      "size_distribution": {"type": "weibull", "mean": R}}, "size_distribution.type"),
    ({"shape": "sphere", "radius": 0.01, "material": "glass",
      "size_distribution": {"type": "normal", "mean": R, "std": -1.0}},
     "size_distribution.std"),
    ({"shape": "mesh", "file": "missing.stl", "particle_radius": R, "material": "glass"},
     "file"),
    ({"shape": "sphere", "radius": 0.01, "particle_radius": R, "material": "glass",
      "seed": 1.5}, "seed"),
])
def test_bad_generator_keys_name_the_key(table, key):
    with pytest.raises(InputError) as error:
        particles_from_generator(table, "scene.toml")
    assert error.value.key == f"particles.generator.{key}"
    assert "scene.toml" in str(error.value)


def test_generator_table_and_bond_table():
    table = {"shape": "sphere", "radius": 5 * R, "particle_radius": R, "material": "glass",
             "solids_fraction": 0.5, "seed": 2}
    position, radius, names = particles_from_generator(table, "s.toml")
    assert abs(radius.size - 0.5 * 125) <= 0.5 and set(names) == {"glass"}
    pairs, diameter, bond_names = bonds_from_table(
        {"max_gap": 0.1 * R, "diameter_ratio": 0.5, "material": "binder"}, position, radius)
    assert len(pairs) > 0 and set(bond_names) == {"binder"}
    for bad, key in [({"max_gap": -1.0, "diameter": 1e-4, "material": "b"}, "max_gap"),
                     ({"max_gap": 0.0, "material": "b"}, "diameter"),
                     ({"max_gap": 0.0, "diameter_ratio": 1.5, "material": "b"},
                      "diameter_ratio"),
                     ({"max_gap": 0.0, "diameter": 1e-4, "material": "b",
                       "max_per_particle": 0}, "max_per_particle")]:
        with pytest.raises(InputError) as error:
            bonds_from_table(bad, position, radius, "s.toml")
        assert error.value.key == f"bonds.{key}"


def test_jammed_request_fails_with_a_clear_error():
    """0.64 in a sphere of R/r ~ 7 is above the jamming fraction with walls: the generator
    must stop (stalled overlaps), not return overlapping spheres."""
    container = Sphere((0, 0, 0), (250 * R ** 3 / 0.64) ** (1 / 3))
    with pytest.raises(RuntimeError, match="jammed"):
        pack_spheres(container, radius=R, solids_fraction=0.64, seed=0)


def test_pack_spheres_takes_the_radii_themselves():
    """An array of radii is packed as given (MUSEN's package generator fixes the counts
    per fraction): the same radii in the same order, inside the box, overlaps within the
    limit."""
    from bondem.generate import Box, max_overlap, pack_spheres
    radii = np.repeat([2e-4, 3e-4], [40, 13])
    box = Box((0.0, 0.01, -0.002), (3e-3, 0.0125, 0.002))
    position, radius = pack_spheres(box, radius=radii, solids_fraction=0.3, seed=2,
                                    max_overlap=1e-3)
    assert np.array_equal(radius, radii)
    low, high = np.array(box.low), np.array(box.high)
    assert np.all(position - radius[:, None] >= low - 1e-12)
    assert np.all(position + radius[:, None] <= high + 1e-12)
    assert max_overlap(position, radius) <= 1e-3 * 1.0001   # relative to the smaller radius
    with pytest.raises(ValueError, match="radii must be finite"):
        pack_spheres(box, radius=np.array([2e-4, -1e-4]), solids_fraction=0.3)

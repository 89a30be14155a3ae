"""Make the demo agglomerate: src/bondem/data/demo/{particles,bonds}.csv.

An FCC packing of spheres (radius 0.5 mm, touching neighbours) cut to a sphere of radius
4.5 mm, bonded between every touching pair (12 per interior particle), bond diameter half
the particle diameter. The agglomerate sits 0.5 mm above the plane z = 0 and moves down
at 6 m/s (the velocity is set in scene.toml). Run once: python scripts/make_demo.py
"""
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

RADIUS = 0.5e-3            # m, particle radius
AGGLOMERATE_RADIUS = 4.5e-3  # m
GAP = 0.5e-3               # m, between the agglomerate and the wall at t = 0
BOND_DIAMETER = 0.5e-3     # m


def fcc_sphere(radius, sphere_radius):
    """Centres of an FCC packing of touching spheres inside a sphere (m)."""
    a = 2.0 * np.sqrt(2.0) * radius  # cubic cell edge for touching neighbours
    n = int(np.ceil(sphere_radius / a)) + 1
    cells = np.stack(np.meshgrid(*[np.arange(-n, n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    points = (cells[:, None, :] + basis[None]).reshape(-1, 3) * a
    return points[np.linalg.norm(points, axis=1) <= sphere_radius - radius]


def main():
    out = Path(__file__).resolve().parents[1] / "src" / "bondem" / "data" / "demo"
    position = fcc_sphere(RADIUS, AGGLOMERATE_RADIUS)
    position[:, 2] += AGGLOMERATE_RADIUS + GAP
    pairs = cKDTree(position).query_pairs(2.0 * RADIUS * 1.001, output_type="ndarray")
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    with open(out / "particles.csv", "w") as f:
        f.write("x,y,z,radius,material\n")
        for p in position:
            f.write(f"{p[0]:.9e},{p[1]:.9e},{p[2]:.9e},{RADIUS:.9e},glass\n")
    with open(out / "bonds.csv", "w") as f:
        f.write("i,j,diameter,material\n")
        for i, j in pairs:
            f.write(f"{i},{j},{BOND_DIAMETER:.9e},binder\n")
    print(f"{len(position)} particles, {len(pairs)} bonds -> {out}")


if __name__ == "__main__":
    main()

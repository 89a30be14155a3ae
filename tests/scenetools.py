"""Small scene files for the scene / CLI / results tests."""
import textwrap

import numpy as np

SCENE = """\
[simulation]
end_time = {end_time}
time_step = "auto"
save_every = {save_every}
gravity = [0.0, 0.0, -9.81]
contact_model = "none"
checkpoint_minutes = 0.0

[materials.glass]
density = 2500.0
young_modulus = 1e8
poisson_ratio = 0.3

[bond_materials.binder]
young_modulus = 1e8
poisson_ratio = 0.3
normal_strength = {strength}
tangential_strength = {strength}

[particles]
file = "particles.csv"

[bonds]
file = "bonds.csv"
"""


def cube_scene(folder, *, n=3, radius=1e-3, end_time=2e-4, save_every=2e-5, strength=3e5,
               speed=0.4, extra=""):
    """n^3 particles on a simple cubic lattice (spacing 2 radius), bonded to their six
    neighbours; the three x-layers move apart at ``speed`` (m/s) so the bonds along x
    stretch and, with the default strength (Pa), break while the others stay intact.
    Writes scene.toml, particles.csv, bonds.csv in ``folder``; returns the scene path."""
    grid = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    position = grid * 2.0 * radius
    centre = position.mean(axis=0)
    velocity = np.zeros_like(position)
    velocity[:, 0] = speed * (position[:, 0] - centre[0]) / (centre[0] or 1.0)
    rows = ["x,y,z,radius,material,vx,vy,vz,wx,wy,wz"]
    rng = np.random.default_rng(1)
    spin = rng.normal(scale=10.0, size=(len(position), 3))
    for p, v, w in zip(position, velocity, spin):
        rows.append(",".join(repr(float(c)) for c in p) + f",{radius!r},glass,"
                    + ",".join(repr(float(c)) for c in v) + ","
                    + ",".join(repr(float(c)) for c in w))
    (folder / "particles.csv").write_text("\n".join(rows) + "\n")
    index = {tuple(g): k for k, g in enumerate(grid.tolist())}
    bonds = ["i,j,diameter,material"]
    for g, k in index.items():
        for axis in range(3):
            h = list(g)
            h[axis] += 1
            if tuple(h) in index:
                bonds.append(f"{k},{index[tuple(h)]},{radius!r},binder")
    (folder / "bonds.csv").write_text("\n".join(bonds) + "\n")
    path = folder / "scene.toml"
    path.write_text(SCENE.format(end_time=end_time, save_every=save_every,
                                 strength=strength) + textwrap.dedent(extra))
    return path

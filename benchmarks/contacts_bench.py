"""Contact benchmark: particle-steps/s of a settled lattice packing, contacts only and
contacts + bonds, and the neighbour-list build time at two sizes.

The scene is the "lattice" benchmark of /work/shared/bench/README.md (n^3 spheres, radius
1 mm, spacing 2 mm, E 1e8, nu 0.3, e 0.5, mu 0.3, velocities uniform in [-0.05, 0.05] m/s,
seed 42, dt 1e-7 s), with the spacing reduced to 1.998 mm so that every particle rests
in contact with its six neighbours (a settled, jammed packing: 3 contacts per particle).
With bonds (diameter 1 mm, nearest neighbours) the bonded pairs carry no contact force.

    NUMBA_NUM_THREADS=1 PYTHONPATH=src python benchmarks/contacts_bench.py 47 200
"""
import sys
import time

import numpy as np

import bondem
from bondem.contacts import ContactSettings
from bondem.neighbors import build_pairs


def lattice(n, spacing=1.998e-3, bonds=False):
    grid = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    rng = np.random.default_rng(42)
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                            restitution=0.5, friction=0.3)
    kwargs = {}
    if bonds:
        index = np.arange(n ** 3).reshape(n, n, n)
        pairs = np.concatenate([
            np.column_stack([index[:-1].ravel(), index[1:].ravel()]),
            np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()]),
            np.column_stack([index[:, :, :-1].ravel(), index[:, :, 1:].ravel()])])
        kwargs = dict(bonds=pairs, bond_diameter=1e-3, bond_material=bondem.BondMaterial(
            young_modulus=1e8, poisson_ratio=0.3, normal_strength=1e30,
            tangential_strength=1e30))
    return bondem.make_system(grid * spacing, 1e-3, glass,
                              velocity=rng.uniform(-0.05, 0.05, grid.shape), **kwargs)


def main(n=47, steps=200):
    for n_side in (n // 2, n):
        model, state = lattice(n_side)
        build_pairs(state.position[:10], model.radius[:10], 2e-4, model.periodic,
                    model.box_low, model.box_high)  # compile
        t0 = time.perf_counter()
        pairs = build_pairs(state.position, model.radius, 2e-4, model.periodic,
                            model.box_low, model.box_high)
        print(f"neighbour list n={n_side ** 3}: {len(pairs)} pairs in "
              f"{time.perf_counter() - t0:.3f} s")
    for bonds in (False, True):
        model, state = lattice(n, bonds=bonds)
        sim = bondem.Simulation(model, state, time_step=1e-7, contact=ContactSettings())
        t0 = time.perf_counter()
        sim.step(5)
        warm = time.perf_counter() - t0
        t0 = time.perf_counter()
        sim.step(steps)
        wall = time.perf_counter() - t0
        touching = sim.contacts.touching()[0]
        print(f"{'contacts+bonds' if bonds else 'contacts only':15s} N={model.n_particles} "
              f"bonds={model.n_bonds} touching={touching} "
              f"rebuilds={int(state.extra['contact_counters'][2])} warm-up {warm:.1f} s: "
              f"{model.n_particles * steps / wall:.3g} particle-steps/s")


if __name__ == "__main__":
    main(*[int(a) for a in sys.argv[1:]])

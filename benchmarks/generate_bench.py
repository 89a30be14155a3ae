"""Packing benchmark (issue 5): a sphere filled with monodisperse spheres at a solids
fraction of 0.60, then bonded (max gap 1e-5 m, radius 2.5e-4 m). Prints N, solids fraction,
max overlap, coordination number, bond count and times. Usage:
    python benchmarks/generate_bench.py 10000 100000
JIT compilation is excluded by a small warm-up packing first. The packing loop is
serial: CPU time is the figure to compare on a shared machine."""
import sys
import time

import numpy as np

from bondem.generate import (Sphere, _minimise, bonds_from_gap, coordination_number, max_overlap,
                             pack_spheres, solids_fraction)

RADIUS, FRACTION, MAX_GAP = 2.5e-4, 0.60, 1e-5


def run(n, fraction=FRACTION):
    container = Sphere((0, 0, 0), (n * RADIUS ** 3 / fraction) ** (1 / 3))
    start, cpu = time.perf_counter(), time.process_time()
    position, radius = pack_spheres(container, radius=RADIUS, solids_fraction=fraction, seed=1)
    packed, packed_cpu = time.perf_counter() - start, time.process_time() - cpu
    pairs, _ = bonds_from_gap(position, radius, MAX_GAP, diameter_ratio=0.5)
    bonded = time.perf_counter() - start - packed
    print(f"N={radius.size} solids_fraction={solids_fraction(radius, container.volume):.4f} "
          f"max_overlap={max_overlap(position, radius):.2e} bonds={len(pairs)} "
          f"coordination={coordination_number(pairs, radius.size):.3f} "
          f"pack_time={packed:.1f}s (cpu {packed_cpu:.1f}s) bond_time={bonded:.2f}s "
          f"iterations,neighbour_builds={_minimise.stats}", flush=True)


if __name__ == "__main__":
    run(500, 0.5)  # warm-up: JIT compilation
    for arg in sys.argv[1:]:
        run(int(arg))

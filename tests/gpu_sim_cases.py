"""Cases for test_gpu_sim.py, run in a subprocess with NUMBA_ENABLE_CUDASIM=1 (the
simulator must be chosen before numba is imported). ``python gpu_sim_cases.py CASE``
exits 0 when the case passes and prints what it compared."""
import os
import sys

import numpy as np

import bondem


def bonded_cluster(seed=3):
    """A 3x3x3 lattice plus 3 satellites (30 particles) with nearest-neighbour and some
    diagonal bonds (~60), random velocities and spins strong enough to break bonds within
    tens of steps; gravity, local damping and one fixed particle exercise every branch."""
    rng = np.random.default_rng(seed)
    spacing = 2e-3
    grid = np.array([[x, y, z] for x in range(3) for y in range(3) for z in range(3)],
                    dtype=float) * spacing
    satellites = np.array([[3, 1, 1], [1, 3, 1], [1, 1, 3]], dtype=float) * spacing
    position = np.vstack([grid, satellites]) + rng.uniform(-5e-5, 5e-5, (30, 3))
    distance = np.linalg.norm(position[:, None] - position[None], axis=2)
    i, j = np.nonzero(np.triu(distance < 1.5 * spacing, 1))
    order = rng.permutation(i.size)[:60]
    bonds = np.column_stack([i, j])[np.sort(order)]
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=4e5,
                                 tangential_strength=3e5, breakage="combined")
    fixed = np.zeros(30, dtype=bool)
    fixed[0] = True
    velocity = rng.uniform(-1.0, 1.0, (30, 3))
    velocity[0] = 0.0
    return bondem.make_system(position, 1e-3, glass, velocity=velocity,
                              angular_velocity=rng.uniform(-300.0, 300.0, (30, 3)),
                              fixed=fixed, bonds=bonds, bond_diameter=1e-3,
                              bond_material=binder, gravity=(0.0, 0.0, -9.81), damping=0.05)


def case_bonds_match_cpu(steps=30):
    """GPU (simulator) and CPU runs of the same cluster agree to round-off."""
    runs = {}
    for backend in ("cpu", "gpu"):
        model, state = bonded_cluster()
        sim = bondem.Simulation(model, state, backend=backend)
        sim.step(steps // 2)
        sim.step(steps - steps // 2)   # two batches: the host copy between them is exact
        runs[backend] = (sim.state, sim.energy_terms())
    cpu, gpu = runs["cpu"][0], runs["gpu"][0]
    print(f"bonds {cpu.bond_active.size}, broken cpu {np.sum(~cpu.bond_active)} "
          f"gpu {np.sum(~gpu.bond_active)}, time {cpu.time:.3e} s")
    assert np.sum(~cpu.bond_active) >= 3, "the case must break bonds"
    assert np.sum(cpu.bond_active) >= 3, "the case must keep some bonds"
    assert np.array_equal(cpu.bond_active, gpu.bond_active)
    assert np.array_equal(cpu.bond_break_mode, gpu.bond_break_mode)
    assert np.array_equal(np.isnan(cpu.bond_break_time), np.isnan(gpu.bond_break_time))
    np.testing.assert_array_equal(np.nan_to_num(cpu.bond_break_time),
                                  np.nan_to_num(gpu.bond_break_time))
    assert cpu.step == gpu.step and cpu.time == gpu.time
    for name, scale in (("position", 1e-2), ("velocity", 1.0), ("angular_velocity", 300.0),
                        ("bond_axis", 1.0), ("bond_tangential_force", None),
                        ("bond_normal_moment", None), ("bond_tangential_moment", None),
                        ("bond_break_energy", None)):
        a, b = getattr(cpu, name), getattr(gpu, name)
        scale = scale or max(float(np.abs(a).max()), 1e-300)
        error = float(np.abs(a - b).max()) / scale
        print(f"{name:24s} max |cpu - gpu| / scale = {error:.2e}")
        assert error < 1e-12, name
    for key, value in runs["cpu"][1].items():
        other = runs["gpu"][1][key]
        print(f"energy {key:22s} cpu {value:.10e} gpu {other:.10e}")
        assert abs(value - other) <= 1e-10 * max(abs(value), 1e-12), key


def case_blow_up_flag():
    """A NaN set on the device is reported by the host once per batch, naming 'gpu'."""
    model, state = bonded_cluster()
    state.velocity[5, 0] = np.nan
    sim = bondem.Simulation(model, state, backend="gpu")
    try:
        sim.step(2)
    except bondem.SimulationBlowUp as error:
        print(error)
        assert "NaN" in str(error) and "gpu" in str(error)
        return
    raise AssertionError("no SimulationBlowUp")


def case_neighbour_search():
    """The GPU cell-list pairs equal the brute-force pairs (scipy cKDTree)."""
    from scipy.spatial import cKDTree
    from numba import cuda
    from bondem.backends.cuda import device_neighbour_pairs, inclusive_scan, neighbour_pairs
    rng = np.random.default_rng(7)
    values = rng.integers(0, 20, 1000)
    scanned = inclusive_scan(cuda.to_device(values)).copy_to_host()
    assert np.array_equal(scanned, np.cumsum(values)), "multi-level scan"
    # (n, box, grid): grid None spans the particles; a narrower grid clamps particles
    # outside it into the edge cells, which must not lose pairs.
    for n, box, grid in ((40, 6e-3, None), (200, 12e-3, None), (1, 1e-3, None),
                         (60, 8e-3, (2e-3, 5e-3))):
        radius = rng.uniform(0.4e-3, 1e-3, n)
        position = rng.uniform(0.0, box, (n, 3))
        skin = 2e-4
        if grid is None:
            pairs = neighbour_pairs(position, radius, skin)
        else:
            pairs = device_neighbour_pairs(cuda.to_device(position), cuda.to_device(radius),
                                           skin, np.full(3, grid[0]),
                                           np.full(3, grid[1])).copy_to_host()
        tree = cKDTree(position)
        candidates = tree.query_pairs(2 * radius.max() + skin, output_type="ndarray")
        d = np.linalg.norm(position[candidates[:, 0]] - position[candidates[:, 1]], axis=1)
        keep = d < radius[candidates[:, 0]] + radius[candidates[:, 1]] + skin
        expected = {tuple(sorted(p)) for p in candidates[keep].tolist()}
        found = [tuple(p) for p in pairs.tolist()]
        print(f"n = {n}: {len(found)} pairs, brute force {len(expected)}")
        assert len(found) == len(set(found)), "duplicate pairs"
        assert set(found) == expected
        assert all(i < j for i, j in found)


if __name__ == "__main__":
    assert os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" or "--device" in sys.argv
    globals()["case_" + sys.argv[1]]()
    print("ok")

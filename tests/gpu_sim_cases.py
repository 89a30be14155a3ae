"""Cases for test_gpu_sim.py, run in a subprocess with NUMBA_ENABLE_CUDASIM=1 (the
simulator must be chosen before numba is imported). ``python gpu_sim_cases.py CASE``
exits 0 when the case passes and prints what it compared."""
import os
import sys

import numpy as np
from numba import cuda

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


def periodic_chain(n=12):
    """A bonded ring of n particles wrapped around a periodic x axis (bonds cross the
    boundary: minimum image), bent and twisted by random spins, no breakage."""
    rng = np.random.default_rng(5)
    length = n * 2e-3
    position = np.column_stack([np.arange(n) * 2e-3 + 1e-3, np.zeros(n), np.zeros(n)])
    bonds = np.column_stack([np.arange(n), (np.arange(n) + 1) % n])
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, breakage="none")
    return bondem.make_system(position, 1e-3, glass, velocity=rng.uniform(-0.5, 0.5, (n, 3)),
                              angular_velocity=rng.uniform(-200.0, 200.0, (n, 3)),
                              bonds=bonds, bond_diameter=1e-3, bond_material=binder,
                              periodic=(True, False, False), box_low=(0.0, -1.0, -1.0),
                              box_high=(length, 1.0, 1.0))


def kelvin_cluster():
    """bonded_cluster with half of its bonds Kelvin bonds (damping ratio ~0.1 along the
    axis), bond materials chosen per bond."""
    model, state = bonded_cluster()
    elastic = model.bond_materials[0]
    kelvin = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=4e5,
                                 tangential_strength=3e5, model="kelvin", viscosity=2.3e-6,
                                 name="kelvin")
    index = np.arange(model.n_bonds) % 2
    glass = model.materials[0]
    return bondem.make_system(state.position, model.radius, glass,
                              velocity=state.velocity, angular_velocity=state.angular_velocity,
                              fixed=model.fixed, bonds=model.bond_pairs,
                              bond_diameter=model.bond_diameter,
                              bond_material=[elastic, kelvin], bond_material_index=index,
                              gravity=model.gravity, damping=model.damping)


def plastic_cluster():
    """bonded_cluster with elastic-perfectly plastic bonds (yielding at a quarter of the
    strength, breaking by strain), creep bonds,
    softening parallel bonds with Weibull strengths, weakening bonds drawing their drops,
    aerogel and plastic concrete bonds, elastic ones (a seventh each)."""
    model, state = bonded_cluster()
    elastic = model.bond_materials[0]
    plastic = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3,
                                  model="elastic_plastic", yield_strength=1e5,
                                  compressive_yield_ratio=1.4, fracture_strain=0.01,
                                  compressive_fracture_strain=0.02, name="plastic")
    creep = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, model="creep",
                                yield_strength=1.5e5, fracture_strain=0.01,
                                creep_rate=2e-4, creep_exponent=0.8, name="creep")
    rock = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.25, model="parallel",
                               normal_strength=5e4, tangential_strength=4e5,
                               friction_angle=30.0, moment_factor=0.8, softening=0.5,
                               strength_scatter="weibull", strength_spread=4.0,
                               strength_seed=11, name="rock")
    weak = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, model="weakening",
                               yield_strength=1e5, weakening_factor=0.6, fracture_strain=0.01,
                               strength_seed=4, name="weak")
    aerogel = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, model="aerogel",
                                  compressive_plastic_strain=8e-4,
                                  tensile_plastic_strain=1e-3, compressive_softness=-1.0,
                                  tensile_softness=0.5, tensile_break_strain=1.3e-3,
                                  name="aerogel")
    concrete = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, model="concrete",
                                   yield_strength=1e5, name="concrete")
    index = np.arange(model.n_bonds) % 7
    return bondem.make_system(state.position, model.radius, model.materials[0],
                              velocity=state.velocity, angular_velocity=state.angular_velocity,
                              fixed=model.fixed, bonds=model.bond_pairs,
                              bond_diameter=model.bond_diameter,
                              bond_material=[elastic, plastic, creep, rock, weak, aerogel,
                                             concrete],
                              bond_material_index=index,
                              gravity=model.gravity, damping=model.damping)


def case_plastic_bonds_match_cpu():
    """Plastic and elastic bonds side by side, yielding and breaking: GPU equals CPU, the
    plastic strains and the dissipated energy included, in both numerics."""
    case_bonds_match_cpu(system=plastic_cluster)
    case_bonds_match_cpu(system=plastic_cluster, musen_compat=True)


def case_kelvin_bonds_match_cpu():
    """Kelvin and elastic bonds side by side, breaking: GPU equals CPU, the dashpots' loss
    included; then the same with MUSEN's Kelvin numerics (musen_compat)."""
    case_bonds_match_cpu(system=kelvin_cluster)
    case_bonds_match_cpu(system=kelvin_cluster, musen_compat=True)


def case_periodic_match_cpu():
    """Periodic boundaries and MUSEN-compatible start-up: GPU equals CPU to round-off."""
    case_bonds_match_cpu(steps=20, system=periodic_chain, musen_compat=True, breaks=False)


def case_musen_bonds_match_cpu():
    """MUSEN-compatible bond law (elastic_bond_musen) with breakage: GPU equals CPU."""
    case_bonds_match_cpu(musen_compat=True)


def fluid_cluster():
    """bonded_cluster in a dense liquid that flows past it (Di Felice drag in a bed of
    voidage 0.7, buoyancy) with a random flow grid, seen from a frame turning fast about
    a skew axis: every branch of the fluid and frame forces."""
    model, state = bonded_cluster()
    model.fields["fluid"] = bondem.model.fluid_array(
        density=800.0, viscosity=2e-3, velocity=(1.0, 0.5, -0.2), drag="di_felice",
        buoyancy=True, voidage=0.7)
    model.fields["frame"] = bondem.model.frame_array((50.0, -100.0, 2000.0),
                                                     (1e-3, 0.0, -2e-3))
    rng = np.random.default_rng(8)
    model.set_flow(rng.uniform(-0.5, 0.5, (3, 4, 2, 3)), (-1e-3, 0.0, 1e-3),
                   (3e-3, 2e-3, 5e-3))
    return model, state


def case_fluid_match_cpu():
    case_bonds_match_cpu(system=fluid_cluster)


def case_flow_field_and_coupling_match_cpu():
    """fluid_cluster with a flow formula of x, y, z and t, a local voidage (a grid through
    the cluster) and a coupled solver (a linear drag towards a swirl, a moment on the
    spin, every 4 steps): on the GPU the positions go to the host each step and the
    solver's loads come back to the device; the run equals the CPU's."""
    from bondem.coupling import FlowField
    from bondem.expression import flow_function

    def flow():
        return FlowField(velocity=flow_function(["0.3 * sin(2000 * t) + 100 * y",
                                                 "-100 * x", "0.2 * cos(300 * z / 1e-3)"]),
                         voidage_grid=((-3e-3, -3e-3, -3e-3), (3e-3, 3e-3, 3e-3), (3, 2, 4)),
                         voidage_floor=0.3)

    calls = []

    def solver(exchange):
        calls.append(exchange.step)
        swirl = np.column_stack([-exchange.position[:, 1], exchange.position[:, 0],
                                 np.zeros(len(exchange.radius))]) * 50.0
        force = 2e-4 * exchange.radius[:, None] * (swirl - exchange.velocity)
        return force, -1e-9 * exchange.angular_velocity

    case_bonds_match_cpu(system=fluid_cluster, flow=flow,
                         prepare=lambda sim: sim.couple(solver, every=4))
    assert len(calls) == 16 and calls[:2] == [0, 4], calls
    print("ok: exchanges", len(calls))


def case_bonds_match_cpu(steps=30, system=bonded_cluster, musen_compat=False, breaks=True,
                         laws=lambda backend: [], time_step="auto", flow=lambda: None,
                         prepare=lambda sim: None):
    """GPU (simulator) and CPU runs of the same cluster agree to round-off."""
    runs = {}
    for backend in ("cpu", "gpu"):
        model, state = system()
        sim = bondem.Simulation(model, state, backend=backend, musen_compat=musen_compat,
                                laws=laws(backend), time_step=time_step, flow=flow())
        prepare(sim)
        sim.step(steps // 2)
        sim.step(steps - steps // 2)   # two batches: the host copy between them is exact
        runs[backend] = (sim.state, sim.energy_terms(), *(
            a.copy_to_host() if hasattr(a, "copy_to_host") else np.array(a)
            for a in (sim.force, sim.moment)))
    cpu, gpu = runs["cpu"][0], runs["gpu"][0]
    # the particles' loads of the last evaluation (results' /particles/force): the bonds'
    # included, on both backends
    for k, name in ((2, "force"), (3, "moment")):
        a, b = runs["cpu"][k], runs["gpu"][k]
        scale = max(float(np.abs(a).max()), 1e-300)
        error = float(np.abs(a - b).max()) / scale
        print(f"{name:24s} max |cpu - gpu| / scale = {error:.2e}")
        assert error < 1e-12, name
    assert set(runs["cpu"][1]) == set(runs["gpu"][1])
    print(f"bonds {cpu.bond_active.size}, broken cpu {np.sum(~cpu.bond_active)} "
          f"gpu {np.sum(~gpu.bond_active)}, time {cpu.time:.3e} s")
    if breaks:
        assert np.sum(~cpu.bond_active) >= 3, "the case must break bonds"
        assert np.sum(cpu.bond_active) >= 3, "the case must keep some bonds"
    elif breaks is False:
        wrapped = np.ptp(cpu.position[:, 0]) > 0.5 * (system()[0].box_high[0])
        assert wrapped and np.all(cpu.bond_active)
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
        if a.size == 0:
            continue
        scale = scale or max(float(np.abs(a).max()), 1e-300)
        error = float(np.abs(a - b).max()) / scale
        print(f"{name:24s} max |cpu - gpu| / scale = {error:.2e}")
        assert error < 1e-12, name
    if "bond_model_state" in cpu.extra:
        a, b = cpu.extra["bond_model_state"], gpu.extra["bond_model_state"]
        scale = np.maximum(np.abs(a).max(axis=0), 1e-300)
        error = float((np.abs(a - b).max(axis=0) / scale).max())
        print(f"bond_model_state         max |cpu - gpu| / scale = {error:.2e}, "
              f"columns in use {np.count_nonzero(np.abs(a).max(axis=0))}")
        assert error < 1e-12
    assert np.array_equal(cpu.bond_previous_length, gpu.bond_previous_length) or \
        np.abs(cpu.bond_previous_length - gpu.bond_previous_length).max() < 1e-12 \
        * cpu.bond_previous_length.max()
    for key, value in runs["cpu"][1].items():
        other = runs["gpu"][1][key]
        print(f"energy {key:22s} cpu {value:.10e} gpu {other:.10e}")
        assert abs(value - other) <= 1e-10 * max(abs(value), 1e-12), key


class TetherCpu:
    """Test law: each particle tied to its start by a spring, force -k (x - x0) (N) and a
    moment -k l (x - x0) (N m), so the extra-law path carries forces and moments."""

    def __init__(self, anchor, stiffness=50.0, lever=1e-3):
        self.anchor, self.stiffness, self.lever = anchor.copy(), stiffness, lever

    def accumulate(self, model, state, force, moment, increment_dt):
        pull = -self.stiffness * (state.position - self.anchor)
        force += pull
        moment += self.lever * pull


class TetherGpu(TetherCpu):
    backend = "gpu"

    def attach(self, backend):
        self.device_backend = backend
        self.device_anchor = cuda.to_device(self.anchor)

    def accumulate(self, model, state, force, moment, increment_dt):
        from bondem.backends.cuda_device import THREADS
        n = model.n_particles
        tether_kernel[(n + THREADS - 1) // THREADS, THREADS](
            self.device_backend.device.position, self.device_anchor, self.stiffness,
            self.lever, force, moment)


@cuda.jit
def tether_kernel(position, anchor, stiffness, lever, force, moment):
    p = cuda.grid(1)
    if p < position.shape[0]:
        for k in range(3):
            pull = -stiffness * (position[p, k] - anchor[p, k])
            force[p, k] += pull
            moment[p, k] += lever * pull


def case_extra_law_match_cpu():
    """An extra device law (zeroed load arrays, added to the fused bond gather) equals the
    same law on the CPU."""
    anchor = bonded_cluster()[1].position

    def law(backend):
        return [TetherGpu(anchor) if backend == "gpu" else TetherCpu(anchor)]
    case_bonds_match_cpu(steps=20, laws=law)
    # No bonds at all: the tether alone, an oscillator per particle.
    unbonded = lambda: bondem.make_system(anchor, 1e-3, bonded_cluster()[0].materials[0],
                                          velocity=np.full((30, 3), 0.1),
                                          gravity=(0.0, 0.0, -9.81))
    case_bonds_match_cpu(steps=10, system=unbonded, laws=law, breaks=None)
    model, state = bonded_cluster()
    try:
        bondem.Simulation(model, state, backend="gpu", laws=[TetherCpu(anchor)])
    except ValueError as error:
        print(error)
        assert "backend = 'gpu'" in str(error) and "TetherCpu" in str(error)
    else:
        raise AssertionError("a CPU law was accepted by the gpu backend")


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
    from gpu_prototypes import device_neighbour_pairs, inclusive_scan, neighbour_pairs
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
        assert found == sorted(expected), "pairs sorted by (i, j)"


def case_history_remap():
    """Contact history follows its pair across a rebuilt list (dict reference); pairs new
    to the list start from zero; an empty old list gives zeros."""
    from gpu_prototypes import neighbour_pairs, remap_pair_history
    rng = np.random.default_rng(3)
    n = 50
    radius = np.full(n, 0.8e-3)
    before = rng.uniform(0.0, 8e-3, (n, 3))
    after = before + rng.uniform(-4e-4, 4e-4, (n, 3))
    old_pairs = neighbour_pairs(before, radius, 2e-4)
    new_pairs = neighbour_pairs(after, radius, 2e-4)
    old_history = rng.normal(size=(len(old_pairs), 3))
    carried = remap_pair_history(cuda.to_device(old_pairs), cuda.to_device(old_history),
                                 cuda.to_device(new_pairs)).copy_to_host()
    table = {tuple(p): h for p, h in zip(old_pairs.tolist(), old_history)}
    expected = np.array([table.get(tuple(p), np.zeros(3)) for p in new_pairs.tolist()])
    kept = sum(tuple(p) in table for p in new_pairs.tolist())
    print(f"{len(old_pairs)} old pairs, {len(new_pairs)} new, {kept} carried over")
    assert 0 < kept < len(new_pairs), "the case must both keep and create contacts"
    assert np.array_equal(carried, expected)
    empty = cuda.to_device(np.zeros((0, 2), dtype=np.int64))
    zeros = remap_pair_history(empty, cuda.to_device(np.zeros((0, 3))),
                               cuda.to_device(new_pairs)).copy_to_host()
    assert np.array_equal(zeros, np.zeros((len(new_pairs), 3)))


def linear_law(n, overlap, v_rel, w_rel, spring, k_n, k_t, r_star, m_star, beta, friction,
               rolling_friction, dt):
    """A test pair law with the contact laws' signature: linear normal spring with a
    dashpot, tangential spring capped by Coulomb, constant rolling torque against w_rel."""
    v_n = v_rel[0] * n[0] + v_rel[1] * n[1] + v_rel[2] * n[2]
    f_n = k_n * overlap - beta * m_star * v_n
    xi = (spring[0] + (v_rel[0] - v_n * n[0]) * dt, spring[1] + (v_rel[1] - v_n * n[1]) * dt,
          spring[2] + (v_rel[2] - v_n * n[2]) * dt)
    f_t = (k_t * xi[0], k_t * xi[1], k_t * xi[2])
    size = (f_t[0] ** 2 + f_t[1] ** 2 + f_t[2] ** 2) ** 0.5
    if size > friction * f_n and size > 0.0:
        f_t = (f_t[0] * friction * f_n / size, f_t[1] * friction * f_n / size,
               f_t[2] * friction * f_n / size)
    spin = (w_rel[0] ** 2 + w_rel[1] ** 2 + w_rel[2] ** 2) ** 0.5
    # No builtin max: this numba's CUDA target rejects it (see case_ptx).
    size = rolling_friction * r_star * f_n / spin if spin > 0.0 and f_n > 0.0 else 0.0
    torque = (-size * w_rel[0], -size * w_rel[1], -size * w_rel[2])
    force = (-f_n * n[0] + f_t[0], -f_n * n[1] + f_t[1], -f_n * n[2] + f_t[2])
    return force, torque, f_t, xi, 0.5 * k_n * overlap * overlap, 0.0


def case_contact_kernel():
    """make_contact_kernel + CSR gather against a NumPy loop over the same pair law."""
    from numba import cuda
    from bondem.backends.cpu import particle_bond_index
    from bondem.backends.cuda import gather_bond_loads_kernel
    from bondem.backends.cuda_device import THREADS
    from bondem.backends.loops import BondIndex, BondLoads
    from gpu_prototypes import make_contact_kernel, neighbour_pairs
    rng = np.random.default_rng(11)
    n = 40
    position = rng.uniform(0.0, 5e-3, (n, 3))
    radius = rng.uniform(0.6e-3, 1e-3, n)
    velocity = rng.uniform(-1, 1, (n, 3))
    angular_velocity = rng.uniform(-100, 100, (n, 3))
    mass = 2500.0 * 4 / 3 * np.pi * radius ** 3
    material = rng.integers(0, 2, n).astype(np.int32)
    pairs = neighbour_pairs(position, radius, 1e-4)
    pair_bond = np.full(len(pairs), -1, dtype=np.int64)
    pair_bond[::5] = np.arange(len(pairs[::5]))          # some pairs are bonded ...
    bond_active = np.arange(len(pairs[::5])) % 2 == 0    # ... half of those bonds intact
    table = rng.uniform(0.5, 2.0, (2, 2, 5)) * np.array([1e4, 5e3, 1.0, 0.5, 0.1])
    table = 0.5 * (table + table.transpose(1, 0, 2))
    spring = rng.uniform(-1e-6, 1e-6, (len(pairs), 3))
    dt = 1e-6
    C = len(pairs)
    out = [cuda.device_array((C, 3)) for _ in range(3)] + [cuda.device_array(C) for _ in range(2)]
    d_spring = cuda.to_device(spring)
    kernel = make_contact_kernel(cuda.jit(device=True)(linear_law))
    put = cuda.to_device
    kernel[(C + THREADS - 1) // THREADS, THREADS](
        put(pairs), put(pair_bond), put(bond_active), put(position), put(velocity),
        put(angular_velocity), put(radius), put(mass), put(material), put(table),
        put(np.ones(3)), put(np.zeros(3, dtype=bool)), d_spring, dt, *out)
    offsets, ends = particle_bond_index(pairs, n)
    force, moment = cuda.device_array((n, 3)), cuda.device_array((n, 3))
    gather_bond_loads_kernel[(n + THREADS - 1) // THREADS, THREADS](
        BondIndex(put(offsets), put(ends)), BondLoads(*out[:3]), force, moment, True)
    # NumPy reference, written from the SPEC's contact geometry.
    ref_force, ref_moment, ref_spring = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros_like(spring)
    touching = 0
    for c, (i, j) in enumerate(pairs):
        r = position[j] - position[i]
        d = np.linalg.norm(r)
        overlap = radius[i] + radius[j] - d
        if (pair_bond[c] >= 0 and bond_active[pair_bond[c]]) or overlap <= 0:
            continue
        touching += 1
        nn = r / d
        a_i, a_j = radius[i] - overlap / 2, radius[j] - overlap / 2
        v_rel = velocity[j] - velocity[i] - np.cross(a_i * angular_velocity[i]
                                                     + a_j * angular_velocity[j], nn)
        p = table[material[i], material[j]]
        f, torque, f_t, xi, _, _ = linear_law(
            tuple(nn), overlap, tuple(v_rel), tuple(angular_velocity[i] - angular_velocity[j]),
            tuple(spring[c]), p[0], p[1], radius[i] * radius[j] / (radius[i] + radius[j]),
            mass[i] * mass[j] / (mass[i] + mass[j]), p[2], p[3], p[4], dt)
        ref_spring[c] = xi
        ref_force[i] += f
        ref_force[j] -= f
        ref_moment[i] += a_i * np.cross(nn, f_t) + torque
        ref_moment[j] += a_j * np.cross(nn, f_t) - np.array(torque)
    print(f"{C} candidate pairs, {touching} in contact and not bonded")
    assert touching >= 10
    np.testing.assert_allclose(force.copy_to_host(), ref_force, rtol=1e-12,
                               atol=1e-12 * np.abs(ref_force).max())
    np.testing.assert_allclose(moment.copy_to_host(), ref_moment, rtol=1e-12,
                               atol=1e-12 * np.abs(ref_moment).max())
    np.testing.assert_allclose(d_spring.copy_to_host(), ref_spring, rtol=1e-12, atol=1e-20)


class _HostArray(np.ndarray):
    """A NumPy array standing in for a device array (case_ptx records launches only)."""

    def copy_to_host(self, out=None):
        if out is None:
            return np.array(self)
        out[...] = self
        return out

    def copy_to_device(self, array):
        self[...] = array


def _argument_type(value):
    """The Numba type a CUDA launch gives ``value`` (arrays of a launch are C-contiguous)."""
    import numba
    from numba import types
    if isinstance(value, np.ndarray):
        return types.Array(numba.from_dtype(value.dtype), value.ndim, "C")
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return types.NamedTuple([_argument_type(v) for v in value], type(value))
    if isinstance(value, tuple):
        return types.Tuple([_argument_type(v) for v in value])
    return numba.typeof(value)


def record_backend_launches():
    """{kernel name: (kernel, arguments)} of every kernel the GPU backend launches in a
    few steps of bonds, breakage, Hertz-Mindlin and linear contacts, a plane and a moving
    mesh wall, MUSEN-compatible bonds and bond energies, with host arrays for device
    arrays and the launches recorded, not run."""
    from numba import cuda
    from numba.cuda.dispatcher import CUDADispatcher
    from bondem.backends import cuda as gb, cuda_contacts as gc
    from bondem.contacts import ContactSettings
    launches = {}

    class Recorder:
        def __init__(self, name, kernel):
            self.name, self.kernel = name, kernel

        def __getitem__(self, configuration):
            return lambda *args: launches.setdefault(self.name, (self.kernel, args))

    saved = {}
    fake = {"to_device": lambda a, *rest, **kw: np.array(a).view(_HostArray),
            "device_array": lambda shape, dtype=np.float64, **kw:
                np.zeros(shape, dtype).view(_HostArray)}
    for name, value in fake.items():
        saved[(cuda, name)] = getattr(cuda, name)
        setattr(cuda, name, value)
    saved[(gb, "require_device")] = gb.require_device
    gb.require_device = lambda name="gpu": None
    for module in (gb, gc):
        for name, value in vars(module).copy().items():
            if isinstance(value, CUDADispatcher):
                saved[(module, name)] = value
                setattr(module, name, Recorder(name, value))
    try:
        for settings, musen in ((ContactSettings(model="hertz_mindlin"), False),
                                (ContactSettings(model="linear"), True)):
            model, state, walls = falling_clusters()
            sim = bondem.Simulation(model, state, backend="gpu", contact=settings,
                                    walls=walls, musen_compat=musen)
            sim.step(3)
            sim.energy_terms()
        model, state = bonded_cluster()
        sim = bondem.Simulation(model, state, backend="gpu")
        sim.step(2)
        sim.bonds.accumulate(model, sim.state, sim.force, sim.moment, 1e-9)
    finally:
        for (module, name), value in saved.items():
            setattr(module, name, value)
    return launches


def case_ptx():
    """Every kernel compiles to PTX for an H100 (sm_90) with the real NVVM, no GPU needed.

    The simulator runs kernels as Python and accepts code that the CUDA target rejects
    (builtin min/max on mixed ints did); this compiles each kernel the backend launches
    with the argument types of its real launch (``record_backend_launches``), and the
    test-only prototypes with explicit types. Device functions ask for the current
    device's compute capability, which a machine without a driver has not: it is stubbed
    for this check only.
    """
    import numba.cuda.dispatcher as dispatcher
    from types import SimpleNamespace
    from numba import cuda, types
    import gpu_prototypes as gp
    dispatcher.get_current_device = lambda: SimpleNamespace(compute_capability=(9, 0))

    def array(dtype, ndim):
        return types.Array(dtype, ndim, "C")
    f64, i64 = types.float64, types.int64
    A1, A2, I1, I2 = array(f64, 1), array(f64, 2), array(i64, 1), array(i64, 2)
    B1, I32 = array(types.boolean, 1), array(types.int32, 1)
    signatures = {
        "cell_keys_kernel": (A2, A1, f64, I1, i64, I1),
        "bitonic_stage_kernel": (I1, i64, i64),
        "cell_start_kernel": (I1, i64, i64, I1),
        "count_pairs_kernel": (A2, A1, f64, A1, f64, I1, I1, I1, I1, I2),
        "write_pairs_kernel": (A2, A1, f64, A1, f64, I1, I1, I1, I1, I2),
        "_block_scan_kernel": (I1, I1, I1),
        "_add_block_offsets_kernel": (I1, I1),
        "remap_history_kernel": (I2, A2, I2, A2),
        "_displacement_flag_kernel": (A2, A2, f64, I1),
        "_bounds_kernel": (A2, A1, A1),
        "_pair_bond_kernel": (I2, I1, I1, I1),
        "contact_kernel": (I2, I1, B1, A2, A2, A2, A1, A1, I32, array(f64, 3), A1, B1, A2,
                           f64, A2, A2, A2, A1, A1),
    }
    kernels = {name: getattr(gp, name).py_func for name in signatures if hasattr(gp, name)}
    kernels["contact_kernel"] = gp.make_contact_kernel(
        cuda.jit(device=True)(linear_law)).py_func
    launched = record_backend_launches()
    for name, (kernel, args) in launched.items():
        kernels[name] = kernel.py_func
        signatures[name] = tuple(_argument_type(a) for a in args)
    expected = {"elastic_bonds_kernel", "integrate_kernel", "bond_energies_kernel",
                "gather_bond_loads_kernel",
                "particle_contacts_kernel", "gather_pairs_kernel", "wall_contacts_kernel",
                "displacement_flag_kernel", "_zero_kernel"}
    assert expected <= set(launched), sorted(expected - set(launched))
    for name, function in kernels.items():
        ptx, _ = cuda.compile_ptx(function, signatures[name], cc=(9, 0))
        assert ".visible .entry" in ptx
        print(f"{name:28s} PTX for sm_90: {len(ptx)} characters, "
              f"{ptx.count('fma.rn.f64')} fused multiply-adds")


class LinearContactsCpu:
    """Brute-force reference for ParticleContactsGpu with ``linear_law``: every pair, every
    step; springs kept in a dict while a pair touches (and is not held by a bond)."""

    def __init__(self, table):
        self.table, self.springs = table, {}

    def accumulate(self, model, state, force, moment, dt):
        x, v, w, radius = state.position, state.velocity, state.angular_velocity, model.radius
        bonded = {tuple(sorted(p)): b for b, p in enumerate(model.bond_pairs.tolist())}
        springs = {}
        for i in range(len(x)):
            for j in range(i + 1, len(x)):
                r = x[j] - x[i]
                d = np.linalg.norm(r)
                overlap = radius[i] + radius[j] - d
                b = bonded.get((i, j))
                if overlap <= 0 or (b is not None and state.bond_active[b]):
                    continue
                n = r / d
                a_i, a_j = radius[i] - overlap / 2, radius[j] - overlap / 2
                v_rel = v[j] - v[i] - np.cross(a_i * w[i] + a_j * w[j], n)
                p = self.table[model.material[i], model.material[j]]
                f, torque, f_t, xi, _, _ = linear_law(
                    tuple(n), overlap, tuple(v_rel), tuple(w[i] - w[j]),
                    tuple(self.springs.get((i, j), (0.0, 0.0, 0.0))), p[0], p[1],
                    radius[i] * radius[j] / (radius[i] + radius[j]),
                    model.mass[i] * model.mass[j] / (model.mass[i] + model.mass[j]),
                    p[2], p[3], p[4], dt)
                springs[(i, j)] = xi
                force[i] += f
                force[j] -= f
                moment[i] += a_i * np.cross(n, f_t) + torque
                moment[j] += a_j * np.cross(n, f_t) - np.array(torque)
        self.springs = springs


def colliding_cluster():
    """18 spheres on a 3x3x2 grid with 20 um gaps, converging and jittered, two materials,
    three bonds between touching neighbours: contacts open, close and persist."""
    rng = np.random.default_rng(9)
    grid = np.array([[x, y, z] for x in range(3) for y in range(3) for z in range(2)],
                    dtype=float) * 2.02e-3
    centre = grid.mean(axis=0)
    velocity = -(grid - centre) * 300.0 + rng.uniform(-0.2, 0.2, grid.shape)
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    steel = bondem.Material(density=7800.0, young_modulus=2e8, poisson_ratio=0.3)
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=1e5,
                                 tangential_strength=1e5)
    return bondem.make_system(grid, 1e-3, [glass, steel], material_index=np.arange(18) % 2,
                              velocity=velocity,
                              angular_velocity=rng.uniform(-100.0, 100.0, grid.shape),
                              bonds=[[0, 1], [4, 10], [8, 9]], bond_diameter=1e-3,
                              bond_material=binder)


def case_contacts_match_cpu():
    """ParticleContactsGpu (neighbour list, rebuilds with history carried, bonded pairs
    skipped) equals the brute-force CPU reference over 40 steps."""
    from gpu_prototypes import ParticleContactsGpu
    table = np.array([[[2e4, 1e4, 0.3, 0.4, 0.05], [3e4, 1.5e4, 0.2, 0.3, 0.02]],
                      [[3e4, 1.5e4, 0.2, 0.3, 0.02], [4e4, 2e4, 0.1, 0.5, 0.0]]])
    gpu_law = ParticleContactsGpu(colliding_cluster()[0], cuda.jit(device=True)(linear_law),
                                  table, skin=2e-5)
    cpu_law = LinearContactsCpu(table)

    def laws(backend):
        return [gpu_law if backend == "gpu" else cpu_law]
    case_bonds_match_cpu(steps=40, system=colliding_cluster, laws=laws, breaks=None,
                         time_step=1e-6)
    touching = len(cpu_law.springs)
    print(f"rebuilds {gpu_law.rebuilds}, contacts at the end {touching}, "
          f"list {gpu_law.pairs.shape[0]}")
    assert gpu_law.rebuilds >= 3 and touching >= 5


def falling_clusters(seed=11, periodic=False, keys=None):
    """Two bonded 2x2x2 clusters and 8 loose spheres (24 in all, two materials) falling
    onto a plane (z = 0) beside a tilted, moving and turning two-triangle mesh wall, with
    spins, gravity and weak bonds: particle contacts, wall contacts of both kinds and
    breakage within tens of steps. periodic: x periodic with a period of 12.08 r, so that the row of six
    closes across the boundary (its ends overlap by 0.02 r). keys: contact model keys
    given to every material (the two particle materials get 1 and 1.5 times each value)."""
    keys = keys or {}
    rng = np.random.default_rng(seed)
    r = 1e-3
    cube = np.array([[x, y, z] for x in range(2) for y in range(2) for z in range(2)],
                    dtype=float) * 2 * r
    first = cube + (0.0, 0.0, 1.02 * r)
    second = cube + (4.04 * r, 0.0, 1.02 * r)
    # a row of six beside the clusters (gaps 0.02 r) and one on top of each cluster
    loose = np.array([[0.0, 4.03, 0.51], [1.01, 4.03, 0.51], [2.02, 4.03, 0.51],
                      [3.03, 4.03, 0.51], [4.04, 4.03, 0.51], [5.05, 4.03, 0.51],
                      [1.0, 1.0, 2.52], [3.02, 1.0, 2.52]]) * 2 * r
    position = np.vstack([first, second, loose]) + rng.uniform(-2e-5, 2e-5, (24, 3))
    bonds = []
    for base in (0, 8):
        for a in range(8):
            for b in range(a + 1, 8):
                if np.sum(np.abs(cube[a] - cube[b]) > 0) == 1:
                    bonds.append((base + a, base + b))
    velocity = rng.uniform(-0.3, 0.3, (24, 3)) + (0.0, 0.0, -1.0)
    velocity[:8, 0] += 1.0    # the clusters converge and hit each other
    velocity[8:16, 0] -= 1.0
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                            restitution=0.6, friction=0.4, rolling_friction=0.05, **keys)
    steel = bondem.Material(density=7800.0, young_modulus=2e8, poisson_ratio=0.28,
                            restitution=0.8, friction=0.3, rolling_friction=0.02,
                            **{k: 1.5 * v for k, v in keys.items()})
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=3e5,
                                 tangential_strength=3e5)
    model, state = bondem.make_system(
        position, r, [glass, steel], material_index=np.arange(24) % 2, velocity=velocity,
        angular_velocity=rng.uniform(-200.0, 200.0, (24, 3)), bonds=bonds,
        bond_diameter=1e-3, bond_material=binder, gravity=(0.0, 0.0, -9.81),
        **(dict(periodic=(True, False, False), box_low=(-1.06 * r, -0.1, -0.1),
                box_high=(11.02 * r, 0.1, 0.1)) if periodic else {}))
    from bondem.walls import MeshWall, PlaneWall
    wall_material = bondem.Material(density=7800.0, young_modulus=2e8, poisson_ratio=0.3,
                                    restitution=0.7, friction=0.5, rolling_friction=0.03,
                                    **keys)
    # A square tilted 45 degrees about y, its lower edge under the first cluster's x = 0
    # face, 0.99 r from the lower spheres of that face (moving at them: they touch it).
    x0 = -0.37 * r
    vertices = np.array([[x0, -3 * r, 0.0], [x0, 12 * r, 0.0],
                         [x0 - 8 * r, 12 * r, 8 * r], [x0 - 8 * r, -3 * r, 8 * r]])
    walls = [PlaneWall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), wall_material),
             MeshWall(vertices, [[0, 1, 2], [0, 2, 3]], wall_material,
                      velocity=(0.05, 0.0, 0.0), angular_velocity=(0.0, 20.0, 0.0),
                      rotation_center=(x0, 4.5 * r, 0.0))]
    return model, state, walls


def compare_contact_runs(system, settings, steps, time_step="auto", expect_walls=True,
                         restart=False, musen_compat=False):
    """GPU (simulator) and CPU runs with contacts and walls: everything to 1e-12.

    restart: the GPU run's second batch is made by a new Simulation from a copy of the
    host state after the first (a checkpoint: lists and history from ``state.extra``)."""
    runs = {}
    for backend in ("cpu", "gpu"):
        model, state, walls = system()
        sim = bondem.Simulation(model, state, backend=backend, contact=settings, walls=walls,
                                time_step=time_step, musen_compat=musen_compat)
        sim.step(steps // 2)
        half = (sim.wall_force.copy(), sim.wall_torque.copy())
        if restart and backend == "gpu":
            sim = bondem.Simulation(model, sim.state.copy(), backend=backend, contact=settings,
                                    walls=walls, time_step=sim.time_step,
                                    musen_compat=musen_compat)
        sim.step(steps - steps // 2)
        runs[backend] = (sim.state, sim.energy_terms(), sim.wall_force.copy(),
                         sim.wall_torque.copy(), half, sim.contacts.touching())
    cpu, gpu = runs["cpu"][0], runs["gpu"][0]
    counters = cpu.extra["contact_counters"]
    print(f"steps {cpu.step}, broken bonds {np.sum(~cpu.bond_active)} of "
          f"{cpu.bond_active.size}, rebuilds {counters[2]:.0f}, touching (pairs, walls) "
          f"cpu {runs['cpu'][5]} gpu {runs['gpu'][5]}")
    assert runs["cpu"][5] == runs["gpu"][5]
    assert runs["cpu"][5][0] >= 3, "the case must have particle contacts"
    if expect_walls:
        assert runs["cpu"][5][1] >= 3, "the case must have wall contacts"
    assert np.array_equal(cpu.bond_active, gpu.bond_active)
    assert np.array_equal(cpu.bond_break_mode, gpu.bond_break_mode)
    assert cpu.step == gpu.step and cpu.time == gpu.time
    for name in ("contact_pairs", "wall_pairs"):
        assert np.array_equal(cpu.extra[name], gpu.extra[name]), name
    assert np.array_equal(cpu.extra["contact_counters"][2:], gpu.extra["contact_counters"][2:])
    worst = 0.0
    checks = [(name, getattr(cpu, name), getattr(gpu, name), None) for name in (
        "position", "velocity", "angular_velocity", "bond_axis", "bond_tangential_force",
        "bond_normal_moment", "bond_tangential_moment", "bond_break_energy",
        "clump_position", "clump_orientation", "clump_velocity", "clump_angular_momentum")]
    checks += [(name, cpu.extra[name], gpu.extra[name], None) for name in (
        "contact_spring", "contact_force", "contact_moment_i", "contact_moment_j",
        "contact_energy", "wall_spring", "wall_force_rows", "wall_moment_rows",
        "wall_energy_rows")]
    if musen_compat:
        checks += [(name, cpu.extra[name], gpu.extra[name], None)
                   for name in ("contact_tangential", "wall_tangential")]
    checks += [("wall_force", runs["cpu"][2], runs["gpu"][2], None),
               ("wall_torque", runs["cpu"][3], runs["gpu"][3], None),
               ("wall_force (batch 1)", runs["cpu"][4][0], runs["gpu"][4][0], None)]
    for name, a, b, scale in checks:
        if a.size == 0:
            continue
        assert a.shape == b.shape, name
        scale = scale or max(float(np.abs(a).max()), 1e-300)
        error = float(np.abs(a - b).max()) / scale
        worst = max(worst, error)
        print(f"{name:24s} max |cpu - gpu| / scale = {error:.2e}")
        assert error < 1e-12, name
    assert np.all(np.abs(runs["cpu"][2]).max(axis=1) > 0.0), "every wall must carry a load"
    total = sum(abs(v) for v in runs["cpu"][1].values())
    for key, value in runs["cpu"][1].items():
        other = runs["gpu"][1][key]
        print(f"energy {key:22s} cpu {value:.12e} gpu {other:.12e}")
        assert abs(value - other) <= 1e-12 * total, key
    print(f"worst relative difference {worst:.2e}")
    return cpu


def case_contacts_walls_match_cpu():
    """Hertz-Mindlin contacts, a plane and a moving mesh wall, breakage: GPU equals CPU."""
    from bondem.contacts import ContactSettings
    compare_contact_runs(falling_clusters, ContactSettings(model="hertz_mindlin"), steps=30)


def frictionless_platen_clusters():
    """falling_clusters with walls whose friction is their contacts' own (own_friction)."""
    model, state, walls = falling_clusters()
    for wall in walls:
        wall.own_friction = True
    return model, state, walls


def case_own_friction_walls_match_cpu():
    """Walls whose material friction is their contacts' own: GPU equals CPU."""
    from bondem.contacts import ContactSettings
    compare_contact_runs(frictionless_platen_clusters, ContactSettings(model="hertz_mindlin"),
                         steps=30)


def case_musen_contacts_walls_match_cpu():
    """MUSEN's Hertz-Mindlin (musen_compat) with a plane, a moving turning mesh wall and
    breakage: the CUDA kernels take the same flag and bodies as the CPU's, GPU equals CPU."""
    from bondem.contacts import ContactSettings
    cpu = compare_contact_runs(falling_clusters, ContactSettings(model="hertz_mindlin"),
                               steps=30, musen_compat=True)
    assert np.any(cpu.extra["contact_tangential"] != 0.0)
    assert np.any(cpu.extra["wall_tangential"] != 0.0)


# Adhesive laws strong enough to act within the case's 30 steps on 1 mm spheres.
ADHESIVE = {"jkr": {"surface_energy": 2.0},
            "popov_jkr": {"surface_energy": 2.0},
            "vdw": {"hamaker_constant": 1e-17, "vdw_cutoff": 3e-5, "vdw_min_distance": 4e-7},
            "liquid_bridge": {"surface_tension": 0.07, "contact_angle": 20.0,
                              "bridge_volume": 2e-12, "viscosity": 1e-3,
                              "bridge_min_gap": 2e-6}}


def case_adhesive_contacts_match_cpu():
    """Every adhesive contact model (JKR, Popov's JKR, van der Waals, liquid bridge; Popov's
    also in MUSEN's numerics) with a plane, a moving mesh wall and breakage: the
    CUDA kernels dispatch on the model's code as the CPU's do, GPU equals CPU."""
    from bondem.contacts import ContactSettings
    # MUSEN's numerics once (Popov's: its own normal law on both kinds of contact, and its
    # wall model's lagging spring): the other kinds share that dispatch and its code
    for name, keys in ADHESIVE.items():
        for musen in ((False, True) if name == "popov_jkr" else (False,)):
            print(f"-- {name}, musen_compat {musen}")
            cpu = compare_contact_runs(lambda: falling_clusters(keys=keys),
                                       ContactSettings(model=name), steps=16,
                                       musen_compat=musen)
            assert np.any(cpu.extra["contact_energy"] < 0.0) or musen, \
                "the case must have an adhesive contact"


def falling_clumps():
    """falling_clusters with the row of six loose spheres made into two rigid clumps of
    three (alternate spheres: one material each) and one of the two on top (with its
    neighbour in the row) left free, with local damping: the clump kernel's sums, its
    damping and its placing of members on both backends."""
    from bondem.clumps import make_clumps
    model, state, walls = falling_clusters(seed=5)
    clump_of = np.full(model.n_particles, -1)
    clump_of[[16, 18, 20]] = 0
    clump_of[[17, 19, 21]] = 1
    model, state = make_clumps(model, state, clump_of)
    model.damping = 0.05
    return model, state, walls


def case_clumps_match_cpu():
    """Clumps among bonded clusters, contacts, a plane and a moving mesh wall, the GPU run
    restarted half-way from a copy of its state: GPU equals CPU."""
    from bondem.contacts import ContactSettings
    cpu = compare_contact_runs(falling_clumps, ContactSettings(model="hertz_mindlin"),
                               steps=30, restart=True)
    assert np.any(cpu.clump_angular_momentum != 0.0)


def case_contacts_linear_rebuilds():
    """Linear contacts with a small skin (a list rebuild every few steps, springs carried
    by the host rebuild), x periodic (contacts across the boundary), the GPU run resumed
    from a copy of its state half-way (as from a checkpoint): GPU equals CPU."""
    from bondem.contacts import ContactSettings

    def system():
        model, state, walls = falling_clusters(seed=12, periodic=True)
        return model, state, walls[:1]
    cpu = compare_contact_runs(system, ContactSettings(model="linear", skin=2e-5), steps=30,
                               time_step=2e-6, restart=True)
    pairs = cpu.extra["contact_pairs"]
    loaded = pairs[np.any(cpu.extra["contact_force"] != 0.0, axis=1)]
    gap = np.abs(cpu.position[loaded[:, 1], 0] - cpu.position[loaded[:, 0], 0])
    print(f"loaded pairs across the periodic boundary: {int(np.sum(gap > 6e-3))}")
    assert np.any(gap > 6e-3), "the case must have a contact across the periodic boundary"

def nvvm_available():
    try:
        from numba.cuda.cudadrv import nvvm
        nvvm.NVVM()
        return True
    except Exception:
        return False


if __name__ == "__main__":
    if sys.argv[1] == "ptx" and not nvvm_available():
        print("NVVM (libnvvm from a CUDA toolkit) not found")
        sys.exit(3)
    assert (os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" or "--device" in sys.argv
            or sys.argv[1] == "ptx")
    globals()["case_" + sys.argv[1]]()
    print("ok")

"""CUDA backend under numba's simulator, against the CPU backend and brute force.

Reference: the CPU backend (same physics functions, compiled by numba.njit) to round-off,
1e-12 relative over 30 steps with breakage; brute-force pair finding (scipy cKDTree) for the
neighbour search, exactly. NUMBA_ENABLE_CUDASIM must be set before numba is imported, so
each case runs in a subprocess (tests/gpu_sim_cases.py). Tests marked ``gpu`` run the same
kernels on a real device at the benchmark sizes and skip without one.
"""
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bondem
from bondem.errors import InputError

HERE = Path(__file__).parent
SRC = HERE.parent / "src"


def run_case(name, simulator=True, timeout=300, skip_status=None):
    env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
               NUMBA_NUM_THREADS="1")
    if simulator:
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    else:
        env.pop("NUMBA_ENABLE_CUDASIM", None)
    args = [sys.executable, str(HERE / "gpu_sim_cases.py"), name]
    if not simulator:
        args.append("--device")
    result = subprocess.run(args, env=env, capture_output=True, text=True, timeout=timeout)
    if skip_status is not None and result.returncode == skip_status:
        pytest.skip(result.stdout.strip())
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


def test_bond_path_matches_cpu_under_simulator():
    """30 steps of a 30-particle, 60-bond cluster with breakage: same broken bonds, modes
    and break times; positions, velocities, bond vectors and energies to 1e-12."""
    out = run_case("bonds_match_cpu")
    assert "ok" in out


def test_fluid_forces_match_cpu_under_simulator():
    """The bonded cluster in a flowing liquid (drag, buoyancy) in a rotating frame: the
    CUDA kernel takes the fluid and frame arrays and the same physics functions as the
    CPU's."""
    out = run_case("fluid_match_cpu")
    assert "velocity" in out and "energy work_external" in out


def test_flow_field_and_coupling_match_cpu_under_simulator():
    """A flow formula of x, y, z, t, a local voidage and a coupled solver on the GPU: the
    per-particle fluid array and the solver's loads go to the device; the run equals the
    CPU's to 1e-12."""
    out = run_case("flow_field_and_coupling_match_cpu")
    assert "ok: exchanges 16" in out and "energy work_external" in out


def test_periodic_musen_start_matches_cpu_under_simulator():
    """A bonded ring across a periodic boundary, MUSEN-compatible start-up, 20 steps."""
    run_case("periodic_match_cpu")


def test_musen_bond_law_matches_cpu_under_simulator():
    """The MUSEN-compatible bond law (musen_compat=True) with breakage, 30 steps: the CUDA
    kernel takes the same flag and the same physics function as the CPU kernel."""
    assert "ok" in run_case("musen_bonds_match_cpu")


def test_kelvin_bonds_match_cpu_under_simulator():
    """Kelvin bonds beside elastic ones, breaking: positions, velocities, bond state and
    every energy term (the dashpots' loss too) to 1e-12 of the CPU's."""
    out = run_case("kelvin_bonds_match_cpu")
    assert "dissipated_bonds" in out


def test_plastic_bonds_match_cpu_under_simulator():
    """Elastic-plastic, creep and softening parallel bonds (scattered strengths) beside
    elastic ones, yielding, creeping, softening and breaking, in bondem's and MUSEN's
    numerics: state, plastic strains, damage and energies to 1e-12."""
    out = run_case("plastic_bonds_match_cpu")
    assert "dissipated_plastic" in out and "dissipated_creep" in out
    assert "dissipated_softening" in out and "dissipated_weakening" in out
    assert "dissipated_aerogel" in out and "dissipated_concrete" in out
    assert "columns in use 3" in out


def test_extra_device_law_matches_cpu_under_simulator():
    """A second law on the device (a tether spring) adds to the fused bond gather as the
    CPU law does; a CPU-only law is refused by backend='gpu' with a message."""
    run_case("extra_law_match_cpu")


def test_blow_up_flag_under_simulator():
    """A NaN velocity sets the device status flag; the host raises SimulationBlowUp."""
    run_case("blow_up_flag")


def test_neighbour_search_matches_brute_force_under_simulator():
    """Cell sort + scan + pair finding on the (simulated) GPU equals brute force."""
    run_case("neighbour_search")


def test_history_remap_under_simulator():
    """Per-pair history follows its pair when the pair list is rebuilt (dict reference)."""
    run_case("history_remap")


def test_particle_contacts_match_brute_force_under_simulator():
    """ParticleContactsGpu (pair list rebuilt with history carried, bonded pairs skipped)
    against a brute-force CPU law: 40 steps to 1e-12."""
    run_case("contacts_match_cpu")


def test_contact_kernel_matches_numpy_under_simulator():
    """The contact kernel around a compiled pair law, gathered through the CSR index,
    equals a NumPy loop over the same law (forces, moments, springs to 1e-12)."""
    run_case("contact_kernel")


def test_contacts_and_walls_match_cpu_under_simulator():
    """Simulation(backend="gpu", contact=Hertz-Mindlin, walls=[plane, moving mesh]): two
    bonded clusters and loose spheres falling and colliding, bonds breaking, 30 steps in
    two batches: positions, velocities, bond vectors, contact and wall history rows,
    wall force and torque to 1e-12 of the CPU ContactLaw; same lists and energy terms."""
    out = run_case("contacts_walls_match_cpu")
    assert "wall_force" in out


def test_own_friction_walls_match_cpu_under_simulator():
    """The same scene with walls whose friction is their contacts' own (the lab's
    frictionless platens): the CUDA kernels read the same wall pair table."""
    out = run_case("own_friction_walls_match_cpu")
    assert "wall_force" in out


def test_musen_contacts_and_walls_match_cpu_under_simulator():
    """The same scene with MUSEN's Hertz-Mindlin (musen_compat=True): the CUDA kernels run
    the same bodies with the flag, so everything, the stored tangential forces that MUSEN
    applies while sliding included, equals the CPU's to 1e-12."""
    out = run_case("musen_contacts_walls_match_cpu")
    assert "contact_tangential" in out and "wall_tangential" in out


def test_adhesive_contacts_match_cpu_under_simulator():
    """JKR, Popov's JKR, van der Waals and liquid bridges (Popov's also MUSEN's) on the
    same scene: the kernels dispatch on the contact model's code on both backends, and
    every history row, wall load and energy term equals the CPU's to 1e-12."""
    out = run_case("adhesive_contacts_match_cpu")
    assert out.count("worst relative difference") == 5


def test_clumps_match_cpu_under_simulator():
    """Two rigid clumps among bonded clusters, loose spheres, a plane and a moving mesh
    wall, with damping, the GPU run restarted half-way: the clump kernel runs the CPU's
    body, so the clumps' positions, quaternions and momenta and every particle equal the
    CPU's to 1e-12."""
    out = run_case("clumps_match_cpu")
    assert "clump_orientation" in out


def test_contact_list_rebuilds_match_cpu_under_simulator():
    """Linear contacts with a small skin, x periodic (a contact across the boundary): the
    lists are rebuilt every few steps (on the host, springs carried), the GPU run is
    resumed half-way from a copy of its state (a checkpoint's state.extra), and it still
    equals the CPU run to 1e-12."""
    run_case("contacts_linear_rebuilds")


def test_kernels_compile_for_h100():
    """Every kernel compiles to PTX for sm_90 with NVVM (skips without a CUDA toolkit):
    the simulator alone accepts code that the CUDA target rejects."""
    out = run_case("ptx", simulator=False, skip_status=3)
    assert "elastic_bonds_kernel" in out and "contact_kernel" in out
    assert "particle_contacts_kernel" in out and "wall_contacts_kernel" in out


def test_gpu_backend_without_device_is_a_clear_error(glass, binder):
    """Without a GPU and without the simulator, backend='gpu' names the backend."""
    from numba import cuda
    if cuda.is_available():
        pytest.skip("a CUDA device (or the simulator) is available here")
    model, state = bondem.make_system([[0, 0, 0], [2e-3, 0, 0]], 1e-3, glass,
                                      bonds=[[0, 1]], bond_diameter=1e-3, bond_material=binder)
    with pytest.raises(RuntimeError, match="backend = 'gpu'") as error:
        bondem.Simulation(model, state, backend="gpu")
    assert isinstance(error.value, InputError)  # the command line prints one line, exit 2
    with pytest.raises(ValueError, match="backend = 'tpu'"):
        bondem.Simulation(model, state, backend="tpu")


def test_numpy_without_row_stack_is_a_clear_error():
    """numba-cuda registers np.row_stack, which NumPy 2.5 removed: backend='gpu' says so
    and what to install, instead of failing at the first launch (skips without numba-cuda;
    NumPy 2.5 is imitated by removing the function)."""
    import importlib.util
    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed")
    from bondem.backends.cuda import cuda_target_problem
    assert cuda_target_problem() is None
    code = ("import numpy, bondem\n"
            "from bondem.backends.cuda import cuda_target_problem\n"
            "del numpy.row_stack\n"
            "print(cuda_target_problem())\n")
    env = dict(os.environ, PYTHONPATH=str(SRC))
    env.pop("NUMBA_ENABLE_CUDASIM", None)
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == (
        f"numba-cuda cannot compile kernels with NumPy {np.__version__} (module 'numpy' "
        "has no attribute 'row_stack'; NVIDIA/numba-cuda#907): install numpy<2.5, as pip "
        "install 'bondem[gpu]' does")


# every case of gpu_sim_cases.py but the PTX check (which needs no device)
DEVICE_CASES = sorted(set(re.findall(r"^def case_(\w+)\(", (HERE / "gpu_sim_cases.py").read_text(),
                                     re.MULTILINE)) - {"ptx"})


def test_device_cases_are_every_simulator_case():
    """The device run repeats each case a simulator test runs (none forgotten as cases are
    added)."""
    simulated = set(re.findall(r'run_case\("(\w+)"\)', Path(__file__).read_text()))
    assert simulated and simulated <= set(DEVICE_CASES)


def _has_gpu():
    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
        return False
    try:
        from numba import cuda
        return cuda.is_available()
    except Exception:
        return False


@pytest.mark.gpu
@pytest.mark.skipif(not _has_gpu(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("case", DEVICE_CASES)
def test_cases_on_device(case):
    """Every simulator case again on the real device (fused multiply-add may change bits,
    not the 1e-12 agreement)."""
    run_case(case, simulator=False)


def lattice(n, seed=42):
    """The bench lattice (shared/bench/README.md): n^3 spheres, spacing 2 mm, radius 1 mm,
    a bond between every pair of nearest neighbours, intact variant, velocities uniform in
    [-0.05, 0.05] m/s."""
    index = np.arange(n ** 3).reshape(n, n, n)
    grid = np.indices((n, n, n)).reshape(3, -1).T * 2e-3
    bonds = np.vstack([np.column_stack([index[:-1].ravel(), index[1:].ravel()]),
                       np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()]),
                       np.column_stack([index[:, :, :-1].ravel(), index[:, :, 1:].ravel()])])
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=1e30,
                                 tangential_strength=1e30)
    velocity = np.random.default_rng(seed).uniform(-0.05, 0.05, (n ** 3, 3))
    return bondem.make_system(grid, 1e-3, glass, velocity=velocity, bonds=bonds,
                              bond_diameter=1e-3, bond_material=binder)


@pytest.mark.gpu
@pytest.mark.skipif(not _has_gpu(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("n", [100, 200])
def test_lattice_bench_size_on_device(n):
    """The bench lattice at 1e6 and 8e6 particles: 10 steps on the device equal 10 steps
    on the CPU to 1e-12 (catches index overflow and launch-size errors at these sizes)."""
    states = {}
    for backend in ("cpu", "gpu"):
        model, state = lattice(n)
        sim = bondem.Simulation(model, state, backend=backend, time_step=1e-7)
        sim.step(10)
        states[backend] = sim.state
    cpu, gpu = states["cpu"], states["gpu"]
    assert np.all(gpu.bond_active)
    np.testing.assert_allclose(gpu.position, cpu.position, rtol=0, atol=1e-12 * 2e-3 * n)
    np.testing.assert_allclose(gpu.velocity, cpu.velocity, rtol=0, atol=1e-12)
    np.testing.assert_allclose(gpu.bond_tangential_force, cpu.bond_tangential_force, rtol=0,
                               atol=1e-12 * max(np.abs(cpu.bond_tangential_force).max(), 1e-30))

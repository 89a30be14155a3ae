"""``bondem bench [lattice|impact|bed]``: particle-steps/s and bond-updates/s of the bench
scenes.

Thin: parses, calls ``bondem.bench``, prints a table (and writes JSON with --json).
"""
import gc
import json
import statistics
import sys
from pathlib import Path

import click

from ..errors import InputError


def _sizes(text, scene="lattice"):
    try:
        sizes = [int(float(s)) for s in text.split(",") if s.strip()]
    except ValueError:
        raise InputError(f"--sizes = {text!r}: expected integers separated by commas, "
                         "e.g. 22,47") from None
    low, high, what = ((2, 400, "each lattice size n") if scene == "lattice" else
                       (100, 10_000_000, f"each {scene} size (particles)"))
    if not sizes or any(n < low or n > high for n in sizes):
        raise InputError(f"--sizes = {text!r}: {what} must lie in [{low}, {high}]")
    return sizes


def _ranks(text):
    try:
        ranks = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        ranks = []
    if not ranks or any(r < 1 or r > 64 for r in ranks):
        raise InputError(f"--ranks = {text!r}: MPI rank counts in [1, 64], e.g. 1,2")
    return ranks


@click.command(name="bench")
@click.argument("scene", type=click.Choice(["lattice", "impact", "bed", "bed_jkr", "bed_vdw",
                                            "bed_liquid"]), default="lattice")
@click.option("--sizes", default=None,
              help="Lattice sizes n (n^3 particles), e.g. 22,47,74 [default 22]; for impact "
                   "and bed the particle counts, e.g. 1e4,1e5 [default 1e4].")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="Timed steps after warm-up [default: 1000 for n <= 22, else 200].")
@click.option("--variant", type=click.Choice(["intact", "breaking"]), default="intact",
              show_default=True)
@click.option("--backend", type=click.Choice(["cpu", "gpu"]), default="cpu",
              show_default=True)
@click.option("--order", type=click.Choice(["morton", "lattice", "random"]),
              default="morton", show_default=True,
              help="Particle numbering: Morton-sorted (default), as built, or shuffled.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the results as JSON to this file.")
@click.option("--peer", type=click.Choice(["lammps"]), default=None,
              help="Also run the same scene in LAMMPS (benchmarks/lammps) and compare.")
@click.option("--peer-steps", type=click.IntRange(min=1), default=None,
              help="Timed steps for the lattice peer [default: same as --steps].")
@click.option("--ranks", default="1,2", show_default=True,
              help="MPI ranks of the LAMMPS peer (each a run).")
@click.option("--warmup", type=click.IntRange(min=0), default=5, show_default=True,
              help="Untimed steps before the timed ones, for impact and bed (both codes): "
                   "e.g. 1500 to time the impact well under way.")
@click.option("--profile", is_flag=True,
              help="Also time each part of the CPU step (bonds, gather, neighbour "
                   "lists, contacts, walls, integrate).")
@click.option("--rounds", type=click.IntRange(min=1, max=50), default=1, show_default=True,
              help="Run bondem and its peer in turn this many times (each a fresh run) and "
                   "print each round's ratio and their median: this host's speed can change "
                   "between one run and the next.")
@click.option("--triad", is_flag=True,
              help="Also measure memory bandwidth (STREAM-like triad); with --profile, "
                   "each part's share of that roofline.")
def command(scene, sizes, steps, variant, backend, order, json_path, peer, peer_steps,
            ranks, warmup, profile, rounds, triad):
    """Time SCENE (the bench scenes of docs/performance.md) and print a table: lattice (a
    bonded cubic lattice), impact (a dense random bonded agglomerate hitting a plane,
    contacts live, bonds breaking), bed (an unbonded bed resting on a plane) or the same bed
    with adhesive contacts: bed_jkr, bed_vdw, bed_liquid (JKR, van der Waals, liquid
    bridges)."""
    from .. import bench

    results = []
    extra = {}
    if triad:
        extra["triad_bytes_per_s"] = bench.stream_triad()
        click.echo(f"memory bandwidth (triad): {extra['triad_bytes_per_s'] / 1e9:.1f} GB/s")
    sizes = _sizes(sizes or ("22" if scene == "lattice" else "1e4"), scene)
    ranks = _ranks(ranks)
    for round_number in range(1, rounds + 1):
        done = len(results)
        if round_number > 1:
            gc.collect()   # the last round's simulation, so that peak RSS stays its own
        if scene == "lattice":
            _lattices(bench, sizes, steps, variant, backend, order, peer, peer_steps, ranks,
                      profile, results)
        else:
            _scenes(bench, scene, sizes, steps, backend, peer, ranks, profile, results,
                    warmup)
        if rounds > 1:
            for r in results[done:]:
                r["round"] = round_number
    click.echo(bench.format_table(results))
    for r in results:
        if "ratio_bondem_over_lammps" in r:
            click.echo(f"{r['scene']} n={r['n']}: bondem / {r['backend']} particle-steps/s "
                       f"= {r['ratio_bondem_over_lammps']:.2f}")
        if r.get("profile"):
            parts = ", ".join(f"{k} {v * 1e3:.3f}" for k, v in r["profile"].items())
            click.echo(f"{r['scene']} n={r['n']} ms per step (median): {parts}")
            lists = r["profile_mean"]["neighbour lists"]
            click.echo(f"{r['scene']} n={r['n']} neighbour lists, mean over the profile's "
                       f"steps (rebuilds included): {lists * 1e3:.3f} ms per step")
            if "triad_bytes_per_s" in extra:
                click.echo(f"{r['scene']} n={r['n']} parts against the roofline (the "
                           "median step; least bytes, no rebuild):")
                for line in bench.format_profile(r, extra["triad_bytes_per_s"]):
                    click.echo("  " + line)
            if not r["bonds"]:
                continue
            bond_s = r["profile_best"]["bond kernel"]
            line = (f"n={r['n']} bond kernel (best step of the profile): "
                    f"{bond_s / r['bonds'] * 1e9:.1f} ns per bond")
            if "triad_bytes_per_s" in extra:
                bandwidth = extra["triad_bytes_per_s"]
                r["bond_roofline_share"] = bench.bond_roofline_share(bond_s, r["bonds"],
                                                                     bandwidth)
                line += (f", roofline {bench.BOND_UPDATE_BYTES / bandwidth * 1e9:.1f} ns "
                         f"({bench.BOND_UPDATE_BYTES} B at {bandwidth / 1e9:.1f} GB/s): "
                         f"{100 * r['bond_roofline_share']:.0f} % of the roofline")
            click.echo(line)
    if scene == "lattice" and "triad_bytes_per_s" in extra:
        _step_roofline(bench, results, extra["triad_bytes_per_s"])
    if rounds > 1 and peer:
        extra["round_ratios"] = _round_ratios(results)
    cpu_runs = [r for r in results if r.get("backend") == "cpu" and r["bonds"]]
    if cpu_runs:
        estimate = bench.memory_estimate(cpu_runs[-1])
        click.echo(f"arrays for 10^6 particles with 3 bonds each: {estimate / 1e9:.2f} GB")
    if json_path is not None:
        clean = [{k: v for k, v in r.items() if not k.startswith("_")} for r in results]
        json_path.write_text(json.dumps({"results": clean, **extra}, indent=2) + "\n")
        click.echo(f"json: {json_path}")
    sys.stdout.flush()


def _step_roofline(bench, results, bandwidth):
    """Print and record the whole lattice step against the memory roofline (the timed
    steps' seconds per step, ``bench.step_bytes`` at the triad's bandwidth)."""
    for r in results:
        if r.get("backend") != "cpu":     # the triad measures the CPU's memory only
            continue
        total = bench.step_bytes(r["particles"], r["bonds"])
        r["step_bytes_per_particle"] = total / r["particles"]
        r["step_roofline_share"] = bench.step_roofline_share(r["s_per_step"], r["particles"],
                                                             r["bonds"], bandwidth)
        click.echo(f"n={r['n']} whole step: {total / r['particles']:.0f} B per particle-step "
                   f"counted, roofline {total / bandwidth * 1e3:.3f} ms per step at "
                   f"{bandwidth / 1e9:.1f} GB/s, measured {r['s_per_step'] * 1e3:.3f} ms: "
                   f"{100 * r['step_roofline_share']:.0f} % of the roofline")


def _round_ratios(results):
    """Print and return, for each scene, size and peer, the ratio of particle-steps/s
    of every round and their median (a list of dicts)."""
    groups = {}
    for r in results:
        if "ratio_bondem_over_lammps" in r:
            key = (r["scene"], r["n"], r["backend"])
            groups.setdefault(key, []).append(r["ratio_bondem_over_lammps"])
    summary = []
    for (scene, n, backend), ratios in groups.items():
        median = statistics.median(ratios)
        click.echo(f"{scene} n={n}: bondem / {backend} particle-steps/s in {len(ratios)} "
                   f"rounds: {', '.join(f'{x:.2f}' for x in ratios)}; median {median:.2f}")
        summary.append({"scene": scene, "n": n, "backend": backend, "ratios": ratios,
                        "median": median})
    return summary


def _add_peer(results, result, run):
    """Run a peer (``run()``: its figures) beside ``result`` and add it with the ratio of
    particle-steps/s; a peer that fails is reported, not fatal."""
    try:
        other = run()
    except (RuntimeError, OSError) as error:
        click.echo(f"bondem: lammps peer failed: {error}", err=True)
        return
    other["ratio_bondem_over_lammps"] = (result["particle_steps_per_s"]
                                         / other["particle_steps_per_s"])
    results.append(other)


def _lammps_peers(results, result, label, ranks, run):
    """The LAMMPS peer of ``result`` on each rank count (``run(ranks)``: its figures)."""
    for count in ranks:
        click.echo(f"bench {label}: the same in LAMMPS on {count} MPI "
                   f"rank{'s' if count > 1 else ''} ...", err=True)
        _add_peer(results, result, lambda: run(count))


def _lattices(bench, sizes, steps, variant, backend, order, peer, peer_steps, ranks,
              profile, results):
    """The lattice scene at each size n, and its LAMMPS peer (benchmarks/lammps) on each
    rank count."""
    for n in sizes:
        n_steps = steps or (1000 if n <= 22 else 200)
        click.echo(f"bench lattice n={n}: {n ** 3:,} particles, building the scene, "
                   f"warming up (compiles kernels on a first run), then {n_steps} timed "
                   "steps ...", err=True)
        try:
            result = bench.lattice_run(n, n_steps, variant=variant, backend=backend,
                                       order=order, profile=profile)
        except ValueError as error:
            raise InputError(f"bench: {error}") from None
        results.append(result)
        for note in result["notes"]:
            click.echo(f"n={n}: {note}")
        if peer == "lammps":
            _lammps_peers(results, result, f"lattice n={n}", ranks,
                          lambda count: bench.lammps_run(n, peer_steps or n_steps, count))


def _scenes(bench, scene, sizes, steps, backend, peer, ranks, profile, results, warmup=5):
    """The impact or bed scene at each size, and its LAMMPS peer on each rank count (the
    same initial state, time step and steps, through ``bondem export lammps``'s writer)."""
    for n in sizes:
        n_steps = steps or (500 if n <= 20_000 else 100)
        click.echo(f"bench {scene} {n:,} particles: packing and bonding the scene, warming up "
                   f"(compiles kernels on a first run) and {warmup} more steps, then "
                   f"{n_steps} timed steps ...", err=True)
        try:
            result = bench.scene_run(scene, n, n_steps, backend=backend, profile=profile,
                                     warmup=warmup)
        except ValueError as error:
            raise InputError(f"bench: {error}") from None
        results.append(result)
        for note in result["notes"]:
            click.echo(f"{scene} {n}: {note}")
        click.echo(f"{scene} {n}: {result['s_per_loaded_row'] * 1e9:.1f} ns per step per "
                   f"row that carried a load ({result['contact_model']})")
        if peer == "lammps":
            _lammps_peers(results, result, f"{scene} {n:,} particles", ranks,
                          lambda count: bench.lammps_scene_run(result, count))

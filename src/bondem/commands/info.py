"""``bondem info SCENE.toml``: counts, masses, stable time step, memory estimate."""
from pathlib import Path

import click


@click.command(name="info")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a scene value as `bondem run --set` does (repeatable).")
def command(scene, overrides):
    """Counts, total mass, stable time step (and what limits it), memory estimate."""
    from ..scene import load_scene, parse_override
    from ..timestep import stable_time_step

    changes = dict(parse_override(text) for text in overrides)
    loaded = load_scene(scene, changes or None)
    for warning in loaded.warnings:
        click.echo(f"bondem: warning: {warning}", err=True)
    click.echo("\n".join(describe(loaded, stable_time_step)))


def describe(scene, stable_time_step):
    """Lines of text describing a loaded scene."""
    import numpy as np

    from ..runner import frame_schedule

    model, options = scene.model, scene.simulation_options
    n, b = model.n_particles, model.n_bonds
    walls = options.get("walls", [])
    stable, cause = stable_time_step(model, options["safety_factor"])
    dt = stable if options["time_step"] == "auto" else options["time_step"]
    total, stride = frame_schedule(scene, dt)
    frames = 1 + -(-total // stride)  # t = 0, every stride steps, and the last step
    memory, base = peak_memory(n, b, "contact" in options)
    results = frames * 8 * (12 * n + 9 * b) + frames * b
    materials = ", ".join(f"{m.name} ({int(np.sum(model.material == k))})"
                          for k, m in enumerate(model.materials))
    lines = [
        f"scene:           {scene.path}",
        f"particles:       {n}   materials: {materials}",
        *([f"clumps:          {model.n_clumps} (rigid grains of "
             f"{int(np.count_nonzero(model.clump_of >= 0))} of the particles)"]
          if model.n_clumps else []),
        f"bonds:           {b}",
        f"walls:           {len(walls)}   contacts: "
        f"{scene.data['simulation'].get('contact_model', 'none')}",
        f"total mass:      {model.mass.sum():.6g} kg",
        f"radius:          {model.radius.min():.4g} .. {model.radius.max():.4g} m",
        f"stable step:     {stable:.4g} s (safety factor {options['safety_factor']}, "
        f"limited by {cause})",
        f"time step:       {dt:.4g} s" + (" (auto)" if options["time_step"] == "auto" else ""),
        f"end time:        {scene.end_time:.4g} s = {total} steps, {frames} frames "
        f"every {stride} steps",
        f"memory estimate: {memory / 2**20:.3g} MiB peak on the CPU ({base / 2**20:.3g} MiB "
        f"of it Python, NumPy, Numba and the kernels; ~{COMPILE_BYTES / 2**20:.0f} MiB more "
        "while kernels compile, first run only)",
        f"results size:    up to {results / 2**20:.3g} MiB before compression",
        f"backend:         {scene.backend}",
    ]
    return lines


# Peak resident memory of `bondem run` on the CPU, measured (/usr/bin/time, maximum RSS)
# on bench lattices with 1 000 to 103 823 particles, with and without bonds and contacts:
# Python with NumPy, h5py, Numba and the loaded kernels ~190 MiB; each particle ~540 B
# (state, the CSV rows while read, frame and checkpoint copies), each bond ~480 B (history,
# loads, the frame's force and moments), and with contacts ~1 090 B per particle
# (neighbour list, pair history). n = 47 (103 823 particles, 304 842 bonds) measured
# 498 MiB, this gives 491 MiB; n = 22 measured 220 MiB, this gives 221 MiB.
RUNTIME_BYTES = 190 * 2 ** 20
PARTICLE_BYTES = 540
BOND_BYTES = 480
CONTACT_BYTES_PER_PARTICLE = 1090
COMPILE_BYTES = 120 * 2 ** 20   # Numba's compiler, when the kernel cache is cold


def peak_memory(n_particles, n_bonds, contacts):
    """(peak bytes of a CPU run, bytes of it taken by the runtime itself): the measured
    model above, for ``n_particles``, ``n_bonds`` and contacts on or off."""
    data = (n_particles * (PARTICLE_BYTES + (CONTACT_BYTES_PER_PARTICLE if contacts else 0))
            + n_bonds * BOND_BYTES)
    return RUNTIME_BYTES + data, RUNTIME_BYTES

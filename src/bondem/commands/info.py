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
    # State: 3 (N,3) float64 arrays + per-bond history (~17 float64 each) + kernel scratch
    # (force/moment (N,3), per-bond loads 9 floats); results: position, velocity, angular
    # velocity and force per frame and particle, force and two moments plus a flag per
    # frame and bond.
    memory = 8 * (n * (9 + 6 + 6) + b * (17 + 9 + 4))
    results = frames * 8 * (12 * n + 9 * b) + frames * b
    materials = ", ".join(f"{m.name} ({int(np.sum(model.material == k))})"
                          for k, m in enumerate(model.materials))
    lines = [
        f"scene:           {scene.path}",
        f"particles:       {n}   materials: {materials}",
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
        f"memory estimate: {memory / 2**20:.3g} MiB in RAM, results up to "
        f"{results / 2**20:.3g} MiB before compression",
        f"backend:         {scene.backend}",
    ]
    return lines

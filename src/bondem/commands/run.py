"""``bondem run SCENE.toml``: run a scene with a progress bar and write DIR/results.h5;
``bondem run script.txt``: run the jobs of a cmusen script (musen_jobs.py)."""
import sys
from pathlib import Path

import click


def _folder(ctx, param, value):
    """--out as a Path; an empty name (which would mean the current folder) is an error."""
    from ..errors import InputError
    if value is None:
        return None
    if not value.strip():
        raise InputError("empty folder name; give a folder, e.g. --out results", key="--out")
    return Path(value)


@click.command(name="run")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", callback=_folder,
              help="Output folder (default: next to the scene, named after it).")
@click.option("--backend", type=click.Choice(["cpu", "gpu"]),
              help="Override simulation.backend of the scene.")
@click.option("--resume", is_flag=True,
              help="Continue from the folder's last checkpoint (same scene).")
@click.option("--overwrite", is_flag=True,
              help="Replace the results of an earlier run in the output folder (and the "
                   "analysis, report and vtk output made from them).")
@click.option("--checkpoint-minutes", type=click.FloatRange(min=0.0, max=1e9),
              help="Wall-clock minutes between checkpoints (scene default: 10).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a scene value, e.g. --set simulation.end_time=1e-3 (repeatable).")
@click.option("--no-progress", is_flag=True, help="No progress bar.")
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True,
              help="A cmusen script: Dask processes for its independent simulations.")
def command(scene, out_dir, backend, resume, overwrite, checkpoint_minutes, overrides,
            no_progress, workers):
    """Run SCENE (a TOML scene file, docs/scene.md) and write OUT/results.h5 with a
    checkpoint beside it. An output folder that holds results is refused unless
    --overwrite or --resume is given. SCENE may also be a cmusen job script (JOB,
    COMPONENT IMPORT_FROM_TEXT / SIMULATOR / EXPORT_TO_TEXT ...): its jobs run in order,
    each simulation in the folder named after its RESULT_FILE (docs/musen_migration.md)."""
    from ..runner import RunFailed, RunInterrupted, default_out_dir, run_scene
    from ..scene import load_scene, parse_override

    from ..errors import InputError
    from ..musen_jobs import is_script, run_script
    if is_script(scene):
        given = [name for name, value in (("--out", out_dir), ("--backend", backend),
                                          ("--resume", resume), ("--set", overrides),
                                          ("--checkpoint-minutes", checkpoint_minutes))
                 if value]
        if given:
            raise InputError(f"{given[0]} does not apply to a cmusen script (its jobs name "
                             "their files)", file=scene, key=given[0])
        try:
            run_script(scene, workers=workers, echo=click.echo)
        except RunFailed as error:
            click.echo(f"bondem: run failed: {error}", err=True)
            sys.exit(1)
        return
    if checkpoint_minutes is not None and checkpoint_minutes != checkpoint_minutes:
        raise InputError("nan is not a number of minutes; allowed [0, 1e9]",
                         key="--checkpoint-minutes")
    changes = dict(parse_override(text) for text in overrides)
    if backend is not None:
        changes["simulation.backend"] = backend
    loaded = load_scene(scene, changes or None)
    for warning in loaded.warnings:
        click.echo(f"bondem: warning: {warning}", err=True)
    out_dir = out_dir or default_out_dir(scene)
    try:
        path = run_scene(loaded, out_dir, progress=not no_progress, resume=resume,
                         checkpoint_minutes=checkpoint_minutes, overwrite=overwrite)
    except RunFailed as error:
        click.echo(f"bondem: run failed: {error}", err=True)
        sys.exit(1)
    except RunInterrupted as error:
        click.echo(f"bondem: {error}", err=True)
        click.echo("continue with: " + resume_command(scene, out_dir, overrides, backend),
                   err=True)
        sys.exit(128 + error.signal_number)   # the shell's status for a signal
    click.echo(f"results: {path}")
    warning = energy_warning(path)
    if warning:
        click.echo(f"bondem: warning: {warning}", err=True)
    click.echo(f"next: bondem analyze {path}   (fragments, broken bonds, energy, wall force)")
    click.echo(f"      bondem report {path}    (one HTML page with the figures)")
    click.echo(f"      bondem export vtk {path}   (ParaView files)")


ENERGY_TOLERANCE = 0.05    # of the reference energy: beyond it a run's numbers are suspect


def energy_warning(path):
    """What to say about the energy balance of results file ``path`` when its error
    exceeds ENERGY_TOLERANCE (None: within it, or no energy recorded)."""
    from ..analysis.energy import energy_balance
    from ..analysis.results import Results
    with Results(path) as results:
        balance = energy_balance(results)
    if balance is None or not balance["max_relative_error"] > ENERGY_TOLERANCE:
        return None
    return (f"the energy balance is off by {balance['max_relative_error']:.1%} of the "
            f"reference energy ({balance['reference']:.3g} J; allowed "
            f"{ENERGY_TOLERANCE:.0%}): the run's forces are not to be trusted. Lower "
            "simulation.safety_factor (a smaller time step), check for particles that "
            "start inside each other or inside a wall, and see bondem analyze for the "
            "terms")


def resume_command(scene, out_dir, overrides, backend):
    """The command line that continues an interrupted run: the same scene, folder, --set
    options and backend, with --resume."""
    import shlex
    words = ["bondem", "run", str(scene), "--out", str(out_dir), "--resume"]
    for text in overrides:
        words += ["--set", text]
    if backend is not None:
        words += ["--backend", backend]
    return " ".join(shlex.quote(w) for w in words)

"""``bondem import musen FILE``: a MUSEN text scene as a bondem scene (docs/musen_migration.md)."""
from pathlib import Path

import click

from ..errors import InputError


@click.group(name="import")
def command():
    """Import scenes of other codes (MUSEN's text format)."""


@command.command(name="musen")
@click.argument("text_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--script", "script", type=click.Path(dir_okay=False, path_type=Path),
              help="cmusen script with the models and time stepping (MODEL_SB, "
                   "SIMULATION_STEP, END_TIME, SAVING_STEP, EXT_ACCEL ...).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              required=True, help="Folder for scene.toml, particles.csv, bonds.csv.")
@click.option("--end-time", type=click.FloatRange(min=0.0, min_open=True),
              help="Simulated time (s) if the script gives none [default: END_TIME, "
                   "else 1e-3].")
@click.option("--musen-version", type=click.Choice(["1.74.2", "1.70.0"]), default="1.74.2",
              show_default=True,
              help="The MUSEN release whose numerics the scene reproduces (musen_compat; "
                   "their contacts differ).")
def musen_command(text_file, script, out_dir, end_time, musen_version):
    """A MUSEN text file (what MUSEN's GUI and cmusen export and IMPORT_FROM_TEXT reads:
    spheres, solid bonds, triangular walls and their geometries, compounds, interactions,
    domain, periodic boundaries) and its cmusen script as a bondem scene with
    musen_compat = true. Anything it cannot map is listed, not dropped silently."""
    from ..io.musen_text import import_musen

    if script is not None and not script.is_file():
        raise InputError("no such file", file=script, key="--script")
    import shlex
    path, notes = import_musen(text_file, out_dir, script, end_time=end_time,
                               musen_version=musen_version)
    click.echo(f"scene: {path}")
    for note in notes:
        click.echo(f"note: {note}")
    # --out: the results beside the imported files (a run's folder would otherwise be
    # OUT/scene, one level below them)
    click.echo(f"next: bondem run {shlex.quote(str(path))} --out {shlex.quote(str(out_dir))}"
               f"   (writes {out_dir / 'results.h5'})")

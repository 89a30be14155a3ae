"""``bondem import musen FILE``: a MUSEN text scene or .mdem file as a bondem scene, and a
finished MUSEN simulation as a bondem results file (docs/musen_migration.md)."""
from pathlib import Path

import click

from ..errors import InputError


@click.group(name="import")
def command():
    """Import scenes and results of other codes (MUSEN's text format and .mdem files)."""


@command.command(name="musen")
@click.argument("text_file", metavar="FILE", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--script", "script", type=click.Path(dir_okay=False, path_type=Path),
              help="cmusen script with the models and time stepping (MODEL_SB, "
                   "SIMULATION_STEP, END_TIME, SAVING_STEP, EXT_ACCEL ...).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              required=True, help="Folder for scene.toml, particles.csv, bonds.csv.")
@click.option("--end-time", type=click.FloatRange(min=0.0, min_open=True),
              help="Simulated time (s) if the script gives none [default: END_TIME, "
                   "else 1e-3].")
@click.option("--musen-version", type=click.Choice(["1.74.2", "1.70.0"]), default=None,
              help="The MUSEN release whose numerics the scene reproduces (musen_compat; "
                   "their contacts differ) [default: a .mdem file's own (its model "
                   "manager tells 1.70 from 1.74), 1.74.2 for text].")
@click.option("--results", is_flag=True,
              help="A .mdem file of a finished simulation: also every saved time point "
                   "as OUT/results.h5 (for bondem analyze, report, export vtk, the lab).")
def musen_command(text_file, script, out_dir, end_time, musen_version, results):
    """A MUSEN text file (what MUSEN's GUI and cmusen export and IMPORT_FROM_TEXT reads:
    spheres, solid bonds, triangular walls and their geometries, compounds, interactions,
    domain, periodic boundaries) and its cmusen script, or a MUSEN .mdem file (which
    holds its models and simulator settings itself), as a bondem scene with
    musen_compat = true. Anything it cannot map is listed, not dropped silently."""
    from ..io.musen_text import import_musen

    if script is not None and not script.is_file():
        raise InputError("no such file", file=script, key="--script")
    import shlex
    mdem = text_file.suffix.lower() == ".mdem"
    if mdem and script is not None:
        raise InputError("a .mdem file holds its models and settings: no --script",
                         file=text_file, key="--script")
    if results and not mdem:
        raise InputError("--results reads a .mdem file (a text export holds one time "
                         "point per object line, not a run)", file=text_file,
                         key="--results")
    if results:
        from ..io.musen_mdem import import_mdem_results
        if (out_dir / "results.h5").exists():
            raise InputError("already holds a results.h5 (remove it or choose another "
                             "folder)", file=out_dir, key="--out")
        results_path, notes = import_mdem_results(text_file, out_dir,
                                                  musen_version=musen_version)
        click.echo(f"scene: {out_dir / 'scene.toml'}")
        click.echo(f"results: {results_path}")
        for note in notes:
            click.echo(f"note: {note}")
        click.echo(f"next: bondem analyze {shlex.quote(str(results_path))}")
        return
    if mdem:
        from ..io.musen_mdem import import_mdem
        path, notes = import_mdem(text_file, out_dir, end_time=end_time,
                                  musen_version=musen_version)
    else:
        path, notes = import_musen(text_file, out_dir, script, end_time=end_time,
                                   musen_version=musen_version or "1.74.2")
    click.echo(f"scene: {path}")
    for note in notes:
        click.echo(f"note: {note}")
    # --out: the results beside the imported files (a run's folder would otherwise be
    # OUT/scene, one level below them)
    click.echo(f"next: bondem run {shlex.quote(str(path))} --out {shlex.quote(str(out_dir))}"
               f"   (writes {out_dir / 'results.h5'})")

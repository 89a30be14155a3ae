"""``bondem export vtk|musen RESULTS.h5``: ParaView files or MUSEN text of a results file."""
from pathlib import Path

import click

from . import results_file
from ..errors import InputError


def _check_results(results):
    """InputError unless ``results`` (Path) is a readable bondem results file."""
    from ..io.results import open_results
    if not results.is_file():
        raise InputError("no such file", file=results, key="RESULTS")
    try:
        with open_results(results) as f:
            missing = [k for k in ("time", "particles/position", "bonds/pairs") if k not in f]
    except InputError as error:
        raise InputError(error.reason, file=results, key="RESULTS") from None
    if missing:
        raise InputError(f"not a bondem results file (missing {', '.join(missing)})",
                         file=results, key="RESULTS")


@click.group(name="export")
def command():
    """Export results to other formats."""


@command.command(name="vtk")
@click.argument("results", type=click.Path(path_type=Path), callback=results_file)
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Output folder (default: 'vtk' next to the results file).")
@click.option("--every", type=click.IntRange(min=1), default=1, show_default=True,
              help="Write every N-th frame only.")
def vtk_command(results, out_dir, every):
    """ParaView files, one set per frame, and a .pvd index with the times: particles
    (points: radius, velocity, speed, angular velocity, force, material, fragment id),
    bonds (intact ones as lines, broken ones as points where they broke: active, break
    mode, force, normal and shear stress) and walls (planes as squares, meshes as
    triangles, moving with the wall: force). See docs/scene.md."""
    from ..io.vtk import export_vtk

    _check_results(results)
    pvd = export_vtk(results, out_dir, every=every)
    click.echo(f"ParaView: {pvd}")


@command.command(name="musen")
@click.argument("results", type=click.Path(path_type=Path), callback=results_file)
@click.option("--out", "out_file", type=click.Path(dir_okay=False, path_type=Path),
              help="Output file: MUSEN text, or a .mdem file when it ends in .mdem "
                   "(default: musen.txt next to the results file).")
@click.option("--every", type=click.IntRange(min=1), default=1, show_default=True,
              help="Write every N-th frame only.")
def musen_command(results, out_file, every):
    """A MUSEN text or .mdem file of the scene and its frames (compounds, interactions, domain,
    spheres with every frame's coordinates, velocities and angular velocities, solid bonds
    with their activity intervals, walls as triangles at t = 0), which MUSEN's GUI and
    cmusen's IMPORT_FROM_TEXT read (docs/musen_migration.md)."""
    from ..io.musen_text import export_musen

    _check_results(results)
    out_file = out_file or results.with_name("musen.txt")
    if out_file.suffix.lower() == ".mdem":
        from ..io.musen_mdem import export_mdem
        path, script, notes = export_mdem(results, out_file, every=every)
        click.echo(f"MUSEN .mdem: {path}")
    else:
        path, script, notes = export_musen(results, out_file, every=every)
        click.echo(f"MUSEN text: {path}")
    click.echo(f"cmusen script: {script}   (cmusen -s={script.name}, run in its folder)")
    for note in notes:
        click.echo(f"note: {note}")


@command.command(name="lammps")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              required=True, help="Output folder for data.lammps, bond_coeffs.lammps and "
                                  "in.lammps.")
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE",
              help="Override a scene value, e.g. --set simulation.end_time=1e-3.")
def lammps_command(scene, out_dir, settings):
    """The scene as a LAMMPS data file and input deck (BPM bonds: bond_style
    bpm/rotational; contacts: pair_style granular hertz/material + Mindlin, Tsuji damping;
    plane walls: fix wall/gran/region), for a cross-check against a second code. Run it
    with `lmp -in in.lammps` in the output folder. The parameter translation and what does
    not carry over: docs/lammps.md."""
    from ..io.lammps import export_lammps
    from ..scene import parse_override

    if not scene.is_file():
        raise InputError("no such file", file=scene, key="SCENE")
    overrides = dict(parse_override(s) for s in settings)
    data, deck, notes = export_lammps(scene, out_dir, overrides or None)
    click.echo(f"LAMMPS data: {data}")
    click.echo(f"LAMMPS input: {deck}   (lmp -in {deck.name}, run in its folder)")
    for note in notes:
        click.echo(f"note: {note}")

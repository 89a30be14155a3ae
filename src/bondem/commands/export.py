"""``bondem export vtk RESULTS.h5``: ParaView files of a results file."""
from pathlib import Path

import click

from ..errors import InputError


@click.group(name="export")
def command():
    """Export results to other formats."""


@command.command(name="vtk")
@click.argument("results", type=click.Path(dir_okay=False, path_type=Path))
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
    from ..io.results import open_results
    from ..io.vtk import export_vtk

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
    pvd = export_vtk(results, out_dir, every=every)
    click.echo(f"ParaView: {pvd}")

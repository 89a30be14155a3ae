"""``bondem report RESULTS.h5 [--out report.html] [--frames 0,-1]``: one self-contained
HTML report (figures inlined) of a run."""
from pathlib import Path

import click

from . import results_file

from .analyze import check_frames, parse_frames


@click.command("report")
@click.argument("results", type=click.Path(path_type=Path), callback=results_file)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="HTML file to write [default: RESULTS_report.html next to the file].")
@click.option("--frames", default="0,-1", show_default=True,
              help="Frames for the picture of the body, comma-separated (negative: from "
                   "the end).")
def command(results, out, frames):
    """Write a self-contained HTML report of RESULTS.h5."""
    from ..analysis.report import write_report
    from ..analysis.results import Results

    frame_list = parse_frames(frames)
    with Results(results) as opened:
        check_frames(opened, frame_list, results)
    written, _ = write_report(results, out, frame_list)
    click.echo(f"report -> {written}")

"""``bondem report RESULTS.h5 [--out report.html] [--frames 0,-1]``: one self-contained
HTML report (figures inlined) of a run, or of a ``bondem lab envelope`` folder."""
from pathlib import Path

import click

from . import results_file

from .analyze import check_frames, parse_frames


def _results_or_envelope(ctx, param, value):
    """A results file, a run's folder, or a folder holding a lab envelope (envelope.json)."""
    path = Path(value)
    if path.is_dir() and not (path / "results.h5").is_file() and \
            (path / "envelope.json").is_file():
        return path
    return results_file(ctx, param, value)


@click.command("report")
@click.argument("results", type=click.Path(path_type=Path), callback=_results_or_envelope)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="HTML file to write [default: RESULTS_report.html next to the file].")
@click.option("--frames", default="0,-1", show_default=True,
              help="Frames for the picture of the body, comma-separated (negative: from "
                   "the end).")
def command(results, out, frames):
    """Write a self-contained HTML report of RESULTS.h5 (or of the folder of a ``bondem
    lab envelope``: the fit, its tests and the Mohr circles)."""
    from ..analysis.report import write_envelope_report, write_report
    from ..analysis.results import Results

    if results.is_dir():
        click.echo(f"report -> {write_envelope_report(results, out)}")
        return
    frame_list = parse_frames(frames)
    with Results(results) as opened:
        check_frames(opened, frame_list, results)
    written, _ = write_report(results, out, frame_list)
    click.echo(f"report -> {written}")

"""``bondem analyze RESULTS.h5 [--out DIR] [--json]``: key numbers of a run (a table, or
JSON with --json), figures (PNG + PDF), the time series as CSV and the numbers as JSON."""
import json
from pathlib import Path

import click

from . import results_file
from ..errors import InputError


@click.command("analyze")
@click.argument("results", type=click.Path(path_type=Path), callback=results_file)
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Folder for figures, timeseries.csv and summary.json "
                   "[default: RESULTS_analysis next to the file].")
@click.option("--json", "as_json", is_flag=True, help="Print the key numbers as JSON.")
@click.option("--frames", default="0,-1", show_default=True,
              help="Frames for the picture of the body, comma-separated (negative: from "
                   "the end).")
def command(results, out_dir, as_json, frames):
    """Fragments, broken bonds, energy balance and wall force of RESULTS.h5."""
    from ..analysis.figures import build_figures, save_figures
    from ..analysis.results import Results
    from ..analysis.summary import (analyze, format_number, key_numbers, time_series,
                                    write_table)

    frame_list = parse_frames(frames)
    out_dir = results.with_name(results.stem + "_analysis") if out_dir is None else out_dir
    with Results(results) as opened:
        check_frames(opened, frame_list, results)
        data = analyze(opened)
        numbers = key_numbers(opened, data)
        figures = build_figures(opened, frame_list, data=data)
    written = save_figures(figures, out_dir)
    write_table(time_series(data), out_dir / "timeseries.csv")
    (out_dir / "summary.json").write_text(json.dumps(numbers, indent=2) + "\n")
    if as_json:
        click.echo(json.dumps(numbers, indent=2))
        return
    width = max(len(k) for k in numbers)
    for key, value in numbers.items():
        shown = format_number(key, value)
        click.echo(f"{key.replace('_', ' '):<{width}}  {shown}")
    click.echo(f"figures ({len(written)}), timeseries.csv, summary.json -> {out_dir}")


def parse_frames(text):
    """'0,-1' -> [0, -1]; InputError naming --frames otherwise."""
    try:
        frames = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise InputError(f"{text!r} is not a comma-separated list of integers",
                         key="--frames") from None
    if not frames:
        raise InputError("expected at least one frame index", key="--frames")
    return frames


def check_frames(results, frames, path):
    """InputError unless every frame index exists among the complete frames."""
    for frame in frames:
        try:
            results.frame_index(frame)
        except IndexError:
            raise InputError(f"frame {frame} is outside [-{results.n_frames}, "
                             f"{results.n_frames - 1}] ({results.n_frames} complete frames)",
                             file=str(path), key="--frames") from None

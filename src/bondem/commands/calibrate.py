"""``bondem calibrate CALIB.toml``: find bond parameters that give the measured macro
properties (docs/calibration.md); resumable, on Dask."""
import sys
from pathlib import Path

import click

from .run import _folder


@click.command(name="calibrate")
@click.argument("calibration", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", callback=_folder,
              help="Output folder (default: next to the file, named after it).")
@click.option("--scheduler", default=None,
              help="Dask scheduler address (tcp://host:8786), or 'serial' for this process "
                   "[default: a LocalCluster of --workers processes].")
@click.option("--workers", type=click.IntRange(min=1), help="LocalCluster processes.")
@click.option("--resume", is_flag=True, help="Continue the table in the output folder.")
@click.option("--overwrite", is_flag=True, help="Start afresh over an earlier table.")
def command(calibration, out_dir, scheduler, workers, resume, overwrite):
    """Calibrate the parameters of CALIBRATION (TOML: spec, parameters, targets, budget)."""
    from ..analysis.calibration import percent
    from ..calibrate import CalibrationFailed, load_calibration, run_calibration
    from tqdm import tqdm

    loaded = load_calibration(calibration)
    for message in loaded.warnings:
        click.echo(f"bondem: warning: {message}", err=True)
    out_dir = out_dir or calibration.with_name(calibration.stem)
    if overwrite and (out_dir / "calibration.csv").exists():
        (out_dir / "calibration.csv").unlink()
    bar = tqdm(total=loaded.budget, unit="trial", desc="bondem calibrate")

    def progress(done, total, value):
        bar.n = done
        bar.set_postfix_str(f"misfit {value:.3g}")
        bar.refresh()

    def stage(text):
        bar.set_postfix_str(text)
        bar.refresh()

    try:
        summary = run_calibration(loaded, out_dir, scheduler=scheduler, workers=workers,
                                  resume=resume, progress=progress, stage=stage)
    except CalibrationFailed as error:
        bar.close()
        click.echo(f"bondem: calibration failed: {error} (table: "
                   f"{out_dir / 'calibration.csv'})", err=True)
        sys.exit(1)
    bar.close()
    best = summary["best"]
    click.echo(f"best of {summary['trials']} trials (trial {best['trial']}, misfit "
               f"{best['misfit']:.3g}); {len(summary['consistent'])} sets meet every target")
    for key, value in best["parameters"].items():
        click.echo(f"  {key} = {value:.5g}   ({summary['identifiability'][key]['verdict']})")
    for name, value in best["predictions"].items():
        target = summary["targets"][name]
        click.echo(f"  {name}: {value:.4g} (target {target['value']:.4g} "
                   f"+-{percent(target['tolerance'])})")
    for message in summary["warnings"][len(loaded.warnings):]:
        click.echo(f"bondem: warning: {message}", err=True)
    click.echo(f"table: {out_dir / 'calibration.csv'}; summary: calibration.json; page: "
               f"{out_dir / 'calibration.html'}")

"""``bondem study STUDY.toml [--scheduler ADDRESS] [--workers N] [--resume] [--out DIR]``
runs an ensemble study on Dask; ``bondem study fit TABLE [--plot F]`` fits the Vogel &
Peukert breakage master curve to a finished impact study's table."""
import math
from pathlib import Path

import click
import numpy as np

from ..errors import InputError


class _DefaultRun(click.Group):
    """A group whose default subcommand is ``run``: ``bondem study S.toml`` means
    ``bondem study run S.toml``."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ("-h", "--help"):
            args = ["run", *args]
        return super().parse_args(ctx, args)


@click.group(cls=_DefaultRun)
def command():
    """Ensemble studies on Dask: `bondem study STUDY.toml`, `bondem study fit TABLE`."""


@command.command("run")
@click.argument("study_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Dask scheduler address (default: a local cluster); 'serial' for no Dask.")
@click.option("--workers", type=int, default=None, help="Local worker processes (default: cores).")
@click.option("--resume", is_flag=True, help="Run only the cases missing from the table.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder of table.csv and cases/ (default: next to the study, named after it).")
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def run_command(study_file, scheduler, workers, resume, out_dir, no_progress):
    """Run every case of STUDY_FILE and collect the table."""
    from ..study import load_study, read_table, run_study

    if workers is not None and workers < 1:
        raise InputError(f"--workers = {workers}; expected an integer >= 1", key="--workers")
    study = load_study(study_file)
    path = run_study(study, scheduler=scheduler, workers=workers, resume=resume,
                     out_dir=out_dir, progress=not no_progress)
    rows = read_table(path)
    failed = sum(r["status"] != "ok" for r in rows)
    click.echo(f"{path}: {len(rows)} cases, {failed} failed")


@command.command("fit")
@click.argument("table", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--velocity", default=None, metavar="COLUMN",
              help="Impact velocity column (m/s); W = v^2/2. Default: the column with "
                   "'velocity' in its name.")
@click.option("--energy", default=None, metavar="COLUMN",
              help="Mass-specific energy column (J/kg), instead of --velocity.")
@click.option("--quantity", default="broken_bond_fraction", show_default=True,
              help="Column that says how much a case broke.")
@click.option("--threshold", type=float, default=0.0, show_default=True,
              help="A case counts as broken when the quantity exceeds this "
                   "(for largest_fragment_fraction: when it is below 1 - threshold).")
@click.option("--size", type=float, default=None, help="Particle size x (m), to report f_mat.")
@click.option("--impacts", type=int, default=1, show_default=True, help="Number of impacts k.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the plot (PNG or PDF by suffix).")
def fit_command(table, velocity, energy, quantity, threshold, size, impacts, plot):
    """Fit P = 1 - exp(-f_mat x k (W - W_min)) to the cases of TABLE."""
    from ..impact import fit_master_curve, plot_master_curve
    from ..study import table_columns

    if not table.is_file():
        raise InputError("table not found", file=table)
    columns = table_columns(table)
    if not columns:
        raise InputError("table has no finished case", file=table)
    ok = columns["status"] == "ok"
    energy_values, outcome = broken_outcome(columns, table, velocity, energy, quantity, threshold)
    energy_values, outcome = energy_values[ok], outcome[ok]
    if size is not None and not (size > 0 and math.isfinite(size)):
        raise InputError(f"--size = {size}; expected a positive length in m", key="--size")
    try:
        fit = fit_master_curve(energy_values, outcome, size=size, impacts=impacts)
    except ValueError as error:
        raise InputError(str(error), file=table) from None
    click.echo(f"cases: {fit.cases}, broken: {int(outcome.sum())}")
    click.echo(f"f_mat x k = {fit.rate:.6g} +- {fit.rate_error:.2g} kg/J")
    click.echo(f"W_m,min   = {fit.minimum_energy:.6g} +- {fit.minimum_energy_error:.2g} J/kg")
    if size is not None:
        click.echo(f"f_mat     = {fit.f_mat:.6g} kg/(J m)  (x = {size:g} m, k = {impacts})")
    if plot is not None:
        plot_master_curve(energy_values, outcome, fit, plot,
                          bins=None if np.unique(energy_values).size <= 30 else 15)
        click.echo(f"plot: {plot}")


def broken_outcome(columns, table, velocity, energy, quantity, threshold):
    """(specific energy J/kg, 0/1 broken) arrays from table columns."""
    if velocity is not None and energy is not None:
        raise InputError("give --velocity or --energy, not both", key="--energy")
    if energy is None and velocity is None:
        guesses = [c for c in columns if "velocity" in c]
        if len(guesses) != 1:
            raise InputError(f"no single velocity column among {list(columns)}; name it with "
                             "--velocity or --energy", file=table, key="--velocity")
        velocity = guesses[0]
    name = energy if energy is not None else velocity
    for column, option in ((name, "--energy" if energy else "--velocity"),
                           (quantity, "--quantity")):
        if column not in columns or columns[column].dtype != np.float64:
            raise InputError(f"{column!r} is not a numeric column; columns: {list(columns)}",
                             file=table, key=option)
    x = columns[name]
    values = columns[quantity]
    specific_energy = x if energy is not None else 0.5 * x ** 2
    if quantity == "largest_fragment_fraction":
        outcome = values < 1.0 - max(threshold, 1e-9)  # a mass sum may round to 1 - eps
    else:
        outcome = values > threshold
    return specific_energy, outcome.astype(np.float64)

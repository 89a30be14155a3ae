"""``bondem lab TEST SPEC.toml``: one laboratory test (ucs, triaxial, brazilian, tension,
agglomerate) of the specimen in SPEC (docs/lab.md); writes lab.csv, lab.json, the figures
and results.h5 into the output folder and prints the numbers."""
from pathlib import Path

import click

from .run import _folder

TESTS = ("ucs", "triaxial", "brazilian", "tension", "agglomerate", "envelope")
SHOWN = ("n_particles", "n_bonds", "ucs", "tensile_strength", "peak_deviator_stress",
         "breakage_force", "young_modulus_secant", "young_modulus_tangent", "poisson_ratio",
         "strain_at_peak", "crack_initiation_stress", "confining_stress_error",
         "crack_damage_stress", "platen_force_mismatch", "kinetic_energy_ratio",
         "broken_bonds_final", "fragments", "fragments_multi", "breakage_energy",
         "applied_energy", "fragment_size_d50", "loose_particles", "ae_events", "b_value",
         "steps", "wall_time")

# Why a number can be missing (NaN) from a test's results, as the command line says it.
NOT_FOUND = {
    "crack_initiation_stress": "no bond broke before the peak stress",
    "young_modulus_secant": "the loading curve never reached half its peak stress",
    "young_modulus_tangent": "too few samples around half the peak stress",
    "poisson_ratio": "the loading curve never reached half its peak stress",
    "platen_force_mismatch": "the platens pressed no force at the peak",
    "kinetic_energy_ratio": "no elastic energy was stored",
    "crack_damage_stress": "the volumetric strain did not turn to dilatancy before the peak",
    "b_value": "fewer than 10 AE events, or all of one magnitude",
}


@click.command(name="lab")
@click.argument("test", type=click.Choice(TESTS))
@click.argument("spec", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", callback=_folder,
              help="Output folder (default: next to SPEC, named SPEC_TEST).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a spec value, e.g. --set test.strain_rate=5 (repeatable).")
@click.option("--overwrite", is_flag=True, help="Replace an earlier test's files there.")
@click.option("--confining", "pressures", multiple=True, type=float, metavar="PA",
              help="envelope: a confining stress (Pa) of one of its triaxial tests "
                   "(repeat, at least two).")
@click.option("--scheduler", default=None,
              help="envelope: Dask scheduler address (tcp://host:8786), or 'serial' for this "
                   "process (default: a local cluster).")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="envelope, --seed: processes of the local cluster (default: one per "
                   "run, at most the cores).")
@click.option("--seed", "seeds", multiple=True, type=click.IntRange(min=0), metavar="N",
              help="Run the test on the specimen made with each seed (repeat): a series "
                   "with the mean and scatter of its numbers, on Dask like the envelope.")
def command(test, spec, out_dir, overrides, overwrite, pressures, scheduler, workers,
            seeds):
    """Run laboratory TEST on the specimen of SPEC (TOML: [specimen] and [test]).
    ``envelope`` runs triaxial tests at each --confining stress and fits the
    Mohr-Coulomb envelope through their peaks."""
    from ..errors import InputError
    from ..lab import RUNNERS
    from ..lab.procedures import STRENGTHS
    from ..lab.spec import load_spec
    from ..scene import parse_override

    changes = dict(parse_override(text) for text in overrides)
    out_dir = out_dir or spec.with_name(f"{spec.stem}_{test}")
    if test == "envelope":
        return _envelope(spec, out_dir, changes, overwrite, pressures, scheduler, workers)
    if seeds:
        return _series(test, spec, out_dir, changes, overwrite, seeds, scheduler, workers)
    if (out_dir / "lab.json").exists() and not overwrite:
        raise InputError("holds the files of an earlier test; give --overwrite to replace "
                         "them or --out for another folder", file=out_dir, key="--out")
    specimen, settings, text = load_spec(spec, changes or None)
    if test == "triaxial" and settings.confining_stress is None:
        raise InputError("a triaxial test needs test.confining_stress (Pa)", file=spec,
                         key="test.confining_stress")
    if test == "triaxial" and specimen.shape not in ("box", "cylinder"):
        raise InputError(f"a triaxial test needs a cylinder (in a membrane) or a box (plane "
                         f"lateral walls); this one is a {specimen.shape}", file=spec,
                         key="specimen.shape")
    click.echo(f"bondem lab {test}: {specimen.n_particles} particles, {specimen.n_bonds} "
               f"bonds ({'; '.join(specimen.notes)})")
    for name in ("results.h5", "lab.json"):
        (out_dir / name).unlink(missing_ok=True)
    result = RUNNERS[test](specimen, settings, out_dir=out_dir, scene_text=text)
    paths = result.write(out_dir)
    for key in SHOWN:
        if key in result.numbers:
            value = result.numbers[key]
            unit = result.units.get(key, "")
            if isinstance(value, float) and value != value:   # NaN: say why, not "nan Pa"
                why = (result.no_failure if key in STRENGTHS and result.no_failure else
                       NOT_FOUND.get(key, 'the test did not reach it'))
                click.echo(f"  {key.replace('_', ' ')}: none ({why})")
                continue
            shown = f"{value:.4g}" if isinstance(value, float) else str(value)
            click.echo(f"  {key.replace('_', ' ')}: {shown}"
                       + (f" {unit}" if unit not in ("", "1") else ""))
    click.echo(f"  ({result.notes[-1]})")
    tables = [p.name for k, p in paths.items() if k.endswith("_csv")]
    click.echo(f"table:   {paths['csv']}  and {', '.join([paths['json'].name, *tables])}")
    figures = [p.name for k, p in paths.items() if k not in ("csv", "json")
               and not k.endswith("_csv")]
    click.echo(f"figures: {', '.join(figures)}")
    click.echo(f"next: bondem report {out_dir / 'results.h5'}")


def _envelope(spec, out_dir, changes, overwrite, pressures, scheduler, workers):
    """``bondem lab envelope``: the triaxial tests and the Mohr-Coulomb fit."""
    from ..errors import InputError
    from ..lab.envelope import run_envelope, write_envelope
    from ..lab.spec import load_spec
    if len(set(pressures)) < 2 or min(pressures) <= 0.0:
        raise InputError(f"value {list(pressures)!r}: give at least two different confining "
                         f"stresses > 0 Pa (--confining 1e5 --confining 3e5 ...)",
                         key="--confining")
    if (out_dir / "envelope.json").exists() and not overwrite:
        raise InputError("holds an earlier envelope; give --overwrite to replace it or "
                         "--out for another folder", file=out_dir, key="--out")
    specimen, _, _ = load_spec(spec, {**changes, "test.confining_stress": pressures[0]})
    if specimen.shape not in ("box", "cylinder"):
        raise InputError(f"a triaxial test needs a cylinder (in a membrane) or a box; this "
                         f"one is a {specimen.shape}", file=spec, key="specimen.shape")
    click.echo(f"bondem lab envelope: {len(pressures)} triaxial tests of "
               f"{specimen.n_particles} particles, {specimen.n_bonds} bonds")
    try:
        summary = run_envelope(spec, pressures, overrides=changes or None,
                               scheduler=scheduler if scheduler is not None else None,
                               workers=workers)
    except ValueError as error:
        raise InputError(str(error), file=spec) from None
    for t in summary["tests"]:
        state = (f"peak sigma_1 {t['peak_stress']:.4g} Pa" if not t["no_failure"] else
                 f"no failure ({t['no_failure']})")
        click.echo(f"  sigma_3 {t['confining_stress']:.4g} Pa: {state}")
    fit = summary["fit"]
    if fit["friction_angle"] == fit["friction_angle"]:
        click.echo(f"  cohesion: {fit['cohesion']:.4g} Pa")
        click.echo(f"  friction angle: {fit['friction_angle']:.4g} degrees")
    else:
        click.echo(f"  no Mohr-Coulomb line: the peaks' sigma_1 rises by {fit['slope']:.3g} "
                   f"times sigma_3, less than 1 (no friction)")
    click.echo(f"  R^2 of the line through the peaks: {fit['r_squared']:.4f}")
    paths = write_envelope(summary, out_dir)
    click.echo(f"table:   {paths['csv']}  and {paths['json'].name}")
    click.echo(f"figure:  {paths['figure'].name}")
    click.echo(f"next: bondem report {out_dir}")


def _series(test, spec, out_dir, changes, overwrite, seeds, scheduler, workers):
    """``bondem lab TEST SPEC --seed 1 --seed 2 ...``: the test on each seed's specimen."""
    from ..errors import InputError
    from ..lab.series import run_series, write_series
    from ..lab.spec import load_spec
    if len(set(seeds)) < 2:
        raise InputError(f"value {list(seeds)!r}: give at least two different seeds",
                         key="--seed")
    out_dir = out_dir.with_name(out_dir.name + "_series") if out_dir == spec.with_name(
        f"{spec.stem}_{test}") else out_dir
    if (out_dir / "series.json").exists() and not overwrite:
        raise InputError("holds an earlier series; give --overwrite to replace it or --out "
                         "for another folder", file=out_dir, key="--out")
    load_spec(spec, {**changes, "specimen.seed": seeds[0]})   # bad input: before the runs
    click.echo(f"bondem lab {test}: {len(seeds)} specimens (seeds "
               f"{', '.join(str(s) for s in seeds)})")
    series = run_series(spec, test, seeds, overrides=changes or None, scheduler=scheduler,
                        workers=workers)
    for r in series["runs"]:
        if r["no_failure"]:
            click.echo(f"  seed {r['seed']}: no strength ({r['no_failure']})")
    from ..lab.procedures import UNITS
    for name, values in series["summary"].items():
        unit = UNITS.get(name, "")
        unit = "" if unit in ("", "1") else f" {unit}"
        spread = (f" +- {values['std']:.3g}{unit} (cv {100 * values['cv']:.3g} %)"
                  if values["std"] == values["std"] else "")
        click.echo(f"  {name.replace('_', ' ')}: {values['mean']:.4g}{unit}{spread} "
                   f"over {values['count']}")
    paths = write_series(series, out_dir)
    click.echo(f"table:   {paths['csv']}  and {paths['json'].name}")
    if "figure" in paths:
        click.echo(f"figure:  {paths['figure'].name}")

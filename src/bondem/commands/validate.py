"""``bondem validate``: run the validation suite and print the table (issue 7).

Exit status 0 when every row passes (skipped rows do not fail), 1 when any fails, 2 on
bad arguments.
"""
import time

import click

from ..errors import InputError


@click.command("validate")
@click.option("--quick", is_flag=True, help="Only the quick subset (the one CI runs).")
@click.option("--compat", type=click.Choice(["musen"]), default=None,
              help="Reproduce MUSEN's numerical choices where they differ from bondem's "
                   "(docs/musen_compat.md).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Write validation.csv, validation.md and plots (PNG) here.")
@click.option("--case", "cases", multiple=True, metavar="NAME",
              help="Run only this case (repeatable): two_particle, cantilever, wave, "
                   "strength, rotation, contact, refdata.")
def command(quick, compat, out_dir, cases):
    """Run the validation suite against theory and reference data."""
    from ..validation import load_cases, run_suite, table_lines
    known = load_cases()
    unknown = [c for c in cases if c not in known]
    if unknown:
        raise InputError(f"unknown case {unknown[0]!r}; allowed: " + ", ".join(known),
                         key="--case")
    start = time.perf_counter()
    rows = run_suite(quick=quick, compat=compat, out_dir=out_dir, cases=list(cases) or None,
                     progress=lambda name, s: click.echo(f"{name}: {s:.1f} s", err=True))
    for line in table_lines(rows):
        click.echo(line)
    failed = [r for r in rows if r.passed is False]
    click.echo(f"\n{len(rows)} rows: {sum(r.passed is True for r in rows)} passed, "
               f"{len(failed)} failed, {sum(r.passed is None for r in rows)} skipped/info "
               f"({time.perf_counter() - start:.1f} s"
               + (", MUSEN-compatible" if compat else "") + ")")
    if not compat and any(r.passed is None and _musen_row(r) for r in rows):
        click.echo("info rows beside runs of the real MUSEN: bondem's SPEC mode differs from "
                   "MUSEN by design (docs/musen_compat.md lists where and why); "
                   "'bondem validate --compat musen' reproduces MUSEN and checks those rows "
                   "to round-off")
    if out_dir:
        click.echo(f"report: {out_dir}/validation.md")
    if failed:
        raise SystemExit(1)


def _musen_row(row):
    """True for a row that compares against a run of the real MUSEN."""
    return row.case == "musen" or row.case.startswith("refdata:")

"""Validation machinery: rows, the case registry, parameters from TOML, the suite runner,
and the table / plot writers.

A case is a function ``run(parameters, compat, quick=False) -> CaseResult`` registered with
``@case(name, quick=...)``. ``parameters`` is the case's TOML file under
``bondem/data/validation/NAME.toml`` (a small scene: particles, materials, loads, run
settings and tolerances); ``compat`` is None (follow the SPEC) or "musen". A case returns
rows (one per compared quantity) and the data for its plot.
"""
from __future__ import annotations

import csv
import importlib
import math
import time
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

COMPAT_CHOICES = (None, "musen")


@dataclass
class Row:
    """One compared quantity.

    reference and bondem: numbers (SI units, the unit in ``quantity``) or strings (e.g.
    a break mode); error: relative error (bondem - reference) / |reference| for numbers,
    None for strings; tolerance: the allowed |error| (None for exact string match);
    passed: True, False, or None when the row is skipped or informational (``note``
    says why).
    """
    case: str
    quantity: str
    reference: object
    bondem: object
    error: float | None
    tolerance: float | None
    passed: bool | None
    note: str = ""

    @property
    def status(self) -> str:
        return {True: "pass", False: "FAIL", None: "skip" if not self.note.startswith("info")
                else "info"}[self.passed]


def compare(case, quantity, reference, value, tolerance, *, absolute=False, note=""):
    """A numeric row: relative error (or absolute when ``absolute``) within tolerance."""
    reference = float(reference)
    value = float(value)
    if absolute:
        error = value - reference
    else:
        error = (value - reference) / abs(reference) if reference != 0.0 else math.inf
    passed = bool(math.isfinite(error) and abs(error) <= tolerance)
    return Row(case, quantity, reference, value, error, tolerance, passed, note)


def compare_exact(case, quantity, reference, value, note=""):
    """A row for a label (a break mode, a count): passes when equal."""
    return Row(case, quantity, reference, value, None, None, reference == value, note)


def skipped(case, quantity, reason):
    """A row for a case that could not run here (missing optional module, no data)."""
    return Row(case, quantity, "", f"skipped: {reason}", None, None, None, reason)


def info(case, quantity, reference, value, note, *, absolute=False):
    """An informational comparison: shown with its error, never a failure."""
    reference = float(reference)
    value = float(value)
    if absolute:
        error = value - reference
    else:
        error = (value - reference) / abs(reference) if reference else math.inf
    return Row(case, quantity, reference, value, error, None, None, f"info: {note}")


@dataclass
class Series:
    """One curve or set of points of a plot (x, y in the plot's units)."""
    label: str
    x: list
    y: list
    style: str = "o"


@dataclass
class Plot:
    """Data for one figure: axis labels, log scales, and series."""
    title: str
    xlabel: str
    ylabel: str
    series: list = field(default_factory=list)
    logx: bool = False
    logy: bool = False


@dataclass
class CaseResult:
    """What a case returns: its rows and zero or more plots."""
    rows: list
    plots: list = field(default_factory=list)


@dataclass(frozen=True)
class Case:
    """A registered validation case."""
    name: str
    function: object
    quick: bool
    description: str


CASES: dict = {}
_MODULES = ("two_particle", "cantilever", "wave", "strength", "bond_models", "rotation",
            "contact", "adhesion", "clumps", "fields",
            "refdata", "musen_run")


def case(name, *, quick):
    """Register ``function(parameters, compat, quick=False) -> CaseResult`` as case ``name``;
    ``quick``: part of the ``--quick`` subset that runs in CI."""
    def register(function):
        doc = (function.__doc__ or "").strip().splitlines()
        CASES[name] = Case(name, function, quick, doc[0] if doc else name)
        return function
    return register


def load_cases():
    """Import every case module so that the registry is complete; return CASES."""
    for module in _MODULES:
        importlib.import_module(f"bondem.validation.{module}")
    return CASES


def load_parameters(name):
    """The parameters of case ``name`` from ``bondem/data/validation/NAME.toml``."""
    path = resources.files("bondem") / "data" / "validation" / f"{name}.toml"
    with path.open("rb") as handle:
        return tomllib.load(handle)


def run_suite(quick=False, compat=None, out_dir=None, cases=None, progress=None):
    """Run the validation cases and return their rows (list of Row).

    quick: only the cases flagged quick (the CI subset); compat: None (SPEC) or "musen"
    (Simulation(musen_compat=True)); out_dir: where to write validation.csv,
    validation.md and one PNG per plot (nothing written when None); cases: names to run
    (default all, or all quick ones); progress(name, seconds): called after each case.
    Raises ValueError for an unknown case or compat.
    """
    if compat not in COMPAT_CHOICES:
        raise ValueError(f"compat = {compat!r}; allowed: None or 'musen'")
    registry = load_cases()
    if cases:
        unknown = [c for c in cases if c not in registry]
        if unknown:
            raise ValueError(f"unknown validation case(s) {', '.join(unknown)}; known: "
                             + ", ".join(registry))
        selected = [registry[c] for c in cases]
    else:
        selected = [c for c in registry.values() if c.quick or not quick]
    rows, plots, timings = [], [], {}
    for entry in selected:
        parameters = load_parameters(entry.name)
        start = time.perf_counter()
        result = entry.function(parameters, compat, quick=quick)
        timings[entry.name] = time.perf_counter() - start
        rows.extend(result.rows)
        plots.extend((entry.name, p) for p in result.plots)
        if progress is not None:
            progress(entry.name, timings[entry.name])
    if out_dir is not None:
        write_outputs(rows, plots, Path(out_dir), compat, timings)
    return rows


def _fmt(value):
    if value is None or value == "":
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def table_lines(rows, markdown=False):
    """The table as text lines (fixed-width, or Markdown with ``markdown``)."""
    header = ["case", "quantity", "reference", "bondem", "error", "tolerance", "pass"]
    body = [[r.case, r.quantity, _fmt(r.reference), _fmt(r.bondem),
             "" if r.error is None else f"{r.error:.2e}",
             "" if r.tolerance is None else f"{r.tolerance:.1e}", r.status] for r in rows]
    if markdown:
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        # A "|" inside a cell (e.g. |F_t|) would split the Markdown cell.
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"
                  for cells in body]
        return lines
    widths = [max(len(h), *(len(b[k]) for b in body)) if body else len(h)
              for k, h in enumerate(header)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return [fmt.format(*header), fmt.format(*("-" * w for w in widths))] + \
        [fmt.format(*cells) for cells in body]


def write_outputs(rows, plots, out_dir, compat=None, timings=None):
    """Write validation.csv, validation.md and the plots (PNG, matplotlib Agg)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    with open(out_dir / "validation.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["case", "quantity", "reference", "bondem", "error", "tolerance",
                         "pass", "note"])
        for r in rows:
            writer.writerow([r.case, r.quantity, r.reference, r.bondem,
                             "" if r.error is None else repr(r.error),
                             "" if r.tolerance is None else repr(r.tolerance), r.status,
                             r.note])
    names = []
    if plots:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        for k, (name, plot) in enumerate(plots):
            fig, ax = plt.subplots(figsize=(6, 4))
            for s in plot.series:
                ax.plot(s.x, s.y, s.style, label=s.label)
            ax.set_title(plot.title)
            ax.set_xlabel(plot.xlabel)
            ax.set_ylabel(plot.ylabel)
            if plot.logx:
                ax.set_xscale("log")
            if plot.logy:
                ax.set_yscale("log")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
            fig.tight_layout()
            filename = f"{name}_{k}.png"
            fig.savefig(out_dir / filename, dpi=100)
            plt.close(fig)
            names.append((plot.title, filename))
    failed = sum(r.passed is False for r in rows)
    lines = ["# bondem validation", "",
             f"Mode: {'MUSEN-compatible' if compat == 'musen' else 'SPEC'}; "
             f"{len(rows)} rows, {failed} failed.", ""]
    lines += table_lines(rows, markdown=True)
    notes = [f"- {r.case} / {r.quantity}: {r.note}" for r in rows if r.note]
    if notes:
        lines += ["", "Notes:", ""] + notes
    if timings:
        lines += ["", "Run time per case (s): "
                  + ", ".join(f"{k} {v:.1f}" for k, v in timings.items())]
    for title, filename in names:
        lines += ["", f"![{title}]({filename})"]
    (out_dir / "validation.md").write_text("\n".join(lines) + "\n")

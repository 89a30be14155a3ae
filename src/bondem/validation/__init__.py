"""``bondem validate``: the model against closed-form solutions and reference runs.

Each case family lives in its own module (two_particle, cantilever, wave, strength,
contact, refdata) and is described by a small TOML scene in
``bondem/data/validation/``. ``run_suite`` runs them and writes the table (CSV and
Markdown) and plots. See docs/validation.md.
"""
from .core import (CASES, Case, CaseResult, Plot, Row, Series, compare, compare_exact,
                   load_cases, load_parameters, run_suite, table_lines, write_outputs)

__all__ = ["CASES", "Case", "CaseResult", "Plot", "Row", "Series", "compare",
           "compare_exact", "load_cases", "load_parameters", "run_suite", "table_lines",
           "write_outputs"]

"""Command line: ``bondem COMMAND``. Thin: each command lives in ``bondem.commands.NAME``
(a click command called ``command``), parses its arguments, calls the library, prints.

Exit status 0 on success, 2 on bad input with one line naming file and key (SPEC 5).
"""
import importlib
import sys

import click

from .errors import InputError

COMMANDS = {
    "run": "Run a scene and write results.h5 (docs/scene.md).",
    "info": "Counts, masses, stable time step and memory estimate of a scene.",
    "demo": "Built-in demo: an agglomerate breaking on a wall.",
    "export": "Export results to other formats (ParaView VTK).",
    "generate": "Generate a packing and its bonds as particles.csv and bonds.csv.",
    "analyze": "Fragments, broken bonds, energy and force curves of a results file.",
    "report": "A self-contained HTML report of a results file.",
    "validate": "Run the validation suite against theory and reference data.",
    "bench": "Benchmarks: particle-steps/s and bond-updates/s on the bench scenes.",
    "study": "Run an ensemble study (parameter sweep) on Dask.",
}


class LazyGroup(click.Group):
    """Imports a command's module only when that command runs or help lists it."""

    def list_commands(self, ctx):
        return [name for name in COMMANDS if self._load(name) is not None]

    def get_command(self, ctx, name):
        return self._load(name)

    @staticmethod
    def _load(name):
        if name not in COMMANDS:
            return None
        try:
            module = importlib.import_module(f"bondem.commands.{name}")
        except ModuleNotFoundError as error:
            if error.name == f"bondem.commands.{name}":
                return None
            raise
        return module.command

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except InputError as error:
            click.echo(f"bondem: error: {error}", err=True)
            sys.exit(2)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="bondem")
def main():
    """bondem: DEM of bonded particles (elastic solid bond, Hertz-Mindlin contacts)."""

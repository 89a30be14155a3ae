"""Command line: ``bondem COMMAND``. Thin: each command lives in ``bondem.commands.NAME``
(a click command called ``command``), parses its arguments, calls the library, prints.

Exit status 0 on success, 2 on bad input with one line naming file and key (SPEC 5).
"""
import importlib
import os
import sys

import click

from .errors import InputError

COMMANDS = {
    "run": "Run a scene and write results.h5 (docs/scene.md).",
    "info": "Counts, masses, stable time step and memory estimate of a scene.",
    "demo": "Built-in demo: an agglomerate breaking on a wall.",
    "export": "Export results to other formats (ParaView VTK, MUSEN text).",
    "import": "Import a scene of another code (MUSEN's text format).",
    "generate": "Generate a packing and its bonds as particles.csv and bonds.csv.",
    "analyze": "Fragments, broken bonds, energy and force curves of a results file.",
    "report": "A self-contained HTML report of a results file.",
    "validate": "Run the validation suite against theory and reference data.",
    "bench": "Benchmarks: particle-steps/s and bond-updates/s on the bench scenes.",
    "study": "Run an ensemble study (parameter sweep) on Dask.",
    "calibrate": "Calibrate bond parameters to measured macro properties (optuna, Dask).",
    "lab": "Laboratory tests of a bonded specimen: UCS, triaxial, Brazilian, tension, "
           "agglomerate.",
}


# Commands whose module has another name ("import" is a Python keyword).
MODULES = {"import": "importer"}


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
        module_name = f"bondem.commands.{MODULES.get(name, name)}"
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name == module_name:
                return None
            raise
        return module.command

    def invoke(self, ctx):
        argv = [*getattr(ctx, "_protected_args", ()), *ctx.args]
        try:
            return super().invoke(ctx)
        except InputError as error:
            click.echo(f"bondem: error: {error}", err=True)
            sys.exit(2)
        except BrokenPipeError:
            _quiet_broken_pipe()
        except OSError as error:
            # a file that opened but cannot be read (damaged HDF5 data), or cannot be
            # written: named by the error, else the command's first argument that is a file
            where = error.filename or next((a for a in argv if os.path.isfile(a)), None)
            reason = error.strerror or str(error)
            click.echo(f"bondem: error: {where}: {reason}" if where else
                       f"bondem: error: {reason}", err=True)
            sys.exit(2)

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True,
             **extra):
        """As click's, but a usage error is one line (SPEC 5), like every other input
        error: 'bondem: error: bondem run: Missing argument 'SCENE' (bondem run --help)'."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode, **extra)
        try:
            result = super().main(args, prog_name, complete_var, standalone_mode=False,
                                  **extra)
            sys.stdout.flush()    # here, so that a reader that went away is caught below
        except BrokenPipeError:
            _quiet_broken_pipe()
        except click.UsageError as error:
            if type(error).__name__ == "NoArgsIsHelpError":   # bare 'bondem': the help
                click.echo(error.ctx.get_help())
                sys.exit(2)
            where = error.ctx.command_path if error.ctx is not None else "bondem"
            click.echo(f"bondem: error: {where}: {error.format_message()} "
                       f"(see {where} --help)", err=True)
            sys.exit(2)
        except click.ClickException as error:
            error.show()
            sys.exit(error.exit_code)
        except click.exceptions.Abort:
            click.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(result if isinstance(result, int) else 0)


def _quiet_broken_pipe():
    """The reader of our output went away (``bondem analyze ... | head``): that is no
    error to report. Python's own recipe: point stdout at /dev/null so that the flush at
    exit is quiet, and exit 1."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    sys.exit(1)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="bondem")
def main():
    """bondem: DEM of bonded particles (elastic solid bond, Hertz-Mindlin contacts)."""

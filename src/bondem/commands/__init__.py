"""Command-line commands, one module per command (see bondem.cli)."""
from pathlib import Path


def results_file(ctx, param, value):
    """A RESULTS argument: a results file, or a run's folder holding results.h5 (what
    ``bondem run`` printed as its folder); InputError for a folder without one."""
    from ..errors import InputError
    path = Path(value)
    if path.is_dir():
        if (path / "results.h5").is_file():
            return path / "results.h5"
        raise InputError("is a folder without results.h5; give a results file or the "
                         "folder of a run", file=path, key=param.name.upper())
    return path

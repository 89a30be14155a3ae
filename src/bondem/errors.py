"""Errors raised at the edge (scene files, CSV files, command-line arguments)."""


class InputError(ValueError):
    """Bad user input. The message names the file, the key, the bad value and the allowed
    range; the command line prints it on one line and exits with status 2."""

    def __init__(self, message, *, file=None, key=None):
        self.file = file
        self.key = key
        where = ": ".join(str(p) for p in (file, key) if p)
        super().__init__(f"{where}: {message}" if where else message)

"""Errors raised at the edge (scene files, CSV files, command-line arguments)."""


class InputError(ValueError):
    """Bad user input. The message names the file, the key, the bad value and the allowed
    range; the command line prints it on one line and exits with status 2."""

    def __init__(self, message, *, file=None, key=None):
        self.file = file
        self.key = key
        self.reason = message
        where = ": ".join(str(p) for p in (file, key) if p)
        super().__init__(f"{where}: {message}" if where else message)


def unknown_key(name, allowed, what="key"):
    """The message for an unknown key (or column) ``name``: the nearest allowed one when
    there is a close one (a typo), then every allowed one."""
    import difflib
    allowed = [str(a) for a in allowed]
    close = difflib.get_close_matches(str(name), allowed, n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}? " if close else ""
    return f"unknown {what} {str(name)!r}; {hint}allowed: {', '.join(allowed)}"


class BackendUnavailable(InputError, RuntimeError):
    """The requested backend cannot run on this machine (an input error for the command
    line: one line, exit status 2)."""


def decode_text(raw, path):
    """``raw`` bytes of a text file as str; InputError naming the line of the first byte
    that is not UTF-8 (Latin-1, UTF-16 and binary files are refused, not guessed)."""
    try:
        return raw.decode("utf-8-sig")   # a byte-order mark (spreadsheet CSVs) is fine
    except UnicodeDecodeError as error:
        line = raw[:error.start].count(b"\n") + 1
        raise InputError(f"line {line}: byte 0x{raw[error.start]:02x} is not UTF-8 text; "
                         "save the file as UTF-8", file=path) from None

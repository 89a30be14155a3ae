"""Command-line commands, one module per command (see bondem.cli)."""

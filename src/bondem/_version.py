"""bondem's version, in a module of its own so that the results file (io/results.py) can
record it without importing the package's public API above it."""
__version__ = "0.1.0"

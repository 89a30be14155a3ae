"""Analysis of results files (SPEC 6): fragments, broken bonds, energy balance, wall
force curves, figures and an HTML report. Everything reads only complete frames, so it
works on a file that a run is still writing (HDF5 SWMR)."""
from .breakage import broken_bond_fraction, broken_series, first_break_time, radial_breakage
from .energy import energy_balance
from .fragments import (count_distribution, fragment_labels, fragment_series,
                        fragment_sizes, frame_fragments, largest_fragment_fraction,
                        size_distribution, write_fragment_ids)
from .results import Results
from .summary import analyze, key_numbers, summarize, time_series
from .walls import force_mismatch, wall_curve

__all__ = ["Results", "analyze", "broken_bond_fraction", "broken_series",
           "count_distribution", "energy_balance", "first_break_time", "force_mismatch",
           "fragment_labels", "fragment_series", "fragment_sizes", "frame_fragments",
           "key_numbers", "largest_fragment_fraction", "radial_breakage",
           "size_distribution", "summarize", "time_series", "wall_curve",
           "write_fragment_ids"]

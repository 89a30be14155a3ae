"""The virtual laboratory: specimens (``make_specimen``, ``lattice_specimen``,
``specimen_from_scene``) and the tests ``uniaxial``, ``triaxial``, ``brazilian``,
``direct_tension``, ``agglomerate`` with their ``LabSettings``; ``bondem lab TEST spec.toml``
on the command line. Definitions and formulas: docs/lab.md."""
from .procedures import (RUNNERS, TESTS, LabResult, LabSettings, agglomerate, brazilian,
                         direct_tension, triaxial, uniaxial)
from .specimen import (Specimen, consolidate, lattice_specimen, make_specimen,
                       specimen_from_scene)

__all__ = ["RUNNERS", "TESTS", "LabResult", "LabSettings", "Specimen", "agglomerate",
           "brazilian", "consolidate", "direct_tension", "lattice_specimen", "make_specimen",
           "specimen_from_scene", "triaxial", "uniaxial"]

"""The body-force field models: every ``physics/field_<name>.py`` that declares ``NAME``.

Gravity (Model.gravity, m/s^2) is the one field every run has; the others are models. A
field model file declares, besides its ``@physics`` functions:
    NAME      the scene's table ([fluid], [frame]) and the key of Model.fields holding
              its parameter array
    KEYS      its table's keys in the scene schema (type, default, low or choices, high,
              include low, include high): ARRAY's keyword arguments
    ARRAY     name of its function (keywords: KEYS) -> its parameter array (1-D float;
              ValueError names a bad value); called with no arguments, the field off
    INPUTS    names of further Model arrays its FORCE takes after its own ((): none),
              e.g. the fluid's flow grid and per-particle fluid
    FORCE     name of its @physics force (array, *inputs, p, mass, radius, x, v, gravity)
              -> N (3-tuple) on particle p of mass (kg) and radius (m) at x (m) moving at
              v (m/s), gravity (m/s^2)
    MOMENT    optional: name of its @physics moment (array, inertia, w) -> N m on a sphere
              of moment of inertia (kg m^2) spinning at w (rad/s)
    CLUMPS    whether it acts on clumps' members (FORCE only; else a run with clumps and
              the field on is refused)
    active(array) -> whether the field acts: the particle loops call FORCE and MOMENT only
              then (so both must be zero when it is false); energy bookkeeping, results'
              field force
    time_scales(array, mass, radius) -> {name: s}, its limits on the time step
The particle loops add every acting model's FORCE and MOMENT (backends/loops.py), the
scene reads each table, the time step and the results ask every model: a new field is its
file and its test.
"""
import importlib
import pkgutil
from pathlib import Path

import numpy as np

_NAMES = sorted(info.name for info in pkgutil.iter_modules([str(Path(__file__).parent)])
                if info.name.startswith("field_") and info.name != "field_models")
MODELS = [m for m in (importlib.import_module(f"{__package__}.{name}") for name in _NAMES)
          if hasattr(m, "NAME")]
BY_NAME = {m.NAME: m for m in MODELS}
# The arrays the particle loops take (loops.Fields): gravity, the models' switches
# (``switches``), each model's parameter array under its NAME, then the INPUTS of them all.
ARRAYS = ("gravity", "acting", *BY_NAME,
          *dict.fromkeys(i for m in MODELS for i in m.INPUTS))


def array(module, **values):
    """Model ``module``'s parameter array from its table's ``values`` (ARRAY)."""
    return getattr(module, module.ARRAY)(**values)


def defaults():
    """{NAME: parameter array} with every field off."""
    return {m.NAME: array(m) for m in MODELS}


def acting(fields):
    """The NAMEs of the models acting in ``fields`` ({NAME: parameter array})."""
    return [m.NAME for m in MODELS if m.active(fields[m.NAME])]


def switches(fields):
    """uint8 per model of MODELS, 1 where it acts in ``fields`` ({NAME: parameter
    array}): the particle loops evaluate the acting models only."""
    return np.array([m.active(fields[m.NAME]) for m in MODELS], dtype=np.uint8)


def time_scales(fields, mass, radius):
    """{name: s}: every acting model's limits on the time step, for particles of mass
    (N,) kg and radius (N,) m."""
    scales = {}
    for module in MODELS:
        scales.update(module.time_scales(fields[module.NAME], mass, radius))
    return scales

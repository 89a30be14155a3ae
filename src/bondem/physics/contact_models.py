"""The contact models: every ``physics/contact_<name>.py`` that declares ``NAME`` is one.

A contact model file declares, besides its ``@physics`` functions:
    NAME        the value of ``simulation.contact_model`` ("hertz_mindlin", "jkr", ...)
    PARAMETERS  its particle (and wall) material keys: {key: (schema entry as the scene's
                MATERIAL_KEYS: type, default, low, high, include low, include high),
                mixing rule of a pair of materials: "mean" | "geometric")}
    UNITS       {key: unit} for reports
    LAW         name of its loads function, one contact with overlap delta (m; negative
                beyond contact): (n, overlap, v_rel, w_rel, spring, pair, q, r_star,
                m_star, i_star, dt) -> (force on i N, rolling torque on i N m, tangential
                force on i N, new spring m, stored energy J); n: unit normal i -> j;
                v_rel: velocity of j's surface relative to i's (m/s); w_rel = w_i - w_j;
                pair: the pair table (rows: ordered pairs of materials, columns PAIR_*
                of _registry.py and the model's own PARAMETERS from PAIR_MODEL on, in their
                order), q: the contact's row
    REACH       optional: name of (pair, q, r_star) -> m, how far beyond contact (a gap)
                the law acts; 0 without
    CONSTANTS   optional: names of pair-table columns after PARAMETERS' that the model
                derives once per pair of materials (a cosine, a cube root the law would
                otherwise take per contact and step), with ``constants(values)`` -> their
                values from the mixed {key: value} and the pair's E* (Pa) under "e_star"
    HYSTERETIC  with REACH: True when beyond contact only a contact that formed by
                touching acts (JKR's neck, a liquid bridge) until REACH; False when every
                pair within REACH does (van der Waals)
    MUSEN       optional: {"pp": MODEL_PP name, "pw": MODEL_PW name, "parameters":
                {MUSEN parameter word: key}, "properties": {MUSEN material property: key}}
    check(values) -> [(key, message)] of a material used with the model (optional)
The scene schema, the Material fields, the pair tables of both backends' kernels, the
neighbour search's reach and ``bondem import/export musen`` read these, so a new contact
model is its file and its test (the kernels dispatch on ``CODE``, set here).

The stored energy must be a potential of the law's elastic force (its work over a closed
path is zero), so that the loops' work balance books the rest, damping, sliding and an
adhesive snap-in, as dissipated.
"""
import importlib
import math
import pkgutil
from pathlib import Path


_NAMES = sorted(info.name for info in pkgutil.iter_modules([str(Path(__file__).parent)])
                if info.name.startswith("contact_") and info.name != "contact_models")
_FOUND = [importlib.import_module(f"{__package__}.{name}") for name in _NAMES]
# Hertz-Mindlin first: code 0 is the default law the CPU kernels compile alone.
MODELS = sorted((m for m in _FOUND if hasattr(m, "NAME")),
                key=lambda m: (m.NAME != "hertz_mindlin", m.NAME))
for _code, _module in enumerate(MODELS):
    _module.CODE = _code
BY_NAME = {m.NAME: m for m in MODELS}
NAMES = tuple(BY_NAME)


def material_schema():
    """{key: schema entry} of every contact model's material keys (a key that several
    models declare has one entry: they must declare it alike)."""
    schema = {}
    for module in MODELS:
        for key, (entry, _mixing) in module.PARAMETERS.items():
            if schema.setdefault(key, entry) != entry:
                raise RuntimeError(f"contact model {module.NAME!r} declares {key!r} unlike "
                                   "another model")
    return schema


def units():
    """{key: unit} of every contact model's material keys."""
    out = {}
    for module in MODELS:
        out.update(module.UNITS)
    return out


def mix(rule, a, b):
    """The pair value of two materials' values a, b by mixing ``rule``: "mean"
    (a + b)/2, "geometric" sqrt(a b) (Berthelot's rule for adhesion energies)."""
    if rule == "geometric":
        return math.sqrt(a * b)
    return 0.5 * (a + b)


def pair_parameters(module, values_i, values_j, e_star=math.nan):
    """The model's own pair-table columns (from PAIR_MODEL on) for two materials given as
    {key: value} dicts: its PARAMETERS mixed, then its CONSTANTS (from the mixed values and
    the pair's ``e_star``, Pa, under "e_star")."""
    mixed = {key: mix(rule, values_i[key], values_j[key])
             for key, (_entry, rule) in module.PARAMETERS.items()}
    derived = (list(module.constants({**mixed, "e_star": e_star}))
               if getattr(module, "CONSTANTS", ()) else [])
    return list(mixed.values()) + derived


def pair_columns(module):
    """How many pair-table columns the model owns (PARAMETERS and CONSTANTS)."""
    return len(module.PARAMETERS) + len(getattr(module, "CONSTANTS", ()))


def owners(key):
    """The contact models whose PARAMETERS declare ``key``."""
    return [module for module in MODELS if key in module.PARAMETERS]

"""The bond models: every ``physics/bond_<name>.py`` that declares ``NAME`` is one.

A bond model file declares, besides its ``@physics`` functions:
    NAME        the value of a bond material's ``model`` key ("elastic", "kelvin")
    PARAMETERS  its bond material keys beyond the elastic bond's, in the scene schema
                (type, default, low or choices, high, include low, include high)
    UNITS       {key: unit} for reports
    LOADS       name of its loads function, called after the elastic bond's springs have
                been advanced and tested for breakage, (musen, r, length, l0, diameter,
                vi, vj, wi, wj, f_n, f_t, m_n, m_t, k_n, k_t, materials, m) -> (force on
                i, moment on i, moment on j, rate of its per-bond state); None for the
                elastic bond
    STATE       None, or (what its per-bond energy is, the energy term that its sum is:
                an energy loss in J), column 0 of state.extra["bond_model_state"]
    SPRINGS     optional: name of its springs function, for models that change the
                springs themselves (plasticity, creep, damage), called after the elastic
                springs have been advanced and tested, before LOADS: (musen, b, time, dt,
                length, l0, diameter, n, f_n, f_t, m_n, m_t, mode, k_n, k_t, scatter,
                lp, s1, s2, materials, m) -> (f_n, f_t, m_n, m_t, break mode, s1, s2, J
                lost this step); scatter: the bond's strength factor (multiplies its
                strengths); lp: its length in the previous step (m); s1, s2 are its per-bond columns 1 and 2 of the state, the J
                lost are added to column 0
    COLUMNS     with SPRINGS: what columns 1 and 2 hold, e.g. ("plastic strain (-)",)
    ENERGY      optional: name of its normal energy function (length, l0, k_n, s1, s2,
                materials, m) -> J held by the normal spring (default k_n (L - L0)^2 / 2)
    MUSEN       optional: its MUSEN counterpart for io/musen_text.py ({"model": MODEL_SB
                name, "parameters": {MODEL_SB_PARAMS word: key}, "properties": {bond
                material property id: key}, "strengths": whether it reads the strengths;
                optional "import"(words, entry) and "export"(values) -> (words, note) for
                parameters that need more than a renaming)
    VECTORISED  whether the CPU's vectorised elastic block may advance its bonds
    check(values, musen_compat) -> [(key, message)] of a material that uses the model
    time_scales(model, bonds, reduced_mass, musen_compat) -> {name: s}, its bonds' limits
Everything else (bond materials, the scene schema, kernels on both backends, energy terms,
time steps) reads these, so a new bond model is its file and its test.
"""
import importlib
import pkgutil
from pathlib import Path

from . import bond_elastic
from ._registry import REQUIRED  # noqa: F401  (the schema's "no default")

_NAMES = sorted(info.name for info in pkgutil.iter_modules([str(Path(__file__).parent)])
                if info.name.startswith("bond_") and info.name != "bond_models")
MODELS = [bond_elastic] + [m for m in (importlib.import_module(f"{__package__}.{name}")
                                       for name in _NAMES)
                           if hasattr(m, "NAME") and m is not bond_elastic]
for _code, _module in enumerate(MODELS):
    _module.CODE = _code
BY_NAME = {m.NAME: m for m in MODELS}
# Columns of state.extra["bond_model_state"]: the energy (STATE), then SPRINGS' own two.
STATE_COLUMNS = 3


def has_state(module):
    """True when bond model ``module`` keeps a per-bond state (STATE or SPRINGS)."""
    return bool(module.STATE) or bool(getattr(module, "SPRINGS", None))


def bond_material_schema():
    """Every bond material key with its schema entry: the elastic bond's, ``model``, then
    each other model's own PARAMETERS (a key that several models declare, such as the
    plastic bonds' yield_strength, has one entry: they must declare it alike)."""
    schema = dict(bond_elastic.PARAMETERS)
    schema["model"] = ("str", bond_elastic.NAME, tuple(BY_NAME), None, None, None)
    for module in MODELS[1:]:
        for key, entry in module.PARAMETERS.items():
            if schema.setdefault(key, entry) != entry:
                raise RuntimeError(f"bond model {module.NAME!r} declares {key!r} unlike "
                                   f"{' and '.join(m.NAME for m in owners(key))}")
    return schema


def owners(key):
    """The bond models whose PARAMETERS declare ``key`` (none for the shared ones)."""
    return [module for module in MODELS[1:] if key in module.PARAMETERS]


def check(values, musen_compat=False):
    """[(key, message)] of what is wrong with bond material ``values`` (a dict of every
    key): another model's parameter set away from its default, and the model's own
    ``check``."""
    problems = []
    schema = bond_material_schema()
    for key, entry in schema.items():
        models = [m.NAME for m in owners(key)]
        if models and values["model"] not in models and values[key] != entry[1]:
            needs = " or ".join(repr(name) for name in models)
            problems.append((key, f"{key} = {values[key]!r} needs model = {needs} "
                                  f"(model = {values['model']!r} has no such parameter)"))
    problems.extend(bond_elastic.check(values, musen_compat))   # the shared keys'
    module = BY_NAME[values["model"]]
    if module is not bond_elastic and hasattr(module, "check"):
        problems.extend(module.check(values, musen_compat))
    return problems


def units():
    """{key: unit} of every bond material key."""
    out = {}
    for module in MODELS:
        out.update(module.UNITS)
    return out

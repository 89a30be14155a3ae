"""The bond models' Python, without a simulation: the schema every bond material is
read by (each model's keys, one entry for a key several share, a clash refused), the
rules that name a wrong key (another model's parameter, a scatter without spread, what
MUSEN cannot follow), the Kelvin dashpot's time scale from its definition, and the
weakening bond's MUSEN words both ways. Every message is compared whole."""
import math
import types

import numpy as np
import pytest

import bondem
from bondem.physics import (bond_concrete, bond_elastic, bond_kelvin, bond_models,
                            bond_parallel, bond_plastic, bond_weakening)

NAMES = ["elastic", "aerogel", "concrete", "creep", "kelvin", "parallel", "elastic_plastic",
         "weakening"]


def _values(**changes):
    """Every bond material key at its default (young_modulus 1e8 Pa), then ``changes``."""
    values = {key: entry[1] for key, entry in bond_models.bond_material_schema().items()}
    values["young_modulus"] = 1e8
    values.update(changes)
    return values


# ---------------------------------------------------------------- the schema

def test_schema_holds_each_models_keys_once_after_the_elastic_bonds():
    schema = bond_models.bond_material_schema()
    keys = list(schema)
    assert keys[:10] == list(bond_elastic.PARAMETERS) + ["model"]
    assert schema["model"] == ("str", "elastic", tuple(NAMES), None, None, None)
    assert [m.NAME for m in bond_models.MODELS] == NAMES
    for module in bond_models.MODELS:
        for key, entry in module.PARAMETERS.items():
            assert schema[key] == entry, (module.NAME, key)
    assert len(keys) == len(set(keys)) == 10 + len(
        {k for m in bond_models.MODELS[1:] for k in m.PARAMETERS} - set(keys[:10]))
    # the first model to declare a shared key fixes the order
    assert keys.index("compressive_plastic_strain") < keys.index("yield_strength") \
        < keys.index("creep_rate") < keys.index("viscosity") < keys.index("weakening_factor")


def test_a_key_declared_unlike_by_two_models_is_refused(monkeypatch):
    changed = dict(bond_weakening.PARAMETERS)
    changed["yield_strength"] = ("number", 1e6, 0.0, math.inf, False, True)
    monkeypatch.setattr(bond_weakening, "PARAMETERS", changed)
    with pytest.raises(RuntimeError) as error:
        bond_models.bond_material_schema()
    assert str(error.value) == ("bond model 'weakening' declares 'yield_strength' unlike "
                                "concrete and creep and elastic_plastic and weakening")


def test_owners_are_the_models_that_declare_a_key():
    def names(key):
        return [m.NAME for m in bond_models.owners(key)]
    assert names("yield_strength") == ["concrete", "creep", "elastic_plastic", "weakening"]
    assert names("viscosity") == ["kelvin"]
    assert names("tensile_softness") == ["aerogel"]
    assert names("young_modulus") == names("breakage") == []


def test_every_number_has_a_unit():
    schema = bond_models.bond_material_schema()
    units = bond_models.units()
    assert set(units) == {key for key, entry in schema.items() if entry[0] == "number"}
    assert units["viscosity"] == "s (s/m with musen_compat)"
    assert units["young_modulus"] == units["yield_strength"] == "Pa"
    assert units["creep_rate"] == "1/(s Pa^m)" and units["friction_angle"] == "degree"


def test_only_the_elastic_bond_keeps_no_state():
    assert [m.NAME for m in bond_models.MODELS if not bond_models.has_state(m)] == ["elastic"]
    # a model of springs alone (no energy of its own) keeps their columns all the same
    springs = types.SimpleNamespace(STATE=None, SPRINGS="my_springs")
    assert bond_models.has_state(springs) is True
    assert bond_models.has_state(types.SimpleNamespace(STATE=None)) is False
    assert bond_models.has_state(types.SimpleNamespace(STATE=None, SPRINGS=None)) is False


# ---------------------------------------------------------------- the rules

def test_another_models_parameter_away_from_its_default_is_named():
    assert bond_models.check(_values(viscosity=0.2)) == [
        ("viscosity", "viscosity = 0.2 needs model = 'kelvin' (model = 'elastic' has no "
                      "such parameter)")]
    assert bond_models.check(_values(model="kelvin", yield_strength=3e6)) == [
        ("yield_strength", "yield_strength = 3000000.0 needs model = 'concrete' or 'creep' "
                           "or 'elastic_plastic' or 'weakening' (model = 'kelvin' has no "
                           "such parameter)")]
    # at its default, or on its own model, a parameter is no problem
    assert bond_models.check(_values(viscosity=0.0)) == []
    assert bond_models.check(_values(model="creep", yield_strength=3e6)) == []
    assert bond_models.check(_values(model="kelvin", viscosity=0.2)) == []


def test_the_elastic_rules_hold_for_every_model_then_the_models_own():
    values = _values(model="kelvin", breakage="separate", strength_scatter="weibull",
                     friction_angle=30.0)
    assert bond_models.check(values, musen_compat=True) == [
        ("friction_angle", "friction_angle = 30.0 needs model = 'parallel' (model = 'kelvin' "
                           "has no such parameter)"),
        ("strength_spread", "strength_scatter = 'weibull' needs strength_spread > 0"),
        ("breakage", "musen_compat: MUSEN's Kelvin bond breaks by the combined criterion "
                     "only; breakage = 'separate' is bondem's (docs/bond_kelvin.md)")]
    assert bond_models.check(values) == bond_models.check(values, True)[:2]
    assert bond_models.check(_values(model="elastic", breakage="separate"), True) == []


@pytest.mark.parametrize("scatter, spread, seed, problems", [
    ("none", 0.0, 0.0, []),
    ("none", 0.4, 3.0, []),
    ("normal", 0.0, 0.0,
     [("strength_spread", "strength_scatter = 'normal' needs strength_spread > 0")]),
    ("weibull", 0.0, 0.0,
     [("strength_spread", "strength_scatter = 'weibull' needs strength_spread > 0")]),
    ("normal", 0.999, 12.0, []),
    ("normal", 1.0, 0.0, [("strength_spread", "1.0: the coefficient of variation of a "
                                              "normal scatter must be below 1")]),
    ("weibull", 1.5, 0.0, []),                 # a Weibull modulus has no upper limit
    ("weibull", 6.0, 2.5, [("strength_seed", "2.5: a whole number")]),
])
def test_a_scatter_needs_its_spread_and_a_whole_seed(scatter, spread, seed, problems):
    values = _values(strength_scatter=scatter, strength_spread=spread, strength_seed=seed)
    assert bond_elastic.check(values) == problems
    assert bond_models.check(values) == problems


def test_a_bond_material_with_a_broken_rule_is_refused():
    with pytest.raises(ValueError) as error:
        bondem.BondMaterial(young_modulus=1e8, strength_scatter="normal", strength_spread=1.2)
    assert str(error.value).endswith(
        "1.2: the coefficient of variation of a normal scatter must be below 1")


def test_kelvin_follows_musen_in_the_combined_criterion_only():
    message = ("musen_compat: MUSEN's Kelvin bond breaks by the combined criterion only; "
               "breakage = 'separate' is bondem's (docs/bond_kelvin.md)")
    separate = _values(model="kelvin", breakage="separate")
    assert bond_kelvin.check(separate, musen_compat=True) == [("breakage", message)]
    assert bond_kelvin.check(separate) == []
    assert bond_kelvin.check(_values(model="kelvin"), musen_compat=True) == []


def test_musens_plastic_bond_breaks_by_strains_only():
    def message(key):
        return (key, f"musen_compat: MUSEN's elastic-plastic bond breaks by fracture_strain "
                     f"and compressive_fracture_strain only; {key} must stay inf "
                     f"(docs/bond_plastic.md)")
    plastic = _values(model="elastic_plastic", normal_strength=2e6)
    assert bond_plastic.check(plastic, musen_compat=True) == [message("normal_strength")]
    both = _values(model="elastic_plastic", normal_strength=2e6, tangential_strength=1e6)
    assert bond_plastic.check(both, musen_compat=True) == [message("normal_strength"),
                                                           message("tangential_strength")]
    assert bond_plastic.check(both) == []
    assert bond_plastic.check(_values(model="elastic_plastic"), musen_compat=True) == []


def test_the_parallel_bond_has_its_own_criterion():
    assert bond_parallel.check(_values(model="parallel", breakage="separate")) == [
        ("breakage", "the parallel bond has its own criterion (tension, then Mohr-Coulomb "
                     "shear); breakage = 'separate' does not apply (docs/bond_parallel.md)")]
    assert bond_parallel.check(_values(model="parallel"), musen_compat=True) == []


def test_musen_fixes_the_concrete_bonds_ratio_softening_and_hardening():
    changed = _values(model="concrete", tensile_yield_ratio=0.6, tensile_softening=0.25,
                      compressive_hardening=0.4)
    assert bond_concrete.check(changed, musen_compat=True) == [
        ("tensile_yield_ratio", "musen_compat: MUSEN's plastic concrete bond fixes "
                                "tensile_yield_ratio = 0.7"),
        ("tensile_softening", "musen_compat: MUSEN's plastic concrete bond fixes "
                              "tensile_softening = 0.3"),
        ("compressive_hardening", "musen_compat: MUSEN's plastic concrete bond fixes "
                                  "compressive_hardening = 0.5")]
    one = _values(model="concrete", tensile_softening=0.25)
    assert [key for key, _ in bond_concrete.check(one, True)] == ["tensile_softening"]
    assert bond_concrete.check(changed) == []
    assert bond_concrete.check(_values(model="concrete"), musen_compat=True) == []


# ---------------------------------------------------------------- time scales

def test_kelvin_dashpot_time_is_the_reduced_mass_over_the_dashpot_constant():
    """t = m_red / (eta E A / L0): the time in which the dashpot alone stops its pair.
    Three bonds of different lengths, diameters and materials, one without viscosity."""
    glass = bondem.Material(density=2500.0, young_modulus=1e8)
    soft = bondem.BondMaterial(young_modulus=1e8, model="kelvin", viscosity=2e-3)
    none = bondem.BondMaterial(young_modulus=5e7, model="kelvin", viscosity=0.0)
    stiff = bondem.BondMaterial(young_modulus=3e8, model="kelvin", viscosity=5e-4)
    position = [[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0], [2e-3, 2.5e-3, 0.0], [5e-3, 2.5e-3, 0.0]]
    model, _ = bondem.make_system(position, [1e-3, 1e-3, 1.3e-3, 1.6e-3], glass,
                                  bonds=[[0, 1], [1, 2], [2, 3]],
                                  bond_diameter=[1e-3, 1.4e-3, 0.8e-3],
                                  bond_material=[soft, none, stiff],
                                  bond_material_index=[0, 1, 2])
    reduced = np.array([1.3e-6, 2.1e-6, 3.4e-6])           # kg, any masses
    lengths = np.array([2e-3, 2.5e-3, 3e-3])
    areas = np.pi / 4 * np.array([1e-3, 1.4e-3, 0.8e-3]) ** 2
    viscosity = np.array([2e-3, 0.0, 5e-4])
    with np.errstate(divide="ignore"):        # the bond without a dashpot: no limit
        times = reduced / (viscosity * np.array([1e8, 5e7, 3e8]) * areas / lengths)
    bonds = np.arange(3)
    assert bond_kelvin.time_scales(model, bonds, reduced) == {
        "bond_dashpot": pytest.approx(min(times[0], times[2]), rel=1e-14)}
    assert bond_kelvin.time_scales(model, bonds[[2]], reduced[[2]]) == {
        "bond_dashpot": pytest.approx(times[2], rel=1e-14)}
    assert bond_kelvin.time_scales(model, bonds[[1]], reduced[[1]]) == {}
    assert bond_kelvin.time_scales(model, bonds, reduced, musen_compat=True) == {}


# ---------------------------------------------------------------- MUSEN's words

@pytest.mark.parametrize("words, expected", [
    ({}, dict(fracture_strain=0.1, compressive_fracture_strain=math.inf,
              weakening_factor=0.5)),
    ({"BREAKAGE_STRAIN": 0.03, "COMPRESSIVE_BREAK": 1.0, "WEAKENING_FACTOR": 0.7},
     dict(fracture_strain=0.03, compressive_fracture_strain=0.06, weakening_factor=0.7)),
    ({"BREAKAGE_STRAIN": 0.03, "COMPRESSIVE_BREAK": 0.0, "CONSIDER_BREAKAGE": 1.0},
     dict(fracture_strain=0.03, compressive_fracture_strain=math.inf,
          weakening_factor=0.5)),
    ({"BREAKAGE_STRAIN": 0.03, "COMPRESSIVE_BREAK": 1.0, "CONSIDER_BREAKAGE": 0.0},
     dict(fracture_strain=math.inf, compressive_fracture_strain=math.inf,
          weakening_factor=0.5)),
])
def test_musens_weakening_words_as_bondem_keys(words, expected):
    entry = {"name": "kept"}
    bond_weakening._import(words, entry)
    assert entry == dict(expected, name="kept")


@pytest.mark.parametrize("values, words, note", [
    ({}, "CONSIDER_BREAKAGE 1 COMPRESSIVE_BREAK 0 BREAKAGE_STRAIN 0.1 WEAKENING_FACTOR 0.5",
     None),
    (dict(fracture_strain=0.03, compressive_fracture_strain=0.06, weakening_factor=0.7),
     "CONSIDER_BREAKAGE 1 COMPRESSIVE_BREAK 1 BREAKAGE_STRAIN 0.03 WEAKENING_FACTOR 0.7", None),
    (dict(fracture_strain=math.inf, weakening_factor=0.25),
     "CONSIDER_BREAKAGE 0 COMPRESSIVE_BREAK 0 BREAKAGE_STRAIN 0.1 WEAKENING_FACTOR 0.25",
     None),
    (dict(fracture_strain=0.03, compressive_fracture_strain=0.05),
     "CONSIDER_BREAKAGE 1 COMPRESSIVE_BREAK 1 BREAKAGE_STRAIN 0.03 WEAKENING_FACTOR 0.5",
     "weakening bond: MUSEN breaks in compression at twice the tensile fracture strain "
     "(0.06), not at compressive_fracture_strain 0.05"),
])
def test_a_weakening_bond_in_musens_words(values, words, note):
    assert bond_weakening._export(values) == (words, note)


def test_musens_weakening_words_read_back_as_written():
    values = dict(fracture_strain=0.045, compressive_fracture_strain=0.09,
                  weakening_factor=0.35)
    text, note = bond_weakening._export(values)
    tokens = text.split()
    words = {tokens[k]: float(tokens[k + 1]) for k in range(0, len(tokens), 2)}
    entry = {}
    bond_weakening._import(words, entry)
    assert note is None and entry == values

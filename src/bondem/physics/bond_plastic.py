"""Elastic-perfectly plastic solid bond: the elastic bond whose normal and tangential forces
are capped at a yield stress, with the plastic strain carried per bond; MUSEN's
ModelSBElasticPerfectlyPlastic ("Elastic-plastic bond", MUSEN 1.74.2).

Parameters beyond the elastic bond's (bond_elastic.py): yield strength sigma_y (Pa; MUSEN's
bond material property YIELD_STRENGTH), the ratio c of the compressive to the tensile
yield stress (RATIO_COMPR_TENSILE_YIELD), whether the tangential force yields
(TANGENTIAL_YIELD), the fracture strains eps_f (FRACTURE_STRAIN_TENSION) and eps_fc
(FRACTURE_STRAIN_COMPRESSION; inf for none, MUSEN's 0). With the strain
eps = (L - L0) / L0 and the plastic strain eps_p (0 at creation), each step:
    sigma = E (eps - eps_p);  sigma_lim = sigma_y, or c sigma_y when sigma < 0
    sigma >  sigma_lim:  eps_p = eps - sigma_lim / E,  sigma =  sigma_lim
    sigma < -sigma_lim:  eps_p = eps + sigma_lim / E,  sigma = -sigma_lim
    F_n = sigma A n                                       (on i, n = (x_j - x_i) / L)
    |F_t| / A > sigma_y:  F_t = F_t sigma_y A / |F_t|     (tangential yield on)
The moments are the elastic bond's. Unloading follows the elastic slope E A / L0 from the
plastic length L0 (1 + eps_p), so a pull to eps_1 past yield and back leaves
eps_p = eps_1 - sigma_y / E, and the loop between F = +-sigma_y A encloses
sigma_y A L0 delta(eps_p) per plastic increment. The bond breaks when eps > eps_f or
eps < -eps_fc (mode tension or compression), or, besides MUSEN, by the elastic bond's stress
criterion on the capped loads (normal_strength, tangential_strength: off at their default
inf). Booked: the J that yielding removed (sigma_lim A L0 |delta eps_p| per normal
increment, the stored energy lost by a tangential cap), column 0 of the bond's state; eps_p
is column 1 (STATE, SPRINGS in physics/bond_models.py).

MUSEN-compatible runs (musen_compat) use MUSEN's numerics (bond_elastic_musen.py) and its
choices: the bond breaks by the fracture strains only, and its tangential test compares
|F_t| / A with sigma_y but caps at sigma_lim (c sigma_y while the normal trial stress is
compressive). docs/bond_plastic.md.
"""
import math

from ._registry import physics
from .bond_elastic import COMPRESSION, INTACT, TENSION, bond_break_mode
from .vector import dot, norm, scale

NAME = "elastic_plastic"
_INF = float("inf")
PARAMETERS = {
    "yield_strength": ("number", _INF, 0.0, _INF, False, True),
    "compressive_yield_ratio": ("number", 1.0, 0.0, _INF, False, False),
    "tangential_yield": ("bool", True, None, None, None, None),
    "fracture_strain": ("number", 0.1, 0.0, _INF, False, True),
    "compressive_fracture_strain": ("number", _INF, 0.0, _INF, False, True),
}
UNITS = {"yield_strength": "Pa", "compressive_yield_ratio": "-", "fracture_strain": "-",
         "compressive_fracture_strain": "-"}
LOADS = None
SPRINGS = "plastic_springs"
COLUMNS = ("normal plastic strain (-)",)
ENERGY = "plastic_normal_energy"
STATE = ("J dissipated by the bond's yielding", "dissipated_plastic")
VECTORISED = False
# MUSEN's counterpart (io/musen_text.py): FRACTURE_STRAIN_COMPRESSION 0 is none (inf),
# YIELD_STRENGTH is bond material property 15; it reads no strengths.
MUSEN = {"model": "ModelSBElasticPerfectlyPlastic",
         "parameters": {"FRACTURE_STRAIN_TENSION": "fracture_strain",
                        "FRACTURE_STRAIN_COMPRESSION": "compressive_fracture_strain",
                        "TANGENTIAL_YIELD": "tangential_yield",
                        "RATIO_COMPR_TENSILE_YIELD": "compressive_yield_ratio"},
         "properties": {15: "yield_strength"}, "strengths": False,
         "zero_is_inf": ("compressive_fracture_strain",)}


def check(values, musen_compat=False):
    """[(key, message)]: MUSEN's bond breaks by its fracture strains only."""
    problems = []
    if musen_compat:
        for key in ("normal_strength", "tangential_strength"):
            if values[key] != _INF:
                problems.append((key, f"musen_compat: MUSEN's elastic-plastic bond breaks by "
                                      f"fracture_strain and compressive_fracture_strain "
                                      f"only; {key} must stay inf (docs/bond_plastic.md)"))
    return problems


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """No limit beyond the elastic springs' (yielding only softens them): {}."""
    return {}


@physics
def plastic_normal_stress(strain, plastic_strain, young_modulus, yield_strength, ratio):
    """(normal stress sigma in Pa, plastic strain after this step, the yield limit in Pa
    that applied) of a bond at ``strain`` (-) with ``plastic_strain`` (-) carried, E (Pa),
    tensile yield stress (Pa) and compressive/tensile yield ratio (module docstring)."""
    stress = (strain - plastic_strain) * young_modulus
    limit = yield_strength
    if stress < 0.0:
        limit = yield_strength * ratio
    if stress > limit:
        return limit, strain - limit / young_modulus, limit
    if stress < -limit:
        return -limit, strain + limit / young_modulus, limit
    return stress, plastic_strain, limit


@physics
def plastic_yield(compat, strain, plastic_strain, n, f_t, area, l0, kt, young,
                  yield_strength, ratio, tangential_yield):
    """The yield caps of the elastic-plastic bond (module docstring), shared by the creep
    bond: (F_n on i in N, F_t in N, normal stress in Pa, plastic strain, the yield limit
    in Pa that applied, J dissipated), from the strain (-) and the carried plastic strain,
    the spring's F_t (N), the bond's area (m^2), L0 (m), k_t (N/m), E and the yield stress
    (Pa). compat: MUSEN's tangential cap at the limit of the normal trial stress."""
    stress, strain_p, limit = plastic_normal_stress(strain, plastic_strain, young,
                                                    yield_strength, ratio)
    lost = 0.0
    if strain_p != plastic_strain:
        lost = limit * area * l0 * abs(strain_p - plastic_strain)
    if compat:
        f_n = scale(scale(n, stress), area)
    else:
        f_n = scale(n, stress * area)
    if tangential_yield:
        size = norm(f_t)
        if size > yield_strength * area:
            cap = yield_strength * area
            if compat:
                cap = limit * area
            f_t_new = scale(f_t, cap / size)
            lost += 0.5 * (size * size - dot(f_t_new, f_t_new)) / kt
            f_t = f_t_new
    return f_n, f_t, stress, strain_p, limit, lost


@physics
def fracture_mode(strain, materials, m):
    """TENSION past fracture_strain, COMPRESSION past -compressive_fracture_strain, else
    INTACT: the strain test of the plastic family (MUSEN's fracture strains)."""
    if strain > materials.fracture_strain[m]:
        return TENSION
    if strain < -materials.compressive_fracture_strain[m]:
        return COMPRESSION
    return INTACT


@physics
def strength_mode(compat, length, l0, f_n, f_t, m_n, m_t, diameter, scatter, materials, m):
    """The elastic bond's stress criterion on the material's strengths times the bond's
    strength factor, which bondem's law adds to the models that MUSEN breaks otherwise;
    INTACT with compat (MUSEN's models have no such test)."""
    if compat:
        return INTACT
    return bond_break_mode(length, l0, f_n, f_t, m_n, m_t, diameter,
                           materials.normal_strength[m] * scatter,
                           materials.tangential_strength[m] * scatter,
                           materials.breakage[m], materials.compressive_breakage[m])


@physics
def plastic_springs(musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode,
                    kn, kt, scatter, lp, plastic_strain, unused, materials, m):
    """SPRINGS of the elastic-plastic bond (module docstring): (F_n, F_t in N, M_n, M_t in
    N m, break mode, plastic strain, unused column, J dissipated by this step's yielding),
    from the elastic springs f_n, f_t, m_n, m_t (on i) of bond b of material m and its
    carried plastic strain. musen True: MUSEN's choices; None or False: bondem's."""
    compat = False
    if musen is not None:
        compat = musen
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    strain = (length - l0) / l0
    f_n, f_t, _, strain_p, _, lost = plastic_yield(
        compat, strain, plastic_strain, n, f_t, area, l0, kt, materials.young_modulus[m],
        materials.yield_strength[m] * scatter, materials.compressive_yield_ratio[m],
        materials.tangential_yield[m])
    mode = fracture_mode(strain, materials, m)
    if mode == INTACT:
        mode = strength_mode(compat, length, l0, f_n, f_t, m_n, m_t, diameter, scatter,
                             materials, m)
    return f_n, f_t, m_n, m_t, mode, strain_p, unused, lost


@physics
def plastic_normal_energy(length, l0, kn, plastic_strain, unused, materials, m):
    """ENERGY of the elastic-plastic bond: J held by its normal spring, stretched from the
    plastic length L0 (1 + eps_p): k_n (L - L0 - eps_p L0)^2 / 2."""
    stretch = length - l0 - plastic_strain * l0
    return 0.5 * kn * stretch * stretch

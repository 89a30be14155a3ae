"""Creep bond: the elastic-perfectly plastic bond (bond_plastic.py) whose plastic strain also
grows with time under load by a power law (Norton creep); MUSEN's ModelSBCreep ("Creep
bond", MUSEN 1.74.2).

Parameters: the elastic-plastic bond's (yield_strength ... compressive_fracture_strain,
with its defaults: no yield unless given) and the creep rate A (1/(s Pa^m); MUSEN's
CREEP_PARAMATER_A) and exponent m (CREEP_PARAMATER_m). After the plastic step of
bond_plastic.py, with the normal stress sigma and the tangential stress tau = |F_t| / A_b
(after its cap):
    normal:      d eps_p / dt = A |sigma|^m sign(sigma)        (applied from the next step)
    tangential:  |F_t| shrinks by G A_b dt A |tau|^m           (this step)
so a bond held at a fixed strain relaxes as d sigma / dt = -E A sigma^m (for m = 2:
sigma = sigma_0 / (1 + E A sigma_0 t)), and one under a constant force F stretches at
L0 A (F / A_b)^m. Creep is integrated explicitly (error O(dt E A sigma^(m-1))). Breakage as
the elastic-plastic bond's (fracture strains, and bondem's stress criterion on the
strengths); booked: the J yielding and creep removed (sigma A_b L0 |delta eps_p| per
increment, the stored energy a tangential cut removes).

MUSEN-compatible runs (musen_compat): MUSEN's springs and choices as for the elastic-plastic
bond (tangential cap at the compressive yield while compressed); its stress test
(FRACTURE_BY_STRESS 1) is MUSEN's combined criterion with the material's strengths, on
when a strength is finite. A creep step larger than the tangential force reverses it in
MUSEN; bondem's own law stops it at zero. docs/bond_creep.md.
"""
import math

from ._registry import physics
from .bond_elastic import CRITERION_COMBINED, INTACT
from .bond_elastic_musen import bond_break_mode_musen
from .bond_plastic import PARAMETERS as PLASTIC, UNITS as PLASTIC_UNITS, \
    fracture_mode, plastic_normal_energy, plastic_yield, strength_mode  # noqa: F401
from .vector import dot, norm, scale

NAME = "creep"
_INF = float("inf")
PARAMETERS = dict(PLASTIC)
PARAMETERS.update({"creep_rate": ("number", 0.0, 0.0, _INF, True, False),
                   "creep_exponent": ("number", 1.0, 0.0, _INF, True, False)})
UNITS = dict(PLASTIC_UNITS, creep_rate="1/(s Pa^m)", creep_exponent="-")
LOADS = None
SPRINGS = "creep_springs"
COLUMNS = ("normal plastic strain (-)",)
ENERGY = "plastic_normal_energy"
STATE = ("J dissipated by the bond's yielding and creep", "dissipated_creep")
VECTORISED = False
# MUSEN's counterpart (io/musen_text.py); FRACTURE_BY_STRESS is read from the strengths
MUSEN = {"model": "ModelSBCreep",
         "parameters": {"FRACTURE_STRAIN_TENSION": "fracture_strain",
                        "FRACTURE_STRAIN_COMPRESSION": "compressive_fracture_strain",
                        "TANGENTIAL_YIELD": "tangential_yield",
                        "RATIO_COMPR_TENSILE_YIELD": "compressive_yield_ratio",
                        "CREEP_PARAMATER_A": "creep_rate",
                        "CREEP_PARAMATER_m": "creep_exponent"},
         "properties": {15: "yield_strength"}, "strengths": "FRACTURE_BY_STRESS",
         "zero_is_inf": ("compressive_fracture_strain",),
         "defaults": {"creep_rate": 0.01, "creep_exponent": 0.01}}


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """No limit beyond the springs' (creep is integrated explicitly; its own accuracy
    needs dt E A sigma^(m-1) << 1, docs/bond_creep.md): {}."""
    return {}


@physics
def creep_springs(musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode,
                  kn, kt, scatter, lp, plastic_strain, unused, materials, m):
    """SPRINGS of the creep bond (module docstring): (F_n, F_t in N, M_n, M_t in N m, break
    mode, plastic strain for the next step, unused column, J dissipated by this step's
    yielding and creep). musen True: MUSEN's choices; None or False: bondem's."""
    compat = False
    if musen is not None:
        compat = musen
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    rate = materials.creep_rate[m]
    exponent = materials.creep_exponent[m]
    strain = (length - l0) / l0
    f_n, f_t, stress, strain_p, _, lost = plastic_yield(
        compat, strain, plastic_strain, n, f_t, area, l0, kt, materials.young_modulus[m],
        materials.yield_strength[m] * scatter, materials.compressive_yield_ratio[m],
        materials.tangential_yield[m])
    creep = dt * rate * math.pow(abs(stress), exponent)
    if stress > 0.0:
        strain_p += creep
    else:
        strain_p -= creep
    lost += abs(stress) * area * l0 * creep
    size = norm(f_t)
    if size > 0.0 and rate > 0.0:
        shear_modulus = kt * l0 / area
        factor = 1.0 - dt * rate * math.pow(size / area, exponent) * shear_modulus * area / size
        if factor < 0.0 and not compat:
            factor = 0.0
        f_t_new = scale(f_t, factor)
        lost += 0.5 * (size * size - dot(f_t_new, f_t_new)) / kt
        f_t = f_t_new
    mode = fracture_mode(strain, materials, m)
    if mode == INTACT:
        if compat:
            if materials.normal_strength[m] != math.inf or \
                    materials.tangential_strength[m] != math.inf:
                # MUSEN's FRACTURE_BY_STRESS: its combined criterion (1.70's criterion 1)
                mode = bond_break_mode_musen(length, l0, f_n, f_t, m_n, m_t, diameter,
                                             materials.normal_strength[m] * scatter,
                                             materials.tangential_strength[m] * scatter,
                                             CRITERION_COMBINED)
        else:
            mode = strength_mode(compat, length, l0, f_n, f_t, m_n, m_t, diameter, scatter,
                                 materials, m)
    return f_n, f_t, m_n, m_t, mode, strain_p, unused, lost

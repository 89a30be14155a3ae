"""Plastic concrete bond: a normal spring that softens after a tensile yield stress and
breaks when the softening has eaten its strength, and hardens after a larger compressive
yield stress; MUSEN's ModelSBPlasticConcrete ("Plastic concrete bond", MUSEN 1.74.2) with
its two defects corrected in bondem's own law.

Parameters: the yield stress sigma_y (yield_strength; MUSEN's bond material property
YIELD_STRENGTH): compressive yield at -sigma_y, tensile yield at r sigma_y
(tensile_yield_ratio, 0.7 fixed in MUSEN), softening alpha (tensile_softening, 0.3 in
MUSEN), hardening beta (compressive_hardening, 0.5 in MUSEN), and whether the bond breaks
once softened (tensile_failure; MUSEN's CONSIDER_BREAKAGE). With eps = (L - L0)/L0 and the
plastic strain eps_p (column 1), MUSEN's explicit update each step:
    sigma = E (eps - eps_p)
    sigma >= 0:  limit = r sigma_y - alpha E eps_p;  sigma > limit:
                 eps_p += (sigma - limit)(1 + alpha)/E, sigma = E (eps - eps_p);
                 sigma < 0 after it: the bond breaks (tension)
    sigma <  0:  limit = -sigma_y + beta E eps_p;    sigma < limit:
                 eps_p += (sigma - limit)(1 - beta)/E, sigma = E (eps - eps_p)
As the strain increments shrink this follows the envelopes
    tension:      sigma = (r sigma_y - alpha E eps) / (1 - alpha), from eps = r sigma_y/E
                  to zero at eps_f = r sigma_y / (alpha E)
    compression:  sigma = (-sigma_y + beta E eps) / (1 + beta), from eps = -sigma_y/E
and unloads along E A. F_n = sigma A n (on i, tension pulls i towards j); the tangential
force and the moments are the elastic bond's (they neither yield nor break). Energy: the
spring holds E A (L - L0 (1 + eps_p))^2 / (2 L0); the work of the axial force over each
step (trapezoidal, from the previous length) less the change of that is booked as
dissipated (column 0).

MUSEN's defects, reproduced only with musen_compat (docs/bond_concrete.md): its normal force
is currentContact sigma A without the minus sign of its other bonds, so a stretched bond
pushes its particles apart; and its tangential force is its tangential overlap times G A,
not G A / L0 (L0 / 1 m times too stiff, for MUSEN's overlap in m).
"""
import math

from ._registry import physics
from .bond_elastic import TENSION, bond_loads_on_particles
from .bond_plastic import PARAMETERS as PLASTIC, plastic_normal_energy, \
    strength_mode  # noqa: F401  (plastic_normal_energy: the ENERGY it shares)
from .vector import scale

NAME = "concrete"
PARAMETERS = {"yield_strength": PLASTIC["yield_strength"],
              "tensile_yield_ratio": ("number", 0.7, 0.0, float("inf"), False, False),
              "tensile_softening": ("number", 0.3, 0.0, 1.0, False, False),
              "compressive_hardening": ("number", 0.5, 0.0, 1.0, True, False),
              "tensile_failure": ("bool", True, None, None, None, None)}
UNITS = {"yield_strength": "Pa", "tensile_yield_ratio": "-", "tensile_softening": "-",
         "compressive_hardening": "-"}
LOADS = "concrete_loads"
SPRINGS = "concrete_springs"
COLUMNS = ("normal plastic strain (-)",)
ENERGY = "plastic_normal_energy"
STATE = ("J dissipated by the bond's softening and hardening", "dissipated_concrete")
VECTORISED = False
MUSEN = {"model": "ModelSBPlasticConcrete",
         "parameters": {"CONSIDER_BREAKAGE": "tensile_failure"},
         "properties": {15: "yield_strength"}, "strengths": False,
         "fixed": {"tensile_yield_ratio": 0.7, "tensile_softening": 0.3,
                   "compressive_hardening": 0.5}}


def check(values, musen_compat=False):
    """[(key, message)]: MUSEN fixes the ratio, softening and hardening."""
    fixed = {"tensile_yield_ratio": 0.7, "tensile_softening": 0.3,
             "compressive_hardening": 0.5}
    if not musen_compat:
        return []
    return [(key, f"musen_compat: MUSEN's plastic concrete bond fixes {key} = {value}")
            for key, value in fixed.items() if values[key] != value]


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """No limit beyond the elastic springs': {}."""
    return {}


@physics
def concrete_stress(strain, plastic_strain, young, yield_strength, ratio, alpha, beta):
    """(sigma in Pa, plastic strain, True if softened through zero) after one of MUSEN's
    explicit updates at ``strain`` (module docstring)."""
    elastic = strain - plastic_strain
    softened = False
    if elastic >= 0.0:
        stress = elastic * young
        limit = ratio * yield_strength - plastic_strain * young * alpha
        if stress > limit:
            plastic_strain += (stress - limit) * (1.0 + alpha) / young
            stress = (strain - plastic_strain) * young
        if stress < 0.0:
            softened = True
    else:
        stress = elastic * young
        limit = -yield_strength + plastic_strain * young * beta
        if stress < limit:
            plastic_strain += (stress - limit) * (1.0 - beta) / young
            stress = (strain - plastic_strain) * young
    return stress, plastic_strain, softened


@physics
def concrete_springs(musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode,
                     kn, kt, scatter, lp, plastic_strain, unused, materials, m):
    """SPRINGS of the plastic concrete bond (module docstring): (F_n, F_t in N, M_n, M_t in
    N m, break mode, plastic strain, unused column, J dissipated this step)."""
    compat = False
    if musen is not None:
        compat = musen
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    young = materials.young_modulus[m]
    old = (lp - l0 - plastic_strain * l0) * young / l0       # stress held before (Pa)
    stress, strain_p, softened = concrete_stress(
        (length - l0) / l0, plastic_strain, young, materials.yield_strength[m] * scatter,
        materials.tensile_yield_ratio[m], materials.tensile_softening[m],
        materials.compressive_hardening[m])
    # work of the axial force over the step less the change of what the spring holds
    lost = 0.5 * (old + stress) * area * (length - lp) \
        - 0.5 * (stress * stress - old * old) * area * l0 / young
    if compat:
        f_n = scale(scale(n, -stress), area)        # MUSEN's sign: pushes when stretched
    else:
        f_n = scale(n, stress * area)
    if softened and materials.tensile_failure[m]:
        mode = TENSION
    else:
        mode = strength_mode(compat, length, l0, f_n, f_t, m_n, m_t, diameter, scatter,
                             materials, m)
    return f_n, f_t, m_n, m_t, mode, strain_p, unused, lost


@physics
def concrete_loads(musen, r, length, l0, diameter, vi, vj, wi, wj, f_n, f_t, m_n, m_t, kn,
                   kt, materials, m):
    """LOADS of the plastic concrete bond: the springs' own loads (force on i, moment on i,
    moment on j, no energy rate); with musen True MUSEN's tangential force, its overlap
    times G A, that is the spring's F_t times L0 (in m), applied and turning the spheres,
    while the spring itself keeps G A / L0 for its increments."""
    if musen is not None:
        if musen:
            force_i, moment_i, moment_j = bond_loads_on_particles(r, f_n, scale(f_t, l0),
                                                                  m_n, m_t)
            return force_i, moment_i, moment_j, 0.0
    force_i, moment_i, moment_j = bond_loads_on_particles(r, f_n, f_t, m_n, m_t)
    return force_i, moment_i, moment_j, 0.0

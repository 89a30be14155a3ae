"""Aerogel bond: a bond whose axial force, past a plastic strain in compression or tension,
follows a softening (or hardening) line and, once that line crosses zero, turns into a
one-sided spring that only resists coming back; MUSEN's ModelSBAerogel ("Aerogel bond",
MUSEN 1.74.2), for the fragile nano-porous networks of aerogels.

Parameters (MUSEN's names): the plastic strains eps_pc (compressive_plastic_strain,
PLASTIC_STRAIN_COMPR; taken as -|eps_pc|) and eps_pt (tensile_plastic_strain,
PLASTIC_STRAIN_TENS), the softness ratios s_c (compressive_softness, SOFTNESS_RATIO_COMPR)
and s_t (tensile_softness, SOFTNESS_RATIO_TENS), the breaking strain eps_b
(tensile_break_strain, BREAK_STRAIN_TENS) and the hardness ratios h_c, h_t
(compressive_hardness, tensile_hardness; HARDNESS_RATIO_*). With K = E A, the strain
eps = (L - L0)/L0, the carried strain eps_p (column 1) and the state flag f (column 2: 0
intact, -1 crushed, +1 torn; MUSEN keeps it in TangentialPlasticStrain.x), the axial
force F (positive in tension, on i along n):
  f = 0:  eps < -eps_pc:  F = K (-eps_pc + s_c d), d = eps + eps_pc, eps_p = d (1 - s_c);
                          F > 0 -> f = -1, F = 0
          eps > eps_pt:   F = K (eps_pt + s_t d), d = eps - eps_pt, eps_p = d (1 - s_t);
                          F < 0 -> f = +1, F = 0
          else:           F = K (eps - eps_p)                  (unloading along E A)
          F > eps_b K:    the bond breaks (tension)
  f = -1: eps_p = min(eps_p, eps),  F = h_c K (eps - eps_p)  (resists re-stretching)
  f = +1: eps_p = max(eps_p, eps),  F = h_t K (eps - eps_p)  (resists re-compression)
The tangential force and the moments are the elastic bond's and never break. Energy: the
spring holds F^2 / (2 k) with k = K/L0, or h K/L0 once crushed or torn; what the
force's work over a step (trapezoidal, from the previous length) does not leave stored is
booked as dissipated (column 0). In bondem's own law the elastic bond's stress criterion
(normal_strength, tangential_strength; inf by default) also applies; MUSEN has none.
docs/bond_aerogel.md.
"""
import math

from ._registry import physics
from .bond_elastic import TENSION
from .bond_plastic import strength_mode
from .vector import scale

NAME = "aerogel"
_INF = float("inf")
PARAMETERS = {
    "compressive_plastic_strain": ("number", 0.1, 0.0, _INF, True, False),
    "tensile_plastic_strain": ("number", 0.05, 0.0, _INF, True, False),
    "compressive_softness": ("number", -2.0, -_INF, _INF, False, False),
    "tensile_softness": ("number", 0.0, -_INF, _INF, False, False),
    "tensile_break_strain": ("number", 0.5, 0.0, _INF, True, True),
    "compressive_hardness": ("number", 0.1, 0.0, _INF, False, False),
    "tensile_hardness": ("number", 0.1, 0.0, _INF, False, False),
}
UNITS = {key: "-" for key in PARAMETERS}
LOADS = None
SPRINGS = "aerogel_springs"
COLUMNS = ("carried strain eps_p (-)", "state: 0 intact, -1 crushed, +1 torn")
ENERGY = "aerogel_normal_energy"
STATE = ("J dissipated by the bond's plastic branches", "dissipated_aerogel")
VECTORISED = False
MUSEN = {"model": "ModelSBAerogel",
         "parameters": {"PLASTIC_STRAIN_COMPR": "compressive_plastic_strain",
                        "PLASTIC_STRAIN_TENS": "tensile_plastic_strain",
                        "SOFTNESS_RATIO_COMPR": "compressive_softness",
                        "SOFTNESS_RATIO_TENS": "tensile_softness",
                        "BREAK_STRAIN_TENS": "tensile_break_strain",
                        "HARDNESS_RATIO_COMPR": "compressive_hardness",
                        "HARDNESS_RATIO_TENS": "tensile_hardness"},
         "properties": {}, "strengths": False}


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """No limit beyond the elastic springs' (the softness ratios are taken below 1 in
    magnitude in practice; a hardness above 1 stiffens: docs/bond_aerogel.md): {}."""
    return {}


@physics
def aerogel_normal(strain, carried, state, materials, m):
    """(F / K, carried strain, state, breaks) of the aerogel law (module docstring) at
    ``strain`` from the bond's carried strain and state; F / K is the axial force over
    E A (positive in tension). Evaluating it twice at one strain gives the same force."""
    breaks = False
    if abs(state) < 0.5:
        compressive = -abs(materials.compressive_plastic_strain[m])
        tensile = abs(materials.tensile_plastic_strain[m])
        if strain < 0.0 and strain < compressive:
            shift = strain - compressive
            force = compressive + shift * materials.compressive_softness[m]
            carried = shift * (1.0 - materials.compressive_softness[m])
            if force > 0.0:
                state = -1.0
                force = 0.0
        elif strain > 0.0 and strain > tensile:
            shift = strain - tensile
            force = tensile + shift * materials.tensile_softness[m]
            carried = shift * (1.0 - materials.tensile_softness[m])
            if force < 0.0:
                state = 1.0
                force = 0.0
        else:
            force = strain - carried
        if force > abs(materials.tensile_break_strain[m]):
            breaks = True
    elif state < -0.5:
        if strain < carried:
            carried = strain
        force = materials.compressive_hardness[m] * (strain - carried)
    else:
        if strain > carried:
            carried = strain
        force = materials.tensile_hardness[m] * (strain - carried)
    return force, carried, state, breaks


@physics
def aerogel_stiffness(state, materials, m):
    """The axial spring's slope over E A / L0 in ``state`` (1 intact, h_c crushed, h_t
    torn)."""
    if state < -0.5:
        return materials.compressive_hardness[m]
    if state > 0.5:
        return materials.tensile_hardness[m]
    return 1.0


@physics
def aerogel_held(force, slope, stiffness, l0):
    """J held by the axial spring at force / K = ``force`` on a branch of ``slope`` (over
    E A / L0; 0 holds nothing), K = ``stiffness`` = E A (N), L0 in m: F^2 / (2 k)."""
    if slope <= 0.0:
        return 0.0
    return 0.5 * force * force * stiffness * l0 / slope


@physics
def aerogel_springs(musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode,
                    kn, kt, scatter, lp, carried, state, materials, m):
    """SPRINGS of the aerogel bond (module docstring): (F_n, F_t in N, M_n, M_t in N m,
    break mode, carried strain, state, J dissipated this step)."""
    compat = False
    if musen is not None:
        compat = musen
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    stiffness = materials.young_modulus[m] * area           # K = E A (N)
    old_force, _, _, _ = aerogel_normal((lp - l0) / l0, carried, state, materials, m)
    old_slope = aerogel_stiffness(state, materials, m)
    force, carried, state, breaks = aerogel_normal((length - l0) / l0, carried, state,
                                                   materials, m)
    slope = aerogel_stiffness(state, materials, m)
    # work of the axial force over the step (trapezoidal) less the change of what it holds
    work = 0.5 * (old_force + force) * stiffness * (length - lp)
    lost = work - (aerogel_held(force, slope, stiffness, l0)
                   - aerogel_held(old_force, old_slope, stiffness, l0))
    f_n = scale(n, force * stiffness)    # MUSEN: -currentContact F, currentContact = -n
    if breaks:
        mode = TENSION
    else:
        mode = strength_mode(compat, length, l0, f_n, f_t, m_n, m_t, diameter, scatter,
                             materials, m)
    return f_n, f_t, m_n, m_t, mode, carried, state, lost


@physics
def aerogel_normal_energy(length, l0, kn, carried, state, materials, m):
    """ENERGY of the aerogel bond: F^2 / (2 k), k = k_n times its state's slope (J)."""
    force, _, _, _ = aerogel_normal((length - l0) / l0, carried, state, materials, m)
    return aerogel_held(force, aerogel_stiffness(state, materials, m), kn * l0, l0)

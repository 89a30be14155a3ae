"""Parallel bond with a Mohr-Coulomb shear strength and an optional softening branch, in the
vocabulary of PFC's linear parallel bond (Potyondy & Cundall 2004; Potyondy 2015) so that
its users recognise it; bondem's own, no MUSEN counterpart.

Springs: the elastic bond's (bond_elastic.py). Strength, with the bond's area A, second
moments I, J, radius R, the normal force F_n (positive in tension) and the moment
contribution factor beta (PFC's pb_mcf):
    sigma = F_n / A + beta |M_t| R / I          (tensile stress at the bond's edge)
    tau   = |F_t| / A + beta |M_n| R / J
    sigma >= sigma_t                      -> breaks in tension   (sigma_t: normal_strength,
                                                                  PFC's pb_ten)
    tau >= tau_c = c - (F_n / A) tan phi  -> breaks in shear      (c: tangential_strength,
                                                                  pb_coh; phi:
                                                                  friction_angle, pb_fa)
so the shear strength rises with compression along a line of slope tan phi (the
Mohr-Coulomb envelope); a bond pulled to F_n / A = c / tan phi (the envelope's apex) has
none left and breaks in tension even below sigma_t.
Softening (softening = zeta > 0; PFC's soft-bond idea, sb_soft): instead of breaking when
its axial stress reaches sigma_t, the bond loses axial stiffness by a damage D from the
largest axial strain kappa it has seen (column 1), along the linear envelope
    sigma_env(kappa) = sigma_t (eps_f - kappa) / (eps_f - eps_0),
    eps_0 = sigma_t / E,  eps_f = eps_0 (1 + 1 / zeta),  D = 1 - sigma_env / (E kappa)
(zeta: the softening slope over the elastic slope); in tension F_n = (1 - D) E A eps,
unloading and reloading along that secant, in compression undamaged (the crack closes);
the bond breaks in tension when kappa reaches eps_f, having dissipated
sigma_t eps_f A L0 / 2 (the envelope's area), booked as the damage grows
(k_n (L - L0)^2 dD / 2, column 0). With softening the moments count in the shear test
only. Strength scatter (strength_scatter) multiplies sigma_t and c. docs/bond_parallel.md.
"""
import math

from ._registry import physics
from .bond_elastic import INTACT, SHEAR, TENSION
from .vector import norm, scale

NAME = "parallel"
_INF = float("inf")
PARAMETERS = {
    "friction_angle": ("number", 0.0, 0.0, 90.0, True, False),
    "moment_factor": ("number", 1.0, 0.0, 1.0, True, True),
    "softening": ("number", 0.0, 0.0, _INF, True, False),
}
UNITS = {"friction_angle": "degree", "moment_factor": "-", "softening": "-"}
LOADS = None
SPRINGS = "parallel_springs"
COLUMNS = ("largest axial strain reached (-)", "damage D (-)")
ENERGY = "parallel_normal_energy"
STATE = ("J dissipated by the bond's softening", "dissipated_softening")
VECTORISED = False


def check(values, musen_compat=False):
    """[(key, message)]: the parallel bond is tested by its own criterion (breakage is
    not read) and has no MUSEN counterpart to follow."""
    if values["breakage"] == "separate":
        return [("breakage", "the parallel bond has its own criterion (tension, then "
                             "Mohr-Coulomb shear); breakage = 'separate' does not apply "
                             "(docs/bond_parallel.md)")]
    return []


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """No limit beyond the elastic springs' (damage only softens them): {}."""
    return {}


@physics
def parallel_damage(kappa, young_modulus, tensile_strength, softening):
    """Damage D (-) of a softening parallel bond whose largest axial strain is ``kappa``
    (module docstring); 1 at and beyond eps_f."""
    eps_0 = tensile_strength / young_modulus
    if kappa <= eps_0:
        return 0.0
    eps_f = eps_0 * (1.0 + 1.0 / softening)
    if kappa >= eps_f:
        return 1.0
    envelope = tensile_strength * (eps_f - kappa) / (eps_f - eps_0)
    return 1.0 - envelope / (young_modulus * kappa)


@physics
def parallel_springs(musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode,
                     kn, kt, scatter, lp, kappa, damage, materials, m):
    """SPRINGS of the parallel bond (module docstring): (F_n, F_t in N, M_n, M_t in N m,
    break mode, largest axial strain, damage, J dissipated by softening this step) of
    bond b of material m from the elastic springs (on i)."""
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    second = 0.25 * area * radius * radius
    young = materials.young_modulus[m]
    tensile = materials.normal_strength[m] * scatter
    cohesion = materials.tangential_strength[m] * scatter
    beta = materials.moment_factor[m]
    softening = materials.softening[m]
    strain = (length - l0) / l0
    lost = 0.0
    if softening > 0.0 and strain > 0.0 and tensile != _INF:
        if strain > kappa:
            kappa = strain
            grown = parallel_damage(kappa, young, tensile, softening)
            if grown >= 1.0:
                return f_n, f_t, m_n, m_t, TENSION, kappa, 1.0, lost
            if grown > damage:
                lost = 0.5 * kn * (length - l0) * (length - l0) * (grown - damage)
                damage = grown
        f_n = scale(f_n, 1.0 - damage)
    if materials.breakage[m] == 0:
        return f_n, f_t, m_n, m_t, INTACT, kappa, damage, lost
    normal = norm(f_n) / area
    if strain < 0.0:
        normal = -normal
    bending = beta * norm(m_t) * radius / second
    if softening == 0.0 and normal + bending >= tensile:
        return f_n, f_t, m_n, m_t, TENSION, kappa, damage, lost
    shear = norm(f_t) / area + beta * norm(m_n) * radius / (2.0 * second)
    limit = cohesion - normal * math.tan(materials.friction_angle[m] * math.pi / 180.0)
    if limit <= 0.0:
        # pulled past the envelope's apex c / tan(phi): no shear strength left, a
        # tensile failure whatever the shear
        return f_n, f_t, m_n, m_t, TENSION, kappa, damage, lost
    if shear >= limit:
        return f_n, f_t, m_n, m_t, SHEAR, kappa, damage, lost
    return f_n, f_t, m_n, m_t, INTACT, kappa, damage, lost


@physics
def parallel_normal_energy(length, l0, kn, kappa, damage, materials, m):
    """ENERGY of the parallel bond: J held by its normal spring, (1 - D) k_n (L - L0)^2 / 2
    in tension, k_n (L - L0)^2 / 2 in compression (the crack closes)."""
    stretch = length - l0
    energy = 0.5 * kn * stretch * stretch
    if stretch > 0.0:
        energy *= 1.0 - damage
    return energy

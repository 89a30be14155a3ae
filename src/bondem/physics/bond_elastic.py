"""MUSEN's elastic solid bond (Dosta et al. 2013; Potyondy & Cundall 2004), SPEC section 2.

Bond between particles i and j with diameter d_b (R_b = d_b / 2) and material E, nu:
    A_b = pi R_b^2,  I = pi R_b^4 / 4,  J = pi R_b^4 / 2,  G = E / (2 (1 + nu))
    r = x_j - x_i,  L = |r|,  n = r / L
    w_rel = w_i - w_j
    v_rel = v_j - v_i - (w_i + w_j) x r / 2        (j's side relative to i's, at the centre)
    v_t = v_rel - n (n . v_rel);  w_n = n (n . w_rel);  w_t = w_rel - w_n
    F_n = E A_b (L - L0) / L0 n                   (on i: tension pulls i toward j)
    F_t = T F_t + (G A_b / L0) v_t dt
    M_n = T M_n - (G J / L0) w_n dt
    M_t = T M_t - (E I / L0) w_t dt
    on i: F += F_n + F_t,  M +=  M_n + M_t + (r/2) x F_t
    on j: F -= F_n + F_t,  M += -M_n - M_t + (r/2) x F_t
T is the exact rotation of ``rotation.bond_rotate``. The seed writes every increment with a
plus sign; the signs here make each spring resist the relative motion (SPEC).

Breakage, with s = +1 in tension and -1 in compression:
    sigma = s |F_n| / A_b + |M_t| R_b / I,   tau = |F_t| / A_b + |M_n| R_b / J
"combined" breaks when sigma >= sigma_max or tau >= tau_max; "separate" when any single
term reaches its strength. The normal (sigma) terms are evaluated only while L > L0 unless
compressive breakage is on, in which case always, with s = +1.
"""
import math

from ._registry import REQUIRED, physics
from .rotation import twist_sincos
from .vector import add, cross, dot, norm, scale, sub

INTACT, TENSION, COMPRESSION, SHEAR = 0, 1, 2, 3
BREAK_MODE_NAMES = ("intact", "tension", "compression", "shear")
CRITERION_NONE, CRITERION_COMBINED, CRITERION_SEPARATE = 0, 1, 2
CRITERION_CODES = {"none": CRITERION_NONE, "combined": CRITERION_COMBINED,
                   "separate": CRITERION_SEPARATE}

# The bond model's declaration (physics/bond_models.py). Its parameters are every bond
# material's, one schema for the scene file and the Python API (model.BondMaterial):
# type, default, then for numbers (low, high, include low, include high), for strings the
# allowed values.
NAME = "elastic"
LOADS = None        # the springs' loads themselves (bond_loads_on_particles)
STATE = None
VECTORISED = True
_INF = float("inf")
PARAMETERS = {
    "young_modulus": ("number", REQUIRED, 0.0, _INF, False, False),
    "poisson_ratio": ("number", 0.3, -1.0, 0.5, False, False),
    "normal_strength": ("number", _INF, 0.0, _INF, False, True),
    "tangential_strength": ("number", _INF, 0.0, _INF, False, True),
    "breakage": ("str", "combined", tuple(CRITERION_CODES), None, None, None),
    "compressive_breakage": ("bool", False, None, None, None, None),
    # per-bond strength scatter (model.Model.bond_strength_factors): every strength of
    # the bond (and a plastic bond's yield stress) times a factor of mean 1 drawn per bond
    "strength_scatter": ("str", "none", ("none", "normal", "weibull"), None, None, None),
    "strength_spread": ("number", 0.0, 0.0, _INF, True, False),
    "strength_seed": ("number", 0.0, 0.0, 2.0 ** 63, True, False),
}
UNITS = {"young_modulus": "Pa", "poisson_ratio": "-", "normal_strength": "Pa",
         "tangential_strength": "Pa", "strength_spread": "- (normal: coefficient of "
         "variation; weibull: the Weibull modulus)", "strength_seed": "-"}


def check(values, musen_compat=False):
    """[(key, message)]: a scatter needs its spread (a Weibull modulus above 0, a
    coefficient of variation of the normal law below 1) and a whole seed."""
    scatter, spread = values["strength_scatter"], values["strength_spread"]
    problems = []
    if scatter != "none" and spread <= 0.0:
        problems.append(("strength_spread", f"strength_scatter = {scatter!r} needs "
                                            "strength_spread > 0"))
    if scatter == "normal" and spread >= 1.0:
        problems.append(("strength_spread", f"{spread!r}: the coefficient of variation of "
                                            "a normal scatter must be below 1"))
    if values["strength_seed"] != int(values["strength_seed"]):
        problems.append(("strength_seed", f"{values['strength_seed']!r}: a whole number"))
    return problems
# MUSEN's counterpart (io/musen_text.py): its MODEL_SB name, MODEL_SB_PARAMS and bond
# material properties (ids of Databases/MaterialsDatabase/DefinesMDB.h) by bondem key;
# "strengths": whether it breaks by normal and tangential strength (CONSIDER_BREAKAGE).
MUSEN = {"model": "ModelSBElastic", "parameters": {}, "properties": {}, "strengths": True}


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """No limit beyond the springs' (timestep.py): {}."""
    return {}


@physics
def bond_stiffnesses(young_modulus, poisson_ratio, diameter, initial_length):
    """Linear spring constants of the bond: (E A/L0 in N/m, G A/L0 in N/m,
    G J/L0 in N m/rad, E I/L0 in N m/rad)."""
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    second_moment = 0.25 * area * radius * radius
    # Two divisions instead of five: this runs for every bond in every step.
    inverse_length = 1.0 / initial_length
    shear_modulus = 0.5 * young_modulus / (1.0 + poisson_ratio)
    return (young_modulus * area * inverse_length,
            shear_modulus * area * inverse_length,
            shear_modulus * 2.0 * second_moment * inverse_length,
            young_modulus * second_moment * inverse_length)


@physics
def elastic_bond(r, vi, vj, wi, wj, previous_axis, tangential_force, normal_moment,
                 tangential_moment, initial_length, normal_stiffness, shear_stiffness,
                 twist_stiffness, bending_stiffness, dt):
    """One step of the elastic bond law.

    r: x_j - x_i (m); vi, vj: velocities (m/s); wi, wj: angular velocities (rad/s);
    previous_axis: unit axis of the previous step; tangential_force (N), normal_moment and
    tangential_moment (N m): accumulated vectors on i, as stored by the previous step
    (tangential ones perpendicular to previous_axis, normal_moment parallel to it);
    stiffnesses from ``bond_stiffnesses``; dt: the increment's time (s).
    Returns (L, n, F_n, F_t, M_n, M_t), all on particle i, the accumulated vectors updated.
    """
    length = norm(r)
    n = scale(r, 1.0 / length)
    w_rel = sub(wi, wj)
    w_sum = add(wi, wj)
    v_rel = sub(sub(vj, vi), scale(cross(w_sum, r), 0.5))
    twist_sin, twist_cos, _ = twist_sincos(0.5 * dot(w_sum, n) * dt)

    # T = Q R (rotation.bond_rotate) with R's constants shared by the carried vectors.
    k = cross(previous_axis, n)
    c = dot(previous_axis, n)
    if c > -1.0 + 1e-12:
        inverse = 1.0 / (1.0 + c)
        # M_n is parallel to the previous axis and R carries that axis onto n, so
        # T M_n = n (n_prev . M_n) (the twist about n leaves it unchanged).
        carried_twist = dot(previous_axis, normal_moment)
    else:
        # Half turn: as align_rotate, keep the vectors rather than divide by 0.
        k = (0.0, 0.0, 0.0)
        c = 1.0
        inverse = 0.0
        carried_twist = dot(n, normal_moment)

    f_n = scale(n, normal_stiffness * (length - initial_length))
    # Q's term along n, (1 - cos b) n (n . R v), is left out: the projection below
    # removes it. The increments are made tangential first, though: adding the axial
    # parts of v_rel and w_rel (large when the bond stretches or twists) and projecting
    # them out after would cost F_t and M_t their low bits (round-off that grows in
    # tests/test_conservation.py's spinning cube).
    w_twist = dot(n, w_rel)
    u = add(add(scale(tangential_force, c), cross(k, tangential_force)),
            scale(k, dot(k, tangential_force) * inverse))
    f_t = add(add(scale(u, twist_cos), scale(cross(n, u), twist_sin)),
              scale(sub(v_rel, scale(n, dot(n, v_rel))), shear_stiffness * dt))
    u = add(add(scale(tangential_moment, c), cross(k, tangential_moment)),
            scale(k, dot(k, tangential_moment) * inverse))
    m_t = sub(add(scale(u, twist_cos), scale(cross(n, u), twist_sin)),
              scale(sub(w_rel, scale(n, w_twist)), bending_stiffness * dt))
    # Project onto the bond's planes: removes Q's axial term and the round-off.
    f_t = sub(f_t, scale(n, dot(n, f_t)))
    m_t = sub(m_t, scale(n, dot(n, m_t)))
    m_n = scale(n, carried_twist - twist_stiffness * dt * w_twist)
    return length, n, f_n, f_t, m_n, m_t


@physics
def bond_loads_on_particles(r, f_n, f_t, m_n, m_t):
    """Force on i (N), moment on i and moment on j (N m) from the bond's vectors."""
    shear_torque = cross(scale(r, 0.5), f_t)
    force_i = add(f_n, f_t)
    moment_i = add(add(m_n, m_t), shear_torque)
    moment_j = sub(shear_torque, add(m_n, m_t))
    return force_i, moment_i, moment_j


@physics
def bond_stresses(length, initial_length, f_n, f_t, m_n, m_t, diameter):
    """(sigma, tau) in Pa: signed normal stress (s = -1 in compression) and shear stress."""
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    second_moment = 0.25 * math.pi * radius ** 4
    sign = 1.0 if length > initial_length else -1.0
    sigma = sign * norm(f_n) / area + norm(m_t) * radius / second_moment
    tau = norm(f_t) / area + norm(m_n) * radius / (2.0 * second_moment)
    return sigma, tau


@physics
def bond_surely_intact(f_n, f_t, m_n, m_t, diameter, normal_strength, tangential_strength,
                       criterion):
    """True when no stress term can reach its strength: a cheap test without square roots
    (or branches) that ``bond_break_mode`` makes first; False means "test exactly".

    Each term squared against its strength squared (half its strength for "combined",
    where two terms add), with a margin far above round-off. Strengths in Pa.
    """
    # One division per bond: 1/A = (2/d)^2/pi, R/I = 4 (2/d)^3/pi, R/J = 2 (2/d)^3/pi.
    inverse_radius = 2.0 / diameter
    inverse_area = inverse_radius * inverse_radius * (1.0 / math.pi)
    bending_factor = 4.0 * inverse_area * inverse_radius
    margin = 0.999999 * (0.25 if criterion == CRITERION_COMBINED else 1.0)
    normal_limit = margin * normal_strength * normal_strength if normal_strength > 0.0 \
        else -1.0
    tangential_limit = margin * tangential_strength * tangential_strength \
        if tangential_strength > 0.0 else -1.0
    area_factor = inverse_area * inverse_area
    moment_factor = bending_factor * bending_factor
    return ((dot(f_n, f_n) * area_factor < normal_limit)
            & (dot(m_t, m_t) * moment_factor < normal_limit)
            & (dot(f_t, f_t) * area_factor < tangential_limit)
            & (0.25 * dot(m_n, m_n) * moment_factor < tangential_limit))


@physics
def bond_stress_terms(f_n, f_t, m_n, m_t, diameter):
    """The four stress terms of the break test (Pa): axial |F_n| / A_b, bending
    |M_t| R_b / I, shear |F_t| / A_b, torsion |M_n| R_b / J; loads in N and N m,
    diameter in m."""
    inverse_radius = 2.0 / diameter
    inverse_area = inverse_radius * inverse_radius * (1.0 / math.pi)
    bending_factor = 4.0 * inverse_area * inverse_radius
    return (norm(f_n) * inverse_area, norm(m_t) * bending_factor, norm(f_t) * inverse_area,
            norm(m_n) * (0.5 * bending_factor))


@physics
def bond_failures(length, initial_length, f_n, f_t, m_n, m_t, diameter, normal_strength,
                  tangential_strength, criterion, compressive_breakage):
    """(the normal stress reaches its strength where it is checked, the tangential stress
    reaches its) under ``criterion`` _COMBINED or _SEPARATE; the arguments and units of
    ``bond_break_mode``."""
    axial, bending, shear, torsion = bond_stress_terms(f_n, f_t, m_n, m_t, diameter)
    normal_checked = length > initial_length or compressive_breakage
    if criterion == CRITERION_COMBINED:
        return (normal_checked and axial + bending >= normal_strength,
                shear + torsion >= tangential_strength)
    return (normal_checked and (axial >= normal_strength or bending >= normal_strength),
            shear >= tangential_strength or torsion >= tangential_strength)


@physics
def bond_breaks(length, initial_length, f_n, f_t, m_n, m_t, diameter, normal_strength,
                tangential_strength, criterion, compressive_breakage):
    """``bond_break_mode`` != INTACT without ``bond_surely_intact`` first: the vectorised
    bond kernel's exact test of the bonds that test could not clear. Same arguments and
    units as ``bond_break_mode``."""
    if criterion == CRITERION_NONE:
        return False
    normal, tangential = bond_failures(length, initial_length, f_n, f_t, m_n, m_t, diameter,
                                       normal_strength, tangential_strength, criterion,
                                       compressive_breakage)
    return normal or tangential


@physics
def bond_break_mode(length, initial_length, f_n, f_t, m_n, m_t, diameter, normal_strength,
                    tangential_strength, criterion, compressive_breakage):
    """INTACT, or the mode (TENSION, COMPRESSION, SHEAR) in which the bond breaks now.

    Strengths in Pa; criterion is CRITERION_NONE, _COMBINED or _SEPARATE.
    """
    if criterion == CRITERION_NONE:
        return INTACT
    if bond_surely_intact(f_n, f_t, m_n, m_t, diameter, normal_strength,
                          tangential_strength, criterion):
        return INTACT
    normal, tangential = bond_failures(length, initial_length, f_n, f_t, m_n, m_t, diameter,
                                       normal_strength, tangential_strength, criterion,
                                       compressive_breakage)
    if normal:
        return TENSION if length > initial_length else COMPRESSION
    if tangential:
        return SHEAR
    return INTACT


@physics
def bond_elastic_energy(length, initial_length, f_t, m_n, m_t, normal_stiffness,
                        shear_stiffness, twist_stiffness, bending_stiffness):
    """Elastic energy stored in the bond (J): the four springs' potentials."""
    stretch = length - initial_length
    return (0.5 * normal_stiffness * stretch * stretch
            + 0.5 * dot(f_t, f_t) / shear_stiffness
            + 0.5 * dot(m_n, m_n) / twist_stiffness
            + 0.5 * dot(m_t, m_t) / bending_stiffness)

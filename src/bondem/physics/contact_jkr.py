"""JKR adhesive elastic contact (Johnson, Kendall & Roberts 1971), with its hysteresis.

The normal law of two adhesive elastic spheres with work of adhesion w (J/m^2, the
materials' ``surface_energy``, mixed as sqrt(w_i w_j) as MUSEN mixes it), E* and R* as
Hertz-Mindlin's. The contact radius a (m) follows from the overlap delta (m, negative
beyond contact) on the stable branch of
    delta = a^2 / R* - sqrt(2 pi w a / E*)
and the elastic normal force (repulsive > 0) and its potential are
    F(a) = 4 E* a^3 / (3 R*) - sqrt(8 pi w E* a^3)
    U(a) = 8 E* a^5 / (15 R*^2) - 4/3 E* k a^(7/2) / R* + E* k^2 a^2 / 2 - U(a_c),
    k = sqrt(2 pi w / E*),  a_c = (pi w R*^2 / (8 E*))^(1/3),
with U = integral of F d(delta) from the pull-off point (a_c, delta = -delta_c), so that
the potential is zero when the neck breaks. Closed forms this law reaches exactly:
the pull-off force (load control, the least F) -3/2 pi w R*; the contact radius at zero
load a_0 = (9 pi w R*^2 / (2 E*))^(1/3); the pull-off separation (displacement control)
    delta_c = 3/4 (pi^2 w^2 R* / E*^2)^(1/3),  F(-delta_c) = -5/6 pi w R*.
Hysteresis: a contact forms when the surfaces touch (delta > 0) and then holds, neck
stretched, until delta <= -delta_c (``REACH``, ``HYSTERETIC``); approaching surfaces feel
nothing before they touch. At the touch the potential jumps from 0 to U(delta = 0) < 0:
the loops book that jump, the energy of the whole approach-and-pull-off cycle, as
dissipated (the snap-in's kinetic energy goes into elastic waves, which a DEM contact
does not resolve).
Damping as Hertz-Mindlin's with S_n = 2 E* a, tangential stiffness S_t = 8 G* a, and the
Coulomb and rolling limits of the adhesive load F + 2 F_c (F_c = 3/2 pi w R*), as LAMMPS's
granular jkr and Thornton & Yin (1991) take it: an adhesive contact resists sliding at
zero load. With w = 0 the law is Hertz-Mindlin's (a = sqrt(R* delta)).
The contact radius is the quartic's largest root in closed form (Ferrari's, as LAMMPS's
granular jkr takes it): s = sqrt(a) solves s^4 - k R* s - R* delta = 0, which factors into
(s^2 + u s + v)(s^2 - u s + v') with z = u^2 the positive root of the resolvent cubic
z^3 + 4 R* delta z - k^2 R*^2 = 0; its discriminant is >= 0 exactly for delta >= -delta_c,
so Cardano's one real root serves the whole stable branch, written as a quotient of
positive terms (no cancellation when Hertz's part dominates). Half the cost of the
Newton solve it replaced (5.35 passes per contact on the adhesive bed;
docs/performance.md).
"""
import math

from ._registry import (PAIR_BETA, PAIR_E_STAR, PAIR_FRICTION, PAIR_G_STAR, PAIR_MODEL,
                        PAIR_ROLLING, physics)
from .contact_hertz import SQRT_5_6, friction_and_rolling
from .vector import add, dot, scale, sub

NAME = "jkr"
PARAMETERS = {"surface_energy": (("number", 0.0, 0.0, math.inf, True, False), "geometric")}
UNITS = {"surface_energy": "J/m^2"}
LAW = "jkr_law"
REACH = "jkr_pull_off_gap"
HYSTERETIC = True
# MUSEN's ModelPPJKR / ModelPWJKR (musen_compat: contact_hertz_musen's MUSEN_JKR), with
# the surface energy, material property 11, as w
MUSEN = {"pp": "ModelPPJKR", "pw": "ModelPWJKR", "kind_pp": 1, "kind_pw": 1,
         "properties": {"surface_energy": 11}}
SURFACE_ENERGY = PAIR_MODEL
# k = sqrt(2 pi w / E*) once per pair of materials: a division and a square root the law
# took per contact and step
CONSTANTS = ("adhesion_k",)
ADHESION_K = PAIR_MODEL + 1


@physics
def jkr_k(w, e_star):
    """k = sqrt(2 pi w / E*) (m^1/2) of work of adhesion w (J/m^2) and E* (Pa)."""
    return math.sqrt(2.0 * math.pi * w / e_star)


def constants(values):
    """(k, ``jkr_k``,) of a pair's mixed surface energy w (J/m^2) and its E* (Pa,
    ``values["e_star"]``)."""
    return (jkr_k(values["surface_energy"], values["e_star"]),)


@physics
def jkr_root(overlap, r_star, k):
    """(s, s_c): s = sqrt(a), a the contact radius (m) on JKR's stable branch at overlap
    (m) for R* (m) and k = sqrt(2 pi w / E*) (m^1/2), that is the largest root of
    s^4 / R* - k s = overlap (overlap >= -delta_c; else the tip's, s_c); s_c = sqrt(a_c)
    = (k R* / 4)^(1/3), the root at pull-off."""
    kr = k * r_star
    if kr == 0.0:
        # Hertz: a = sqrt(R* delta) (if-expressions: numba's CUDA target has no max)
        return math.sqrt(math.sqrt(r_star * overlap if overlap > 0.0 else 0.0)), 0.0
    s_c = (0.25 * kr) ** (1.0 / 3.0)
    # the resolvent z^3 + 3 p z - 2 h = 0: p = 4/3 R* delta, h = (k R*)^2 / 2
    p = 4.0 / 3.0 * r_star * overlap
    h = 0.5 * kr * kr
    disc = h * h + p * p * p
    if not disc > 0.0:
        return s_c, s_c
    # Cardano's z = c + c', c = cbrt(h + sqrt(disc)), c c' = -p; as 2h / (c^2 - c c' +
    # c'^2) = 2h c^2 / (c^4 + p c^2 + p^2), a sum of positive terms where p > 0 (one
    # division)
    c = (h + math.sqrt(disc)) ** (1.0 / 3.0)
    cc = c * c
    z = 2.0 * h * cc / (cc * cc + p * cc + p * p)
    u = math.sqrt(z)
    # the larger root of s^2 - u s + v' = 0, v' = (z - k R* / u) / 2
    rest = 2.0 * kr / u - z
    return 0.5 * (u + math.sqrt(rest if rest > 0.0 else 0.0)), s_c


@physics
def jkr_contact_radius(overlap, r_star, e_star, w):
    """Contact radius a (m) on JKR's stable branch at overlap (m) for R* (m), E* (Pa) and
    work of adhesion w (J/m^2); overlap >= -delta_c (else the value at the tip)."""
    s, _ = jkr_root(overlap, r_star, jkr_k(w, e_star))
    return s * s


# The force and the potential in s = sqrt(a), k and 1/R*: sqrt(8 pi w E* a^3) =
# 2 E* k s^3, and with a_c^(3/2) = k R* / 4 the potential at pull-off is E* k^2 a_c^2 / 5;
# so no powers beyond products and no division (the law's cost per contact,
# docs/performance.md)
@physics
def jkr_force_of_root(s, inverse_r, e_star, k):
    """JKR's elastic normal force (N, repulsive > 0) at s = sqrt(a) (m^1/2), inverse_r =
    1/R* (1/m)."""
    s3 = s * s * s
    return e_star * s3 * (4.0 / 3.0 * s3 * inverse_r - 2.0 * k)


@physics
def jkr_potential_of_root(s, s_c, inverse_r, e_star, k):
    """JKR's elastic energy (J) at s = sqrt(a), zero at pull-off (s_c = sqrt(a_c));
    inverse_r = 1/R* (1/m)."""
    a = s * s
    s3 = a * s
    at_a = (8.0 / 15.0 * a * a * a * a * a * inverse_r * inverse_r
            - 4.0 / 3.0 * k * s3 * s3 * s * inverse_r + 0.5 * k * k * a * a)
    a_c = s_c * s_c
    return e_star * (at_a - 0.2 * k * k * a_c * a_c)


@physics
def jkr_force(a, r_star, e_star, w):
    """JKR's elastic normal force (N, repulsive > 0) at contact radius a (m)."""
    return jkr_force_of_root(math.sqrt(a), 1.0 / r_star, e_star, jkr_k(w, e_star))


@physics
def jkr_potential(a, r_star, e_star, w):
    """JKR's elastic energy (J) at contact radius a (m), zero at the pull-off point."""
    k = jkr_k(w, e_star)
    return jkr_potential_of_root(math.sqrt(a), (0.25 * r_star * k) ** (1.0 / 3.0),
                                 1.0 / r_star, e_star, k)


@physics
def jkr_pull_off_gap(pair, q, r_star):
    """delta_c = 3/4 (pi^2 w^2 R* / E*^2)^(1/3) (m): the gap at which a JKR neck breaks
    (row q of the pair table, R* in m)."""
    w = pair[q, SURFACE_ENERGY]
    e_star = pair[q, PAIR_E_STAR]
    return 0.75 * (math.pi * math.pi * w * w * r_star / (e_star * e_star)) ** (1.0 / 3.0)


@physics
def jkr_law(n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt):
    """One step of the JKR law (module docstring); arguments and results as
    contact_models.LAW."""
    e_star = pair[q, PAIR_E_STAR]
    g_star = pair[q, PAIR_G_STAR]
    beta = pair[q, PAIR_BETA]
    w = pair[q, SURFACE_ENERGY]
    k = pair[q, ADHESION_K]
    inverse_r = 1.0 / r_star
    v_n = dot(v_rel, n)
    v_t = sub(v_rel, scale(n, v_n))
    root, root_c = jkr_root(overlap, r_star, k)
    a = root * root
    s_n = 2.0 * e_star * a
    s_t = 8.0 * g_star * a
    c_n = -2.0 * SQRT_5_6 * beta * math.sqrt(s_n * m_star)
    c_t = -2.0 * SQRT_5_6 * beta * math.sqrt(s_t * m_star)
    f_n = jkr_force_of_root(root, inverse_r, e_star, k) - c_n * v_n
    # the limits of an adhesive contact: its load plus twice the pull-off force
    load = f_n + 3.0 * math.pi * w * r_star
    f_t, torque, xi = friction_and_rolling(n, v_t, w_rel, spring, load, s_t, c_t,
                                           pair[q, PAIR_FRICTION], pair[q, PAIR_ROLLING],
                                           r_star, i_star, dt)
    energy = (jkr_potential_of_root(root, root_c, inverse_r, e_star, k)
              + 0.5 * s_t * dot(xi, xi))
    return add(scale(n, -f_n), f_t), torque, f_t, xi, energy

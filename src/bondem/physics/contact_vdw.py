"""Hertz-Mindlin plus van der Waals attraction (Hamaker 1937), for dry fine powders.

Two spheres whose surfaces are a gap h (m) apart attract with Hamaker's near-field force
(Derjaguin's approximation, h << R*):
    F_vdW = A R* / (6 max(h, h_0)^2)   for h < h_cut,  0 beyond,
A the Hamaker constant (J, the materials' ``hamaker_constant``, mixed as sqrt(A_i A_j),
the usual combining rule), h_0 the minimum separation (m, ``vdw_min_distance``, default
0.4 nm: the force saturates at contact, at A R* / (6 h_0^2)), h_cut the cut-off
(``vdw_cutoff``, m: the neighbour lists reach that far). A wall is a sphere of infinite
radius, R* = r. In contact (overlap > 0) the saturated force adds to Hertz-Mindlin's
(DMT-like), and the Coulomb and rolling limits take the total load F_n + F_vdW: the
attraction presses the surfaces together.
Its potential, zero at the cut-off (the force drops to zero there, its energy does not
jump): U(h) = -A R* / (6 h) + A R* / (6 h_cut) for h >= h_0, continued linearly
(constant force) below h_0, and Hertz-Mindlin's potential on top in contact. Every pair
within the cut-off attracts (``HYSTERETIC`` False): no history beyond the spring.
"""
import math

from ._registry import (PAIR_BETA, PAIR_E_STAR, PAIR_FRICTION, PAIR_G_STAR, PAIR_MODEL,
                        PAIR_ROLLING, physics)
from .contact_hertz import hertz_mindlin_pulled
from .vector import add, scale

NAME = "vdw"
PARAMETERS = {
    "hamaker_constant": (("number", 0.0, 0.0, math.inf, True, False), "geometric"),
    "vdw_min_distance": (("number", 4e-10, 0.0, math.inf, False, False), "mean"),
    "vdw_cutoff": (("number", 1e-7, 0.0, math.inf, False, False), "mean"),
}
UNITS = {"hamaker_constant": "J", "vdw_min_distance": "m", "vdw_cutoff": "m"}
LAW = "vdw_law"
REACH = "vdw_reach"
HYSTERETIC = False
# MUSEN's ModelPPHertzMindlinVdW (musen_compat: contact_hertz_musen's MUSEN_VDW) derives
# Hamaker's constant from the surface energy, 24 pi Dmin^2 w; it has no wall model
MUSEN = {"pp": "ModelPPHertzMindlinVdW", "pw": "ModelPWHertzMindlin", "kind_pp": 2,
         "kind_pw": 0}
HAMAKER, MIN_DISTANCE, CUTOFF = PAIR_MODEL, PAIR_MODEL + 1, PAIR_MODEL + 2


def check(values):
    """[(key, message)]: the cut-off must lie beyond the minimum separation."""
    if values["vdw_cutoff"] <= values["vdw_min_distance"]:
        return [("vdw_cutoff", f"vdw_cutoff = {values['vdw_cutoff']!r} m must exceed "
                               f"vdw_min_distance = {values['vdw_min_distance']!r} m")]
    return []


@physics
def vdw_reach(pair, q, r_star):
    """The cut-off gap h_cut (m) of row q of the pair table (0 without attraction)."""
    if pair[q, HAMAKER] == 0.0:
        return 0.0
    return pair[q, CUTOFF]


@physics
def vdw_force(gap, r_star, hamaker, h_0):
    """Attraction (N, > 0) across a gap (m; <= h_0, contact included, saturates)."""
    h = h_0 if gap < h_0 else gap
    return hamaker * r_star / (6.0 * h * h)


@physics
def vdw_potential(gap, r_star, hamaker, h_0, h_cut):
    """Potential (J) of the attraction at a gap (m), zero at the cut-off h_cut."""
    u_cut = -hamaker * r_star / (6.0 * h_cut)
    if gap >= h_0:
        return -hamaker * r_star / (6.0 * gap) - u_cut
    return (-hamaker * r_star / (6.0 * h_0)
            + hamaker * r_star / (6.0 * h_0 * h_0) * (h_0 - gap) - u_cut)


@physics
def vdw_law(n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt):
    """One step of Hertz-Mindlin plus van der Waals (module docstring); arguments and
    results as contact_models.LAW."""
    hamaker = pair[q, HAMAKER]
    h_0 = pair[q, MIN_DISTANCE]
    pull = vdw_force(-overlap, r_star, hamaker, h_0)
    energy = vdw_potential(-overlap, r_star, hamaker, h_0, pair[q, CUTOFF])
    if overlap <= 0.0:
        return scale(n, pull), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), energy
    force, torque, f_t, xi, elastic = hertz_mindlin_pulled(
        n, overlap, v_rel, w_rel, spring, pair[q, PAIR_E_STAR], pair[q, PAIR_G_STAR], r_star,
        m_star, i_star, pair[q, PAIR_BETA], pair[q, PAIR_FRICTION], pair[q, PAIR_ROLLING],
        dt, pull)
    return add(force, scale(n, pull)), torque, f_t, xi, elastic + energy

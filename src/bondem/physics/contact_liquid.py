"""Hertz-Mindlin plus a pendular liquid bridge: capillary attraction and viscous lubrication.

A bridge of volume V (m^3, the materials' ``bridge_volume``), surface tension gamma (N/m,
``surface_tension``), contact angle theta (degrees, ``contact_angle``) and viscosity eta
(Pa s, ``viscosity``) forms when two surfaces touch and holds until their gap s (m)
reaches the rupture distance of Lian, Thornton & Adams (1993)
    s_rup = (1 + theta/2) V^(1/3)            (theta in radians).
Capillary force (Rabinovich et al. 2005, its meniscus term; attractive, N): with the
immersion height d_sp = s/2 (-1 + sqrt(1 + 2V / (pi R* s^2))),
    F_cap = 2 pi R* gamma cos(theta) / (1 + s / (2 d_sp))
          = 2 pi R* gamma cos(theta) (1 - s / sqrt(s^2 + c)),   c = 2V / (pi R*),
which is 2 pi R* gamma cos(theta) at contact (and held at that in contact), with the
potential U(s) = F_0 ((s - sqrt(s^2 + c)) - (s_rup - sqrt(s_rup^2 + c))) <= 0, zero at
rupture (continued linearly into overlap). Viscous lubrication (Reynolds; Goldman, Cox
& Brenner 1967 for the tangential part), on the gap held at least ``bridge_min_gap``
s_min (m):
    F_n,visc = -6 pi eta R*^2 v_n / s,   F_t,visc = 6 pi eta R* (8/15 ln(R*/s) + 0.9588) v_t
(v_n < 0 approaching: the film resists approach and separation alike). In contact the
bridge adds to Hertz-Mindlin's forces, and its capillary pull adds to the load of the
Coulomb and rolling limits. A wall is a sphere of infinite radius: R* = r. Mixing: the
mean of the two materials' values (one liquid wets both).
The energy that the viscous forces and the bridge's snap-in take is booked as
dissipated by the loops' work balance.
"""
import math

from ._registry import (PAIR_BETA, PAIR_E_STAR, PAIR_FRICTION, PAIR_G_STAR, PAIR_MODEL,
                        PAIR_ROLLING, physics)
from .contact_hertz import hertz_mindlin_pulled
from .vector import add, dot, scale, sub

NAME = "liquid_bridge"
_MEAN = "mean"
PARAMETERS = {
    "surface_tension": (("number", 0.0, 0.0, math.inf, True, False), _MEAN),
    "contact_angle": (("number", 0.0, 0.0, 90.0, True, False), _MEAN),
    "bridge_volume": (("number", 0.0, 0.0, math.inf, True, False), _MEAN),
    "viscosity": (("number", 0.0, 0.0, math.inf, True, False), _MEAN),
    "bridge_min_gap": (("number", 1e-7, 0.0, math.inf, False, False), _MEAN),
}
UNITS = {"surface_tension": "N/m", "contact_angle": "degree", "bridge_volume": "m^3",
         "viscosity": "Pa s", "bridge_min_gap": "m"}
LAW = "liquid_bridge_law"
REACH = "bridge_rupture_distance"
HYSTERETIC = True
TENSION, ANGLE, VOLUME, VISCOSITY, MIN_GAP, COS_ANGLE, RUPTURE = range(PAIR_MODEL,
                                                                      PAIR_MODEL + 7)
# constants of a pair of materials: the law took the cosine and the cube root per contact
# and step (the adhesive bed's step 1.5-2.0x -> 1.4x Hertz-Mindlin's, docs/performance.md)
CONSTANTS = ("cos_angle", "rupture_distance")


def constants(values):
    """(cos theta, Lian et al.'s rupture distance (1 + theta/2) V^(1/3) in m, 0 without
    liquid) of a pair's mixed values (module docstring)."""
    theta = values["contact_angle"] * math.pi / 180.0
    volume = values["bridge_volume"]
    rupture = (1.0 + 0.5 * theta) * volume ** (1.0 / 3.0) if volume > 0.0 else 0.0
    return math.cos(theta), rupture


def time_scales(model):
    """{"liquid_viscous": s}: m* s_min / (6 pi eta R*^2) of the most damped self-pair
    (m* = m/2, R* = r/2), the step an explicit dashpot of the film needs; none without
    viscosity."""
    import numpy as np
    eta = np.array([m.viscosity for m in model.materials])[model.material]
    gap = np.array([m.bridge_min_gap for m in model.materials])[model.material]
    wet = eta > 0.0
    if not np.any(wet):
        return {}
    r_star = 0.5 * model.radius[wet]
    scale = 0.5 * model.mass[wet] * gap[wet] / (6.0 * math.pi * eta[wet] * r_star * r_star)
    return {"liquid_viscous": float(scale.min())}


@physics
def bridge_rupture_distance(pair, q, r_star):
    """Lian et al.'s rupture distance (1 + theta/2) V^(1/3) (m) of row q's bridge (0
    without liquid; ``constants``)."""
    return pair[q, RUPTURE]


# The force and the potential take f_0 = 2 pi R* gamma cos(theta) (N) and c = 2 V / (pi
# R*) (m^2), which the law computes once per contact for both
@physics
def capillary_force(gap, f_0, c):
    """Rabinovich's capillary attraction (N, > 0) across a gap (m; contact: gap <= 0)."""
    if gap <= 0.0:
        return f_0
    return f_0 * (1.0 - gap / math.sqrt(gap * gap + c))


@physics
def capillary_potential(gap, f_0, c, rupture):
    """The bridge's potential (J, <= 0) at a gap (m), zero at the rupture distance (m)."""
    at_rupture = rupture - math.sqrt(rupture * rupture + c)
    if gap <= 0.0:
        return f_0 * (-math.sqrt(c) - at_rupture + gap)
    return f_0 * (gap - math.sqrt(gap * gap + c) - at_rupture)


@physics
def liquid_bridge_law(n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt):
    """One step of Hertz-Mindlin plus a liquid bridge (module docstring); arguments and
    results as contact_models.LAW."""
    tension = pair[q, TENSION]
    volume = pair[q, VOLUME]
    viscosity = pair[q, VISCOSITY]
    gap = -overlap
    pull = 0.0
    energy = 0.0
    if volume > 0.0:
        f_0 = 2.0 * math.pi * r_star * tension * pair[q, COS_ANGLE]
        c = 2.0 * volume / (math.pi * r_star)
        pull = capillary_force(gap, f_0, c)
        energy = capillary_potential(gap, f_0, c, pair[q, RUPTURE])
    film = gap if gap > pair[q, MIN_GAP] else pair[q, MIN_GAP]
    v_n = dot(v_rel, n)
    v_t = sub(v_rel, scale(n, v_n))
    f_visc = -6.0 * math.pi * viscosity * r_star * r_star * v_n / film
    f_t_visc = scale(v_t, 6.0 * math.pi * viscosity * r_star
                     * (8.0 / 15.0 * math.log(r_star / film) + 0.9588))
    liquid = scale(n, pull - f_visc)
    if overlap <= 0.0:
        return add(liquid, f_t_visc), (0.0, 0.0, 0.0), f_t_visc, (0.0, 0.0, 0.0), energy
    force, torque, f_t, xi, elastic = hertz_mindlin_pulled(
        n, overlap, v_rel, w_rel, spring, pair[q, PAIR_E_STAR], pair[q, PAIR_G_STAR], r_star,
        m_star, i_star, pair[q, PAIR_BETA], pair[q, PAIR_FRICTION], pair[q, PAIR_ROLLING],
        dt, pull)
    f_t = add(f_t, f_t_visc)
    return add(add(force, liquid), f_t_visc), torque, f_t, xi, elastic + energy

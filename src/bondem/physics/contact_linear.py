"""Linear spring-dashpot contact (Cundall & Strack 1979), the alternative to Hertz-Mindlin.

Same geometry, friction and rolling resistance as ``contact_hertz`` (see there), with
constant stiffnesses k_n, k_t (N/m) and the damping that gives exactly the restitution e
of a linear oscillator (force not clipped):
    beta = ln e / sqrt(ln^2 e + pi^2),  c_n = -2 beta sqrt(k_n m*),  c_t = -2 beta sqrt(k_t m*)
    f_n = k_n delta - c_n v_n,  F_t = k_t xi - c_t v_t (Coulomb-limited)
Contact time t_c = pi / sqrt(k_n/m* - (c_n / 2 m*)^2). Stiffnesses come from the contact
settings (default k_n = 2 E* sqrt(R* delta_ref), the Hertz stiffness S_n at the reference
overlap delta_ref = 0.01 R*, and k_t = k_n S_t/S_n = 4 k_n G*/E*).
"""
import math

from ._registry import (PAIR_BETA, PAIR_E_STAR, PAIR_FRICTION, PAIR_G_STAR, PAIR_ROLLING,
                        PAIR_STIFFNESS, physics)
from .contact_hertz import friction_and_rolling
from .vector import add, dot, scale, sub

# The linear law's default stiffness: Hertz's k_n at an overlap of
# LINEAR_REFERENCE_OVERLAP R*.
LINEAR_REFERENCE_OVERLAP = 0.01

# The contact model (physics/contact_models.py); its k_n is a contact setting
# (ContactSettings.linear_stiffness), column PAIR_STIFFNESS of the pair table.
NAME = "linear"
PARAMETERS = {}
UNITS = {}
LAW = "linear_law"


@physics
def linear_spring_dashpot(n, overlap, v_rel, w_rel, spring, k_n, k_t, r_star, m_star, i_star,
                          beta, friction, rolling_friction, dt):
    """One step of the linear law for a contact with overlap > 0 (m); arguments and
    results as ``hertz_mindlin`` but with stiffnesses k_n, k_t in N/m."""
    v_n = dot(v_rel, n)
    v_t = sub(v_rel, scale(n, v_n))
    c_n = -2.0 * beta * math.sqrt(k_n * m_star)
    c_t = -2.0 * beta * math.sqrt(k_t * m_star)
    f_n = k_n * overlap - c_n * v_n
    f_t, torque, xi = friction_and_rolling(n, v_t, w_rel, spring, f_n, k_t, c_t, friction,
                                           rolling_friction, r_star, i_star, dt)
    energy = 0.5 * k_n * overlap * overlap + 0.5 * k_t * dot(xi, xi)
    return add(scale(n, -f_n), f_t), torque, f_t, xi, energy


@physics
def linear_law(n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt):
    """``linear_spring_dashpot`` with the pair's properties from row q of the pair table:
    k_n its PAIR_STIFFNESS (N/m; <= 0 for the default, Hertz's at 1 % of R*) and
    k_t = 4 k_n G*/E*."""
    e_star = pair[q, PAIR_E_STAR]
    k_n = pair[q, PAIR_STIFFNESS]
    if k_n <= 0.0:
        k_n = 2.0 * e_star * math.sqrt(LINEAR_REFERENCE_OVERLAP) * r_star
    return linear_spring_dashpot(n, overlap, v_rel, w_rel, spring, k_n,
                                 4.0 * k_n * pair[q, PAIR_G_STAR] / e_star, r_star, m_star,
                                 i_star, pair[q, PAIR_BETA], pair[q, PAIR_FRICTION],
                                 pair[q, PAIR_ROLLING], dt)

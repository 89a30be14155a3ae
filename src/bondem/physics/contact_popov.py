"""Popov's approximation of the JKR force (MUSEN's PopovJKR), with JKR's hysteresis.

Popov, Hess & Willert (Handbook of Contact Mechanics, 2019) fit the JKR force-overlap
curve of two adhesive spheres by one power law; MUSEN 1.74.2 ships it as ModelPPPopovJKR /
ModelPWPopovJKR. With w the work of adhesion (J/m^2, ``surface_energy`` as JKR's, which
MUSEN reads from the surface tension property), E* and R* as Hertz-Mindlin's:
    F_A = 3/2 pi w R*                                (JKR's pull-off force)
    S   = (0.4626 (w/E*)^2 R*)^(1/3)                 (the overlap scale)
    F(delta) = F_A (-1 + 0.12 (1 + delta/S)^(5/3))   repulsive > 0, for delta >= -S
At delta = 0 it is -0.88 F_A (JKR: -8/9), at delta = -S the least force -F_A. Its
potential, zero where the neck breaks (delta = -S):
    U(delta) = F_A (-(delta + S) + 0.045 S (1 + delta/S)^(8/3)).
Hysteresis as JKR's (``REACH`` S, ``HYSTERETIC``): the contact forms at touch and holds
beyond contact until delta <= -S. The stiffnesses of the damping and the tangential spring
are Hertz's, S_n = 2 E* a, S_t = 8 G* a with a = sqrt(R* delta): beyond contact (delta <
0) the neck has neither (MUSEN's model stops at delta = 0), only the adhesive force. The
Coulomb and rolling limits take F + 2 F_A, as JKR's.
"""
import math

from ._registry import (PAIR_BETA, PAIR_E_STAR, PAIR_FRICTION, PAIR_G_STAR, PAIR_MODEL,
                        PAIR_ROLLING, physics)
from .contact_hertz import SQRT_5_6, friction_and_rolling
from .contact_jkr import PARAMETERS as JKR_PARAMETERS
from .vector import add, dot, scale, sub

NAME = "popov_jkr"
PARAMETERS = {"surface_energy": JKR_PARAMETERS["surface_energy"]}
UNITS = {"surface_energy": "J/m^2"}
LAW = "popov_law"
REACH = "popov_reach"
HYSTERETIC = True
# MUSEN's ModelPPPopovJKR / ModelPWPopovJKR (musen_compat: contact_hertz_musen's
# MUSEN_POPOV); MUSEN reads w from the surface tension, material property 13
MUSEN = {"pp": "ModelPPPopovJKR", "pw": "ModelPWPopovJKR", "kind_pp": 3, "kind_pw": 3,
         "properties": {"surface_energy": 13}}
SURFACE_ENERGY = PAIR_MODEL


@physics
def popov_scale(w, e_star, r_star):
    """Popov's overlap scale S = (0.4626 (w/E*)^2 R*)^(1/3) (m)."""
    ratio = w / e_star
    return (0.4626 * ratio * ratio * r_star) ** (1.0 / 3.0)


@physics
def popov_reach(pair, q, r_star):
    """The gap S (m) at which a Popov neck breaks (row q of the pair table)."""
    return popov_scale(pair[q, SURFACE_ENERGY], pair[q, PAIR_E_STAR], r_star)


@physics
def popov_force(overlap, w, e_star, r_star):
    """(force N, repulsive > 0; potential J, zero at delta = -S) at overlap (m)."""
    f_a = 1.5 * math.pi * w * r_star
    s = popov_scale(w, e_star, r_star)
    x = 1.0 + overlap / s
    if x < 0.0:
        x = 0.0
    return (f_a * (-1.0 + 0.12 * x ** (5.0 / 3.0)),
            f_a * (-(overlap + s) + 0.045 * s * x ** (8.0 / 3.0)))


@physics
def popov_law(n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt):
    """One step of Popov's JKR (module docstring); arguments and results as
    contact_models.LAW."""
    e_star = pair[q, PAIR_E_STAR]
    w = pair[q, SURFACE_ENERGY]
    force, energy = popov_force(overlap, w, e_star, r_star)
    if overlap <= 0.0:
        return scale(n, -force), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), energy
    v_n = dot(v_rel, n)
    v_t = sub(v_rel, scale(n, v_n))
    a = math.sqrt(r_star * overlap)
    s_t = 8.0 * pair[q, PAIR_G_STAR] * a
    c_n = -2.0 * SQRT_5_6 * pair[q, PAIR_BETA] * math.sqrt(2.0 * e_star * a * m_star)
    c_t = -2.0 * SQRT_5_6 * pair[q, PAIR_BETA] * math.sqrt(s_t * m_star)
    f_n = force - c_n * v_n
    f_t, torque, xi = friction_and_rolling(n, v_t, w_rel, spring,
                                           f_n + 3.0 * math.pi * w * r_star, s_t, c_t,
                                           pair[q, PAIR_FRICTION], pair[q, PAIR_ROLLING],
                                           r_star, i_star, dt)
    return add(scale(n, -f_n), f_t), torque, f_t, xi, energy + 0.5 * s_t * dot(xi, xi)

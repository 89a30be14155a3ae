"""Hertz-Mindlin contact with restitution damping, Coulomb friction and rolling resistance.

One contact between particle i and a partner j (another particle or a wall), SPEC section 3.
n is the unit normal from i towards j, delta > 0 the overlap. Effective properties of the pair
(wall: R* = r_i, m* = m_i):
    1/E* = (1 - nu_i^2)/E_i + (1 - nu_j^2)/E_j
    1/G* = 2 (2 - nu_i)(1 + nu_i)/E_i + 2 (2 - nu_j)(1 + nu_j)/E_j
    1/R* = 1/r_i + 1/r_j,   1/m* = 1/m_i + 1/m_j
Restitution e, friction mu and rolling friction mu_r of a pair are the means of the two
materials' values (a wall has its own material).

Relative velocity of j's surface with respect to i's at the contact point (lever arms
a_i = r_i - delta/2, a_j = r_j - delta/2 for particles; a_i = distance to the wall, a_j = 0
for walls):
    v_rel = v_j - v_i - (a_i w_i + a_j w_j) x n,  v_n = v_rel . n (< 0 approaching),
    v_t = v_rel - v_n n
Normal (Hertz 1882; damping of Tsuji et al. 1992 in the EDEM form, Cundall & Strack
1979 for the idea; Antypov & Elliott 2011 show it gives exactly e at any velocity when the
force is not clipped, so it is not clipped here):
    beta = ln e / sqrt(ln^2 e + pi^2),  S_n = 2 E* sqrt(R* delta)
    f_n = 4/3 E* sqrt(R*) delta^(3/2) + 2 sqrt(5/6) beta sqrt(S_n m*) v_n   (repulsive > 0)
Tangential (Mindlin 1949 no-slip stiffness, EDEM form):
    S_t = 8 G* sqrt(R* delta)
    xi  = xi_prev projected onto the current contact plane and rescaled to |xi_prev|, + v_t dt
    F_t = S_t xi - 2 sqrt(5/6) beta sqrt(S_t m*) v_t            (on i, drags i along j)
    Coulomb: if |F_t| > mu max(f_n, 0): F_t scaled to mu max(f_n, 0) and xi = F_t / S_t
Rolling resistance (constant directional torque, EDEM's "type A", Ai et al. 2011):
    w_roll = (w_i - w_j) tangential part,  M_r = -mu_r R* max(f_n, 0) w_roll / |w_roll| on i
    capped at |w_roll| I* / dt (1/I* = 1/I_i + 1/I_j; wall: I* = I_i), the torque that just
    stops the relative rolling in one step, so that a resting contact does not chatter
    (dt is the increment's time: 0 in the start-up step, which is not capped).
Loads: on i  F = -f_n n + F_t,  M = a_i n x F_t + M_r; on j the opposite force and
M = a_j n x F_t - M_r, which conserves angular momentum exactly (a_i + a_j = |x_j - x_i|).
Stored energy: 8/15 E* sqrt(R*) delta^(5/2) + S_t |xi|^2 / 2. The energy dissipated by
damping, sliding and rolling is booked by the loops from the work balance of each contact
(work of its loads over the step, trapezoidal, minus the change of its stored energy),
which also takes up Mindlin's non-conservative part (S_t changing under a held xi).
"""
import math

from ._registry import (PAIR_BETA, PAIR_E_STAR, PAIR_FRICTION, PAIR_G_STAR, PAIR_ROLLING,
                        physics)
from .vector import add, cross, dot, norm, scale, sub

SQRT_5_6 = math.sqrt(5.0 / 6.0)

# The contact model (physics/contact_models.py): the default law, no parameters of its own.
NAME = "hertz_mindlin"
PARAMETERS = {}
UNITS = {}
LAW = "hertz_mindlin_law"
MUSEN = {"pp": "ModelPPHertzMindlin", "pw": "ModelPWHertzMindlin", "kind_pp": 0,
         "kind_pw": 0}


@physics
def effective_young_modulus(young_i, poisson_i, young_j, poisson_j):
    """E* (Pa) of two materials (E in Pa, nu dimensionless)."""
    return 1.0 / ((1.0 - poisson_i * poisson_i) / young_i
                  + (1.0 - poisson_j * poisson_j) / young_j)


@physics
def effective_shear_modulus(young_i, poisson_i, young_j, poisson_j):
    """G* (Pa) of two materials (Mindlin): 1/G* = sum 2 (2 - nu)(1 + nu) / E."""
    return 1.0 / (2.0 * (2.0 - poisson_i) * (1.0 + poisson_i) / young_i
                  + 2.0 * (2.0 - poisson_j) * (1.0 + poisson_j) / young_j)


@physics
def restitution_beta(restitution):
    """beta = ln e / sqrt(ln^2 e + pi^2) (<= 0); 0 for e = 1."""
    if restitution >= 1.0:
        return 0.0
    log_e = math.log(restitution)
    return log_e / math.sqrt(log_e * log_e + math.pi * math.pi)


@physics
def contact_relative_velocity(n, vi, vj, wi, wj, arm_i, arm_j):
    """Velocity (m/s) of j's surface relative to i's at the contact point."""
    spin = add(scale(wi, arm_i), scale(wj, arm_j))
    return sub(sub(vj, vi), cross(spin, n))


@physics
def carry_to_plane(spring, n):
    """Project the tangential spring onto the plane normal to n, keeping its length."""
    length = norm(spring)
    projected = sub(spring, scale(n, dot(spring, n)))
    new_length = norm(projected)
    if new_length <= 0.0 or length <= 0.0:
        return (0.0, 0.0, 0.0)
    return scale(projected, length / new_length)


@physics
def friction_and_rolling(n, v_t, w_rel, spring, f_n, k_t, c_t, friction, rolling_friction,
                         r_star, i_star, dt):
    """Tangential spring-dashpot with Coulomb limit, and the rolling resistance torque.

    n: unit normal i -> j; v_t: tangential relative velocity (m/s); w_rel = w_i - w_j
    (rad/s); spring: previous tangential displacement (m); f_n: normal force (N, > 0
    repulsive); k_t: tangential stiffness (N/m); c_t: tangential damping (N s/m);
    i_star: reduced moment of inertia (kg m^2) that caps the rolling torque.
    Returns (F_t on i in N, rolling torque on i in N m, new spring in m).
    """
    xi = add(carry_to_plane(spring, n), scale(v_t, dt))
    f_t = add(scale(xi, k_t), scale(v_t, c_t))
    # if-expressions instead of builtin max/min, which the CUDA target of numba 0.68 does
    # not compile (same value as max(f_n, 0.0), NaN included).
    f_n_positive = 0.0 if 0.0 > f_n else f_n
    limit = friction * f_n_positive
    magnitude = norm(f_t)
    if magnitude > limit:
        f_t = scale(f_t, limit / magnitude) if magnitude > 0.0 else f_t
        # Sliding: the spring holds exactly the Coulomb force, so a reversal unloads it.
        xi = scale(f_t, 1.0 / k_t)
    w_roll = sub(w_rel, scale(n, dot(w_rel, n)))
    w_roll_size = norm(w_roll)
    torque = (0.0, 0.0, 0.0)
    if rolling_friction > 0.0 and w_roll_size > 0.0:
        torque_size = rolling_friction * r_star * f_n_positive
        # dt = 0 in the start-up step (zero increments, SPEC 1): no step to stop in
        if dt > 0.0:
            cap = w_roll_size * i_star / dt
            torque_size = cap if cap < torque_size else torque_size  # min(torque_size, cap)
        torque = scale(w_roll, -torque_size / w_roll_size)
    return f_t, torque, xi


@physics
def hertz_mindlin_pulled(n, overlap, v_rel, w_rel, spring, e_star, g_star, r_star, m_star,
                         i_star, beta, friction, rolling_friction, dt, pull):
    """``hertz_mindlin`` whose Coulomb and rolling limits take its normal force plus an
    attraction ``pull`` (N, >= 0) that presses the surfaces together (van der Waals, a
    liquid bridge); the force returned is Hertz-Mindlin's alone."""
    v_n = dot(v_rel, n)
    v_t = sub(v_rel, scale(n, v_n))
    root = math.sqrt(r_star * overlap)
    s_n = 2.0 * e_star * root
    s_t = 8.0 * g_star * root
    c_n = -2.0 * SQRT_5_6 * beta * math.sqrt(s_n * m_star)
    c_t = -2.0 * SQRT_5_6 * beta * math.sqrt(s_t * m_star)
    f_n = 2.0 / 3.0 * s_n * overlap - c_n * v_n
    f_t, torque, xi = friction_and_rolling(n, v_t, w_rel, spring, f_n + pull, s_t, c_t,
                                           friction, rolling_friction, r_star, i_star, dt)
    energy = 0.4 * (2.0 / 3.0) * s_n * overlap * overlap + 0.5 * s_t * dot(xi, xi)
    return add(scale(n, -f_n), f_t), torque, f_t, xi, energy


@physics
def hertz_mindlin(n, overlap, v_rel, w_rel, spring, e_star, g_star, r_star, m_star, i_star,
                  beta, friction, rolling_friction, dt):
    """One step of the Hertz-Mindlin law for a contact with overlap > 0 (m).

    n: unit normal from i to j; v_rel: velocity of j's surface relative to i's (m/s);
    w_rel: w_i - w_j (rad/s); spring: tangential displacement (m); E*, G* (Pa), R* (m),
    m* (kg), I* (kg m^2), beta from ``restitution_beta``; dt: s.
    Returns (force on i N, rolling torque on i N m, F_t on i N, new spring m,
    elastic energy J). (Its normal force is never -0, so adding a pull of +0 changes
    no bit.)
    """
    return hertz_mindlin_pulled(n, overlap, v_rel, w_rel, spring, e_star, g_star, r_star,
                                m_star, i_star, beta, friction, rolling_friction, dt, 0.0)


@physics
def contact_moments(n, f_t, torque, arm_i, arm_j):
    """Moments (N m) on i and on j of a contact's tangential force on i and rolling torque."""
    lever = cross(n, f_t)
    return add(scale(lever, arm_i), torque), sub(scale(lever, arm_j), torque)


@physics
def hertz_mindlin_law(n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt):
    """``hertz_mindlin`` with the pair's properties from row q of the pair table
    (contact_models.LAW)."""
    return hertz_mindlin_pulled(n, overlap, v_rel, w_rel, spring, pair[q, PAIR_E_STAR],
                                pair[q, PAIR_G_STAR], r_star, m_star, i_star,
                                pair[q, PAIR_BETA], pair[q, PAIR_FRICTION],
                                pair[q, PAIR_ROLLING], dt, 0.0)

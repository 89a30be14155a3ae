"""MUSEN's own Hertz-Mindlin contact numerics (``Simulation(musen_compat=True)``).

The same springs as ``contact_hertz`` (Hertz normal, Mindlin tangential, restitution
damping, Coulomb limit, rolling friction), with the choices read from MUSEN 1.70.0
(github.com/msolids/musen, commit 1547403: ModelPPHertzMindlin.cpp,
ModelPWHertzMindlin.cpp, SimplifiedScene.cpp ``CalculateInteractionProperty``,
CPUSimulator.cpp ``CalculateForcesPP/PW``; docs/musen_compat.md lists them):
- the damping constant is the literal 1.8257, not 2 sqrt(5/6) = 1.825742;
- the slip test takes the spring force k_t xi alone, without its dashpot, against the
  Coulomb force of the elastic normal force alone;
- while sliding, the tangential force applied is the one of the previous step (MUSEN
  keeps ``vTangForce`` from the last sticking step; 0 for a contact that slides from its
  first step), and the spring is set to the Coulomb force over k_t;
- the lever arm of the tangential force is the particle's full radius r, not r - delta/2;
- rolling friction acts on each particle against its own spin, -mu_r |f_n| r w / |w|,
  with no cap, and only when |w| is not zero;
- the particle-particle contact point splits the centre distance in the ratio of the radii;
- particle-wall: the normal is the wall's own (plane or triangle) normal, the normal force
  is scaled by |n_rc . n_wall| (n_rc from the contact point to the centre: 1 on a face,
  less on an edge or vertex), the reduced mass is the particle's mass and R* its radius;
- G* = 1 / ((2 - nu_1)/G_1 + (2 - nu_2)/G_2) with G = E / (2 (1 + nu)) (the same value as
  ``contact_hertz.effective_shear_modulus``; written as MUSEN writes it for its round-off).

MUSEN 1.74.2 (tag v1.74.2: Models/ParticleParticle/HertzMindlin, Models/ParticleWall/
PWHertzMindlin) changed three of these, selected by ``version`` = MUSEN_1_74 below:
- the damping constant is 2 sqrt(5/6) (``_2_SQRT_5_6``, MUSENDefinitions.h);
- the Coulomb limit is mu |F_n + F_n,d|, the normal force with its dashpot;
- while sliding, the tangential force applied is the spring's, scaled to the Coulomb limit
  (no longer the previous step's); the spring is that force over k_t, as before;
and it rescales the carried tangential overlap by old length / new length as one factor
(1.70: times the old length, then divided by the new) and tests the projected overlap for
being significant in both laws (1.70's particle pairs: squared length > 0).

Every expression keeps MUSEN's order of operations, so that the results agree with MUSEN's
to round-off. Signs: MUSEN's contact vector is x_j - x_i (j the higher index), the force
returned is the one on i; MUSEN's alpha = ln e / sqrt(pi^2 + ln^2 e) is <= 0.
"""
import math

from ._registry import physics
from .vector import add, cross, dot, norm, scale, sub

# ModelPPHertzMindlin.cpp / ModelPWHertzMindlin.cpp of 1.70.0 write 2 sqrt(5/6) as this
# literal; 1.74.2 as MUSENDefinitions.h's _2_SQRT_5_6.
MUSEN_DAMPING = 1.8257
MUSEN_DAMPING_1_74 = 1.825741858350553711523232609336

# The MUSEN releases whose numerics musen_compat reproduces, by the code the kernels get
# (0: bondem's own SPEC numerics). The newest is the default.
MUSEN_1_70, MUSEN_1_74 = 1, 2
MUSEN_VERSIONS = {"1.70.0": MUSEN_1_70, "1.74.2": MUSEN_1_74}
MUSEN_VERSION = "1.74.2"


# MUSEN's contact models whose normal force this module writes (the rest is Hertz-
# Mindlin's): ModelPPHertzMindlin / ModelPWHertzMindlin, ModelPPJKR / ModelPWJKR,
# ModelPPHertzMindlinVdW, ModelPPPopovJKR / ModelPWPopovJKR (1.74.2;
# docs/contact_models.md).
MUSEN_HERTZ_MINDLIN, MUSEN_JKR, MUSEN_VDW, MUSEN_POPOV = 0, 1, 2, 3
# ModelPPHertzMindlinVdW's fixed minimum separation (m): Hamaker's constant is
# 24 pi Dmin^2 times the surface energy.
MUSEN_VDW_DMIN = 7.5e-10


def musen_code(version=MUSEN_VERSION):
    """The kernels' code of MUSEN release ``version`` (a key of MUSEN_VERSIONS;
    ValueError naming the allowed ones)."""
    if version not in MUSEN_VERSIONS:
        raise ValueError(f"musen_version {version!r}; allowed: "
                         + ", ".join(repr(v) for v in MUSEN_VERSIONS))
    return MUSEN_VERSIONS[version]


@physics
def musen_alpha(restitution):
    """MUSEN's damping factor ln e / sqrt(pi^2 + ln^2 e) (dimensionless, <= 0)."""
    log_e = math.log(restitution)
    return log_e / math.sqrt(math.pi * math.pi + log_e * log_e)


@physics
def musen_shear_modulus(young_i, poisson_i, young_j, poisson_j):
    """G* (Pa) as MUSEN computes it: 1 / ((2 - nu_i)/G_i + (2 - nu_j)/G_j)."""
    g_i = young_i / (2.0 * (1.0 + poisson_i))
    g_j = young_j / (2.0 * (1.0 + poisson_j))
    return 1.0 / ((2.0 - poisson_i) / g_i + (2.0 - poisson_j) / g_j)


@physics
def musen_significant(v):
    """MUSEN's CVector3::IsSignificant: some component larger than 1e-100 in size."""
    return abs(v[0]) > 1e-100 or abs(v[1]) > 1e-100 or abs(v[2]) > 1e-100


@physics
def musen_rolling_torque(w, rolling, f_n, radius):
    """-mu_r |f_n| r w / |w| (N m), 0 when w is not significant (MUSEN's rolling friction
    on one particle; w in rad/s, f_n in N, r in m)."""
    if not musen_significant(w):
        return (0.0, 0.0, 0.0)
    return scale(w, -rolling * abs(f_n) * radius / norm(w))


@physics
def musen_carry_overlap(overlap_t, n, pp, version):
    """The tangential overlap (m) projected onto the plane normal to n and rescaled to its
    old length; pp: True for 1.70's particle-particle test (squared length > 0), False for
    the wall's (IsSignificant, every test of 1.74); version: MUSEN_1_70 or MUSEN_1_74."""
    projected = sub(overlap_t, scale(n, dot(n, overlap_t)))
    rescale = (dot(projected, projected) > 0.0 if pp and version < MUSEN_1_74
               else musen_significant(projected))
    if not rescale:
        return projected
    old = norm(overlap_t)
    new = norm(projected)     # MUSEN's sqrt of the squared length: the same operations
    if version >= MUSEN_1_74:
        return scale(projected, old / new)
    return (projected[0] * old / new, projected[1] * old / new, projected[2] * old / new)


@physics
def musen_coulomb(xi, k_t, damping_t, f_n, damping, friction, f_t_prev, newer, pull):
    """MUSEN's slip test on the spring force k_t xi (N; xi in m, k_t in N/m, negative for
    the particle-wall law's sign): (tangential force applied in N, spring xi in m).
    Sticking: the spring force plus its dashpot damping_t. Sliding, MUSEN 1.74 (newer):
    the spring force cut to mu |f_n + damping| (normal force with its dashpot, N); 1.70:
    the last sticking step's force f_t_prev while the spring is cut to mu |f_n|. In
    either case the spring is the cut force over k_t, in MUSEN's order of operations.
    pull (N): ModelPPHertzMindlinVdW's attraction, in its 1.74 limit (0 otherwise)."""
    f_t = scale(xi, k_t)
    magnitude = norm(f_t)
    limit = friction * abs(f_n + damping + pull) if newer else friction * abs(f_n)
    if not magnitude > limit:      # as MUSEN's test reads (a NaN sticks)
        return add(f_t, damping_t), xi
    if newer:
        cut = (f_t[0] * limit / magnitude, f_t[1] * limit / magnitude,
               f_t[2] * limit / magnitude)
        return cut, (cut[0] / k_t, cut[1] / k_t, cut[2] / k_t)
    cut = scale(f_t, limit / magnitude)
    return f_t_prev, (cut[0] / k_t, cut[1] / k_t, cut[2] / k_t)


@physics
def musen_popov(overlap, radius, e_star, w):
    """ModelPPPopovJKR's / ModelPWPopovJKR's normal force (N, repulsive > 0) and its
    potential (J, as contact_popov's) at overlap (m), in MUSEN's order of operations
    (w: MUSEN's surface tension, J/m^2; radius: R*, m)."""
    adh = 3.0 / 2.0 * w * math.pi * radius
    ratio = w / e_star
    s = (0.4626 * (ratio * ratio) * radius) ** (1.0 / 3.0)
    x = overlap / s + 1.0
    return (adh * (-1.0 + 0.12 * x ** (5.0 / 3.0)),
            adh * (-(overlap + s) + 0.045 * s * x ** (8.0 / 3.0)))


@physics
def musen_normal_pp(kind, cv, overlap, r_i, r_j, r_star, e_star, adhesion):
    """(elastic normal force along x_j - x_i in N (negative: pushes i away), stiffness k_n
    N/m, attraction N, overlap the law uses m, potential J) of MUSEN's particle-particle
    model ``kind`` (MUSEN_HERTZ_MINDLIN, MUSEN_JKR with surface energy ``adhesion`` J/m^2,
    MUSEN_VDW with Hamaker's constant ``adhesion`` J) at ``overlap`` (m), in MUSEN's
    order of operations."""
    if kind == MUSEN_VDW:
        # the gap as MUSEN's VdW model computes it, from the centres
        surface = norm(cv) - r_i - r_j
        pull = adhesion * (2.0 * r_star) / (12.0 * MUSEN_VDW_DMIN * MUSEN_VDW_DMIN)
        overlap = abs(surface)
        k_n = 2.0 * e_star * math.sqrt(r_star * overlap)
        energy = 0.4 * (2.0 / 3.0) * k_n * overlap * overlap - pull * overlap
        return -overlap * k_n * 2.0 / 3.0, k_n, pull, overlap, energy
    a = math.sqrt(r_star * overlap)
    k_n = 2.0 * e_star * a
    if kind == MUSEN_POPOV:
        f_n, energy = musen_popov(overlap, r_star, e_star, adhesion)
        return -f_n, k_n, 0.0, overlap, energy
    if kind == MUSEN_JKR:
        a3 = a ** 3.0
        f_n = -1.0 * (4.0 * a3 * e_star / (3.0 * r_star)
                      - math.sqrt(8.0 * math.pi * e_star * adhesion * a3))
        # the potential of that force in delta (a = sqrt(R* delta))
        energy = (0.4 * (2.0 / 3.0) * k_n * overlap * overlap
                  - 4.0 / 7.0 * math.sqrt(8.0 * math.pi * e_star * adhesion) * a3 ** 0.5 * overlap)
        return f_n, k_n, 0.0, overlap, energy
    return -overlap * k_n * 2.0 / 3.0, k_n, 0.0, overlap, 0.4 * (2.0 / 3.0) * k_n * overlap * overlap


@physics
def hertz_mindlin_musen_pp(cv, overlap, r_i, r_j, vi, vj, wi, wj, overlap_t, f_t_prev,
                           e_star, g_star, alpha, friction, rolling, r_star, m_star, dt,
                           version, kind, adhesion):
    """One step of MUSEN's ModelPPHertzMindlin for particles i < j touching with overlap
    (m) > 0; cv = x_j - x_i (m); overlap_t: tangential overlap (m); f_t_prev: the
    tangential force (N) of the last sticking step; alpha from ``musen_alpha``; version:
    MUSEN_1_70 or MUSEN_1_74 (module docstring); kind, adhesion: ``musen_normal_pp``'s
    (ModelPPJKR, ModelPPHertzMindlinVdW: the same law but for the normal force).

    Returns (force on i N, moment on i N m, moment on j N m, new overlap_t m, new
    tangential force N, elastic energy J). The force on j is minus the force on i."""
    total = r_i + r_j
    rc_i = scale(cv, r_i / total)
    rc_j = scale(cv, -r_j / total)
    length = norm(cv)
    n = (cv[0] / length, cv[1] / length, cv[2] / length) if length != 0.0 else (0.0, 0.0, 0.0)
    rel = sub(add(vj, cross(wj, rc_j)), add(vi, cross(wi, rc_i)))
    v_n = dot(n, rel)
    rel_t = sub(rel, scale(n, v_n))
    newer = version >= MUSEN_1_74
    constant = MUSEN_DAMPING_1_74 if newer else MUSEN_DAMPING
    f_n, k_n, pull, overlap, normal_energy = musen_normal_pp(kind, cv, overlap, r_i, r_j,
                                                             r_star, e_star, adhesion)
    damping = -constant * alpha * v_n * math.sqrt(k_n * m_star)
    k_t = 8.0 * g_star * math.sqrt(r_star * overlap)
    xi = add(musen_carry_overlap(overlap_t, n, True, version), scale(rel_t, dt))
    damping_t = scale(rel_t, -constant * alpha * math.sqrt(k_t * m_star))
    f_t_new, xi = musen_coulomb(xi, k_t, damping_t, f_n, damping, friction, f_t_prev, newer,
                                pull)
    lever = cross(n, f_t_new)
    moment_i = add(scale(lever, r_i), musen_rolling_torque(wi, rolling, f_n, r_i))
    moment_j = add(scale(lever, r_j), musen_rolling_torque(wj, rolling, f_n, r_j))
    force_i = add(scale(n, f_n + damping + pull), f_t_new)
    energy = normal_energy + 0.5 * k_t * dot(xi, xi)
    return force_i, moment_i, moment_j, xi, f_t_new, energy


@physics
def hertz_mindlin_musen_pw(x, q, n_wall, radius, v, w, v_wall, omega_wall, center,
                           overlap_t, f_t_prev, e_star, g_star, alpha, friction, rolling,
                           mass, dt, version, kind, adhesion):
    """One step of MUSEN's ModelPWHertzMindlin for a particle at x (m) touching a wall at
    its point q (m), |x - q| < radius; n_wall: the wall element's unit normal towards the
    particle; v_wall, omega_wall, center: the wall's velocity (m/s), spin (rad/s) and
    centre of rotation (m); v, w, mass: the particle's (m/s, rad/s, kg); version:
    MUSEN_1_70 or MUSEN_1_74 (module docstring); kind: MUSEN_HERTZ_MINDLIN, or
    MUSEN_JKR (ModelPWJKR, surface energy ``adhesion`` J/m^2: its adhesive term, not its
    elastic one, scaled by |n_rc . n_wall|), or MUSEN_POPOV (ModelPWPopovJKR: its whole
    normal force scaled, its spring force from the previous step's overlap).

    Returns (force on the particle N, moment N m, its rolling torque N m, new overlap_t m,
    new tangential force N, elastic energy J)."""
    rc = sub(x, q)
    d_rc = norm(rc)
    n_rc = (rc[0] / d_rc, rc[1] / d_rc, rc[2] / d_rc)
    spin_velocity = (0.0, 0.0, 0.0)
    if omega_wall[0] != 0.0 or omega_wall[1] != 0.0 or omega_wall[2] != 0.0:
        spin_velocity = cross(sub(q, center), omega_wall)
    overlap = radius - d_rc
    rel = add(add(sub(v, v_wall), spin_velocity), scale(cross(n_rc, w), radius))
    v_n = dot(n_wall, rel)
    rel_t = sub(rel, scale(n_wall, v_n))
    newer = version >= MUSEN_1_74
    constant = MUSEN_DAMPING_1_74 if newer else MUSEN_DAMPING
    a = math.sqrt(radius * overlap)
    k_n = 2.0 * e_star * a
    if kind == MUSEN_POPOV:
        popov, normal_energy = musen_popov(overlap, radius, e_star, adhesion)
        f_n = popov * abs(dot(n_rc, n_wall))
    elif kind == MUSEN_JKR:
        a3 = a ** 3.0
        f_n = (4.0 * a3 * e_star / (3.0 * radius)
               - math.sqrt(8.0 * math.pi * e_star * adhesion * a3) * abs(dot(n_rc, n_wall)))
        normal_energy = (0.4 * (2.0 / 3.0) * k_n * overlap * overlap - 4.0 / 7.0
                         * math.sqrt(8.0 * math.pi * e_star * adhesion) * a3 ** 0.5 * overlap)
    else:
        f_n = 2.0 / 3.0 * overlap * k_n * abs(dot(n_rc, n_wall))
        normal_energy = 0.4 * (2.0 / 3.0) * k_n * overlap * overlap
    damping = constant * alpha * v_n * math.sqrt(k_n * mass)
    xi = add(musen_carry_overlap(overlap_t, n_wall, False, version), scale(rel_t, dt))
    k_t = 8.0 * g_star * math.sqrt(radius * overlap)
    damping_t = scale(rel_t, constant * alpha * math.sqrt(k_t * mass))
    # the wall's spring pushes against its overlap: -k_t
    if kind == MUSEN_POPOV:
        # ModelPWPopovJKR's spring force takes the previous step's overlap (not carried,
        # not advanced); a sticking contact still keeps the advanced one
        f_t_new, cut = musen_coulomb(overlap_t, -k_t, damping_t, f_n, damping, friction,
                                     f_t_prev, newer, 0.0)
        if norm(scale(overlap_t, -k_t)) > friction * abs(f_n + damping):
            xi = cut
    else:
        f_t_new, xi = musen_coulomb(xi, -k_t, damping_t, f_n, damping, friction, f_t_prev,
                                    newer, 0.0)
    force = add(f_t_new, scale(n_wall, f_n + damping))
    torque = musen_rolling_torque(w, rolling, f_n, radius)
    moment = add(scale(cross(n_wall, f_t_new), -radius), torque)
    energy = normal_energy + 0.5 * k_t * dot(xi, xi)
    return force, moment, torque, xi, f_t_new, energy

"""MUSEN's own numerics of the elastic solid bond (``Simulation(musen_compat=True)``).

Same springs as ``bond_elastic.elastic_bond`` (SPEC section 2), but with the choices found
in MUSEN's source (github.com/msolids/musen, ModelSBElastic.cpp, CModelSBElastic::
CalculateSBForce, commit 1547403; see docs/musen_compat.md), written in bondem's
convention r = x_j - x_i (MUSEN's currentBond is -r; every sign flip cancels):
    p  = r of the previous step, WITH its length (m), t = p x r (m^2, not a unit vector)
    phi = n (n . (w_i + w_j)) dt / 2
    M  = (I + [t]x)(I - [phi]x)            linearised, not orthonormal, twist sense reversed
    F_t = M F_t + (G A / L0) v_t dt,  M_n = M M_n - (2 I G / L0) w_n dt,
    M_t = M M_t - (E I / L0) w_t dt,   F_n = n (E A (L - L0) / L0)
and nothing is projected back onto the bond's planes. MUSEN keeps the tangential overlap
and multiplies it by G A / L0; for a constant stiffness that is F_t above up to round-off.

Breakage (MUSEN 1547403, parameter CONSIDER_BREAKAGE), with s = +1 in tension (L > L0)
and -1 otherwise: sigma_1 = s |F_n| / A, sigma_2 = |M_t| R / I, tau_1 = |F_t| / A,
tau_2 = |M_n| R / J.
    1 ("combined"): break when sigma_1 + sigma_2 >= sigma_max or tau_1 + tau_2 >= tau_max,
                    in compression too (no compressive-breakage switch);
    2 ("separate"): sigma_1 >= sigma_max, or sigma_2 >= sigma_max in tension only, or
                    tau_1 >= tau_max, or tau_2 >= tau_max.
"""
import math

from ._registry import physics
from .bond_elastic import COMPRESSION, CRITERION_COMBINED, CRITERION_NONE, INTACT, SHEAR, \
    TENSION
from .vector import add, cross, dot, norm, scale, sub


@physics
def musen_rotate(v, previous_bond, bond, phi):
    """MUSEN's M v with M = (I + [p x r]x)(I - [phi]x), entries as written in MUSEN.

    previous_bond p, bond r: m; phi: rad (vector). M is built row by row exactly as
    ModelSBElastic.cpp writes it (row-major, M v = rows . v) so round-off follows MUSEN's.
    """
    # MUSEN's tempVector = PrevBond x currentBond = (-p) x (-r) = p x r.
    t = cross(previous_bond, bond)
    # MUSEN's Phi is built from its contact normal -n: n (n . w) is the same either way.
    m00 = 1.0 + t[2] * phi[2] + t[1] * phi[1]
    m01 = phi[2] - t[2] - t[1] * phi[0]
    m02 = -phi[1] - t[2] * phi[0] + t[1]
    m10 = t[2] - phi[2] - t[0] * phi[1]
    m11 = t[2] * phi[2] + 1.0 + t[0] * phi[0]
    m12 = -t[2] * phi[1] + phi[0] - t[0]
    m20 = -t[1] - t[0] * phi[2] + phi[1]
    m21 = -t[1] * phi[2] + t[0] - phi[0]
    m22 = t[1] * phi[1] + t[0] * phi[0] + 1.0
    return (m00 * v[0] + m01 * v[1] + m02 * v[2],
            m10 * v[0] + m11 * v[1] + m12 * v[2],
            m20 * v[0] + m21 * v[1] + m22 * v[2])


@physics
def elastic_bond_musen(r, vi, vj, wi, wj, previous_bond, tangential_force, normal_moment,
                       tangential_moment, initial_length, young_modulus, poisson_ratio,
                       diameter, dt):
    """One step of the elastic bond with MUSEN's numerics (module docstring).

    r: x_j - x_i (m); vi, vj (m/s); wi, wj (rad/s); previous_bond: r of the previous step
    (m, with its length); tangential_force (N), normal_moment, tangential_moment (N m):
    accumulated vectors on i; E (Pa), nu, bond diameter (m), dt (s).
    Returns (L, n, F_n, F_t, M_n, M_t) on particle i, the same as ``elastic_bond``.
    """
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    axial_moment = 0.25 * math.pi * radius ** 4   # MUSEN's AxialMoment = I; J = 2 I
    shear_modulus = young_modulus / (2.0 * (1.0 + poisson_ratio))
    length = norm(r)
    n = scale(r, 1.0 / length)
    w_rel = sub(wi, wj)
    w_sum = add(wi, wj)
    v_rel = sub(sub(vj, vi), scale(cross(w_sum, r), 0.5))
    v_t = sub(v_rel, scale(n, dot(n, v_rel)))
    w_n = scale(n, dot(n, w_rel))
    w_t = sub(w_rel, w_n)
    phi = scale(n, dot(w_sum, n) * dt * 0.5)
    strain = (length - initial_length) / initial_length
    f_n = scale(n, area * young_modulus * strain)
    f_t = add(musen_rotate(tangential_force, previous_bond, r, phi),
              scale(v_t, dt * shear_modulus * area / initial_length))
    m_n = sub(musen_rotate(normal_moment, previous_bond, r, phi),
              scale(w_n, dt * 2.0 * axial_moment * shear_modulus / initial_length))
    m_t = sub(musen_rotate(tangential_moment, previous_bond, r, phi),
              scale(w_t, dt * young_modulus * axial_moment / initial_length))
    # No projection back onto the planes: MUSEN does none.
    return length, n, f_n, f_t, m_n, m_t


@physics
def bond_break_mode_musen(length, initial_length, f_n, f_t, m_n, m_t, diameter,
                          normal_strength, tangential_strength, criterion):
    """INTACT or the break mode under MUSEN's criteria (module docstring); strengths in Pa.

    MUSEN records no mode; bondem reports TENSION / COMPRESSION when the normal test fires
    (by the sign of the strain), else SHEAR.
    """
    if criterion == CRITERION_NONE:
        return INTACT
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    axial_moment = 0.25 * math.pi * radius ** 4
    in_tension = length > initial_length
    axial = norm(f_n) / area
    if not in_tension:
        axial = -axial
    bending = norm(m_t) * diameter / (2.0 * axial_moment)
    shear = norm(f_t) / area
    torsion = norm(m_n) * diameter / (4.0 * axial_moment)
    normal_mode = TENSION if in_tension else COMPRESSION
    if criterion == CRITERION_COMBINED:
        if axial + bending >= normal_strength:
            return normal_mode
        if shear + torsion >= tangential_strength:
            return SHEAR
        return INTACT
    if axial >= normal_strength or (bending >= normal_strength and in_tension):
        return normal_mode
    if shear >= tangential_strength or torsion >= tangential_strength:
        return SHEAR
    return INTACT

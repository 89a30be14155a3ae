"""Kelvin (viscoelastic) solid bond: the elastic bond with a dashpot beside each force
spring (Kelvin-Voigt), the idea of MUSEN's ModelSBKelvin.

Parameters: the elastic bond's (bond_elastic.py) and the viscosity eta (s), the ratio of
each force dashpot to its spring, c = eta k. With the elastic bond's n, relative velocity
v_rel at the bond centre and its tangential part v_t:
    F_n,d = eta k_n (n . v_rel) n,   F_t,d = eta k_t v_t                 (on i; -F on j)
k_n = E A_b / L0, k_t = G A_b / L0. The dashpot forces act at the bond centre, like the
springs' forces, so they also turn i and j by (r/2) x F_t,d; they are not stored (the
bond's state is the elastic bond's) and do not enter the break test (it reads the
springs, as MUSEN's). Moments have no dashpot (as in MUSEN).
Two free spheres of mass m along the bond axis follow the damped oscillator
    (m/2) x'' = -k_n x - eta k_n x',  omega_0^2 = 2 k_n / m,  zeta = eta omega_0 / 2.
The dashpots remove eta (k_n (n . v_rel)^2 + k_t |v_t|^2) >= 0 watts (minus the power of
their forces on the particles), booked per bond in state.extra["bond_model_state"] (STATE).

MUSEN-compatible runs (musen_compat) use MUSEN 1.70's ModelSBKelvin instead
(``kelvin_loads_musen``, on top of MUSEN's elastic numerics): with its viscosity mu (s/m,
MUSEN's model parameter MU),
    F_n,d = mu E A |strain| (n . v_rel) n,   F_t,d = mu |F_t| v_t
each capped at max_damping_ratio (0.5, fixed in MUSEN 1.70; later MUSEN versions call it
MAX_DAMP_RATIO, default 1, 0 for no cap) times the spring force |F_n| or |F_t|; the dashpot forces are added to the force only, without their
moment (r/2) x F_t,d (angular momentum then drifts), and its break test is the combined
one. A damping force that vanishes at zero deformation whatever the speed has no closed
form, hence bondem's own law above.
"""
import math

import numpy as np

from ._registry import physics
from .bond_elastic import bond_loads_on_particles
from .vector import add, cross, dot, norm, scale, sub

# The bond model's declaration (physics/bond_models.py): its parameters beyond the elastic
# bond's, in the scene's schema (type, default, low, high, include low, include high).
NAME = "kelvin"
PARAMETERS = {"viscosity": ("number", 0.0, 0.0, float("inf"), True, False),
              "max_damping_ratio": ("number", 0.5, 0.0, float("inf"), True, False)}
UNITS = {"viscosity": "s (s/m with musen_compat)", "max_damping_ratio": "-"}
LOADS = "kelvin_loads"
STATE = ("J removed by the bond's dashpots", "dissipated_bonds")
VECTORISED = False
# MUSEN's counterpart (io/musen_text.py); its damping cap is fixed at 0.5 (1.70 to 1.74.2)
MUSEN = {"model": "ModelSBKelvin", "parameters": {"MU": "viscosity"}, "properties": {},
         "strengths": True, "fixed": {"max_damping_ratio": 0.5}}


def check(values, musen_compat=False):
    """[(key, message)]: MUSEN's Kelvin bond has the combined break test only."""
    if musen_compat and values["breakage"] == "separate":
        return [("breakage", "musen_compat: MUSEN's Kelvin bond breaks by the combined "
                             "criterion only; breakage = 'separate' is bondem's "
                             "(docs/bond_kelvin.md)")]
    return []


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """{"bond_dashpot": s}: m_red / (eta E A / L0), the time in which a dashpot alone
    stops its pair (the smallest scale once the damping ratio exceeds 1/2). None with
    musen_compat: MUSEN's viscosity is in s/m and MUSEN sets no limit."""
    table = model.bond_material_table()
    viscosity = table["viscosity"][model.bond_material[bonds]]
    viscous = viscosity > 0.0
    if musen_compat or not np.any(viscous):
        return {}
    area = np.pi * (0.5 * model.bond_diameter[bonds]) ** 2
    young = table["young_modulus"][model.bond_material[bonds]]
    stiffness = young * area / model.bond_initial_length[bonds]
    dashpot = reduced_mass[viscous] / (viscosity[viscous] * stiffness[viscous])
    return {"bond_dashpot": float(dashpot.min())}


@physics
def kelvin_dashpots(r, length, vi, vj, wi, wj, normal_stiffness, shear_stiffness,
                    viscosity):
    """Dashpot forces on i (N) of a Kelvin bond: (normal F_n,d, tangential F_t,d) and the
    power they remove (W). r: x_j - x_i (m) of this step, length |r| (m); vi, vj (m/s),
    wi, wj (rad/s); normal_stiffness k_n, shear_stiffness k_t (N/m); viscosity eta (s)."""
    n = scale(r, 1.0 / length)
    v_rel = sub(sub(vj, vi), scale(cross(add(wi, wj), r), 0.5))
    v_n = dot(n, v_rel)
    v_t = sub(v_rel, scale(n, v_n))
    c_n = viscosity * normal_stiffness
    c_t = viscosity * shear_stiffness
    power = c_n * v_n * v_n + c_t * dot(v_t, v_t)
    return scale(n, c_n * v_n), scale(v_t, c_t), power


@physics
def kelvin_loads_musen(r, length, initial_length, vi, vj, wi, wj, f_n, f_t, m_n, m_t,
                       young_modulus, diameter, viscosity, max_damping_ratio):
    """MUSEN's ModelSBKelvin on top of MUSEN's elastic step (module docstring): (force on
    i in N, moment on i, moment on j in N m, power the dashpots take from the particles
    in W). f_n, f_t, m_n, m_t: the spring loads on i of this step (``elastic_bond_musen``);
    viscosity mu in s/m; max_damping_ratio: 0 for no cap."""
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    n = scale(r, 1.0 / length)
    v_rel = sub(sub(vj, vi), scale(cross(add(wi, wj), r), 0.5))
    v_n = scale(n, dot(n, v_rel))
    v_t = sub(v_rel, v_n)
    strain = (length - initial_length) / initial_length
    # MUSEN multiplies the vector factor by factor, in this order.
    f_dn = scale(scale(scale(scale(v_n, viscosity), area), young_modulus), abs(strain))
    f_dt = scale(v_t, viscosity * norm(f_t))
    if max_damping_ratio != 0.0:
        limit = max_damping_ratio * norm(f_n)
        size = norm(f_dn)
        if size > limit:
            f_dn = scale(f_dn, limit / size)
        limit = max_damping_ratio * norm(f_t)
        size = norm(f_dt)
        if size > limit:
            f_dt = scale(f_dt, limit / size)
    _, moment_i, moment_j = bond_loads_on_particles(r, f_n, f_t, m_n, m_t)
    force_i = add(add(add(f_n, f_t), f_dn), f_dt)
    return force_i, moment_i, moment_j, dot(add(f_dn, f_dt), sub(vj, vi))


@physics
def kelvin_loads(musen, r, length, initial_length, diameter, vi, vj, wi, wj, f_n, f_t, m_n,
                 m_t, normal_stiffness, shear_stiffness, materials, m):
    """LOADS of the Kelvin bond: (force on i in N, moment on i, moment on j in N m, power
    removed in W) of a bond of material m (row of the ``materials`` table: viscosity,
    max_damping_ratio, young_modulus) whose springs carry f_n, f_t, m_n, m_t (on i) after
    this step: bondem's law, or with musen True MUSEN's (``kelvin_loads_musen``; musen
    None or False: bondem's)."""
    viscosity = materials.viscosity[m]
    if musen is not None:
        if musen:
            return kelvin_loads_musen(r, length, initial_length, vi, vj, wi, wj, f_n, f_t,
                                      m_n, m_t, materials.young_modulus[m], diameter,
                                      viscosity, materials.max_damping_ratio[m])
    f_dn, f_dt, power = kelvin_dashpots(r, length, vi, vj, wi, wj, normal_stiffness,
                                        shear_stiffness, viscosity)
    force_i, moment_i, moment_j = bond_loads_on_particles(r, add(f_n, f_dn), add(f_t, f_dt),
                                                          m_n, m_t)
    return force_i, moment_i, moment_j, power

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
their forces on the particles), booked per bond in state.extra["bond_dissipated"].

Not MUSEN's numerics: MUSEN scales the normal dashpot by |strain| and the tangential one by
|tangential overlap| (a damping force that vanishes at zero deformation whatever the
speed; its viscosity is in s/m), caps each at MAX_DAMP_RATIO times the spring force and
leaves out the dashpot's moment (angular momentum then drifts). MUSEN-compatible runs
refuse Kelvin bond materials rather than run another law under MUSEN's name.
"""
from ._registry import physics
from .vector import add, cross, dot, scale, sub

MODEL_ELASTIC, MODEL_KELVIN = 0, 1

# The bond model's parameters beyond the elastic bond's, in the scene's schema
# (scene.BOND_MATERIAL_KEYS): type, default, range (low, high, include low, include high).
PARAMETERS = {"viscosity": ("number", 0.0, 0.0, float("inf"), True, False)}
UNITS = {"viscosity": "s"}


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

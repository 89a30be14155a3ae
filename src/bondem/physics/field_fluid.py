"""A fluid around the particles: drag and buoyancy (body forces on each particle).

The fluid has a density rho_f (kg/m^3), a dynamic viscosity mu (Pa s), a velocity u (m/s,
uniform and constant) and a voidage eps (-, the local fluid fraction; 1 for a lone
particle). A particle of diameter d (m) moving at v feels, with the slip s = u - v and the
particle Reynolds number Re = rho_f eps |s| d / mu:

- drag, by the chosen correlation:
  - "stokes": F = 3 pi mu d s (creeping flow, Re << 1);
  - "schiller_naumann": F = 1/2 rho_f C_d (pi d^2 / 4) |s| s with
    C_d = 24/Re (1 + 0.15 Re^0.687) for Re < 1000, 0.44 above (Schiller & Naumann 1933;
    within 5 % of the standard drag curve up to Re = 1000);
  - "di_felice": F = 1/2 rho_f C_d (pi d^2 / 4) eps^2 |s| s eps^(-chi) with
    C_d = (0.63 + 4.8 / sqrt(Re))^2 and chi = 3.7 - 0.65 exp(-(1.5 - log10 Re)^2 / 2)
    (Di Felice 1994, Int. J. Multiphase Flow 20, 153: a particle in a bed of voidage eps;
    eps = 1 gives Dallavalle's single-particle drag);
  - "musen_viscous": MUSEN's ModelEFViscousField: Re = |s| d / nu (nu = mu / rho_f), C_d =
    24/Re (Re < 0.5), 27/Re^0.8 (Re < 10.1), 17/Re^0.6 above; F = C_d pi r^2 rho_f / 2
    |s| s (MUSEN's fluid is at rest: u = 0 in its runs);
- buoyancy: F = -rho_f (pi d^3 / 6) g (Archimedes, g the gravity vector), when on.

The fluid's parameters travel as one array (``FLUID_*`` columns) so that the particle
loop body takes them as it takes gravity.
"""
import math

from ._registry import physics

# columns of the fluid array (Model.fluid)
FLUID_DRAG, FLUID_DENSITY, FLUID_VISCOSITY, FLUID_VELOCITY = 0, 1, 2, 3
FLUID_BUOYANCY, FLUID_VOIDAGE, FLUID_COLUMNS = 6, 7, 8
# drag correlations: their names and codes (0: no drag)
DRAG_LAWS = {"none": 0, "stokes": 1, "schiller_naumann": 2, "di_felice": 3,
             "musen_viscous": 4}


@physics
def drag_coefficient(law, re):
    """C_d (-) of drag correlation ``law`` (a DRAG_LAWS code) at particle Reynolds number
    re > 0 (module docstring; Stokes: 24 / Re)."""
    if law == 1:
        return 24.0 / re
    if law == 2:
        if re < 1000.0:
            return 24.0 / re * (1.0 + 0.15 * re ** 0.687)
        return 0.44
    if law == 3:
        c = 0.63 + 4.8 / math.sqrt(re)
        return c * c
    if re < 0.5:
        return 24.0 / re
    if re < 10.1:
        return 27.0 / re ** 0.8
    return 17.0 / re ** 0.6


@physics
def fluid_force(fluid, radius, v, gravity):
    """Drag plus buoyancy (N, 3-tuple) on a particle of radius (m) moving at v (m/s) in
    the fluid ``fluid`` (FLUID_* columns), gravity (m/s^2)."""
    law = int(fluid[FLUID_DRAG])
    rho = fluid[FLUID_DENSITY]
    fx = 0.0
    fy = 0.0
    fz = 0.0
    if fluid[FLUID_BUOYANCY] != 0.0:
        displaced = rho * 4.0 / 3.0 * math.pi * radius * radius * radius
        fx = -displaced * gravity[0]
        fy = -displaced * gravity[1]
        fz = -displaced * gravity[2]
    if law == 0:
        return (fx, fy, fz)
    mu = fluid[FLUID_VISCOSITY]
    eps = fluid[FLUID_VOIDAGE]
    sx = fluid[FLUID_VELOCITY] - v[0]
    sy = fluid[FLUID_VELOCITY + 1] - v[1]
    sz = fluid[FLUID_VELOCITY + 2] - v[2]
    speed = math.sqrt(sx * sx + sy * sy + sz * sz)
    if speed == 0.0 or mu == 0.0:
        return (fx, fy, fz)
    d = 2.0 * radius
    if law == 1:
        c = 3.0 * math.pi * mu * d
    else:
        if law == 4:
            re = rho * speed * d / mu
        else:
            re = rho * eps * speed * d / mu
        c = 0.5 * rho * drag_coefficient(law, re) * 0.25 * math.pi * d * d * speed
        if law == 3:
            log_re = math.log10(re)
            chi = 3.7 - 0.65 * math.exp(-0.5 * (1.5 - log_re) * (1.5 - log_re))
            c *= eps ** (2.0 - chi)
    return (fx + c * sx, fy + c * sy, fz + c * sz)

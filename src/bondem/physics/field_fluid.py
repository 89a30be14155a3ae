"""A fluid around the particles: drag and buoyancy (body forces on each particle).

The fluid has a density rho_f (kg/m^3), a dynamic viscosity mu (Pa s), a velocity field
u(x) = u_0 + W x x + u_grid(x) (m/s: a uniform flow u_0, a rigid rotation at W rad/s about
an axis through the origin, as a liquid turning with its drum, and a field given on a
grid, interpolated trilinearly) and a voidage eps (-, the local
fluid fraction; 1 for a lone particle). A particle of diameter d (m) at x moving at v
feels, with the slip s = u(x) - v and the particle Reynolds number
Re = rho_f eps |s| d / mu:

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
  - "musen_centrifugal": MUSEN's ModelEFCentrifugalCasting: Stokes drag 6 pi mu r s in the
    turning liquid plus (m - rho_f pi d^3 / 6) |W|^2 x_perp, the centrifugal force of the
    frame that turns with the liquid less the liquid's buoyancy (x_perp: x's part across
    the axis), as MUSEN adds both to a particle it moves in the laboratory's frame;
- buoyancy: F = -rho_f (pi d^3 / 6) g (Archimedes, g the gravity vector), when on.

The fluid's parameters travel as one array (``FLUID_*`` columns) so that the particle
loop body takes them as it takes gravity.
"""
import math

import numpy as np

from ._registry import physics

# columns of the fluid array (Model.fluid)
FLUID_DRAG, FLUID_DENSITY, FLUID_VISCOSITY, FLUID_VELOCITY = 0, 1, 2, 3
FLUID_BUOYANCY, FLUID_VOIDAGE, FLUID_SPIN, FLUID_COLUMNS = 6, 7, 8, 11
# drag correlations: their names and codes (0: no drag)
DRAG_LAWS = {"none": 0, "stokes": 1, "schiller_naumann": 2, "di_felice": 3,
             "musen_viscous": 4, "musen_centrifugal": 5}

# The field model's declaration (physics/field_models.py): the scene's [fluid] table (the
# fluid_array's keywords; the flow grid's file, formulas and local voidage are the
# scene's and coupling.FlowField's), the Model arrays its force reads beside its own.
NAME = "fluid"
INF = float("inf")
KEYS = {
    "density": ("number", 0.0, 0.0, INF, True, False),
    "viscosity": ("number", 0.0, 0.0, INF, True, False),
    "velocity": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "drag": ("str", "none", tuple(DRAG_LAWS), None, None, None),
    "buoyancy": ("bool", None, None, None, None, None),
    "voidage": ("number", 1.0, 0.0, 1.0, False, True),
    "spin": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
}
ARRAY = "fluid_array"
INPUTS = ("flow", "flow_box", "fluid_local")
FORCE = "fluid_field_force"
CLUMPS = True


def fluid_array(density=0.0, viscosity=0.0, velocity=(0.0, 0.0, 0.0), drag="none",
                buoyancy=False, voidage=1.0, spin=(0.0, 0.0, 0.0)):
    """The fluid around the particles as the particle loop takes it (FLUID_* columns):
    density kg/m^3 (>= 0), dynamic viscosity Pa s (> 0 for a drag law), velocity (3,)
    m/s, drag one of DRAG_LAWS, buoyancy (Archimedes' force, needs the density; None, the
    scene's default: on when the density is > 0), voidage in (0, 1], spin (3,) rad/s (the fluid turning
    about an axis through the origin: u(x) = velocity + spin x x). ValueError names a
    bad one."""
    if drag not in DRAG_LAWS:
        raise ValueError(f"drag = {drag!r}; allowed: {', '.join(DRAG_LAWS)}")
    velocity = np.asarray(velocity, dtype=np.float64)
    if velocity.shape != (3,) or not np.all(np.isfinite(velocity)):
        raise ValueError(f"velocity: expected 3 finite numbers, got {velocity!r}")
    spin = np.asarray(spin, dtype=np.float64)
    if spin.shape != (3,) or not np.all(np.isfinite(spin)):
        raise ValueError(f"spin: expected 3 finite numbers, got {spin!r}")
    if not (math.isfinite(density) and density >= 0.0):
        raise ValueError(f"density = {density!r}; allowed [0, inf)")
    if not (math.isfinite(viscosity) and viscosity >= 0.0):
        raise ValueError(f"viscosity = {viscosity!r}; allowed [0, inf)")
    if drag != "none" and viscosity == 0.0:
        raise ValueError(f"drag = {drag!r} needs viscosity > 0 (Pa s)")
    if drag not in ("none", "stokes") and density == 0.0:
        raise ValueError(f"drag = {drag!r} needs density > 0 (kg/m^3)")
    if not (0.0 < voidage <= 1.0):
        raise ValueError(f"voidage = {voidage!r}; allowed (0, 1]")
    if buoyancy is None:
        buoyancy = density > 0.0
    out = np.zeros(FLUID_COLUMNS)
    out[FLUID_DRAG] = DRAG_LAWS[drag]
    out[FLUID_DENSITY] = density
    out[FLUID_VISCOSITY] = viscosity
    out[FLUID_VELOCITY:FLUID_VELOCITY + 3] = velocity
    out[FLUID_BUOYANCY] = 1.0 if buoyancy else 0.0
    out[FLUID_VOIDAGE] = voidage
    out[FLUID_SPIN:FLUID_SPIN + 3] = spin
    return out


def active(fluid):
    """Whether the fluid ``fluid`` (FLUID_* columns) acts: a drag law or buoyancy."""
    return bool(fluid[FLUID_DRAG] != 0.0 or fluid[FLUID_BUOYANCY] != 0.0)


def time_scales(fluid, mass, radius):
    """{"fluid_drag": s} when the fluid drags particles of mass (N,) kg and radius (N,) m:
    a particle's velocity relaxes to the fluid's in m / (3 pi mu d) under Stokes drag;
    faster drag laws relax faster, by the factor their drag exceeds Stokes' at the
    Reynolds number they run at (docs/fields.md)."""
    if fluid[FLUID_DRAG] == 0.0 or not radius.size:
        return {}
    return {"fluid_drag": float((mass / (6.0 * np.pi * fluid[FLUID_VISCOSITY]
                                         * radius)).min())}


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


# the flow grid's box (Model.flow_box): origin (3,) m, spacing (3,) m (0: no grid)
FLOW_ORIGIN, FLOW_SPACING = 0, 3


@physics
def flow_cell(n, s):
    """(node index, weight of the next node) along one axis of n nodes at grid
    coordinate s (x - origin) / spacing, the nearest face's node outside the grid."""
    if n == 1 or s <= 0.0:
        return 0, 0.0
    if s >= n - 1:
        return n - 2, 1.0
    i = int(math.floor(s))
    return i, s - i


@physics
def flow_velocity(flow, flow_box, x):
    """The flow grid's velocity (m/s, 3-tuple) at x (m): trilinear interpolation of the
    node values flow (nx, ny, nz, 3) m/s on the nodes origin + (i, j, k) spacing
    (flow_box: FLOW_ORIGIN, FLOW_SPACING); outside the grid, the nearest face's values.
    Zero when the spacing is 0 (no grid)."""
    if flow_box[FLOW_SPACING] == 0.0:
        return (0.0, 0.0, 0.0)
    nx, ny, nz = flow.shape[0], flow.shape[1], flow.shape[2]
    i0, fx = flow_cell(nx, (x[0] - flow_box[FLOW_ORIGIN]) / flow_box[FLOW_SPACING])
    j0, fy = flow_cell(ny, (x[1] - flow_box[FLOW_ORIGIN + 1]) / flow_box[FLOW_SPACING + 1])
    k0, fz = flow_cell(nz, (x[2] - flow_box[FLOW_ORIGIN + 2]) / flow_box[FLOW_SPACING + 2])
    i1 = i0 + 1 if nx > 1 else i0
    j1 = j0 + 1 if ny > 1 else j0
    k1 = k0 + 1 if nz > 1 else k0
    ux = 0.0
    uy = 0.0
    uz = 0.0
    for c in range(3):
        c00 = flow[i0, j0, k0, c] * (1.0 - fx) + flow[i1, j0, k0, c] * fx
        c10 = flow[i0, j1, k0, c] * (1.0 - fx) + flow[i1, j1, k0, c] * fx
        c01 = flow[i0, j0, k1, c] * (1.0 - fx) + flow[i1, j0, k1, c] * fx
        c11 = flow[i0, j1, k1, c] * (1.0 - fx) + flow[i1, j1, k1, c] * fx
        value = ((c00 * (1.0 - fy) + c10 * fy) * (1.0 - fz)
                 + (c01 * (1.0 - fy) + c11 * fy) * fz)
        if c == 0:
            ux = value
        elif c == 1:
            uy = value
        else:
            uz = value
    return (ux, uy, uz)


@physics
def local_fluid(local, p):
    """Particle p's row of the per-particle fluid array ``local`` (N, 4): the fluid's
    velocity added there (m/s, 3) and the voidage around it (-, 0: the fluid's own), as a
    4-tuple; zeros when the array has no row p (none given)."""
    if p >= local.shape[0]:
        return (0.0, 0.0, 0.0, 0.0)
    return (local[p, 0], local[p, 1], local[p, 2], local[p, 3])


@physics
def fluid_force(fluid, flow, flow_box, local, radius, mass, x, v, gravity):
    """Drag plus buoyancy (N, 3-tuple) on a particle of radius (m) and mass (kg) at x (m)
    moving at v (m/s) in the fluid ``fluid`` (FLUID_* columns) whose velocity adds the
    flow grid's (``flow_velocity``) and the particle's own ``local`` (``local_fluid``'s
    4-tuple: a velocity, m/s, and a voidage replacing the fluid's where > 0), gravity
    (m/s^2)."""
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
    eps = fluid[FLUID_VOIDAGE] if local[3] <= 0.0 else local[3]
    wx = fluid[FLUID_SPIN]
    wy = fluid[FLUID_SPIN + 1]
    wz = fluid[FLUID_SPIN + 2]
    grid = flow_velocity(flow, flow_box, x)
    sx = fluid[FLUID_VELOCITY] + wy * x[2] - wz * x[1] + grid[0] + local[0] - v[0]
    sy = fluid[FLUID_VELOCITY + 1] + wz * x[0] - wx * x[2] + grid[1] + local[1] - v[1]
    sz = fluid[FLUID_VELOCITY + 2] + wx * x[1] - wy * x[0] + grid[2] + local[2] - v[2]
    if law == 5:
        # MUSEN's centrifugal casting: x's part across the spin axis, |W|^2 times the
        # mass less the liquid it displaces
        w2 = wx * wx + wy * wy + wz * wz
        along = (x[0] * wx + x[1] * wy + x[2] * wz) / w2 if w2 > 0.0 else 0.0
        net = (mass - rho * 4.0 / 3.0 * math.pi * radius * radius * radius) * w2
        c = 6.0 * math.pi * mu * radius
        return (fx + c * sx + net * (x[0] - along * wx),
                fy + c * sy + net * (x[1] - along * wy),
                fz + c * sz + net * (x[2] - along * wz))
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


@physics
def fluid_field_force(fluid, flow, flow_box, local, p, mass, radius, x, v, gravity):
    """The field model's FORCE (physics/field_models.py): ``fluid_force`` on particle p
    of mass (kg) and radius (m) at x (m) moving at v (m/s), with its row of the
    per-particle fluid ``local`` (N, 4), gravity (m/s^2). N, 3-tuple."""
    return fluid_force(fluid, flow, flow_box, local_fluid(local, p), radius, mass, x, v,
                       gravity)

"""The loop bodies of both backends, written once: what one bond, particle or contact does.

Each body below is a plain function of an index (a bond, a particle, a contact row) and
named tuples of arrays (``Bonds``, ``Particles``, ...); it reads its inputs, calls the
``bondem.physics`` laws and writes its own outputs. ``compile_loops(jit, physics_jit)``
compiles them for a target exactly as ``compile_physics`` compiles the laws: the CPU
backend with ``numba.njit(inline="always")``, inlined into serial loops over chunks of
items that its ``prange`` kernels run (``backends/cpu.py``, ``cpu_contacts.py``), the CUDA
backend with ``cuda.jit(device=True)``, called from grid-stride kernels (``cuda.py``,
``cuda_contacts.py``). So the two backends share every line of a step but the loop.

Why chunks on the CPU (each measured): a body inlined into the ``prange`` itself reads
its arrays from named tuples inside the parallel region, where Numba 0.68 drops the
stores (it treats the tuple as immutable and removes the loop as dead code); a body
called once per item pays a reference count round trip per array (integrate 2.5x
slower). The serial chunk loops use NumPy's error model, as parfor bodies do.

Choices made at compile time, not per item: ``musen`` and the contact ``law`` are None
on the CPU for the SPEC's bond law and for Hertz-Mindlin, so Numba prunes the other laws
from the kernel it compiles (``x is None`` on an argument is decided by its type); the
CUDA kernels cannot take None, so they pass a flag and compile both branches. For the
contacts ``musen`` is the MUSEN release's code (physics/contact_hertz_musen.py:
MUSEN_1_70, MUSEN_1_74; 0 on the GPU for the SPEC's law), for the bonds True (their law
is the same in both releases).
"""
import math
from collections import namedtuple

import numpy as np

from ..physics import compile_physics
from ..physics._registry import compile_functions
from ..physics.bond_elastic import INTACT
from ..physics import bond_models
from ..physics.bond_models import bond_material_schema
from ..physics.triangle import FACE
from ..status import STATUS_NOT_FINITE, STATUS_OK, STATUS_OUT_OF_DOMAIN
from ..walls import PLANE

from ..physics import contact_models, field_models
from ..physics._registry import (PAIR_BETA, PAIR_E_STAR, PAIR_FRICTION,  # noqa: F401
                                 PAIR_G_STAR, PAIR_MODEL, PAIR_ROLLING, PAIR_STIFFNESS)

# What the bodies take, by name (a swapped pair of same-shaped arrays would otherwise
# run silently). Units: SI throughout (m, m/s, rad/s, kg, kg m^2, N, N m, J, Pa).
Particles = namedtuple("Particles", "position velocity angular_velocity")
Bodies = namedtuple("Bodies", "mass inertia fixed external_force external_moment radius")
# The body-force fields (physics/field_models.py's ARRAYS): gravity (3,) m/s^2, acting
# (uint8 per model, field_models.switches: which models the loops evaluate), each
# field model's parameter array under its NAME (the fluid's FLUID_* columns, the rotating
# frame's FRAME_*), then their INPUTS (the fluid's flow grid (nx, ny, nz, 3) m/s and box
# FLOW_*, its per-particle fluid_local (N, 4) or (0, 4): a velocity m/s and a voidage)
Fields = namedtuple("Fields", field_models.ARRAYS)
Box = namedtuple("Box", "low high length periodic")
# Clumps (Model.clump_*): members of clump c are members[offsets[c]:offsets[c+1]]; offset
# (N,3) m each member's place in its clump's body frame; mass (C,) kg; inertia (C,3)
# kg m^2 the principal moments; fixed (C,) bool: motion prescribed. ClumpState: State.clump_* (m, unit quaternion, m/s, N m s).
Clumps = namedtuple("Clumps", "offsets members offset mass inertia fixed")
ClumpState = namedtuple("ClumpState", "position orientation velocity angular_momentum")
# strength: each bond's strength factor (Model.bond_strength_factors; 1 without scatter)
Bonds = namedtuple("Bonds", "pairs diameter initial_length material strength")
# One array per bond material key (Model.bond_material_table: breakage as criterion codes,
# model as the bond model's code), whatever the bond models declare.
BondMaterials = namedtuple("BondMaterials", list(bond_material_schema()))
# model_state: (B, 3) the per-bond state of bond models that have one (physics/
# bond_models.py: column 0 the J of STATE, e.g. a Kelvin bond's J lost, columns 1 and 2
# SPRINGS' own, e.g. a plastic strain), one unused row when none is used.
BondState = namedtuple("BondState", "active axis previous_length tangential_force "
                       "normal_moment tangential_moment break_time break_mode break_energy "
                       "model_state")
BondLoads = namedtuple("BondLoads", "force_i moment_i moment_j")
BondIndex = namedtuple("BondIndex", "offsets ends")
Grains = namedtuple("Grains", "radius mass inertia material")
# pair: one row per ordered pair of materials (a M + b, M materials) with columns PAIR_*,
# the pair's properties the SPEC law needs, computed once (contact_materials) instead of
# per contact and step (a log and five divisions).
ContactMaterials = namedtuple("ContactMaterials",
                              "young poisson restitution friction rolling pair")
# tangential: the tangential force of the last sticking step (N), which MUSEN's law applies
# while a contact slides (musen_compat only; SPEC runs pass one unused row)
PairRows = namedtuple("PairRows", "spring force moment_i moment_j energy dissipated "
                      "tangential")
# quiet: 1 for a row that holds no load (``row_quiet``): the gather skips a particle whose
# rows are all quiet. The CPU keeps it per step, the GPU passes zeros (it reads every row).
PairIndex = namedtuple("PairIndex", "i_start i_order j_start j_order quiet")
# pair: the pair table of particle material a against wall w in row a W + w (W walls)
Walls = namedtuple("Walls", "rows types element_wall velocity omega center young poisson "
                   "restitution friction rolling pair")
WallRows = namedtuple("WallRows", "spring force moment energy dissipated work distance "
                      "point feature tangential")

_BODIES = []


def contact_materials(young, poisson, restitution, friction, rolling, model=None,
                      parameters=(), stiffness=0.0, use_rolling=True, wall=None):
    """The ``ContactMaterials`` of M materials (arrays of E in Pa, nu, e, mu, mu_r), with
    the pair table (physics/contact_models.py): E* and G* (Pa), beta of the mean
    restitution, the mean friction and mean rolling friction (0 without rolling
    resistance) of each ordered pair by the physics' own functions, the linear law's k_n
    setting ``stiffness`` (N/m, 0 for its default) and contact model ``model``'s own
    parameters (``parameters``: one {key: value} dict per material, mixed by its rules).
    wall: None, or the walls' (E, nu, e, mu, mu_r, parameters) for a table whose row
    a W + w is particle material a against wall w (W walls) instead."""
    from ..physics.contact_hertz import (effective_shear_modulus, effective_young_modulus,
                                         restitution_beta)
    from ..physics.contact_models import pair_columns, pair_parameters
    young, poisson, restitution, friction, rolling = (
        np.ascontiguousarray(a, dtype=np.float64)
        for a in (young, poisson, restitution, friction, rolling))
    m = young.shape[0]
    other = (young, poisson, restitution, friction, rolling, parameters) if wall is None \
        else tuple(np.ascontiguousarray(a, dtype=np.float64) for a in wall[:5]) + (wall[5],)
    w = other[0].shape[0]
    own = pair_columns(model) if model is not None else 0
    # at least one model column: MUSEN's laws read column PAIR_MODEL whatever the model
    pair = np.zeros((max(m * w, 1), PAIR_MODEL + max(own, 1)))
    for a in range(m):
        for b in range(w):
            q = a * w + b
            pair[q, PAIR_E_STAR] = effective_young_modulus(young[a], poisson[a], other[0][b],
                                                           other[1][b])
            pair[q, PAIR_G_STAR] = effective_shear_modulus(young[a], poisson[a], other[0][b],
                                                           other[1][b])
            pair[q, PAIR_BETA] = restitution_beta(0.5 * (restitution[a] + other[2][b]))
            pair[q, PAIR_FRICTION] = 0.5 * (friction[a] + other[3][b])
            pair[q, PAIR_ROLLING] = 0.5 * (rolling[a] + other[4][b]) if use_rolling else 0.0
            pair[q, PAIR_STIFFNESS] = stiffness
            if own:
                pair[q, PAIR_MODEL:] = pair_parameters(model, parameters[a], other[5][b],
                                                       pair[q, PAIR_E_STAR])
    return ContactMaterials(young, poisson, restitution, friction, rolling, pair)


def body(function):
    """Register a loop body (compiled for every backend by ``compile_loops``)."""
    _BODIES.append(function)
    return function


def compile_loops(jit, physics_jit, substitute=None, given=None):
    """Namespace of every loop body compiled by ``jit``, calling the physics compiled by
    ``physics_jit`` (and the physics functions themselves, by name); ``given``: {body
    name: compiled function} used instead of those bodies (the CPU's ``raw.ROWS``)."""
    return compile_functions(_BODIES, jit, base=compile_physics(physics_jit, substitute),
                             given=given)


# -- small helpers ------------------------------------------------------------------------

@body
def row3(a, i):
    """Row i of an (n, 3) array as a 3-tuple."""
    return (a[i, 0], a[i, 1], a[i, 2])


@body
def store3(a, i, v):
    """a[i] = v for an (n, 3) array and a 3-tuple."""
    a[i, 0] = v[0]
    a[i, 1] = v[1]
    a[i, 2] = v[2]


@body
def sign(x):
    """-1, 0 or +1 (np.sign of a float; 0 for NaN)."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@body
def separation(position, i, j, box):
    """x_j - x_i (m), the shortest periodic image."""
    return minimum_image((position[j, 0] - position[i, 0], position[j, 1] - position[i, 1],
                          position[j, 2] - position[i, 2]),
                         (box.length[0], box.length[1], box.length[2]),
                         box.periodic[0], box.periodic[1], box.periodic[2])


# -- bonds --------------------------------------------------------------------------------

@body
def bond_update(musen, r, vi, vj, wi, wj, axis, previous_length, f_t0, m_n0, m_t0, l0,
                young, poisson, diameter, normal_strength, tangential_strength, criterion,
                compressive, dt):
    """One increment dt (s) of a bond and its break test: (length, n, F_n, F_t, M_n, M_t,
    break mode, k_n, k_t, k_tw, k_b). musen: None or False for the SPEC's law, True for
    MUSEN's numerics (physics/bond_elastic_musen.py), which need the previous bond with
    its length."""
    kn, kt, ktw, kb = bond_stiffnesses(young, poisson, diameter, l0)
    if musen is not None:
        if musen:
            lp = previous_length
            length, n, f_n, f_t, m_n, m_t = elastic_bond_musen(
                r, vi, vj, wi, wj, (axis[0] * lp, axis[1] * lp, axis[2] * lp), f_t0, m_n0,
                m_t0, l0, young, poisson, diameter, dt)
            mode = bond_break_mode_musen(length, l0, f_n, f_t, m_n, m_t, diameter,
                                         normal_strength, tangential_strength, criterion)
            return length, n, f_n, f_t, m_n, m_t, mode, kn, kt, ktw, kb
    length, n, f_n, f_t, m_n, m_t = elastic_bond(r, vi, vj, wi, wj, axis, f_t0, m_n0, m_t0,
                                                 l0, kn, kt, ktw, kb, dt)
    mode = bond_break_mode(length, l0, f_n, f_t, m_n, m_t, diameter, normal_strength,
                           tangential_strength, criterion, compressive)
    return length, n, f_n, f_t, m_n, m_t, mode, kn, kt, ktw, kb


def _generated(name, signature, dispatch, default, doc, models=None, code="code",
               none_first=False):
    """A loop body ``name(code, signature)`` written from a list of models (``models``:
    physics/bond_models.py's by default): ``dispatch(module)`` gives the lines of the
    branch of a model's code (or None), ``default`` the lines for every other code.
    none_first: a ``code`` of None (the CPU's default law, then compiled alone: Numba
    prunes the other branch by type) runs ``default`` before any comparison."""
    head = [f"def {name}({code}, {signature}):"]
    indent = "    "
    if none_first:
        head += [f"    if {code} is None:"] + [f"        {x}" for x in default] + ["    else:"]
        indent = "        "
    lines = head
    for module in (models if models is not None else bond_models.MODELS):
        branch = dispatch(module)
        if branch:
            lines += [f"{indent}if {code} == {module.CODE}:"] + [f"{indent}    {x}"
                                                                 for x in branch]
    lines += [f"{indent}{x}" for x in default]
    namespace = {}
    exec(compile("\n".join(lines), f"<models: {__name__}>", "exec"), namespace)
    function = namespace[name]
    function.__doc__ = doc
    return function


_LOADS_ARGUMENTS = ("musen, r, length, l0, diameter, vi, vj, wi, wj, f_n, f_t, m_n, m_t, "
                    "kn, kt, materials, m")
model_loads = body(_generated(
    "model_loads", _LOADS_ARGUMENTS,
    lambda module: module.LOADS and [f"return {module.LOADS}({_LOADS_ARGUMENTS})"],
    ["force_i, moment_i, moment_j = bond_loads_on_particles(r, f_n, f_t, m_n, m_t)",
     "return force_i, moment_i, moment_j, 0.0"],
    """(force on i, moment on i, moment on j, rate of the bond model's energy) by the
    LOADS of the bond model with that code (the springs' own loads for the elastic
    bond)."""))

_SPRINGS_ARGUMENTS = ("musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, "
                      "mode, kn, kt, scatter, lp")
model_springs = body(_generated(
    "model_springs", _SPRINGS_ARGUMENTS + ", columns, materials, m",
    lambda module: getattr(module, "SPRINGS", None) and [
        f"f_n, f_t, m_n, m_t, mode, s1, s2, lost = {module.SPRINGS}({_SPRINGS_ARGUMENTS}, "
        "columns[b, 1], columns[b, 2], materials, m)",
        "columns[b, 1] = s1", "columns[b, 2] = s2", "columns[b, 0] += lost",
        "return f_n, f_t, m_n, m_t, mode"],
    ["return f_n, f_t, m_n, m_t, mode"],
    """The springs (F_n, F_t in N, M_n, M_t in N m) and break mode of bond b after the
    SPRINGS of the bond model with that code, which reads and writes its columns of
    ``columns`` (state.model_state) and scales its strengths by ``scatter`` (the bond's
    strength factor); lp: the bond's length in the previous step (m). Unchanged for a
    model without SPRINGS."""))

_ENERGY_ARGUMENTS = "length, l0, f_t, m_n, m_t, kn, kt, ktw, kb"
model_bond_energy = body(_generated(
    "model_bond_energy", _ENERGY_ARGUMENTS + ", b, columns, materials, m",
    lambda module: getattr(module, "ENERGY", None) and [
        "return bond_elastic_energy(l0, l0, f_t, m_n, m_t, kn, kt, ktw, kb) + "
        f"{module.ENERGY}(length, l0, kn, columns[b, 1], columns[b, 2], materials, m)"],
    [f"return bond_elastic_energy({_ENERGY_ARGUMENTS})"],
    """J held by bond b at ``length`` (m) with springs f_t (N), m_n, m_t (N m): the four
    springs' potentials, its normal spring's by the ENERGY of the bond model with that
    code if it has one (a plastic bond's spring is stretched from its plastic length)."""))


@body
def zero_bond_loads(b, loads):
    """Bond b puts no load on its particles."""
    for k in range(3):
        loads.force_i[b, k] = 0.0
        loads.moment_i[b, k] = 0.0
        loads.moment_j[b, k] = 0.0


@body
def advance_bond(b, bonds, materials, state, particles, box, time, dt, musen, loads):
    """Advance bond b by one increment dt (s) at ``time`` (s): its state, its break test,
    its loads on i (force, moment) and j (moment) in its own row of ``loads``, and its
    model's per-bond state (state.model_state[b], e.g. a Kelvin bond's J lost)."""
    if not state.active[b]:
        zero_bond_loads(b, loads)
        return
    i = bonds.pairs[b, 0]
    j = bonds.pairs[b, 1]
    m = bonds.material[b]
    l0 = bonds.initial_length[b]
    diameter = bonds.diameter[b]
    scatter = bonds.strength[b]
    r = separation(particles.position, i, j, box)
    vi = row3(particles.velocity, i)
    vj = row3(particles.velocity, j)
    wi = row3(particles.angular_velocity, i)
    wj = row3(particles.angular_velocity, j)
    length, n, f_n, f_t, m_n, m_t, mode, kn, kt, ktw, kb = bond_update(
        musen, r, vi, vj, wi, wj, row3(state.axis, b), state.previous_length[b],
        row3(state.tangential_force, b), row3(state.normal_moment, b),
        row3(state.tangential_moment, b), l0, materials.young_modulus[m],
        materials.poisson_ratio[m], diameter, materials.normal_strength[m] * scatter,
        materials.tangential_strength[m] * scatter, materials.breakage[m],
        materials.compressive_breakage[m], dt)
    code = materials.model[m]
    f_n, f_t, m_n, m_t, mode = model_springs(
        code, musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode, kn, kt,
        scatter, state.previous_length[b], state.model_state, materials, m)
    if mode != INTACT:
        state.active[b] = False
        state.break_time[b] = time
        state.break_mode[b] = mode
        state.break_energy[b] = model_bond_energy(code, length, l0, f_t, m_n, m_t, kn, kt,
                                                  ktw, kb, b, state.model_state, materials, m)
        zero_bond_loads(b, loads)
        return
    force_i, moment_i, moment_j, rate = model_loads(
        code, musen, r, length, l0, diameter, vi, vj, wi, wj, f_n, f_t, m_n, m_t, kn, kt,
        materials, m)
    if rate != 0.0:
        state.model_state[b, 0] += rate * dt
    state.previous_length[b] = length
    store3(state.axis, b, n)
    store3(state.tangential_force, b, f_t)
    store3(state.normal_moment, b, m_n)
    store3(state.tangential_moment, b, m_t)
    store3(loads.force_i, b, force_i)
    store3(loads.moment_i, b, moment_i)
    store3(loads.moment_j, b, moment_j)


@body
def bond_ends_sum(p, index, loads, start_f, start_m):
    """start_f (N) and start_m (N m) plus the force and moment of particle p's bonds, added
    one bond end at a time in a fixed CSR order (end = 2 bond + side; side 1 is j, which
    gets -F and its own moment). Starting from the loads already there adds the bonds
    after the contacts, in MUSEN's order (CPUSimulator::CalculateForcesSB)."""
    force, moment = start_f, start_m
    for k in range(index.offsets[p], index.offsets[p + 1]):
        b = index.ends[k] >> 1
        if index.ends[k] & 1:
            force = sub(force, row3(loads.force_i, b))
            moment = add(moment, row3(loads.moment_j, b))
        else:
            force = add(force, row3(loads.force_i, b))
            moment = add(moment, row3(loads.moment_i, b))
    return force, moment


@body
def bond_energy(b, bonds, materials, state, position, box):
    """Elastic energy (J) stored in bond b; 0 if broken."""
    if not state.active[b]:
        return 0.0
    m = bonds.material[b]
    l0 = bonds.initial_length[b]
    r = separation(position, bonds.pairs[b, 0], bonds.pairs[b, 1], box)
    kn, kt, ktw, kb = bond_stiffnesses(materials.young_modulus[m], materials.poisson_ratio[m],
                                       bonds.diameter[b], l0)
    return model_bond_energy(materials.model[m],
                             math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]), l0,
                             row3(state.tangential_force, b), row3(state.normal_moment, b),
                             row3(state.tangential_moment, b), kn, kt, ktw, kb, b,
                             state.model_state, materials, m)


# -- particles ----------------------------------------------------------------------------

def _summed(name, signature, terms, doc):
    """A loop body ``name(signature)`` returning the sum of the 3-tuples ``terms``
    ((k, expression): a field model's term, evaluated only where fields.acting[k], the
    model's switch; zero for none acting), added in their order. The switch is there
    for speed: a field that does not act still costs its call per particle (its arrays
    passed by value), 2 of the 3 ms of integrating a 10^5-particle bed on two threads."""
    lines = [f"def {name}({signature}):", "    total = (0.0, 0.0, 0.0)",
             "    started = False"]
    for k, term in terms:
        lines += [f"    if fields.acting[{k}]:",
                  f"        term = {term}",
                  "        total = add(total, term) if started else term",
                  "        started = True"]
    lines.append("    return total")
    namespace = {}
    exec(compile("\n".join(lines), f"<fields: {__name__}>", "exec"), namespace)
    function = namespace[name]
    function.__doc__ = doc
    return function


def _field_force_term(module):
    arrays = ", ".join(f"fields.{name}" for name in (module.NAME, *module.INPUTS))
    return f"{module.FORCE}({arrays}, p, mass, radius, x, v, fields.gravity)"


field_force = body(_summed(
    "field_force", "fields, p, mass, radius, x, v",
    [(k, _field_force_term(m)) for k, m in enumerate(field_models.MODELS)],
    """The acting field models' force (N, 3-tuple; physics/field_models.py's FORCE) on
    particle p of mass (kg) and radius (m) at x (m) moving at v (m/s), from the
    ``fields``."""))
clump_field_force = body(_summed(
    "clump_field_force", "fields, p, mass, radius, x, v",
    [(k, _field_force_term(m)) for k, m in enumerate(field_models.MODELS) if m.CLUMPS],
    """``field_force`` of the field models that act on clumps' members (CLUMPS)."""))
field_moment = body(_summed(
    "field_moment", "fields, inertia, w",
    [(k, f"{m.MOMENT}(fields.{m.NAME}, inertia, w)")
     for k, m in enumerate(field_models.MODELS) if getattr(m, "MOMENT", None)],
    """The acting field models' moment (N m, 3-tuple; MOMENT) on a sphere of moment of
    inertia (kg m^2) spinning at w (rad/s), from the ``fields``."""))


@body
def kick(v, w, load_f, load_m, applied, applied_m, mass, inertia, damping, kick_dt):
    """One component of ``integrate_particle``'s kick: (new v (m/s), new w (rad/s), the
    damping force (N) and moment (N m)), from the old v, w, the contact and bond loads
    load_f (N), load_m (N m) and the applied ones (gravity, fields, external)."""
    f = load_f + applied
    mk = load_m + applied_m
    damp_f = 0.0
    damp_m = 0.0
    if damping > 0.0:
        damp_f = -damping * abs(f) * sign(v)
        damp_m = -damping * abs(mk) * sign(w)
    return (v + (f + damp_f) / mass * kick_dt, w + (mk + damp_m) / inertia * kick_dt,
            damp_f, damp_m)


@body
def kick_energy(v, w, kicked, applied, applied_m, kick_dt, track_energy):
    """(work of the applied loads, energy removed by damping) in J of one component
    ``kicked`` (``kick``'s result) from the old v (m/s), w (rad/s): each load times the
    mean of the old and new velocity. 0 where the caller does not track and no load is
    applied (it would add +-0, which changes no sum)."""
    if track_energy or applied != 0.0 or applied_m != 0.0:
        v_mean = 0.5 * (v + kicked[0])
        w_mean = 0.5 * (w + kicked[1])
        return ((applied * v_mean + applied_m * w_mean) * kick_dt,
                -(kicked[2] * v_mean + kicked[3] * w_mean) * kick_dt)
    return 0.0, 0.0


@body
def particle_status(p, particles, box):
    """STATUS_NOT_FINITE if particle p's position, velocity or spin is not finite,
    STATUS_OUT_OF_DOMAIN if it lies outside the box on an axis that is not periodic,
    else STATUS_OK (on axes in order, the last such finding)."""
    status = STATUS_OK
    for k in range(3):
        x = particles.position[p, k]
        if not box.periodic[k] and (x < box.low[k] or x > box.high[k]):
            status = STATUS_OUT_OF_DOMAIN
        if not (math.isfinite(x) and math.isfinite(particles.velocity[p, k])
                and math.isfinite(particles.angular_velocity[p, k])):
            status = STATUS_NOT_FINITE
    return status


@body
def integrate_particle(p, load_f, load_m, particles, bodies, fields, damping, kick_dt,
                       drift_dt, box, track_energy):
    """Semi-implicit Euler for particle p: v += F/m kick_dt; x += v drift_dt;
    w += M/I kick_dt, with its loads load_f (N), load_m (N m) and the ``fields``: gravity,
    the field models' forces and moments (``field_force``, ``field_moment``: a fluid's
    drag and buoyancy, a rotating frame's centrifugal and Coriolis forces and its torque
    on the spin; all at the state before the kick), external loads and local
    damping (Cundall:
    damping |F_k| against the sign of v_k, |M_k| against w_k, per component). Fixed
    particles keep their velocity. Returns (work of gravity, the fields and external
    loads, energy removed by damping) in J over this kick, each
    load times the mean of the old and new velocity (the leapfrog's exact change of
    kinetic energy; only where track_energy or an external load acts on the component,
    since it costs a third of the step), and a status:
    STATUS_NOT_FINITE or STATUS_OUT_OF_DOMAIN if it blew up, else STATUS_OK; a periodic
    axis wraps the position into the box."""
    work = 0.0
    lost = 0.0
    v = row3(particles.velocity, p)
    w = row3(particles.angular_velocity, p)
    if not bodies.fixed[p]:
        mass = bodies.mass[p]
        inertia = bodies.inertia[p]
        gravity = fields.gravity
        carried = field_force(fields, p, mass, bodies.radius[p],
                              row3(particles.position, p), v)
        turned = field_moment(fields, inertia, w)
        outside_f = row3(bodies.external_force, p)
        outside_m = row3(bodies.external_moment, p)
        applied = (mass * gravity[0] + outside_f[0] + carried[0],
                   mass * gravity[1] + outside_f[1] + carried[1],
                   mass * gravity[2] + outside_f[2] + carried[2])
        applied_m = (outside_m[0] + turned[0], outside_m[1] + turned[1],
                     outside_m[2] + turned[2])
        along_x = kick(v[0], w[0], load_f[0], load_m[0], applied[0], applied_m[0], mass,
                       inertia, damping, kick_dt)
        along_y = kick(v[1], w[1], load_f[1], load_m[1], applied[1], applied_m[1], mass,
                       inertia, damping, kick_dt)
        along_z = kick(v[2], w[2], load_f[2], load_m[2], applied[2], applied_m[2], mass,
                       inertia, damping, kick_dt)
        # Energies only where tracked or a load is applied, tested once for the three
        # components rather than in each (without gravity, damping or fields the caller
        # does not track, and the external loads are zero but where a script or a
        # coupled solver set them)
        if track_energy or ((applied[0] != 0.0) | (applied[1] != 0.0)
                            | (applied[2] != 0.0) | (applied_m[0] != 0.0)
                            | (applied_m[1] != 0.0) | (applied_m[2] != 0.0)):
            energy_x = kick_energy(v[0], w[0], along_x, applied[0], applied_m[0], kick_dt,
                                   track_energy)
            energy_y = kick_energy(v[1], w[1], along_y, applied[1], applied_m[1], kick_dt,
                                   track_energy)
            energy_z = kick_energy(v[2], w[2], along_z, applied[2], applied_m[2], kick_dt,
                                   track_energy)
            # in component order
            work = 0.0 + energy_x[0] + energy_y[0] + energy_z[0]
            lost = 0.0 + energy_x[1] + energy_y[1] + energy_z[1]
        v = (along_x[0], along_y[0], along_z[0])
        w = (along_x[1], along_y[1], along_z[1])
        store3(particles.velocity, p, v)
        store3(particles.angular_velocity, p, w)
    here = row3(particles.position, p)
    # Without branches: ``outside`` on any axis off the domain, ``spread`` NaN where any
    # of x, v, w is not finite (x - x is 0 only for a finite x); the status itself, rare,
    # from ``particle_status``. With the energies' single test above: integrating took
    # 0.9 of its time on the n = 47 lattice, 0.83 on the 10^5 bed (two threads).
    outside = False
    spread = 0.0
    for k in range(3):
        x = here[k] + v[k] * drift_dt
        if box.periodic[k]:
            length = box.high[k] - box.low[k]
            x -= length * math.floor((x - box.low[k]) / length)
        else:
            outside |= (x < box.low[k]) | (x > box.high[k])
        spread += (x - x) + (v[k] - v[k]) + (w[k] - w[k])
        particles.position[p, k] = x
    if outside or spread != 0.0:
        return work, lost, particle_status(p, particles, box)
    return work, lost, STATUS_OK


@body
def row4(a, i):
    """Row i of an (n, 4) array as a 4-tuple."""
    return (a[i, 0], a[i, 1], a[i, 2], a[i, 3])


@body
def integrate_clump(c, force, moment, clumps, clump_state, particles, bodies, fields,
                    damping, kick_dt, drift_dt, box, track_energy):
    """The leapfrog of rigid clump c (physics/rigid_body.py): its members' loads force (N)
    and moment (N m), their external loads and the fields' force on each
    (``clump_field_force``, at its own place and velocity) summed into the clump's force
    and its torque about the centre of mass, lever arms R(q) d from the clump's
    orientation at the start of the step; gravity
    on the clump's mass; local damping per component against the signs of V and of the
    angular velocity. Kick: V += F/M kick_dt, L += T kick_dt (lab frame); drift:
    X += V drift_dt, q by NO_SQUISH over drift_dt. Then each member p is placed at
    X + R(q) d_p (wrapped into a periodic box) with velocity V + w x R(q) d_p and angular
    velocity w = R I^-1 R^T L. Returns (work of gravity, fields and external loads, energy
    removed by damping) in J over this kick (0 unless track_energy or external loads
    act) and a status as
    ``integrate_particle``'s. A fixed clump keeps its V and L (no kick), and moves."""
    first = clumps.offsets[c]
    last = clumps.offsets[c + 1]
    mass = clumps.mass[c]
    inertia = row3(clumps.inertia, c)
    q = row4(clump_state.orientation, c)
    centre = row3(clump_state.position, c)
    velocity = row3(clump_state.velocity, c)
    spin = body_angular_velocity(q, row3(clump_state.angular_momentum, c), inertia)
    gravity = fields.gravity
    applied = (mass * gravity[0], mass * gravity[1], mass * gravity[2])
    load = (0.0, 0.0, 0.0)
    torque = (0.0, 0.0, 0.0)
    applied_m = (0.0, 0.0, 0.0)
    for k in range(first, last):
        p = clumps.members[k]
        arm = quaternion_rotate(q, row3(clumps.offset, p))
        here = add(centre, arm)
        moving = add(velocity, cross(spin, arm))
        outside = add(row3(bodies.external_force, p),
                      clump_field_force(fields, p, bodies.mass[p], bodies.radius[p], here,
                                        moving))
        f = row3(force, p)
        load = add(load, f)
        torque = add(torque, add(row3(moment, p), cross(arm, f)))
        applied = add(applied, outside)
        applied_m = add(applied_m, add(row3(bodies.external_moment, p), cross(arm, outside)))
    torque = add(torque, applied_m)
    damp_m = (0.0, 0.0, 0.0)
    if damping > 0.0:
        damp_m = (-damping * abs(torque[0]) * sign(spin[0]),
                  -damping * abs(torque[1]) * sign(spin[1]),
                  -damping * abs(torque[2]) * sign(spin[2]))
    work = 0.0
    lost = 0.0
    v = clump_state.velocity
    momentum = clump_state.angular_momentum
    fixed = clumps.fixed[c]
    for k in range(3):
        if fixed:
            break
        f = load[k] + applied[k]
        damp_f = 0.0
        if damping > 0.0:
            damp_f = -damping * abs(f) * sign(v[c, k])
        v_old = v[c, k]
        v[c, k] = v_old + (f + damp_f) / mass * kick_dt
        momentum[c, k] += (torque[k] + damp_m[k]) * kick_dt
        if track_energy or applied[k] != 0.0:   # as integrate_particle's
            v_mean = 0.5 * (v_old + v[c, k])
            work += applied[k] * v_mean * kick_dt
            lost -= damp_f * v_mean * kick_dt
    if (track_energy or applied_m[0] != 0.0 or applied_m[1] != 0.0
            or applied_m[2] != 0.0) and not fixed:
        # the torques' work with the mean of the old and new angular velocities
        spin_mean = scale(add(spin, body_angular_velocity(q, row3(momentum, c), inertia)),
                          0.5)
        work += dot(applied_m, spin_mean) * kick_dt
        lost -= dot(damp_m, spin_mean) * kick_dt
    status = STATUS_OK
    for k in range(3):
        x = clump_state.position[c, k] + v[c, k] * drift_dt
        if box.periodic[k]:
            length = box.high[k] - box.low[k]
            x -= length * math.floor((x - box.low[k]) / length)
        if not (math.isfinite(x) and math.isfinite(v[c, k]) and math.isfinite(momentum[c, k])):
            status = STATUS_NOT_FINITE
        clump_state.position[c, k] = x
    if drift_dt != 0.0:
        q = free_rotation(q, row3(momentum, c), inertia, drift_dt)
        for k in range(4):
            clump_state.orientation[c, k] = q[k]
    centre = row3(clump_state.position, c)
    velocity = row3(v, c)
    spin = body_angular_velocity(q, row3(momentum, c), inertia)
    for k in range(first, last):
        p = clumps.members[k]
        arm = quaternion_rotate(q, row3(clumps.offset, p))
        moving = add(velocity, cross(spin, arm))
        for a in range(3):
            x = centre[a] + arm[a]
            if box.periodic[a]:
                length = box.high[a] - box.low[a]
                x -= length * math.floor((x - box.low[a]) / length)
            elif x < box.low[a] or x > box.high[a]:
                status = STATUS_OUT_OF_DOMAIN
            if not math.isfinite(x):
                status = STATUS_NOT_FINITE
            particles.position[p, a] = x
            particles.velocity[p, a] = moving[a]
            particles.angular_velocity[p, a] = spin[a]
    return work, lost, status


# -- contacts -----------------------------------------------------------------------------

def _contact_generated(name, signature, dispatch, default, doc):
    """``_generated`` over physics/contact_models.py's list: ``name(law, signature)``,
    ``default`` for ``law`` None (CPU: the default law, compiled alone) and every other
    code."""
    return _generated(name, signature, dispatch, default, doc, contact_models.MODELS,
                      "law", none_first=True)


_LAW_ARGUMENTS = "n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt"
contact_law = body(_contact_generated(
    "contact_law", _LAW_ARGUMENTS,
    lambda module: module.CODE and [f"return {module.LAW}({_LAW_ARGUMENTS})"],
    [f"return hertz_mindlin_law({_LAW_ARGUMENTS})"],
    """Loads of one contact by the LAW of contact model ``law`` (its CODE; None on the
    CPU for Hertz-Mindlin, which is then compiled alone) with the pair's row q of the
    pair table: (force on i N, rolling torque on i N m, tangential force on i N, new
    spring m, stored energy J)."""))

_BEYOND_ARGUMENTS = "pair, q, r_star, gap, formed"
contact_beyond = body(_contact_generated(
    "contact_beyond", _BEYOND_ARGUMENTS,
    lambda module: getattr(module, "REACH", None) and [
        f"return gap < {module.REACH}(pair, q, r_star)"
        + (" and formed" if module.HYSTERETIC else "")],
    ["return False"],
    """Whether contact model ``law`` acts between surfaces a ``gap`` (m, >= 0) apart:
    within its REACH for the pair (row q of ``pair``, R* in m), and for a HYSTERETIC law
    only on a contact that ``formed`` by touching and has held since."""))


musen_kind = body(_contact_generated(
    "musen_kind", "wall",
    lambda module: getattr(module, "MUSEN", {}).get("kind_pp") and [
        f"return {module.MUSEN['kind_pw']} if wall else {module.MUSEN['kind_pp']}"],
    ["return 0"],
    """The kind of MUSEN's law (physics/contact_hertz_musen.py: MUSEN_HERTZ_MINDLIN,
    MUSEN_JKR, MUSEN_VDW, MUSEN_POPOV) that contact model ``law`` follows with
    musen_compat, for a wall contact or a particle pair."""))


@body
def spec_pair_loads(r, distance, overlap, i, j, vi, vj, wi, wj, grains, materials, law,
                    spring, dt):
    """The SPEC's loads of the pair i, j (r = x_j - x_i in m, overlap m, negative beyond
    contact) by contact model ``law``: (force on i N, moment on i N m, moment on j N m,
    new spring m, elastic energy J)."""
    radius = grains.radius
    n = (r[0] / distance, r[1] / distance, r[2] / distance)
    arm_i = radius[i] - 0.5 * overlap
    arm_j = radius[j] - 0.5 * overlap
    v_rel = contact_relative_velocity(n, vi, vj, wi, wj, arm_i, arm_j)
    w_rel = (wi[0] - wj[0], wi[1] - wj[1], wi[2] - wj[2])
    q = grains.material[i] * materials.young.shape[0] + grains.material[j]
    mass = grains.mass
    inertia = grains.inertia
    force_i, torque, f_t, xi, energy = contact_law(
        law, n, overlap, v_rel, w_rel, spring, materials.pair, q,
        radius[i] * radius[j] / (radius[i] + radius[j]), mass[i] * mass[j] / (mass[i] + mass[j]),
        inertia[i] * inertia[j] / (inertia[i] + inertia[j]), dt)
    moment_i, moment_j = contact_moments(n, f_t, torque, arm_i, arm_j)
    return force_i, moment_i, moment_j, xi, energy


@body
def pair_geometry(c, pairs, pair_bond, bond_active, position, radius, box, reach):
    """(i, j, r = x_j - x_i in m, distance m, overlap m, apart) of contact row c; apart:
    the pair carries no contact load (a gap of ``reach`` (m, the contact law's longest
    range beyond contact; 0 for contact only) or more, or joined by an intact bond)."""
    i = pairs[c, 0]
    j = pairs[c, 1]
    r = separation(position, i, j, box)
    distance = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    overlap = radius[i] + radius[j] - distance
    # the bond index is read for an overlapping pair only (most listed pairs are apart)
    apart = overlap <= -reach or distance == 0.0 or (pair_bond[c] >= 0
                                                     and bond_active[pair_bond[c]])
    return i, j, r, distance, overlap, apart


@body
def row_formed(c, rows):
    """True when contact row c (pair or wall rows) holds a load or an energy: its contact
    held in the previous evaluation (a reset row holds neither)."""
    return (rows.energy[c] != 0.0 or rows.force[c, 0] != 0.0 or rows.force[c, 1] != 0.0
            or rows.force[c, 2] != 0.0)


@body
def row_quiet(c, rows):
    """1 when contact row c holds no load, no stored energy and no dissipation (a reset
    row: ``pair_contact`` leaves it as it is while its pair stays apart), else 0."""
    if rows.energy[c] != 0.0 or rows.dissipated[c] != 0.0:
        return 0
    for k in range(3):
        if rows.force[c, k] != 0.0 or rows.moment_i[c, k] != 0.0 \
                or rows.moment_j[c, k] != 0.0:
            return 0
    return 1


@body
def pair_contact(c, pairs, pair_bond, bond_active, particles, grains, materials, law,
                 reach, use_rolling, box, rows, dt, moved_dt, musen):
    """Contact row c (pair pairs[c]): its loads (force on i, moments on i and j), stored
    energy and tangential spring, written over the previous step's row, which is read
    first for the work balance. A pair not touching or joined by an intact bond
    (pair_bond[c] >= 0) gets zero loads and its spring is reset. rows.dissipated[c]: J
    removed by the contact since the previous evaluation, moved_dt (s) ago: minus the work
    of its loads on the particles (trapezoidal in the loads, with the velocities that
    moved the particles) minus the change of its stored energy. musen: None (CPU) or
    False for the SPEC's law, True for MUSEN's Hertz-Mindlin
    (physics/contact_hertz_musen.py). law: the contact model's CODE (None on the CPU for
    Hertz-Mindlin); reach (m): its longest range beyond contact (``contact_beyond``
    decides for each pair; 0 for a law that acts in contact only)."""
    i, j, r, distance, overlap, apart = pair_geometry(c, pairs, pair_bond, bond_active,
                                                      particles.position, grains.radius,
                                                      box, reach)
    radius = grains.radius
    previous_energy = rows.energy[c]
    if law is not None and not apart and overlap <= 0.0:
        # beyond contact: the law's own reach for this pair, and whether it formed
        apart = not contact_beyond(
            law, materials.pair, grains.material[i] * materials.young.shape[0]
            + grains.material[j], radius[i] * radius[j] / (radius[i] + radius[j]),
            -overlap, row_formed(c, rows))
    if apart and not row_formed(c, rows):
        # Apart now and a reset row before (a touching row stores a positive energy and
        # a force; with neither, its spring and moments are zero too): nothing to read,
        # nothing to write but its 0 J. Most listed pairs are such rows in a packing.
        rows.dissipated[c] = 0.0
        return
    vi = row3(particles.velocity, i)
    vj = row3(particles.velocity, j)
    wi = row3(particles.angular_velocity, i)
    wj = row3(particles.angular_velocity, j)
    # Work of the previous loads over the step just made (their half of the trapezoid).
    work = 0.0
    force, moment_on_i, moment_on_j = (row3(rows.force, c), row3(rows.moment_i, c),
                                       row3(rows.moment_j, c))
    for k in range(3):
        work += (force[k] * (vi[k] - vj[k]) + moment_on_i[k] * wi[k]
                 + moment_on_j[k] * wj[k])
    if apart:
        zero = (0.0, 0.0, 0.0)
        store3(rows.spring, c, zero)
        store3(rows.force, c, zero)
        store3(rows.moment_i, c, zero)
        store3(rows.moment_j, c, zero)
        if musen is not None and musen:
            store3(rows.tangential, c, zero)
        rows.energy[c] = 0.0
        rows.dissipated[c] = -0.5 * moved_dt * work + previous_energy
        return
    if musen is not None and musen:
        a = grains.material[i]
        b = grains.material[j]
        q = a * materials.young.shape[0] + b
        table = materials.pair
        # E*, friction and rolling friction as the SPEC's (the pair table); G* and the
        # damping are MUSEN's own
        force_i, moment_i, moment_j, xi, f_t, energy = hertz_mindlin_musen_pp(
            r, overlap, radius[i], radius[j], vi, vj, wi, wj, row3(rows.spring, c),
            row3(rows.tangential, c), table[q, PAIR_E_STAR],
            musen_shear_modulus(materials.young[a], materials.poisson[a], materials.young[b],
                                materials.poisson[b]),
            musen_alpha(0.5 * (materials.restitution[a] + materials.restitution[b])),
            table[q, PAIR_FRICTION], table[q, PAIR_ROLLING] if use_rolling else 0.0,
            radius[i] * radius[j] / (radius[i] + radius[j]),
            grains.mass[i] * grains.mass[j] / (grains.mass[i] + grains.mass[j]), dt, musen,
            musen_kind(law, False), table[q, PAIR_MODEL])
        store3(rows.tangential, c, f_t)
    else:
        force_i, moment_i, moment_j, xi, energy = spec_pair_loads(
            r, distance, overlap, i, j, vi, vj, wi, wj, grains, materials, law,
            row3(rows.spring, c), dt)
    store3(rows.spring, c, xi)
    store3(rows.force, c, force_i)
    store3(rows.moment_i, c, moment_i)
    store3(rows.moment_j, c, moment_j)
    for k in range(3):
        work += force_i[k] * (vi[k] - vj[k]) + moment_i[k] * wi[k] + moment_j[k] * wj[k]
    rows.energy[c] = energy
    rows.dissipated[c] = -0.5 * moved_dt * work - (energy - previous_energy)


@body
def pair_rows_sum(p, index, rows):
    """Force (N) and moment (N m) of particle p's contact rows: those where it is i
    (index.i_order[i_start[p]:i_start[p+1]]), then those where it is j, each in a fixed
    order. When every one of p's rows is marked in index.quiet (they hold zeros), none is
    read and the sums are +0, as summing them gives (they start at +0, and adding +-0 to
    +0 gives +0). The test is branch-free per row: a branch per row, mispredicted
    whenever touching and apart rows alternate, cost more than the reads it saved."""
    zero = (0.0, 0.0, 0.0)
    loaded = 0
    for s in range(index.i_start[p], index.i_start[p + 1]):
        loaded |= 1 - index.quiet[index.i_order[s]]
    for s in range(index.j_start[p], index.j_start[p + 1]):
        loaded |= 1 - index.quiet[index.j_order[s]]
    if loaded == 0:
        return zero, zero
    force = moment = zero
    for s in range(index.i_start[p], index.i_start[p + 1]):
        c = index.i_order[s]
        force = add(force, row3(rows.force, c))
        moment = add(moment, row3(rows.moment_i, c))
    for s in range(index.j_start[p], index.j_start[p + 1]):
        c = index.j_order[s]
        force = sub(force, row3(rows.force, c))
        moment = add(moment, row3(rows.moment_j, c))
    return force, moment


@body
def plane_contact(x, rows, e):
    """(signed distance (m) of x from plane element e (rows: point, unit normal), its
    closest point, FACE)."""
    d = ((x[0] - rows[e, 0, 0]) * rows[e, 1, 0] + (x[1] - rows[e, 0, 1]) * rows[e, 1, 1]
         + (x[2] - rows[e, 0, 2]) * rows[e, 1, 2])
    return d, (x[0] - d * rows[e, 1, 0], x[1] - d * rows[e, 1, 1], x[2] - d * rows[e, 1, 2]), FACE


@body
def element_contact(x, rows, e, etype, triangles):
    """(distance (m) from x to wall element e's closest point, signed for a plane; that
    point; its feature). triangles: None when every element is a plane (CPU: the
    triangle code is then not compiled)."""
    if triangles is None:
        return plane_contact(x, rows, e)
    if etype == PLANE:
        return plane_contact(x, rows, e)
    q, feature = closest_point_on_triangle(
        x, (rows[e, 0, 0], rows[e, 0, 1], rows[e, 0, 2]),
        (rows[e, 1, 0], rows[e, 1, 1], rows[e, 1, 2]),
        (rows[e, 2, 0], rows[e, 2, 1], rows[e, 2, 2]))
    d = math.sqrt((x[0] - q[0]) ** 2 + (x[1] - q[1]) ** 2 + (x[2] - q[2]) ** 2)
    return d, q, feature


@body
def element_normal(rows, e, etype, x, q):
    """Unit normal of wall element e turned towards the particle at x (m) touching it at q
    (m): a plane's own normal, a triangle's (v2 - v1) x (v3 - v1) normalised (MUSEN's)."""
    if etype == PLANE:
        n = (rows[e, 1, 0], rows[e, 1, 1], rows[e, 1, 2])
    else:
        a = (rows[e, 1, 0] - rows[e, 0, 0], rows[e, 1, 1] - rows[e, 0, 1],
             rows[e, 1, 2] - rows[e, 0, 2])
        b = (rows[e, 2, 0] - rows[e, 0, 0], rows[e, 2, 1] - rows[e, 0, 1],
             rows[e, 2, 2] - rows[e, 0, 2])
        t = cross(a, b)
        size = norm(t)
        n = (t[0] / size, t[1] / size, t[2] / size)
    if (x[0] - q[0]) * n[0] + (x[1] - q[1]) * n[1] + (x[2] - q[2]) * n[2] < 0.0:
        return (-n[0], -n[1], -n[2])
    return n


@body
def wall_contacts_of(p, wall_start, wall_pairs, walls, particles, grains, materials, law,
                     reach, use_rolling, triangles, rows, dt, moved_dt, musen):
    """Loads on particle p of each of its wall candidates (rows wall_start[p] to
    wall_start[p+1] of ``rows``: force and moment on the particle, stored energy, spring),
    written over the previous step's rows (read first); rows.work[c]: J done by the moving
    wall since the previous evaluation, rows.dissipated[c]: J removed (work of the wall -
    work on the particle - change of stored energy, trapezoidal as for pairs).

    A triangle hit at point q is dropped when another touching triangle of the same wall
    contains q (within 1e-9 r) and has its own closest point elsewhere (then strictly
    closer: q is no local minimum of the distance to the mesh), or at q too and comes
    earlier in the list (a shared edge or vertex counted once). No distance comparison,
    so a centre just beside an edge is not counted twice.

    musen: None (CPU) or False for the SPEC's law, True for MUSEN's particle-wall
    Hertz-Mindlin (physics/contact_hertz_musen.py), which pushes along the element's own
    normal (a plane's, or a triangle's (v2 - v1) x (v3 - v1)), turned towards the particle.
    """
    first = wall_start[p]
    last = wall_start[p + 1]
    x = row3(particles.position, p)
    radius = grains.radius[p]
    a = grains.material[p]
    tol = 1e-9 * radius
    types = walls.types
    element_wall = walls.element_wall
    spring = rows.spring
    for c in range(first, last):
        e = wall_pairs[c, 1]
        d, q, feature = element_contact(x, walls.rows, e, types[e], triangles)
        rows.distance[c] = d
        rows.feature[c] = feature
        store3(rows.point, c, q)
    # Which hits count (rows.feature becomes 1 for kept, 0 for dropped).
    for c in range(first, last):
        e = wall_pairs[c, 1]
        q = row3(rows.point, c)
        d = rows.distance[c]
        keep = d < radius and d > -radius and (types[e] == PLANE or d > 0.0)
        if law is not None and not keep and d >= radius and d < radius + reach:
            # beyond contact: the law's own reach for this pair, and whether it formed
            keep = contact_beyond(law, walls.pair, a * walls.young.shape[0]
                                  + element_wall[e], radius, d - radius,
                                  row_formed(c, rows))
        if triangles is not None and keep and types[e] != PLANE:
            for c2 in range(first, last):
                e2 = wall_pairs[c2, 1]
                if c2 == c or element_wall[e2] != element_wall[e] or types[e2] == PLANE:
                    continue
                if rows.distance[c2] >= radius + reach:
                    continue
                inside, _, _ = element_contact(q, walls.rows, e2, types[e2], triangles)
                if inside >= tol:
                    continue
                gap = 0.0
                for k in range(3):
                    gap += (rows.point[c, k] - rows.point[c2, k]) ** 2
                # Triangle e2 holds q: its own closest point is then either elsewhere and
                # strictly closer (q is no local minimum) or q itself (a shared edge or
                # vertex, counted once, by the first hit).
                if gap > tol * tol or c2 < c:
                    keep = False
                    break
        rows.feature[c] = 1 if keep else 0
    # A sphere moving across a mesh changes triangles: a new hit takes over the spring of
    # a hit of the same wall that ended now, so the tangential force carries on.
    for c in range(first, last):
        if rows.feature[c] != 1 or spring[c, 0] != 0.0 or spring[c, 1] != 0.0 \
                or spring[c, 2] != 0.0:
            continue
        for c2 in range(first, last):
            if rows.feature[c2] == 0 and element_wall[wall_pairs[c2, 1]] == \
                    element_wall[wall_pairs[c, 1]] and (spring[c2, 0] != 0.0 or
                                                        spring[c2, 1] != 0.0 or
                                                        spring[c2, 2] != 0.0):
                for k in range(3):
                    spring[c, k] = spring[c2, k]
                    spring[c2, k] = 0.0
                break
    vi = row3(particles.velocity, p)
    wi = row3(particles.angular_velocity, p)
    for c in range(first, last):
        e = wall_pairs[c, 1]
        w = element_wall[e]
        om = row3(walls.omega, w)
        q = row3(rows.point, c)
        lever = (q[0] - walls.center[w, 0], q[1] - walls.center[w, 1],
                 q[2] - walls.center[w, 2])
        v_wall = (walls.velocity[w, 0] + om[1] * lever[2] - om[2] * lever[1],
                  walls.velocity[w, 1] + om[2] * lever[0] - om[0] * lever[2],
                  walls.velocity[w, 2] + om[0] * lever[1] - om[1] * lever[0])
        on_particle = 0.0
        by_wall = 0.0
        for k in range(3):
            on_particle += rows.force[c, k] * vi[k] + rows.moment[c, k] * wi[k]
            by_wall += rows.force[c, k] * v_wall[k]
        previous_energy = rows.energy[c]
        d = rows.distance[c]
        if rows.feature[c] != 1:
            for k in range(3):
                spring[c, k] = 0.0
                rows.force[c, k] = 0.0
                rows.moment[c, k] = 0.0
                if musen is not None and musen:
                    rows.tangential[c, k] = 0.0
            rows.energy[c] = 0.0
            rows.work[c] = 0.5 * moved_dt * by_wall
            rows.dissipated[c] = 0.5 * moved_dt * (by_wall - on_particle) + previous_energy
            continue
        mu_r = 0.5 * (materials.rolling[a] + walls.rolling[w]) if use_rolling else 0.0
        if musen is not None and musen:
            n_wall = element_normal(walls.rows, e, types[e], x, q)
            force_i, moment_i, torque, xi, f_t, energy = hertz_mindlin_musen_pw(
                x, q, n_wall, radius, vi, wi, row3(walls.velocity, w), om,
                row3(walls.center, w), row3(spring, c), row3(rows.tangential, c),
                effective_young_modulus(materials.young[a], materials.poisson[a],
                                        walls.young[w], walls.poisson[w]),
                musen_shear_modulus(materials.young[a], materials.poisson[a],
                                    walls.young[w], walls.poisson[w]),
                musen_alpha(0.5 * (materials.restitution[a] + walls.restitution[w])),
                0.5 * (materials.friction[a] + walls.friction[w]), mu_r, grains.mass[p],
                dt, musen, musen_kind(law, True), walls.pair[a * walls.young.shape[0] + w,
                                                             PAIR_MODEL])
            store3(rows.tangential, c, f_t)
        else:
            if types[e] == PLANE:
                n = (-walls.rows[e, 1, 0], -walls.rows[e, 1, 1], -walls.rows[e, 1, 2])
            else:
                n = ((q[0] - x[0]) / d, (q[1] - x[1]) / d, (q[2] - x[2]) / d)
            overlap = radius - d
            v_rel = contact_relative_velocity(n, vi, v_wall, wi, (0.0, 0.0, 0.0), d, 0.0)
            w_rel = (wi[0] - om[0], wi[1] - om[1], wi[2] - om[2])
            force_i, torque, f_t, xi, energy = contact_law(
                law, n, overlap, v_rel, w_rel, row3(spring, c), walls.pair,
                a * walls.young.shape[0] + w, radius, grains.mass[p], grains.inertia[p], dt)
            moment_i, _ = contact_moments(n, f_t, torque, d, 0.0)
        for k in range(3):
            spring[c, k] = xi[k]
            rows.force[c, k] = force_i[k]
            rows.moment[c, k] = moment_i[k]
            on_particle += force_i[k] * vi[k] + moment_i[k] * wi[k]
            # The rolling torque is the couple about the contact point, turning with the
            # wall at w_wall; the previous one is not kept, so the current one counts for
            # the whole step.
            by_wall += force_i[k] * v_wall[k] + 2.0 * torque[k] * om[k]
        rows.energy[c] = energy
        rows.work[c] = 0.5 * moved_dt * by_wall
        rows.dissipated[c] = 0.5 * moved_dt * (by_wall - on_particle) - (energy - previous_energy)


@body
def add_wall_rows(p, wall_start, rows, force, moment):
    """Add particle p's wall rows to force[p] (N) and moment[p] (N m), in list order."""
    for c in range(wall_start[p], wall_start[p + 1]):
        for k in range(3):
            force[p, k] += rows.force[c, k]
            moment[p, k] += rows.moment[c, k]

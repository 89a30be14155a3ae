"""One time step: zero loads (or let the first law store its own), add every law's loads,
then the semi-implicit Euler update.

SPEC section 1. Laws read the state at the start of the step. The first step of a run
evaluates the loads at x_0 with zero increments of the incremental springs, kicks the
velocities by half a step, v_1/2 = v_0 + F/m dt/2, and moves, x_1 = x_0 + v_1/2 dt; every
later step is a leapfrog step with increments v_n-1/2 dt. The scheme is second order from
the first step (free fall from rest is exact to round-off). MUSEN-compatible mode keeps
MUSEN's "prediction step" instead: a first evaluation with increments of the full dt that
only half-kicks, without moving or advancing time; then the same leapfrog steps.
"""
from .status import STATUS_OK, SimulationBlowUp, blow_up  # noqa: F401 (re-exported)


def step_plan(started, dt, musen_compat=False):
    """(increment_dt, kick_dt, drift_dt, advances_time) of the next step, in s (SPEC 1):
    the start-up (not ``started``) as SPEC mode or MUSEN's mode does it, else a leapfrog
    step. Both backends take their start-up from here."""
    if started:
        return dt, dt, dt, True
    if musen_compat:
        return dt, 0.5 * dt, 0.0, False
    return 0.0, 0.5 * dt, dt, True


def extra_start_up_steps(started, musen_compat=False):
    """Evaluations beyond the steps asked for: 1 for MUSEN's prediction step (it takes no
    time), else 0."""
    return 1 if (not started and musen_compat) else 0


def acting_laws(model, laws):
    """The laws that add loads to ``model``, in order: those without ``acts(model)``, or
    whose ``acts(model)`` is True (a bond law without bonds adds none)."""
    return [law for law in laws if not hasattr(law, "acts") or law.acts(model)]


def storing_law(model, laws):
    """The law of ``laws`` (in the order the step adds them) that stores its loads rather
    than adding them: the first acting one, if it has ``assign``; else None (the step then
    zeroes the loads first)."""
    acting = acting_laws(model, laws)
    return acting[0] if acting and hasattr(acting[0], "assign") else None


def step(model, state, laws, integrator, force, moment, dt, musen_compat=False):
    """Advance ``state`` in place by one step of ``dt`` seconds (or do the start-up kick).

    laws: objects with ``accumulate(model, state, force, moment, increment_dt)``; the
    first law may also have ``assign`` (same arguments), which stores its loads instead,
    and any may have ``acts(model)``, False when it adds no load (it is then left out);
    force, moment: (N,3) scratch arrays. Raises SimulationBlowUp on a bad status.
    """
    increment_dt, kick, drift, advances = step_plan(state.started, dt, musen_compat)
    if musen_compat:
        # MUSEN adds contact and wall loads first, then the bonds' (CPUSimulator::
        # CalculateForcesStep); laws[0] is the bond law
        laws = [*laws[1:], *laws[:1]]
    # A law that adds no load here (the bonds' without bonds) is left out, so that the
    # next may store its loads: one pass over the loads less.
    laws = acting_laws(model, laws)
    storing = storing_law(model, laws)
    if storing is not None:
        # a first law that stores its loads (the bonds', else the contacts'): nothing to
        # zero beforehand
        storing.assign(model, state, force, moment, increment_dt)
        laws = laws[1:]
    else:
        force.fill(0.0)
        moment.fill(0.0)
    for law in laws:
        law.accumulate(model, state, force, moment, increment_dt)
    status = integrator.advance(model, state, force, moment, kick, drift)
    state.started = True
    if advances:
        state.time += dt
        state.step += 1
    if status != STATUS_OK:
        raise blow_up(status, state.time, state.step)

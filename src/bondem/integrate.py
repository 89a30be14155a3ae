"""One time step: zero loads, add every law's loads, then the semi-implicit Euler update.

SPEC section 1. Laws read the state at the start of the step. The very first force
evaluation of a run (MUSEN's prediction step) only half-kicks the velocities, v += F/m dt/2,
without moving particles or advancing time; from then on velocities live at half steps
(leapfrog). Its bond increments use dt/2, or the full dt in MUSEN-compatible mode as MUSEN
does.
"""
from .backends.cpu import STATUS_NOT_FINITE, STATUS_OK, STATUS_OUT_OF_DOMAIN


class SimulationBlowUp(RuntimeError):
    """A particle's position or velocity became NaN/infinite or left the domain."""


def step(model, state, laws, integrator, force, moment, dt, musen_compat=False):
    """Advance ``state`` in place by one step of ``dt`` seconds (or do the start-up kick).

    laws: objects with ``accumulate(model, state, force, moment, increment_dt)``;
    force, moment: (N,3) scratch arrays. Raises SimulationBlowUp on a bad status.
    """
    start_up = not state.started
    increment_dt = 0.5 * dt if (start_up and not musen_compat) else dt
    force.fill(0.0)
    moment.fill(0.0)
    for law in laws:
        law.accumulate(model, state, force, moment, increment_dt)
    if start_up:
        status = integrator.advance(model, state, force, moment, 0.5 * dt, 0.0)
        state.started = True
    else:
        status = integrator.advance(model, state, force, moment, dt, dt)
        state.time += dt
        state.step += 1
    if status != STATUS_OK:
        what = {STATUS_NOT_FINITE: "a position or velocity became NaN or infinite",
                STATUS_OUT_OF_DOMAIN: "a particle left the domain"}.get(status, "bad status")
        raise SimulationBlowUp(f"simulation blew up at t = {state.time:.6g} s "
                               f"(step {state.step}): {what}; reduce the time step or check "
                               "the loads")

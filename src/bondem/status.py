"""Status codes that kernels set instead of raising, and the error the step raises.

A kernel that meets a NaN or a particle outside the domain writes a code into a status
array; the Python loop reads it after the step (or the batch, on the GPU) and raises
``SimulationBlowUp``. This module imports nothing of bondem, so kernels, backends and the
integrator can all use it.
"""

STATUS_OK, STATUS_NOT_FINITE, STATUS_OUT_OF_DOMAIN = 0, 1, 2


class SimulationBlowUp(RuntimeError):
    """A particle's position or velocity became NaN/infinite or left the domain, or the
    energy blew up."""


def blow_up(status, time, step, backend="cpu"):
    """The SimulationBlowUp for a bad ``status`` code at ``time`` (s) and ``step``."""
    what = {STATUS_NOT_FINITE: "a position or velocity became NaN or infinite",
            STATUS_OUT_OF_DOMAIN: "a particle left the domain"}.get(status, "bad status")
    where = f"step {step}" + (f", backend '{backend}'" if backend != "cpu" else "")
    return SimulationBlowUp(f"simulation blew up at t = {time:.6g} s ({where}): {what}; "
                            "reduce the time step or check the loads")

"""Energy balance over a run (SPEC 1-3, ``Simulation.energy_terms``).

    stored(t) = kinetic translational + kinetic rotational + bond elastic + contact elastic
    work(t)   = work of gravity and external loads + work of moving walls    (since t = 0)
    losses(t) = local damping + contact dissipation + energy held by bonds when they broke
    residual(t) = stored(t) - stored(0) - work(t) + losses(t)

A closed balance has residual 0 up to the integrator's error: the leapfrog's kinetic
energy uses half-step velocities, an O(dt) oscillation that does not grow. The relative
error divides by the initial kinetic energy (the energy an impact brings), or, for a run
that starts at rest (compression between plates), by the largest |work| done.
Terms a file does not record (no contacts, no walls) count as zero.
"""
from __future__ import annotations

import numpy as np

from .results import ENERGY_LOSSES, ENERGY_STORED, ENERGY_WORK


def energy_balance(results):
    """Energy balance series of an open ``Results``.

    Returns None if the file has no /energy group, else {"time": (F,) s, "terms": {name:
    (F,) J} every recorded term, "stored", "work", "losses", "residual": (F,) J,
    "reference": J (initial kinetic energy, or max |work| if that is 0),
    "relative_error": (F,) residual / reference, "max_relative_error": float}.
    """
    terms = results.energy()
    if not terms:
        return None
    time = results.time
    zero = np.zeros_like(time)

    def total(names):
        return sum((terms.get(name, zero) for name in names), zero.copy())

    stored, work, losses = total(ENERGY_STORED), total(ENERGY_WORK), total(ENERGY_LOSSES)
    if len(time) == 0:
        return {"time": time, "terms": terms, "stored": stored, "work": work,
                "losses": losses, "residual": zero, "reference": 0.0,
                "relative_error": zero, "max_relative_error": 0.0}
    residual = stored - stored[0] - work + losses
    initial_kinetic = float(terms.get("kinetic_translational", zero)[0]
                            + terms.get("kinetic_rotational", zero)[0])
    reference = initial_kinetic if initial_kinetic > 0 else float(np.max(np.abs(work)))
    relative = residual / reference if reference > 0 else np.zeros_like(residual)
    return {"time": time, "terms": terms, "stored": stored, "work": work, "losses": losses,
            "residual": residual, "reference": reference, "relative_error": relative,
            "max_relative_error": float(np.max(np.abs(relative)))}

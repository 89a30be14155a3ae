"""The fields' force on the particles over a run: the fluid's drag and buoyancy and a
rotating frame's forces, from /particles/field_force (F,N,3) N.

Per frame: the total force F (N, the sum over the particles: in a coupled or closed
fluid it is what the particles push back on the fluid), the mean and the largest
magnitude per particle (N), and the share of the moving particles' weight the fields
carry, -F . g / (M |g|^2) with M the mass of the particles that are not fixed (-; 1 when
the fluid holds the bed up, as at minimum fluidisation or for spheres settling at their
terminal velocity; None without gravity).
"""
from __future__ import annotations

import numpy as np


def field_series(results):
    """{"time" (F,) s, "total" (F,3) N, "mean" (F,) N, "largest" (F,) N,
    "weight_carried" (F,) - or None} of an open ``Results`` (module docstring), or None
    when the file holds no field forces."""
    if not results.has("particles/field_force"):
        return None
    force = np.asarray(results.frames("particles/field_force"), dtype=np.float64)
    magnitude = np.linalg.norm(force, axis=2)
    total = force.sum(axis=1)
    gravity = np.asarray(results.attrs.get("gravity", np.zeros(3)), dtype=np.float64)
    carried = None
    if results.has("particles/fixed") and np.any(gravity):
        moving = ~np.asarray(results.file["particles/fixed"][()], dtype=bool)
        weight = float(results.mass[moving].sum()) * float(gravity @ gravity)
        if weight > 0.0:
            carried = -(total @ gravity) / weight
    n = force.shape[1]
    return {"time": results.time, "total": total,
            "mean": magnitude.mean(axis=1) if n else np.zeros(len(force)),
            "largest": magnitude.max(axis=1) if n else np.zeros(len(force)),
            "weight_carried": carried}

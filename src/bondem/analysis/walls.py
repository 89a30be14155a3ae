"""Wall force against wall displacement, e.g. an agglomerate compressed between plates.

/walls/force (F,W,3) is the total force the particles exert on each wall and
/walls/position (F,W,3) a reference point of each wall. A wall's displacement is measured
along its direction of travel u = (p_last - p_0) / |p_last - p_0|: s = (p - p_0) . u
(m). The compressive force is the component resisting that travel, -F . u (N, positive
when the body pushes back on an advancing plate). A wall that does not move has no
direction of travel; its curve uses |F| against time only.
"""
from __future__ import annotations

import numpy as np


def wall_curve(results, wall=None):
    """Force-displacement curve of one wall of an open ``Results``.

    wall: index; default the wall that travelled farthest (the moving plate).
    Returns None without walls, else {"wall": index, "time": (F,) s, "displacement":
    (F,) m, "force": (F,) N compressive force (|F| if the wall does not move),
    "force_magnitude": (F,) N, "peak_index", "peak_force" N, "peak_displacement" m,
    "first_break_index": first frame with a broken bond or None, "first_break_force" N,
    "first_break_displacement" m}.
    """
    if results.n_walls == 0 or results.n_frames == 0:
        return None
    force = np.asarray(results.frames("walls/force"), dtype=np.float64)
    position = np.asarray(results.frames("walls/position"), dtype=np.float64)
    travel = np.linalg.norm(position[-1] - position[0], axis=-1)
    wall = int(np.argmax(travel)) if wall is None else int(wall)
    if not 0 <= wall < results.n_walls:
        raise IndexError(f"wall {wall} out of range: the file has {results.n_walls} walls")
    magnitude = np.linalg.norm(force[:, wall], axis=-1)
    if travel[wall] > 0.0:
        direction = (position[-1, wall] - position[0, wall]) / travel[wall]
        displacement = (position[:, wall] - position[0, wall]) @ direction
        compressive = -(force[:, wall] @ direction)
    else:
        displacement = np.zeros(len(magnitude))
        compressive = magnitude
    peak = int(np.argmax(compressive))
    out = {"wall": wall, "time": results.time, "displacement": displacement,
           "force": compressive, "force_magnitude": magnitude, "peak_index": peak,
           "peak_force": float(compressive[peak]),
           "peak_displacement": float(displacement[peak]), "first_break_index": None,
           "first_break_force": None, "first_break_displacement": None}
    broken = results.any_broken()
    if broken.any():
        first = int(np.argmax(broken))
        out.update(first_break_index=first, first_break_force=float(compressive[first]),
                   first_break_displacement=float(displacement[first]))
    return out

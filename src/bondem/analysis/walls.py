"""Wall force against displacement, e.g. an agglomerate compressed between plates.

/walls/force (F,W,3) is the total force the particles exert on each wall and
/walls/position (F,W,3) a reference point of each wall. The loading wall is the one that
travelled farthest; its direction of travel is u = (p_last - p_0) / |p_last - p_0|.
Its counterpart, when there is one, is a wall travelling the other way (two plates closing
on the body) or, failing that, a fixed wall the body pushes along u (an anvil).

With a counterpart the displacement is the decrease of the gap between the two plates,
s = (p_a - p_a0) . u_a + (p_b - p_b0) . u_b (m; each plate's travel counts), the gap is
g = g_0 - s with g_0 = |(p_b0 - p_a0) . u|, and the force is the mean of the two plates'
compressive forces -F_a . u and F_b . u (N, positive when the body pushes back); their
difference is a quasi-static check. Without one, s is the loading wall's own travel and
the force its compressive force. A wall that does not move has no direction of travel;
its curve is |F| against time.
"""
from __future__ import annotations

import numpy as np


def _counterpart(force, position, travel, wall, direction):
    """Index of the wall facing the loading wall, or None (see the module docstring)."""
    best, best_push = None, 0.0
    for other in range(force.shape[1]):
        if other == wall:
            continue
        if travel[other] > 0.0:
            u_other = (position[-1, other] - position[0, other]) / travel[other]
            if np.dot(u_other, direction) < -0.5:
                return other
            continue
        push = float(np.mean(force[:, other] @ direction))
        if push > best_push:
            best, best_push = other, push
    return best


class _Plates:
    """The loading wall and its counterpart: their compressive forces, the displacement
    and the gap (module docstring) of any rows of wall forces and positions, so the frames
    and the per-step history are read the same way."""

    def __init__(self, start, travel, wall, partner, direction, last):
        self.start, self.wall, self.partner, self.direction = start, wall, partner, direction
        self.moving = direction is not None
        self.u_partner = (None if partner is None or travel[partner] <= 0.0 else
                          (last[partner] - start[partner]) / travel[partner])

    def curve(self, force, position):
        """(force_wall, force_partner or None, compressive force, displacement, gap or
        None), each (rows,), of force and position (rows, W, 3)."""
        wall, partner, direction = self.wall, self.partner, self.direction
        if not self.moving:
            magnitude = np.linalg.norm(force[:, wall], axis=-1)
            return magnitude, None, magnitude, np.zeros(len(magnitude)), None
        displacement = (position[:, wall] - self.start[wall]) @ direction
        force_wall = -(force[:, wall] @ direction)
        if partner is None:
            return force_wall, None, force_wall, displacement, None
        if self.u_partner is not None:
            displacement = displacement + (position[:, partner] - self.start[partner]) \
                @ self.u_partner
        force_partner = force[:, partner] @ direction
        gap = abs(float((self.start[partner] - self.start[wall]) @ direction)) - displacement
        return force_wall, force_partner, 0.5 * (force_wall + force_partner), displacement, gap


def force_mismatch(force_a, force_b, peak=None):
    """The platens' (plates') force mismatch, a quasi-static check (the one definition of
    analysis, lab and report): the largest |F_a - F_b| up to the peak over the peak's
    mean force (F_a + F_b) / 2, both compressive forces in N sampled alike; ``peak``: the
    sample of the peak, by default that of the largest mean force. Dimensionless; None
    when the mean force at the peak is not positive."""
    force_a = np.asarray(force_a, dtype=np.float64)
    force_b = np.asarray(force_b, dtype=np.float64)
    mean = 0.5 * (force_a + force_b)
    if mean.size == 0:
        return None
    peak = int(np.argmax(mean)) if peak is None else int(peak)
    if not mean[peak] > 0.0:
        return None
    return float(np.max(np.abs(force_a - force_b)[:peak + 1]) / mean[peak])


def wall_curve(results, wall=None):
    """Force-displacement curve of the plates of an open ``Results``.

    wall: index of the loading wall; default the wall that travelled farthest.
    Returns None without walls, else {"wall": index, "partner": index of the facing wall
    or None, "time": (F,) s, "displacement": (F,) m (decrease of the plate gap, or the
    wall's travel without a partner; zeros for a wall that stays), "gap": (F,) m or None,
    "force": (F,) N (mean compressive force of both plates, or of the one wall; |F| for
    a wall that stays), "force_wall", "force_partner": (F,) N each plate's compressive
    force (force_partner None without a partner), "force_magnitude": (F,) N |F| of the
    loading wall, "peak_index" (the frame nearest the peak), "peak_time" s, "peak_force"
    N, "displacement_at_peak_force" m (None for a wall that stays), "gap_at_peak_force" m
    or None, "force_mismatch": max |F_wall - F_partner| up to the peak over the peak force
    (None without a partner); the peak and the mismatch come from /walls/history (every
    step) where the file has it, else from the frames; "first_break_index": first frame
    with a broken bond or None, "first_break_force" N, "first_break_displacement" m}.
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
    partner, direction = None, None
    if travel[wall] > 0.0:
        direction = (position[-1, wall] - position[0, wall]) / travel[wall]
        partner = _counterpart(force, position, travel, wall, direction)
    plates = _Plates(position[0], travel, wall, partner, direction, position[-1])
    force_wall, force_partner, compressive, displacement, gap = plates.curve(force, position)
    # The peak between frames: /walls/history holds every step whose wall forces changed,
    # the frames only every save_every (a peak between two frames was read 9 % low).
    peak_time, peak_force, peak_displacement, peak_gap, mismatch = None, None, None, None, None
    history = results.wall_history()
    if history is not None and len(history[0]):
        h_time = history[0]
        h_wall, h_partner, h_force, h_displacement, h_gap = plates.curve(*history[1:])
        h_peak = int(np.argmax(h_force))
        peak_time, peak_force = float(h_time[h_peak]), float(h_force[h_peak])
        peak_displacement = float(h_displacement[h_peak])
        peak_gap = None if h_gap is None else float(h_gap[h_peak])
        if partner is not None:
            mismatch = force_mismatch(h_wall, h_partner, h_peak)
        peak = int(np.argmin(np.abs(results.time - peak_time)))
    else:
        peak = int(np.argmax(compressive))
        peak_time, peak_force = float(results.time[peak]), float(compressive[peak])
        peak_displacement = float(displacement[peak])
        peak_gap = None if gap is None else float(gap[peak])
        if partner is not None:
            mismatch = force_mismatch(force_wall, force_partner, peak)
    out = {"wall": wall, "partner": partner, "time": results.time,
           "displacement": displacement, "gap": gap, "force": compressive,
           "force_wall": force_wall, "force_partner": force_partner,
           "force_magnitude": magnitude, "peak_index": peak, "peak_time": peak_time,
           "peak_force": peak_force,
           # a wall that stays has no displacement to report (not 0 m)
           "displacement_at_peak_force": (peak_displacement if plates.moving else None),
           "gap_at_peak_force": peak_gap,
           "force_mismatch": mismatch, "first_break_index": None,
           "first_break_force": None, "first_break_displacement": None}
    broken = results.any_broken()
    if broken.any():
        first = int(np.argmax(broken))
        out.update(first_break_index=first, first_break_force=float(compressive[first]),
                   first_break_displacement=float(displacement[first]))
    return out

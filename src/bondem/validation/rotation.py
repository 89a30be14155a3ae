"""Objectivity: a bonded pair turning as a rigid body keeps its stored bond vectors.

The bond's stored F_t, M_n and M_t are held fixed in the pair's frame when the pair turns
rigidly: after the rigid rotation Q they must equal Q F_t0, Q M_n0, Q M_t0 (the increments
vanish: v_rel = 0 and w_rel = 0 for a rigid motion). The SPEC's T (shortest rotation of
the old axis onto the new, then the twist (w_i + w_j) . n dt / 2 about n) is an exact
rotation, so lengths are kept to round-off; for a rotation axis perpendicular to the bond
the direction is exact too, for an oblique axis the align-then-twist split is exact to
first order in the step's angle (a drift of O(Omega dt) radians per quarter turn).
The bond law is called directly (bondem.backends.cpu.elastic_bond, the compiled physics)
on the prescribed rigid motion. For comparison the same motion is fed to a transcription
of MUSEN's matrix (musen_reference; shown as information, see docs/musen_compat.md).
A last row checks that MUSEN's formulas, transcribed, give bondem's loads for one step
from rest with random velocities (the sign conventions and relative velocity agree).
"""
import numpy as np

from .core import CaseResult, Plot, Series, case, compare, info
from .musen_reference import musen_bond_step, musen_rotation_matrix


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _angle(a, b):
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b)))


def _constants(p):
    from bondem.backends.cpu import bond_stiffnesses
    b = p["bond"]
    return bond_stiffnesses(b["young_modulus"], b["poisson_ratio"], b["diameter"],
                            b["initial_length"])


def rigid_turn(p, axis):
    """Stored vectors after a rigid quarter turn about ``axis``: bondem's and MUSEN's,
    with the exact answers. Returns dict of (bondem, musen, exact) per vector name."""
    from bondem.backends.cpu import elastic_bond
    length = p["bond"]["initial_length"]
    omega_size, steps = p["run"]["angular_speed"], p["run"]["steps"]
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    dt = (np.pi / 2) / omega_size / steps
    omega = omega_size * axis
    kn, ks, ktw, kb = _constants(p)
    stored = {k: np.asarray(p["stored"][k], float) for k in
              ("tangential_force", "normal_moment", "tangential_moment")}
    f_t, m_n, m_t = (tuple(stored[k]) for k in stored)
    musen = {k: v.copy() for k, v in stored.items()}
    r0 = np.array([length, 0.0, 0.0])
    previous_axis = (1.0, 0.0, 0.0)
    previous_bond = -r0  # MUSEN's bond vector is x_i - x_j
    zero = (0.0, 0.0, 0.0)
    w = tuple(omega)
    for k in range(1, steps + 1):
        r = _rotation(axis, omega_size * k * dt) @ r0
        vj = tuple(np.cross(omega, r))  # i at the origin, on the axis: v_i = 0
        _, n, _, f_t, m_n, m_t = elastic_bond(tuple(r), zero, vj, w, w, previous_axis, f_t,
                                              m_n, m_t, length, kn, ks, ktw, kb, dt)
        previous_axis = n
        matrix = musen_rotation_matrix(previous_bond, -r, 2 * omega, dt)
        previous_bond = -r
        musen = {name: matrix @ v for name, v in musen.items()}
    q = _rotation(axis, np.pi / 2)
    ours = dict(zip(stored, (np.array(f_t), np.array(m_n), np.array(m_t))))
    return {name: (ours[name], musen[name], q @ stored[name]) for name in stored}


def transcription_difference(p):
    """Largest difference between MUSEN's transcribed formulas and bondem's kernel for one
    step from rest with random velocities and spins, in units of its round-off estimate.

    Each compared load is a sum of terms computed in a different order by the two codes,
    so they may differ by a few eps times the sum of the terms' magnitudes, not times the
    result: F_n = k_n (L - L0) cancels L against L0 (one ulp of L is eps k_n L, up to
    1/strain times |F_n| eps), the tangential increments cancel v_j - v_i against
    (w_i + w_j) x r / 2. The estimate per sample, in N and N m:
        force:  eps (k_n L + k_s dt V),   V = |v_i| + |v_j| + |w_i + w_j| L / 2 (m/s)
        moment: eps ((k_tw + k_b) dt (|w_i| + |w_j|) + L / 2 k_s dt V)
    Returns max |ours - MUSEN's| / estimate (dimensionless; a sign or factor error gives
    ~1/eps, round-off a few units).
    """
    from bondem.backends.cpu import bond_loads_on_particles, elastic_bond
    rng = np.random.default_rng(p["run"]["seed"])
    length = p["bond"]["initial_length"]
    kn, ks, ktw, kb = _constants(p)
    b = p["bond"]
    radius = b["diameter"] / 2
    area, second = np.pi * radius ** 2, np.pi * radius ** 4 / 4
    shear_modulus = b["young_modulus"] / (2 * (1 + b["poisson_ratio"]))
    eps = np.finfo(float).eps
    worst = 0.0
    for _ in range(20):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        xi = rng.normal(size=3) * 1e-3
        xj = xi + direction * length * (1 + 1e-3 * rng.normal())
        vi, vj, wi, wj = (rng.normal(size=3) for _ in range(4))
        dt = 1e-7
        r = xj - xi
        zero = (0.0, 0.0, 0.0)
        _, n, f_n, f_t, m_n, m_t = elastic_bond(
            tuple(r), tuple(vi), tuple(vj), tuple(wi), tuple(wj), tuple(r / np.linalg.norm(r)),
            zero, zero, zero, length, kn, ks, ktw, kb, dt)
        force_i, moment_i, moment_j = bond_loads_on_particles(tuple(r), f_n, f_t, m_n, m_t)
        total, mn, mt, unsym, _, _ = musen_bond_step(
            xi, xj, vi, vj, wi, wj, xi - xj, np.zeros(3), np.zeros(3), np.zeros(3), length,
            b["young_modulus"], shear_modulus, area, second, dt)
        size = np.linalg.norm(r)
        speed = (np.linalg.norm(vi) + np.linalg.norm(vj)
                 + np.linalg.norm(wi + wj) * size / 2)
        force_scale = eps * (kn * size + ks * dt * speed)
        moment_scale = eps * ((ktw + kb) * dt * (np.linalg.norm(wi) + np.linalg.norm(wj))
                              + size / 2 * ks * dt * speed)
        # MUSEN (CPUSimulator::CalculateForcesSB): on left += M_n + M_t - unsym, on right
        # -= M_n + M_t + unsym.
        pairs = [(np.array(force_i), total, force_scale),
                 (np.array(moment_i), mn + mt - unsym, moment_scale),
                 (np.array(moment_j), -(mn + mt + unsym), moment_scale)]
        for ours, theirs, scale in pairs:
            worst = max(worst, float(np.linalg.norm(ours - theirs) / scale))
    return worst


@case("rotation", quick=True)
def run(p, compat, quick=False):
    """Rigid rotation of a loaded bond: stored vectors keep length and turn with the pair."""
    rows, bars = [], []
    run_p = p["run"]
    for axis in run_p["axes"]:
        along = abs(axis[0]) / np.linalg.norm(axis)  # the bond starts along x
        oblique = 1e-12 < along < 1 - 1e-12
        label = ("oblique axis" if oblique else "axis along the bond" if along > 0.5
                 else "axis normal to the bond")
        result = rigid_turn(p, axis)
        for name, (ours, musen, exact) in result.items():
            if name == "normal_moment" and along < 1e-12:
                continue  # rotation normal to the bond: M_n turns with n, same check as F_t
            short = {"tangential_force": "F_t", "normal_moment": "M_n",
                     "tangential_moment": "M_t"}[name]
            initial = np.linalg.norm(exact)
            rows.append(compare("rotation", f"quarter turn, {label}: |{short}| / |{short}0|",
                                1.0, np.linalg.norm(ours) / initial,
                                run_p["tolerance_length"]))
            tolerance = run_p["tolerance_direction_oblique" if oblique
                              else "tolerance_direction"]
            rows.append(compare("rotation", f"quarter turn, {label}: {short} direction "
                                "error (rad)", 0.0, _angle(ours, exact), tolerance,
                                absolute=True))
            if name == "tangential_force":
                rows.append(info("rotation", f"MUSEN matrix, {label}: F_t direction error "
                                 "(rad)", 0.0, _angle(musen, exact),
                                 f"MUSEN's |F_t| / |F_t0| = {np.linalg.norm(musen) / initial:.6g}"
                                 " (docs/musen_compat.md)", absolute=True))
                bars.append((label, _angle(ours, exact), _angle(musen, exact)))
    rows.append(compare("rotation", "one step from rest: MUSEN's formulas vs bondem "
                        "(max difference / round-off estimate)", 0.0,
                        transcription_difference(p),
                        run_p["tolerance_transcription"], absolute=True))
    x = list(range(len(bars)))
    plot = Plot("Rigid quarter turn: direction error of the stored F_t",
                "0 = axis normal to bond, 1 = along it, 2 = oblique", "error (rad)", [
                    Series("bondem (SPEC T)", x, [max(b[1], 1e-17) for b in bars], "o"),
                    Series("MUSEN matrix M", x, [max(b[2], 1e-17) for b in bars], "s")],
                logy=True)
    return CaseResult(rows, [plot])

"""The shortcuts of the fast bond update give the physics of SPEC section 2 to round-off.

References: math.sin / math.cos (and 2 sin^2(b/2) for 1 - cos b); the bond update
written literally with rotation.bond_rotate (T applied to each carried vector, then the
increments of the tangential parts and the projections); the break test written
literally with square roots and divisions (the pre-test without square roots must never
change its answer, also for loads a hair either side of the strengths).
"""
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bondem.physics.bond_elastic import (COMPRESSION, CRITERION_COMBINED, CRITERION_SEPARATE,
                                         INTACT, SHEAR, TENSION, bond_break_mode, elastic_bond)
from bondem.physics.rotation import SMALL_ANGLE, bond_rotate, twist_sincos

unit = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: 0.1 < np.linalg.norm(v))
vec = st.tuples(*[st.floats(-10, 10)] * 3)


def test_twist_sincos_matches_libm_across_the_series_threshold():
    angles = np.concatenate([np.logspace(-14, 0, 400), SMALL_ANGLE * (1 + np.linspace(-1e-3,
                                                                                       1e-3, 21))])
    for b in np.concatenate([angles, -angles, [0.0]]):
        sb, cb, omc = twist_sincos(float(b))
        assert abs(sb - math.sin(b)) <= 2.5e-16 * abs(math.sin(b))
        assert abs(cb - math.cos(b)) <= 2.5e-16
        exact_omc = 2.0 * math.sin(0.5 * b) ** 2      # no cancellation at small b
        # Relative accuracy where the series is used; 1 - cos b (rounded) above it.
        bound = 1e-15 * exact_omc if abs(b) < SMALL_ANGLE else 2.3e-16
        assert abs(omc - exact_omc) <= bound
        assert abs(sb * sb + cb * cb - 1.0) <= 4.5e-16


def normalise(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def literal_bond(r, vi, vj, wi, wj, n_prev, f_t, m_n, m_t, l0, kn, kt, ktw, kb, dt):
    """SPEC section 2 as written: every carried vector through T, tangential parts, then
    the projections of the seed."""
    r, vi, vj, wi, wj = (np.asarray(x, float) for x in (r, vi, vj, wi, wj))
    length = np.linalg.norm(r)
    n = r / length
    w_rel, w_sum = wi - wj, wi + wj
    v_rel = vj - vi - 0.5 * np.cross(w_sum, r)
    v_t = v_rel - n * (n @ v_rel)
    w_n = n * (n @ w_rel)
    w_t = w_rel - w_n
    twist = 0.5 * (w_sum @ n) * dt
    rot = [np.array(bond_rotate(tuple(v), tuple(n_prev), tuple(n), twist))
           for v in (f_t, m_n, m_t)]
    f_t = rot[0] + kt * dt * v_t
    m_n = rot[1] - ktw * dt * w_n
    m_t = rot[2] - kb * dt * w_t
    f_t -= n * (n @ f_t)
    m_t -= n * (n @ m_t)
    m_n = n * (n @ m_n)
    return length, n, n * kn * (length - l0), f_t, m_n, m_t


@settings(max_examples=300, deadline=None)
@given(unit, unit, vec, vec, vec, vec, vec, vec, vec, st.floats(-1, 1),
       st.floats(-0.3, 0.3))
def test_fast_update_equals_the_literal_spec(a, b, vi, vj, wi, wj, ft, mt, ft_dir, mn,
                                             twist_scale):
    """Random carried vectors consistent with the stored axis (tangential ones in its
    plane, M_n along it), axes up to ~170 degrees apart, twists up to ~0.3 rad."""
    n_prev, n = normalise(a), normalise(b)
    if n_prev @ n < -0.98:
        return
    r = 2e-3 * n * (1.0 + 0.01 * twist_scale)
    f_t = np.asarray(ft) - n_prev * (n_prev @ ft)
    m_t = np.asarray(mt) - n_prev * (n_prev @ mt)
    m_n = 3.0 * mn * n_prev
    # dt chosen so the twist angle reaches both branches of twist_sincos.
    w_sum = np.asarray(wi) + np.asarray(wj)
    dt = abs(twist_scale) / max(abs(0.5 * (w_sum @ n)), 1e-9)
    args = (tuple(r), vi, vj, wi, wj, tuple(n_prev), tuple(f_t), tuple(m_n), tuple(m_t),
            2e-3, 7.0, 3.0, 2.0, 5.0, min(dt, 1.0))
    fast = elastic_bond(*args)
    ref = literal_bond(*args)
    assert abs(fast[0] - ref[0]) <= 1e-15 * ref[0]
    for x, y in zip(fast[1:], ref[1:]):
        scale = 1.0 + np.linalg.norm(y) + np.linalg.norm(args[2]) + np.linalg.norm(args[3])
        assert np.linalg.norm(np.asarray(x) - y) <= 1e-13 * scale


def literal_break_mode(length, l0, f_n, f_t, m_n, m_t, d, s_n, s_t, criterion, compressive):
    radius = 0.5 * d
    area = math.pi * radius ** 2
    inertia = 0.25 * math.pi * radius ** 4
    axial = np.linalg.norm(f_n) / area
    bending = np.linalg.norm(m_t) * radius / inertia
    shear = np.linalg.norm(f_t) / area
    torsion = np.linalg.norm(m_n) * radius / (2 * inertia)
    mode = TENSION if length > l0 else COMPRESSION
    checked = length > l0 or compressive
    if criterion == CRITERION_COMBINED:
        if checked and axial + bending >= s_n:
            return mode
        return SHEAR if shear + torsion >= s_t else INTACT
    if checked and (axial >= s_n or bending >= s_n):
        return mode
    return SHEAR if (shear >= s_t or torsion >= s_t) else INTACT


def test_break_pre_test_never_changes_the_decision():
    """Loads whose stresses sit at 0.3-1.7 strengths, and at strength * (1 +- 1e-12)."""
    rng = np.random.default_rng(11)
    d = 1e-3
    radius = 0.5 * d
    area, inertia = math.pi * radius ** 2, 0.25 * math.pi * radius ** 4
    counts = {}
    for trial in range(4000):
        criterion = (CRITERION_COMBINED, CRITERION_SEPARATE)[trial % 2]
        s_n, s_t = 10.0 ** rng.uniform(3, 9, size=2)
        share = rng.uniform(0, 1, size=2) if criterion == CRITERION_COMBINED else (1, 1)
        level = rng.uniform(0.3, 1.7, size=2)
        if trial % 5 == 0:       # a hair either side of the threshold
            level = 1.0 + rng.choice([-1e-12, 1e-12], size=2)
        # Each term gets its share of the strength: axial+bending, shear+torsion.
        which = rng.integers(0, 2, size=2)
        axial = s_n * level[0] * (share[0] if which[0] else 1 - share[0])
        bending = s_n * level[0] - axial if criterion == CRITERION_COMBINED else \
            s_n * level[0] * rng.uniform(0, 1)
        shear = s_t * level[1] * (share[1] if which[1] else 1 - share[1])
        torsion = s_t * level[1] - shear if criterion == CRITERION_COMBINED else \
            s_t * level[1] * rng.uniform(0, 1)
        n = normalise(rng.normal(size=3))
        t = normalise(np.cross(n, rng.normal(size=3)))
        f_n = tuple(n * axial * area)
        m_t = tuple(t * bending * inertia / radius)
        f_t = tuple(np.cross(n, t) * shear * area)
        m_n = tuple(-n * torsion * 2 * inertia / radius)
        length = 2e-3 * (1 + rng.choice([-1e-3, 1e-3]))
        compressive = bool(rng.integers(0, 2))
        args = (length, 2e-3, f_n, f_t, m_n, m_t, d, s_n, s_t, criterion, compressive)
        expected = literal_break_mode(*args)
        assert bond_break_mode(*args) == expected, args
        counts[expected] = counts.get(expected, 0) + 1
    # The sample exercises every outcome.
    assert set(counts) == {INTACT, TENSION, COMPRESSION, SHEAR}

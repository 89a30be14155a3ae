"""The bond law as pure functions, checked with plain numbers, and the CPU kernel against a
slow NumPy reference written straight from SPEC section 2."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import bondem
from bondem.backends import cpu
from bondem.physics.bond_elastic import bond_stresses, elastic_bond
from bondem.physics.rotation import align_rotate, axis_rotate, bond_rotate

unit = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: 0.1 < np.linalg.norm(v))
vec = st.tuples(*[st.floats(-10, 10)] * 3)


def normalise(v):
    v = np.asarray(v, float)
    return tuple(v / np.linalg.norm(v))


@settings(max_examples=200, deadline=None)
@given(unit, unit, vec, st.floats(-3, 3))
def test_bond_rotation_is_proper_and_carries_axis(a, b, v, twist):
    """T is orthonormal (keeps lengths and angles) and maps n_prev onto n (SPEC 2)."""
    n_prev, n = normalise(a), normalise(b)
    if np.dot(n_prev, n) < -0.99:
        return
    rotated = np.array(bond_rotate(v, n_prev, n, twist))
    assert np.linalg.norm(rotated) == pytest.approx(np.linalg.norm(v), rel=1e-12, abs=1e-12)
    assert np.allclose(bond_rotate(n_prev, n_prev, n, twist), n, atol=1e-12)
    # angle between v and n_prev equals angle between T v and n
    assert np.dot(rotated, n) == pytest.approx(np.dot(v, n_prev), abs=1e-11)
    # a proper rotation has determinant +1
    matrix = np.column_stack([bond_rotate(e, n_prev, n, twist) for e in np.eye(3)])
    assert np.linalg.det(matrix) == pytest.approx(1.0, abs=1e-12)


def test_twist_rotates_about_axis_by_angle():
    v = axis_rotate((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), math.pi / 2)
    assert np.allclose(v, (0.0, 1.0, 0.0), atol=1e-15)
    assert align_rotate((0.0, 1.0, 0.0), (1.0, 0.0, 0.0), (1.0, 0.0, 0.0)) == (0.0, 1.0, 0.0)


def test_rigidly_turning_bond_carries_its_vectors_without_change_of_length():
    """No spurious force from T: turn a loaded bond rigidly (no relative motion) many
    times; stored vectors keep their length and stay attached to the bond."""
    rng = np.random.default_rng(3)
    n = np.array([1.0, 0.0, 0.0])
    f_t, m_n, m_t = (0.0, 2.0, 0.5), (3.0, 0.0, 0.0), (0.0, 0.0, -1.5)
    axis = tuple(n)
    total = np.eye(3)
    for _ in range(1000):
        w = rng.normal(size=3)
        angle = 0.01
        k = w / np.linalg.norm(w)
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
        total = R @ total
        r = tuple(2e-3 * total @ n)
        _, axis, _, f_t, m_n, m_t = elastic_bond(r, (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0),
                                                 axis, f_t, m_n, m_t, 2e-3, 1.0, 1.0, 1.0, 1.0,
                                                 1e-6)
    assert np.linalg.norm(f_t) == pytest.approx(np.linalg.norm((0, 2.0, 0.5)), rel=1e-10)
    assert np.linalg.norm(m_n) == pytest.approx(3.0, rel=1e-10)
    assert np.linalg.norm(m_t) == pytest.approx(1.5, rel=1e-10)
    # Stored vectors stay perpendicular / parallel to the turned axis.
    assert abs(np.dot(f_t, axis)) < 1e-12 and abs(np.dot(m_t, axis)) < 1e-12
    assert abs(abs(np.dot(m_n, axis)) - 3.0) < 1e-10


def test_stress_signs_follow_spec():
    sigma, tau = bond_stresses(2.1e-3, 2e-3, (1.0, 0, 0), (0, 3.0, 0), (0, 0, 0), (0, 0, 0), 1e-3)
    area = math.pi * 0.25e-6
    assert sigma == pytest.approx(1.0 / area) and tau == pytest.approx(3.0 / area)
    sigma, _ = bond_stresses(1.9e-3, 2e-3, (1.0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0), 1e-3)
    assert sigma == pytest.approx(-1.0 / area)


def reference_bond_step(model, state, dt):
    """SPEC 2 written with NumPy, bond by bond: (force on i, moment on i, moment on j)."""
    E, nu = model.bond_materials[0].young_modulus, model.bond_materials[0].poisson_ratio
    G = E / (2 * (1 + nu))
    out = []
    for b, (i, j) in enumerate(model.bond_pairs):
        R = model.bond_diameter[b] / 2
        A, I, J = np.pi * R ** 2, np.pi * R ** 4 / 4, np.pi * R ** 4 / 2
        L0 = model.bond_initial_length[b]
        r = state.position[j] - state.position[i]
        L = np.linalg.norm(r)
        n = r / L
        wi, wj = state.angular_velocity[i], state.angular_velocity[j]
        v_rel = state.velocity[j] - state.velocity[i] - np.cross(wi + wj, r) / 2
        v_t = v_rel - n * (n @ v_rel)
        w_rel = wi - wj
        w_n = n * (n @ w_rel)
        w_t = w_rel - w_n
        # T as a matrix: shortest rotation n_prev -> n, then twist about n
        p = state.bond_axis[b]
        k = np.cross(p, n)
        c = p @ n
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        align = np.eye(3) + K + K @ K / (1 + c)
        theta = (wi + wj) @ n * dt / 2
        N = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
        twist = np.eye(3) + math.sin(theta) * N + (1 - math.cos(theta)) * N @ N
        T = twist @ align
        F_n = E * A * (L - L0) / L0 * n
        F_t = T @ state.bond_tangential_force[b] + G * A / L0 * v_t * dt
        M_n = T @ state.bond_normal_moment[b] - G * J / L0 * w_n * dt
        M_t = T @ state.bond_tangential_moment[b] - E * I / L0 * w_t * dt
        F_t -= n * (n @ F_t)
        M_t -= n * (n @ M_t)
        M_n = n * (n @ M_n)
        out.append((F_n + F_t, M_n + M_t + np.cross(r / 2, F_t), -M_n - M_t + np.cross(r / 2, F_t)))
    return [np.array(x) for x in zip(*out)]


def test_cpu_kernel_matches_numpy_reference_on_random_bonds(glass):
    rng = np.random.default_rng(7)
    n = 30
    position = rng.uniform(0, 6e-3, size=(n, 3))
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)
                      if np.linalg.norm(position[i] - position[j]) < 2.5e-3])
    binder = bondem.BondMaterial(young_modulus=2e8, poisson_ratio=0.25, breakage="none")
    model, state = bondem.make_system(
        position, 1e-3, glass, velocity=rng.normal(0, 0.1, (n, 3)),
        angular_velocity=rng.normal(0, 50, (n, 3)), bonds=pairs,
        bond_diameter=rng.uniform(0.5e-3, 1e-3, len(pairs)), bond_material=binder)
    # Give every bond a history and a slightly different previous axis and length.
    state.position += rng.normal(0, 2e-5, (n, 3))
    b = len(pairs)
    state.bond_tangential_force[:] = rng.normal(0, 1e-3, (b, 3))
    state.bond_normal_moment[:] = rng.normal(0, 1e-6, (b, 3))
    state.bond_tangential_moment[:] = rng.normal(0, 1e-6, (b, 3))
    dt = 1e-7
    expected = reference_bond_step(model, state, dt)
    law = cpu.ElasticBonds(model)
    force = np.zeros((n, 3))
    moment = np.zeros((n, 3))
    law.accumulate(model, state, force, moment, dt)
    assert np.allclose(law.force_i, expected[0], rtol=1e-10, atol=1e-14)
    assert np.allclose(law.moment_i, expected[1], rtol=1e-10, atol=1e-17)
    assert np.allclose(law.moment_j, expected[2], rtol=1e-10, atol=1e-17)
    # the per-particle gather is the plain sum over bond ends
    ref_force = np.zeros((n, 3))
    ref_moment = np.zeros((n, 3))
    np.add.at(ref_force, pairs[:, 0], expected[0])
    np.add.at(ref_force, pairs[:, 1], -expected[0])
    np.add.at(ref_moment, pairs[:, 0], expected[1])
    np.add.at(ref_moment, pairs[:, 1], expected[2])
    assert np.allclose(force, ref_force, rtol=1e-10, atol=1e-14)
    assert np.allclose(moment, ref_moment, rtol=1e-10, atol=1e-17)

"""Oblique impact of a sphere on a plane with friction (Maw, Barber & Fawcett 1976;
Walton 1993; Thornton's benchmark, Chung & Ooi 2011 test 6).

- Gross sliding (V_t / V_n > 7/2 mu (1 + e), rigid-body theory): the tangential impulse is
  mu times the normal one, so v_t' = V_t - mu (1 + e) V_n and w' R = 5/2 mu (1 + e) V_n,
  whatever the contact stiffness. Tolerance 3 % (the lever arm is R - delta, not R: the
  largest overlap here is about 2 % of R).
- Sticking (small V_t / V_n): the Mindlin spring stores and returns tangential energy, so
  the rebound is not rigid rolling. Reference: the same contact law as continuous ODEs,
  written here independently (RK4, Coulomb projection), tolerance 3 %; and the rebound
  spin lies clearly below the sliding line.
"""
import math

import numpy as np
import pytest

import bondem
from bondem.walls import PlaneWall
from contacttools import collide

RADIUS = 1e-3
V_N = 0.2
MU = 0.3
E = 0.9


def impact(v_t):
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                            restitution=E, friction=MU, rolling_friction=0.0)
    model, state = bondem.make_system([[0.0, 0.0, RADIUS + 1e-7]], RADIUS, glass,
                                      velocity=[[v_t, 0.0, -V_N]])
    sim, _ = collide(model, state, walls=[PlaneWall((0, 0, 0), (0, 0, 1), glass)])
    return glass, model, state


def reference_ode(glass, mass, v_t, steps=20000):
    """Sphere on a rigid plane: Hertz + Tsuji damping normal, Mindlin spring + damping +
    Coulomb tangential, integrated by RK4 with the slip projection after each step."""
    e_star = glass.young_modulus / (2 * (1 - glass.poisson_ratio ** 2))
    nu = glass.poisson_ratio
    g_star = glass.young_modulus / (4 * (2 - nu) * (1 + nu))
    log_e = math.log(E)
    beta = abs(log_e) / math.sqrt(log_e ** 2 + math.pi ** 2)
    inertia = 0.4 * mass * RADIUS ** 2
    t_c = 3.3 * (mass ** 2 / (RADIUS * e_star ** 2 * V_N)) ** 0.2
    h = t_c / steps

    def loads(y):
        delta, approach, u, w, xi = y
        d = max(delta, 0.0)
        s_n = 2 * e_star * math.sqrt(RADIUS * d)
        s_t = 8 * g_star * math.sqrt(RADIUS * d)
        f_n = 2 / 3 * s_n * d + 2 * math.sqrt(5 / 6) * beta * math.sqrt(s_n * mass) * approach
        slip = u - (RADIUS - d) * w
        f_t = s_t * xi - 2 * math.sqrt(5 / 6) * beta * math.sqrt(s_t * mass) * slip
        return f_n, f_t, slip, s_t

    def rhs(y):
        f_n, f_t, slip, _ = loads(y)
        limit = MU * max(f_n, 0.0)
        if abs(f_t) > limit:
            f_t = math.copysign(limit, f_t)
        return np.array([y[1], -f_n / mass, f_t / mass,
                         -(RADIUS - max(y[0], 0.0)) * f_t / inertia, -slip])

    y = np.array([0.0, V_N, v_t, 0.0, 0.0])
    while True:
        k1 = rhs(y)
        k2 = rhs(y + h / 2 * k1)
        k3 = rhs(y + h / 2 * k2)
        k4 = rhs(y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        f_n, f_t, _, s_t = loads(y)
        if abs(f_t) > MU * max(f_n, 0.0) and s_t > 0:
            y[4] = math.copysign(MU * max(f_n, 0.0), f_t) / s_t
        if y[0] <= 0.0:
            return y[2], y[3]


def test_gross_sliding_follows_rigid_theory():
    v_t = 4.0 * 3.5 * MU * (1 + E) * V_N / 2.0  # twice the sliding threshold
    glass, model, state = impact(v_t)
    assert -state.velocity[0, 2] / V_N == pytest.approx(-E, rel=0.01)
    expected_v = v_t - MU * (1 + E) * V_N
    expected_spin = 2.5 * MU * (1 + E) * V_N / RADIUS
    assert state.velocity[0, 0] == pytest.approx(expected_v, rel=0.03)
    assert state.angular_velocity[0, 1] == pytest.approx(expected_spin, rel=0.03)
    assert abs(state.angular_velocity[0, 0]) + abs(state.angular_velocity[0, 2]) < 1e-9


@pytest.mark.parametrize("ratio", [0.3, 1.0])
def test_sticking_regime_matches_contact_ode(ratio):
    v_t = ratio * V_N
    glass, model, state = impact(v_t)
    u, w = reference_ode(glass, model.mass[0], v_t)
    assert state.velocity[0, 0] == pytest.approx(u, rel=0.03, abs=0.01 * v_t)
    assert state.angular_velocity[0, 1] == pytest.approx(w, rel=0.03)
    sliding_line = 2.5 * MU * (1 + E) * V_N / RADIUS
    assert state.angular_velocity[0, 1] < 0.9 * sliding_line

"""Head-on impacts against Hertz theory (sphere-sphere, sphere-plane, sphere-meshed plane).

References: the damped Hertz ODE of the Tsuji/EDEM damping integrated by scipy (which
returns exactly the input restitution, Antypov & Elliott 2011), and for e = 1 Hertz's
closed form t_c = 2.87 (m*^2 / (R* E*^2 v))^(1/5). Tolerances: restitution 1 %, contact
time 2 % (the step is 1 % of the Rayleigh step: about 300 steps per contact).
A linear spring-dashpot impact is checked against its exact solution
(e exact, t_c = pi / sqrt(k/m* - (c/2m*)^2)).
"""
import math

import numpy as np
import pytest

import bondem
from bondem.contacts import ContactSettings
from bondem.walls import PlaneWall
from contacttools import collide, damped_hertz_reference, effective_modulus, flat_mesh

RADIUS = 1e-3
SPEED = 0.5


def material(restitution):
    return bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                           restitution=restitution, friction=0.3, name="glass")


def check(sim, steps, e_star, r_star, m_star, restitution, relative_speed_after):
    t_ref, e_ref = damped_hertz_reference(e_star, r_star, m_star, restitution, SPEED * 2
                                          if r_star < RADIUS else SPEED)
    measured_e = relative_speed_after
    assert abs(e_ref - restitution) < 1e-4  # the reference itself keeps e exactly
    assert measured_e == pytest.approx(restitution, rel=0.01)
    assert steps * sim.time_step == pytest.approx(t_ref, rel=0.02)
    if restitution == 1.0:
        speed = SPEED * 2 if r_star < RADIUS else SPEED
        hertz = 2.87 * (m_star ** 2 / (r_star * e_star ** 2 * speed)) ** 0.2
        assert steps * sim.time_step == pytest.approx(hertz, rel=0.02)
    return steps * sim.time_step / t_ref - 1.0, measured_e / restitution - 1.0


@pytest.mark.parametrize("restitution", [1.0, 0.5])
def test_sphere_sphere(restitution):
    glass = material(restitution)
    model, state = bondem.make_system([[0, 0, 0], [2 * RADIUS + 1e-6, 0, 0]], RADIUS, glass,
                                      velocity=[[SPEED, 0, 0], [-SPEED, 0, 0]])
    sim, steps = collide(model, state)
    after = (state.velocity[1, 0] - state.velocity[0, 0]) / (2 * SPEED)
    check(sim, steps, effective_modulus(glass), RADIUS / 2, model.mass[0] / 2, restitution,
          after)
    assert np.allclose(model.mass @ state.velocity, 0.0, atol=1e-18)


def test_two_materials_collide_with_their_pair_properties():
    """Unlike spheres: E* = 1/((1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b) (Hertz), the mean
    restitution and m* of the two masses; a third material in the table, unused, must not
    be read (the pair's row is a M + b)."""
    soft = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                           restitution=0.9, friction=0.3, name="soft")
    stiff = bondem.Material(density=5000.0, young_modulus=4e8, poisson_ratio=0.2,
                            restitution=0.5, friction=0.3, name="stiff")
    unused = bondem.Material(density=1000.0, young_modulus=1e10, poisson_ratio=0.45,
                             restitution=0.1, friction=0.9, name="unused")
    model, state = bondem.make_system([[0, 0, 0], [2 * RADIUS + 1e-6, 0, 0]], RADIUS,
                                      [unused, soft, stiff], material_index=[1, 2],
                                      velocity=[[SPEED, 0, 0], [-SPEED, 0, 0]])
    sim, steps = collide(model, state)
    e_star = 1.0 / ((1 - 0.3 ** 2) / 1e8 + (1 - 0.2 ** 2) / 4e8)
    m_star = model.mass[0] * model.mass[1] / (model.mass[0] + model.mass[1])
    t_ref, e_ref = damped_hertz_reference(e_star, RADIUS / 2, m_star, 0.7, 2 * SPEED)
    after = (state.velocity[1, 0] - state.velocity[0, 0]) / (2 * SPEED)
    assert after == pytest.approx(0.7, rel=0.01) and e_ref == pytest.approx(0.7, abs=1e-4)
    assert steps * sim.time_step == pytest.approx(t_ref, rel=0.02)
    before = (model.mass[0] - model.mass[1]) * SPEED
    assert np.allclose(model.mass @ state.velocity, [before, 0.0, 0.0], rtol=0, atol=1e-18)


@pytest.mark.parametrize("restitution", [1.0, 0.5])
@pytest.mark.parametrize("where", ["plane", "mesh_vertex", "mesh_edge"])
def test_sphere_wall(restitution, where):
    glass = material(restitution)
    spacing = 0.5 * RADIUS
    if where == "plane":
        wall = PlaneWall((0, 0, 0), (0, 0, 1), glass)
        x = 0.0
    else:
        wall = flat_mesh(8 * spacing, 16, glass)
        x = 0.0 if where == "mesh_vertex" else 0.5 * spacing
    model, state = bondem.make_system([[x, 0.0, RADIUS + 1e-6]], RADIUS, glass,
                                      velocity=[[0, 0, -SPEED]])
    sim, steps = collide(model, state, walls=[wall])
    check(sim, steps, effective_modulus(glass), RADIUS, model.mass[0], restitution,
          state.velocity[0, 2] / SPEED)
    assert np.allclose(state.velocity[0, :2], 0.0, atol=1e-12)
    assert np.allclose(state.angular_velocity, 0.0, atol=1e-9)


def test_linear_spring_dashpot_exact():
    glass = material(0.3)
    stiffness = 2e3  # N/m
    model, state = bondem.make_system([[0, 0, 0], [2 * RADIUS + 1e-6, 0, 0]], RADIUS, glass,
                                      velocity=[[SPEED, 0, 0], [-SPEED, 0, 0]])
    settings = ContactSettings(model="linear", linear_stiffness=stiffness)
    sim, steps = collide(model, state, settings=settings)
    m_star = model.mass[0] / 2
    beta = math.log(0.3) / math.sqrt(math.log(0.3) ** 2 + math.pi ** 2)
    damping = -2 * beta * math.sqrt(stiffness * m_star)
    t_c = math.pi / math.sqrt(stiffness / m_star - (damping / (2 * m_star)) ** 2)
    after = (state.velocity[1, 0] - state.velocity[0, 0]) / (2 * SPEED)
    assert after == pytest.approx(0.3, rel=0.01)
    assert steps * sim.time_step == pytest.approx(t_c, rel=0.02)


def test_linear_stiffness_limits_auto_time_step():
    """The linear law's sqrt(m*/k_n) enters the automatic step; a stiff spring wins over
    the Rayleigh step, and a larger given step is refused."""
    glass = material(0.5)
    model, state = bondem.make_system([[0, 0, 0], [3e-3, 0, 0]], RADIUS, glass)
    stiffness = 1e9
    settings = ContactSettings(model="linear", linear_stiffness=stiffness)
    sim = bondem.Simulation(model, state, contact=settings)
    expected = 0.2 * math.sqrt(0.5 * model.mass[0] / stiffness)
    assert sim.time_step == pytest.approx(expected, rel=1e-12)
    assert sim.time_step_cause == "contact_linear"
    with pytest.raises(ValueError, match="stable limit"):
        bondem.Simulation(model, state, contact=settings, time_step=10 * expected / 0.2)
    with pytest.raises(ValueError, match="contact model"):
        ContactSettings(model="hooke")

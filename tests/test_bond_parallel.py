"""The parallel bond (physics/bond_parallel.py) against its closed forms: the shear stress
at which a bond held at a normal stress breaks lies on the Mohr-Coulomb line c - sigma_n
tan phi, a bending moment breaks it at sigma_t I / (beta R), and with softening the axial
force follows the bilinear envelope, unloads along the secant and dissipates the
envelope's area."""
import math

import numpy as np
import pytest

import bondem
from bondem.physics.bond_elastic import SHEAR, TENSION

from bondtools import BOND_DIAMETER, SPACING

AXIS = np.array([2.0, 2.0, 1.0]) / 3.0
SIDE = np.array([1.0, -1.0, 0.0]) / math.sqrt(2.0)
YOUNG = 1e8
RADIUS = BOND_DIAMETER / 2
AREA = math.pi * RADIUS ** 2
SECOND = AREA * RADIUS ** 2 / 4
K = YOUNG * AREA / SPACING
DT = 1e-6


def parallel(**kw):
    values = dict(young_modulus=YOUNG, poisson_ratio=0.25, model="parallel",
                  normal_strength=3e5, tangential_strength=2e5, friction_angle=35.0)
    values.update(kw)
    return bondem.BondMaterial(**values)


def pair(material):
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    model, state = bondem.make_system([[0.0, 0.0, 0.0], SPACING * AXIS], 1e-3, glass,
                                      fixed=[True, True], bonds=[[0, 1]],
                                      bond_diameter=BOND_DIAMETER, bond_material=material)
    return bondem.Simulation(model, state, time_step=DT)


def shear_to_break(sim, axial_strain):
    """Hold the pair at ``axial_strain``, then slide particle 1 sideways at 1 mm/s until
    the bond breaks: (normal stress on the bond, positive in compression, and |F_t| / A
    of its last intact step, both in Pa; break mode)."""
    state = sim.state
    state.velocity[1] = axial_strain * SPACING / (1000 * DT) * AXIS
    sim.step(1000)
    state.velocity[1] = 1e-3 * SIDE
    normal = shear = 0.0
    while state.bond_active[0]:
        normal = -np.dot(sim.bonds.loads.force_i[0], state.bond_axis[0]) / AREA
        shear = np.linalg.norm(state.bond_tangential_force[0]) / AREA
        sim.step(1)
        assert state.time < 0.1
    return normal, shear, state.bond_break_mode[0]


def test_the_shear_strength_rises_along_the_mohr_coulomb_line():
    """Five normal stresses from 1e5 Pa tension to 8e5 Pa compression: the shear stress
    at break is c - sigma tan phi (phi = 35 degrees, c = 2e5 Pa) within 1 % of c, and a
    line through them has slope tan 35 (1 %) and intercept c (1 %)."""
    normal, shear = [], []
    for strain in (1e-3, -1e-3, -3e-3, -5.5e-3, -8e-3):
        s_n, tau, mode = shear_to_break(pair(parallel()), strain)
        assert mode == SHEAR
        normal.append(s_n)
        shear.append(tau)
    normal, shear = np.array(normal), np.array(shear)
    assert normal.min() < -0.5e5 and normal.max() > 7e5
    np.testing.assert_allclose(shear, 2e5 + normal * math.tan(math.radians(35.0)),
                               atol=2e3)
    slope, intercept = np.polyfit(normal, shear, 1)
    assert slope == pytest.approx(math.tan(math.radians(35.0)), rel=1e-2)
    assert intercept == pytest.approx(2e5, rel=1e-2)


@pytest.mark.parametrize("beta", [1.0, 0.4])
def test_a_bending_moment_breaks_it_at_the_tensile_strength(beta):
    """Particle 1 turned about an axis normal to the bond (cohesion inf): the bond breaks
    in tension when beta |M_t| R / I reaches sigma_t, i.e. at |M_t| = sigma_t I /
    (beta R) (the last intact moment within 1 %)."""
    sim = pair(parallel(tangential_strength=float("inf"), moment_factor=beta))
    state = sim.state
    state.angular_velocity[1] = 2.0 * SIDE
    moment = 0.0
    while state.bond_active[0]:
        moment = np.linalg.norm(state.bond_tangential_moment[0])
        sim.step(1)
        assert state.time < 0.1
    assert state.bond_break_mode[0] == TENSION
    assert moment == pytest.approx(3e5 * SECOND / (beta * RADIUS), rel=1e-2)


def test_softening_follows_the_envelope_and_dissipates_its_area():
    """zeta = 0.5: peak sigma_t A at eps_0 = sigma_t / E, the envelope down to zero at
    eps_f = 3 eps_0; pulled to 2 eps_0, released to zero strain (along the secant: F =
    (1 - D) k delta), pushed into compression (undamaged slope k), pulled to breaking at
    eps_f; dissipated sigma_t eps_f A L0 / 2 (1 %)."""
    sigma_t, zeta = 3e5, 0.5
    eps_0 = sigma_t / YOUNG
    eps_f = eps_0 * (1 + 1 / zeta)
    sim = pair(parallel(softening=zeta, tangential_strength=float("inf")))
    state = sim.state
    speed = 1e-3
    steps_0 = eps_0 * SPACING / (speed * DT)          # 6000 steps to the peak

    def run(steps, sign):
        state.velocity[1] = sign * speed * AXIS
        out = []
        for _ in range(int(round(steps))):
            stretch = np.dot(state.position[1] - state.position[0], AXIS) - SPACING
            sim.step(1)
            out.append((stretch, np.dot(sim.bonds.loads.force_i[0], AXIS)))
        return np.array(out)
    up = run(2 * steps_0, 1)
    assert up[:, 1].max() == pytest.approx(sigma_t * AREA, rel=1e-3)
    end = up[-1]
    envelope = sigma_t * AREA * (eps_f * SPACING - end[0]) / ((eps_f - eps_0) * SPACING)
    assert end[1] == pytest.approx(envelope, rel=1e-3)
    down = run(2.5 * steps_0, -1)
    tension = down[down[:, 0] > 1e-9]
    np.testing.assert_allclose(tension[:, 1], tension[:, 0] * end[1] / end[0], rtol=1e-3)
    squeezed = down[down[:, 0] < -1e-9]
    np.testing.assert_allclose(squeezed[:, 1], K * squeezed[:, 0], rtol=1e-3)
    run(4 * steps_0, 1)
    assert not state.bond_active[0] and state.bond_break_mode[0] == TENSION
    booked = sim.energy_terms()["dissipated_softening"]
    assert booked == pytest.approx(0.5 * sigma_t * eps_f * AREA * SPACING, rel=1e-2)


@pytest.mark.parametrize("strength, step", [(2.5e5, 5000),
                                            (3e5, 2e5 / math.tan(math.radians(35.0))
                                             / YOUNG * SPACING / (1e-3 * DT))])
def test_brittle_tension_breaks_at_the_tensile_strength_or_the_apex(strength, step):
    """Without softening a pulled bond breaks in tension in the step whose axial stress
    E eps reaches sigma_t (2.5e5 Pa: step 5000 at 1 mm/s), or the Mohr-Coulomb apex
    c / tan phi = 2.86e5 Pa if that comes first (sigma_t 3e5 Pa: step 5714)."""
    sim = pair(parallel(softening=0.0, normal_strength=strength))
    sim.state.velocity[1] = 1e-3 * AXIS
    sim.step(6100)
    assert sim.state.bond_break_mode[0] == TENSION
    assert sim.state.bond_break_time[0] == pytest.approx(math.ceil(step) * DT,
                                                         abs=1.01 * DT)

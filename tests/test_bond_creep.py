"""The creep bond (physics/bond_creep.py) against its closed forms: held at a fixed
stretch or shear its stress relaxes as d sigma/dt = -E A sigma^m (m = 2: sigma_0 / (1 +
E A sigma_0 t)), under a constant force it stretches at L0 A (F/A_b)^m, and without
creep it is the elastic-plastic bond to the bit."""
import numpy as np
import pytest

import bondem

from bondtools import BOND_DIAMETER, SPACING

AXIS = np.array([2.0, -1.0, 2.0]) / 3.0
SIDE = np.array([1.0, 2.0, 0.0]) / np.sqrt(5.0)     # normal to AXIS
YOUNG = 1e8
SHEAR = YOUNG / (2 * 1.3)
AREA = np.pi * (BOND_DIAMETER / 2) ** 2
DT = 1e-6


def glass():
    return bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)


def creep(**kw):
    values = dict(young_modulus=YOUNG, poisson_ratio=0.3, breakage="none", model="creep",
                  fracture_strain=1.0)
    values.update(kw)
    return bondem.BondMaterial(**values)


def held_pair(material, direction, speed=1e-3):
    model, state = bondem.make_system(
        [[0.0, 0.0, 0.0], SPACING * AXIS], 1e-3, glass(),
        velocity=[[0.0, 0.0, 0.0], speed * direction], fixed=[True, True], bonds=[[0, 1]],
        bond_diameter=BOND_DIAMETER, bond_material=material)
    return bondem.Simulation(model, state, time_step=DT)


@pytest.mark.parametrize("direction, modulus, rate", [(AXIS, YOUNG, 5.3e-12),
                                                      (SIDE, SHEAR, 3.4e-11)])
def test_a_held_bond_relaxes_by_the_creep_law(direction, modulus, rate):
    """Stretched (or sheared) by 4 um in 4000 steps, then held for 0.02 s: the stress
    follows sigma_h / (1 + M A sigma_h t) (M = E, or G in shear; m = 2) within 0.5 %,
    having lost more than half of itself."""
    sim = held_pair(creep(creep_rate=rate, creep_exponent=2.0), direction)
    sim.step(4000)
    sim.state.velocity[1] = 0.0

    def stress():
        if direction is AXIS:
            return np.dot(sim.bonds.loads.force_i[0], AXIS) / AREA
        return np.linalg.norm(sim.state.bond_tangential_force[0]) / AREA
    sim.step(1)
    held, start = stress(), sim.state.time
    for _ in range(4):
        sim.step(5000)
        t = sim.state.time - start
        assert stress() == pytest.approx(held / (1 + modulus * rate * held * t), rel=5e-3)
    assert stress() < 0.45 * held
    assert sim.energy_terms()["dissipated_creep"] > 0.0


def test_a_constant_force_stretches_the_bond_at_the_creep_rate():
    """Particle 1 pulled by 0.1 N (the other clamped, local damping for the ringing):
    after the transient its distance grows at L0 A sigma^1.5, sigma = F / A_b (1 %)."""
    rate, exponent, force = 1.1e-9, 1.5, 0.1
    model, state = bondem.make_system(
        [[0.0, 0.0, 0.0], SPACING * AXIS], 1e-3, glass(), fixed=[True, False],
        external_force=[[0.0, 0.0, 0.0], force * AXIS], bonds=[[0, 1]],
        bond_diameter=BOND_DIAMETER, damping=0.7,
        bond_material=creep(creep_rate=rate, creep_exponent=exponent))
    sim = bondem.Simulation(model, state, time_step=DT)
    sim.step(5000)
    times, lengths = [], []
    for _ in range(15):
        sim.step(1000)
        times.append(state.time)
        lengths.append(np.linalg.norm(state.position[1]))
    slope = np.polyfit(times, lengths, 1)[0]
    assert slope == pytest.approx(SPACING * rate * (force / AREA) ** exponent, rel=1e-2)


def test_without_creep_it_is_the_elastic_plastic_bond_to_the_bit():
    """creep_rate 0: the same yield, the same plastic strain and forces, bit for bit."""
    runs = []
    for material in (creep(yield_strength=1e5),
                     bondem.BondMaterial(young_modulus=YOUNG, poisson_ratio=0.3,
                                         breakage="none", model="elastic_plastic",
                                         yield_strength=1e5, fracture_strain=1.0)):
        sim = held_pair(material, (AXIS + SIDE) / np.sqrt(2.0))
        sim.step(3000)
        runs.append((sim.bonds.loads.force_i.copy(), sim.state.bond_tangential_force.copy(),
                     sim.state.extra["bond_model_state"].copy()))
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)
    assert runs[0][2][0, 1] > 0.0       # it yielded


def test_creep_keys_need_the_creep_model_and_yield_keys_are_shared():
    with pytest.raises(ValueError, match="creep_rate = 0.01 needs model = 'creep'"):
        bondem.BondMaterial(young_modulus=1e8, model="elastic_plastic", creep_rate=0.01)
    with pytest.raises(ValueError, match="needs model = .*'creep' or 'elastic_plastic'"):
        bondem.BondMaterial(young_modulus=1e8, yield_strength=1e5)
    assert creep(yield_strength=1e5, creep_rate=1e-9).yield_strength == 1e5

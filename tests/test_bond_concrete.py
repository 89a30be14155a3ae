"""The plastic concrete bond (physics/bond_concrete.py) against the envelopes its explicit
update converges to: tensile yield at r sigma_y, softening along (r sigma_y - alpha E eps)
/ (1 - alpha) to a break at eps_f = r sigma_y / (alpha E) having dissipated the
triangle's area, unloading along E; compressive yield at -sigma_y and hardening along
(-sigma_y + beta E eps) / (1 + beta). MUSEN's defective original is reproduced only with
musen_compat (test_validate.py, the real run)."""
import math

import numpy as np
import pytest

import bondem
from bondem.physics.bond_elastic import TENSION

from bondtools import BOND_DIAMETER, SPACING

AXIS = np.array([1.0, 2.0, 2.0]) / 3.0
YOUNG, YIELD = 1e8, 2e5
R, ALPHA, BETA = 0.6, 0.25, 0.4          # away from MUSEN's fixed 0.7, 0.3, 0.5
AREA = math.pi * (BOND_DIAMETER / 2) ** 2
DT, SPEED = 1e-6, 1e-3


def pair():
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    material = bondem.BondMaterial(young_modulus=YOUNG, poisson_ratio=0.3, model="concrete",
                                   yield_strength=YIELD, tensile_yield_ratio=R,
                                   tensile_softening=ALPHA, compressive_hardening=BETA)
    model, state = bondem.make_system([[0.0, 0.0, 0.0], SPACING * AXIS], 1e-3, glass,
                                      fixed=[True, True], bonds=[[0, 1]],
                                      bond_diameter=BOND_DIAMETER, bond_material=material)
    return bondem.Simulation(model, state, time_step=DT)


def drive(sim, strain, sign):
    sim.state.velocity[1] = sign * SPEED * AXIS
    out = []
    for _ in range(int(round(strain * SPACING / (SPEED * DT)))):
        if not sim.state.bond_active[0]:
            break
        eps = (np.linalg.norm(sim.state.position[1] - sim.state.position[0]) - SPACING) \
            / SPACING
        sim.step(1)
        out.append((eps, np.dot(sim.bonds.loads.force_i[0], AXIS) / AREA))
    return np.array(out)


def test_tension_softens_along_its_envelope_and_breaks_at_eps_f():
    sim = pair()
    eps_0, eps_f = R * YIELD / YOUNG, R * YIELD / (ALPHA * YOUNG)
    rows = drive(sim, 1.2 * eps_f, 1)
    eps, stress = rows[:, 0], rows[:, 1]
    assert stress.max() == pytest.approx(R * YIELD, rel=1e-3)
    elastic = eps < 0.99 * eps_0
    np.testing.assert_allclose(stress[elastic], YOUNG * eps[elastic], rtol=1e-6)
    soft = (eps > 1.05 * eps_0) & (eps < 0.95 * eps_f)
    envelope = (R * YIELD - ALPHA * YOUNG * eps[soft]) / (1 - ALPHA)
    np.testing.assert_allclose(stress[soft], envelope, atol=1e-2 * R * YIELD)
    state = sim.state
    assert not state.bond_active[0] and state.bond_break_mode[0] == TENSION
    assert state.bond_break_time[0] * SPEED / SPACING == pytest.approx(eps_f, rel=1e-2)
    dissipated = sim.energy_terms()["dissipated_concrete"] + state.bond_break_energy[0]
    assert dissipated == pytest.approx(0.5 * R * YIELD * eps_f * AREA * SPACING, rel=2e-2)


def test_unloading_from_the_softening_branch_follows_e():
    sim = pair()
    eps_0 = R * YIELD / YOUNG
    drive(sim, 2 * eps_0, 1)
    back = drive(sim, 0.5 * eps_0, -1)
    slope = np.polyfit(back[2:, 0], back[2:, 1], 1)[0]
    assert slope == pytest.approx(YOUNG, rel=1e-6)


def test_compression_hardens_along_its_envelope():
    sim = pair()
    rows = drive(sim, 4 * YIELD / YOUNG, -1)
    eps, stress = rows[:, 0], rows[:, 1]
    hard = eps < -1.05 * YIELD / YOUNG
    envelope = (-YIELD + BETA * YOUNG * eps[hard]) / (1 + BETA)
    np.testing.assert_allclose(stress[hard], envelope, atol=1e-2 * YIELD)
    assert stress.min() < -1.5 * YIELD
    assert sim.state.bond_active[0]

"""The integrator's energy counters (SPEC 1, Simulation.energy_terms) that the energy
balance of bondem.analysis relies on.

Reference: each kick changes a free particle's kinetic energy by exactly
(F_applied + F_damping) . (v_old + v_new) / 2 dt, so with gravity and local damping
KE(t) - KE(0) = work_external - dissipated_damping to round-off. (A numba prange
reduction inside an `if` was silently dropped once, leaving both counters at 0.)
"""
import numpy as np
import pytest

import bondem


@pytest.mark.parametrize("damping", [0.0, 0.3])
def test_gravity_work_and_damping_loss_balance_kinetic_energy(glass, damping):
    velocity = [[0.1, -0.2, 0.3], [0.0, 0.0, -0.5]]
    model, state = bondem.make_system([[0, 0, 0], [1e-2, 0, 0]], 1e-3, glass,
                                      velocity=velocity, gravity=(1.0, 0.0, -9.81),
                                      damping=damping)
    sim = bondem.Simulation(model, state)
    before = sum(sim.kinetic_energy())
    sim.step(2000)
    terms = sim.energy_terms()
    change = sum(sim.kinetic_energy()) - before
    assert terms["work_external"] > 1e-7                # gravity did real work
    if damping:
        assert terms["dissipated_damping"] > 0.1 * terms["work_external"]
    else:
        assert terms["dissipated_damping"] == 0.0
    assert change == pytest.approx(terms["work_external"] - terms["dissipated_damping"],
                                   rel=1e-9, abs=1e-18)

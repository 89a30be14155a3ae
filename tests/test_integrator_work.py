"""The integrator's energy counters (CPU backend).

Reference: for a free particle under a constant load the leapfrog's kinetic energy change
equals the load times the mean velocity of each kick, which is what ``work_external``
sums, so the two agree to round-off; damping removes what ``dissipated_damping`` says.
(These counters read 0 while numba's parallel reduction dropped the sums made inside the
nested if/for of the particle loop.)
"""
import numpy as np

import bondem


def test_gravity_work_equals_kinetic_energy_gain(glass):
    model, state = bondem.make_system([[0, 0, 0], [1, 0, 0]], 1e-3, glass,
                                      velocity=[[0.0, 0.0, 1.0], [0.5, 0.0, 0.0]],
                                      gravity=(0.0, 0.0, -9.81),
                                      external_force=[[1e-4, 0, 0], [0, 0, 0]])
    sim = bondem.Simulation(model, state, time_step=1e-6)
    before = sum(sim.kinetic_energy())
    sim.step(200)
    gained = sum(sim.kinetic_energy()) - before
    assert abs(sim.state.work_external) > 1e-10
    # The gain is a difference of energies ~ before, so round-off scales with before.
    assert abs(sim.state.work_external - gained) <= 1e-12 * before


def test_damping_loss_balances(glass):
    model, state = bondem.make_system([[0, 0, 0]], 1e-3, glass, velocity=[[0.0, 0.0, 1.0]],
                                      gravity=(0.0, 0.0, -9.81), damping=0.3)
    sim = bondem.Simulation(model, state, time_step=1e-6)
    before = sum(sim.kinetic_energy())
    sim.step(200)
    gained = sum(sim.kinetic_energy()) - before
    assert sim.state.dissipated_damping > 0.0
    balance = sim.state.work_external - sim.state.dissipated_damping - gained
    assert abs(balance) <= 1e-12 * before

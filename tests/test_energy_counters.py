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


def test_damping_loss_of_spin_balances_rotational_energy(glass):
    """Local damping of the moments: a spinning sphere driven by an external moment loses
    |M_k| |w_k| dt per component to damping, and the counters must close the balance of
    its rotational energy too (the translational damping alone, as above, would not
    notice a loss booked with the force in place of the moment). No gravity, no force."""
    model, state = bondem.make_system([[0, 0, 0], [1e-2, 0, 0]], 1e-3, glass,
                                      angular_velocity=[[0.0] * 3, [2.0, -3.0, 1.0]],
                                      damping=0.3)
    model.external_moment[1] = (4e-7, -2e-7, 3e-7)
    sim = bondem.Simulation(model, state)
    before = sum(sim.kinetic_energy())
    sim.step(2000)
    terms = sim.energy_terms()
    translational, rotational = sim.kinetic_energy()
    assert translational == 0.0
    change = translational + rotational - before
    assert terms["dissipated_damping"] > 0.1 * abs(terms["work_external"]) > 0.0
    assert change == pytest.approx(terms["work_external"] - terms["dissipated_damping"],
                                   rel=1e-9, abs=1e-18)


def test_external_loads_set_between_steps_without_gravity_are_counted(glass):
    """No gravity, damping or field: the integrator tracks only the external loads, which a
    script (or a coupled solver) may set in place between any two steps. Their work must
    be the kinetic energy they gave: a constant force F on a free sphere changes its
    velocity by F/m per second, its moment M its spin by M/I."""
    velocity = [[0.1, -0.2, 0.3], [0.0, 0.05, 0.0]]
    spin = [[0.0, 0.0, 0.0], [3.0, -1.0, 2.0]]
    model, state = bondem.make_system([[0, 0, 0], [1e-2, 0, 0]], 1e-3, glass,
                                      velocity=velocity, angular_velocity=spin)
    sim = bondem.Simulation(model, state)
    sim.step(50)
    assert sim.energy_terms()["work_external"] == 0.0
    v0 = sim.state.velocity.copy()
    w0 = sim.state.angular_velocity.copy()
    t0 = sim.state.time
    force = np.array([0.02, -0.01, 0.005])      # N, on sphere 0
    moment = np.array([1e-7, 0.0, -2e-7])       # N m, on sphere 1
    model.external_force[0] = force
    model.external_moment[1] = moment
    sim.step(2000)
    elapsed = sim.state.time - t0
    dv = sim.state.velocity[0] - v0[0]
    dw = sim.state.angular_velocity[1] - w0[1]
    assert dv == pytest.approx(force / model.mass[0] * elapsed, rel=1e-6)
    assert dw == pytest.approx(moment / model.inertia[1] * elapsed, rel=1e-6)
    gained = (0.5 * model.mass[0] * (sim.state.velocity[0] @ sim.state.velocity[0]
                                     - v0[0] @ v0[0])
              + 0.5 * model.inertia[1] * (sim.state.angular_velocity[1]
                                          @ sim.state.angular_velocity[1] - w0[1] @ w0[1]))
    terms = sim.energy_terms()
    assert gained > 1e-9
    assert terms["work_external"] == pytest.approx(gained, rel=1e-9)
    assert terms["dissipated_damping"] == 0.0


@pytest.mark.parametrize("kind", ["force", "moment"])
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_single_external_load_component_is_counted(glass, kind, axis):
    """The integrator decides once per particle whether to count energies: a load on one
    component alone must be counted, on any axis, force or moment. Its work is the
    kinetic energy it gave the free sphere (2000 steps, no gravity or damping)."""
    model, state = bondem.make_system([[0, 0, 0], [1e-2, 0, 0]], 1e-3, glass,
                                      velocity=[[0.0, 0.0, 0.0], [0.1, -0.2, 0.3]],
                                      angular_velocity=[[0.0] * 3, [2.0, -3.0, 1.0]])
    sim = bondem.Simulation(model, state)
    sim.step(5)
    v0 = sim.state.velocity[1].copy()
    w0 = sim.state.angular_velocity[1].copy()
    load = np.zeros(3)
    load[axis] = -0.03 if kind == "force" else 4e-7
    (model.external_force if kind == "force" else model.external_moment)[1] = load
    sim.step(2000)
    v, w = sim.state.velocity[1], sim.state.angular_velocity[1]
    gained = (0.5 * model.mass[1] * (v @ v - v0 @ v0)
              + 0.5 * model.inertia[1] * (w @ w - w0 @ w0))
    assert abs(gained) > 1e-9
    assert sim.energy_terms()["work_external"] == pytest.approx(gained, rel=1e-9)


def test_external_force_on_a_clump_without_gravity_is_counted(glass):
    """A dumbbell clump pulled along its axis (no torque about its centre), no gravity
    or damping: the force's work is the clump's gain of kinetic energy,
    M (|V|^2 - |V0|^2) / 2, and V changes by F/M per second."""
    from bondem.clumps import make_clumps
    model, state = bondem.make_system([[-1e-3, 0, 0], [1e-3, 0, 0], [2e-2, 0, 0]], 1e-3,
                                      glass, velocity=[[0.0, 0.1, 0.0]] * 2 + [[0, 0, 0]])
    model, state = make_clumps(model, state, [0, 0, -1])
    sim = bondem.Simulation(model, state)
    sim.step(20)
    assert sim.energy_terms()["work_external"] == 0.0
    v0 = sim.state.clump_velocity[0].copy()
    t0 = sim.state.time
    force = np.array([0.03, 0.0, 0.0])
    model.external_force[1] = force
    sim.step(1000)
    elapsed = sim.state.time - t0
    mass = model.clump_mass[0]
    v = sim.state.clump_velocity[0]
    assert v - v0 == pytest.approx(force / mass * elapsed, rel=1e-6, abs=1e-12)
    gained = 0.5 * mass * (v @ v - v0 @ v0)
    assert gained > 1e-9
    assert sim.energy_terms()["work_external"] == pytest.approx(gained, rel=1e-9)

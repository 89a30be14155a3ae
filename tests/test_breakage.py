"""Bond breakage (SPEC 2): each mode breaks in the first step its stress reaches the
strength, the mode and break time are recorded, and the broken bond applies no force.

Particles are driven kinematically (fixed = prescribed velocities), so the stress history
is known in closed form. Each evaluation after the first adds the increment of one step,
dt; the start-up evaluation at t = 0 adds none (SPEC 1). Hence after the evaluation at
t = m dt, with a relative rate q:
    accumulated (shear, twist, bending) = k q m dt,   stretch = v m dt.
"""
import math

import numpy as np
import pytest

import bondem
from bondem.physics.bond_elastic import COMPRESSION, INTACT, SHEAR, TENSION

from bondtools import bond_constants

DT = 1e-7


def driven_pair(glass, velocity=None, angular_velocity=None, **bond):
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, **bond)
    model, state = bondem.make_system([[0, 0, 0], [2e-3, 0, 0]], 1e-3, glass, fixed=[True, True],
                                      velocity=velocity, angular_velocity=angular_velocity,
                                      bonds=[[0, 1]], bond_diameter=1e-3, bond_material=binder)
    return binder, bondem.Simulation(model, state, time_step=DT)


def first_step(stress_at_step, strength):
    """Smallest m with stress(m) >= strength, and a strength halfway between steps."""
    m = 0
    while stress_at_step(m) < strength:
        m += 1
    return m


def run_until_break(sim, limit=100_000):
    sim.step(0)
    while sim.state.bond_active[0] and sim.state.step < limit:
        sim.step(1)
    return sim.state


def mid_strength(stress_at_step, m):
    return 0.5 * (stress_at_step(m) + stress_at_step(m + 1))


def test_tension_breaks_at_first_step_reaching_normal_strength(glass):
    speed = 0.01
    (kn, _, _, _), (area, _, _) = bond_constants(bondem.BondMaterial(young_modulus=1e8))
    sigma = lambda m: kn * speed * m * DT / area  # noqa: E731
    strength = mid_strength(sigma, 400)
    _, sim = driven_pair(glass, velocity=[[0, 0, 0], [speed, 0, 0]], normal_strength=strength)
    state = run_until_break(sim)
    assert first_step(sigma, strength) == 401
    assert state.bond_break_mode[0] == TENSION
    assert state.bond_break_time[0] == pytest.approx(401 * DT, rel=1e-9)
    assert np.all(sim.bonds.force_i == 0.0) and np.all(sim.force == 0.0)  # no force that step


def test_shear_breaks_at_first_step_reaching_tangential_strength(glass):
    # Both particles spin alike about z: v_rel = -(w_i + w_j) x r / 2 = -w L y, no bending.
    spin = 50.0
    (_, ks, _, _), (area, _, _) = bond_constants(bondem.BondMaterial(young_modulus=1e8))
    tau = lambda m: ks * spin * 2e-3 * m * DT / area  # noqa: E731
    strength = mid_strength(tau, 300)
    _, sim = driven_pair(glass, angular_velocity=[[0, 0, spin], [0, 0, spin]],
                         tangential_strength=strength)
    state = run_until_break(sim)
    assert state.bond_break_mode[0] == SHEAR
    assert state.bond_break_time[0] == pytest.approx(301 * DT, rel=1e-9)


def test_torsion_breaks_at_first_step_reaching_tangential_strength(glass):
    spin = 50.0
    (_, _, ktw, _), (_, _, polar) = bond_constants(bondem.BondMaterial(young_modulus=1e8))
    tau = lambda m: ktw * spin * m * DT * 0.5e-3 / polar  # noqa: E731
    strength = mid_strength(tau, 250)
    _, sim = driven_pair(glass, angular_velocity=[[0, 0, 0], [spin, 0, 0]],
                         tangential_strength=strength)
    state = run_until_break(sim)
    assert state.bond_break_mode[0] == SHEAR
    assert state.bond_break_time[0] == pytest.approx(251 * DT, rel=1e-9)


def test_bending_at_initial_length_breaks_only_with_compressive_breakage(glass):
    # Opposite spins about z: pure bending, L stays L0, so sigma is evaluated only when
    # compressive breakage is on (SPEC: the sigma criterion needs L > L0 otherwise).
    spin = 50.0
    (_, _, _, kb), (_, second, _) = bond_constants(bondem.BondMaterial(young_modulus=1e8))
    sigma = lambda m: kb * 2 * spin * m * DT * 0.5e-3 / second  # noqa: E731
    strength = mid_strength(sigma, 200)
    w = [[0, 0, spin], [0, 0, -spin]]
    _, sim = driven_pair(glass, angular_velocity=w, normal_strength=strength)
    state = run_until_break(sim, limit=2000)
    assert state.bond_active[0] and state.bond_break_mode[0] == INTACT
    _, sim = driven_pair(glass, angular_velocity=w, normal_strength=strength,
                         compressive_breakage=True)
    state = run_until_break(sim)
    assert state.bond_break_mode[0] == COMPRESSION  # L is not > L0
    assert state.bond_break_time[0] == pytest.approx(201 * DT, rel=1e-9)


@pytest.mark.parametrize("compressive", [False, True])
def test_compression_breaks_only_with_compressive_breakage(glass, compressive):
    speed = 0.01
    (kn, _, _, _), (area, _, _) = bond_constants(bondem.BondMaterial(young_modulus=1e8))
    sigma = lambda m: kn * speed * m * DT / area  # noqa: E731
    strength = mid_strength(sigma, 150)
    _, sim = driven_pair(glass, velocity=[[0, 0, 0], [-speed, 0, 0]], normal_strength=strength,
                         compressive_breakage=compressive)
    state = run_until_break(sim, limit=1000)
    if compressive:
        assert state.bond_break_mode[0] == COMPRESSION
        assert state.bond_break_time[0] == pytest.approx(151 * DT, rel=1e-9)
    else:
        assert state.bond_active[0] and math.isnan(state.bond_break_time[0])


def test_combined_sums_terms_and_separate_waits_for_one(glass):
    # Shear force and torsion grow together; tau = shear + torsion. Combined breaks when
    # the sum reaches the strength, separate only when the larger term alone does.
    spin = 50.0
    (_, ks, ktw, _), (area, _, polar) = bond_constants(bondem.BondMaterial(young_modulus=1e8))
    w = [[0, 0, spin], [0, 0, spin]]
    w_twist = [[spin, 0, spin], [-spin, 0, spin]]
    shear = lambda m: ks * spin * 2e-3 * m * DT / area  # noqa: E731
    torsion = lambda m: ktw * 2 * spin * m * DT * 0.5e-3 / polar  # noqa: E731
    total = lambda m: shear(m) + torsion(m)  # noqa: E731
    strength = mid_strength(total, 200)
    _, combined = driven_pair(glass, angular_velocity=w_twist, tangential_strength=strength)
    state = run_until_break(combined)
    assert state.bond_break_mode[0] == SHEAR
    assert state.bond_break_time[0] == pytest.approx(201 * DT, rel=1e-9)
    _, separate = driven_pair(glass, angular_velocity=w_twist, tangential_strength=strength,
                              breakage="separate")
    state = run_until_break(separate)
    larger = lambda m: max(shear(m), torsion(m))  # noqa: E731
    assert state.bond_break_time[0] == pytest.approx(first_step(larger, strength) * DT, rel=1e-9)
    assert state.bond_break_time[0] > 201 * DT
    _, never = driven_pair(glass, angular_velocity=w, tangential_strength=1e3, breakage="none")
    assert run_until_break(never, limit=500).bond_active[0]


def test_musen_compat_uses_full_start_up_increment(glass):
    spin = 50.0
    (_, _, ktw, _), (_, _, polar) = bond_constants(bondem.BondMaterial(young_modulus=1e8))
    tau = lambda m: ktw * spin * (m + 2) * DT * 0.5e-3 / polar  # noqa: E731
    strength = mid_strength(tau, 250)
    binder = bondem.BondMaterial(young_modulus=1e8, tangential_strength=strength)
    model, state = bondem.make_system([[0, 0, 0], [2e-3, 0, 0]], 1e-3, glass, fixed=[True, True],
                                      angular_velocity=[[0, 0, 0], [spin, 0, 0]], bonds=[[0, 1]],
                                      bond_diameter=1e-3, bond_material=binder)
    state = run_until_break(bondem.Simulation(model, state, time_step=DT, musen_compat=True))
    assert state.bond_break_time[0] == pytest.approx(251 * DT, rel=1e-9)

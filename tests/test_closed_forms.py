"""Closed-form checks that fail on bugs a line-by-line reference of our own code would
share: each expected value comes from the physics (kinematics, symmetry, a rigid motion,
a stress that grows linearly), not from the formulas the code implements.

- free fall from rest is exact to round-off from the first step (SPEC 1's start-up: a
  half kick, not a full one);
- a tensile (damped) normal force carries no friction (the Coulomb limit uses max(f_n, 0));
- swapping the two materials of a contact gives the mirrored loads (pair mixing rules);
- local damping of moments opposes the spin, whatever the velocity does;
- a bond across a periodic boundary at rest carries no force, in either pair order;
- a stored shear force of a pair spinning rigidly about its axis turns with the pair;
- the combined criterion breaks when the sum of axial and bending stress reaches the
  strength.
"""
import numpy as np
import pytest

import bondem
from bondem import BondMaterial, Material, Simulation, make_system

GLASS = Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)


def test_free_fall_from_rest_is_exact_from_the_first_step():
    """x_n = x_0 - g t_n^2 / 2 and v_n+1/2 = -g t_n+1/2 to round-off: leapfrog with a half
    kick at the start is exact for a constant force; a full first kick is off by g dt^2/2."""
    g, dt = 9.81, 2e-5
    model, state = make_system(np.array([[0.0, 0.0, 1.0]]), radius=1e-3, material=GLASS,
                               gravity=[0.0, 0.0, -g])
    sim = Simulation(model, state, time_step=dt)
    for n in range(1, 201):
        sim.step(1)
        t = n * dt
        assert state.time == pytest.approx(t, rel=1e-14)
        assert state.position[0, 2] == pytest.approx(1.0 - 0.5 * g * t * t, rel=0, abs=1e-15)
        assert state.velocity[0, 2] == pytest.approx(-g * (t - 0.5 * dt), rel=1e-12)


def test_tensile_damped_normal_force_carries_no_friction():
    """A contact separating fast enough that the damping pulls (f_n < 0) has no Coulomb
    capacity: F_t = 0 and no rolling torque, though the spring and the slip are not zero."""
    from bondem.backends.cpu_contacts import hertz_mindlin, restitution_beta
    n = (1.0, 0.0, 0.0)
    beta = restitution_beta(0.1)
    overlap = 1e-9
    v_rel = (5.0, 0.3, -0.2)           # separating at 5 m/s, sliding
    force, torque, f_t, _, _ = hertz_mindlin(
        n, overlap, v_rel, (0.0, 10.0, 0.0), (0.0, 1e-7, 0.0), 1e8, 4e7, 5e-4, 1e-5, 1e-12,
        beta, 0.5, 0.1, 1e-7)
    assert force[0] > 0.0              # on i, along +n: j pulls i (tensile)
    assert f_t == (0.0, 0.0, 0.0)
    assert torque == (0.0, 0.0, 0.0)
    assert force[1] == 0.0 and force[2] == 0.0


def _oblique_pair(first, second, order):
    """Two spheres of different materials meeting obliquely and sliding; order (0, 1) or
    (1, 0) says which one is particle 0."""
    position = np.array([[0.0, 0.0, 0.0], [1.89e-3, 0.1e-3, 0.0]])   # overlapping 7 um
    velocity = np.array([[0.5, -2.0, 0.1], [-0.5, 2.0, 0.0]])
    spin = np.array([[0.0, 0.0, 300.0], [10.0, 0.0, -100.0]])
    radius = np.array([1e-3, 0.9e-3])
    index = list(order)
    model, state = make_system(position[index], radius=radius[index],
                               material=[first, second], material_index=index,
                               velocity=velocity[index], angular_velocity=spin[index])
    contact = bondem.ContactSettings("hertz_mindlin")
    return Simulation(model, state, time_step=1e-8, contact=contact), state


def test_swapping_the_materials_of_a_contact_mirrors_the_loads():
    """The same two spheres numbered the other way round: each sphere's motion is the
    same, so friction, restitution and stiffness come from the pair, not from particle i."""
    sticky = Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.2,
                      restitution=0.3, friction=0.9, rolling_friction=0.05)
    slick = Material(density=7800.0, young_modulus=3e8, poisson_ratio=0.35,
                     restitution=0.8, friction=0.1, rolling_friction=0.01)
    a, state_a = _oblique_pair(sticky, slick, (0, 1))
    b, state_b = _oblique_pair(sticky, slick, (1, 0))
    a.step(400)
    b.step(400)
    assert a.contacts.touching()[0] == 1
    for name in ("position", "velocity", "angular_velocity"):
        np.testing.assert_allclose(getattr(state_b, name)[::-1], getattr(state_a, name),
                                   rtol=1e-9, atol=1e-15)
    # the sliding really happened: the tangential speeds changed by friction
    assert abs(state_a.velocity[0, 1] + 2.0) > 1e-3


def test_local_damping_of_moments_opposes_the_spin():
    """Constant moment M along +w on a sphere moving along -x: with damping d the spin
    grows at (1 - d) M / I, whatever the sign of v (w_n+1/2 = w_0 + (1-d) M/I t_n+1/2)."""
    d, dt, moment = 0.4, 1e-5, 1e-9
    model, state = make_system(np.zeros((1, 3)), radius=1e-3, material=GLASS,
                               velocity=[[-1.0, -1.0, -1.0]],
                               angular_velocity=[[2.0, 2.0, 2.0]],
                               external_moment=[[moment, moment, moment]], damping=d)
    sim = Simulation(model, state, time_step=dt)
    sim.step(50)
    t_half = (50 - 0.5) * dt
    expected = 2.0 + (1 - d) * moment / model.inertia[0] * t_half
    np.testing.assert_allclose(state.angular_velocity[0], expected, rtol=1e-12)
    np.testing.assert_allclose(state.velocity[0], -1.0, rtol=0)


@pytest.mark.parametrize("order", [(0, 1), (1, 0)])
def test_bond_across_a_periodic_boundary_at_rest_carries_no_force(order):
    """Two spheres at x = 0.5 mm and x = L - 1.5 mm of a periodic box of L = 10 mm are
    2 mm apart through the boundary; bonded at rest they must stay at rest."""
    length = 10e-3
    position = np.array([[0.5e-3, 5e-3, 5e-3], [length - 1.5e-3, 5e-3, 5e-3]])
    binder = BondMaterial(young_modulus=1e8, poisson_ratio=0.3)
    model, state = make_system(position, radius=1e-3, material=GLASS, bonds=[list(order)],
                               bond_diameter=1e-3, bond_material=binder,
                               periodic=[True, False, False], box_low=[0.0, 0.0, 0.0],
                               box_high=[length, length, length])
    assert model.bond_initial_length[0] == pytest.approx(2e-3, rel=1e-12)
    sim = Simulation(model, state, time_step=1e-7)
    sim.step(20)
    np.testing.assert_allclose(state.position, position, rtol=0, atol=1e-18)
    assert np.all(state.velocity == 0.0)
    assert state.bond_active.all()


def test_stored_shear_force_turns_with_a_pair_spinning_about_its_axis():
    """A pair on the x axis spinning rigidly at w about x (both held at that spin) carries
    a stored F_t along y: F_t must turn with the pair, by w t about +x, where t is the time
    of the last evaluation (a rigid motion changes nothing else)."""
    w, dt = 200.0, 1e-5
    binder = BondMaterial(young_modulus=1e8, poisson_ratio=0.3)
    model, state = make_system(np.array([[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0]]), radius=1e-3,
                               material=GLASS, angular_velocity=[[w, 0, 0], [w, 0, 0]],
                               fixed=[True, True], bonds=[[0, 1]], bond_diameter=1e-3,
                               bond_material=binder)
    state.bond_tangential_force[0] = [0.0, 1e-3, 0.0]
    sim = Simulation(model, state, time_step=dt)
    steps = 300
    sim.step(steps)
    angle = w * (steps - 1) * dt        # the first evaluation, at t = 0, turns nothing
    expected = 1e-3 * np.array([0.0, np.cos(angle), np.sin(angle)])
    np.testing.assert_allclose(state.bond_tangential_force[0], expected, rtol=0, atol=1e-12)


def test_combined_criterion_breaks_on_the_summed_stress():
    """Ends held apart at u and spun oppositely about z at w: the axial stress
    E u t / L0 and the bending stress |M_t| R / I = 2 E R w t / L0 both grow linearly with
    the evaluation time t; the bond breaks at the first evaluation where their sum
    reaches sigma_max (set halfway between evaluations 39 and 40), not where the larger
    alone does (evaluation 79)."""
    young, length, radius_b, dt = 1e8, 2e-3, 0.5e-3, 1e-6
    u, w = 0.02, 20.0                   # u = 2 R w: both stresses equal
    rate = young * (u + 2 * radius_b * w) / length      # Pa/s of the summed stress
    strength = rate * 39.5 * dt
    binder = BondMaterial(young_modulus=young, poisson_ratio=0.3, normal_strength=strength,
                          tangential_strength=1e30, breakage="combined")
    model, state = make_system(np.array([[0.0, 0.0, 0.0], [length, 0.0, 0.0]]), radius=1e-3,
                               material=GLASS, velocity=[[-u / 2, 0, 0], [u / 2, 0, 0]],
                               angular_velocity=[[0, 0, w], [0, 0, -w]], fixed=[True, True],
                               bonds=[[0, 1]], bond_diameter=2 * radius_b,
                               bond_material=binder)
    sim = Simulation(model, state, time_step=dt)
    sim.step(100)
    assert not state.bond_active[0]
    assert state.bond_break_time[0] == pytest.approx(40 * dt, rel=1e-9)
    assert state.bond_break_mode[0] == 1   # tension

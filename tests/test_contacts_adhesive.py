"""Adhesive contacts (JKR, van der Waals, liquid bridge) against their closed forms.

Every expected value is derived here from the theory, not from the code: JKR's pull-off
force 3/2 pi w R* (load control) and separation 3/4 (pi^2 w^2 R*/E*^2)^(1/3), its contact
radius at zero load (9 pi w R*^2 / (2 E*))^(1/3) and its force-overlap curve (the pair
(a, delta) of the theory, parametrised by a); Hamaker's A R* / (6 h^2); a liquid bridge's
2 pi R* gamma cos(theta) at contact and Lian et al.'s rupture distance (1 + theta/2)
V^(1/3). Unlike spheres and mixed materials keep the tests off symmetric points.
"""
import math

import numpy as np
import pytest

import bondem
from bondem.contacts import ContactSettings
from bondem.physics import contact_jkr, contact_liquid
from bondem.walls import PlaneWall

E, NU = 1e8, 0.28


def approx(expected, rel, abs=0.0):
    """pytest.approx without its default absolute tolerance of 1e-12, which would pass
    any of the micro-newton forces and femtojoule energies here."""
    return pytest.approx(expected, rel=rel, abs=abs)


def material(name="a", restitution=0.4, **keys):
    return bondem.Material(density=2500.0, young_modulus=E, poisson_ratio=NU,
                           restitution=restitution, friction=0.3, name=name, **keys)


def e_star_of(*materials):
    return 1.0 / sum((1 - m.poisson_ratio ** 2) / m.young_modulus for m in materials)


# -- JKR: the law alone --------------------------------------------------------------------

def jkr_overlap(a, r_star, e_star, w):
    """The theory's overlap (m) at contact radius a (m)."""
    return a * a / r_star - math.sqrt(2 * math.pi * w * a / e_star)


def jkr_theory_force(a, r_star, e_star, w):
    return 4 * e_star * a ** 3 / (3 * r_star) - math.sqrt(8 * math.pi * w * e_star * a ** 3)


@pytest.mark.parametrize("w", [0.02, 0.3])
def test_jkr_curve_pull_off_and_zero_load_radius(w):
    r_star, e_star = 3.7e-6, 5.3e7
    a_c = (math.pi * w * r_star ** 2 / (8 * e_star)) ** (1 / 3)
    # the stable branch, from the pull-off point to a large load: the code's a(delta)
    # inverts the theory's delta(a), and its force is the theory's
    for a in a_c * np.array([1.02, 1.3, 2.0, 5.0, 40.0]):
        delta = jkr_overlap(a, r_star, e_star, w)
        found = contact_jkr.jkr_contact_radius(delta, r_star, e_star, w)
        assert found == approx(a, rel=1e-9)
        assert contact_jkr.jkr_force(found, r_star, e_star, w) == approx(
            jkr_theory_force(a, r_star, e_star, w), rel=1e-8, abs=1e-12 * w * r_star)
    # load control: the least force over the branch is -3/2 pi w R*
    overlaps = np.linspace(jkr_overlap(a_c, r_star, e_star, w), 5 * a_c ** 2 / r_star, 4001)
    forces = [contact_jkr.jkr_force(contact_jkr.jkr_contact_radius(d, r_star, e_star, w),
                                    r_star, e_star, w) for d in overlaps]
    assert min(forces) == approx(-1.5 * math.pi * w * r_star, rel=0.01)
    # displacement control: the neck breaks at delta_c with -5/6 pi w R*
    pair = np.zeros((1, 7))
    pair[0, 0], pair[0, 6] = e_star, w
    delta_c = 0.75 * (math.pi ** 2 * w ** 2 * r_star / e_star ** 2) ** (1 / 3)
    assert contact_jkr.jkr_pull_off_gap(pair, 0, r_star) == approx(delta_c, rel=1e-12)
    tip = contact_jkr.jkr_contact_radius(-delta_c * (1 - 1e-9), r_star, e_star, w)
    assert contact_jkr.jkr_force(tip, r_star, e_star, w) == approx(
        -5 / 6 * math.pi * w * r_star, rel=1e-3)
    # zero load: a_0 = (9 pi w R*^2 / (2 E*))^(1/3), at the overlap a_0^2 / (3 R*)
    a_0 = (9 * math.pi * w * r_star ** 2 / (2 * e_star)) ** (1 / 3)
    found = contact_jkr.jkr_contact_radius(a_0 ** 2 / (3 * r_star), r_star, e_star, w)
    assert found == approx(a_0, rel=1e-9)
    assert abs(contact_jkr.jkr_force(found, r_star, e_star, w)) < 1e-9 * w * r_star


def test_jkr_radius_at_and_beyond_the_tip_is_the_pull_off_radius():
    """At the pull-off point, delta = -delta_c, and beyond it (the neck breaks there; the
    law's value is the tip's) the contact radius is a_c = (pi w R*^2 / (8 E*))^(1/3)."""
    r_star, e_star, w = 4.3e-6, 6.1e7, 0.07
    a_c = (math.pi * w * r_star ** 2 / (8 * e_star)) ** (1 / 3)
    delta_c = 0.75 * (math.pi ** 2 * w ** 2 * r_star / e_star ** 2) ** (1 / 3)
    for delta in (-1.01 * delta_c, -2.0 * delta_c):
        assert contact_jkr.jkr_contact_radius(delta, r_star, e_star, w) == approx(
            a_c, rel=1e-12)
    assert contact_jkr.jkr_contact_radius(-delta_c, r_star, e_star, w) == approx(
        a_c, rel=1e-6)


def test_jkr_potential_is_the_integral_of_its_force_and_zero_at_pull_off():
    r_star, e_star, w = 2.1e-6, 7.7e7, 0.11
    delta_c = 0.75 * (math.pi ** 2 * w ** 2 * r_star / e_star ** 2) ** (1 / 3)

    def u(delta):
        return contact_jkr.jkr_potential(
            contact_jkr.jkr_contact_radius(delta, r_star, e_star, w), r_star, e_star, w)

    def f(delta):
        return contact_jkr.jkr_force(
            contact_jkr.jkr_contact_radius(delta, r_star, e_star, w), r_star, e_star, w)

    tip = -delta_c * (1 - 1e-12)
    assert abs(u(tip)) < 1e-6 * math.pi * w * r_star * delta_c
    # a Simpson integral of the force from the tip matches the potential
    for end in (-0.5 * delta_c, 0.0, 3 * delta_c):
        x = np.linspace(tip, end, 2001)
        y = np.array([f(d) for d in x])
        integral = (x[1] - x[0]) / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())
        assert u(end) == approx(integral, rel=2e-4, abs=1e-4 * abs(integral) + 1e-30)


def test_jkr_without_adhesion_is_hertz():
    r_star, e_star = 1e-3, 5e7
    for delta in (1e-7, 3e-6, 2e-5):
        a = contact_jkr.jkr_contact_radius(delta, r_star, e_star, 0.0)
        assert a == approx(math.sqrt(r_star * delta), rel=1e-12)
        assert contact_jkr.jkr_force(a, r_star, e_star, 0.0) == approx(
            4 / 3 * e_star * math.sqrt(r_star) * delta ** 1.5, rel=1e-11)


# -- JKR in the simulator --------------------------------------------------------------------

def test_jkr_pull_off_force_under_a_constant_load():
    """A sphere held by JKR adhesion to a clamped one, pulled away by a constant force
    and started at the theory's equilibrium for 0.99 of 3/2 pi w R* (on the stable branch,
    between the pull-off point and zero load): with 0.99 it stays there; with 1.01, beyond
    the pull-off force, no equilibrium is left and it lets go (w = sqrt(w_a w_b), R* of
    two unlike radii)."""
    from scipy.optimize import brentq
    a = material("a", surface_energy=0.09)
    b = material("b", surface_energy=0.04)
    r_a, r_b = 4e-6, 7e-6
    w = math.sqrt(0.09 * 0.04)
    r_star = r_a * r_b / (r_a + r_b)
    e_star = e_star_of(a, b)
    f_c = 1.5 * math.pi * w * r_star
    a_weakest = (9 * math.pi * w * r_star ** 2 / (8 * e_star)) ** (1 / 3)   # F = -F_c
    a_0 = (9 * math.pi * w * r_star ** 2 / (2 * e_star)) ** (1 / 3)         # F = 0
    a_held = brentq(lambda x: jkr_theory_force(x, r_star, e_star, w) + 0.99 * f_c,
                    a_weakest, a_0, xtol=1e-20, rtol=1e-15)
    overlap = jkr_overlap(a_held, r_star, e_star, w)
    delta_c = 0.75 * (math.pi ** 2 * w ** 2 * r_star / e_star ** 2) ** (1 / 3)
    gaps = {}
    for factor in (0.99, 1.01):
        # touching at zero load first (the neck forms), then moved to the equilibrium
        model, state = bondem.make_system(
            [[0, 0, 0], [r_a + r_b - a_0 ** 2 / (3 * r_star), 0, 0]], [r_a, r_b], [a, b],
            material_index=[0, 1], fixed=[True, False])
        sim = bondem.Simulation(model, state, contact=ContactSettings(model="jkr"),
                                safety_factor=0.2)
        sim.step(1)
        state.position[1, 0] = r_a + r_b - overlap
        state.velocity[1] = 0.0
        model.external_force[1, 0] = factor * f_c
        sim.step(3000)
        gaps[factor] = state.position[1, 0] - r_a - r_b
    assert gaps[0.99] == approx(-overlap, rel=1e-6)      # held where the theory says:
    assert 0.0 < gaps[0.99] < delta_c                            # beyond contact, necked
    assert gaps[1.01] > 10 * delta_c                             # gone


def test_jkr_hysteresis_touch_to_form_pull_off_gap_to_break():
    """Approaching surfaces feel nothing before they touch; once touched the neck holds
    beyond contact, to the pull-off gap."""
    m = material(surface_energy=0.2)
    r = 5e-6
    model, state = bondem.make_system([[0, 0, 0], [2 * r + 2e-8, 0, 0]], r, m,
                                      velocity=[[0, 0, 0], [-0.002, 0, 0]],
                                      fixed=[True, False])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="jkr"),
                            safety_factor=0.05)
    # approach: no force while apart, although within the pull-off gap
    delta_c = 0.75 * (math.pi ** 2 * 0.2 ** 2 * (r / 2) / e_star_of(m, m) ** 2) ** (1 / 3)
    assert 2e-8 < delta_c
    touched = False
    for _ in range(20000):
        sim.step(1)
        gap = state.position[1, 0] - 2 * r
        force = state.extra["contact_force"]
        if gap > 0:
            assert touched or not np.any(force != 0.0)
        else:
            touched = True
            break
    assert touched
    # it sticks (the impact is far too slow to bounce off)
    sim.step(20000)
    assert state.position[1, 0] - 2 * r < 0.0
    assert abs(state.velocity[1, 0]) < 1e-4


def test_jkr_energy_balance_closes_with_the_adhesion_booked():
    """A sticking JKR impact: stored + dissipated = the initial kinetic energy (the snap-in
    and the hysteresis booked as dissipated, never negative)."""
    m = material(surface_energy=0.15)
    r = 3e-6
    model, state = bondem.make_system([[0, 0, 0], [2 * r + 1e-9, 0, 0]], r, m,
                                      velocity=[[0.01, 0, 0], [-0.01, 0, 0]])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="jkr"),
                            safety_factor=0.05)
    before = sum(sim.kinetic_energy())
    sim.step(3000)
    terms = sim.energy_terms()
    stored = terms["kinetic_translational"] + terms["kinetic_rotational"] + terms["contact_elastic"]
    assert terms["dissipated_contacts"] > 0
    assert stored + terms["dissipated_contacts"] == approx(before, rel=1e-3)
    assert terms["contact_elastic"] < 0   # bound in the adhesive well


# -- van der Waals ---------------------------------------------------------------------------

@pytest.mark.parametrize("gap", [2e-9, 1.3e-8])
def test_van_der_waals_force_against_separation(gap):
    """Two unlike clamped spheres a gap h apart: each feels A R* / (6 h^2) towards the
    other, A = sqrt(A_a A_b); beyond the cut-off nothing."""
    a = material("a", hamaker_constant=4e-20, vdw_cutoff=5e-8)
    b = material("b", hamaker_constant=9e-20, vdw_cutoff=5e-8)
    r_a, r_b = 3e-6, 8e-6
    model, state = bondem.make_system([[0, 0, 0], [r_a + r_b + gap, 0, 0]], [r_a, r_b],
                                      [a, b], material_index=[0, 1], fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="vdw"),
                            safety_factor=0.1)
    sim.step(1)
    r_star = r_a * r_b / (r_a + r_b)
    expected = math.sqrt(4e-20 * 9e-20) * r_star / (6 * gap ** 2)
    force = state.extra["contact_force"][0]      # on particle 0, towards particle 1: +x
    assert force[0] == approx(expected, rel=1e-9)
    assert force[1] == 0.0 and force[2] == 0.0
    # the potential's derivative is the force
    assert state.extra["contact_energy"][0] == approx(
        -math.sqrt(4e-20 * 9e-20) * r_star / 6 * (1 / gap - 1 / 5e-8), rel=1e-9)


def test_van_der_waals_beyond_its_cut_off_and_in_contact():
    a = material("a", hamaker_constant=1e-19, vdw_cutoff=2e-8, vdw_min_distance=3e-10)
    r = 2e-6
    model, state = bondem.make_system([[0, 0, 0], [2 * r + 2.5e-8, 0, 0]], r, a,
                                      fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="vdw"))
    sim.step(1)
    assert not np.any(state.extra["contact_force"] != 0.0)
    # in contact the force saturates: Hertz's push minus A R* / (6 h_0^2)
    overlap = 1e-9
    model, state = bondem.make_system([[0, 0, 0], [2 * r - overlap, 0, 0]], r, a,
                                      fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="vdw"))
    sim.step(1)
    e_star = e_star_of(a, a)
    hertz = 4 / 3 * e_star * math.sqrt(r / 2) * overlap ** 1.5
    pull = 1e-19 * (r / 2) / (6 * 3e-10 ** 2)
    assert state.extra["contact_force"][0, 0] == approx(pull - hertz, rel=1e-9)


def test_van_der_waals_towards_a_wall():
    """A plane is a sphere of infinite radius: A r / (6 h^2)."""
    a = material("a", hamaker_constant=6e-20, vdw_cutoff=4e-8)
    r, gap = 5e-6, 7e-9
    model, state = bondem.make_system([[0, 0, r + gap]], r, a, fixed=[True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="vdw"),
                            walls=[PlaneWall([0, 0, 0], [0, 0, 1], a)])
    sim.step(1)
    assert state.extra["wall_force_rows"][0, 2] == approx(
        -6e-20 * r / (6 * gap ** 2), rel=1e-9)


# -- liquid bridge ---------------------------------------------------------------------------

def test_liquid_bridge_force_at_contact_and_rupture_distance():
    """A bridge formed at contact pulls with 2 pi R* gamma cos(theta) there; pulled apart
    at constant speed it follows Rabinovich's meniscus force and breaks at (1 + theta/2)
    V^(1/3) (theta in rad)."""
    gamma, theta, volume = 0.072, 25.0, 3e-18
    # no damping (e = 1): the Hertz force at a separating contact is elastic only
    a = material("a", 1.0, surface_tension=gamma, contact_angle=theta, bridge_volume=volume)
    r_a, r_b = 6e-6, 9e-6
    r_star = r_a * r_b / (r_a + r_b)
    speed = 0.01
    model, state = bondem.make_system([[0, 0, 0], [r_a + r_b - 1e-10, 0, 0]], [r_a, r_b], a,
                                      velocity=[[0, 0, 0], [speed, 0, 0]], fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="liquid_bridge"),
                            safety_factor=0.2)
    f_0 = 2 * math.pi * r_star * gamma * math.cos(math.radians(theta))
    sim.step(1)
    hertz = 4 / 3 * e_star_of(a, a) * math.sqrt(r_star) * 1e-10 ** 1.5
    assert state.extra["contact_force"][0, 0] == approx(f_0 - hertz, rel=1e-9)
    rupture = (1 + math.radians(theta) / 2) * volume ** (1 / 3)
    c = 2 * volume / (math.pi * r_star)
    last_gap = None
    checked = 0
    while True:
        gap = state.position[1, 0] - r_a - r_b    # where the step evaluates the force
        sim.step(1)
        force = state.extra["contact_force"][0, 0]
        if force == 0.0:
            break
        last_gap = gap
        if checked < 5 and gap > 0.2 * rupture * (checked + 1) / 5:
            assert force == approx(f_0 * (1 - gap / math.sqrt(gap * gap + c)), rel=1e-9)
            checked += 1
    assert checked == 5
    step = speed * sim.time_step
    assert last_gap < rupture <= gap + step


def test_liquid_bridge_lubrication_resists_separation_and_sets_the_step():
    """A wet bridge (no surface tension) pulled apart at constant speed v: the film pulls
    back with Reynolds' 6 pi eta R*^2 v / s at gaps beyond s_min; its dashpot m* s_min /
    (6 pi eta R*^2) of the lightest self-pair is one of the automatic step's limits."""
    eta, s_min, speed = 0.05, 2e-8, 1.0
    a = material("a", 1.0, viscosity=eta, bridge_volume=1e-17, bridge_min_gap=s_min)
    r_a, r_b = 5e-6, 8e-6
    r_star = r_a * r_b / (r_a + r_b)
    model, state = bondem.make_system([[0, 0, 0], [r_a + r_b - 1e-11, 0, 0]], [r_a, r_b], a,
                                      velocity=[[0, 0, 0], [speed, 0, 0]], fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="liquid_bridge"))
    m_star = 0.5 * model.mass[0]
    assert sim.time_step_cause == "liquid_viscous"
    assert sim.time_step == approx(
        0.2 * m_star * s_min / (6 * math.pi * eta * (r_a / 2) ** 2), rel=1e-12)
    checked = 0
    while checked < 3:
        gap = state.position[1, 0] - r_a - r_b
        sim.step(1)
        if gap > s_min * (2 + 4 * checked):
            assert state.extra["contact_force"][0, 0] == approx(
                6 * math.pi * eta * r_star ** 2 * speed / gap, rel=1e-9)
            checked += 1


def test_popov_jkr_pulled_apart_follows_its_curve_to_the_pull_off_force():
    """Popov's JKR, two unlike spheres pulled apart at constant speed from contact: the
    force at the touch is -0.88 F_A, the least force -F_A = -3/2 pi w R* (JKR's pull-off
    force), reached where the neck breaks, at the gap S = (0.4626 (w/E*)^2 R*)^(1/3); the
    potential is the integral of the force (Simpson) from that point."""
    from bondem.physics import contact_popov
    a = material("a", 1.0, surface_energy=0.2)
    b = material("b", 1.0, surface_energy=0.05)
    r_a, r_b = 3e-6, 5e-6
    w = math.sqrt(0.2 * 0.05)
    r_star = r_a * r_b / (r_a + r_b)
    e_star = e_star_of(a, b)
    f_a = 1.5 * math.pi * w * r_star
    s = (0.4626 * (w / e_star) ** 2 * r_star) ** (1 / 3)
    speed = 1e-3
    model, state = bondem.make_system([[0, 0, 0], [r_a + r_b - 1e-12, 0, 0]], [r_a, r_b],
                                      [a, b], material_index=[0, 1],
                                      velocity=[[0, 0, 0], [speed, 0, 0]], fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="popov_jkr"))
    sim.time_step = s / speed / 400
    forces, gaps = [], []
    while True:
        gap = state.position[1, 0] - r_a - r_b
        sim.step(1)
        force = -state.extra["contact_force"][0, 0]     # on 1 along +x: repulsive > 0
        if force == 0.0:
            break
        forces.append(force)
        gaps.append(gap)
    assert forces[0] == approx(-0.88 * f_a, rel=1e-4)   # at an overlap of 1e-12 m
    assert min(forces) == approx(-f_a, rel=1e-4)
    assert s - speed * sim.time_step <= gaps[-1] < s
    x = np.linspace(-s, 0.0, 2001)
    y = np.array([contact_popov.popov_force(d, w, e_star, r_star)[0] for d in x])
    integral = (x[1] - x[0]) / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())
    assert contact_popov.popov_force(0.0, w, e_star, r_star)[1] == approx(integral,
                                                                                   rel=1e-6)


def test_a_jkr_neck_longer_than_the_skin_is_not_lost():
    """The neighbour lists reach the pull-off gap beyond the skin (LAMMPS's issue 4685:
    necks lost beyond the neighbour cut-off): with a skin of a thousandth of delta_c, a
    pair pulled apart slowly still lets go at delta_c."""
    m = material(surface_energy=0.3)
    r = 4e-6
    e_star = e_star_of(m, m)
    w, r_star = 0.3, r / 2
    delta_c = 0.75 * (math.pi ** 2 * w ** 2 * r_star / e_star ** 2) ** (1 / 3)
    speed = 1e-3
    model, state = bondem.make_system([[0, 0, 0], [2 * r - 1e-9, 0, 0]], r, m,
                                      velocity=[[0, 0, 0], [speed, 0, 0]], fixed=[True, True])
    sim = bondem.Simulation(model, state,
                            contact=ContactSettings(model="jkr", skin=1e-3 * delta_c))
    sim.time_step = delta_c / speed / 300
    last = None
    while True:
        gap = state.position[1, 0] - 2 * r
        sim.step(1)
        if state.extra["contact_force"].shape[0] == 0 or \
                not np.any(state.extra["contact_force"] != 0.0):
            break
        last = gap
    assert last is not None and delta_c - 2 * speed * sim.time_step < last < delta_c
    assert state.extra["contact_counters"][2] > 10      # the lists were rebuilt on the way


def test_jkr_contact_at_zero_load_resists_sliding_with_its_pull_off_force():
    """An adhesive contact slides only at mu (F_n + 2 F_c), F_c = 3/2 pi w R* (Thornton &
    Yin; LAMMPS's granular jkr): two unlike spheres held at JKR's zero-load overlap, one
    driven sideways at constant speed, the tangential force rises and stays at
    mu x 3 pi w R* (F_n = 0), with mu the mean of the two frictions."""
    a = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.28,
                        restitution=1.0, friction=0.2, surface_energy=0.09, name="a")
    b = bondem.Material(density=2500.0, young_modulus=2e8, poisson_ratio=0.22,
                        restitution=1.0, friction=0.5, surface_energy=0.04, name="b")
    r_a, r_b = 4e-6, 7e-6
    w = math.sqrt(0.09 * 0.04)
    r_star = r_a * r_b / (r_a + r_b)
    e_star = e_star_of(a, b)
    a_0 = (9 * math.pi * w * r_star ** 2 / (2 * e_star)) ** (1 / 3)
    model, state = bondem.make_system(
        [[0, 0, 0], [r_a + r_b - a_0 ** 2 / (3 * r_star), 0, 0]], [r_a, r_b], [a, b],
        material_index=[0, 1], velocity=[[0, 0, 0], [0, 1e-3, 0]], fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="jkr"),
                            safety_factor=0.1)
    sim.step(4000)
    force = state.extra["contact_force"][0]              # on sphere 0
    # the normal where the last step evaluated the force (before its drift)
    centre = state.position[1] - state.velocity[1] * sim.time_step - state.position[0]
    n = centre / np.linalg.norm(centre)
    normal = -float(force @ n)                           # repulsive > 0
    tangential = np.linalg.norm(force + normal * n)
    assert abs(normal) < 0.01 * 1.5 * math.pi * w * r_star      # about zero load
    assert tangential == approx(0.35 * (normal + 3 * math.pi * w * r_star), rel=1e-9)


def test_the_bridge_potential_is_the_integral_of_its_force_and_zero_at_rupture():
    """U(gap) = -(integral of the attraction from gap to the rupture distance): zero at
    rupture, and dU/dgap the attraction (Rabinovich's, f_0 at contact)."""
    f_0, c = 2.3e-5, 4.1e-12            # N, m^2 (a bridge of 2 V / (pi R*))
    rupture = 3.0e-6                    # m
    assert contact_liquid.capillary_potential(rupture, f_0, c, rupture) == 0.0
    h = 1e-10
    for gap in (-2e-7, 0.4e-6, 1.7e-6, 2.9e-6):
        slope = (contact_liquid.capillary_potential(gap + h, f_0, c, rupture)
                 - contact_liquid.capillary_potential(gap - h, f_0, c, rupture)) / (2 * h)
        assert slope == approx(contact_liquid.capillary_force(gap, f_0, c), rel=1e-5)
    assert contact_liquid.capillary_force(-1e-7, f_0, c) == f_0


def test_a_bridge_between_two_liquids_takes_the_mean_angle_and_volume():
    """The pair table's bridge columns for two materials (20 and 40 degrees, 1e-18 and
    3e-18 m^3): the means, then the constants the law reads, cos 30 degrees = sqrt(3)/2
    and the rupture distance (1 + pi/12) (2e-18)^(1/3) = 1.58977 um."""
    from bondem.physics import contact_models
    wet = dict(surface_tension=0.07, viscosity=1e-3, bridge_min_gap=1e-7)
    first = dict(wet, contact_angle=20.0, bridge_volume=1e-18)
    second = dict(wet, contact_angle=40.0, bridge_volume=3e-18)
    columns = contact_models.pair_parameters(contact_liquid, first, second)
    assert contact_models.pair_columns(contact_liquid) == len(columns) == 7
    names = list(contact_liquid.PARAMETERS) + list(contact_liquid.CONSTANTS)
    table = dict(zip(names, columns))
    assert table["contact_angle"] == approx(30.0, rel=1e-15)
    assert table["bridge_volume"] == approx(2e-18, rel=1e-15)
    assert table["cos_angle"] == approx(math.sqrt(3) / 2, rel=1e-15)
    assert table["rupture_distance"] == approx(1.58977e-6, rel=1e-5)
    assert table["rupture_distance"] == approx((1 + math.pi / 12) * 2e-18 ** (1 / 3),
                                               rel=1e-14)
    dry = contact_models.pair_parameters(contact_liquid, dict(first, bridge_volume=0.0),
                                         dict(second, bridge_volume=0.0))
    assert dry[-1] == 0.0


def test_a_jkr_pair_of_two_materials_reads_k_from_the_pair_table():
    """The pair table of two JKR materials (w = 0.02 and 0.08 J/m^2; E 1e8 and 3e8 Pa,
    nu 0.2 and 0.35): w mixed geometrically (0.04), then k = sqrt(2 pi w / E*) with the
    pair's own E* = 1 / ((1 - nu_1^2) / E_1 + (1 - nu_2^2) / E_2); a row of it built by
    the backends' table maker holds the same."""
    from bondem.backends.loops import contact_materials
    from bondem.physics import contact_models
    e_star = 1.0 / ((1 - 0.2 ** 2) / 1e8 + (1 - 0.35 ** 2) / 3e8)
    columns = contact_models.pair_parameters(contact_jkr, {"surface_energy": 0.02},
                                             {"surface_energy": 0.08}, e_star)
    assert contact_models.pair_columns(contact_jkr) == len(columns) == 2
    assert columns[0] == approx(0.04, rel=1e-15)
    assert columns[1] == approx(math.sqrt(2 * math.pi * 0.04 / e_star), rel=1e-15)
    table = contact_materials([1e8, 3e8], [0.2, 0.35], [0.5, 0.5], [0.3, 0.3], [0.0, 0.0],
                              model=contact_jkr, parameters=[{"surface_energy": 0.02},
                                                             {"surface_energy": 0.08}])
    row = table.pair[1]                                   # material 0 against material 1
    assert row[contact_jkr.ADHESION_K] == approx(columns[1], rel=1e-14)
    assert table.pair[0][contact_jkr.ADHESION_K] == approx(
        math.sqrt(2 * math.pi * 0.02 / (1e8 / (2 * (1 - 0.2 ** 2)))), rel=1e-14)

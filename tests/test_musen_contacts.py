"""MUSEN-compatible Hertz-Mindlin contacts (physics/contact_hertz_musen.py, musen_compat).

References, none of them a transcription of the code under test:
- Hertz (1882): a contact at rest carries f_n = 4/3 E* sqrt(R*) delta^(3/2), with
  E* = E / (2 (1 - nu^2)) for two equal materials; the restitution damping returns e.
- MUSEN's documented behaviours (docs/musen_compat.md, "Contacts"), each checked on a
  configuration where it differs from the SPEC's law: the full radius as lever arm, the
  previous step's tangential force while sliding, the slip test on the spring force alone,
  rolling friction against each particle's own spin, and the wall's normal force scaled
  by |n_rc . n_wall| on an edge.
- Runs of the real MUSEN 1.70.0 made for this (src/bondem/data/validation/musen-runs:
  contacts, moving_wall; impact in bondem validate): to round-off in compat mode.
"""
import math
from pathlib import Path

import numpy as np
import pytest

import bondem
from bondem.backends.cpu_contacts import ContactLaw
from bondem.physics.contact_hertz import contact_moments, hertz_mindlin, restitution_beta
from bondem.physics.contact_hertz_musen import (MUSEN_1_70, MUSEN_1_74,
                                                hertz_mindlin_musen_pp,
                                                hertz_mindlin_musen_pw, musen_alpha,
                                                musen_shear_modulus)
from bondem.validation import refdata

E, NU = 1e8, 0.3
E_STAR = E / (2.0 * (1.0 - NU * NU))          # Pa, two equal materials
G_STAR = musen_shear_modulus(E, NU, E, NU)
RUNS = Path(bondem.__file__).parent / "data" / "validation" / "musen-runs"


def pp(cv, overlap, r_i=1e-3, r_j=1e-3, vi=(0, 0, 0), vj=(0, 0, 0), wi=(0, 0, 0),
       wj=(0, 0, 0), xi=(0, 0, 0), f_t_prev=(0, 0, 0), restitution=0.5, friction=0.3,
       rolling=0.0, dt=1e-7, mass=1e-5, version=MUSEN_1_70):
    """MUSEN's particle-particle law for two equal materials, as plain Python (1.70.0's
    unless ``version`` says otherwise)."""
    return hertz_mindlin_musen_pp(
        cv, overlap, r_i, r_j, vi, vj, wi, wj, xi, f_t_prev, E_STAR, G_STAR,
        musen_alpha(restitution), friction, rolling, r_i * r_j / (r_i + r_j), mass / 2, dt,
        version, 0, 0.0)


def test_a_contact_at_rest_carries_the_hertz_force():
    r, delta = 1e-3, 1e-5
    force, m_i, m_j, xi, f_t, energy = pp((2 * r - delta, 0.0, 0.0), delta)
    hertz = 4.0 / 3.0 * E_STAR * math.sqrt(r / 2) * delta ** 1.5
    assert force[0] == pytest.approx(-hertz, rel=1e-13)          # pushes i away from j
    assert force[1] == force[2] == 0.0 and f_t == (0.0, 0.0, 0.0)
    assert energy == pytest.approx(0.4 * hertz * delta, rel=1e-13)  # 8/15 E* sqrt(R) d^2.5
    # a wall: R* = r, m* = m
    x, q = (0.0, 0.0, r - delta), (0.0, 0.0, 0.0)
    force = hertz_mindlin_musen_pw(x, q, (0.0, 0.0, 1.0), r, (0, 0, 0), (0, 0, 0), (0, 0, 0),
                                   (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0), E_STAR,
                                   G_STAR, musen_alpha(0.5), 0.3, 0.0, 1e-5, 1e-7,
                                   MUSEN_1_70, 0, 0.0)[0]
    assert force[2] == pytest.approx(4.0 / 3.0 * E_STAR * math.sqrt(r) * delta ** 1.5,
                                     rel=1e-13)


def test_the_lever_arm_is_the_full_radius():
    """MUSEN: M_i = r_i n x F_t; the SPEC's lever is r_i - delta/2 (0.5 % shorter here)."""
    r_i, r_j, delta = 1e-3, 0.6e-3, 1e-5
    force, m_i, m_j, _, _, _ = pp((r_i + r_j - delta, 0.0, 0.0), delta, r_i, r_j,
                                  vj=(0.0, 0.01, 0.002))
    f_t = np.array(force) - np.array([force[0], 0.0, 0.0])
    assert np.linalg.norm(f_t) > 0.0
    lever = np.cross([1.0, 0.0, 0.0], f_t)
    np.testing.assert_allclose(m_i, r_i * lever, rtol=1e-13, atol=0)
    np.testing.assert_allclose(m_j, r_j * lever, rtol=1e-13, atol=0)
    spec = contact_moments((1.0, 0.0, 0.0), tuple(f_t), (0.0, 0.0, 0.0), r_i - delta / 2,
                           r_j - delta / 2)
    assert abs(np.linalg.norm(spec[0]) / np.linalg.norm(m_i) - 1.0) > 1e-3


def test_while_sliding_the_previous_tangential_force_is_applied():
    """MUSEN keeps vTangForce of the last sticking step while a contact slides; the spring
    is cut back to the Coulomb force."""
    r, delta, friction = 1e-3, 1e-5, 0.3
    previous = (0.0, 1.234e-3, -0.5e-3)
    xi_large = (0.0, 1e-4, 0.0)                       # far beyond the Coulomb limit
    force, _, _, xi, f_t, _ = pp((2 * r - delta, 0.0, 0.0), delta, xi=xi_large,
                                 f_t_prev=previous, friction=friction)
    assert f_t == previous
    assert force[1:] == previous[1:]                  # the tangential part of the force
    f_n = 4.0 / 3.0 * E_STAR * math.sqrt(r / 2) * delta ** 1.5
    k_t = 8.0 * G_STAR * math.sqrt(r / 2 * delta)
    assert k_t * np.linalg.norm(xi) == pytest.approx(friction * f_n, rel=1e-12)
    # the SPEC's law applies the Coulomb force itself
    spec = hertz_mindlin((1.0, 0.0, 0.0), delta, (0, 0, 0), (0, 0, 0), xi_large, E_STAR,
                         G_STAR, r / 2, 5e-6, 1e-12, restitution_beta(0.5), friction, 0.0,
                         1e-7)
    assert np.linalg.norm(spec[2]) == pytest.approx(friction * f_n, rel=1e-12)


def test_the_slip_test_ignores_the_dashpot():
    """Spring force below mu f_n, spring plus dashpot above: MUSEN sticks and applies
    both, more than the Coulomb force; the SPEC's law slides at mu f_n."""
    r, delta, friction = 1e-3, 1e-5, 0.3
    f_n = 4.0 / 3.0 * E_STAR * math.sqrt(r / 2) * delta ** 1.5
    k_t = 8.0 * G_STAR * math.sqrt(r / 2 * delta)
    xi0 = (0.0, 0.9 * friction * f_n / k_t, 0.0)     # 90 % of the limit
    v_t = (0.0, 0.5, 0.0)                             # a fast tangential slip: big dashpot
    force, _, _, xi, f_t, _ = pp((2 * r - delta, 0.0, 0.0), delta, vj=v_t, xi=xi0, dt=1e-12)
    spring = k_t * (xi0[1] + 0.5 * 1e-12)
    assert spring < friction * f_n < abs(f_t[1])
    assert xi[1] == pytest.approx(xi0[1] + 0.5e-12, rel=1e-14)     # not cut back
    assert force[1] == f_t[1]


def test_musen_1_74_slides_at_the_coulomb_force_of_the_damped_normal_force():
    """MUSEN 1.74.2: a sliding contact carries its spring force cut to mu |F_n + F_n,d| (the
    normal force with its dashpot), not the previous step's; the spring is set to it."""
    r, delta, friction, v_n = 1e-3, 1e-5, 0.3, -0.2      # approaching at 0.2 m/s
    previous = (0.0, 1.234e-3, -0.5e-3)
    force, _, _, xi, f_t, _ = pp((2 * r - delta, 0.0, 0.0), delta, vj=(v_n, 0.0, 0.0),
                                 xi=(0.0, 1e-4, 0.0), f_t_prev=previous, friction=friction,
                                 version=MUSEN_1_74)
    f_n = 4.0 / 3.0 * E_STAR * math.sqrt(r / 2) * delta ** 1.5
    k_n = 2.0 * E_STAR * math.sqrt(r / 2 * delta)
    alpha = math.log(0.5) / math.sqrt(math.pi ** 2 + math.log(0.5) ** 2)
    dashpot = 2.0 * math.sqrt(5.0 / 6.0) * alpha * v_n * math.sqrt(k_n * 1e-5 / 2)
    assert dashpot > 0.0                                  # approaching: the dashpot pushes
    coulomb = friction * (f_n + dashpot)
    assert f_t != previous and abs(f_t[2]) < 1e-30
    assert f_t[1] == pytest.approx(coulomb, rel=1e-12)
    assert force[1] == f_t[1] and force[0] == pytest.approx(-(f_n + dashpot), rel=1e-12)
    k_t = 8.0 * G_STAR * math.sqrt(r / 2 * delta)
    assert k_t * xi[1] == pytest.approx(coulomb, rel=1e-12)
    # 1.70.0 keeps the previous force and cuts the spring to the undamped normal force
    old = pp((2 * r - delta, 0.0, 0.0), delta, vj=(v_n, 0.0, 0.0), xi=(0.0, 1e-4, 0.0),
             f_t_prev=previous, friction=friction)
    assert old[4] == previous and k_t * old[3][1] == pytest.approx(friction * f_n, rel=1e-12)


def test_rolling_friction_acts_against_each_particles_own_spin():
    """Two spheres spinning alike (no relative rolling): MUSEN brakes each one by
    mu_r f_n r_k against its own spin; the SPEC's law, on relative rolling, not at all."""
    r_i, r_j, delta, mu_r = 1e-3, 0.5e-3, 1e-5, 0.05
    spin = (0.0, 0.0, 40.0)
    force, m_i, m_j, _, f_t, _ = pp((r_i + r_j - delta, 0.0, 0.0), delta, r_i, r_j, wi=spin,
                                    wj=spin, rolling=mu_r, dt=0.0)
    f_n = 4.0 / 3.0 * E_STAR * math.sqrt(r_i * r_j / (r_i + r_j)) * delta ** 1.5
    lever = np.cross([1.0, 0.0, 0.0], f_t)
    np.testing.assert_allclose(np.array(m_i) - r_i * lever, [0, 0, -mu_r * f_n * r_i],
                               rtol=1e-10)
    np.testing.assert_allclose(np.array(m_j) - r_j * lever, [0, 0, -mu_r * f_n * r_j],
                               rtol=1e-10)


def test_a_wall_edge_scales_the_normal_force_by_the_cosine():
    """An edge contact whose centre line makes 60 degrees with the wall normal: MUSEN
    pushes along the wall normal with half the Hertz force of the overlap."""
    r, delta = 1e-3, 1e-5
    d = r - delta
    x = (d * math.sin(math.pi / 3), 0.0, d * math.cos(math.pi / 3))
    force = hertz_mindlin_musen_pw(x, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), r, (0, 0, 0),
                                   (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0),
                                   (0, 0, 0), E_STAR, G_STAR, musen_alpha(0.5), 0.3, 0.0,
                                   1e-5, 1e-7, MUSEN_1_70, 0, 0.0)[0]
    hertz = 4.0 / 3.0 * E_STAR * math.sqrt(r) * delta ** 1.5
    assert force[2] == pytest.approx(0.5 * hertz, rel=1e-12)
    assert force[0] == force[1] == 0.0


@pytest.mark.parametrize("partner", ["wall", "sphere"])
def test_a_normal_impact_returns_the_restitution(partner):
    """Head-on impact at 0.5 m/s (no gravity, no friction effects): the rebound speed is
    e times the impact speed (Tsuji damping; MUSEN's 1.8257 is 2 sqrt(5/6) to 4e-5)."""
    glass = bondem.Material(density=2500.0, young_modulus=E, poisson_ratio=NU,
                            restitution=0.5)
    if partner == "wall":
        position, velocity = [[0.0, 0.0, 1.01e-3]], [[0.0, 0.0, -0.5]]
        walls = [bondem.PlaneWall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), glass)]
    else:
        position = [[0.0, 0.0, 0.0], [2.02e-3, 0.0, 0.0]]
        velocity = [[0.25, 0.0, 0.0], [-0.25, 0.0, 0.0]]
        walls = []
    model, state = bondem.make_system(np.array(position), 1e-3, glass,
                                      velocity=np.array(velocity))
    sim = bondem.Simulation(model, state, contact=bondem.ContactSettings(),
                            walls=walls, musen_compat=True, time_step=1e-7)
    sim.run(until=2e-4)
    if partner == "wall":
        ratio = sim.state.velocity[0, 2] / 0.5
    else:
        ratio = (sim.state.velocity[1, 0] - sim.state.velocity[0, 0]) / 0.5
    assert ratio == pytest.approx(0.5, rel=5e-3)


def worst_rows(name, compat):
    run = next(r for r in refdata.discover(RUNS) if r.name == name)
    return refdata.compare_run(run, compat, compat_only=True)


@pytest.mark.parametrize("name", ["contacts", "moving_wall", "rotating_wall", "impact",
                                  "contacts_1.74.2", "jkr_cluster", "vdw_cluster",
                                  "popov_cluster"])
def test_real_musen_contact_runs_are_reproduced_to_round_off(name):
    """Positions, velocities and spins in every frame of MUSEN's run (impact: 14 of its 369
    particles, and every bond's break step): in compat mode within 1e-10 of the largest
    value (measured: 6e-15 or less for positions, 2e-11 for velocities, 5e-13 for spins;
    the impact's 220 breaks all in MUSEN's step; the JKR and van der Waals clusters of
    1.74.2's ModelPPJKR / ModelPWJKR, ModelPPHertzMindlinVdW and ModelPPPopovJKR /
    ModelPWPopovJKR 3.4e-16, 3.6e-16 and 8.4e-16 in velocity); SPEC mode parts by far more."""
    rows = worst_rows(name, "musen")
    assert len(rows) >= 3 and all(r.passed for r in rows), [(r.quantity, r.error) for r in rows]
    for row in rows:
        if isinstance(row.error, float):
            assert abs(row.error) < 1e-10, (row.quantity, row.error)
    spec = worst_rows(name, "spec")
    assert max(abs(r.error) for r in spec if isinstance(r.error, float)) > 1e-4


def test_musen_walls_lead_the_particles_by_one_step(monkeypatch):
    """MUSEN moves its walls in its prediction step too: without that lead, the moving
    wall run parts from MUSEN's (the check can fail)."""
    monkeypatch.setattr(ContactLaw, "wall_time", lambda self, state, dt: state.time)
    rows = worst_rows("moving_wall", "musen")
    assert not all(r.passed for r in rows)


def test_musen_walls_stand_still_in_the_prediction_step(monkeypatch):
    """MUSEN sets its walls' motion in its first MoveWalls, after the prediction step's
    loads: a sphere resting on the turning plane at t = 0 feels a still wall then.
    With the wall's spin in that step the rotating-wall run parts from MUSEN's."""
    monkeypatch.setattr(ContactLaw, "_walls_still", lambda self, state: False)
    rows = worst_rows("rotating_wall", "musen")
    assert not all(r.passed for r in rows)


def test_a_linear_law_keeps_bondems_own_numerics_in_compat_mode():
    """MUSEN's linear models are not reproduced: a compat run with the linear law runs
    bondem's linear law (and MUSEN's bonds), it does not fail."""
    glass = bondem.Material(density=2500.0, young_modulus=E, poisson_ratio=NU)
    model, state = bondem.make_system(np.array([[0.0, 0.0, 0.0], [1.99e-3, 0.0, 0.0]]),
                                      1e-3, glass)
    sim = bondem.Simulation(model, state, musen_compat=True, time_step=1e-7,
                            contact=bondem.ContactSettings(model="linear"))
    assert sim.contacts.musen_compat is False
    sim.step(3)
    assert sim.state.velocity[0, 0] < 0.0


def test_the_1_74_2_run_needs_its_own_release_numerics(tmp_path):
    """The same scene run by MUSEN 1.70.0 and 1.74.2 parts by up to 73 % in velocity: the
    1.74.2 run compared with the 1.70.0 numerics (musen_version) fails its 1e-9 rows, so
    each release's run checks its own branch of the law."""
    import shutil
    folder = tmp_path / "contacts_1.74.2"
    shutil.copytree(RUNS / "contacts_1.74.2", folder)
    scene = folder / "scene.toml"
    scene.write_text(scene.read_text().replace('musen_version = "1.74.2"',
                                               'musen_version = "1.70.0"'))
    run = next(r for r in refdata.discover(tmp_path) if r.name == "contacts_1.74.2")
    rows = refdata.compare_run(run, "musen", compat_only=True)
    velocity = max(abs(r.error) for r in rows if r.quantity.startswith("particles/velocity"))
    assert not all(r.passed for r in rows) and velocity > 1e-2


def test_an_unknown_musen_version_is_refused(tmp_path):
    glass = bondem.Material(density=2500.0, young_modulus=E, poisson_ratio=NU)
    model, state = bondem.make_system(np.array([[0.0, 0.0, 0.0]]), 1e-3, glass)
    with pytest.raises(ValueError, match="1.74.2"):
        bondem.Simulation(model, state, musen_compat=True, musen_version="1.72")

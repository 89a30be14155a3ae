"""The Kelvin (viscoelastic) bond against closed forms and conservation laws.

- Two free equal spheres (mass m) pulled apart at v0 along the bond: the stretch follows
  the damped oscillator (m/2) x'' = -k_n x - eta k_n x', x(0) = 0, x'(0) = v0:
  x(t) = v0 / omega_d exp(-zeta omega_0 t) sin(omega_d t), omega_0^2 = 2 k_n / m,
  zeta = eta omega_0 / 2, omega_d = omega_0 sqrt(1 - zeta^2) (to 1 % of the amplitude).
- The energy lost by the pair equals what the dashpots booked (dissipated_bonds), to
  0.2 % of the energy at the start (the leapfrog's kinetic energy at half steps is off
  by O(dt); the dashpots have no share in the twist, bending and rigid-body motion).
- A spinning, sliding pair keeps its total angular momentum to round-off: the dashpot
  force acts at the bond centre, so it turns both spheres by (r/2) x F_t,d (MUSEN's
  Kelvin bond leaves that moment out; this test fails for it).
- viscosity 0 gives the elastic bond's bits; the scene and API refuse viscosity without
  model = "kelvin", and MUSEN-compatible runs refuse Kelvin bonds with "separate" breakage
  (MUSEN's Kelvin bond has the combined criterion only). MUSEN's own Kelvin numerics are
  checked against a run of the real MUSEN in test_validate.py (kelvin_cluster).
"""
import numpy as np
import pytest

import bondem

from bondtools import RADIUS, SPACING, bond_constants


def kelvin(viscosity, **kw):
    return bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, breakage="none",
                               model="kelvin", viscosity=viscosity, name="kelvin", **kw)


def pair(glass, material, velocity, angular_velocity=None):
    return bondem.make_system([[0.0, 0.0, 0.0], [SPACING, 0.0, 0.0]], RADIUS, glass,
                              velocity=velocity, angular_velocity=angular_velocity,
                              bonds=[[0, 1]], bond_diameter=1e-3, bond_material=material)


def axial_constants(glass, material):
    (kn, _, _, _), _ = bond_constants(material)
    m = glass.density * 4 / 3 * np.pi * RADIUS ** 3
    return kn, m, np.sqrt(2.0 * kn / m)


@pytest.mark.parametrize("zeta", [0.05, 0.3])
def test_axial_stretch_follows_the_damped_oscillator(glass, zeta):
    material = kelvin(1.0)
    kn, m, omega_0 = axial_constants(glass, material)
    material = kelvin(2.0 * zeta / omega_0)
    v0 = 2e-4
    model, state = pair(glass, material, [[-v0 / 2, 0, 0], [v0 / 2, 0, 0]])
    dt = 2e-3 * 2 * np.pi / omega_0
    sim = bondem.Simulation(model, state, time_step=dt)
    omega_d = omega_0 * np.sqrt(1 - zeta ** 2)
    steps = int(3 * 2 * np.pi / omega_d / dt)
    time, stretch = np.empty(steps), np.empty(steps)
    for k in range(steps):
        sim.step(1)
        time[k] = state.time
        stretch[k] = state.position[1, 0] - state.position[0, 0] - SPACING
    expected = v0 / omega_d * np.exp(-zeta * omega_0 * time) * np.sin(omega_d * time)
    amplitude = v0 / omega_0
    assert np.max(np.abs(stretch - expected)) < 1e-2 * amplitude
    # the damping is really there: the third peak is exp(-2 zeta omega_0 T_d) of the first
    assert np.max(np.abs(stretch[time > 2 * 2 * np.pi / omega_d])) < \
        1.05 * amplitude * np.exp(-zeta * omega_0 * 2 * 2 * np.pi / omega_d)


def test_the_tangential_dashpot_is_eta_times_the_shear_spring(glass):
    """Both spheres driven (fixed), j sliding sideways at v: in the first step the shear
    spring holds nothing yet, so the bond's sideways force on i is the dashpot's alone,
    eta k_t v with k_t = G A / L0 (1e-9), and after k steps eta k_t v + k_t v k dt. A
    dashpot built on the normal spring (k_n = 2.6 k_t here) fails both."""
    eta, v, dt = 3e-6, 1e-3, 1e-7
    material = kelvin(eta)
    model, state = bondem.make_system([[0.0, 0.0, 0.0], [SPACING, 0.0, 0.0]], RADIUS, glass,
                                      velocity=[[0.0, 0.0, 0.0], [0.0, v, 0.0]],
                                      fixed=[True, True], bonds=[[0, 1]], bond_diameter=1e-3,
                                      bond_material=material)
    (_, kt, _, _), _ = bond_constants(material)
    sim = bondem.Simulation(model, state, time_step=dt)
    sim.step(1)
    assert sim.bonds.loads.force_i[0, 1] == pytest.approx(eta * kt * v, rel=1e-9)
    sim.step(9)
    assert sim.bonds.loads.force_i[0, 1] == pytest.approx(eta * kt * v + kt * v * 9 * dt,
                                                          rel=1e-3)


def test_lost_energy_is_what_the_dashpots_booked(glass):
    material = kelvin(1.0)
    _, _, omega_0 = axial_constants(glass, material)
    rng = np.random.default_rng(4)
    velocity = rng.normal(0, 1e-4, (2, 3))
    model, state = pair(glass, kelvin(0.4 / omega_0), velocity - velocity.mean(axis=0),
                        rng.normal(0, 0.2, (2, 3)))
    sim = bondem.Simulation(model, state, time_step=1e-3 * 2 * np.pi / omega_0)
    sim.step(1)
    first = sim.energy_terms()

    def stored(terms):
        return (terms["kinetic_translational"] + terms["kinetic_rotational"]
                + terms["bond_elastic"])
    sim.step(4000)
    last = sim.energy_terms()
    lost = stored(first) - stored(last)
    booked = last["dissipated_bonds"] - first["dissipated_bonds"]
    assert booked > 0.05 * stored(first)
    assert abs(booked - lost) < 2e-3 * stored(first)


def angular_momentum(model, state):
    linear = model.mass[:, None] * np.cross(state.position, state.velocity)
    return (linear + model.inertia[:, None] * state.angular_velocity).sum(axis=0)


def test_a_spinning_sliding_pair_keeps_its_angular_momentum(glass):
    _, _, omega_0 = axial_constants(glass, kelvin(1.0))
    model, state = pair(glass, kelvin(0.5 / omega_0), [[0, -1e-4, 3e-5], [0, 1e-4, 0]],
                        [[0.3, 0.5, -0.2], [-0.1, 0.2, 0.4]])
    sim = bondem.Simulation(model, state, time_step=1e-3 * 2 * np.pi / omega_0)
    sim.step(1)
    start = angular_momentum(model, state)
    sim.step(3000)
    end = angular_momentum(model, state)
    scale = np.linalg.norm(start)
    assert sim.energy_terms()["dissipated_bonds"] > 0.0
    np.testing.assert_allclose(end, start, atol=1e-9 * scale)


def test_zero_viscosity_gives_the_elastic_bits(glass, binder):
    rng = np.random.default_rng(5)
    velocity, spin = rng.normal(0, 1e-4, (2, 3)), rng.normal(0, 0.2, (2, 3))
    runs = []
    for material in (binder, kelvin(0.0)):
        model, state = pair(glass, material, velocity, spin)
        sim = bondem.Simulation(model, state)
        sim.step(200)
        runs.append(state)
    for name in ("position", "velocity", "angular_velocity", "bond_tangential_force",
                 "bond_normal_moment", "bond_tangential_moment"):
        np.testing.assert_array_equal(getattr(runs[0], name), getattr(runs[1], name))


def test_viscosity_needs_the_kelvin_model_and_musen_mode_refuses_it(glass, tmp_path):
    with pytest.raises(ValueError, match="viscosity.*model = 'kelvin'"):
        bondem.BondMaterial(young_modulus=1e8, viscosity=1e-6)
    with pytest.raises(ValueError, match="model = 'plastic'; allowed: 'elastic', .*'kelvin'"):
        bondem.BondMaterial(young_modulus=1e8, model="plastic")
    with pytest.raises(ValueError, match="viscosity = -1"):
        kelvin(-1.0)
    material = bondem.BondMaterial(young_modulus=1e8, model="kelvin", viscosity=1e-6,
                                   breakage="separate")
    model, state = pair(glass, material, [[0, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match="musen_compat.*combined criterion only"):
        bondem.Simulation(model, state, musen_compat=True)


def test_scene_files_select_the_model_per_bond_material(tmp_path):
    from bondem.errors import InputError
    from bondem.scene import load_scene
    from scenetools import cube_scene
    path = cube_scene(tmp_path)
    text = path.read_text()
    kelvin_text = text.replace("[bond_materials.binder]",
                               '[bond_materials.binder]\nmodel = "kelvin"\nviscosity = 1e-6')
    path.write_text(kelvin_text)
    scene = load_scene(path)
    assert scene.model.bond_materials[0].model == "kelvin"
    assert scene.model.bond_materials[0].viscosity == 1e-6
    path.write_text(text.replace("[bond_materials.binder]",
                                 "[bond_materials.binder]\nviscosity = 1e-6"))
    with pytest.raises(InputError, match="needs model = 'kelvin'") as error:
        load_scene(path)
    assert error.value.key == "bond_materials.binder.viscosity"
    path.write_text(kelvin_text.replace("[simulation]", "[simulation]\nmusen_compat = true")
                    .replace('model = "kelvin"', 'model = "kelvin"\nbreakage = "separate"'))
    with pytest.raises(InputError, match="combined criterion only") as error:
        load_scene(path)
    assert error.value.key == "bond_materials.binder.breakage"
    path.write_text(text.replace("[bond_materials.binder]",
                                 '[bond_materials.binder]\nmodel = "plastic"'))
    with pytest.raises(InputError, match="elastic.*kelvin"):
        load_scene(path)


def test_a_stiff_dashpot_limits_the_time_step(glass):
    """Past a damping ratio of 1/2 the dashpot's own time m_red / (eta k_n) is the
    smallest scale; a given step above it is refused."""
    kn, m, omega_0 = axial_constants(glass, kelvin(1.0))
    zeta = 5.0
    model, state = pair(glass, kelvin(2 * zeta / omega_0), [[0, 0, 0], [0, 0, 0]])
    scales = bondem.time_scales(model)
    assert scales["bond_dashpot"] == pytest.approx((m / 2) / (2 * zeta / omega_0 * kn))
    assert min(scales, key=scales.get) == "bond_dashpot"
    with pytest.raises(ValueError, match="bond_dashpot"):
        bondem.Simulation(model, state, time_step=0.5 * scales["bond_axial"])
    # MUSEN's Kelvin viscosity is in s/m: no such scale in MUSEN-compatible runs
    assert "bond_dashpot" not in bondem.time_scales(model, musen_compat=True)

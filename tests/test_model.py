"""Validation at the edge: make_system and Simulation reject bad input with clear messages."""
import numpy as np
import pytest

import bondem


def two(glass, binder, **kwargs):
    base = dict(bonds=[[0, 1]], bond_diameter=1e-3, bond_material=binder)
    base.update(kwargs)
    position = base.pop("position", [[0, 0, 0], [2e-3, 0, 0]])
    radius = base.pop("radius", 1e-3)
    return bondem.make_system(position, radius, glass, **base)


def test_valid_pair_has_initial_length_and_mass(glass, binder):
    model, state = two(glass, binder)
    assert model.bond_initial_length[0] == pytest.approx(2e-3)
    assert model.mass[0] == pytest.approx(2500 * 4 / 3 * np.pi * 1e-9)
    assert model.inertia[0] == pytest.approx(0.4 * model.mass[0] * 1e-6)
    assert state.bond_active.all() and np.isnan(state.bond_break_time).all()


@pytest.mark.parametrize("kwargs, message", [
    (dict(radius=[1e-3]), "radius: length 1, expected 2"),
    (dict(radius=[1e-3, -1e-3]), "radius: particle 1"),
    (dict(radius=[1e-3, np.nan]), "radius: particle 1"),
    (dict(position=[[0, 0, 0], [np.nan, 0, 0]]), "position: contains NaN"),
    (dict(position=[[0, 0, 0], [0, 0, 0]]), "initial length 0"),
    (dict(bonds=[[0, 2]]), "indices must lie in [0, 1]"),
    (dict(bonds=[[0, 1], [1, 0]], bond_diameter=1e-3), "bonded more than once"),
    (dict(bonds=[[1, 1]]), "to itself"),
    (dict(bond_diameter=0.0), "bond_diameter: bond 0"),
    (dict(bond_diameter=[1e-3, 1e-3]), "bond_diameter: length 2, expected 1"),
    (dict(velocity=[[0, 0, 0]]), "velocity: shape (1, 3)"),
    (dict(damping=1.0), "damping"),
])
def test_bad_arrays_raise_value_error_naming_the_argument(glass, binder, kwargs, message):
    with pytest.raises(ValueError) as error:
        two(glass, binder, **kwargs)
    assert message in str(error.value)


@pytest.mark.parametrize("key, value", [("density", -1.0), ("poisson_ratio", 0.5),
                                        ("young_modulus", 0.0), ("restitution", 1.5)])
def test_bad_material_names_key_and_range(key, value):
    kwargs = dict(density=2500.0, young_modulus=1e8)
    kwargs[key] = value
    with pytest.raises(ValueError, match=rf"{key} = .* outside the allowed range"):
        bondem.Material(**kwargs)


def test_bad_breakage_criterion_lists_allowed():
    with pytest.raises(ValueError, match="allowed: 'none', 'combined', 'separate'"):
        bondem.BondMaterial(young_modulus=1e8, breakage="sometimes")


def test_time_step_above_stable_limit_is_an_error_unless_forced(glass, binder):
    model, state = two(glass, binder)
    limit = min(bondem.time_scales(model).values())
    with pytest.raises(ValueError, match="exceeds the stable limit"):
        bondem.Simulation(model, state, time_step=2 * limit)
    sim = bondem.Simulation(model, state, time_step=2 * limit, force_time_step=True)
    assert sim.time_step == 2 * limit


def test_auto_time_step_is_safety_times_smallest_scale(glass, binder):
    model, state = two(glass, binder)
    scales = bondem.time_scales(model)
    sim = bondem.Simulation(model, state)
    assert sim.time_step == pytest.approx(0.2 * min(scales.values()))
    # axial scale of the pair: sqrt(m_red L0 / (E A))
    m_red = model.mass[0] / 2
    assert scales["bond_axial"] == pytest.approx(np.sqrt(m_red * 2e-3 / (1e8 * np.pi * 0.25e-6)))


def test_blow_up_stops_with_message_and_last_good_state(glass, binder):
    model, state = two(glass, binder, velocity=[[0, 0, 0], [1e9, 0, 0]],
                       box_low=[-1, -1, -1], box_high=[1, 1, 1])
    sim = bondem.Simulation(model, state, time_step=1e-9)
    with pytest.raises(bondem.SimulationBlowUp, match="left the domain") as error:
        sim.run(steps=10, every=1e-9)
    good = error.value.last_good_state
    assert np.all(np.abs(good.position) <= 1.0)


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("kind", ["force", "moment"])
def test_a_load_that_is_not_finite_stops_the_run(glass, binder, kind, axis):
    """An infinite load on one component of one sphere (inside an unbounded box) makes its
    velocity or spin infinite: the step must stop the run as not finite, on any axis."""
    model, state = two(glass, binder)
    sim = bondem.Simulation(model, state)
    sim.step(3)
    load = np.zeros(3)
    load[axis] = np.inf
    (model.external_force if kind == "force" else model.external_moment)[1] = load
    with pytest.raises(bondem.SimulationBlowUp, match="NaN or infinite"):
        sim.step(1)


def test_reprs_show_counts_time_and_intact_bonds(tmp_path):
    import bondem
    from bondem.analysis import Results
    from bondem.runner import run_scene
    from bondem.scene import load_scene
    from scenetools import cube_scene
    glass = bondem.Material(density=2500.0, young_modulus=1e8)
    binder = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3)
    model, state = bondem.make_system(np.array([[0, 0, 0], [2e-3, 0, 0.0]]), radius=1e-3,
                                      material=glass, bonds=[[0, 1]], bond_diameter=1e-3,
                                      bond_material=binder)
    sim = bondem.Simulation(model, state, time_step=1e-6)
    sim.step(3)
    assert repr(model).startswith("Model(2 particles, 1 bonds")
    assert repr(state) == "State(t = 3e-06 s, step 3, 2 particles, 1 of 1 bonds intact)"
    assert "step 3" in repr(sim) and "dt = 1e-06 s" in repr(sim) and "1 of 1 bonds" in repr(sim)
    path = run_scene(load_scene(cube_scene(tmp_path, end_time=1e-4)), tmp_path / "o",
                     progress=False)
    with Results(path) as results:
        text = repr(results)
    assert ": 6 frames, t = 0 .. 9.93042e-05 s, 27 particles" in text
    assert "of 54 bonds intact at the end" in text

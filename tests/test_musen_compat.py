"""Simulation(musen_compat=True) reproduces MUSEN's own bond numerics.

The reference is the plain NumPy transcription of MUSEN's bond update and integrator
(bondem.validation.musen_reference), run step by step next to bondem's compiled kernel.
"""
import math

import numpy as np
import pytest

import bondem
from bondem.io.checkpoint import read_checkpoint, write_checkpoint
from bondem.physics.bond_elastic import COMPRESSION, CRITERION_COMBINED, \
    CRITERION_SEPARATE, INTACT, SHEAR, TENSION
from bondem.physics.bond_elastic_musen import bond_break_mode_musen, musen_rotate
from bondem.validation.core import load_parameters
from bondem.validation.musen_reference import musen_rotation_matrix
from bondem.validation.musen_run import QUANTITIES, largest_difference, run_both

STEPS = 300


@pytest.fixture(scope="module")
def cluster():
    return load_parameters("musen")["cluster"]


@pytest.mark.parametrize("radius", [1e-3, 0.5])
def test_compat_kernel_follows_musen_transcription(cluster, radius):
    # L0 = 2 mm: MUSEN's turning term (in m^2) is tiny; L0 = 1 m: it is of full size.
    ours, reference, _ = run_both(radius, cluster, STEPS, compat=True)
    for name in QUANTITIES:
        assert largest_difference(ours, reference, name) < 1e-12, name
    # The run really tumbles, stretches and twists: the SPEC's numerics end far away.
    spec, _, _ = run_both(radius, cluster, STEPS, compat=False)
    for name in ("tangential_force", "normal_moment", "tangential_moment"):
        assert largest_difference(spec, reference, name) > 1e-3, name


@pytest.mark.parametrize("breakage, factor", [("combined", 4.0), ("separate", 3.0)])
def test_compat_breaks_the_bonds_musen_breaks_at_the_same_step(cluster, breakage, factor):
    # Strengths a few times the median shear / bending stress an unbreakable run ends
    # with, so that some bonds break during the run (mid-run) and others do not.
    ours, _, _ = run_both(0.5, cluster, STEPS, compat=True)
    diameter = cluster["bond_diameter_ratio"] * 2 * 0.5
    area, second = math.pi * diameter ** 2 / 4, math.pi * diameter ** 4 / 64
    tau = np.linalg.norm(ours["tangential_force"], axis=1) / area
    sigma = np.linalg.norm(ours["tangential_moment"], axis=1) * diameter / 2 / second
    p = dict(cluster, breakage=breakage, normal_strength=factor * float(np.median(sigma)),
             tangential_strength=factor * float(np.median(tau)))
    ours, reference, dt = run_both(0.5, p, STEPS, compat=True)
    broken = ~reference["active"]
    assert 0 < broken.sum() < broken.size
    assert np.nanmax(reference["break_time"]) > 10 * dt
    np.testing.assert_array_equal(ours["active"], reference["active"])
    np.testing.assert_allclose(ours["break_time"][broken], reference["break_time"][broken],
                               rtol=1e-12)
    for name in QUANTITIES:
        if name in ("position", "velocity", "angular_velocity"):
            assert largest_difference(ours, reference, name) < 1e-12, name
        else:  # stored vectors of broken bonds are frozen at different moments: skip them
            scale = np.abs(reference[name][~broken]).max()
            assert np.abs(ours[name] - reference[name])[~broken].max() < 1e-12 * scale


def test_musen_rotate_is_musen_matrix_in_bondem_convention():
    rng = np.random.default_rng(3)
    for _ in range(20):
        p, r, w, v = rng.standard_normal((4, 3))
        dt = 1e-2
        n = r / np.linalg.norm(r)
        phi = n * (np.dot(w, n) * dt * 0.5)
        # MUSEN's bond vectors are x_i - x_j = -r (bondem's r = x_j - x_i).
        expected = musen_rotation_matrix(-p, -r, w, dt) @ v
        ours = np.array(musen_rotate(tuple(v), tuple(p), tuple(r), tuple(phi)))
        np.testing.assert_allclose(ours, expected, rtol=1e-14, atol=1e-14 * np.abs(v).max())


def _stresses_to_loads(sigma_axial, bending, shear, torsion, diameter, stretched):
    """Loads (L, L0, F_n, F_t, M_n, M_t) giving the four stress terms (Pa)."""
    radius = diameter / 2
    area, second = math.pi * radius ** 2, math.pi * radius ** 4 / 4
    length = 1.001 if stretched else 0.999
    return (length, 1.0, (sigma_axial * area, 0.0, 0.0), (0.0, shear * area, 0.0),
            (torsion * 2 * second / radius, 0.0, 0.0), (0.0, 0.0, bending * second / radius))


@pytest.mark.parametrize("stretched, criterion, terms, expected", [
    # combined: sigma = s |F_n|/A + |M_t| R/I, in compression too (s = -1)
    (True, CRITERION_COMBINED, (60.0, 50.0, 0.0, 0.0), TENSION),
    (False, CRITERION_COMBINED, (60.0, 50.0, 0.0, 0.0), INTACT),    # -60 + 50 < 100
    (False, CRITERION_COMBINED, (10.0, 115.0, 0.0, 0.0), COMPRESSION),  # -10 + 115
    (True, CRITERION_COMBINED, (0.0, 0.0, 30.0, 25.0), SHEAR),      # 30 + 25 >= 50
    # separate: axial alone (signed), bending only in tension, shear, torsion alone
    (True, CRITERION_SEPARATE, (60.0, 50.0, 0.0, 0.0), INTACT),
    (False, CRITERION_SEPARATE, (10.0, 150.0, 0.0, 0.0), INTACT),
    (True, CRITERION_SEPARATE, (10.0, 150.0, 0.0, 0.0), TENSION),
    (False, CRITERION_SEPARATE, (150.0, 0.0, 0.0, 0.0), INTACT),   # -150: never in compression
    (False, CRITERION_SEPARATE, (0.0, 0.0, 0.0, 55.0), SHEAR),
])
def test_musen_breakage_criteria(stretched, criterion, terms, expected):
    loads = _stresses_to_loads(*terms, diameter=1e-3, stretched=stretched)
    # strengths 100 Pa (normal) and 50 Pa (tangential)
    assert bond_break_mode_musen(*loads, 1e-3, 100.0, 50.0, criterion) == expected


def test_previous_length_survives_checkpoint_and_old_states_get_initial_length(
        tmp_path, glass, binder):
    model, state = bondem.make_system([[0, 0, 0], [2e-3, 0, 0]], 1e-3, glass,
                                      velocity=[[0, 0, 0], [0.01, 0.02, 0]],
                                      bonds=[[0, 1]], bond_diameter=1e-3,
                                      bond_material=binder)
    sim = bondem.Simulation(model, state, musen_compat=True)
    sim.step(9)
    position = state.position.copy()  # the bond law reads positions before the drift
    sim.step(1)
    assert state.bond_previous_length[0] == pytest.approx(
        np.linalg.norm(position[1] - position[0]), rel=1e-15)
    write_checkpoint(tmp_path / "a.npz", state, frames=0)
    back = read_checkpoint(tmp_path / "a.npz")[0]
    np.testing.assert_array_equal(back.bond_previous_length, state.bond_previous_length)
    # A state made before the array existed (None) is written without it and read back
    # as None; Simulation then starts its bonds from L0.
    old = state.copy()
    old.bond_previous_length = None
    write_checkpoint(tmp_path / "b.npz", old, frames=0)
    back = read_checkpoint(tmp_path / "b.npz")[0]
    assert back.bond_previous_length is None
    bondem.Simulation(model, back, musen_compat=True)
    np.testing.assert_array_equal(back.bond_previous_length, model.bond_initial_length)

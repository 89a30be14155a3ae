"""Per-bond strength scatter (bond material strength_scatter, strength_spread,
strength_seed; Model.bond_strength_factors): the factors follow the chosen law with mean 1,
depend only on the seed and the bond's index, and each bond breaks at its own strength on
both CPU bond paths, for the elastic and a plastic model."""
import math

import numpy as np
import pytest
from scipy import stats

import bondem

from bondtools import pairs_along_x

E = 1e8
AREA = math.pi * 0.5e-3 ** 2
SPACING = 2e-3


@pytest.mark.parametrize("scatter, spread, law", [
    ("normal", 0.2, stats.norm(1.0, 0.2)),
    ("weibull", 4.0, stats.weibull_min(4.0, scale=1.0 / math.gamma(1.25)))])
def test_the_factors_follow_their_law_with_mean_one(scatter, spread, law):
    """20,000 bonds: the factors pass a Kolmogorov-Smirnov test against the law (the
    Weibull's scale chosen so that its mean is 1), their mean is 1 within 4 standard
    errors; the same seed gives the same factors, another seed others."""
    material = bondem.BondMaterial(young_modulus=E, normal_strength=1e6,
                                   strength_scatter=scatter, strength_spread=spread,
                                   strength_seed=12)
    model, _ = pairs_along_x(20000, material)
    factors = model.bond_strength_factors()
    assert stats.kstest(factors, law.cdf).pvalue > 1e-3
    assert abs(factors.mean() - 1.0) < 4 * law.std() / math.sqrt(factors.size)
    np.testing.assert_array_equal(factors, model.bond_strength_factors())
    other = bondem.BondMaterial(young_modulus=E, normal_strength=1e6,
                                strength_scatter=scatter, strength_spread=spread,
                                strength_seed=13)
    assert not np.allclose(pairs_along_x(20000, other)[0].bond_strength_factors(), factors)


def test_a_bond_keeps_its_factor_whatever_the_other_materials():
    """Bond b of a material takes draw b of its seed: a second material on the odd bonds
    leaves the even bonds' factors as they were."""
    scattered = bondem.BondMaterial(young_modulus=E, normal_strength=1e6,
                                    strength_scatter="weibull", strength_spread=6.0,
                                    strength_seed=3, name="a")
    model, _ = pairs_along_x(10, scattered)
    alone = model.bond_strength_factors()
    plain = bondem.BondMaterial(young_modulus=E, normal_strength=1e6, name="b")
    mixed, _ = bondem.make_system(pairs_along_x(10, scattered)[1].position,
                                  1e-3, model.materials[0], bonds=model.bond_pairs,
                                  bond_diameter=1e-3, bond_material=[scattered, plain],
                                  bond_material_index=np.arange(10) % 2)
    factors = mixed.bond_strength_factors()
    np.testing.assert_array_equal(factors[0::2], alone[0::2])
    assert np.all(factors[1::2] == 1.0)


@pytest.mark.parametrize("vectorised", [False, True])
def test_each_bond_breaks_at_its_own_strength(vectorised):
    """40 pairs pulled at 1 mm/s: bond b breaks in the first step whose stress E eps
    reaches its strength times its factor (eps before step k: k v dt / L0), on the
    scalar and the vectorised CPU path alike ("separate": the vectorised block hands a
    bond to the exact test only near its full strength, not at half of it)."""
    strength = 1e5
    material = bondem.BondMaterial(young_modulus=E, normal_strength=strength,
                                   breakage="separate", strength_scatter="normal",
                                   strength_spread=0.25, strength_seed=5)
    model, state = pairs_along_x(40, material)
    dt = 1e-6
    sim = bondem.Simulation(model, state, time_step=dt)
    sim.bonds.vectorise_from = 0 if vectorised else 10 ** 9
    factors = model.bond_strength_factors()
    sim.step(int(1.2 * factors.max() * strength / E * SPACING / (1e-3 * dt)) + 2)
    assert not np.any(state.bond_active)
    first = np.floor(factors * strength / E * SPACING / (1e-3 * dt) + 1e-9)
    first = np.where(first * 1e-3 * dt / SPACING * E >= factors * strength * (1 - 1e-12),
                     first, first + 1)
    np.testing.assert_allclose(state.bond_break_time / dt, first, atol=1.01)
    assert np.ptp(state.bond_break_time) > 0.5 * strength / E * SPACING / 1e-3


def test_each_bond_breaks_in_shear_at_its_own_strength():
    """20 pairs slid sideways at 1 mm/s (normal strength inf): each bond's last intact
    shear stress |F_t| / A is its tangential strength times its factor (1 %)."""
    material = bondem.BondMaterial(young_modulus=E, tangential_strength=1e5,
                                   breakage="combined", strength_scatter="normal",
                                   strength_spread=0.25, strength_seed=8)
    model, state = pairs_along_x(20, material, speed=0.0)
    state.velocity[1::2, 2] = 1e-3
    sim = bondem.Simulation(model, state, time_step=1e-6)
    last = np.zeros(20)
    while np.any(state.bond_active):
        intact = state.bond_active.copy()
        last[intact] = np.linalg.norm(state.bond_tangential_force[intact], axis=1) / AREA
        sim.step(1)
        assert state.time < 0.1
    np.testing.assert_allclose(last, 1e5 * model.bond_strength_factors(), rtol=1e-2)
    assert np.all(state.bond_break_mode == 3)


def test_a_plastic_bond_yields_at_its_scattered_yield_stress():
    """The elastic-plastic bond's yield stress scales with the factor: each pulled
    pair's force stops at sigma_y A times its factor."""
    material = bondem.BondMaterial(young_modulus=E, model="elastic_plastic",
                                   yield_strength=1e5, fracture_strain=1.0,
                                   breakage="none", strength_scatter="weibull",
                                   strength_spread=3.0, strength_seed=9)
    model, state = pairs_along_x(12, material)
    sim = bondem.Simulation(model, state, time_step=1e-6)
    sim.step(8000)
    np.testing.assert_allclose(sim.bonds.loads.force_i[:, 0],
                               1e5 * AREA * model.bond_strength_factors(), rtol=1e-12)


def test_bad_scatter_values_are_refused():
    with pytest.raises(ValueError, match="strength_spread > 0"):
        bondem.BondMaterial(young_modulus=E, strength_scatter="normal")
    with pytest.raises(ValueError, match="below 1"):
        bondem.BondMaterial(young_modulus=E, strength_scatter="normal", strength_spread=1.5)
    with pytest.raises(ValueError, match="strength_scatter"):
        bondem.BondMaterial(young_modulus=E, strength_scatter="lognormal",
                            strength_spread=0.1)

"""What a lab report reads off a curve (bondem.lab.measure), against definitions: curves
and specimens built with known moduli, strains and fragments, away from symmetric points
(a specimen that does not start at zero, loaded along y, a curved stress-strain line,
a Poisson's ratio that changes with strain)."""
import math

import numpy as np
import pytest

from bondem.lab import measure


def column(heights, axis=1, offset=(0.3, -2.0, 5.0)):
    """Particles at ``heights`` along ``axis`` (m), spread across it, shifted by offset."""
    heights = np.asarray(heights, float)
    position = np.tile(np.asarray(offset, float), (heights.size, 1))
    across = [k for k in range(3) if k != axis]
    position[:, across[0]] += 1e-3 * np.arange(heights.size) % 3e-3
    position[:, axis] += heights
    return position


def test_gauge_groups_take_the_bands_a_tenth_to_a_quarter_from_either_end():
    # height 0.8 m from -2.0 m (along y): the lower band [0.08, 0.2] m above the bottom,
    # the upper one [0.6, 0.72] m
    heights = np.array([0.0, 0.05, 0.09, 0.15, 0.19, 0.21, 0.4, 0.59, 0.61, 0.7, 0.73, 0.8])
    near, far = measure.gauge_groups(column(heights), axis=1)
    assert near.tolist() == [2, 3, 4] and far.tolist() == [8, 9]
    near, far = measure.gauge_groups(column(heights), axis=1, fractions=(0.0, 0.1))
    assert near.tolist() == [0, 1] and far.tolist() == [10, 11]
    # four layers (0, 1/3, 2/3, 1 of the height): both bands empty, the second layer from
    # either end instead
    heights = np.repeat([0.0, 0.3, 0.6, 0.9], 2)
    near, far = measure.gauge_groups(column(heights), axis=1)
    assert near.tolist() == [2, 3] and far.tolist() == [4, 5]
    # the same in millimetres (a real specimen's size)
    near, far = measure.gauge_groups(column(heights * 1e-3, offset=(0.0, 2e-3, 0.0)), axis=1)
    assert near.tolist() == [2, 3] and far.tolist() == [4, 5]
    # three layers, two: the end layers (a gauge of the whole height, never of none)
    for layers, top in (([0.0, 0.45, 0.9], [4, 5]), ([0.0, 0.9], [2, 3])):
        near, far = measure.gauge_groups(column(np.repeat(layers, 2)), axis=1)
        assert near.tolist() == [0, 1] and far.tolist() == top
    # one band empty only (the upper end's layers sparse): the layers, both ends
    heights = np.array([0.0, 0.1, 0.2, 0.3, 0.5, 1.0])
    near, far = measure.gauge_groups(column(heights), axis=1)
    assert near.tolist() == [1] and far.tolist() == [4]
    # the bands are closed: particles exactly at a tenth and a quarter of the height
    # (a power-of-two height from 0.5 m: exact in binary) belong to them
    heights = np.array([0.0, 0.2, 0.5, 1.0, 1.5, 1.8, 2.0])
    near, far = measure.gauge_groups(column(heights, offset=(0.0, 0.5, 0.0)), axis=1,
                                     fractions=(0.125, 0.25))
    assert near.tolist() == [2] and far.tolist() == [4]
    # a band of one particle is a band
    near, far = measure.gauge_groups(column(heights, offset=(0.0, 0.5, 0.0)), axis=1,
                                     fractions=(0.0625, 0.125))
    assert near.tolist() == [1] and far.tolist() == [5]


def test_gauge_length_and_middle_band_by_their_definitions():
    heights = np.array([0.0, 0.1, 0.24, 0.26, 0.5, 0.74, 0.76, 1.0]) * 0.6
    position = column(heights, axis=2)
    assert measure.middle_band(position, 2).tolist() == [3, 4, 5]
    # closed: a quarter and three quarters of a 2 m height from 0.5 m, exactly
    exact = column(np.array([0.0, 0.5, 1.0, 1.5, 2.0]), axis=2, offset=(0.0, 0.0, 0.5))
    assert measure.middle_band(exact, 2).tolist() == [1, 2, 3]
    assert measure.middle_band(position, 2, fractions=(0.0, 0.2)).tolist() == [0, 1]
    # fewer than two particles in the band: all of them
    assert measure.middle_band(position, 2, fractions=(0.45, 0.55)).tolist() == list(range(8))
    length = measure.gauge_length(position, np.array([1, 2]), np.array([5, 6, 7]), 2)
    assert length == pytest.approx(0.6 * ((0.74 + 0.76 + 1.0) / 3 - (0.1 + 0.24) / 2),
                                   rel=1e-12)


@pytest.mark.parametrize("strain", [2.5e-3, -1.2e-3])
def test_lateral_strain_of_a_uniform_widening_moved_and_compressed(strain):
    rng = np.random.default_rng(3)
    position0 = rng.uniform([1.0, 2.0, -3.0], [1.2, 2.3, -2.9], (40, 3))
    centre = position0.mean(axis=0)
    position = position0.copy()
    # axis y: x and z widen by ``strain`` about the centroid, y shortens, all translate
    position[:, [0, 2]] = centre[[0, 2]] + (1.0 + strain) * (position0[:, [0, 2]]
                                                           - centre[[0, 2]])
    position[:, 1] = centre[1] + 0.97 * (position0[:, 1] - centre[1])
    position += [4e-3, -1e-3, 2e-3]
    band = np.arange(5, 35)
    # the band's centroid is not the specimen's: still exact for u = eps rho
    assert measure.lateral_strain(position0, position, band, 1) == pytest.approx(
        strain, rel=1e-9)
    # along x instead: y shortens by 3 %, z widens by strain: the mean, weighted by the
    # spread of each coordinate
    rho0 = position0[band][:, 1:] - position0[band][:, 1:].mean(axis=0)
    weights = np.sum(rho0 ** 2, axis=0)
    expected = (weights[0] * -0.03 + weights[1] * strain) / weights.sum()
    assert measure.lateral_strain(position0, position, band, 0) == pytest.approx(
        expected, rel=1e-9)
    one = np.array([7])
    assert measure.lateral_strain(position0, position, one, 1) == 0.0


def test_peak_is_the_first_of_equal_maxima():
    assert measure.peak([1.0, 3.0, 2.0, 3.0, 0.5]) == 1
    assert measure.peak([-4.0, -1.0, -2.0]) == 1


def curve(young=30e9, curvature=4e12, nu=0.21, growth=20.0, samples=4001):
    """stress = E e - c e^2 up to past its peak e_p = E / (2c), lateral strain
    nu e + growth e^2 (Poisson's ratio rising with strain)."""
    peak_strain = young / (2.0 * curvature)
    strain = np.linspace(0.0, 1.3 * peak_strain, samples)
    return strain, young * strain - curvature * strain ** 2, nu * strain + growth * strain ** 2


@pytest.mark.parametrize("fraction", [0.5, 0.3])
def test_moduli_of_a_curved_line_by_their_definitions(fraction):
    young, c, nu, growth = 30e9, 4e12, 0.21, 20.0
    strain, stress, lateral = curve(young, c, nu, growth)
    peak_stress = young ** 2 / (4.0 * c)
    # stress = f peak: e = e_p (1 - sqrt(1 - f))
    at = young / (2.0 * c) * (1.0 - math.sqrt(1.0 - fraction))
    out = measure.moduli(strain, stress, lateral, fraction=fraction)
    assert out["young_modulus_secant"] == pytest.approx(fraction * peak_stress / at, rel=1e-6)
    # the least-squares slope of a parabola over an interval is its slope at the middle
    low = young / (2.0 * c) * (1.0 - math.sqrt(1.0 - (fraction - 0.1)))
    high = young / (2.0 * c) * (1.0 - math.sqrt(1.0 - (fraction + 0.1)))
    assert out["young_modulus_tangent"] == pytest.approx(
        young - c * (low + high), rel=2e-4)
    assert out["poisson_ratio"] == pytest.approx(nu + growth * at, rel=1e-6)
    assert out["young_modulus_secant"] < young and out["young_modulus_tangent"] < young


def test_moduli_without_a_usable_curve_are_nan():
    strain, stress, lateral = curve()
    out = measure.moduli(strain, stress)
    assert math.isnan(out["poisson_ratio"]) and math.isfinite(out["young_modulus_secant"])
    keys = {"young_modulus_secant", "young_modulus_tangent", "poisson_ratio"}
    # too short, never positive (a peak of zero, reached after a crossing of zero), not
    # finite
    for bad in (stress[:2], -np.abs(stress), np.r_[-3.0, -1.0, 0.0, -2.0],
                np.r_[stress[:-1], np.nan]):
        out = measure.moduli(strain[:bad.size], bad, lateral[:bad.size])
        assert set(out) == keys and all(math.isnan(v) for v in out.values()), bad[:3]
    # three samples are a curve, stresses below 1 Pa too (a soft gel)
    out = measure.moduli([0.0, 0.01, 0.02], [0.0, 0.3, 0.6], [0.0, 0.004, 0.008])
    assert out["young_modulus_secant"] == pytest.approx(30.0, rel=1e-12)
    assert out["poisson_ratio"] == pytest.approx(0.4, rel=1e-12)
    # a crossing at zero strain (the stress jumps before the specimen deforms): no secant
    out = measure.moduli([0.0, 0.0, 1e-3, 2e-3], [0.0, 4e6, 6e6, 8e6], [0.0, 1e-5, 1e-4, 2e-4])
    assert math.isnan(out["young_modulus_secant"]) and math.isnan(out["poisson_ratio"])
    # the tangent's window on a vertical stretch (same strain): no slope
    out = measure.moduli([0.0, 1e-3, 1e-3, 1e-3, 2e-3], [0.0, 4.5e5, 5e5, 5.5e5, 1e6])
    assert math.isnan(out["young_modulus_tangent"])
    assert out["young_modulus_secant"] == pytest.approx(5e5 / 1e-3, rel=1e-12)
    # the level reached at the second sample, and at a plateau exactly at the level:
    # where y first reaches it
    out = measure.moduli([0.0, 1e-3, 2e-3, 3e-3], [0.0, 10e6, 12e6, 11e6], [0.0, 3e-4, 0, 0])
    assert out["young_modulus_secant"] == pytest.approx(6e6 / 0.6e-3, rel=1e-12)
    assert out["poisson_ratio"] == pytest.approx(0.3, rel=1e-12)
    out = measure.moduli([0.0, 1e-3, 2e-3, 3e-3], [0.0, 5e6, 5e6, 10e6], [0.0, 2e-4, 0, 0])
    assert out["young_modulus_secant"] == pytest.approx(5e9, rel=1e-12)
    assert out["poisson_ratio"] == pytest.approx(0.2, rel=1e-12)
    # a preloaded curve, already above the level at its first sample: read there
    out = measure.moduli([1e-3, 2e-3, 3e-3, 4e-3], [7e6, 8e6, 10e6, 9e6],
                         [2.5e-4, 5e-4, 7e-4, 8e-4])
    assert out["young_modulus_secant"] == pytest.approx(5e6 / 1e-3, rel=1e-12)
    assert out["poisson_ratio"] == pytest.approx(0.25, rel=1e-12)
    # exactly at the level there, dipping below it after
    out = measure.moduli([1e-3, 2e-3, 3e-3, 4e-3], [5e6, 4e6, 10e6, 9e6],
                         [2.5e-4, 5e-4, 7e-4, 8e-4])
    assert out["young_modulus_secant"] == pytest.approx(5e6 / 1e-3, rel=1e-12)
    # a curve that jumps to its peak: no samples in the tangent's window, no secant point
    # at zero strain
    jump = np.array([0.0, 0.0, 1e6, 0.5e6])
    out = measure.moduli(np.array([0.0, 1e-3, 2e-3, 3e-3]), jump, np.zeros(4))
    assert out["young_modulus_secant"] == pytest.approx(0.5e6 / 1.5e-3, rel=1e-12)
    assert math.isnan(out["young_modulus_tangent"])
    assert out["poisson_ratio"] == 0.0


def test_moduli_of_a_straight_line_sampled_coarsely():
    strain = np.array([0.0, 1e-3, 2e-3, 3e-3, 4e-3, 5e-3, 4.9e-3])
    stress = 2e9 * strain
    stress[-1] = 0.0
    out = measure.moduli(strain, stress, 0.35 * strain)
    assert out["young_modulus_secant"] == pytest.approx(2e9, rel=1e-12)
    assert out["young_modulus_tangent"] == pytest.approx(2e9, rel=1e-9)
    assert out["poisson_ratio"] == pytest.approx(0.35, rel=1e-12)


def test_crack_initiation_at_a_hundredth_of_the_bonds_broken_at_the_peak():
    stress = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 4.5, 3.0])
    broken = np.array([0, 0, 1, 2, 3, 250, 400, 900])
    # a hundredth of 250 is 2.5: the third broken bond
    assert measure.crack_initiation(stress, broken) == 4.0
    assert measure.crack_initiation(stress, broken, fraction=0.005) == 3.0
    assert measure.crack_initiation(stress, broken, fraction=0.001) == 2.0   # at least one
    assert math.isnan(measure.crack_initiation(stress, np.r_[0, 0, 0, 0, 0, 0, 5, 9]))
    # one bond broken at the peak: initiation where it broke
    assert measure.crack_initiation(stress, np.r_[0, 0, 0, 1, 1, 1, 5, 9]) == 3.0


def test_fragments_and_their_table():
    pairs = np.array([[0, 1], [1, 2], [3, 4], [4, 5]])
    mass = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 0.5]) * 1e-6
    radius = np.array([1.0, 1.0, 1.0, 1.26, 1.26, 0.8]) * 1e-3
    # pieces {0,1,2}, {3,4}, {5}; then {0,1}, {2}, {3}, {4}, {5}: a loose particle is a
    # fragment of its own (as in the analysis), the second count is of 2+ particles
    count, multi, largest = measure.fragments(pairs, np.array([True, True, True, False]),
                                              mass)
    assert (count, multi) == (3, 2) and largest == pytest.approx(4.0 / 7.5, rel=1e-12)
    count, multi, largest = measure.fragments(pairs, np.array([True, False, False, False]),
                                              mass)
    assert (count, multi) == (5, 1) and largest == pytest.approx(2.0 / 7.5, rel=1e-12)
    table = measure.fragment_table(pairs, np.array([True, True, True, False]), radius, mass)
    assert table["particles"].tolist() == [2.0, 3.0, 1.0]
    assert table["mass"] == pytest.approx([4e-6, 3e-6, 0.5e-6], rel=1e-12)
    # the diameter of the sphere of the fragment's volume
    assert table["size"] == pytest.approx([2.52e-3 * 2 ** (1 / 3), 2e-3 * 3 ** (1 / 3),
                                           1.6e-3], rel=1e-12)


def test_unloading_modulus_of_the_first_branch_between_its_turns():
    # loading at 10 GPa to 0.5 %, a first unloading branch: its turn (the top quarter of
    # the stress range) at 40 GPa, 25 GPa in the middle, its return (the bottom quarter)
    # at 5 GPa; reloading, then a second unloading branch at 70 GPa, not read
    strain = [0.0]
    stress = [0.0]
    loading = [1.0]

    def go(slope, d_stress, samples, sign):
        for _ in range(samples):
            stress.append(stress[-1] + d_stress / samples)
            strain.append(strain[-1] + d_stress / samples / slope)
            loading.append(sign)
    go(10e9, 50e6, 20, 1.0)
    top = stress[-1]
    go(40e9, -12e6, 6, -1.0)
    go(25e9, -26e6, 13, -1.0)
    go(5e9, -12e6, 6, -1.0)
    go(10e9, 60e6, 20, 1.0)
    go(70e9, -30e6, 10, -1.0)
    assert top == pytest.approx(50e6)
    assert measure.unloading_modulus(strain, stress, loading) == pytest.approx(25e9, rel=1e-9)
    assert math.isnan(measure.unloading_modulus(strain[:21], stress[:21], loading[:21]))
    # a branch of two samples within its middle half: NaN
    assert math.isnan(measure.unloading_modulus(strain[:23], stress[:23], loading[:23]))


def coarse_unloading(stresses, strains=None, before=0):
    """A record unloading through ``stresses`` (Pa) at 25 GPa (or at ``strains``), after
    ``before`` loading samples (rising to its first stress), with the platen's speed as
    the loading sign (m/s: +5e-2 loading, -5e-2 unloading)."""
    stresses = np.asarray(stresses, float)
    strains = stresses / 25e9 if strains is None else np.asarray(strains, float)
    rise = np.linspace(0.0, stresses[0], before + 1)[:-1]
    return (np.r_[rise / 10e9, strains], np.r_[rise, stresses],
            np.r_[np.full(before, 5e-2), np.full(stresses.size, -5e-2)])


def test_unloading_modulus_in_the_closed_middle_half_of_a_coarse_branch():
    # 50 to 0 MPa in 12.5 MPa steps: the middle half's bounds are samples themselves
    steps = [50e6, 37.5e6, 25e6, 12.5e6, 0.0]
    for before in (0, 3):   # a record that starts unloading, and one that loads first
        strain, stress, loading = coarse_unloading(steps[1:] if before else steps,
                                                   before=before)
        if before:
            stress[before - 1] = 50e6
        assert measure.unloading_modulus(strain, stress, loading) == pytest.approx(
            25e9, rel=1e-12)
    # to a residual stress: the middle half of 50 to 10 MPa
    strain, stress, loading = coarse_unloading([50e6, 40e6, 30e6, 20e6, 10e6])
    assert measure.unloading_modulus(strain, stress, loading) == pytest.approx(25e9,
                                                                               rel=1e-12)
    # two samples in the middle half, or the stress falling at one strain: NaN
    strain, stress, loading = coarse_unloading([50e6, 30e6, 20e6, 0.0])
    assert math.isnan(measure.unloading_modulus(strain, stress, loading))
    strain, stress, loading = coarse_unloading(steps, strains=np.full(5, 2e-3))
    assert math.isnan(measure.unloading_modulus(strain, stress, loading))
    # a first sample at rest (speed 0) is not unloading
    strain, stress, loading = coarse_unloading(steps[1:], before=3)
    stress[2] = 50e6
    loading[0] = 0.0
    assert measure.unloading_modulus(strain, stress, loading) == pytest.approx(25e9,
                                                                               rel=1e-12)
    # one reloading sample ends the first branch: the second is not read
    strain, stress, loading = coarse_unloading(steps)
    strain = np.r_[strain, 1.0e-3, 0.9e-3, 0.8e-3, 0.7e-3]
    stress = np.r_[stress, 30e6, 28e6, 26e6, 24e6]
    loading = np.r_[loading, 5e-2, -5e-2, -5e-2, -5e-2]
    assert measure.unloading_modulus(strain, stress, loading) == pytest.approx(25e9,
                                                                               rel=1e-12)


def test_sieve_curve_and_the_size_a_fraction_of_the_mass_lies_below():
    size = np.array([3e-3, 1e-3, 2e-3, 1e-3])
    mass = np.array([1.0, 2.0, 1.0, 0.0])
    sizes, passing = measure.passing(size, mass)
    assert sizes.tolist() == [1e-3, 1e-3, 2e-3, 3e-3]
    assert passing == pytest.approx([0.5, 0.5, 0.75, 1.0], abs=1e-15)
    assert measure.size_at(size, mass) == 1e-3
    assert measure.size_at(size, mass, 0.6) == 2e-3
    assert measure.size_at(size, mass, 0.75) == 2e-3
    assert measure.size_at(size, mass, 0.9) == 3e-3
    # sizes are lengths (m) whatever numbers they are given in
    assert measure.passing([3, 1, 2], [1, 1, 2])[0].dtype == np.float64

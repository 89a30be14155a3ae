"""Acoustic emission read off a crack log (bondem.lab.cracks) at the edges of its
definitions: the nearest of two events a crack may join, a crack exactly at the radius
or at the end of the window, cracks logged out of time order, Aki's b-value from a given
M_min, the smallest sample it is estimated from, the crack-damage stress at the start of
a curve."""
import math

import numpy as np
import pytest

from bondem.lab import cracks


def test_a_crack_joins_the_nearest_open_event_the_first_when_tied():
    # two events 4 mm apart along y (z = 1 mm); a crack 1.5 mm from the second and
    # 2.5 mm from the first joins the second; one midway joins the first
    time = np.array([0.0, 1e-6, 2e-6, 3e-6])
    position = np.array([[0, 0, 1e-3], [0, 4e-3, 1e-3], [0, 2.5e-3, 1e-3],
                         [0, 2e-3, 1e-3]])
    label = cracks.group_events(time, position, radius=3e-3, window=1e-5)
    assert label.tolist() == [0, 1, 1, 1]   # the midway crack is nearer the second's
    label = cracks.group_events(time[[0, 1, 3]], position[[0, 1, 3]], 3e-3, 1e-5)
    assert label.tolist() == [0, 1, 0]
    ae = cracks.events(time[[0, 1, 3]], position[[0, 1, 3]], np.ones(3), label)
    np.testing.assert_allclose(ae["y"], [1e-3, 4e-3], rtol=1e-12)
    np.testing.assert_allclose(ae["z"], [1e-3, 1e-3], rtol=1e-12)


def test_the_radius_and_the_window_are_closed():
    # 0.5 and 0.25 are exact in binary: a crack exactly at the radius and exactly at
    # the end of the window joins
    time = np.array([0.0, 0.25])
    position = np.array([[0.5, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert cracks.group_events(time, position, radius=0.5, window=0.25).tolist() == [0, 0]
    assert cracks.group_events(time, position, radius=0.4999, window=0.25).tolist() == [0, 1]
    assert cracks.group_events(time, position, radius=0.5, window=0.2499).tolist() == [0, 1]


def test_cracks_logged_out_of_time_order_are_grouped_in_time_order():
    # the log lists a late crack first: it cannot start the event the early ones make;
    # events are numbered in the order they start
    time = np.array([9e-6, 0.0, 1e-6, 1e-6])
    position = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.5e-3, 0.0, 0.0],
                         [7e-3, 0.0, 0.0]])
    label = cracks.group_events(time, position, radius=1e-3, window=2e-6)
    assert label.tolist() == [2, 0, 0, 1]
    ae = cracks.events(time, position, np.array([1.0, 2.0, 3.0, 4.0]), label)
    np.testing.assert_allclose(ae["time"], [0.0, 1e-6, 9e-6])
    assert ae["cracks"].tolist() == [2, 1, 1]
    np.testing.assert_allclose(ae["magnitude"], (np.log10([5.0, 4.0, 1.0]) - 4.8) / 1.5,
                               rtol=1e-12)
    # the same cracks listed as (K, 3) or flat
    assert cracks.group_events(time, position.ravel(), 1e-3, 2e-6).tolist() == [2, 0, 0, 1]
    empty = cracks.events(np.zeros(0), np.zeros((0, 3)), np.zeros(0),
                          np.zeros(0, dtype=np.int64))
    assert empty["cracks"].size == 0 and empty["energy"].size == 0


def test_magnitude_of_no_energy_is_minus_infinity_without_a_warning():
    with np.errstate(all="raise"):
        assert cracks.magnitude(0.0) == -math.inf
        np.testing.assert_array_equal(cracks.magnitude([0.0, 10.0 ** 4.8]), [-math.inf, 0.0])


def test_b_value_from_a_given_minimum_and_at_its_smallest_sample():
    # ten magnitudes: the smallest sample; M_min given below the smallest of them: the
    # mean's distance from M_min, not from the smallest
    m = np.linspace(-3.0, -2.1, 10)
    assert cracks.b_value(m) == pytest.approx(math.log10(math.e) / (m.mean() - m.min()),
                                              rel=1e-12)
    assert cracks.b_value(m, minimum=-3.5) == pytest.approx(
        math.log10(math.e) / (m.mean() + 3.5), rel=1e-12)
    # nine above a minimum: too few; the infinite magnitude of no energy is left out
    assert math.isnan(cracks.b_value(m, minimum=-2.95))
    assert math.isnan(cracks.b_value(np.r_[m[:9], -math.inf]))
    assert math.isnan(cracks.b_value(np.full(12, -2.0)))   # all equal: no spread
    assert cracks.MIN_EVENTS_FOR_B == 10


def test_crack_damage_at_the_edges_of_a_curve():
    assert math.isnan(cracks.crack_damage([], []))
    # compaction largest at the first sample (dilating from the start): that stress
    assert cracks.crack_damage([1.0, 2.0, 3.0, 2.5], [0.5, 0.2, 0.1, 0.0]) == 1.0
    # the peak at the first sample: no pre-peak turn
    assert math.isnan(cracks.crack_damage([3.0, 2.0, 1.0], [0.0, 0.1, 0.2]))


def test_cracks_of_one_step_are_taken_in_the_order_logged():
    # three steps, twenty bonds breaking in each along a line of its own (10 mm apart),
    # 0.8 mm apart: each within the 1 mm radius of the one logged before it, so one event
    # per step (taken in any other order, cracks 1.6 mm apart would start events of
    # their own); the log interleaves the steps
    step = np.repeat([0, 1, 2], 20)   # crack c: its step, its place on its step's line
    rank = np.tile(np.arange(20), 3)
    log = np.random.default_rng(2).permutation(60)
    for s in range(3):   # each step's cracks, wherever they sit in the log, in chain order
        log[np.flatnonzero(step[log] == s)] = np.flatnonzero(step == s)
    time = 1e-6 * (1 + step[log])
    position = np.zeros((60, 3))
    position[:, 0] = 0.8e-3 * rank[log]
    position[:, 1] = 10e-3 * step[log]
    label = cracks.group_events(time, position, radius=1e-3, window=0.5e-6)
    assert label.tolist() == step[log].tolist()
    ae = cracks.events(time, position, np.ones(60), label)
    assert ae["cracks"].tolist() == [20, 20, 20] and ae["cracks"].dtype == np.int64


def test_b_value_counts_the_magnitudes_at_the_minimum():
    m = np.r_[np.full(3, -3.0), np.linspace(-2.9, -2.0, 8)]
    assert cracks.b_value(m, minimum=-3.0) == pytest.approx(
        math.log10(math.e) / (m.mean() + 3.0), rel=1e-12)


def test_crack_damage_looks_before_the_peak_only():
    # the compaction largest just after the peak: the pre-peak turn is still read
    assert cracks.crack_damage([1.0, 2.0, 3.0, 2.0], [0.0, 0.5, 0.4, 0.9]) == 2.0

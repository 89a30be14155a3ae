"""The flexible membrane's forces (lab/membrane.py) on hand-built particle sets, against
the pressure's definition: each cell of the lateral surface, R dtheta dz at the reach R of
the particle pressing it, pushes that particle towards the axis with sigma_3 times its area,
so the forces sum to sigma_3 times the lateral surface 2 pi R h and cancel as a vector on a
full ring. The axis is x here (not z) and the specimen sits off the origin, so a mixed-up
axis or centre shows."""
import math

import numpy as np
import pytest

from bondem.lab.membrane import membrane_forces, nearest_filled

PRESSURE = 2.5e5
N_THETA, N_Z = 12, 4
R_P = 1e-3                      # particle radius (m)
RHO = 5e-3                      # ring radius of the centres (m)
REACH = RHO + R_P
CELL = 2 * math.pi * REACH / N_THETA
LOW = 0.02                      # the specimen's lower end along x (m)
HIGH = LOW + N_Z * CELL
CENTRE = np.array([0.0, -0.03, 0.07])
D_THETA, D_Z = 2 * math.pi / N_THETA, (HIGH - LOW) / N_Z


def ring(rho, z, angles):
    """Particle centres at radius ``rho`` around the x axis through CENTRE, at ``z`` along x."""
    return CENTRE + np.column_stack([np.full(len(angles), z), rho * np.cos(angles),
                                     rho * np.sin(angles)])


def cells():
    """A particle at the middle of each cell: (positions, radii)."""
    angles = -math.pi + (np.arange(N_THETA) + 0.5) * D_THETA
    rows = [ring(RHO, LOW + (j + 0.5) * D_Z, angles) for j in range(N_Z)]
    position = np.vstack(rows)
    return position, np.full(len(position), R_P)


def radial(position):
    """Unit vectors from the axis (x through CENTRE) to each position."""
    out = position - CENTRE
    out[:, 0] = 0.0
    return out / np.linalg.norm(out, axis=1)[:, None]


def test_a_full_surface_is_pressed_cell_by_cell():
    position, radius = cells()
    force, area, mean_radius = membrane_forces(position, radius, 0, LOW, HIGH, PRESSURE, CELL)
    assert area == pytest.approx(2 * math.pi * REACH * (HIGH - LOW), rel=1e-12)
    assert mean_radius == pytest.approx(REACH, rel=1e-12)
    cell_area = REACH * D_THETA * D_Z
    np.testing.assert_allclose(force, -PRESSURE * cell_area * radial(position),
                               rtol=1e-9, atol=1e-12 * PRESSURE * cell_area)
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-9 * PRESSURE * cell_area)


def test_only_the_farthest_reach_of_a_cell_is_pressed():
    """Inner particles get nothing; of two in one cell the one whose surface reaches
    farther (centre distance plus radius) carries the cell, not the one whose centre is
    farther out."""
    position, radius = cells()
    # extra particles in opposite pairs: the centroid, hence the axis, stays at CENTRE
    inner = ring(0.4 * RHO, LOW + 1.5 * D_Z, np.array([0.3, 0.3 - math.pi]))
    # in cells 0 and 6 of row 0: centres farther out than the cells' own particles, but
    # small: they reach less far
    rival = ring(RHO + 0.4 * R_P, LOW + 0.4 * D_Z,
                 np.array([-math.pi + 0.6 * D_THETA, 0.6 * D_THETA]))
    big = 1.5 * R_P                                   # and cell 0's own particle grows
    position = np.vstack([position, inner, rival])
    radius = np.r_[radius, 1.2 * R_P, 1.2 * R_P, 0.5 * R_P, 0.5 * R_P]
    radius[0] = big
    force, area, _ = membrane_forces(position, radius, 0, LOW, HIGH, PRESSURE, CELL)
    n = N_THETA * N_Z
    assert np.all(force[n:] == 0.0)
    # the grown particle presses its cell at its own reach
    assert np.linalg.norm(force[0]) == pytest.approx(
        PRESSURE * (RHO + big) * D_THETA * D_Z, rel=1e-9)
    assert area == pytest.approx(REACH * D_THETA * D_Z * (n - 1)
                                 + (RHO + big) * D_THETA * D_Z, rel=1e-9)


def test_a_gap_is_spanned_by_its_nearest_neighbour_and_an_empty_row_is_not_pressed():
    position, radius = cells()
    row = np.arange(len(position)) // N_THETA
    cell = np.arange(len(position)) % N_THETA
    # gaps in opposite cells (the centroid stays): 4, 5, 6 of row 1 and 10, 11, 0 of row 2;
    # 1 and 7 of row 0
    gone = (row == 1) & ((cell == 4) | (cell == 5) | (cell == 6))
    gone |= (row == 0) & ((cell == 1) | (cell == 7))
    gone |= (row == 2) & ((cell == 10) | (cell == 11) | (cell == 0))
    gone |= row == 3                                                   # the top row empty
    force, area, mean_radius = membrane_forces(position[~gone], radius[~gone], 0, LOW, HIGH,
                                               PRESSURE, CELL)
    cell_area = REACH * D_THETA * D_Z
    share = np.ones(len(position))[~gone]
    kept = np.flatnonzero(~gone)
    # row 1: cell 4 goes to 3 (nearer), 5 to 3 (a tie: the one before), 6 to 7;
    # row 2, across the row's ends: 10 to 9, 11 to 9 (a tie), 0 to 1
    share[kept == 1 * N_THETA + 3] = 3
    share[kept == 1 * N_THETA + 7] = 2
    share[kept == 2 * N_THETA + 9] = 3
    share[kept == 2 * N_THETA + 1] = 2
    # row 0: 1 and 7 are ties, to 0 (the very first cell) and 6
    share[kept == 0] = 2
    share[kept == 6] = 2
    np.testing.assert_allclose(np.linalg.norm(force, axis=1), PRESSURE * cell_area * share,
                               rtol=1e-9)
    assert area == pytest.approx(3 * 2 * math.pi * REACH * D_Z, rel=1e-12)
    assert mean_radius == pytest.approx(REACH, rel=1e-12)


def test_the_mean_radius_weighs_each_pressing_particle_by_the_cells_it_presses():
    """Two particles of row 0 reach farther; one of them also spans an empty cell: the
    mean radius is the mean over all cells of the reach of the particle pressing each."""
    position, radius = cells()
    radius[[2, 7]] = 2 * R_P
    # cells 3 and 9 of row 0 empty (opposite: the centroid stays); both are ties between
    # their neighbours, so they go to the cell before: 3 to 2 (grown), 9 to 8
    keep = (np.arange(len(position)) != 3) & (np.arange(len(position)) != 9)
    _, area, mean_radius = membrane_forces(position[keep], radius[keep], 0, LOW, HIGH,
                                           PRESSURE, CELL)
    reach_of_cell = np.full(N_THETA * N_Z, REACH)
    reach_of_cell[[2, 3, 7]] = RHO + 2 * R_P
    assert mean_radius == pytest.approx(reach_of_cell.mean(), rel=1e-12)
    assert area == pytest.approx(reach_of_cell.sum() * D_THETA * D_Z, rel=1e-12)


def test_particles_beyond_the_platens_are_neither_pressed_nor_centred():
    """Particles below LOW or above HIGH (far off the axis: they would move the centroid)
    get no force; particles exactly at LOW and at HIGH are in the end rows."""
    position, radius = cells()
    outside = CENTRE + np.array([[LOW - 1e-4, 0.02, 0.0], [HIGH + 1e-4, 0.0, 0.02],
                                 [HIGH + 1e-3, 0.02, 0.02]])
    pair = np.array([-math.pi + 0.5 * D_THETA, 0.5 * D_THETA])        # cells 0 and 6
    ends = ring(RHO, LOW, pair)                                        # in row 0
    top = ring(RHO, HIGH, pair)                                        # in row 3
    small = 0.5 * R_P
    all_position = np.vstack([position, outside, ends, top])
    all_radius = np.r_[radius, np.full(3, R_P), np.full(4, small)]
    force, area, _ = membrane_forces(all_position, all_radius, 0, LOW, HIGH, PRESSURE, CELL)
    n = N_THETA * N_Z
    assert np.all(force[n:] == 0.0)      # outside: nothing; at the ends: a smaller reach
    reference, reference_area, _ = membrane_forces(position, radius, 0, LOW, HIGH, PRESSURE,
                                                   CELL)
    np.testing.assert_allclose(force[:n], reference, rtol=1e-6,
                               atol=1e-6 * np.abs(reference).max())
    assert area == pytest.approx(reference_area, rel=1e-6)


def test_coarse_cells_still_go_round_in_six():
    """A cell larger than the circumference: six cells around (the minimum), one row."""
    position, radius = cells()
    top = np.arange(len(position)) // N_THETA == 0
    force, area, _ = membrane_forces(position[top], radius[top], 0, LOW, LOW + D_Z,
                                     PRESSURE, 10.0)
    # six cells of 60 degrees, each holding two particles: one pressed per cell
    pressed = np.flatnonzero(np.linalg.norm(force, axis=1) > 0)
    assert pressed.size == 6
    np.testing.assert_allclose(np.linalg.norm(force[pressed], axis=1),
                               PRESSURE * REACH * (2 * math.pi / 6) * D_Z, rtol=1e-9)
    assert area == pytest.approx(2 * math.pi * REACH * D_Z, rel=1e-12)


def test_nothing_to_press():
    position, radius = cells()
    z0 = LOW + 0.5 * D_Z                 # the lowest row's height: inside, but no length
    for low, high in ((HIGH + 1.0, HIGH + 2.0), (z0, z0)):
        force, area, mean_radius = membrane_forces(position, radius, 0, low, high, PRESSURE,
                                                   CELL)
        assert np.all(force == 0.0) and force.shape == position.shape
        assert (area, mean_radius) == (0.0, 0.0)


def test_nearest_filled_goes_round_and_prefers_the_cell_before():
    grid = np.array([[0, 0, 1, 0, 0, 1, 0, 0, 0, 0],
                     [0, 1, 0, 0, 0, 1, 0, 0, 0, 0],
                     [1, 0, 0, 0, 0, 0, 0, 0, 0, 0],
                     [1, 1, 1, 1, 1, 1, 1, 1, 1, 1],
                     [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]], bool)
    out = nearest_filled(grid).reshape(5, 10)
    assert out[4].tolist() == [-1] * 10                 # a row without a particle
    # row 0: cell 9 is 3 after going round to 2, 4 after 5: it wraps to 2
    assert out[0].tolist() == [2, 2, 2, 2, 5, 5, 5, 5, 5, 2]
    # row 1: ties at 3 (1 and 5) and 8 (5 and 11 = 1): the cell before
    assert (out[1] - 10).tolist() == [1, 1, 1, 1, 5, 5, 5, 5, 5, 1]
    assert (out[2] - 20).tolist() == [0] * 10
    assert (out[3] - 30).tolist() == list(range(10))


def test_a_core_of_inner_particles_changes_nothing():
    """The cells are sized from the surface (the reach that 90 % of the particles stay
    within), so a specimen's core, here as many particles as its surface, leaves the
    cells and the forces as they were."""
    position, radius = cells()
    core = position.copy()
    core[:, 1:] = CENTRE[1:] + 0.5 * (position[:, 1:] - CENTRE[1:])   # half the radius
    force, area, _ = membrane_forces(np.vstack([position, core]), np.r_[radius, radius], 0,
                                     LOW, HIGH, PRESSURE, CELL)
    reference, reference_area, _ = membrane_forces(position, radius, 0, LOW, HIGH, PRESSURE,
                                                   CELL)
    n = len(position)
    np.testing.assert_allclose(force[:n], reference, rtol=1e-9,
                               atol=1e-9 * np.abs(reference).max())
    assert np.all(force[n:] == 0.0) and area == pytest.approx(reference_area, rel=1e-12)


def test_the_end_rows_reach_the_platens():
    """Particles exactly at the platens' heights belong to the end rows."""
    position, radius = cells()
    row = np.arange(len(position)) // N_THETA
    position[row == 0, 0] = LOW
    position[row == N_Z - 1, 0] = HIGH
    force, area, _ = membrane_forces(position, radius, 0, LOW, HIGH, PRESSURE, CELL)
    assert area == pytest.approx(2 * math.pi * REACH * (HIGH - LOW), rel=1e-12)
    np.testing.assert_allclose(np.linalg.norm(force, axis=1),
                               PRESSURE * REACH * D_THETA * D_Z, rtol=1e-9)


def test_a_particle_at_half_a_turn_is_in_the_last_cell():
    """atan2 gives +pi on the negative side of the first lateral axis: that particle is in
    the row's last cell (not the next row's first). Coordinates are binary fractions, so
    the centroid and the angle are exact; six cells of 60 degrees around."""
    c, d, r = 2.0 ** -8, 2.0 ** -7, 2.0 ** -10
    lateral = np.array([[c, c], [-c, c], [-c, -c], [c, -c], [-d, 0.0], [d, 0.0]])
    centre = np.array([0.5, -0.25, 0.125])
    position = centre + np.column_stack([np.zeros(6), lateral])   # x = 0.5: inside
    force, area, _ = membrane_forces(position, np.full(6, r), 0, 0.25, 0.75, PRESSURE, 10.0)
    # cells (from -180 degrees): 0 holds -135, 2 holds -45, 3 holds 0 and 45, 5 holds 135
    # and 180 (the farther); 1 and 4 are ties, given to 0 and 3
    sixth = 2 * math.pi / 6 * 0.5
    np.testing.assert_allclose(force[4], [0.0, PRESSURE * (d + r) * sixth, 0.0], rtol=1e-12)
    assert force[1].tolist() == [0.0, 0.0, 0.0]
    assert area == pytest.approx(sixth * (3 * (c * math.sqrt(2) + r) + 3 * (d + r)),
                                 rel=1e-12)


def test_a_few_particles_standing_out_leave_the_cells_as_they_were():
    """The cells are sized from the reach that 90 % of the particles stay within: five
    particles of 53 (under a tenth) standing out to three times the surface's reach press
    their own cells at their reach, and the cells stay those of the surface."""
    position, radius = cells()
    angles = -math.pi + 0.1 + 2 * math.pi / 5 * np.arange(5)     # a pentagon: centroid kept
    reach_out = 3 * REACH
    out = ring(reach_out - R_P, LOW + 1.5 * D_Z, angles)
    force, area, _ = membrane_forces(np.vstack([position, out]), np.r_[radius, np.full(5, R_P)],
                                     0, LOW, HIGH, PRESSURE, CELL)
    assert np.count_nonzero(np.linalg.norm(force, axis=1)) == N_THETA * N_Z
    np.testing.assert_allclose(np.linalg.norm(force[-5:], axis=1),
                               PRESSURE * reach_out * D_THETA * D_Z, rtol=1e-9)
    assert area == pytest.approx(D_THETA * D_Z * ((N_THETA * N_Z - 5) * REACH
                                                  + 5 * reach_out), rel=1e-9)

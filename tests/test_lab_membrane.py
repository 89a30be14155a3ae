"""The flexible membrane's forces (lab/membrane.py) on hand-built particle sets, against
the pressure's definition: in each row of cells the farthest-reaching particles are the
vertices of a closed polygon (at their reach points, in order round the axis) under the
pressure sigma_3 over the row's height dz, and each vertex carries half of each of its two
edges: sigma_3 dz times the edge's length along its inward normal. A pressure on a closed
surface has no resultant and no torque, whatever the surface's shape. The axis is x here
(not z) and the specimen sits off the origin, so a mixed-up axis or centre shows."""
import math

import numpy as np
import pytest

from bondem.lab.membrane import membrane_forces

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


def flat(position):
    """Lateral (y, z) coordinates of ``position`` from the axis through CENTRE."""
    return (position - CENTRE)[:, 1:]


def reach_point(position, radius):
    """Where each particle reaches farthest from the axis, (y, z) from the axis."""
    xy = flat(position)
    rho = np.linalg.norm(xy, axis=1)
    return xy * ((rho + radius) / rho)[:, None]


def fan_area(angles, reaches):
    """The area a polygon of vertices at ``angles`` (radians) and distances ``reaches``
    from the axis encloses: its triangles with the axis, 1/2 R_i R_i+1 sin(dtheta)."""
    order = np.argsort(angles)
    theta, r = np.asarray(angles)[order], np.asarray(reaches)[order]
    gap = np.diff(np.r_[theta, theta[0] + 2 * math.pi])
    return 0.5 * float(np.sum(r * np.roll(r, -1) * np.sin(gap)))


def regular(n, reach):
    """The area of a regular polygon of n vertices at ``reach``."""
    return 0.5 * n * reach ** 2 * math.sin(2 * math.pi / n)


def vertex_force(before, here, after, dz):
    """The (y, z) force on vertex ``here`` of an anticlockwise polygon: the pressure on
    half of each of its two edges, each along the edge's inward normal."""
    def edge(a, b):                      # sigma_3 dz |b - a| times the inward unit normal
        d = b - a
        return -PRESSURE * dz * np.array([d[1], -d[0]])
    return 0.5 * (edge(before, here) + edge(here, after))


def test_a_full_ring_is_a_regular_polygon():
    """A particle at the middle of every cell: each row is a regular polygon of N_THETA
    sides at the reach R, so every vertex is pushed towards the axis with
    sigma_3 dz R sin(dtheta) and the forces cancel; the membrane's radius is that of the
    polygon's area, N/2 R^2 sin(2 pi / N) = pi R_m^2, its lateral surface 2 pi R_m h."""
    position, radius = cells()
    force, area, mean_radius = membrane_forces(position, radius, 0, LOW, HIGH, PRESSURE, CELL)
    r_m = math.sqrt(regular(N_THETA, REACH) / math.pi)
    assert mean_radius == pytest.approx(r_m, rel=1e-12) and r_m < 0.98 * REACH
    assert area == pytest.approx(2 * math.pi * r_m * (HIGH - LOW), rel=1e-12)
    push = PRESSURE * D_Z * REACH * math.sin(D_THETA)
    np.testing.assert_allclose(force, -push * radial(position), rtol=1e-9,
                               atol=1e-12 * push)
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-12 * push)


def test_each_corner_of_a_rectangle_carries_half_of_its_two_sides():
    """Four particles reaching to the corners (+-a, +-b) of a rectangle, a != b (so
    swapped lateral axes show): each corner is pushed inwards by sigma_3 dz b along y and
    sigma_3 dz a along z, and the virial -sum(f . P) is 2 sigma_3 dz times the area 4 a b,
    the work of the pressure on a dilation."""
    a, b, r = 4e-3, 1.5e-3, 5e-4
    corner = np.array([[a, b], [-a, b], [-a, -b], [a, -b]])
    rho = np.hypot(corner[:, 0], corner[:, 1])
    centre = corner * ((rho - r) / rho)[:, None]
    position = CENTRE + np.column_stack([np.full(4, LOW + 1e-3), centre])
    high = LOW + 2e-3
    force, area, mean_radius = membrane_forces(position, np.full(4, r), 0, LOW, high,
                                               PRESSURE, 10.0)
    dz = high - LOW
    sign = np.sign(corner)
    np.testing.assert_allclose(force[:, 1:], -PRESSURE * dz * sign * [b, a], rtol=1e-9)
    assert np.all(force[:, 0] == 0.0)
    virial = -np.sum(force[:, 1:] * corner)
    assert virial == pytest.approx(2 * PRESSURE * dz * 4 * a * b, rel=1e-9)
    # the cross-section is the rectangle's 4 a b
    assert math.pi * mean_radius ** 2 == pytest.approx(4 * a * b, rel=1e-12)
    assert area == pytest.approx(2 * math.pi * mean_radius * dz, rel=1e-12)


def test_a_rough_broken_specimen_is_neither_pushed_nor_twisted():
    """Particles of mixed sizes scattered in a bulged, cracked cylinder: the membrane's
    forces sum to nothing and have no torque about the axis at the points they press
    (forces along each particle's own direction from the axis, sigma_3 R dtheta dz a
    cell, left a net force of 0.9 % of their sum on a lattice cylinder)."""
    rng = np.random.default_rng(7)
    n = 600
    z = rng.uniform(LOW, HIGH, n)
    angle = rng.uniform(-math.pi, math.pi, n)
    crack = np.abs(angle - 1.0) < 0.3                       # a wedge gone from the middle
    keep = ~(crack & (np.abs(z - 0.5 * (LOW + HIGH)) < D_Z))
    rho = RHO * (1.0 + 0.3 * np.sin(math.pi * (z - LOW) / (HIGH - LOW))) \
        * np.sqrt(rng.uniform(0.0, 1.0, n))
    position = CENTRE + np.column_stack([z, rho * np.cos(angle), rho * np.sin(angle)])
    position, radius = position[keep], rng.uniform(0.5, 1.5, keep.sum()) * R_P
    force, area, _ = membrane_forces(position, radius, 0, LOW, HIGH, PRESSURE, CELL)
    push = np.linalg.norm(force, axis=1)
    assert np.count_nonzero(push) > N_THETA * N_Z / 2 and area > 0.0
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-12 * push.sum())
    # the axis goes through the centroid of the particles between the platens
    point = reach_point(position - np.r_[0.0, flat(position).mean(axis=0)], radius)
    torque = point[:, 0] * force[:, 2] - point[:, 1] * force[:, 1]
    assert abs(torque.sum()) < 1e-12 * np.sum(push * np.linalg.norm(point, axis=1))


def test_only_the_farthest_reach_of_a_cell_is_pressed():
    """Inner particles get nothing; of two in one cell the one whose surface reaches
    farther (centre distance plus radius) is the vertex, not the one whose centre is
    farther out. A vertex's own force depends on its neighbours only; its neighbours'
    edges run to its new reach."""
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
    assert np.all(np.linalg.norm(force[:n], axis=1) > 0.0)
    point = reach_point(position[:N_THETA], radius[:N_THETA])
    for k in (N_THETA - 1, 0, 1):                     # cell 0 and its two neighbours
        expected = vertex_force(point[k - 1], point[k], point[(k + 1) % N_THETA], D_Z)
        np.testing.assert_allclose(force[k, 1:], expected, rtol=1e-9)
    middle = -math.pi + (np.arange(N_THETA) + 0.5) * D_THETA
    row0 = fan_area(middle, np.r_[RHO + big, np.full(N_THETA - 1, REACH)])
    r_m = math.sqrt((row0 + 3 * regular(N_THETA, REACH)) / 4 / math.pi)
    assert area == pytest.approx(2 * math.pi * r_m * (HIGH - LOW), rel=1e-9)


def test_a_gap_is_spanned_by_an_edge_and_a_row_of_two_or_none_is_not_pressed():
    position, radius = cells()
    row = np.arange(len(position)) // N_THETA
    cell = np.arange(len(position)) % N_THETA
    # gaps in opposite cells (the centroid stays): 4, 5, 6 of row 1 and 10, 11, 0 of row 2;
    # 1 and 7 of row 0; row 3 keeps only two opposite particles (the centroid stays)
    gone = (row == 1) & ((cell == 4) | (cell == 5) | (cell == 6))
    gone |= (row == 0) & ((cell == 1) | (cell == 7))
    gone |= (row == 2) & ((cell == 10) | (cell == 11) | (cell == 0))
    gone |= (row == 3) & (cell != 2) & (cell != 8)
    force, area, mean_radius = membrane_forces(position[~gone], radius[~gone], 0, LOW, HIGH,
                                               PRESSURE, CELL)
    kept = np.flatnonzero(~gone)
    point = reach_point(position, radius)
    for j in range(3):
        ring_cells = [k for k in range(N_THETA) if not gone[j * N_THETA + k]]
        for i, k in enumerate(ring_cells):
            before = point[j * N_THETA + ring_cells[i - 1]]
            after = point[j * N_THETA + ring_cells[(i + 1) % len(ring_cells)]]
            at = np.flatnonzero(kept == j * N_THETA + k)[0]
            expected = vertex_force(before, point[j * N_THETA + k], after, D_Z)
            np.testing.assert_allclose(force[at, 1:], expected, rtol=1e-9,
                                       atol=1e-12 * np.abs(expected).max())
    assert np.all(force[row[kept] == 3] == 0.0)
    np.testing.assert_allclose(force.sum(axis=0), 0.0,
                               atol=1e-12 * np.abs(force).sum())
    # three rows pressed, the fourth (two particles) not; the gaps cut the rows' areas
    middle = -math.pi + (np.arange(N_THETA) + 0.5) * D_THETA
    rows = [fan_area(middle[~gone[j * N_THETA:(j + 1) * N_THETA]],
                     np.full(np.count_nonzero(~gone[j * N_THETA:(j + 1) * N_THETA]), REACH))
            for j in range(3)]
    assert rows[0] < regular(N_THETA, REACH) and rows[1] < rows[0]
    r_m = math.sqrt(np.mean(rows) / math.pi)
    assert mean_radius == pytest.approx(r_m, rel=1e-12)
    assert area == pytest.approx(3 * 2 * math.pi * r_m * D_Z, rel=1e-12)


def test_the_radius_is_that_of_the_rows_mean_area():
    """Two particles of row 0 reach farther (cells 2 and 7); cells 3 and 9 of row 0 are
    empty: row 0's polygon encloses its own area, and the membrane's radius is that of
    the mean area of its rows."""
    position, radius = cells()
    radius[[2, 7]] = 2 * R_P
    keep = (np.arange(len(position)) != 3) & (np.arange(len(position)) != 9)
    _, area, mean_radius = membrane_forces(position[keep], radius[keep], 0, LOW, HIGH,
                                           PRESSURE, CELL)
    big = RHO + 2 * R_P
    middle = -math.pi + (np.arange(N_THETA) + 0.5) * D_THETA
    reach = np.full(N_THETA, REACH)
    reach[[2, 7]] = big
    row0 = fan_area(np.delete(middle, [3, 9]), np.delete(reach, [3, 9]))
    r_m = math.sqrt((row0 + 3 * regular(N_THETA, REACH)) / 4 / math.pi)
    assert mean_radius == pytest.approx(r_m, rel=1e-12)
    assert area == pytest.approx(2 * math.pi * r_m * (HIGH - LOW), rel=1e-12)


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
    """A cell larger than the circumference: six cells around (the minimum), one row;
    each cell holds two particles, the second of each a little larger and so its vertex:
    a regular hexagon."""
    position, radius = cells()
    top = np.arange(len(position)) // N_THETA == 0
    radius = radius[top] * np.tile([1.0, 1.1], N_THETA // 2)
    force, area, _ = membrane_forces(position[top], radius, 0, LOW, LOW + D_Z, PRESSURE,
                                     10.0)
    pressed = np.flatnonzero(np.linalg.norm(force, axis=1) > 0)
    assert pressed.tolist() == [1, 3, 5, 7, 9, 11]
    reach = RHO + 1.1 * R_P
    np.testing.assert_allclose(np.linalg.norm(force[pressed], axis=1),
                               PRESSURE * reach * math.sin(2 * math.pi / 6) * D_Z,
                               rtol=1e-9)
    r_m = math.sqrt(regular(6, reach) / math.pi)                 # 3 sqrt(3) / 2 R^2
    assert area == pytest.approx(2 * math.pi * r_m * D_Z, rel=1e-12)


def test_nothing_to_press():
    position, radius = cells()
    z0 = LOW + 0.5 * D_Z                 # the lowest row's height: inside, but no length
    for low, high in ((HIGH + 1.0, HIGH + 2.0), (z0, z0)):
        force, area, mean_radius = membrane_forces(position, radius, 0, low, high, PRESSURE,
                                                   CELL)
        assert np.all(force == 0.0) and force.shape == position.shape
        assert (area, mean_radius) == (0.0, 0.0)
    # two particles enclose nothing: a membrane round them pushes them together and apart
    # alike
    force, area, mean_radius = membrane_forces(position[[0, 6]], radius[[0, 6]], 0, LOW,
                                               LOW + D_Z, PRESSURE, CELL)
    assert np.all(force == 0.0) and (area, mean_radius) == (0.0, 0.0)


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
    r_m = math.sqrt(regular(N_THETA, REACH) / math.pi)
    assert area == pytest.approx(2 * math.pi * r_m * (HIGH - LOW), rel=1e-12)
    np.testing.assert_allclose(np.linalg.norm(force, axis=1),
                               PRESSURE * REACH * math.sin(D_THETA) * D_Z, rtol=1e-9)


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
    # and 180 (the farther): the polygon -135, -45, 0, 180
    diagonal = (c * math.sqrt(2) + r) / math.sqrt(2)
    point = np.array([[-diagonal, -diagonal], [diagonal, -diagonal], [d + r, 0.0],
                      [-d - r, 0.0]])
    np.testing.assert_allclose(force[4, 1:], vertex_force(point[2], point[3], point[0], 0.5),
                               rtol=1e-12)
    assert force[1].tolist() == [0.0, 0.0, 0.0] and force[0].tolist() == [0.0, 0.0, 0.0]
    # gaps of 90, 45, 180 and 45 degrees between the four vertices
    reach = np.array([c * math.sqrt(2) + r, c * math.sqrt(2) + r, d + r, d + r])
    enclosed = fan_area(np.radians([-135.0, -45.0, 0.0, 180.0]), reach)
    assert enclosed == pytest.approx(0.5 * reach[0] ** 2 + 2 * 0.5 * reach[0] * reach[2]
                                     * math.sin(math.pi / 4), rel=1e-12)
    assert area == pytest.approx(2 * math.pi * math.sqrt(enclosed / math.pi) * 0.5,
                                 rel=1e-12)


def test_a_few_particles_standing_out_leave_the_cells_as_they_were():
    """The cells are sized from the reach that 90 % of the particles stay within: five
    particles of 53 (under a tenth) standing out to three times the surface's reach are
    vertices of their own cells (whose neighbours push them as a regular ring's vertex,
    towards the axis along the cell's middle), and the cells stay those of the surface."""
    position, radius = cells()
    angles = -math.pi + 0.1 + 2 * math.pi / 5 * np.arange(5)     # a pentagon: centroid kept
    reach_out = 3 * REACH
    out = ring(reach_out - R_P, LOW + 1.5 * D_Z, angles)
    force, area, _ = membrane_forces(np.vstack([position, out]), np.r_[radius, np.full(5, R_P)],
                                     0, LOW, HIGH, PRESSURE, CELL)
    assert np.count_nonzero(np.linalg.norm(force, axis=1)) == N_THETA * N_Z
    middle = -math.pi + (np.floor((angles + math.pi) / D_THETA) + 0.5) * D_THETA
    inwards = -np.column_stack([np.cos(middle), np.sin(middle)])
    np.testing.assert_allclose(force[-5:, 1:], PRESSURE * D_Z * REACH * math.sin(D_THETA)
                               * inwards, rtol=1e-9)
    # row 1: the spikes replace their cells' own vertices
    cell_middle = -math.pi + (np.arange(N_THETA) + 0.5) * D_THETA
    replaced = np.round((middle + math.pi) / D_THETA - 0.5).astype(int)
    row1 = fan_area(np.r_[np.delete(cell_middle, replaced), angles],
                    np.r_[np.full(N_THETA - 5, REACH), np.full(5, reach_out)])
    r_m = math.sqrt((row1 + 3 * regular(N_THETA, REACH)) / 4 / math.pi)
    assert area == pytest.approx(2 * math.pi * r_m * (HIGH - LOW), rel=1e-9)

"""CPU loops for contacts: one slot per listed pair, then a gather by particle.

Each particle-particle pair and each particle-wall candidate writes its loads to its own
row; particles sum their rows through fixed CSR indices built with the Verlet list. No
atomics, so the sums are the same bits with any number of threads.
"""
import numba
from numba import prange

from . import loops
from .cpu import CHUNK, L, _jit, _serial, chunks

MODEL_HERTZ, MODEL_LINEAR = loops.MODEL_HERTZ, loops.MODEL_LINEAR
LINEAR_REFERENCE_OVERLAP = loops.LINEAR_REFERENCE_OVERLAP
pair_contact = L.pair_contact
pair_rows_sum = L.pair_rows_sum
wall_contacts_of = L.wall_contacts_of
add_wall_rows = L.add_wall_rows
# The compiled physics, for tests that call one law directly.
hertz_mindlin = L.hertz_mindlin
restitution_beta = L.restitution_beta


@numba.njit(**_serial)
def pair_contact_range(first, last, live, pairs, pair_bond, bond_active, particles, grains,
                       materials, law, linear_stiffness, use_rolling, box, rows, dt,
                       moved_dt):
    """``loops.pair_contact`` for the rows live[first:last]."""
    for s in range(first, last):
        pair_contact(live[s], pairs, pair_bond, bond_active, particles, grains, materials,
                     law, linear_stiffness, use_rolling, box, rows, dt, moved_dt)


@numba.njit(**_jit)
def particle_contacts(live, pairs, pair_bond, bond_active, particles, grains, materials,
                      law, linear_stiffness, use_rolling, box, rows, dt, moved_dt):
    """Loads, stored energy and dissipation of every contact row listed in ``live``
    (``loops.pair_contact``), advancing the springs by dt (s); moved_dt (s): time since
    the previous evaluation.

    Only the rows listed in ``live`` are visited: the other rows belong to pairs joined by
    an intact bond, which carry no contact load and keep zero rows (bonds never form during
    a run), so skipping them saves the memory traffic of every bonded neighbour.
    linear_stiffness: None for Hertz-Mindlin (the linear law is then not compiled), else
    k_n (N/m, 0 for the default) of the linear law.
    """
    n = live.shape[0]
    for c in prange(chunks(n)):
        pair_contact_range(c * CHUNK, min(n, (c + 1) * CHUNK), live, pairs, pair_bond,
                           bond_active, particles, grains, materials, law, linear_stiffness,
                           use_rolling, box, rows, dt, moved_dt)


@numba.njit(**_serial)
def gather_pair_range(first, last, index, rows, force, moment):
    """Add the contact loads of particles first to last - 1 (``loops.pair_rows_sum``)."""
    for p in range(first, last):
        f, m = pair_rows_sum(p, index, rows)
        for k in range(3):
            force[p, k] += f[k]
            moment[p, k] += m[k]


@numba.njit(**_jit)
def gather_pair_loads(index, rows, force, moment):
    """Add each particle's contact loads (a ``loops.PairIndex`` over the live rows) to
    force (N) and moment (N m)."""
    n = index.i_start.shape[0] - 1
    for c in prange(chunks(n)):
        gather_pair_range(c * CHUNK, min(n, (c + 1) * CHUNK), index, rows, force, moment)


@numba.njit(**_serial)
def wall_contact_range(first, last, wall_start, wall_pairs, walls, particles, grains,
                       materials, law, linear_stiffness, use_rolling, triangles, rows, dt,
                       moved_dt, force, moment):
    """``loops.wall_contacts_of`` for particles first to last - 1, then their wall loads
    added to force (N) and moment (N m)."""
    for p in range(first, last):
        wall_contacts_of(p, wall_start, wall_pairs, walls, particles, grains, materials, law,
                         linear_stiffness, use_rolling, triangles, rows, dt, moved_dt)
        add_wall_rows(p, wall_start, rows, force, moment)


@numba.njit(**_jit)
def wall_contacts(wall_start, wall_pairs, walls, particles, grains, materials, law,
                  linear_stiffness, use_rolling, triangles, rows, dt, moved_dt, force,
                  moment):
    """Loads of every particle-wall candidate (``loops.wall_contacts_of``; rows sorted by
    particle, ``wall_start`` their CSR offsets), added to force (N) and moment (N m).
    triangles: None when every wall element is a plane (the triangle code is then not
    compiled), else True."""
    n = wall_start.shape[0] - 1
    for c in prange(chunks(n)):
        wall_contact_range(c * CHUNK, min(n, (c + 1) * CHUNK), wall_start, wall_pairs, walls,
                           particles, grains, materials, law, linear_stiffness, use_rolling,
                           triangles, rows, dt, moved_dt, force, moment)


@numba.njit(cache=True, nogil=True)
def wall_totals(wall_pairs, element_wall, scratch_point, force_c, moment_c, position, radius,
                wall_reference, out_force, out_torque):
    """Force (N) and torque (N m, about each wall's reference point) on every wall, summed
    serially in list order (deterministic)."""
    out_force[:] = 0.0
    out_torque[:] = 0.0
    for c in range(wall_pairs.shape[0]):
        if force_c[c, 0] == 0.0 and force_c[c, 1] == 0.0 and force_c[c, 2] == 0.0:
            continue
        p = wall_pairs[c, 0]
        w = element_wall[wall_pairs[c, 1]]
        f = (-force_c[c, 0], -force_c[c, 1], -force_c[c, 2])
        r = (scratch_point[c, 0] - wall_reference[w, 0], scratch_point[c, 1] - wall_reference[w, 1],
             scratch_point[c, 2] - wall_reference[w, 2])
        # The particle's couple about the contact point, M_x + (x - q) x F, acts back on the wall.
        arm = (position[p, 0] - scratch_point[c, 0], position[p, 1] - scratch_point[c, 1],
               position[p, 2] - scratch_point[c, 2])
        m_part = (moment_c[c, 0] + (arm[1] * force_c[c, 2] - arm[2] * force_c[c, 1]),
                  moment_c[c, 1] + (arm[2] * force_c[c, 0] - arm[0] * force_c[c, 2]),
                  moment_c[c, 2] + (arm[0] * force_c[c, 1] - arm[1] * force_c[c, 0]))
        out_force[w, 0] += f[0]
        out_force[w, 1] += f[1]
        out_force[w, 2] += f[2]
        out_torque[w, 0] += r[1] * f[2] - r[2] * f[1] - m_part[0]
        out_torque[w, 1] += r[2] * f[0] - r[0] * f[2] - m_part[1]
        out_torque[w, 2] += r[0] * f[1] - r[1] * f[0] - m_part[2]

"""CPU loops for contacts: one slot per listed pair, then a gather by particle.

Each particle-particle pair and each particle-wall candidate writes its loads to its own
row; particles sum their rows through fixed CSR indices built with the Verlet list. No
atomics, so the sums are the same bits with any number of threads.
"""
import numba
import numpy as np
from numba import prange

from ..physics import compile_physics
from ..physics.triangle import FACE
from ..walls import PLANE

P = compile_physics(numba.njit(cache=False))
hertz_mindlin = P.hertz_mindlin
linear_spring_dashpot = P.linear_spring_dashpot
contact_moments = P.contact_moments
contact_relative_velocity = P.contact_relative_velocity
effective_young_modulus = P.effective_young_modulus
effective_shear_modulus = P.effective_shear_modulus
restitution_beta = P.restitution_beta
closest_point_on_triangle = P.closest_point_on_triangle

MODEL_HERTZ, MODEL_LINEAR = 0, 1
LINEAR_REFERENCE_OVERLAP = 0.01  # delta_ref / R* of the default linear stiffness

_jit = dict(parallel=True, cache=True, fastmath=False, nogil=True)


@numba.njit(cache=True, nogil=True)
def _pair_law(n, overlap, v_rel, w_rel, spring, young_i, poisson_i, young_j, poisson_j,
              restitution, friction, rolling, r_star, m_star, i_star, linear_stiffness, dt):
    """Loads of one contact. The law is chosen by the type of ``linear_stiffness``: None
    for Hertz-Mindlin, a float k_n (N/m; <= 0 for the default) for the linear law, so
    that Numba compiles only the law a scene uses."""
    e_star = effective_young_modulus(young_i, poisson_i, young_j, poisson_j)
    g_star = effective_shear_modulus(young_i, poisson_i, young_j, poisson_j)
    beta = restitution_beta(restitution)
    if linear_stiffness is None:
        return hertz_mindlin(n, overlap, v_rel, w_rel, spring, e_star, g_star, r_star, m_star,
                             i_star, beta, friction, rolling, dt)
    k_n = linear_stiffness
    if k_n <= 0.0:
        k_n = 2.0 * e_star * np.sqrt(LINEAR_REFERENCE_OVERLAP) * r_star
    return linear_spring_dashpot(n, overlap, v_rel, w_rel, spring, k_n,
                                 4.0 * k_n * g_star / e_star, r_star, m_star, i_star, beta,
                                 friction, rolling, dt)


@numba.njit(cache=True, nogil=True)
def minimum_image_component(d, length, periodic):
    """Component d (m) of a separation, wrapped into [-length/2, length/2) if periodic."""
    if periodic:
        return d - length * np.floor(d / length + 0.5)
    return d


@numba.njit(**_jit)
def particle_contacts(pairs, live, pair_bond, bond_active, position, velocity,
                      angular_velocity, radius, mass, inertia, material, young, poisson,
                      restitution, friction, rolling, use_rolling, linear_stiffness, box_length,
                      periodic, spring, dt, moved_dt, force_c, moment_i_c, moment_j_c,
                      energy_c, out_dissipated):
    """Loads of every listed pair (force on i, moments on i and j) and its stored energy,
    written over the previous step's rows, which are read first for the work balance.

    Only the rows listed in ``live`` are visited: the other rows belong to pairs joined by
    an intact bond, which carry no contact load and keep zero rows (bonds never form during
    a run), so skipping them saves the memory traffic of every bonded neighbour. Pairs
    not touching, or joined by an intact bond (pair_bond >= 0), get zero loads and their
    tangential spring is reset. out_dissipated: J removed by the contact since the
    previous evaluation, moved_dt (s) ago: minus the work of its loads on the particles
    (trapezoidal in the loads, with the velocities that moved the particles) minus the
    change of its stored energy.
    """
    for s in prange(live.shape[0]):
        c = live[s]
        i = pairs[c, 0]
        j = pairs[c, 1]
        vi = (velocity[i, 0], velocity[i, 1], velocity[i, 2])
        vj = (velocity[j, 0], velocity[j, 1], velocity[j, 2])
        wi = (angular_velocity[i, 0], angular_velocity[i, 1], angular_velocity[i, 2])
        wj = (angular_velocity[j, 0], angular_velocity[j, 1], angular_velocity[j, 2])
        # Work of the previous loads over the step just made (their half of the trapezoid).
        work = 0.0
        for k in range(3):
            work += (force_c[c, k] * (vi[k] - vj[k]) + moment_i_c[c, k] * wi[k]
                     + moment_j_c[c, k] * wj[k])
        previous_energy = energy_c[c]
        r = (minimum_image_component(position[j, 0] - position[i, 0], box_length[0],
                                     periodic[0]),
             minimum_image_component(position[j, 1] - position[i, 1], box_length[1],
                                     periodic[1]),
             minimum_image_component(position[j, 2] - position[i, 2], box_length[2],
                                     periodic[2]))
        distance = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        overlap = radius[i] + radius[j] - distance
        bonded = pair_bond[c] >= 0 and bond_active[pair_bond[c]]
        if overlap <= 0.0 or bonded or distance == 0.0:
            for k in range(3):
                spring[c, k] = 0.0
                force_c[c, k] = 0.0
                moment_i_c[c, k] = 0.0
                moment_j_c[c, k] = 0.0
            energy_c[c] = 0.0
            out_dissipated[c] = -0.5 * moved_dt * work + previous_energy
            continue
        n = (r[0] / distance, r[1] / distance, r[2] / distance)
        arm_i = radius[i] - 0.5 * overlap
        arm_j = radius[j] - 0.5 * overlap
        v_rel = contact_relative_velocity(n, vi, vj, wi, wj, arm_i, arm_j)
        w_rel = (wi[0] - wj[0], wi[1] - wj[1], wi[2] - wj[2])
        a = material[i]
        b = material[j]
        mu_r = 0.5 * (rolling[a] + rolling[b]) if use_rolling else 0.0
        force_i, torque, f_t, xi, energy = _pair_law(
            n, overlap, v_rel, w_rel, (spring[c, 0], spring[c, 1], spring[c, 2]),
            young[a], poisson[a], young[b], poisson[b],
            0.5 * (restitution[a] + restitution[b]), 0.5 * (friction[a] + friction[b]), mu_r,
            radius[i] * radius[j] / (radius[i] + radius[j]),
            mass[i] * mass[j] / (mass[i] + mass[j]),
            inertia[i] * inertia[j] / (inertia[i] + inertia[j]), linear_stiffness, dt)
        moment_i, moment_j = contact_moments(n, f_t, torque, arm_i, arm_j)
        for k in range(3):
            spring[c, k] = xi[k]
            force_c[c, k] = force_i[k]
            moment_i_c[c, k] = moment_i[k]
            moment_j_c[c, k] = moment_j[k]
            work += force_i[k] * (vi[k] - vj[k]) + moment_i[k] * wi[k] + moment_j[k] * wj[k]
        energy_c[c] = energy
        out_dissipated[c] = -0.5 * moved_dt * work - (energy - previous_energy)


@numba.njit(**_jit)
def gather_pair_loads(i_start, i_order, j_start, j_order, force_c, moment_i_c, moment_j_c,
                      force, moment):
    """Add contact loads per particle: rows where it is i (through i_order), then rows
    where it is j (through j_order), each in a fixed order."""
    for p in prange(i_start.shape[0] - 1):
        fx = fy = fz = mx = my = mz = 0.0
        for s in range(i_start[p], i_start[p + 1]):
            c = i_order[s]
            fx += force_c[c, 0]
            fy += force_c[c, 1]
            fz += force_c[c, 2]
            mx += moment_i_c[c, 0]
            my += moment_i_c[c, 1]
            mz += moment_i_c[c, 2]
        for s in range(j_start[p], j_start[p + 1]):
            c = j_order[s]
            fx -= force_c[c, 0]
            fy -= force_c[c, 1]
            fz -= force_c[c, 2]
            mx += moment_j_c[c, 0]
            my += moment_j_c[c, 1]
            mz += moment_j_c[c, 2]
        force[p, 0] += fx
        force[p, 1] += fy
        force[p, 2] += fz
        moment[p, 0] += mx
        moment[p, 1] += my
        moment[p, 2] += mz


@numba.njit(cache=True, nogil=True)
def _plane_contact(x, rows):
    """(signed distance (m) of centre x from the plane rows (point, unit normal), its
    closest point, FACE)."""
    d = ((x[0] - rows[0, 0]) * rows[1, 0] + (x[1] - rows[0, 1]) * rows[1, 1]
         + (x[2] - rows[0, 2]) * rows[1, 2])
    return d, (x[0] - d * rows[1, 0], x[1] - d * rows[1, 1], x[2] - d * rows[1, 2]), FACE


@numba.njit(cache=True, nogil=True)
def _element_contact(x, radius, rows, etype, triangles):
    """(distance from centre to the closest point (m), closest point, feature).
    triangles: None when every element is a plane (Numba then leaves the triangle code
    out), True otherwise."""
    if triangles is None:
        return _plane_contact(x, rows)
    if etype == PLANE:
        return _plane_contact(x, rows)
    q, feature = closest_point_on_triangle(
        (x[0], x[1], x[2]), (rows[0, 0], rows[0, 1], rows[0, 2]),
        (rows[1, 0], rows[1, 1], rows[1, 2]), (rows[2, 0], rows[2, 1], rows[2, 2]))
    d = np.sqrt((x[0] - q[0]) ** 2 + (x[1] - q[1]) ** 2 + (x[2] - q[2]) ** 2)
    return d, q, feature


@numba.njit(**_jit)
def wall_contacts(wall_start, wall_pairs, rows, types, element_wall, wall_velocity,
                  wall_omega, wall_center, wall_young, wall_poisson, wall_restitution,
                  wall_friction, wall_rolling, position, velocity, angular_velocity, radius,
                  mass, inertia, material, young, poisson, restitution, friction, rolling,
                  use_rolling, linear_stiffness, triangles, spring, dt, moved_dt,
                  scratch_distance, scratch_point,
                  scratch_feature, force_c, moment_c, energy_c, out_dissipated, out_work):
    """Loads of every particle-wall candidate (force and moment on the particle) and its
    stored energy, written over the previous step's rows (read first); out_work: J done
    by the moving wall since the previous evaluation, out_dissipated: J removed (work of
    the wall - work on the particle - change of stored energy, trapezoidal as for pairs).

    A triangle hit at point q is dropped when another touching triangle of the same wall
    contains q (within 1e-9 r) and has its own closest point elsewhere (then strictly
    closer: q is no local minimum of the distance to the mesh), or at q too and comes
    earlier in the list (a shared edge or vertex counted once). No distance comparison,
    so a centre just beside an edge is not counted twice.
    """
    for p in prange(wall_start.shape[0] - 1):
        x = position[p]
        tol = 1e-9 * radius[p]
        for c in range(wall_start[p], wall_start[p + 1]):
            e = wall_pairs[c, 1]
            d, q, feature = _element_contact(x, radius[p], rows[e], types[e], triangles)
            scratch_distance[c] = d
            scratch_feature[c] = feature
            for k in range(3):
                scratch_point[c, k] = q[k]
        # Which hits count (scratch_feature becomes 1 for kept, 0 for dropped).
        for c in range(wall_start[p], wall_start[p + 1]):
            e = wall_pairs[c, 1]
            q = (scratch_point[c, 0], scratch_point[c, 1], scratch_point[c, 2])
            d = scratch_distance[c]
            keep = d < radius[p] and d > -radius[p] and (types[e] == PLANE or d > 0.0)
            if triangles is not None and keep and types[e] != PLANE:
                for c2 in range(wall_start[p], wall_start[p + 1]):
                    e2 = wall_pairs[c2, 1]
                    if c2 == c or element_wall[e2] != element_wall[e] or types[e2] == PLANE:
                        continue
                    if scratch_distance[c2] >= radius[p]:
                        continue
                    inside, _, _ = _element_contact(q, radius[p], rows[e2], types[e2],
                                                    triangles)
                    if inside >= tol:
                        continue
                    gap = 0.0
                    for k in range(3):
                        gap += (scratch_point[c, k] - scratch_point[c2, k]) ** 2
                    # Triangle e2 holds q: its own closest point is then either elsewhere
                    # and strictly closer (q is no local minimum) or q itself (a shared
                    # edge or vertex, counted once, by the first hit).
                    if gap > tol * tol or c2 < c:
                        keep = False
                        break
            scratch_feature[c] = 1 if keep else 0
        # A sphere moving across a mesh changes triangles: a new hit takes over the spring
        # of a hit of the same wall that ended now, so the tangential force carries on.
        for c in range(wall_start[p], wall_start[p + 1]):
            if scratch_feature[c] != 1 or spring[c, 0] != 0.0 or spring[c, 1] != 0.0 \
                    or spring[c, 2] != 0.0:
                continue
            for c2 in range(wall_start[p], wall_start[p + 1]):
                if scratch_feature[c2] == 0 and element_wall[wall_pairs[c2, 1]] == \
                        element_wall[wall_pairs[c, 1]] and (spring[c2, 0] != 0.0 or
                                                            spring[c2, 1] != 0.0 or
                                                            spring[c2, 2] != 0.0):
                    for k in range(3):
                        spring[c, k] = spring[c2, k]
                        spring[c2, k] = 0.0
                    break
        vi = (velocity[p, 0], velocity[p, 1], velocity[p, 2])
        wi = (angular_velocity[p, 0], angular_velocity[p, 1], angular_velocity[p, 2])
        for c in range(wall_start[p], wall_start[p + 1]):
            e = wall_pairs[c, 1]
            w = element_wall[e]
            om = (wall_omega[w, 0], wall_omega[w, 1], wall_omega[w, 2])
            q = (scratch_point[c, 0], scratch_point[c, 1], scratch_point[c, 2])
            lever = (q[0] - wall_center[w, 0], q[1] - wall_center[w, 1], q[2] - wall_center[w, 2])
            v_wall = (wall_velocity[w, 0] + om[1] * lever[2] - om[2] * lever[1],
                      wall_velocity[w, 1] + om[2] * lever[0] - om[0] * lever[2],
                      wall_velocity[w, 2] + om[0] * lever[1] - om[1] * lever[0])
            on_particle = 0.0
            by_wall = 0.0
            for k in range(3):
                on_particle += force_c[c, k] * vi[k] + moment_c[c, k] * wi[k]
                by_wall += force_c[c, k] * v_wall[k]
            previous_energy = energy_c[c]
            d = scratch_distance[c]
            keep = scratch_feature[c] == 1
            if not keep:
                for k in range(3):
                    spring[c, k] = 0.0
                    force_c[c, k] = 0.0
                    moment_c[c, k] = 0.0
                energy_c[c] = 0.0
                out_work[c] = 0.5 * moved_dt * by_wall
                out_dissipated[c] = 0.5 * moved_dt * (by_wall - on_particle) + previous_energy
                continue
            if types[e] == PLANE:
                n = (-rows[e, 1, 0], -rows[e, 1, 1], -rows[e, 1, 2])
            else:
                n = ((q[0] - x[0]) / d, (q[1] - x[1]) / d, (q[2] - x[2]) / d)
            overlap = radius[p] - d
            arm = d
            v_rel = contact_relative_velocity(n, vi, v_wall, wi, (0.0, 0.0, 0.0), arm, 0.0)
            w_rel = (wi[0] - om[0], wi[1] - om[1], wi[2] - om[2])
            a = material[p]
            mu_r = 0.5 * (rolling[a] + wall_rolling[w]) if use_rolling else 0.0
            force_i, torque, f_t, xi, energy = _pair_law(
                n, overlap, v_rel, w_rel, (spring[c, 0], spring[c, 1], spring[c, 2]),
                young[a], poisson[a], wall_young[w], wall_poisson[w],
                0.5 * (restitution[a] + wall_restitution[w]),
                0.5 * (friction[a] + wall_friction[w]), mu_r, radius[p], mass[p], inertia[p],
                linear_stiffness, dt)
            moment_i, _ = contact_moments(n, f_t, torque, arm, 0.0)
            for k in range(3):
                spring[c, k] = xi[k]
                force_c[c, k] = force_i[k]
                moment_c[c, k] = moment_i[k]
                on_particle += force_i[k] * vi[k] + moment_i[k] * wi[k]
                # The rolling torque is the couple about the contact point, turning with the
                # wall at w_wall; the previous one is not kept, so the current one counts
                # for the whole step.
                by_wall += force_i[k] * v_wall[k] + 2.0 * torque[k] * om[k]
            energy_c[c] = energy
            out_work[c] = 0.5 * moved_dt * by_wall
            out_dissipated[c] = (0.5 * moved_dt * (by_wall - on_particle)
                                 - (energy - previous_energy))


@numba.njit(**_jit)
def gather_wall_loads(wall_start, force_c, moment_c, force, moment):
    """Add wall loads per particle (wall candidates sorted by particle)."""
    for p in prange(wall_start.shape[0] - 1):
        for c in range(wall_start[p], wall_start[p + 1]):
            for k in range(3):
                force[p, k] += force_c[c, k]
                moment[p, k] += moment_c[c, k]


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

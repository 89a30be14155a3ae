"""Particle contacts and walls on the CUDA backend: the CPU ContactLaw's loops as kernels.

``ContactLawGpu`` is ``contacts.ContactLaw`` with its per-step loops moved to the device;
the kernels are line-for-line ports of ``backends/cpu_contacts.py`` and call the same
``@physics`` functions (hertz_mindlin, linear_spring_dashpot, friction_and_rolling,
contact_moments, closest_point_on_triangle), compiled with ``cuda.jit(device=True)``.

What runs where:
- every step, on the device: the rebuild test (largest displacement since the list was
  built, minimum image, plus the walls' motion bound), the pair kernel (one thread per
  listed pair, each writing its own row), the pair gather (one thread per particle, CSR,
  no atomics), the wall kernel (one thread per particle: its wall candidates, the
  double-hit filter of meshes, the spring hand-over, the loads, and the gather of its
  wall rows, in the CPU's order);
- at a list rebuild (rare: a particle moved half the skin), on the host: the device
  position, bond flags and history rows are copied back, the CPU ``ContactLaw`` rebuilds
  the lists with the same code (so the lists, their order and the carried springs are the
  CPU's), and the new lists go back to the device;
- at the end of each batch of steps (``to_host``): the history rows are copied into
  ``state.extra`` with the CPU layout (contact_pairs, contact_spring, ..., wall_pairs,
  wall_spring, ...), the dissipated energy and wall work counters are added to
  ``contact_counters`` and ``wall_force`` / ``wall_torque`` of the last step are summed
  on the host by the CPU's ``wall_totals`` (serial, list order).

Differences from the CPU law that do not change results: every listed pair is visited
(the CPU visits only pairs not held by an intact bond; on the device such a pair's row is
left at zero, as the CPU leaves it), so the gather adds exact zeros; energy counters are
summed per particle, then on the host, instead of per step (round-off only).
"""
import math

import numpy as np
from numba import cuda

from ..contacts import PAIR_HISTORY, WALL_HISTORY, ContactLaw, _csr_by
from ..physics import compile_physics
from ..physics.triangle import FACE
from ..walls import PLANE
from . import cpu_contacts
from .cuda import THREADS, _blocks

D = compile_physics(cuda.jit(device=True))
hertz_mindlin = D.hertz_mindlin
linear_spring_dashpot = D.linear_spring_dashpot
contact_moments = D.contact_moments
contact_relative_velocity = D.contact_relative_velocity
effective_young_modulus = D.effective_young_modulus
effective_shear_modulus = D.effective_shear_modulus
restitution_beta = D.restitution_beta
closest_point_on_triangle = D.closest_point_on_triangle

MODEL_HERTZ = cpu_contacts.MODEL_HERTZ
LINEAR_REFERENCE_OVERLAP = cpu_contacts.LINEAR_REFERENCE_OVERLAP


@cuda.jit(device=True)
def _pair_law(law, n, overlap, v_rel, w_rel, spring, young_i, poisson_i, young_j, poisson_j,
              restitution, friction, rolling, r_star, m_star, i_star, linear_stiffness, dt):
    """cpu_contacts._pair_law on the device: material means -> the chosen physics law."""
    e_star = effective_young_modulus(young_i, poisson_i, young_j, poisson_j)
    g_star = effective_shear_modulus(young_i, poisson_i, young_j, poisson_j)
    beta = restitution_beta(restitution)
    if law == MODEL_HERTZ:
        return hertz_mindlin(n, overlap, v_rel, w_rel, spring, e_star, g_star, r_star, m_star,
                             i_star, beta, friction, rolling, dt)
    k_n = linear_stiffness
    if k_n <= 0.0:
        k_n = 2.0 * e_star * math.sqrt(LINEAR_REFERENCE_OVERLAP) * r_star
    return linear_spring_dashpot(n, overlap, v_rel, w_rel, spring, k_n,
                                 4.0 * k_n * g_star / e_star, r_star, m_star, i_star, beta,
                                 friction, rolling, dt)


@cuda.jit(device=True)
def _image(d, length, periodic):
    """Component d (m) wrapped into [-length/2, length/2) if periodic (minimum image)."""
    if periodic:
        return d - length * math.floor(d / length + 0.5)
    return d


@cuda.jit
def displacement_flag_kernel(position, reference, box_length, periodic, limit_squared, flag):
    """flag[0] = 1 when a particle moved more than sqrt(limit_squared) (m, minimum image)
    since the lists were built (a plain store of 1: any order gives the same flag)."""
    p = cuda.grid(1)
    if p < position.shape[0]:
        d2 = 0.0
        for k in range(3):
            d = _image(position[p, k] - reference[p, k], box_length[k], periodic[k])
            d2 += d * d
        if d2 > limit_squared:
            flag[0] = 1


@cuda.jit
def particle_contacts_kernel(law, pairs, pair_bond, bond_active, position, velocity,
                             angular_velocity, radius, mass, inertia, material, young, poisson,
                             restitution, friction, rolling, use_rolling, linear_stiffness,
                             box_length, periodic, spring, dt, moved_dt, force_c, moment_i_c,
                             moment_j_c, energy_c, out_dissipated):
    """One thread per listed pair: cpu_contacts.particle_contacts for that row (see
    there). A pair held by an intact bond keeps its zero rows and dissipates nothing."""
    c = cuda.grid(1)
    if c >= pairs.shape[0]:
        return
    if pair_bond[c] >= 0 and bond_active[pair_bond[c]]:
        out_dissipated[c] = 0.0
        return
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
    r = (_image(position[j, 0] - position[i, 0], box_length[0], periodic[0]),
         _image(position[j, 1] - position[i, 1], box_length[1], periodic[1]),
         _image(position[j, 2] - position[i, 2], box_length[2], periodic[2]))
    distance = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    overlap = radius[i] + radius[j] - distance
    if overlap <= 0.0 or distance == 0.0:
        for k in range(3):
            spring[c, k] = 0.0
            force_c[c, k] = 0.0
            moment_i_c[c, k] = 0.0
            moment_j_c[c, k] = 0.0
        energy_c[c] = 0.0
        out_dissipated[c] = -0.5 * moved_dt * work + previous_energy
        return
    n = (r[0] / distance, r[1] / distance, r[2] / distance)
    arm_i = radius[i] - 0.5 * overlap
    arm_j = radius[j] - 0.5 * overlap
    v_rel = contact_relative_velocity(n, vi, vj, wi, wj, arm_i, arm_j)
    w_rel = (wi[0] - wj[0], wi[1] - wj[1], wi[2] - wj[2])
    a = material[i]
    b = material[j]
    mu_r = 0.5 * (rolling[a] + rolling[b]) if use_rolling else 0.0
    force_i, torque, f_t, xi, energy = _pair_law(
        law, n, overlap, v_rel, w_rel, (spring[c, 0], spring[c, 1], spring[c, 2]),
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


@cuda.jit
def gather_pairs_kernel(i_start, j_start, j_order, force_c, moment_i_c, moment_j_c,
                        dissipated_rows, force, moment, dissipated):
    """One thread per particle: add its pair rows (as i: rows i_start[p]..i_start[p+1],
    the list being sorted by i; as j: through j_order), in cpu_contacts.gather_pair_loads'
    order, to force (N) and moment (N m); add the rows' dissipated energy where it is i
    to dissipated[p] (J, summed on the host at the end of the batch)."""
    p = cuda.grid(1)
    if p >= i_start.shape[0] - 1:
        return
    fx = fy = fz = mx = my = mz = 0.0
    lost = 0.0
    for c in range(i_start[p], i_start[p + 1]):
        fx += force_c[c, 0]
        fy += force_c[c, 1]
        fz += force_c[c, 2]
        mx += moment_i_c[c, 0]
        my += moment_i_c[c, 1]
        mz += moment_i_c[c, 2]
        lost += dissipated_rows[c]
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
    dissipated[p] += lost


@cuda.jit(device=True)
def _element_contact(x, rows, e, etype):
    """(distance from x to element e's closest point (m), that point, feature);
    cpu_contacts._element_contact with the element given by its index."""
    if etype == PLANE:
        d = ((x[0] - rows[e, 0, 0]) * rows[e, 1, 0] + (x[1] - rows[e, 0, 1]) * rows[e, 1, 1]
             + (x[2] - rows[e, 0, 2]) * rows[e, 1, 2])
        q = (x[0] - d * rows[e, 1, 0], x[1] - d * rows[e, 1, 1], x[2] - d * rows[e, 1, 2])
        return d, q, FACE
    q, feature = closest_point_on_triangle(
        x, (rows[e, 0, 0], rows[e, 0, 1], rows[e, 0, 2]),
        (rows[e, 1, 0], rows[e, 1, 1], rows[e, 1, 2]),
        (rows[e, 2, 0], rows[e, 2, 1], rows[e, 2, 2]))
    d = math.sqrt((x[0] - q[0]) ** 2 + (x[1] - q[1]) ** 2 + (x[2] - q[2]) ** 2)
    return d, q, feature


@cuda.jit
def wall_contacts_kernel(law, wall_start, wall_pairs, rows, types, element_wall,
                         wall_velocity, wall_omega, wall_center, wall_young, wall_poisson,
                         wall_restitution, wall_friction, wall_rolling, position, velocity,
                         angular_velocity, radius, mass, inertia, material, young, poisson,
                         restitution, friction, rolling, use_rolling, linear_stiffness,
                         spring, dt, moved_dt, scratch_distance, scratch_point,
                         scratch_feature, force_c, moment_c, energy_c, force, moment,
                         dissipated, work_walls, evaluated_position):
    """One thread per particle: cpu_contacts.wall_contacts for its candidates (see there),
    then gather_wall_loads for it (its rows added to force, moment in list order). Adds
    the J dissipated and the work of the walls to dissipated[p] and work_walls[p], and
    stores the position it used (m) for the wall totals summed on the host."""
    p = cuda.grid(1)
    if p >= wall_start.shape[0] - 1:
        return
    x = (position[p, 0], position[p, 1], position[p, 2])
    for k in range(3):
        evaluated_position[p, k] = x[k]
    first = wall_start[p]
    last = wall_start[p + 1]
    if first == last:
        return
    tol = 1e-9 * radius[p]
    for c in range(first, last):
        e = wall_pairs[c, 1]
        d, q, feature = _element_contact(x, rows, e, types[e])
        scratch_distance[c] = d
        scratch_feature[c] = feature
        for k in range(3):
            scratch_point[c, k] = q[k]
    # Which hits count (scratch_feature becomes 1 for kept, 0 for dropped).
    for c in range(first, last):
        e = wall_pairs[c, 1]
        q = (scratch_point[c, 0], scratch_point[c, 1], scratch_point[c, 2])
        d = scratch_distance[c]
        keep = d < radius[p] and d > -radius[p] and (types[e] == PLANE or d > 0.0)
        if keep and types[e] != PLANE:
            for c2 in range(first, last):
                e2 = wall_pairs[c2, 1]
                if c2 == c or element_wall[e2] != element_wall[e] or types[e2] == PLANE:
                    continue
                if scratch_distance[c2] >= radius[p]:
                    continue
                inside, _, _ = _element_contact(q, rows, e2, types[e2])
                if inside >= tol:
                    continue
                gap = 0.0
                for k in range(3):
                    gap += (scratch_point[c, k] - scratch_point[c2, k]) ** 2
                if gap > tol * tol or c2 < c:
                    keep = False
                    break
        scratch_feature[c] = 1 if keep else 0
    # A new hit takes over the spring of a hit of the same wall that ended now.
    for c in range(first, last):
        if scratch_feature[c] != 1 or spring[c, 0] != 0.0 or spring[c, 1] != 0.0 \
                or spring[c, 2] != 0.0:
            continue
        for c2 in range(first, last):
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
    lost = 0.0
    done = 0.0
    for c in range(first, last):
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
        if scratch_feature[c] != 1:
            for k in range(3):
                spring[c, k] = 0.0
                force_c[c, k] = 0.0
                moment_c[c, k] = 0.0
            energy_c[c] = 0.0
            done += 0.5 * moved_dt * by_wall
            lost += 0.5 * moved_dt * (by_wall - on_particle) + previous_energy
            continue
        if types[e] == PLANE:
            n = (-rows[e, 1, 0], -rows[e, 1, 1], -rows[e, 1, 2])
        else:
            n = ((q[0] - x[0]) / d, (q[1] - x[1]) / d, (q[2] - x[2]) / d)
        overlap = radius[p] - d
        v_rel = contact_relative_velocity(n, vi, v_wall, wi, (0.0, 0.0, 0.0), d, 0.0)
        w_rel = (wi[0] - om[0], wi[1] - om[1], wi[2] - om[2])
        a = material[p]
        mu_r = 0.5 * (rolling[a] + wall_rolling[w]) if use_rolling else 0.0
        force_i, torque, f_t, xi, energy = _pair_law(
            law, n, overlap, v_rel, w_rel, (spring[c, 0], spring[c, 1], spring[c, 2]),
            young[a], poisson[a], wall_young[w], wall_poisson[w],
            0.5 * (restitution[a] + wall_restitution[w]),
            0.5 * (friction[a] + wall_friction[w]), mu_r, radius[p], mass[p], inertia[p],
            linear_stiffness, dt)
        moment_i, _ = contact_moments(n, f_t, torque, d, 0.0)
        for k in range(3):
            spring[c, k] = xi[k]
            force_c[c, k] = force_i[k]
            moment_c[c, k] = moment_i[k]
            on_particle += force_i[k] * vi[k] + moment_i[k] * wi[k]
            # The rolling torque turns with the wall (see cpu_contacts.wall_contacts).
            by_wall += force_i[k] * v_wall[k] + 2.0 * torque[k] * om[k]
        energy_c[c] = energy
        done += 0.5 * moved_dt * by_wall
        lost += 0.5 * moved_dt * (by_wall - on_particle) - (energy - previous_energy)
    # gather_wall_loads for this particle: its rows in list order, after the pair loads.
    for c in range(first, last):
        for k in range(3):
            force[p, k] += force_c[c, k]
            moment[p, k] += moment_c[c, k]
    dissipated[p] += lost
    work_walls[p] += done


def _at_least_one(array):
    """Kernels take non-empty arrays; an empty list passes one unused row."""
    return array if array.shape[0] else np.zeros((1,) + array.shape[1:], array.dtype)


class ContactLawGpu(ContactLaw):
    """``ContactLaw`` (particle contacts and walls, Hertz-Mindlin or linear) on the device.

    Same arguments, results, ``state.extra`` layout, ``wall_force`` (W,3) N and
    ``wall_torque`` (W,3) N m (of the last step, updated at the end of each batch) and
    ``energy_terms`` as the CPU law; ``Simulation(..., backend="gpu", contact=...,
    walls=...)`` builds it. Lists are rebuilt on the host by the CPU code (see the module
    docstring); the host ``state.extra`` is refreshed by ``to_host`` at the end of each
    batch, and a host ``state.extra`` (a checkpoint) is taken up by ``to_device``.
    """

    backend = "gpu"

    def attach(self, backend):
        """Take the device state of ``backend`` (a GpuBackend); upload the constants."""
        self.g = backend
        model = backend.model
        put = cuda.to_device
        self._d_radius = put(model.radius)
        self._d_inertia = put(model.inertia)
        self._d_material = put(model.material)
        self._d_materials = tuple(put(a) for a in self._materials)
        self._d_wall_materials = tuple(put(_at_least_one(a)) for a in self._wall_materials)
        self._d_types = put(_at_least_one(self.walls.element_type))
        self._d_element_wall = put(_at_least_one(self.walls.element_wall))
        self._d_wall_velocity = put(_at_least_one(self.walls.velocity))
        self._d_wall_omega = put(_at_least_one(self.walls.angular_velocity))
        self._moving = bool(np.any(self.walls.velocity) or np.any(self.walls.angular_velocity))
        self._flag = put(np.zeros(1, dtype=np.int64))
        self._d_rows = None
        self._rows_host = None
        n = model.n_particles
        self._d_lost = cuda.to_device(np.zeros(n))
        self._d_work = cuda.to_device(np.zeros(n))
        self._evaluated_position = cuda.to_device(np.zeros((n, 3)))
        self._evaluated_time = None
        self._dev = None   # device lists and history rows; None: take them from the host
        backend.register_transfers(self)

    # -- host <-> device ------------------------------------------------------------------
    def to_device(self, state):
        """The host ``state`` (incl. ``state.extra``) was edited or replaced: the next step
        takes the lists and history rows from it."""
        self._dev = None
        zeros = np.zeros(self.g.model.n_particles)
        self._d_lost.copy_to_device(zeros)
        self._d_work.copy_to_device(zeros)

    def _pull_history(self, state):
        """Copy the device history rows into ``state.extra`` (new host arrays)."""
        for name in (*PAIR_HISTORY, *WALL_HISTORY):
            count = self._counts[0] if name in PAIR_HISTORY else self._counts[1]
            state.extra[name] = self._dev[name].copy_to_host()[:count]

    def to_host(self, state):
        """Copy the history rows into ``state.extra``, add the energy counters and sum the
        loads on the walls of the last step (N, N m)."""
        if self._dev is None:
            return
        self._pull_history(state)
        counters = state.extra["contact_counters"]
        counters[0] += float(self._d_lost.copy_to_host().sum())
        counters[1] += float(self._d_work.copy_to_host().sum())
        zeros = np.zeros(self.g.model.n_particles)
        self._d_lost.copy_to_device(zeros)
        self._d_work.copy_to_device(zeros)
        if self.walls.n_walls and self._evaluated_time is not None:
            wall_pairs = state.extra["wall_pairs"]
            point = self._dev["scratch_point"].copy_to_host()[:wall_pairs.shape[0]]
            cpu_contacts.wall_totals(
                wall_pairs, self.walls.element_wall, point, state.extra["wall_force_rows"],
                state.extra["wall_moment_rows"], self._evaluated_position.copy_to_host(),
                self.g.model.radius, self.walls.positions(self._evaluated_time),
                self.wall_force, self.wall_torque)

    def _upload(self, model, state):
        """Send the host lists (just built or taken from a checkpoint) to the device."""
        self._derive(model, state)
        extra = state.extra
        put = cuda.to_device
        n = model.n_particles
        pairs = extra["contact_pairs"]
        wall_pairs = extra["wall_pairs"]
        # CSR over every row (the CPU's over live rows; the others stay zero).
        i_start = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(pairs[:, 0], minlength=n), out=i_start[1:])
        j_start, j_order = _csr_by(pairs[:, 1], n)
        k = wall_pairs.shape[0]
        dev = {"pairs": put(_at_least_one(pairs)),
               "pair_bond": put(_at_least_one(self._pair_bond)),
               "i_start": put(i_start), "j_start": put(j_start),
               "j_order": put(_at_least_one(j_order)),
               "dissipated_rows": cuda.device_array(max(pairs.shape[0], 1)),
               "wall_pairs": put(_at_least_one(wall_pairs)),
               "wall_start": put(self._wall_start),
               "scratch_distance": cuda.device_array(max(k, 1)),
               "scratch_point": cuda.to_device(np.zeros((max(k, 1), 3))),
               "scratch_feature": cuda.device_array(max(k, 1), dtype=np.int64),
               "reference": put(extra["contact_reference_position"])}
        for name in (*PAIR_HISTORY, *WALL_HISTORY):
            dev[name] = put(_at_least_one(np.ascontiguousarray(extra[name])))
        self._counts = (pairs.shape[0], k)
        self._dev = dev

    def _sync_for_rebuild(self, state):
        """Bring what the host rebuild reads up to date: position, bond flags, history."""
        d = self.g.device
        d.position.copy_to_host(state.position)
        d.bond_active.copy_to_host(state.bond_active)
        self._pull_history(state)

    def _device_needs_rebuild(self, model, state):
        extra = state.extra
        limit = 0.5 * self.skin - self.walls.max_displacement(
            state.time - extra["contact_reference_time"][0])
        if not limit > 0.0:
            return True
        self._flag.copy_to_device(np.zeros(1, dtype=np.int64))
        n = model.n_particles
        displacement_flag_kernel[_blocks(n), THREADS](
            self.g.device.position, self._dev["reference"], self.g.box_length, self.g.periodic,
            limit * limit, self._flag)
        return bool(self._flag.copy_to_host()[0])

    # -- the law ----------------------------------------------------------------------
    def accumulate(self, model, state, force, moment, increment_dt):
        """Add contact and wall loads (N, N m) into the device force and moment, for the
        device state at the start of the step; springs advance by ``increment_dt`` (s)."""
        self._last_state = state
        if self._dev is None:
            # The host state is current here (just uploaded by the backend).
            if self._needs_rebuild(model, state):
                self._rebuild(model, state)
            self._upload(model, state)
        elif self._device_needs_rebuild(model, state):
            self._sync_for_rebuild(state)
            self._rebuild(model, state)
            self._upload(model, state)
        dev = self._dev
        g = self.g
        d = g.device
        n = model.n_particles
        counters = state.extra["contact_counters"]
        moved_dt = state.time - counters[3]  # 0 after the start-up kick: nothing moved
        counters[3] = state.time
        use_rolling = bool(self.settings.rolling_resistance)
        if self._counts[0]:
            particle_contacts_kernel[_blocks(self._counts[0]), THREADS](
                self.pair_law, dev["pairs"], dev["pair_bond"], d.bond_active, d.position,
                d.velocity, d.angular_velocity, self._d_radius, g.mass, self._d_inertia,
                self._d_material, *self._d_materials, use_rolling, self._k_linear,
                g.box_length, g.periodic, dev["contact_spring"], increment_dt, moved_dt,
                dev["contact_force"], dev["contact_moment_i"], dev["contact_moment_j"],
                dev["contact_energy"], dev["dissipated_rows"])
            gather_pairs_kernel[_blocks(n), THREADS](
                dev["i_start"], dev["j_start"], dev["j_order"], dev["contact_force"],
                dev["contact_moment_i"], dev["contact_moment_j"], dev["dissipated_rows"],
                force, moment, self._d_lost)
        if self.walls.n_walls:
            rows = self.walls.elements(state.time)
            if rows is not self._rows_host:   # static walls: the same rows object
                self._d_rows = cuda.to_device(rows)
                self._rows_host = rows
            centers = cuda.to_device(self.walls.centers(state.time))
            wall_contacts_kernel[_blocks(n), THREADS](
                self.wall_law, dev["wall_start"], dev["wall_pairs"], self._d_rows,
                self._d_types, self._d_element_wall, self._d_wall_velocity,
                self._d_wall_omega, centers, *self._d_wall_materials, d.position,
                d.velocity, d.angular_velocity, self._d_radius, g.mass, self._d_inertia,
                self._d_material, *self._d_materials, use_rolling, self._k_linear,
                dev["wall_spring"], increment_dt, moved_dt, dev["scratch_distance"],
                dev["scratch_point"], dev["scratch_feature"], dev["wall_force_rows"],
                dev["wall_moment_rows"], dev["wall_energy_rows"], force, moment,
                self._d_lost, self._d_work, self._evaluated_position)
            self._evaluated_time = state.time

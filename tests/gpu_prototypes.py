"""GPU prototypes kept for the simulator tests only (moved out of bondem.backends.cuda,
which ``Simulation`` uses without them): a device neighbour search (cell keys, bitonic
sort, cell starts, count/scan/write of the pairs), the remapping of pair history, and a
particle-contact kernel around any device-compiled pair law with its driver
``ParticleContactsGpu``. ``Simulation``'s GPU contacts are ``cuda_contacts.ContactLawGpu``
(host-built lists); these stay as tested building blocks for a device-side search.
"""
import math

import numpy as np
from numba import cuda

from bondem.backends.cpu import particle_bond_index
from bondem.backends.cuda import gather_bond_loads_kernel, minimum_image
from bondem.backends.cuda_device import THREADS, blocks as _blocks
from bondem.backends.loops import BondIndex, BondLoads

# ---------------------------------------------------------------------------------------
# Neighbour search: cell index, sort by cell, cell starts by search, count/scan/write pairs
# ---------------------------------------------------------------------------------------

_KEY_PAD = np.iinfo(np.int64).max


@cuda.jit(device=True)
def _lower_bound(values, n, target):
    """First index in the sorted values[:n] whose value is >= target (binary search)."""
    lo = 0
    hi = n
    while lo < hi:
        mid = (lo + hi) // 2
        if values[mid] < target:
            lo = mid + 1
        else:
            hi = mid
    return lo


@cuda.jit(device=True)
def _cell_coordinate(x, low, cell_size, count):
    """Cell index of coordinate x (m) along one axis, clamped into [0, count - 1]."""
    c = int(math.floor((x - low) / cell_size))
    if c < 0:
        return 0
    if c > count - 1:
        return count - 1
    return c


@cuda.jit
def cell_keys_kernel(position, low, cell_size, dims, n_padded, keys):
    """key = cell * N + particle (int64), so sorting keys sorts by cell, then by index;
    padding slots get the largest key. Particles outside the grid are clamped into the
    edge cells, which keeps every neighbour within one cell (clamping never separates)."""
    p = cuda.grid(1)
    n = position.shape[0]
    if p >= n_padded:
        return
    if p >= n:
        keys[p] = _KEY_PAD
        return
    cell = 0
    for k in range(2, -1, -1):
        cell = cell * dims[k] + _cell_coordinate(position[p, k], low[k], cell_size, dims[k])
    keys[p] = cell * n + p


@cuda.jit
def bitonic_stage_kernel(keys, k, j):
    """One compare-exchange stage of a bitonic sort of ``keys`` (length a power of two)."""
    i = cuda.grid(1)
    if i >= keys.shape[0]:
        return
    partner = i ^ j
    if partner > i:
        ascending = (i & k) == 0
        a = keys[i]
        b = keys[partner]
        if (a > b) == ascending:
            keys[i] = b
            keys[partner] = a


def sort_keys(keys):
    """Sort device int64 ``keys`` (length a power of two) in place, ascending: a bitonic
    network, deterministic and without atomics; log2(P)(log2(P)+1)/2 launches."""
    size = keys.shape[0]
    k = 2
    while k <= size:
        j = k // 2
        while j >= 1:
            bitonic_stage_kernel[_blocks(size), THREADS](keys, k, j)
            j //= 2
        k *= 2


@cuda.jit
def cell_start_kernel(keys, n, n_cells, start):
    """start[c] = first slot of sorted ``keys`` whose cell is >= c (binary search);
    start[n_cells] = n. Cell c holds slots start[c] .. start[c+1]-1."""
    c = cuda.grid(1)
    if c > n_cells:
        return
    if c == n_cells:
        start[c] = n
        return
    start[c] = _lower_bound(keys, n, c * n)


@cuda.jit(device=True)
def _visit_neighbours(p, position, radius, skin, low, cell_size, dims, keys, start, n,
                      pairs, offset, write):
    """Count (and write at ``offset`` when ``write``) the pairs (p, q), q > p, with
    |x_q - x_p| < r_p + r_q + skin, scanning the 27 cells around p's cell."""
    c0 = _cell_coordinate(position[p, 0], low[0], cell_size, dims[0])
    c1 = _cell_coordinate(position[p, 1], low[1], cell_size, dims[1])
    c2 = _cell_coordinate(position[p, 2], low[2], cell_size, dims[2])
    found = 0
    for d2 in range(-1, 2):
        z = c2 + d2
        if z < 0 or z >= dims[2]:
            continue
        for d1 in range(-1, 2):
            y = c1 + d1
            if y < 0 or y >= dims[1]:
                continue
            for d0 in range(-1, 2):
                x = c0 + d0
                if x < 0 or x >= dims[0]:
                    continue
                cell = (z * dims[1] + y) * dims[0] + x
                for s in range(start[cell], start[cell + 1]):
                    q = keys[s] - cell * n
                    if q <= p:
                        continue
                    dx = position[q, 0] - position[p, 0]
                    dy = position[q, 1] - position[p, 1]
                    dz = position[q, 2] - position[p, 2]
                    reach = radius[p] + radius[q] + skin
                    if dx * dx + dy * dy + dz * dz < reach * reach:
                        if write:
                            pairs[offset + found, 0] = p
                            pairs[offset + found, 1] = q
                        found += 1
    return found


@cuda.jit
def count_pairs_kernel(position, radius, skin, low, cell_size, dims, keys, start, counts,
                       pairs):
    p = cuda.grid(1)
    n = position.shape[0]
    if p < n:
        counts[p] = _visit_neighbours(p, position, radius, skin, low, cell_size, dims, keys,
                                      start, n, pairs, 0, False)


@cuda.jit
def write_pairs_kernel(position, radius, skin, low, cell_size, dims, keys, start, offsets,
                       pairs):
    """Write particle p's pairs at offsets[p], then sort them by j (insertion sort of a
    short segment), so the whole list is sorted by (i, j): deterministic, and searchable
    when contact history is carried to a rebuilt list (``remap_pair_history``)."""
    p = cuda.grid(1)
    n = position.shape[0]
    if p < n:
        first = offsets[p]
        found = _visit_neighbours(p, position, radius, skin, low, cell_size, dims, keys,
                                  start, n, pairs, first, True)
        for a in range(first + 1, first + found):
            q = pairs[a, 1]
            b = a - 1
            while b >= first and pairs[b, 1] > q:
                pairs[b + 1, 1] = pairs[b, 1]
                b -= 1
            pairs[b + 1, 1] = q


@cuda.jit
def remap_history_kernel(old_pairs, old_history, new_pairs, new_history):
    """One thread per new pair: copy its history row from the old list (both sorted by
    (i, j)) found by binary search, or zero it for a new contact."""
    c = cuda.grid(1)
    if c >= new_pairs.shape[0]:
        return
    i = new_pairs[c, 0]
    j = new_pairs[c, 1]
    lo = 0
    hi = old_pairs.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if old_pairs[mid, 0] < i or (old_pairs[mid, 0] == i and old_pairs[mid, 1] < j):
            lo = mid + 1
        else:
            hi = mid
    found = lo < old_pairs.shape[0] and old_pairs[lo, 0] == i and old_pairs[lo, 1] == j
    for k in range(new_history.shape[1]):
        new_history[c, k] = old_history[lo, k] if found else 0.0


def remap_pair_history(old_pairs, old_history, new_pairs):
    """Carry per-pair history (e.g. the tangential spring, (C_old, K)) from an old pair
    list to a rebuilt one; all device arrays, pair lists sorted by (i, j) as
    ``device_neighbour_pairs`` returns them. Pairs new to the list start from zero."""
    width = old_history.shape[1]
    new_history = cuda.device_array((new_pairs.shape[0], width))
    if new_pairs.shape[0] == 0:
        return new_history
    if old_pairs.shape[0] == 0:
        old_pairs = cuda.to_device(np.full((1, 2), -1, dtype=np.int64))
        old_history = cuda.to_device(np.zeros((1, width)))
    remap_history_kernel[_blocks(new_pairs.shape[0]), THREADS](old_pairs, old_history,
                                                               new_pairs, new_history)
    return new_history


@cuda.jit
def _block_scan_kernel(values, out, block_sums):
    """Inclusive scan of each THREADS-long block (Hillis-Steele in shared memory)."""
    buffer = cuda.shared.array(THREADS, dtype=np.int64)
    t = cuda.threadIdx.x
    i = cuda.grid(1)
    buffer[t] = values[i] if i < values.shape[0] else 0
    cuda.syncthreads()
    step = 1
    while step < THREADS:
        add = buffer[t - step] if t >= step else 0
        cuda.syncthreads()
        buffer[t] += add
        cuda.syncthreads()
        step *= 2
    if i < values.shape[0]:
        out[i] = buffer[t]
    if t == THREADS - 1:
        block_sums[cuda.blockIdx.x] = buffer[t]


@cuda.jit
def _add_block_offsets_kernel(out, scanned_block_sums):
    i = cuda.grid(1)
    block = cuda.blockIdx.x
    if i < out.shape[0] and block > 0:
        out[i] += scanned_block_sums[block - 1]


def inclusive_scan(values):
    """Inclusive prefix sum of a device int64 array (new device array); blocks scanned in
    shared memory, block totals scanned recursively: deterministic, no atomics."""
    n = values.shape[0]
    blocks = _blocks(n)
    out = cuda.device_array(n, dtype=np.int64)
    block_sums = cuda.device_array(blocks, dtype=np.int64)
    _block_scan_kernel[blocks, THREADS](values, out, block_sums)
    if blocks > 1:
        _add_block_offsets_kernel[blocks, THREADS](out, inclusive_scan(block_sums))
    return out


def device_neighbour_pairs(position, radius, skin, low, high, max_cells=1 << 26):
    """Pairs (i < j) of particles closer than r_i + r_j + skin, found on the device.

    position (N,3) m and radius (N,) m: device arrays; skin: m; low, high: (3,) host
    bounds of the grid (m; particles outside are clamped into the edge cells). Returns a
    device (P,2) int64 array sorted by (i, j).
    """
    n = position.shape[0]
    empty = cuda.device_array((0, 2), dtype=np.int64)
    if n < 2:
        return empty
    host_radius_max = float(radius.copy_to_host().max())
    cell_size = 2.0 * host_radius_max + skin
    extent = np.maximum(np.asarray(high, float) - np.asarray(low, float), cell_size)
    # More cells than ~2 per particle buy nothing and a scattered scene (or a blow-up)
    # would make the start table huge.
    max_cells = min(max_cells, max(2 * n, 64))
    while np.prod(np.ceil(extent / cell_size)) > max_cells:
        cell_size *= 1.26  # coarser cells keep the start table bounded for sparse scenes
    dims = np.ceil(extent / cell_size).astype(np.int64)
    n_cells = int(np.prod(dims))
    n_padded = 1 << (n - 1).bit_length()
    keys = cuda.device_array(n_padded, dtype=np.int64)
    d_low = cuda.to_device(np.asarray(low, dtype=np.float64))
    d_dims = cuda.to_device(dims)
    cell_keys_kernel[_blocks(n_padded), THREADS](position, d_low, cell_size, d_dims,
                                                 n_padded, keys)
    sort_keys(keys)
    start = cuda.device_array(n_cells + 1, dtype=np.int64)
    cell_start_kernel[_blocks(n_cells + 1), THREADS](keys, n, n_cells, start)
    counts = cuda.device_array(n, dtype=np.int64)
    count_pairs_kernel[_blocks(n), THREADS](position, radius, skin, d_low, cell_size, d_dims,
                                            keys, start, counts, empty)
    ends = inclusive_scan(counts)
    total = int(ends[n - 1])
    if total == 0:
        return empty
    offsets = cuda.device_array(n, dtype=np.int64)
    offsets[0:1].copy_to_device(np.zeros(1, dtype=np.int64))
    offsets[1:].copy_to_device(ends[:n - 1])
    pairs = cuda.device_array((total, 2), dtype=np.int64)
    write_pairs_kernel[_blocks(n), THREADS](position, radius, skin, d_low, cell_size, d_dims,
                                            keys, start, offsets, pairs)
    return pairs


def neighbour_pairs(position, radius, skin=0.0):
    """Host convenience: (P,2) int64 pairs i < j with |x_j - x_i| < r_i + r_j + skin.

    position (N,3) m, radius (N,) m, skin m (NumPy arrays); runs ``device_neighbour_pairs``
    on a grid spanning the particles.
    """
    position = np.ascontiguousarray(position, dtype=np.float64)
    radius = np.ascontiguousarray(radius, dtype=np.float64)
    if position.shape[0] < 2:
        return np.zeros((0, 2), dtype=np.int64)
    pairs = device_neighbour_pairs(cuda.to_device(position), cuda.to_device(radius),
                                   float(skin), position.min(axis=0), position.max(axis=0))
    return pairs.copy_to_host()


# ---------------------------------------------------------------------------------------
# Particle-particle contacts: a kernel around any compiled pair law
# ---------------------------------------------------------------------------------------

def make_contact_kernel(pair_law):
    """A kernel over a contact list that calls ``pair_law``, a device-compiled pair law
    with the contact laws' common signature (physics/contact_hertz.py, contact_linear.py):

        pair_law(n, overlap, v_rel, w_rel, spring, stiffness_a, stiffness_b, r_star,
                 m_star, beta, friction, rolling_friction, dt)
            -> (force on i, rolling torque on i, F_t on i, new spring, energy, dissipated)

    The kernel takes (pairs (C,2), pair_bond (C,) bond index or -1, bond_active,
    position, velocity, angular_velocity, radius, mass, material, pair_table (M,M,5):
    per material pair (stiffness_a, stiffness_b, beta, friction, rolling_friction),
    box_length, periodic, spring (C,3) m updated in place, dt) and writes per contact
    force_i, moment_i, moment_j, energy, dissipated, like the bond kernel, so
    ``gather_bond_loads_kernel`` with a CSR index of the contact list
    (``particle_bond_index(pairs, N)``) sums them per particle without atomics.
    Intact bonded pairs and pairs without overlap apply nothing; the latter lose their
    spring (the contact ended).
    """
    @cuda.jit
    def contact_kernel(pairs, pair_bond, bond_active, position, velocity, angular_velocity,
                       radius, mass, material, pair_table, box_length, periodic, spring, dt,
                       out_force_i, out_moment_i, out_moment_j, out_energy, out_dissipated):
        c = cuda.grid(1)
        if c >= pairs.shape[0]:
            return
        i = pairs[c, 0]
        j = pairs[c, 1]
        r = minimum_image((position[j, 0] - position[i, 0], position[j, 1] - position[i, 1],
                           position[j, 2] - position[i, 2]),
                          (box_length[0], box_length[1], box_length[2]),
                          periodic[0], periodic[1], periodic[2])
        distance = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        overlap = radius[i] + radius[j] - distance
        bonded = pair_bond[c] >= 0 and bond_active[pair_bond[c]]
        for k in range(3):
            out_force_i[c, k] = 0.0
            out_moment_i[c, k] = 0.0
            out_moment_j[c, k] = 0.0
        out_energy[c] = 0.0
        out_dissipated[c] = 0.0
        if bonded or overlap <= 0.0 or distance <= 0.0:
            for k in range(3):
                spring[c, k] = 0.0
            return
        n = (r[0] / distance, r[1] / distance, r[2] / distance)
        arm_i = radius[i] - 0.5 * overlap
        arm_j = radius[j] - 0.5 * overlap
        wi = (angular_velocity[i, 0], angular_velocity[i, 1], angular_velocity[i, 2])
        wj = (angular_velocity[j, 0], angular_velocity[j, 1], angular_velocity[j, 2])
        # Surface velocity of j relative to i at the contact point (lever arms a_i, a_j).
        spin = (arm_i * wi[0] + arm_j * wj[0], arm_i * wi[1] + arm_j * wj[1],
                arm_i * wi[2] + arm_j * wj[2])
        v_rel = (velocity[j, 0] - velocity[i, 0] - (spin[1] * n[2] - spin[2] * n[1]),
                 velocity[j, 1] - velocity[i, 1] - (spin[2] * n[0] - spin[0] * n[2]),
                 velocity[j, 2] - velocity[i, 2] - (spin[0] * n[1] - spin[1] * n[0]))
        w_rel = (wi[0] - wj[0], wi[1] - wj[1], wi[2] - wj[2])
        mi = material[i]
        mj = material[j]
        r_star = radius[i] * radius[j] / (radius[i] + radius[j])
        m_star = mass[i] * mass[j] / (mass[i] + mass[j])
        force_i, torque, f_t, xi, energy, dissipated = pair_law(
            n, overlap, v_rel, w_rel, (spring[c, 0], spring[c, 1], spring[c, 2]),
            pair_table[mi, mj, 0], pair_table[mi, mj, 1], r_star, m_star,
            pair_table[mi, mj, 2], pair_table[mi, mj, 3], pair_table[mi, mj, 4], dt)
        lever = (n[1] * f_t[2] - n[2] * f_t[1], n[2] * f_t[0] - n[0] * f_t[2],
                 n[0] * f_t[1] - n[1] * f_t[0])
        for k in range(3):
            spring[c, k] = xi[k]
            out_force_i[c, k] = force_i[k]
            out_moment_i[c, k] = arm_i * lever[k] + torque[k]
            out_moment_j[c, k] = arm_j * lever[k] - torque[k]
        out_energy[c] = energy
        out_dissipated[c] = dissipated

    return contact_kernel


def synchronize():
    """Wait for every queued kernel (for timing: call before reading a clock)."""
    cuda.synchronize()


@cuda.jit
def _displacement_flag_kernel(position, reference, limit_squared, flag):
    """flag[0] = 1 when some particle moved more than sqrt(limit_squared) (m) since the
    pair list was built (the list then may miss a contact)."""
    p = cuda.grid(1)
    if p < position.shape[0]:
        dx = position[p, 0] - reference[p, 0]
        dy = position[p, 1] - reference[p, 1]
        dz = position[p, 2] - reference[p, 2]
        if dx * dx + dy * dy + dz * dz > limit_squared:
            flag[0] = 1


@cuda.jit
def _bounds_kernel(position, low, high):
    """Bounding box of the particles (m) by atomic min/max: exact, so order-independent."""
    p = cuda.grid(1)
    if p < position.shape[0]:
        for k in range(3):
            cuda.atomic.min(low, k, position[p, k])
            cuda.atomic.max(high, k, position[p, k])


@cuda.jit
def _pair_bond_kernel(pairs, bond_keys, bond_index, out):
    """out[c] = the bond joining pair c's particles, or -1: binary search of i*N + j in
    the sorted keys of the bonds (i < j)."""
    c = cuda.grid(1)
    if c >= pairs.shape[0]:
        return
    n = bond_keys.shape[0]
    out[c] = -1
    key = pairs[c, 0] * bond_index[n] + pairs[c, 1]  # bond_index[n] holds N
    lo = _lower_bound(bond_keys, n, key)
    if lo < n and bond_keys[lo] == key:
        out[c] = bond_index[lo]


class ParticleContactsGpu:
    """Particle-particle contacts on the device for any pair law (``make_contact_kernel``).

    pair_law: a device-compiled pair law with the contact laws' signature (e.g.
    ``compile_physics(cuda.jit(device=True)).hertz_mindlin``); pair_table (M, M, 5): per
    material pair (stiffness_a, stiffness_b, beta, friction, rolling_friction) in that
    law's units (Hertz: E* Pa, G* Pa); skin: m, the pair list holds pairs closer than
    r_i + r_j + skin and is rebuilt (history carried) when a particle moved skin/2.
    Intact bonded pairs get no contact force. ``state.extra`` is not used: the springs
    stay on the device (``spring``, with ``pairs`` sorted by (i, j)).
    """

    name = "particle_contacts"
    backend = "gpu"

    def __init__(self, model, pair_law, pair_table, *, skin):
        table = np.ascontiguousarray(pair_table, dtype=np.float64)
        m = len(model.materials)
        if table.shape != (m, m, 5):
            raise ValueError(f"pair_table: shape {table.shape}, expected ({m}, {m}, 5)")
        if not skin > 0.0:
            raise ValueError(f"skin = {skin!r} m; must be > 0")
        if np.any(model.periodic):
            raise ValueError("ParticleContactsGpu: periodic boundaries are not supported "
                             "yet by the GPU pair search; use backend = 'cpu'")
        self.kernel = make_contact_kernel(pair_law)
        self.table = table
        self.skin = float(skin)
        self.rebuilds = 0

    def attach(self, backend):
        """Take the device state of ``backend``; upload the constant per-particle arrays."""
        model = backend.model
        self.g = backend
        put = cuda.to_device
        self.radius = put(model.radius)
        self.mass = put(model.mass)
        self.material = put(model.material)
        self.d_table = put(self.table)
        n = model.n_particles
        ordered = np.sort(model.bond_pairs, axis=1)
        keys = ordered[:, 0] * n + ordered[:, 1]
        order = np.argsort(keys)
        self.bond_keys = put(keys[order] if len(keys) else np.full(1, -1, dtype=np.int64))
        # bond_index[-1] holds N, the key's multiplier, so the kernel needs no extra scalar.
        self.bond_index = put(np.append(order, n).astype(np.int64))
        self.n_bond_keys = len(keys)
        self.pairs = cuda.to_device(np.zeros((0, 2), dtype=np.int64))
        self.spring = cuda.to_device(np.zeros((0, 3)))
        self.reference = None
        self.flag = put(np.zeros(1, dtype=np.int64))

    def _needs_rebuild(self, n):
        if self.reference is None:
            return True
        self.flag.copy_to_device(np.zeros(1, dtype=np.int64))
        _displacement_flag_kernel[_blocks(n), THREADS](self.g.device.position, self.reference,
                                                      (0.5 * self.skin) ** 2, self.flag)
        return bool(self.flag.copy_to_host()[0])

    def _rebuild(self, model):
        n = model.n_particles
        position = self.g.device.position
        low = cuda.to_device(np.full(3, np.inf))
        high = cuda.to_device(np.full(3, -np.inf))
        _bounds_kernel[_blocks(n), THREADS](position, low, high)
        pairs = device_neighbour_pairs(position, self.radius, self.skin, low.copy_to_host(),
                                       high.copy_to_host())
        self.spring = remap_pair_history(self.pairs, self.spring, pairs)
        self.pairs = pairs
        count = pairs.shape[0]
        self.pair_bond = cuda.device_array(max(count, 1), dtype=np.int64)
        if count and self.n_bond_keys:
            _pair_bond_kernel[_blocks(count), THREADS](pairs, self.bond_keys[:self.n_bond_keys],
                                                       self.bond_index, self.pair_bond)
        elif count:
            self.pair_bond.copy_to_device(np.full(count, -1, dtype=np.int64))
        # The gather's CSR index of the contact list, built on the host (rebuilds are rare).
        offsets, ends = particle_bond_index(pairs.copy_to_host(), n)
        self.offsets = cuda.to_device(offsets)
        self.ends = cuda.to_device(ends if len(ends) else np.zeros(1, dtype=np.int64))
        width = max(count, 1)
        self.out = ([cuda.device_array((width, 3)) for _ in range(3)]
                    + [cuda.device_array(width) for _ in range(2)])
        self.reference = cuda.device_array_like(position)
        self.reference.copy_to_device(position)
        self.rebuilds += 1

    def accumulate(self, model, state, force, moment, increment_dt):
        """Advance every contact by ``increment_dt`` (s); add loads to the device arrays."""
        n = model.n_particles
        if self._needs_rebuild(n):
            self._rebuild(model)
        count = self.pairs.shape[0]
        if count == 0:
            return
        g = self.g
        d = g.device
        self.kernel[_blocks(count), THREADS](
            self.pairs, self.pair_bond, d.bond_active, d.position, d.velocity,
            d.angular_velocity, self.radius, self.mass, self.material, self.d_table,
            g.box_length, g.periodic, self.spring, increment_dt, *self.out)
        gather_bond_loads_kernel[_blocks(n), THREADS](
            BondIndex(self.offsets, self.ends), BondLoads(*self.out[:3]), force, moment,
            False)

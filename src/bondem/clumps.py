"""Clumps: rigid grains made of several spheres (PFC's clumps, MUSEN's multispheres).

A clump is a rigid body whose surface is the union of its member spheres. Its members
are ordinary particles of the Model: they touch other particles and walls and carry
bonds, with every bond and contact model; the loads on them are summed onto the clump
(forces, and their moments about its centre of mass with the lever arms R(q) d of the
clump's orientation), which moves as one rigid body (backends/loops.py:
``integrate_clump``, physics/rigid_body.py) and then places its members. Members of one
clump never touch each other and cannot be bonded to each other.

Mass properties (``mass_properties``): mass, centre of mass and inertia tensor of the
union of the members at a uniform density, overlaps counted once. When no two members
overlap they are exact (the spheres' sums and the parallel axis theorem); else they are
integrated over columns: on an n x n grid of columns across the clump's extent (n =
``resolution``), the union of the members' chords along each column is found exactly
and its integrals of 1, z and z^2 taken in closed form, the columns summed by the
midpoint rule in x and y. Its error falls roughly as n^-1.5 to n^-2 (the chord's
square-root edge): for n = 256, the default, below 1e-4 relative in the mass and in each
principal moment (measured: at most 4e-5 for two overlapping spheres of radii 1 and 0.7
at 1.2 apart, along a grid axis and obliquely, against a quadrature of the exact solid
of revolution; n = 128 gives 5e-4, n = 64 9e-4). A user's own mass and inertia can
replace the integral.

Members' own mass and inertia (Model.mass, Model.inertia) are their share of the clump's:
m_p = M r_p^3 / sum r^3 and 0.4 m_p r_p^2. Contact damping and the time step read them
(PFC's clumps give the contact the clump's mass instead: a clump's restitution against a
wall therefore differs from a sphere's of the same material).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .model import INDEX


def _check_members(offsets, radii, where):
    offsets = np.asarray(offsets, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    if offsets.ndim != 2 or offsets.shape[1] != 3 or offsets.shape[0] == 0:
        raise ValueError(f"{where}: member centres must be an (M, 3) array with M >= 1, got "
                         f"shape {offsets.shape}")
    if radii.shape != (offsets.shape[0],):
        raise ValueError(f"{where}: {offsets.shape[0]} member centres but radii of shape "
                         f"{radii.shape}")
    if not (np.all(np.isfinite(offsets)) and np.all(np.isfinite(radii))
            and np.all(radii > 0.0)):
        raise ValueError(f"{where}: member centres must be finite and radii > 0 (m)")
    return offsets, radii


def _overlapping(offsets, radii):
    d = np.linalg.norm(offsets[:, None, :] - offsets[None, :, :], axis=2)
    reach = radii[:, None] + radii[None, :]
    np.fill_diagonal(d, np.inf)
    return bool(np.any(d < reach))


def mass_properties(offsets, radii, density, *, resolution=256):
    """Mass (kg), centre of mass (3,) m and inertia tensor (3,3) kg m^2 about the centre
    of mass of the union of spheres (centres ``offsets`` (M,3) m, ``radii`` (M,) m) at
    ``density`` kg/m^3, overlaps counted once: exact without overlaps, else the column
    integral of the module's docstring on a resolution x resolution grid."""
    offsets, radii = _check_members(offsets, radii, "mass_properties")
    if not (density > 0.0 and np.isfinite(density)):
        raise ValueError(f"mass_properties: density = {density!r}; must be > 0 (kg/m^3)")
    if not _overlapping(offsets, radii):
        masses = density * 4.0 / 3.0 * np.pi * radii ** 3
        mass = float(masses.sum())
        centre = masses @ offsets / mass
        r = offsets - centre
        tensor = np.zeros((3, 3))
        for m, a, rad in zip(masses, r, radii):
            tensor += 0.4 * m * rad * rad * np.eye(3) + m * (a @ a * np.eye(3) - np.outer(a, a))
        return mass, centre, tensor
    if int(resolution) < 8:
        raise ValueError(f"mass_properties: resolution = {resolution!r}; must be >= 8")
    n = int(resolution)
    low = (offsets - radii[:, None]).min(axis=0)
    high = (offsets + radii[:, None]).max(axis=0)
    hx, hy = (high[:2] - low[:2]) / n
    x = low[0] + (np.arange(n) + 0.5) * hx
    y = low[1] + (np.arange(n) + 0.5) * hy
    gx, gy = (a.ravel() for a in np.meshgrid(x, y, indexing="ij"))
    # each member's chord along z in each column, empty ones at +inf
    d2 = ((gx[:, None] - offsets[None, :, 0]) ** 2 + (gy[:, None] - offsets[None, :, 1]) ** 2)
    half = np.sqrt(np.maximum(radii[None, :] ** 2 - d2, 0.0))
    hit = d2 < radii[None, :] ** 2
    lo = np.where(hit, offsets[None, :, 2] - half, np.inf)
    hi = np.where(hit, offsets[None, :, 2] + half, np.inf)
    order = np.argsort(lo, axis=1)
    lo = np.take_along_axis(lo, order, axis=1)
    hi = np.take_along_axis(hi, order, axis=1)
    moments = np.zeros((gx.shape[0], 3))   # integrals of 1, z, z^2 over the union

    def flush(a, b, where):
        a = np.where(where, a, 0.0)
        b = np.where(where, b, 0.0)
        moments[:, 0] += b - a
        moments[:, 1] += (b * b - a * a) / 2.0
        moments[:, 2] += (b ** 3 - a ** 3) / 3.0

    cur_lo = lo[:, 0].copy()
    cur_hi = hi[:, 0].copy()
    for k in range(1, lo.shape[1]):
        valid = np.isfinite(lo[:, k])
        gap = valid & (lo[:, k] > cur_hi)
        flush(cur_lo, cur_hi, gap & np.isfinite(cur_lo))
        cur_lo = np.where(gap, lo[:, k], cur_lo)
        cur_hi = np.where(gap, hi[:, k], np.where(valid, np.maximum(cur_hi, hi[:, k]), cur_hi))
    flush(cur_lo, cur_hi, np.isfinite(cur_lo))
    area = hx * hy
    length, z1, z2 = moments[:, 0] * area, moments[:, 1] * area, moments[:, 2] * area
    volume = length.sum()
    mass = density * volume
    centre = np.array([gx @ length, gy @ length, z1.sum()]) / volume
    # second moments about the origin: the columns' x^2 includes the cell's own h^2/12
    xx = (gx * gx + hx * hx / 12.0) @ length
    yy = (gy * gy + hy * hy / 12.0) @ length
    zz = z2.sum()
    xy = (gx * gy) @ length
    xz = gx @ z1
    yz = gy @ z1
    second = density * np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    second -= mass * np.outer(centre, centre)
    tensor = np.trace(second) * np.eye(3) - second
    return float(mass), centre, tensor


def principal_frame(tensor):
    """(moments (3,) kg m^2 ascending, axes (3,3)): the eigen decomposition of an inertia
    tensor, axes[:, k] the unit axis of moment k, a right-handed frame (det +1)."""
    tensor = np.asarray(tensor, dtype=np.float64)
    if tensor.shape != (3, 3) or not np.allclose(tensor, tensor.T, rtol=1e-12,
                                                 atol=1e-300):
        raise ValueError("inertia: expected a symmetric (3, 3) tensor (kg m^2)")
    moments, axes = np.linalg.eigh(0.5 * (tensor + tensor.T))
    if not np.all(moments > 0.0):
        raise ValueError(f"inertia: principal moments {moments.tolist()} must all be > 0")
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


def quaternion_from_matrix(matrix):
    """The unit quaternion (q0, q1, q2, q3), q0 >= 0, of a rotation matrix (3,3)."""
    m = np.asarray(matrix, dtype=np.float64)
    trace = np.trace(m)
    if trace > 0.0:
        s = 2.0 * np.sqrt(1.0 + trace)
        q = np.array([0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s,
                      (m[1, 0] - m[0, 1]) / s])
    else:
        k = int(np.argmax(np.diag(m)))
        i, j = (k + 1) % 3, (k + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[k, k] - m[i, i] - m[j, j])
        q = np.zeros(4)
        q[0] = (m[j, i] - m[i, j]) / s
        q[1 + k] = 0.25 * s
        q[1 + i] = (m[i, k] + m[k, i]) / s
        q[1 + j] = (m[j, k] + m[k, j]) / s
    q /= np.linalg.norm(q)
    return q if q[0] >= 0.0 else -q


def rotation_matrix(q):
    """The rotation matrix (3,3) of a quaternion (q0, q1, q2, q3) (normalised first)."""
    q0, q1, q2, q3 = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
        [2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 - q0 * q1)],
        [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2)]])


def random_orientations(count, rng=None):
    """(count, 4) unit quaternions uniformly distributed over the rotations (normalised
    4D Gaussians; Shoemake's uniformity), q0 >= 0."""
    rng = np.random.default_rng(rng)
    q = rng.standard_normal((int(count), 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    q[q[:, 0] < 0.0] *= -1.0
    return q


def make_clumps(model, state, clump_of, *, resolution=256, mass=None, inertia=None,
                centre=None):
    """Turn groups of the particles of (model, state) into rigid clumps.

    clump_of (N,) int: the clump of each particle (0 .. C-1, each used by >= 2
    particles), -1 for particles that stay free spheres. Each clump's mass, centre and
    inertia tensor are those of the union of its members at their material's density
    (``mass_properties``; one material per clump) unless mass (C,) kg, inertia (C,3,3)
    kg m^2 about the centre and centre (C,3) m are given (centre None: the members'
    volume-weighted mean, right when they do not overlap). Its velocity is the members'
    volume-weighted mean velocity and its angular velocity the mean of theirs; each
    member's velocity becomes the rigid motion's. Its orientation is that of its principal axes
    in the lab frame (q0 >= 0). Returns new (model, state); ValueError names a bad
    clump (a bond between members of one clump, mixed materials, a single member).
    """
    n = model.n_particles
    clump_of = np.asarray(clump_of)
    if clump_of.shape != (n,) or not np.issubdtype(clump_of.dtype, np.integer):
        raise ValueError(f"clump_of: expected {n} integers (a clump index or -1 per particle)")
    clump_of = clump_of.astype(INDEX)
    if np.any(clump_of < -1):
        raise ValueError("clump_of: indices must be >= -1 (-1: a free sphere)")
    count = int(clump_of.max()) + 1 if n else 0
    sizes = np.bincount(clump_of[clump_of >= 0], minlength=count)
    if np.any(sizes < 2):
        bad = int(np.flatnonzero(sizes < 2)[0])
        raise ValueError(f"clump_of: clump {bad} has {int(sizes[bad])} member(s); a clump "
                         "needs at least 2 (leave a single sphere free with -1)")
    if model.n_clumps:
        raise ValueError("make_clumps: the model has clumps already")
    if model.n_bonds:
        ends = clump_of[model.bond_pairs]
        inside = (ends[:, 0] >= 0) & (ends[:, 0] == ends[:, 1])
        if np.any(inside):
            b = int(np.flatnonzero(inside)[0])
            raise ValueError(f"bond {b} joins particles {model.bond_pairs[b].tolist()} of "
                             f"the same clump {int(ends[b, 0])}; a clump is rigid")
    if mass is not None:
        mass = np.asarray(mass, dtype=np.float64)
        inertia = np.asarray(inertia, dtype=np.float64)
        if mass.shape != (count,) or inertia.shape != (count, 3, 3):
            raise ValueError(f"mass, inertia: expected shapes ({count},) and ({count}, 3, 3)")
        if not np.all(mass > 0.0):
            raise ValueError("mass: every clump's mass must be > 0 (kg)")
        if centre is not None:
            centre = np.asarray(centre, dtype=np.float64)
            if centre.shape != (count, 3):
                raise ValueError(f"centre: expected shape ({count}, 3)")
    density = np.array([m.density for m in model.materials])
    new_mass = model.mass.copy()
    new_inertia = model.inertia.copy()
    offset = np.zeros((n, 3))
    clump_mass = np.zeros(count)
    clump_inertia = np.zeros((count, 3))
    position = np.zeros((count, 3))
    orientation = np.zeros((count, 4))
    velocity = np.zeros((count, 3))
    momentum = np.zeros((count, 3))
    new_state = state.copy()
    box_length = model.box_length
    # the members of clump c: grouped[starts[c]:starts[c + 1]] (one sort, not C scans)
    grouped = np.flatnonzero(clump_of >= 0)
    grouped = grouped[np.argsort(clump_of[grouped], kind="stable")]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    for c in range(count):
        members = grouped[starts[c]:starts[c + 1]]
        if np.any(model.fixed[members] != model.fixed[members[0]]):
            raise ValueError(f"clump {c}: some of its members are fixed and some not; fix "
                             "all of them (the clump's motion is then prescribed) or none")
        materials = np.unique(model.material[members])
        if materials.size != 1:
            raise ValueError(f"clump {c}: its members have materials {materials.tolist()}; "
                             "a clump has one material")
        # members as one piece across a periodic boundary: images nearest the first
        x = state.position[members].copy()
        d = x - x[0]
        d -= np.where(model.periodic, box_length * np.round(d / box_length), 0.0)
        x = x[0] + d
        r = model.radius[members]
        if mass is None:
            m, here, tensor = mass_properties(x, r, float(density[materials[0]]),
                                              resolution=resolution)
        else:
            m, tensor = float(mass[c]), inertia[c]
            volume = r ** 3
            here = volume @ x / volume.sum() if centre is None else None
            if centre is not None:
                # the given centre, as the image nearest the members
                here = centre[c] - np.where(model.periodic, box_length * np.round(
                    (centre[c] - x[0]) / box_length), 0.0)
        moments, axes = principal_frame(tensor)
        arm = x - here
        offset[members] = arm @ axes
        share = m * r ** 3 / np.sum(r ** 3)
        new_mass[members] = share
        new_inertia[members] = 0.4 * share * r * r
        weights = r ** 3 / np.sum(r ** 3)
        v = weights @ state.velocity[members]
        w = state.angular_velocity[members].mean(axis=0)
        clump_mass[c] = m
        clump_inertia[c] = moments
        position[c] = here
        orientation[c] = quaternion_from_matrix(axes)
        velocity[c] = v
        momentum[c] = axes @ (moments * (axes.T @ w))
        new_state.velocity[members] = v + np.cross(w, arm)
        new_state.angular_velocity[members] = w
    new_model = replace(model, mass=new_mass, inertia=new_inertia, clump_of=clump_of,
                        clump_offset=offset, clump_mass=clump_mass,
                        clump_inertia=clump_inertia)
    new_state.clump_position = position
    new_state.clump_orientation = orientation
    new_state.clump_velocity = velocity
    new_state.clump_angular_momentum = momentum
    return new_model, new_state


def set_clump_motion(model, state, clump, velocity=None, angular_velocity=None):
    """Give clump ``clump`` a velocity (3,) m/s and/or angular velocity (3,) rad/s (lab
    frame) and its members the rigid motion that goes with them (in place)."""
    axes = rotation_matrix(state.clump_orientation[clump])
    inertia = model.clump_inertia[clump]
    if velocity is not None:
        state.clump_velocity[clump] = np.asarray(velocity, dtype=np.float64)
    if angular_velocity is not None:
        w = np.asarray(angular_velocity, dtype=np.float64)
        state.clump_angular_momentum[clump] = axes @ (inertia * (axes.T @ w))
    w = axes @ ((axes.T @ state.clump_angular_momentum[clump]) / inertia)
    v = state.clump_velocity[clump]
    for p in np.flatnonzero(model.clump_of == clump):
        arm = axes @ model.clump_offset[p]
        state.velocity[p] = v + np.cross(w, arm)
        state.angular_velocity[p] = w


def clump_kinetic_energy(model, state):
    """(translational, rotational) kinetic energy (J) of the clumps: sum of M V^2 / 2 and
    of L . w / 2 with w = R I^-1 R^T L."""
    if model.n_clumps == 0:
        return 0.0, 0.0
    v = state.clump_velocity
    translational = 0.5 * float(np.sum(model.clump_mass * np.einsum("ij,ij->i", v, v)))
    q = state.clump_orientation
    q0, q1, q2, q3 = (q[:, k] for k in range(4))
    # R^T L, row by row of R (rotation_matrix's entries for every clump at once)
    rows = np.stack([
        np.stack([1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 - q0 * q3),
                  2 * (q1 * q3 + q0 * q2)], -1),
        np.stack([2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3),
                  2 * (q2 * q3 - q0 * q1)], -1),
        np.stack([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1),
                  1 - 2 * (q1 * q1 + q2 * q2)], -1)], axis=1)
    body = np.einsum("cij,ci->cj", rows, state.clump_angular_momentum)
    rotational = 0.5 * float(np.sum(body * body / model.clump_inertia))
    return translational, rotational


CANDIDATES = 64   # nodes tried for each next sphere of ClumpTemplate.from_mesh


class ClumpTemplate:
    """The shape of a kind of clump: member centres (M,3) m and radii (M,) m in the
    template's own frame (any origin), and a name. ``properties(density)`` gives its
    mass (kg), centre of mass (3,) m and inertia tensor about it (3,3) kg m^2
    (``mass_properties``, computed once per density)."""

    def __init__(self, centres, radii, *, name="clump", resolution=256):
        self.centres, self.radii = _check_members(centres, radii, f"clump template {name!r}")
        if self.centres.shape[0] < 2:
            raise ValueError(f"clump template {name!r}: a clump needs at least 2 members")
        self.name = str(name)
        self.resolution = int(resolution)
        self._cache = {}

    def __repr__(self):
        return f"ClumpTemplate({self.name!r}, {self.radii.size} members)"

    def properties(self, density):
        """(mass kg, centre (3,) m, inertia tensor (3,3) kg m^2) at ``density`` kg/m^3."""
        key = float(density)
        if key not in self._cache:
            self._cache[key] = mass_properties(self.centres, self.radii, key,
                                               resolution=self.resolution)
        return self._cache[key]

    @classmethod
    def from_mesh(cls, mesh, spheres=10, *, resolution=40, min_radius=0.0, name=None,
                  scale=1.0):
        """Fill a closed triangle mesh (an STL path, a trimesh.Trimesh or a
        ``generate.MeshVolume``; ``scale`` turns an STL's units into m) with at most
        ``spheres`` inscribed spheres, greedily: on a grid of ``resolution`` nodes along
        the mesh's longest side, each next sphere is centred at the node not yet covered
        that lies deepest inside (its radius is that exact distance to the surface, so
        every sphere lies inside the mesh), until ``spheres`` are placed or the next would
        be smaller than ``min_radius`` (m). The template's ``quality`` says how well it
        fills the shape: volume_fraction (the union's volume over the mesh's, <= 1),
        gyration_error (largest relative difference of the principal radii of gyration,
        sqrt(I_k / M), from the mesh's: the shape's spread of mass, whatever the density)
        and spheres. Among the CANDIDATES deepest free nodes the one whose sphere covers
        most free nodes is taken (the deepest alone leaves the corners empty)."""
        from .generate import MeshVolume
        if isinstance(mesh, MeshVolume):
            volume = mesh
        elif hasattr(mesh, "is_watertight"):
            volume = MeshVolume(mesh)
        else:
            volume = MeshVolume.from_stl(mesh, scale)
        if int(spheres) < 2:
            raise ValueError(f"spheres = {spheres!r}; a clump needs at least 2")
        if int(resolution) < 8:
            raise ValueError(f"resolution = {resolution!r}; must be >= 8")
        low, high = volume.bounds()
        h = float(np.max(high - low)) / int(resolution)
        axes = [np.arange(low[k] + 0.5 * h, high[k], h) for k in range(3)]
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        depth = volume.signed_distance(nodes)
        inside = depth > 0.0
        nodes, depth = nodes[inside], depth[inside]
        if nodes.shape[0] == 0:
            raise ValueError("the mesh is thinner than the grid: raise resolution")
        covered = np.zeros(nodes.shape[0], dtype=bool)
        centres, radii = [], []
        while len(radii) < int(spheres):
            free = np.flatnonzero(~covered)
            if free.size == 0:
                break
            # among the deepest free nodes, the one whose sphere covers most free ones
            deepest = free[np.argsort(-depth[free], kind="stable")[:CANDIDATES]]
            deepest = deepest[depth[deepest] >= min_radius]
            if deepest.size == 0:
                break
            gain = [np.count_nonzero(np.linalg.norm(nodes[free] - nodes[k], axis=1)
                                     <= depth[k]) for k in deepest]
            best = deepest[int(np.argmax(gain))]
            centres.append(nodes[best])
            radii.append(float(depth[best]))
            covered |= np.linalg.norm(nodes - nodes[best], axis=1) <= depth[best]
        if len(radii) < 2:
            raise ValueError("fewer than 2 spheres fit (min_radius too large, or the shape "
                             "is a sphere)")
        template = cls(np.array(centres), np.array(radii), name=name or "mesh")
        mass, _, tensor = template.properties(1.0)
        # trimesh's moments are at its mesh's density: scaled to density 1
        mesh_moments = np.linalg.eigvalsh(np.asarray(volume.mesh.moment_inertia)
                                          / float(volume.mesh.density))
        moments = np.linalg.eigvalsh(tensor)
        gyration = np.sqrt(moments / mass) / np.sqrt(mesh_moments / volume.volume)
        template.quality = {
            "spheres": len(radii), "volume_fraction": mass / volume.volume,
            "gyration_error": float(np.max(np.abs(gyration - 1.0)))}
        return template

    @property
    def bounding_radius(self) -> float:
        """Radius (m) of the smallest sphere about the template's centroid of volume
        (r^3-weighted mean of the centres) that holds every member."""
        middle = self.radii ** 3 @ self.centres / np.sum(self.radii ** 3)
        return float(np.max(np.linalg.norm(self.centres - middle, axis=1) + self.radii))


def place_clumps(template, centres, orientations, density):
    """Members of copies of ``template`` whose centres of mass sit at ``centres`` (C,3) m,
    turned by the unit quaternions ``orientations`` (C,4) (template frame to lab).
    Returns a dict: position (C M, 3) m, radius (C M,) m, clump_of (C M,) and, per clump,
    mass (C,) kg, centre (C,3) m, inertia (C,3,3) kg m^2 (``make_clumps``'s arguments)."""
    centres = np.atleast_2d(np.asarray(centres, dtype=np.float64))
    orientations = np.atleast_2d(np.asarray(orientations, dtype=np.float64))
    if centres.shape[1] != 3 or orientations.shape != (centres.shape[0], 4):
        raise ValueError("place_clumps: expected centres (C, 3) and orientations (C, 4)")
    mass, middle, tensor = template.properties(density)
    local = template.centres - middle
    count, m = centres.shape[0], local.shape[0]
    position = np.zeros((count * m, 3))
    inertia = np.zeros((count, 3, 3))
    for c in range(count):
        turn = rotation_matrix(orientations[c])
        position[c * m:(c + 1) * m] = centres[c] + local @ turn.T
        inertia[c] = turn @ tensor @ turn.T
    return {"position": position, "radius": np.tile(template.radii, count),
            "clump_of": np.repeat(np.arange(count, dtype=INDEX), m),
            "mass": np.full(count, mass), "centre": centres.copy(), "inertia": inertia}


def pack_clumps(volume, template, density, *, solids_fraction=0.5, seed=0, compact=1.0,
                max_overlap=1e-3, max_iterations=2000):
    """A random packing of copies of ``template`` in ``volume`` (a ``generate`` Sphere,
    Box, Cylinder or MeshVolume), randomly oriented. Spheres of ``compact`` times the
    template's bounding radius are packed by ``generate.pack_spheres`` at
    ``solids_fraction`` (of those spheres) and a clump put in each. compact = 1: no two
    clumps touch and every member lies inside the volume (the clumps' own solids
    fraction is lower by their volume over the bounding sphere's); compact < 1 (down to
    0.5): the clumps interlock and touch, their members' overlaps then removed by moving
    the clumps apart (translations only, up to max_overlap of the smaller radius, at most
    max_iterations sweeps), and members may stand out of the volume by up to (1 -
    compact) bounding radii. Same seed, same packing. Returns ``place_clumps``'s dict
    plus orientation (C,4). RuntimeError when the overlaps do not go."""
    from scipy.spatial import cKDTree
    from .generate import pack_spheres
    if not 0.5 <= compact <= 1.0:
        raise ValueError(f"compact = {compact!r}; allowed range [0.5, 1]")
    centres, _ = pack_spheres(volume, radius=compact * template.bounding_radius,
                              solids_fraction=solids_fraction, seed=seed)
    # the template's centroid of volume sits at each packed sphere's centre
    mass, middle, _ = template.properties(density)
    shift = middle - template.radii ** 3 @ template.centres / np.sum(template.radii ** 3)
    orientation = random_orientations(centres.shape[0], np.random.default_rng(seed + 1))
    turns = np.array([rotation_matrix(q) for q in orientation]).reshape(-1, 3, 3)
    centres = centres + np.einsum("cij,j->ci", turns, shift)
    if compact < 1.0 and centres.shape[0] > 1:
        local = template.centres - middle
        arms = np.einsum("cij,mj->cmi", turns, local).reshape(-1, 3)
        radius = np.tile(template.radii, centres.shape[0])
        owner = np.repeat(np.arange(centres.shape[0]), local.shape[0])
        reach = 2.0 * radius.max()
        limit = max_overlap * radius.min()
        for _ in range(max_iterations):
            x = centres[owner] + arms
            pairs = cKDTree(x).query_pairs(reach, output_type="ndarray")
            pairs = pairs[owner[pairs[:, 0]] != owner[pairs[:, 1]]]
            d = x[pairs[:, 1]] - x[pairs[:, 0]]
            distance = np.linalg.norm(d, axis=1)
            overlap = radius[pairs[:, 0]] + radius[pairs[:, 1]] - distance
            hit = overlap > 0.0
            if not np.any(overlap > limit):
                break
            pairs, d, distance, overlap = pairs[hit], d[hit], distance[hit], overlap[hit]
            # each clump moves half of each overlap (plus a margin) away from the other
            push = 0.5 * (overlap + 0.5 * limit)[:, None] * d / distance[:, None]
            move = np.zeros_like(centres)
            np.add.at(move, owner[pairs[:, 1]], push)
            np.add.at(move, owner[pairs[:, 0]], -push)
            centres = centres + 0.5 * move
        else:
            raise RuntimeError(f"pack_clumps: members still overlap by more than "
                               f"{max_overlap:g} radii after {max_iterations} sweeps; "
                               "lower solids_fraction or raise compact")
    out = place_clumps(template, centres, orientation, density)
    out["orientation"] = orientation
    return out


def bonds_between_clumps(position, radius, clump_of, max_gap, **options):
    """``generate.bonds_from_gap`` without the pairs inside one clump: bonds (B,2) and
    diameters (B,) m between members of different clumps (or free spheres) whose surface
    gap is at most ``max_gap`` m (``options``: diameter or diameter_ratio,
    max_per_particle, which counts only the bonds kept)."""
    from .generate import bonds_from_gap
    return bonds_from_gap(position, radius, max_gap, groups=clump_of, **options)

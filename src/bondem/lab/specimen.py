"""Specimens for the virtual laboratory: a bonded body as plain arrays (positions, radii,
bonds, materials) and its shape, from which each test builds its own Model.

Genesis (``make_specimen``): pack the container (box, cylinder, disc or sphere) with the
generator; optionally consolidate a box packing to an isotropic stress between six servo
walls with frictionless contacts; install bonds at contacts and within a gap (their initial
lengths are the distances then, so the bonded specimen starts stress-free, and the contact
history is dropped); carve to the final shape. ``lattice_specimen`` builds a simple cubic
lattice whose macro response is known in closed form; ``specimen_from_scene`` takes the
bonded body of any scene (generated or from CSV files).
"""
from __future__ import annotations

import collections
import dataclasses
import math
import pickle
from dataclasses import dataclass, field

import numpy as np

from ..generate import Box, Cylinder, Sphere, bonds_from_gap, pack_spheres
from ..model import BondMaterial, Material, make_system
from ..physics import contact_models

SHAPES = ("box", "cylinder", "disc", "sphere")
# the contact models that hold particles together beyond contact (a REACH)
ADHESIVE = tuple(m.NAME for m in contact_models.MODELS if getattr(m, "REACH", None))


@dataclass
class Specimen:
    """A bonded body for the lab tests.

    position (N,3) m; radius (N,) m; bonds (B,2) particle indices; bond_diameter (B,) m;
    materials: particle Materials with material_index (N,); bond_materials with
    bond_material_index (B,); shape: "box", "cylinder" (axis along z), "disc" (a cylinder
    whose axis is y: thickness along y, diameter in the x-z plane) or "sphere";
    contact_model: the particle contact law during the tests ("hertz_mindlin", "linear",
    "none"); lattice: True for a regular lattice (its closed forms hold at any size).
    """
    position: np.ndarray
    radius: np.ndarray
    bonds: np.ndarray
    bond_diameter: np.ndarray
    materials: list
    bond_materials: list
    shape: str = "box"
    material_index: np.ndarray | None = None
    bond_material_index: np.ndarray | None = None
    contact_model: str = "hertz_mindlin"
    notes: list = field(default_factory=list)
    lattice: bool = False

    def __post_init__(self):
        self.position = np.ascontiguousarray(self.position, dtype=np.float64)
        n = self.position.shape[0]
        self.radius = np.broadcast_to(np.asarray(self.radius, dtype=np.float64), (n,)).copy()
        self.bonds = np.asarray(self.bonds, dtype=np.int64).reshape(-1, 2)
        self.bond_diameter = np.broadcast_to(np.asarray(self.bond_diameter, np.float64),
                                             (self.bonds.shape[0],)).copy()
        if isinstance(self.materials, Material):
            self.materials = [self.materials]
        if isinstance(self.bond_materials, BondMaterial):
            self.bond_materials = [self.bond_materials]
        if self.material_index is None:
            self.material_index = np.zeros(n, dtype=np.int64)
        if self.bond_material_index is None:
            self.bond_material_index = np.zeros(self.bonds.shape[0], dtype=np.int64)
        if self.shape not in SHAPES:
            raise ValueError(f"shape = {self.shape!r}; allowed: {', '.join(SHAPES)}")
        if n < 2 or (self.bonds.shape[0] == 0 and not self.adhesive()):
            raise ValueError(f"a specimen needs bonded particles (or an adhesive contact "
                             f"model: {', '.join(ADHESIVE)}); it has {n} particles and "
                             f"{self.bonds.shape[0]} bonds")

    def adhesive(self):
        """True when the contact model holds particles together without bonds."""
        return self.contact_model in ADHESIVE

    @property
    def n_particles(self):
        return self.position.shape[0]

    @property
    def n_bonds(self):
        return self.bonds.shape[0]

    def bounds(self):
        """(low (3,), high (3,)) m: the box holding every particle surface."""
        return ((self.position - self.radius[:, None]).min(axis=0),
                (self.position + self.radius[:, None]).max(axis=0))

    def size(self):
        """Extent (3,) m of the body along x, y, z."""
        low, high = self.bounds()
        return high - low

    def cross_section(self, axis=2):
        """Area (m^2) normal to ``axis`` (0, 1, 2): width times depth for boxes, the circle
        of the mean lateral extent for cylinders, discs and spheres."""
        size = self.size()
        lateral = [size[k] for k in range(3) if k != axis]
        if self.shape == "box":
            return float(lateral[0] * lateral[1])
        if self.shape == "disc" and axis == 2:   # a disc loaded across its diameter
            return float(size[0] * size[1])
        return float(math.pi * 0.25 * np.mean(lateral) ** 2)

    def solids_fraction(self):
        """Particle volume over the volume of the specimen's shape."""
        size = self.size()
        volume = {"box": np.prod(size),
                  "cylinder": math.pi * 0.25 * np.mean(size[:2]) ** 2 * size[2],
                  "disc": math.pi * 0.25 * np.mean(size[[0, 2]]) ** 2 * size[1],
                  "sphere": math.pi / 6.0 * np.mean(size) ** 3}[self.shape]
        return float(np.sum(4.0 / 3.0 * math.pi * self.radius ** 3) / volume)

    def coordination(self):
        """Mean number of bonds per particle."""
        return 2.0 * self.n_bonds / self.n_particles

    def with_bond_material(self, **changes):
        """A copy whose bond materials all have ``changes`` (e.g. young_modulus=2e9),
        each value multiplied in when given as ``scale_<key>``."""
        materials = []
        for m in self.bond_materials:
            values = {}
            for key, value in changes.items():
                if key.startswith("scale_"):
                    name = key[len("scale_"):]
                    values[name] = getattr(m, name) * value
                else:
                    values[key] = value
            materials.append(dataclasses.replace(m, **values))
        return dataclasses.replace(self, bond_materials=materials, notes=list(self.notes))

    def system(self, *, fixed=None, velocity=None, damping=0.0):
        """(Model, State) of this specimen at rest: bonds' initial lengths are their current
        lengths; fixed (N,) bool and velocity (N,3) m/s for gripped particles; damping:
        local damping coefficient in [0, 1)."""
        bonded = self.bonds.shape[0] > 0
        return make_system(self.position, self.radius, self.materials,
                           material_index=self.material_index, velocity=velocity,
                           fixed=fixed, bonds=self.bonds if bonded else None,
                           bond_diameter=self.bond_diameter if bonded else None,
                           bond_material=self.bond_materials if bonded else None,
                           bond_material_index=self.bond_material_index if bonded else None,
                           damping=damping)


def lattice_specimen(counts, radius, material, bond_material, *, bond_diameter=None,
                     diameter_ratio=1.0, spacing=None, contact_model="hertz_mindlin",
                     shape="box"):
    """A simple cubic lattice of counts = (nx, ny, nz) spheres of ``radius`` (m) at
    ``spacing`` (m, default 2 radius: touching), each bonded to its six neighbours with
    bonds of ``bond_diameter`` (m; default diameter_ratio times the particle diameter).

    Along an axis it is a set of parallel chains: E = k_n / a = E_b A_b / a^2 with
    A_b = pi d_b^2 / 4, Poisson's ratio 0, and in direct tension it fails when the bonds
    reach their normal strength: sigma_t = sigma_b A_b / a^2 (see docs/lab.md).
    shape "cylinder": only the particles whose centres lie within (min(nx, ny) - 1) a / 2
    of the z axis through the lattice's middle (and their bonds): a cylinder of chains."""
    if shape not in ("box", "cylinder"):
        raise ValueError(f"shape = {shape!r}; a lattice is a box or a cylinder")
    counts = [int(c) for c in counts]
    if len(counts) != 3 or min(counts) < 1 or np.prod(counts) < 2:
        raise ValueError(f"counts = {counts}: expected three integers >= 1")
    a = 2.0 * radius if spacing is None else float(spacing)
    index = np.arange(np.prod(counts)).reshape(counts)
    grid = np.stack(np.meshgrid(*[np.arange(c) for c in counts], indexing="ij"), -1)
    position = (grid.reshape(-1, 3) - 0.5 * (np.array(counts) - 1)) * a
    pairs = []
    for axis in range(3):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(0, -1), slice(1, None)
        pairs.append(np.column_stack([index[tuple(lo)].ravel(), index[tuple(hi)].ravel()]))
    pairs = np.concatenate(pairs)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    diameter = 2.0 * radius * diameter_ratio if bond_diameter is None else bond_diameter
    what = f"simple cubic lattice {counts[0]} x {counts[1]} x {counts[2]}, spacing {a:.4g} m"
    if shape == "cylinder":
        cut = 0.5 * (min(counts[0], counts[1]) - 1) * a * (1.0 + 1e-9)
        keep = np.hypot(position[:, 0], position[:, 1]) <= cut
        new = np.cumsum(keep) - 1
        pairs = new[pairs[keep[pairs[:, 0]] & keep[pairs[:, 1]]]]
        position = position[keep]
        what += f", cut to a cylinder of centres within {cut:.4g} m of the axis"
    return Specimen(position, radius, pairs, diameter, [material], [bond_material],
                    shape=shape, contact_model=contact_model, lattice=True, notes=[what])


def _container(shape, size, center):
    size = np.asarray(size, dtype=np.float64).reshape(-1)
    if shape == "box":
        if size.shape != (3,):
            raise ValueError("a box specimen's size is [x, y, z] (m)")
        return Box(center - 0.5 * size, center + 0.5 * size)
    if shape == "cylinder":
        if size.shape != (2,):
            raise ValueError("a cylinder specimen's size is [diameter, height] (m)")
        return Cylinder(center, 0.5 * size[0], size[1], (0.0, 0.0, 1.0))
    if shape == "disc":
        if size.shape != (2,):
            raise ValueError("a disc specimen's size is [diameter, thickness] (m)")
        return Cylinder(center, 0.5 * size[0], size[1], (0.0, 1.0, 0.0))
    if size.shape != (1,):
        raise ValueError("a sphere specimen's size is [diameter] (m)")
    return Sphere(center, 0.5 * size[0])


def _inside(shape, size, position, radius):
    """Particles whose whole sphere lies in the final shape (carving)."""
    size = np.asarray(size, dtype=np.float64).reshape(-1)
    if shape == "box":
        return np.all(np.abs(position) + radius[:, None] <= 0.5 * size + 1e-12, axis=1)
    if shape == "cylinder":
        rho = np.hypot(position[:, 0], position[:, 1])
        return (rho + radius <= 0.5 * size[0]) & (np.abs(position[:, 2]) + radius
                                                   <= 0.5 * size[1])
    if shape == "disc":
        rho = np.hypot(position[:, 0], position[:, 2])
        return (rho + radius <= 0.5 * size[0]) & (np.abs(position[:, 1]) + radius
                                                   <= 0.5 * size[1])
    return np.linalg.norm(position, axis=1) + radius <= 0.5 * size[0]


GEOMETRIES = 8   # packed specimens kept per process (make_specimen)
_geometries = collections.OrderedDict()


def _geometry(shape, size, particle_radius, radius_distribution, solids_fraction, seed,
              material, unbonded, max_gap, diameter_ratio, max_per_particle,
              consolidation_stress, consolidation_steps, progress):
    """make_specimen's packing: (positions (N,3) m, radii (N,) m, bond pairs, bond
    diameters (m), notes)."""
    center = np.zeros(3)
    notes = []
    if consolidation_stress is None:
        volume = _container(shape, size, center)
        position, radius = pack_spheres(volume, radius=particle_radius,
                                        radius_distribution=radius_distribution,
                                        solids_fraction=solids_fraction, seed=seed)
    else:
        box = np.asarray(_container(shape, size, center).bounds())
        # a margin of particles beyond the shape, carved off after consolidation
        reach = 2.0 * (particle_radius or np.max(radius_distribution["radius"]))
        volume = Box(box[0] - reach, box[1] + reach)
        position, radius = pack_spheres(volume, radius=particle_radius,
                                        radius_distribution=radius_distribution,
                                        solids_fraction=solids_fraction, seed=seed)
        position, reached = consolidate(position, radius, material, consolidation_stress,
                                        max_steps=consolidation_steps, progress=progress)
        position -= 0.5 * (position.min(axis=0) + position.max(axis=0))
        notes.append(f"consolidated to {consolidation_stress:.4g} Pa"
                     + ("" if reached else " (not reached within the step limit)"))
        keep = _inside(shape, size, position, radius)
        position, radius = position[keep], radius[keep]
    if unbonded:    # an adhesive agglomerate: its contacts hold it
        pairs, diameter = np.zeros((0, 2), dtype=np.int64), np.zeros(0)
    else:
        pairs, diameter = bonds_from_gap(position, radius, max_gap,
                                         diameter_ratio=diameter_ratio,
                                         max_per_particle=max_per_particle)
    return position, radius, pairs, diameter, notes


def make_specimen(shape, size, *, particle_radius=None, radius_distribution=None,
                  solids_fraction=0.55, seed=0, material, bond_material, max_gap=0.0,
                  diameter_ratio=0.5, max_per_particle=None, consolidation_stress=None,
                  consolidation_steps=200_000, contact_model="hertz_mindlin", progress=None):
    """A random bonded specimen centred at the origin.

    shape: "box" (size [x, y, z] m), "cylinder" (size [diameter, height], axis z), "disc"
    ([diameter, thickness], axis y) or "sphere" ([diameter]); particle_radius (m) or
    radius_distribution (see ``generate.sample_radii``); solids_fraction of the packing;
    seed: the same seed gives the same specimen; material: the particles' Material;
    bond_material: a BondMaterial, or None for no bonds (with an adhesive contact_model:
    its contacts hold the body); max_gap (m): bonds between pairs whose surface gap is at
    most this (overlaps count); diameter_ratio: bond diameter over the smaller particle's;
    consolidation_stress (Pa): if given, the packing is made in the box around the shape,
    pressed to this isotropic stress by six servo walls with frictionless contacts, bonded
    and then carved to the shape (the bonds take the consolidated distances as their
    lengths, so the specimen starts stress-free).
    """
    if shape not in SHAPES:
        raise ValueError(f"shape = {shape!r}; allowed: {', '.join(SHAPES)}")
    if bond_material is None and contact_model not in ADHESIVE:
        raise ValueError(f"bond_material: required with contact_model = {contact_model!r} "
                         f"(without bonds only an adhesive model holds a body: "
                         f"{', '.join(ADHESIVE)})")
    # the packing and its bonds' places do not depend on the bond material: a calibration
    # that varies only the bonds packs each specimen once per process (GEOMETRIES)
    key = pickle.dumps((shape, np.asarray(size, dtype=float).tolist(), particle_radius,
                        radius_distribution, solids_fraction, seed, max_gap, diameter_ratio,
                        max_per_particle, consolidation_stress, consolidation_steps,
                        material if consolidation_stress is not None else None,
                        bond_material is None))
    if key not in _geometries:
        _geometries[key] = _geometry(shape, size, particle_radius, radius_distribution,
                                     solids_fraction, seed, material, bond_material is None,
                                     max_gap, diameter_ratio, max_per_particle,
                                     consolidation_stress, consolidation_steps, progress)
        while len(_geometries) > GEOMETRIES:
            _geometries.popitem(last=False)
    _geometries.move_to_end(key)
    position, radius, pairs, diameter, notes = (
        np.copy(v) if isinstance(v, np.ndarray) else list(v) for v in _geometries[key])
    specimen = Specimen(position, radius, pairs, diameter, [material],
                        [] if bond_material is None else [bond_material],
                        shape=shape, contact_model=contact_model, notes=notes)
    specimen.notes.append(f"{specimen.n_particles} particles, {specimen.n_bonds} bonds, "
                          f"coordination {specimen.coordination():.2f}, solids fraction "
                          f"{specimen.solids_fraction():.3f}")
    return specimen


def consolidate(position, radius, material, stress, *, max_steps=200_000, tolerance=0.02,
                progress=None):
    """Press loose spheres to an isotropic ``stress`` (Pa) between six servo planes with
    frictionless Hertz contacts and local damping 0.7. Returns (positions (N,3) m, True
    when every wall held the stress within ``tolerance`` and the kinetic energy had
    settled)."""
    from ..contacts import ContactSettings
    from ..simulation import Simulation
    from ..walls import PlaneWall, Servo
    smooth = dataclasses.replace(material, friction=0.0, rolling_friction=0.0,
                                 restitution=0.5)
    model, state = make_system(position, radius, smooth, damping=0.7)
    low = (position - radius[:, None]).min(axis=0)
    high = (position + radius[:, None]).max(axis=0)
    probe = Simulation(model, state.copy(), contact=ContactSettings(rolling_resistance=False))
    dt = probe.time_step
    r = float(np.mean(radius))
    force_per_contact = stress * 4.0 * r * r
    e_star = material.young_modulus / (2.0 * (1.0 - material.poisson_ratio ** 2))
    overlap = (3.0 * force_per_contact / (4.0 * e_star * math.sqrt(0.5 * r))) ** (2.0 / 3.0)
    walls, servos = [], []
    for axis in range(3):
        for side, point in ((1.0, low), (-1.0, high)):
            normal = np.zeros(3)
            normal[axis] = side
            # area and gain set below, once the walls exist to measure the box
            servo = Servo(target_stress=stress, area=1.0, gain=1.0, max_velocity=1.0,
                          tolerance=tolerance)
            servos.append((axis, side, servo))
            walls.append(PlaneWall(point.copy(), normal, smooth, motion=servo))
    sim = Simulation(model, state, contact=ContactSettings(rolling_resistance=False),
                     walls=walls, time_step=dt)

    extent = box_widths(sim, walls)

    for axis, side, servo in servos:
        others = [k for k in range(3) if k != axis]
        servo.area = (lambda o=others: extent(o[0]) * extent(o[1]))
        contacts = servo.area() / (4.0 * r * r)
        stiffness = contacts * 1.5 * force_per_contact / overlap
        servo.gain = 0.3 / (stiffness * dt)
        servo.max_velocity = 0.01 * r / dt
    settled = False
    for done in range(0, max_steps, 500):
        sim.step(500)
        kinetic = sum(sim.kinetic_energy())
        scale = stress * float(np.prod([extent(k) for k in range(3)])) * 1e-6
        settled = all(s.reached for _, _, s in servos) and kinetic < scale
        if progress is not None:
            progress(done, max_steps, max(abs(s.error) for _, _, s in servos))
        if settled:
            break
    return sim.state.position.copy(), settled


def box_widths(sim, walls):
    """width(axis): the distance (m) between the two planes of ``walls`` normal to ``axis``
    at the simulation's current time (computed once per time: every servo asks)."""
    cache = {}

    def width(axis):
        now = sim.state.time
        if cache.get("time") != now:
            cache.clear()
            cache["time"] = now
            cache["points"] = [w.position(now) for w in walls]
        pair = [p[axis] for w, p in zip(walls, cache["points"]) if w.normal[axis] != 0.0]
        return abs(pair[1] - pair[0])

    return width


def specimen_from_scene(path, overrides=None, shape="box"):
    """The bonded body of a scene file (generated or from CSV files) as a Specimen, with
    the scene's materials, bond materials and contact model (its walls are not used)."""
    from ..scene import load_scene
    scene = load_scene(path, overrides)
    model, state = scene.model, scene.state
    contact = scene.simulation_options.get("contact")
    return Specimen(state.position.copy(), model.radius.copy(), model.bond_pairs.copy(),
                    model.bond_diameter.copy(), list(model.materials),
                    list(model.bond_materials), shape=shape,
                    material_index=model.material.astype(np.int64),
                    bond_material_index=model.bond_material.astype(np.int64),
                    contact_model=contact.model if contact is not None else "none",
                    notes=[f"from {path}"])

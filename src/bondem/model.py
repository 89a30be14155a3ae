"""Model (constant arrays) and State (changing arrays) of a bonded-particle system.

Structure of arrays, SI units, float64. ``Model`` holds what does not change during a run
(radii, masses, bond pairs and materials); ``State`` what does (positions, velocities,
accumulated bond vectors, contact history). Both are validated here, at the edge; kernels
assume valid input.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, make_dataclass

import numpy as np

from .physics import bond_models, contact_models
from .physics.bond_elastic import CRITERION_CODES
from .physics.bond_models import bond_material_schema
from .physics import field_models
from .physics.field_fluid import fluid_array  # noqa: F401  (bondem.model.fluid_array)
from .physics.field_frame import frame_array  # noqa: F401

INDEX = np.int64


# The particle material's own keys (schema entries as scene.py's), then each contact
# model's (physics/contact_models.py).
BASE_MATERIAL_KEYS = {
    "density": ("number", None, 0.0, math.inf, False, False),
    "young_modulus": ("number", None, 0.0, math.inf, False, False),
    "poisson_ratio": ("number", 0.3, -1.0, 0.5, False, False),
    "restitution": ("number", 0.5, 0.0, 1.0, False, True),
    "friction": ("number", 0.3, 0.0, math.inf, True, False),
    "rolling_friction": ("number", 0.0, 0.0, math.inf, True, False),
}


def material_schema():
    """Every particle material key with its schema entry: the base keys, then the contact
    models' PARAMETERS."""
    return {**BASE_MATERIAL_KEYS, **contact_models.material_schema()}


def _material_post_init(self):
    for key, (_kind, _default, low, high, include_low, include_high) in \
            material_schema().items():
        _check_range(f"material {self.name!r}", key, getattr(self, key), low, high,
                     include_low, include_high)
    values = {key: getattr(self, key) for key in material_schema()}
    for module in contact_models.MODELS:
        for key, message in getattr(module, "check", lambda v: [])(values):
            raise ValueError(f"material {self.name!r}: {message}")


def _material_class():
    """Material: density, young_modulus, the contact keys, name, then the contact models'
    parameters (keyword arguments, each with a default that leaves its law inert)."""
    fields_ = []
    for key, (_kind, default, *_rest) in BASE_MATERIAL_KEYS.items():
        fields_.append((key, float) if default is None
                       else (key, float, field(default=default)))
    fields_.append(("name", str, field(default="material")))
    for key, (_kind, default, *_rest) in contact_models.material_schema().items():
        fields_.append((key, float, field(default=default)))
    units = contact_models.units()
    doc = ("Particle material (also a wall's).\n\n    density: kg/m^3; young_modulus: Pa; "
           "poisson_ratio: -; restitution: coefficient of restitution in (0, 1]; friction: "
           "Coulomb sliding friction; rolling_friction: rolling resistance coefficient "
           "(dimensionless, times radius gives the lever arm); the contact models' keys "
           "(physics/contact_models.py): "
           + "; ".join(f"{k}: {u}" for k, u in units.items()) + ".")
    return make_dataclass("Material", fields_, frozen=True,
                          namespace={"__post_init__": _material_post_init, "__doc__": doc,
                                     "__module__": __name__})


Material = _material_class()


def _bond_material_post_init(self):
    where = f"bond material {self.name!r}"
    values = {key: getattr(self, key) for key in bond_material_schema()}
    for key, (kind, _, low, high, include_low, include_high) in \
            bond_material_schema().items():
        value = values[key]
        if kind == "number":
            _check_range(where, key, value, low, high, include_low, include_high)
        elif kind == "str" and value not in low:
            raise ValueError(f"{where}: {key} = {value!r}; allowed: "
                             + ", ".join(repr(k) for k in low))
    for key, message in bond_models.check(values):
        raise ValueError(f"{where}: {message}")


def _bond_material_class():
    """BondMaterial, its fields the bond models' schema (physics/bond_models.py) in
    order: the elastic bond's keys, ``name``, ``model``, then each other model's keys."""
    schema = bond_material_schema()
    elastic = list(bond_models.MODELS[0].PARAMETERS)
    order = elastic + ["name"] + [k for k in schema if k not in elastic]
    kinds = {"number": float, "str": str, "bool": bool}
    fields_ = []
    for key in order:
        if key == "name":
            fields_.append(("name", str, field(default="bond")))
            continue
        kind, default = schema[key][:2]
        if default is bond_models.REQUIRED:
            fields_.append((key, kinds[kind]))
        else:
            fields_.append((key, kinds[kind], field(default=default)))
    units = bond_models.units()
    doc = ("Bond material: its bond model and the model's parameters, one schema with the "
           "scene file (physics/bond_models.py).\n\n    model: "
           + " | ".join(repr(m.NAME) for m in bond_models.MODELS) + "; "
           + "; ".join(f"{k}: {units[k]}" for k in order if k in units)
           + "; breakage: " + " | ".join(repr(c) for c in CRITERION_CODES)
           + "; compressive_breakage: evaluate the normal criterion in compression too. "
           "Parameters of another model than ``model`` must keep their defaults.")
    cls = make_dataclass("BondMaterial", fields_, frozen=True,
                         namespace={"__post_init__": _bond_material_post_init, "__doc__": doc,
                                    "__module__": __name__})
    return cls


BondMaterial = _bond_material_class()


def _check_range(where, key, value, low, high, include_low=False, include_high=False):
    ok_low = value >= low if include_low else value > low
    ok_high = value <= high if include_high else value < high
    if not (isinstance(value, (int, float, np.floating, np.integer)) and ok_low and ok_high
            and not math.isnan(value)):
        lo, hi = ("[" if include_low else "("), ("]" if include_high else ")")
        raise ValueError(f"{where}: {key} = {value!r} is outside the allowed range "
                         f"{lo}{low}, {high}{hi}")


@dataclass(repr=False)
class Model:
    """Constant part of a system. Arrays indexed by particle (N) or bond (B).

    radius (N,) m; mass (N,) kg; inertia (N,) kg m^2; material (N,) index into materials;
    fixed (N,) bool: velocity prescribed, not integrated (zero velocity = clamped);
    external_force (N,3) N and external_moment (N,3) N m: constant loads;
    bond_pairs (B,2) particle indices i, j; bond_diameter (B,) m; bond_initial_length (B,) m;
    bond_material (B,) index into bond_materials; gravity (3,) m/s^2; fields: {NAME:
    parameter array} of every body-force field model (physics/field_models.py), e.g.
    "fluid": the fluid around the particles (``fluid_array``; drag and buoyancy,
    physics/field_fluid.py), "frame": a rotating frame of reference (``frame_array``;
    physics/field_frame.py);
    flow (nx, ny, nz, 3) m/s and flow_box (origin (3,) m, spacing (3,) m; spacing 0: no
    grid): the fluid's velocity given on a grid (``read_flow_grid``), added to its own;
    fluid_local (N, 4) or (0, 4) for none: the fluid's velocity (m/s) added at each
    particle and the voidage (-) around it (0: the fluid's), set each step by a flow
    field law (coupling.FlowField: an expression of x and t, a local voidage);
    periodic (3,) bool with box_low/box_high (3,) m the periodic cell (also the domain
    outside which a particle means a blown-up run, along non-periodic axes where finite);
    damping: local (non-viscous) damping coefficient in [0, 1), 0 for none.
    Clumps (rigid grains of several spheres, ``bondem.clumps``; empty arrays when there
    are none): clump_of (N,) the clump of each particle, -1 for a free sphere;
    clump_offset (N,3) m each member's centre in its clump's body frame (the principal
    axes, origin at the clump's centre of mass); clump_mass (C,) kg; clump_inertia (C,3)
    kg m^2 the principal moments. A member's mass and inertia above are its share of the
    clump's (what contacts and time steps see); the clump moves as one rigid body.
    """
    radius: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    material: np.ndarray
    fixed: np.ndarray
    external_force: np.ndarray
    external_moment: np.ndarray
    materials: list
    bond_pairs: np.ndarray
    bond_diameter: np.ndarray
    bond_initial_length: np.ndarray
    bond_material: np.ndarray
    bond_materials: list
    gravity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    fields: dict = field(default_factory=field_models.defaults)
    flow: np.ndarray = field(default_factory=lambda: np.zeros((1, 1, 1, 3)))
    flow_box: np.ndarray = field(default_factory=lambda: np.zeros(6))
    fluid_local: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    periodic: np.ndarray = field(default_factory=lambda: np.zeros(3, dtype=bool))
    box_low: np.ndarray = field(default_factory=lambda: np.full(3, -np.inf))
    box_high: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    damping: float = 0.0
    clump_of: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=INDEX))
    clump_offset: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    clump_mass: np.ndarray = field(default_factory=lambda: np.zeros(0))
    clump_inertia: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __repr__(self):
        periodic = "".join(a for a, p in zip("xyz", self.periodic) if p) or "none"
        return (f"Model({self.n_particles} particles, {self.n_bonds} bonds, "
                f"{len(self.materials)} materials, {len(self.bond_materials)} bond materials, "
                f"{int(np.count_nonzero(self.fixed))} fixed, periodic {periodic}, "
                f"gravity {self.gravity.tolist()} m/s^2, damping {self.damping:g})")

    def set_flow(self, velocity, origin, spacing):
        """Give the fluid a velocity field on a grid: velocity (nx, ny, nz, 3) m/s at the
        nodes origin + (i, j, k) spacing (m), interpolated trilinearly (physics/
        field_fluid.py: flow_velocity). ValueError names a bad argument."""
        velocity = np.ascontiguousarray(velocity, dtype=np.float64)
        if velocity.ndim != 4 or velocity.shape[3] != 3 or velocity.size == 0:
            raise ValueError(f"flow velocity: expected an (nx, ny, nz, 3) array, got shape "
                             f"{velocity.shape}")
        if not np.all(np.isfinite(velocity)):
            raise ValueError("flow velocity: not all finite")
        origin = np.asarray(origin, dtype=np.float64)
        spacing = np.asarray(spacing, dtype=np.float64)
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise ValueError(f"flow origin: expected 3 finite numbers, got {origin!r}")
        if spacing.shape != (3,) or not np.all(np.isfinite(spacing) & (spacing > 0)):
            raise ValueError(f"flow spacing: expected 3 numbers > 0, got {spacing!r}")
        self.flow = velocity
        self.flow_box = np.concatenate([origin, spacing])

    @property
    def acting_fields(self) -> list:
        """The names of the field models that act (a fluid's drag or buoyancy, a turning
        frame; gravity is not one of them)."""
        return field_models.acting(self.fields)

    @property
    def n_particles(self) -> int:
        return self.radius.shape[0]

    @property
    def n_bonds(self) -> int:
        return self.bond_pairs.shape[0]

    @property
    def n_clumps(self) -> int:
        """Number of clumps (rigid grains of several spheres)."""
        return self.clump_mass.shape[0]

    def clump_members(self):
        """(offsets (C+1,), members) int64: clump c's member particles are
        members[offsets[c]:offsets[c+1]], ascending."""
        of = self.clump_of
        members = np.flatnonzero(of >= 0).astype(INDEX)
        members = members[np.argsort(of[members], kind="stable")]
        offsets = np.zeros(self.n_clumps + 1, dtype=INDEX)
        np.cumsum(np.bincount(of[members], minlength=self.n_clumps), out=offsets[1:])
        return offsets, members

    def integrated(self) -> np.ndarray:
        """(N,) bool: particles whose velocity is prescribed or set by their clump
        (fixed, or clump members), which the per-particle update does not kick."""
        if self.n_clumps == 0:
            return self.fixed
        return self.fixed | (self.clump_of >= 0)

    @property
    def box_length(self) -> np.ndarray:
        """Periodic cell lengths (m); 1 along axes that are not periodic (unused there)."""
        return np.where(self.periodic, self.box_high - self.box_low, 1.0)

    def material_table(self) -> dict:
        """Per-material property arrays for kernels."""
        m = self.materials
        return {k: np.array([getattr(x, k) for x in m], dtype=np.float64)
                for k in ("density", "young_modulus", "poisson_ratio", "restitution",
                          "friction", "rolling_friction")}

    def bond_material_table(self) -> dict:
        """Per-bond-material arrays for kernels, one per schema key (numbers float64,
        booleans bool, choices int8 codes: ``model`` the bond model's CODE, ``breakage``
        the criterion, also under "criterion")."""
        m = self.bond_materials
        table = {}
        for key, (kind, _, choices, *_rest) in bond_material_schema().items():
            values = [getattr(x, key) for x in m]
            if kind == "number":
                table[key] = np.array(values, dtype=np.float64)
            elif kind == "bool":
                table[key] = np.array(values, dtype=np.bool_)
            else:
                table[key] = np.array([choices.index(v) for v in values], dtype=np.int8)
        table["criterion"] = table["breakage"]
        return table

    def bond_strength_factors(self) -> np.ndarray:
        """(B,) factor of each bond's strengths (and yield stress), mean 1: 1 without
        scatter; with strength_scatter "normal" 1 + cv z (z standard normal, cv =
        strength_spread, clipped at 1e-3), with "weibull" w / Gamma(1 + 1/k) (w Weibull
        of modulus k = strength_spread, scale 1). Bond b of a material takes draw b of
        numpy.random.default_rng(strength_seed), so a bond's factor depends only on its
        index and its material's seed, whatever the backend or thread count."""
        factors = np.ones(self.n_bonds)
        for k, material in enumerate(self.bond_materials):
            scatter = getattr(material, "strength_scatter", "none")
            mine = self.bond_material == k
            if scatter == "none" or not np.any(mine):
                continue
            rng = np.random.default_rng(int(material.strength_seed))
            spread = material.strength_spread
            if scatter == "normal":
                draws = np.maximum(1.0 + spread * rng.standard_normal(self.n_bonds), 1e-3)
            else:
                draws = rng.weibull(spread, self.n_bonds) / math.gamma(1.0 + 1.0 / spread)
            factors[mine] = draws[mine]
        return factors

    def bond_model_codes(self) -> np.ndarray:
        """(B,) int8: each bond's model code (index into physics/bond_models.MODELS)."""
        return self.bond_material_table()["model"][self.bond_material]

    def bond_models_used(self) -> list:
        """The bond model modules (physics/bond_models.py) that some bond uses."""
        return [bond_models.MODELS[int(c)] for c in np.unique(self.bond_model_codes())]


@dataclass(repr=False)
class State:
    """Changing part of a system.

    time: s; step: steps taken; started: the start-up step is done (velocities then
    live at half steps); position, velocity, angular_velocity (N,3) in m, m/s, rad/s;
    bond_active (B,); bond_axis (B,3) unit axis of the last step; bond_tangential_force
    (B,3) N; bond_normal_moment, bond_tangential_moment (B,3) N m, all on particle i;
    bond_break_time (B,) s, NaN while intact; bond_break_mode (B,) 0 intact, 1 tension,
    2 compression, 3 shear; bond_break_energy (B,) J: elastic energy the bond held when it
    broke; work_external: J done on particles by gravity and external loads so far;
    dissipated_damping: J removed by local damping so far. ``extra`` holds other laws'
    history and counters (contacts, walls) as arrays. bond_previous_length (B,) m: |x_j -
    x_i| of the last step, which MUSEN's rotation needs (``musen_compat``); None in states
    made before it existed: ``Simulation`` then sets it to the initial lengths.
    Clumps (C of them; empty without): clump_position (C,3) m their centres of mass;
    clump_orientation (C,4) unit quaternions (q0, q1, q2, q3) from body to lab frame;
    clump_velocity (C,3) m/s; clump_angular_momentum (C,3) N m s about the centre, in the
    lab frame. Their members' rows of position, velocity and angular_velocity follow.
    """
    time: float
    step: int
    started: bool
    position: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    bond_active: np.ndarray
    bond_axis: np.ndarray
    bond_tangential_force: np.ndarray
    bond_normal_moment: np.ndarray
    bond_tangential_moment: np.ndarray
    bond_break_time: np.ndarray
    bond_break_mode: np.ndarray
    bond_break_energy: np.ndarray
    work_external: float = 0.0
    dissipated_damping: float = 0.0
    bond_previous_length: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
    clump_position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    clump_orientation: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    clump_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    clump_angular_momentum: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __repr__(self):
        intact = int(np.count_nonzero(self.bond_active))
        return (f"State(t = {self.time:.6g} s, step {self.step}, "
                f"{self.position.shape[0]} particles, {intact} of {self.bond_active.shape[0]} "
                f"bonds intact)")

    def copy(self) -> "State":
        """Deep copy (arrays copied)."""
        kwargs = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                value = value.copy()
            elif isinstance(value, dict):
                value = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in value.items()}
            kwargs[f.name] = value
        return State(**kwargs)

    def arrays(self) -> dict:
        """Every array of the state by name (``extra`` entries prefixed ``extra/``)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)
               if isinstance(getattr(self, f.name), np.ndarray)}
        out.update({f"extra/{k}": v for k, v in self.extra.items()})
        return out


def _as_vectors(name, value, n, default=0.0):
    if value is None:
        return np.full((n, 3), default, dtype=np.float64)
    array = np.array(value, dtype=np.float64)
    if array.shape == (3,):
        array = np.broadcast_to(array, (n, 3)).copy()
    if array.shape != (n, 3):
        raise ValueError(f"{name}: shape {array.shape}, expected ({n}, 3) for {n} particles")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return np.ascontiguousarray(array)


def _per_item(name, value, n, dtype, count_name):
    array = np.asarray(value, dtype=dtype)
    if array.ndim == 0:
        array = np.full(n, array, dtype=dtype)
    if array.shape != (n,):
        raise ValueError(f"{name}: length {array.shape[0] if array.ndim else 1}, "
                         f"expected {n} ({count_name})")
    return np.ascontiguousarray(array)


def bond_separation(position, pairs, box_length, periodic):
    """x_j - x_i (B,3) m of each pair (B,2) of rows of position (N,3) m, by the minimum
    image along the periodic axes (3,) bool, or None, of a cell of box_length (3,) m."""
    separation = position[pairs[:, 1]] - position[pairs[:, 0]]
    if np.any(periodic):
        box = np.where(periodic, box_length, 1.0)
        separation -= np.where(periodic, box * np.floor(separation / box + 0.5), 0.0)
    return separation


def _field_arrays(given):
    """{NAME: parameter array} of every field model: ``given``'s (float64 copies of the
    default's shape), the default (off) for the others. ValueError names a bad one."""
    out = field_models.defaults()
    for name, values in given.items():
        if name not in out:
            raise ValueError(f"unexpected keyword {name!r}: neither an argument nor a "
                             f"field model (field models: {', '.join(out)})")
        if values is None:
            continue
        values = np.array(values, dtype=np.float64)
        if values.shape != out[name].shape:
            raise ValueError(f"{name}: expected {out[name].size} numbers (its model's "
                             f"array), got shape {values.shape}")
        out[name] = values
    return out


def make_system(position, radius, material, *, material_index=None, velocity=None,
                angular_velocity=None, fixed=None, external_force=None, external_moment=None,
                bonds=None, bond_diameter=None, bond_material=None, bond_material_index=None,
                gravity=(0.0, 0.0, 0.0), periodic=(False, False, False), box_low=None,
                box_high=None, damping=0.0, **fields):
    """Build a validated (Model, State) pair from plain arrays.

    position (N,3) m; radius (N,) or scalar m; material: a Material or a list of them
    (then material_index (N,) selects one per particle); velocity (N,3) m/s;
    angular_velocity (N,3) rad/s; fixed (N,) bool; external_force (N,3) N;
    external_moment (N,3) N m; bonds (B,2) 0-based particle indices; bond_diameter (B,) or
    scalar m; bond_material: a BondMaterial or a list (then bond_material_index (B,));
    gravity (3,) m/s^2; fields: a field model's parameter array under its NAME
    (physics/field_models.py), e.g. fluid=``fluid_array(...)``, frame=``frame_array(...)``
    (absent or None: the field off); periodic (3,) bool with
    box_low/box_high (3,) m; damping: local
    damping coefficient in [0, 1). Bond initial lengths are the current distances
    (minimum image along periodic axes). Raises ValueError on inconsistent input.
    """
    position = np.asarray(position, dtype=np.float64)
    if position.ndim != 2 or position.shape[1] != 3:
        raise ValueError(f"position: shape {position.shape}, expected (N, 3)")
    n = position.shape[0]
    position = _as_vectors("position", position, n)
    radius = _per_item("radius", radius, n, np.float64, "one per particle")
    if not np.all(np.isfinite(radius)) or np.any(radius <= 0.0):
        bad = int(np.flatnonzero(~(radius > 0.0))[0])
        raise ValueError(f"radius: particle {bad} has radius {radius[bad]!r}; must be > 0")

    materials = list(material) if isinstance(material, (list, tuple)) else [material]
    if not materials or not all(isinstance(m, Material) for m in materials):
        raise ValueError("material: expected a Material or a non-empty list of Materials")
    if material_index is None:
        if len(materials) > 1:
            raise ValueError("material_index: required when several materials are given")
        material_index = 0
    material_index = _per_item("material_index", material_index, n, np.int32, "one per particle")
    if np.any((material_index < 0) | (material_index >= len(materials))):
        raise ValueError(f"material_index: values must lie in [0, {len(materials) - 1}]")

    density = np.array([m.density for m in materials])[material_index]
    mass = density * 4.0 / 3.0 * np.pi * radius ** 3
    inertia = 0.4 * mass * radius ** 2

    fixed = _per_item("fixed", False if fixed is None else fixed, n, np.bool_, "one per particle")
    gravity = np.asarray(gravity, dtype=np.float64)
    if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
        raise ValueError(f"gravity: expected 3 finite numbers, got {gravity!r}")
    if not (0.0 <= damping < 1.0):
        raise ValueError(f"damping = {damping!r}; allowed range [0, 1)")

    periodic = np.asarray(periodic, dtype=bool)
    if periodic.shape != (3,):
        raise ValueError("periodic: expected three booleans (x, y, z)")
    box_low = np.full(3, -np.inf) if box_low is None else np.asarray(box_low, dtype=np.float64)
    box_high = np.full(3, np.inf) if box_high is None else np.asarray(box_high, dtype=np.float64)
    if box_low.shape != (3,) or box_high.shape != (3,) or np.any(box_high <= box_low):
        raise ValueError("box_low/box_high: expected three numbers each with high > low")
    if np.any(periodic & ~(np.isfinite(box_low) & np.isfinite(box_high))):
        raise ValueError("periodic axes need finite box_low and box_high")

    if bonds is None:
        bonds = np.zeros((0, 2), dtype=INDEX)
    bonds = np.asarray(bonds)
    if bonds.size == 0:
        bonds = np.zeros((0, 2), dtype=INDEX)
    if bonds.ndim != 2 or bonds.shape[1] != 2:
        raise ValueError(f"bonds: shape {bonds.shape}, expected (B, 2)")
    if not np.issubdtype(bonds.dtype, np.integer):
        raise ValueError("bonds: particle indices must be integers")
    bonds = np.ascontiguousarray(bonds, dtype=INDEX)
    n_bonds = bonds.shape[0]
    if n_bonds:
        if bonds.min() < 0 or bonds.max() >= n:
            bad = int(np.flatnonzero((bonds < 0).any(1) | (bonds >= n).any(1))[0])
            raise ValueError(f"bonds: bond {bad} joins particles {bonds[bad].tolist()}; "
                             f"indices must lie in [0, {n - 1}]")
        if np.any(bonds[:, 0] == bonds[:, 1]):
            bad = int(np.flatnonzero(bonds[:, 0] == bonds[:, 1])[0])
            raise ValueError(f"bonds: bond {bad} joins particle {bonds[bad, 0]} to itself")
        key = np.sort(bonds, axis=1)
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        if np.any(counts > 1):
            dup = key[first[np.argmax(counts > 1)]]
            raise ValueError(f"bonds: particles {dup.tolist()} are bonded more than once")
        if bond_diameter is None:
            raise ValueError("bond_diameter: required when bonds are given")
        if bond_material is None:
            raise ValueError("bond_material: required when bonds are given")
    bond_diameter = _per_item("bond_diameter", 1.0 if bond_diameter is None else bond_diameter,
                              n_bonds, np.float64, "one per bond")
    if n_bonds and (not np.all(np.isfinite(bond_diameter)) or np.any(bond_diameter <= 0)):
        bad = int(np.flatnonzero(~(bond_diameter > 0))[0])
        raise ValueError(f"bond_diameter: bond {bad} has diameter {bond_diameter[bad]!r}; "
                         "must be > 0")
    bond_materials = (list(bond_material) if isinstance(bond_material, (list, tuple))
                      else [bond_material] if bond_material is not None else [])
    if n_bonds and not all(isinstance(m, BondMaterial) for m in bond_materials):
        raise ValueError("bond_material: expected a BondMaterial or a list of them")
    if bond_material_index is None:
        if len(bond_materials) > 1:
            raise ValueError("bond_material_index: required when several bond materials are given")
        bond_material_index = 0
    bond_material_index = _per_item("bond_material_index", bond_material_index, n_bonds,
                                    np.int32, "one per bond")
    if n_bonds and np.any((bond_material_index < 0)
                          | (bond_material_index >= len(bond_materials))):
        raise ValueError(f"bond_material_index: values must lie in "
                         f"[0, {len(bond_materials) - 1}]")

    box_length = np.where(periodic, box_high - box_low, 1.0)
    separation = bond_separation(position, bonds, box_length, periodic)
    initial_length = np.linalg.norm(separation, axis=1)
    if n_bonds and np.any(initial_length <= 0.0):
        bad = int(np.flatnonzero(initial_length <= 0.0)[0])
        raise ValueError(f"bonds: bond {bad} joins particles {bonds[bad].tolist()} at the same "
                         "position (initial length 0)")
    axis = separation / np.where(initial_length > 0, initial_length, 1.0)[:, None]

    model = Model(
        radius=radius, mass=mass, inertia=inertia, material=material_index, fixed=fixed,
        external_force=_as_vectors("external_force", external_force, n),
        external_moment=_as_vectors("external_moment", external_moment, n),
        materials=materials, bond_pairs=bonds, bond_diameter=bond_diameter,
        bond_initial_length=initial_length, bond_material=bond_material_index,
        bond_materials=bond_materials, gravity=gravity,
        fields=_field_arrays(fields),
        periodic=periodic,
        box_low=box_low, box_high=box_high, damping=float(damping))
    state = State(
        time=0.0, step=0, started=False, position=position,
        velocity=_as_vectors("velocity", velocity, n),
        angular_velocity=_as_vectors("angular_velocity", angular_velocity, n),
        bond_active=np.ones(n_bonds, dtype=np.bool_),
        bond_axis=np.ascontiguousarray(axis),
        bond_tangential_force=np.zeros((n_bonds, 3)),
        bond_normal_moment=np.zeros((n_bonds, 3)),
        bond_tangential_moment=np.zeros((n_bonds, 3)),
        bond_break_time=np.full(n_bonds, np.nan),
        bond_break_mode=np.zeros(n_bonds, dtype=np.int8),
        bond_break_energy=np.zeros(n_bonds),
        bond_previous_length=initial_length.copy())
    return model, state

"""Scene files (TOML, SPEC section 4) -> a validated Model, State and Simulation options.

Validation happens here, at the edge: every bad value raises ``InputError`` naming the
file, the key (dotted path, e.g. ``materials.glass.density``), the value and the allowed
range. Kernels downstream assume valid input. The keys are documented in docs/scene.md.
"""
from __future__ import annotations

import copy
import inspect
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .coupling import FlowField
from .errors import InputError, decode_text, unknown_key
from .expression import flow_function
from .generate import bonds_from_gap, particles_from_generator
from .io.csv_files import read_bonds, read_particles
from .io.grid_files import read_flow_grid
from .model import BondMaterial, Material, bond_material_schema, make_system, material_schema
from .physics import bond_models, contact_models, field_models
from .physics._registry import REQUIRED as _REQUIRED
from .physics.contact_hertz_musen import MUSEN_VERSION, MUSEN_VERSIONS
from .physics.field_fluid import DRAG_LAWS

BACKENDS = ("cpu", "gpu")
CONTACT_MODELS = (*contact_models.NAMES, "none")   # declared by physics/contact_*.py

# Each schema entry: key -> (kind, default, low, high, include_low, include_high).
# kind: "number", "int", "bool", "str", "vector3", "bool3", "time_step", "table", "any".
# default REQUIRED means the key must be present; None means optional without default.
REQUIRED = _REQUIRED   # the same sentinel as the bond models' PARAMETERS schemas
INF = math.inf

SIMULATION_KEYS = {
    "end_time": ("number", REQUIRED, 0.0, INF, False, False),
    "time_step": ("time_step", "auto", 0.0, INF, False, False),
    "save_every": ("number", None, 0.0, INF, False, False),
    "gravity": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "backend": ("str", "cpu", BACKENDS, None, None, None),
    "safety_factor": ("number", 0.2, 0.0, 1.0, False, True),
    "force_time_step": ("bool", False, None, None, None, None),
    "musen_compat": ("bool", False, None, None, None, None),
    "musen_version": ("str", MUSEN_VERSION, tuple(MUSEN_VERSIONS), None, None, None),
    "damping": ("number", 0.0, 0.0, 1.0, True, False),
    "periodic": ("bool3", [False, False, False], None, None, None, None),
    "box_low": ("vector3", None, -INF, INF, False, False),
    "box_high": ("vector3", None, -INF, INF, False, False),
    "contact_model": ("str", None, CONTACT_MODELS, None, None, None),
    "bonded_contacts": ("bool", False, None, None, None, None),
    "rolling_resistance": ("bool", True, None, None, None, None),
    "checkpoint_minutes": ("number", 10.0, 0.0, INF, True, False),
    "max_steps": ("number", 1e9, 0.0, INF, False, True),
    "stop_broken_bonds": ("int", None, 0, INF, True, False),
}
# declared by model.py and the contact models (physics/contact_models.py)
MATERIAL_KEYS = {key: ("number", REQUIRED if entry[1] is None else entry[1], *entry[2:])
                 for key, entry in material_schema().items()}
BOND_MATERIAL_KEYS = bond_material_schema()   # declared by the bond models (physics/)
PARTICLE_KEYS = {
    "file": ("str", None, None, None, None, None),
    "generator": ("table", None, None, None, None, None),
    "velocity": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "angular_velocity": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "offset": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
}
BOND_KEYS = {
    "file": ("str", None, None, None, None, None),
    "max_gap": ("number", None, 0.0, INF, True, False),
    "diameter": ("number", None, 0.0, INF, False, False),
    "diameter_ratio": ("number", None, 0.0, 1.0, False, True),
    "max_per_particle": ("int", None, 1, INF, True, False),
    "material": ("str", None, None, None, None, None),
}
PLANE_KEYS = {
    "type": ("str", REQUIRED, ("plane", "mesh"), None, None, None),
    "point": ("vector3", REQUIRED, -INF, INF, False, False),
    "normal": ("vector3", REQUIRED, -INF, INF, False, False),
    "material": ("str", REQUIRED, None, None, None, None),
    "velocity": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "velocity_profile": ("profile", None, None, None, None, None),
    "servo": ("table", None, None, None, None, None),
    "own_friction": ("bool", False, None, None, None, None),
}
SERVO_KEYS = {
    "target_force": ("number", None, 0.0, INF, True, False),
    "target_stress": ("number", None, 0.0, INF, True, False),
    "area": ("number", None, 0.0, INF, False, False),
    "gain": ("number", REQUIRED, 0.0, INF, False, False),
    "max_velocity": ("number", REQUIRED, 0.0, INF, False, False),
    "tolerance": ("number", 0.01, 0.0, 1.0, False, True),
    "integral_time": ("number", None, 0.0, INF, False, False),
}
MESH_KEYS = {
    "type": ("str", REQUIRED, ("plane", "mesh"), None, None, None),
    "file": ("str", REQUIRED, None, None, None, None),
    "material": ("str", REQUIRED, None, None, None, None),
    "scale": ("number", 1.0, 0.0, INF, False, False),
    "velocity": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "angular_velocity": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "rotation_center": ("vector3", [0.0, 0.0, 0.0], -INF, INF, False, False),
    "velocity_profile": ("profile", None, None, None, None, None),
    "own_friction": ("bool", False, None, None, None, None),
}
# and a table for each field model (physics/field_models.py: [fluid], [frame])
TOP_KEYS = ("simulation", "materials", "bond_materials", "particles", "bonds", "walls",
            *field_models.BY_NAME)
# fluid.voidage_grid (with voidage = "local"): the cells whose voidage the drag sees
VOIDAGE_GRID_KEYS = {
    "low": ("vector3", REQUIRED, -INF, INF, False, False),
    "high": ("vector3", REQUIRED, -INF, INF, False, False),
    "cells": ("cells", REQUIRED, None, None, None, None),
    "floor": ("number", 0.2, 0.0, 1.0, False, True),
}
# [fluid] beyond its field model's KEYS (physics/field_fluid.py): its velocity on a grid,
# read from a file (io/grid_files.py)
FLUID_FILE_KEYS = {"velocity_file": ("str", None, None, None, None, None)}


@dataclass
class Scene:
    """A loaded, validated scene.

    model, state: the system at t = 0; end_time, save_every: s; text: the scene TOML after
    overrides; path: the scene file; backend: "cpu" | "gpu"; simulation_options: keyword
    arguments of ``Simulation`` (time_step, safety_factor, contact, walls, ...);
    checkpoint_minutes: wall-clock minutes between checkpoints; stop_broken_bonds: the
    run ends at the first frame with more broken bonds than this (MUSEN's STOP_CRITERION
    BROKEN_BONDS), None: at end_time; data: the parsed table
    with defaults filled in; warnings: messages about input that is legal but likely
    wrong (the command line prints them).
    """
    model: object
    state: object
    end_time: float
    save_every: float
    text: str
    path: Path
    backend: str
    simulation_options: dict
    checkpoint_minutes: float = 10.0
    stop_broken_bonds: int | None = None
    data: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)   # str: legal but suspicious input

    def make_simulation(self, state=None):
        """A Simulation of this scene, from ``state`` (a checkpoint's) or a copy of the
        scene's initial state."""
        from .simulation import Simulation
        options = dict(self.simulation_options)
        # A servo's travel, speed and integral live in its wall object: each simulation
        # gets walls of its own, so a second one starts where the scene says, not where
        # the first one left its walls.
        options["walls"] = copy.deepcopy(options.get("walls", []))
        return Simulation(self.model, (state if state is not None else self.state.copy()),
                          **options)


def load_scene(path, overrides: dict | None = None) -> Scene:
    """Read and validate a scene file (TOML, SPEC 4).

    path: the scene file; overrides: {"simulation.end_time": 1e-3,
    "materials.glass.density": 2000.0, "walls.0.velocity": [0, 0, 1], ...} applied to the
    parsed table before validation (parameter studies). Raises InputError on bad input.
    """
    path = Path(path)
    data, text = read_toml(path, overrides, "scene file")
    return _build(data, text, path)


def read_toml(path, overrides=None, what="file"):
    """(table, text) of a TOML input file with ``overrides`` {dotted key: value} applied
    (text then re-written from the table); InputError naming the file when it cannot be
    read or parsed."""
    try:
        raw = Path(path).read_bytes()
    except OSError as error:
        raise InputError(f"cannot read the {what} ({error.strerror})", file=path)
    text = decode_text(raw, path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"not valid TOML: {error}", file=path)
    if overrides:
        data = copy.deepcopy(data)
        for key, value in overrides.items():
            _apply_override(data, key, value, path)
        import tomli_w
        text = tomli_w.dumps(data)
    return data, text


def parse_override(text, file="--set"):
    """``"simulation.end_time=1e-3"`` -> ("simulation.end_time", 0.001); the value is
    read as a TOML value (a bare word is taken as a string)."""
    if "=" not in text:
        raise InputError(f"{text!r} is not KEY=VALUE", file=file)
    key, raw = (part.strip() for part in text.split("=", 1))
    if not key:
        raise InputError(f"{text!r}: empty key before '='; give KEY=VALUE, e.g. "
                         "simulation.end_time=1e-3", file=file)
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value


def _apply_override(data, key, value, path):
    parts = key.split(".")
    node = data
    for depth, part in enumerate(parts[:-1]):
        where = ".".join(parts[:depth + 1])
        if isinstance(node, list):
            node = node[_list_index(node, part, where, path)]
        elif isinstance(node, dict):
            node = node.setdefault(part, {})
        else:
            raise InputError(f"override {key!r}: {where} is not a table", file=path, key=key)
    last = parts[-1]
    if isinstance(node, list):
        node[_list_index(node, last, key, path)] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise InputError(f"override {key!r}: parent is not a table", file=path, key=key)


def _list_index(node, part, where, path):
    if not part.isdigit() or int(part) >= len(node):
        raise InputError(f"index {part!r} must be in [0, {len(node) - 1}]", file=path, key=where)
    return int(part)


# ---------------------------------------------------------------------------- validation

def _check_table(table, schema, where, path):
    """Validate one table against its schema; return a dict with defaults filled in."""
    if not isinstance(table, dict):
        raise InputError(f"expected a table, got {table!r}", file=path, key=where)
    for key in table:
        if key not in schema:
            raise InputError(unknown_key(key, schema), file=path, key=f"{where}.{key}")
    out = {}
    for key, (kind, default, low, high, inc_low, inc_high) in schema.items():
        full = f"{where}.{key}"
        if key not in table:
            if default is REQUIRED:
                raise InputError("missing required key", file=path, key=full)
            out[key] = copy.deepcopy(default)
            continue
        out[key] = _check_value(table[key], kind, low, high, inc_low, inc_high, full, path)
    return out


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _range_text(low, high, inc_low, inc_high):
    return f"{'[' if inc_low else '('}{low}, {high}{']' if inc_high else ')'}"


def _check_number(value, low, high, inc_low, inc_high, key, path):
    if not _is_number(value):
        allowed = _range_text(low, high, inc_low, inc_high)
        raise InputError(f"value {value!r}: expected a number in {allowed}",
                         file=path, key=key)
    try:
        value = float(value)
    except OverflowError:
        raise InputError(f"value of {len(str(value))} digits is outside the allowed range "
                         f"{_range_text(low, high, inc_low, inc_high)}", file=path,
                         key=key) from None
    ok = ((value >= low if inc_low else value > low)
          and (value <= high if inc_high else value < high))
    if math.isnan(value) or not ok:
        raise InputError(f"value {value!r} is outside the allowed range "
                         f"{_range_text(low, high, inc_low, inc_high)}", file=path, key=key)
    return value


def _check_value(value, kind, low, high, inc_low, inc_high, key, path):
    if kind == "number":
        return _check_number(value, low, high, inc_low, inc_high, key, path)
    if kind == "int":
        if not isinstance(value, int) or isinstance(value, bool) or value < low:
            raise InputError(f"value {value!r}: expected an integer >= {low}", file=path, key=key)
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            raise InputError(f"value {value!r}: expected true or false", file=path, key=key)
        return value
    if kind == "str":
        if not isinstance(value, str):
            raise InputError(f"value {value!r}: expected a string", file=path, key=key)
        if low is not None and value not in low:
            raise InputError(f"value {value!r}; allowed: {', '.join(repr(v) for v in low)}",
                             file=path, key=key)
        return value
    if kind == "time_step":
        if value == "auto":
            return value
        if isinstance(value, str) or not _is_number(value):
            raise InputError(f"value {value!r}: expected \"auto\" or a number of seconds > 0",
                             file=path, key=key)
        return _check_number(value, 0.0, INF, False, False, key, path)
    if kind == "vector3":
        if not (isinstance(value, list) and len(value) == 3 and all(_is_number(v) for v in value)
                and all(math.isfinite(v) for v in value)):
            raise InputError(f"value {value!r}: expected three finite numbers [x, y, z]",
                             file=path, key=key)
        return [float(v) for v in value]
    if kind == "bool3":
        if isinstance(value, bool):
            return [value] * 3
        if not (isinstance(value, list) and len(value) == 3
                and all(isinstance(v, bool) for v in value)):
            raise InputError(f"value {value!r}: expected true/false or three of them [x, y, z]",
                             file=path, key=key)
        return list(value)
    if kind == "cells":
        if (not isinstance(value, list) or len(value) != 3
                or not all(isinstance(c, int) and not isinstance(c, bool) and c >= 1
                           for c in value)):
            raise InputError(f"value {value!r}: expected 3 integers >= 1 [nx, ny, nz]",
                             file=path, key=key)
        return list(value)
    if kind == "table":
        if not isinstance(value, dict):
            raise InputError(f"value {value!r}: expected a table", file=path, key=key)
        return value
    if kind == "profile":
        rows = value if isinstance(value, list) and value else None
        if rows is None or not all(isinstance(r, list) and len(r) == 4
                                   and all(_is_number(v) and math.isfinite(v) for v in r)
                                   for r in rows):
            raise InputError(f"value {value!r}: expected rows [time (s), vx, vy, vz (m/s)]",
                             file=path, key=key)
        times = [float(r[0]) for r in rows]
        if times[0] != 0.0 or any(b < a for a, b in zip(times, times[1:])):
            raise InputError(f"times {times}: the first must be 0 s and none may decrease",
                             file=path, key=key)
        return [[float(v) for v in r] for r in rows]
    raise AssertionError(kind)


def _build(data, text, path):
    for key in data:
        if key not in TOP_KEYS:
            raise InputError(unknown_key(key, TOP_KEYS), file=path, key=key)
    for key in ("simulation", "materials", "particles"):
        if key not in data:
            raise InputError("missing required table", file=path, key=key)
    sim = _check_table(data["simulation"], SIMULATION_KEYS, "simulation", path)
    tables = {name: data.get(name, {}) for name in field_models.BY_NAME}
    tables["fluid"], flow_field = _flow_field(tables["fluid"], path)
    fluid = _check_table(tables["fluid"], {**field_models.BY_NAME["fluid"].KEYS,
                                           **FLUID_FILE_KEYS}, "fluid", path)
    if flow_field is not None and fluid["drag"] == "none":
        raise InputError(f"a velocity formula or a local voidage acts through the drag; "
                         f"allowed: one of {', '.join(d for d in DRAG_LAWS if d != 'none')}",
                         file=path, key="fluid.drag")
    flow_file = fluid.pop("velocity_file")
    field_arrays = {name: _field_array(name, fluid if name == "fluid" else _check_table(
                        tables[name], module.KEYS, name, path), path)
                    for name, module in field_models.BY_NAME.items()}
    save_every_given = sim["save_every"] is not None
    if not save_every_given:
        sim["save_every"] = sim["end_time"] / 100.0   # rounded up to a step below

    materials = _named_tables(data["materials"], "materials", MATERIAL_KEYS, path)
    if not materials:
        raise InputError("at least one particle material is needed", file=path, key="materials")
    bond_materials = _named_tables(data.get("bond_materials", {}), "bond_materials",
                                   BOND_MATERIAL_KEYS, path)
    material_objects = [Material(name=name, **values) for name, values in materials.items()]
    bond_material_objects = []
    for name, values in bond_materials.items():
        for key, message in bond_models.check(values, sim["musen_compat"]):
            raise InputError(message, file=path, key=f"bond_materials.{name}.{key}")
        bond_material_objects.append(BondMaterial(name=name, **values))
    material_names = list(materials)
    bond_material_names = list(bond_materials)

    position, radius, material_index, velocity, angular_velocity, fixed, particles, where, \
        clumps = _particles(data["particles"], material_names, path)
    bonds, bond_diameter, bond_material_index = _bonds(
        data.get("bonds"), position, radius, bond_material_names, path,
        None if clumps is None else clumps["clump_of"])
    particle_key = "particles.file" if particles["file"] is not None else "particles.generator"
    if bonds.shape[0] and not bond_material_objects:
        raise InputError("bonds are given but no [bond_materials] table", file=path,
                         key="bond_materials")

    periodic = sim["periodic"]
    if any(periodic) and (sim["box_low"] is None or sim["box_high"] is None):
        raise InputError("periodic axes need simulation.box_low and simulation.box_high",
                         file=path, key="simulation.periodic")
    try:
        model, state = make_system(
            position, radius, material_objects, material_index=material_index,
            velocity=velocity, angular_velocity=angular_velocity, fixed=fixed, bonds=bonds,
            bond_diameter=bond_diameter if bonds.shape[0] else None,
            bond_material=bond_material_objects or None,
            bond_material_index=bond_material_index if bonds.shape[0] else None,
            gravity=sim["gravity"], periodic=periodic, box_low=sim["box_low"],
            box_high=sim["box_high"], damping=sim["damping"], **field_arrays)
    except ValueError as error:
        raise InputError(str(error), file=path, key=_guess_key(str(error)))
    if clumps is not None and np.any(clumps["clump_of"] >= 0):
        model, state = _make_clumps(model, state, clumps, particles, where, path)
    if flow_file is not None:
        _read_flow(model, path.parent / flow_file, path)
    for name, outside in (("box_low", position < model.box_low),
                          ("box_high", position > model.box_high)):
        rows = np.flatnonzero(outside.any(axis=1))
        if rows.size:   # both bounds are infinite unless given
            raise InputError(f"{rows.size} of {position.shape[0]} particles lie outside the "
                             f"domain at t = 0 (particle {int(rows[0])} at "
                             f"{position[rows[0]].tolist()} m); allowed: box_low <= x <= "
                             "box_high", file=path, key=f"simulation.{name}")
    with np.errstate(all="ignore"):   # an overflow here is the error reported below
        kinetic = 0.5 * float(np.sum(model.mass[:, None] * state.velocity ** 2))
    if not math.isfinite(kinetic):
        raise InputError("the initial kinetic energy is not finite: velocities out of any "
                         "physical range", file=path, key="particles.velocity")

    walls_data = data.get("walls", [])
    if not isinstance(walls_data, list):
        raise InputError("expected an array of tables [[walls]]", file=path, key="walls")
    walls = [_wall(w, k, material_names, path) for k, w in enumerate(walls_data)]

    options = {"time_step": sim["time_step"], "safety_factor": sim["safety_factor"],
               "force_time_step": sim["force_time_step"], "musen_compat": sim["musen_compat"],
               "musen_version": sim["musen_version"]}
    _contact_and_walls(options, sim, walls, material_objects, material_names, path)
    if flow_field is not None:
        options["flow"] = flow_field
    if "contact" in options and any(model.periodic):
        from .contacts import contact_cutoff
        cutoff = contact_cutoff(model.radius, options["contact"].skin)[0]
        short = np.flatnonzero(np.asarray(model.periodic) & (model.box_length < 2.0 * cutoff))
        if short.size:
            axis = "xyz"[int(short[0])]
            raise InputError(f"the periodic box is {model.box_length[short[0]]:.4g} m long in "
                             f"{axis}, less than twice the contact cut-off 2 r_max + skin = "
                             f"{cutoff:.4g} m; allowed box_high - box_low >= "
                             f"{2.0 * cutoff:.4g} m", file=path, key="simulation.box_high")
    warnings = _check_overlaps(position, radius, bonds, where, "contact" in options,
                               sim["bonded_contacts"], path, particle_key,
                               None if clumps is None else clumps["clump_of"])
    warnings += _check_plausible(position, radius, bonds, options.get("walls", []), where,
                                 path, particle_key)
    for name, values in materials.items():
        density = values["density"]
        if not DENSITY_RANGE[0] <= density <= DENSITY_RANGE[1]:
            warnings.append(f"{path}: materials.{name}.density: {density:.4g} kg/m^3 is "
                            f"outside the densities of solids ({DENSITY_RANGE[0]:g} to "
                            f"{DENSITY_RANGE[1]:g} kg/m^3): g/cm^3 (x 1000) or another unit "
                            "instead of kg/m^3?")
    if sim["backend"] != "cpu":
        _require_parameter("backend", path, "simulation.backend", sim["backend"])
        options["backend"] = sim["backend"]
    scene = Scene(model=model, state=state, end_time=sim["end_time"],
                  save_every=sim["save_every"], text=text, path=path, backend=sim["backend"],
                  simulation_options=options, checkpoint_minutes=sim["checkpoint_minutes"],
                  stop_broken_bonds=sim["stop_broken_bonds"],
                  data={"simulation": sim, "materials": materials,
                        "bond_materials": bond_materials, "particles": particles,
                        "walls": walls}, warnings=warnings)
    _check_time_step(scene, path, save_every_given)
    return scene


def _flow_field(table, path):
    """The [fluid] table without its formulas and local voidage, and the FlowField they
    make (None without): ``velocity`` with a formula of x, y, z, t among its three
    components (expression.py), ``voidage = "local"`` with ``voidage_grid = {low, high,
    cells, floor}``."""
    if not isinstance(table, dict):
        return table, None
    table = dict(table)
    velocity = table.get("velocity")
    function = None
    if isinstance(velocity, list) and any(isinstance(v, str) for v in velocity):
        if len(velocity) != 3:
            raise InputError(f"expected 3 components (numbers or formulas of x, y, z, t), "
                             f"got {len(velocity)}", file=path, key="fluid.velocity")
        try:
            function = flow_function(velocity)
        except ValueError as error:
            raise InputError(str(error), file=path, key="fluid.velocity") from None
        table["velocity"] = [0.0, 0.0, 0.0]
    grid = table.pop("voidage_grid", None)
    local = table.get("voidage") == "local"
    if local:
        table["voidage"] = 1.0
        if not isinstance(grid, dict):
            raise InputError('voidage = "local" needs fluid.voidage_grid = {low = [x, y, z], '
                             'high = [x, y, z], cells = [nx, ny, nz]} (m, m, integers >= 1)',
                             file=path, key="fluid.voidage_grid")
        grid = _check_table(grid, VOIDAGE_GRID_KEYS, "fluid.voidage_grid", path)
        if any(h <= low for low, h in zip(grid["low"], grid["high"])):
            raise InputError(f"high {grid['high']} must exceed low {grid['low']} on every "
                             "axis", file=path, key="fluid.voidage_grid.high")
    elif grid is not None:
        raise InputError('a voidage grid needs voidage = "local"', file=path,
                         key="fluid.voidage_grid")
    if function is None and not local:
        return table, None
    return table, FlowField(velocity=function,
                            voidage_grid=((grid["low"], grid["high"], grid["cells"])
                                          if local else None),
                            voidage_floor=grid["floor"] if local else 0.2)


def _field_array(name, values, path):
    """Field model ``name``'s parameter array from its checked table ``values``;
    InputError naming the key its ARRAY objects to (the key a message names first, or
    one it says is needed)."""
    module = field_models.BY_NAME[name]
    try:
        return field_models.array(module, **values)
    except ValueError as error:
        reason = str(error)
        needed = [k for k in module.KEYS if f"needs {k}" in reason]
        key = needed[0] if needed else reason.split()[0].rstrip(":")
        raise InputError(reason, file=path, key=f"{name}.{key}") from None


def _read_flow(model, file, scene_path):
    """The fluid's velocity grid from ``file`` (HDF5, VTK image data or legacy VTK
    structured points: io/grid_files.py) into ``model``; InputError naming the file and
    what is wrong."""
    key = "fluid.velocity_file"
    if not file.is_file():
        raise InputError(f"no such file {str(file)!r}", file=scene_path, key=key)
    velocity, origin, spacing = read_flow_grid(file, key)
    try:
        model.set_flow(velocity, origin, spacing)
    except ValueError as error:
        raise InputError(str(error), file=file, key=key) from None


def _guess_key(message):
    head = message.split(":")[0].split(" ")[0]
    return {"bonds": "bonds", "bond_diameter": "bonds.diameter", "radius": "particles.radius",
            "damping": "simulation.damping", "box_low/box_high": "simulation.box_high",
            "periodic": "simulation.periodic"}.get(head, head)


def _named_tables(tables, where, schema, path):
    if not isinstance(tables, dict):
        raise InputError(f"expected tables [{where}.NAME]", file=path, key=where)
    out = {}
    for name, table in tables.items():
        out[name] = _check_table(table, schema, f"{where}.{name}", path)
    return out


def _check_time_step(scene, path, save_every_given=True):
    from .timestep import stable_time_step, time_scales
    step = scene.simulation_options["time_step"]
    options_auto = step == "auto"
    if step == "auto":
        with np.errstate(all="ignore"):   # absurd sizes overflow: reported just below
            step, cause = stable_time_step(scene.model,
                                           scene.simulation_options["safety_factor"],
                                           scene.simulation_options["musen_compat"])
        if not (step > 0.0 and math.isfinite(step)):
            key = "bonds" if cause.startswith("bond") else "materials"
            raise InputError(f"the stable time step is {step!r} s (limited by {cause}): a bond "
                             "diameter, modulus or particle size is out of any physical "
                             "range", file=path, key=key)
        if step > scene.end_time:
            key = "bonds" if cause.startswith("bond") else "materials"
            raise InputError(f"the stable time step {step:.4g} s (limited by {cause}) is "
                             f"longer than the whole run (simulation.end_time = "
                             f"{scene.end_time:.4g} s): a density, modulus or particle size "
                             "is out of range, or end_time too short", file=path, key=key)
    else:
        critical = min(time_scales(scene.model,
                                   scene.simulation_options["musen_compat"]).values())
        if step > critical and not scene.simulation_options["force_time_step"]:
            raise InputError(f"value {step!r} s exceeds the stable limit {critical:.4g} s; allowed "
                             f"(0, {critical:.4g}] or set force_time_step = true", file=path,
                             key="simulation.time_step")
    _check_step_displacement(scene, step, path)
    steps = scene.end_time / step
    limit = scene.data["simulation"]["max_steps"]
    if steps > limit:
        limited = f" (the stable step, limited by {cause})" if options_auto else ""
        raise InputError(f"value {scene.end_time!r} s is {steps:.3g} steps of {step:.4g} s"
                         f"{limited}, "
                         f"more than simulation.max_steps = {limit:.3g}; shorten the run or "
                         "raise max_steps", file=path, key="simulation.end_time")
    if scene.save_every < step and not save_every_given:
        # the default end_time / 100 of a run shorter than 100 steps: a frame every step
        scene.save_every = step
        scene.data["simulation"]["save_every"] = step
    if scene.save_every < step:
        raise InputError(f"value {scene.save_every!r} s is shorter than the time step "
                         f"{step:.4g} s; allowed [{step:.4g}, end_time]", file=path,
                         key="simulation.save_every")


def _check_step_displacement(scene, step, path):
    """InputError if a particle would move more than its smallest radius in one step from
    its initial velocity, or from gravity within the first step: explicit contacts and
    bonds cannot follow that (and doubles lose the particles soon after)."""
    r_min = float(np.min(scene.model.radius))
    speed = float(np.max(np.abs(scene.state.velocity)))       # the largest component
    gravity = float(np.max(np.abs(scene.model.gravity)))
    if speed * step > r_min:
        raise InputError(f"a particle at {speed:.3g} m/s moves {speed * step / r_min:.3g} "
                         f"radii per time step ({step:.4g} s); allowed up to "
                         f"{r_min / step:.4g} m/s", file=path, key="particles.velocity")
    if gravity * step * step > r_min:
        raise InputError(f"value {gravity:.3g} m/s^2 moves a particle "
                         f"{gravity * step * step / r_min:.3g} radii in one time step "
                         f"({step:.4g} s); allowed up to {r_min / step ** 2:.4g} m/s^2",
                         file=path, key="simulation.gravity")
    for k, wall in enumerate(scene.simulation_options.get("walls", ())):
        reach = 0.0     # the farthest vertex from the rotation centre (m)
        if getattr(wall, "vertices", None) is not None and len(wall.vertices):
            with np.errstate(all="ignore"):
                reach = float(np.max(np.abs(wall.vertices - wall.rotation_center)))
        with np.errstate(all="ignore"):
            slide = wall.motion.max_speed() * step
            moved = slide + float(np.max(np.abs(wall.angular_velocity))) * reach * step
        if not moved <= r_min:
            key = "velocity" if slide > r_min else "angular_velocity"
            raise InputError(f"the wall moves {moved / r_min:.3g} particle radii per time "
                             f"step ({step:.4g} s); allowed up to one", file=path,
                             key=f"walls.{k}.{key}")


def _require_parameter(name, path, key, value):
    from .simulation import Simulation
    if name not in inspect.signature(Simulation).parameters:
        raise InputError(f"value {value!r} is not available in this build of bondem", file=path,
                         key=key)


def _contact_and_walls(options, sim, walls, material_objects, material_names, path):
    """Contacts and walls come from bondem.contacts / bondem.walls (imported lazily)."""
    model = sim["contact_model"]
    try:
        from .contacts import ContactSettings
    except ImportError:
        ContactSettings = None
    if model is None:
        # Default: Hertz-Mindlin where the contact module is present; otherwise none.
        model = "hertz_mindlin" if ContactSettings is not None else "none"
        sim["contact_model"] = model
    if model != "none":
        if ContactSettings is None:
            raise InputError(f"value {model!r} needs bondem.contacts, not in this build; "
                             "allowed here: 'none'", file=path, key="simulation.contact_model")
        _require_parameter("contact", path, "simulation.contact_model", model)
        options["contact"] = ContactSettings(model=model, bonded_pairs=sim["bonded_contacts"],
                                             rolling_resistance=sim["rolling_resistance"])
    if walls:
        try:
            from . import walls as wall_module
        except ImportError:
            raise InputError("walls need bondem.walls, not in this build", file=path,
                             key="walls")
        _require_parameter("walls", path, "walls", "[[walls]]")
        objects = []
        for w in walls:
            material = material_objects[material_names.index(w["material"])]
            motion = None
            if w["velocity_profile"] is not None:
                rows = np.array(w["velocity_profile"])
                motion = wall_module.VelocityProfile(rows[:, 0], rows[:, 1:])
            elif w.get("servo") is not None:
                motion = wall_module.Servo(**w["servo"])
            if w["type"] == "plane":
                objects.append(wall_module.PlaneWall(w["point"], w["normal"], material,
                                                     velocity=w["velocity"], motion=motion,
                                                     own_friction=w["own_friction"]))
            else:
                try:
                    objects.append(wall_module.MeshWall.from_stl(
                        w["file"], material, scale=w["scale"], velocity=w["velocity"],
                        angular_velocity=w["angular_velocity"],
                        rotation_center=w["rotation_center"], motion=motion,
                        own_friction=w["own_friction"]))
                except (OSError, ValueError) as error:
                    raise InputError(f"cannot read the mesh {w['file']!r}: {error}",
                                     file=path, key=f"walls.{w['index']}.file")
        options["walls"] = objects


def _wall(table, index, material_names, path):
    where = f"walls.{index}"
    if not isinstance(table, dict):
        raise InputError("expected a table", file=path, key=where)
    kind = table.get("type")
    if kind not in ("plane", "mesh"):
        raise InputError(f"value {kind!r}; allowed: 'plane', 'mesh'", file=path,
                         key=f"{where}.type")
    wall = _check_table(table, PLANE_KEYS if kind == "plane" else MESH_KEYS, where, path)
    if wall["material"] not in material_names:
        raise InputError(f"value {wall['material']!r} is not defined; defined materials: "
                         f"{', '.join(material_names)}", file=path, key=f"{where}.material")
    motions = [k for k in ("velocity_profile", "servo") if wall.get(k) is not None]
    if any(wall["velocity"]) and motions:
        motions.insert(0, "velocity")
    if len(motions) > 1:
        raise InputError(f"give one of velocity, velocity_profile, servo; got "
                         f"{', '.join(motions)}", file=path, key=f"{where}.{motions[1]}")
    if wall.get("servo") is not None:
        servo = _check_table(wall["servo"], SERVO_KEYS, f"{where}.servo", path)
        given = [k for k in ("target_force", "target_stress") if servo[k] is not None]
        if len(given) != 1:
            raise InputError("give exactly one of target_force (N) or target_stress (Pa)",
                             file=path, key=f"{where}.servo.target_force")
        if servo["target_stress"] is not None and servo["area"] is None:
            raise InputError("target_stress needs the area (m^2) it acts on",
                             file=path, key=f"{where}.servo.area")
        wall["servo"] = {k: v for k, v in servo.items() if v is not None}
    if kind == "plane" and np.linalg.norm(wall["normal"]) == 0.0:
        raise InputError("value [0, 0, 0]: the normal must be a non-zero vector", file=path,
                         key=f"{where}.normal")
    if kind == "mesh":
        wall["file"] = str((path.parent / wall["file"]).resolve())
        if not Path(wall["file"]).is_file():
            raise InputError(f"value {table['file']!r}: no such file", file=path,
                             key=f"{where}.file")
    wall["index"] = index
    return wall


# ---------------------------------------------------------------------------- CSV input

def _read_csv(reader, file, key, path, **kwargs):
    """Read a particle or bond CSV with bondem.io.csv_files; its errors (which name the
    CSV file, line and column) are reported against the scene key that named the file."""
    try:
        return reader(file, **kwargs)
    except InputError as error:
        raise InputError(str(error), file=path, key=key) from None


def _particles(table, material_names, path):
    p = _check_table(table, PARTICLE_KEYS, "particles", path)
    if (p["file"] is None) == (p["generator"] is None):
        raise InputError("give exactly one of particles.file or particles.generator",
                         file=path, key="particles")
    if p["file"] is not None:
        file = path.parent / p["file"]
        columns = _read_csv(read_particles, file, "particles.file", path)
        position = np.column_stack([columns["x"], columns["y"], columns["z"]])
        radius = columns["radius"]
        names = np.asarray(columns["material"])
        velocity = (np.column_stack([columns["vx"], columns["vy"], columns["vz"]])
                    if "vx" in columns else np.zeros_like(position))
        angular_velocity = (np.column_stack([columns["wx"], columns["wy"], columns["wz"]])
                            if "wx" in columns else np.zeros_like(position))
        fixed = columns.get("fixed")
        where = [f"{file.name} line {line}" for line in columns["line"].tolist()]
        clumps = {"clump_of": columns["clump"]} if "clump" in columns else None
    elif isinstance(p["generator"], dict) and "clump" in p["generator"]:
        position, radius, names, clumps = _clump_generator(p["generator"], path)
        velocity = np.zeros_like(position)
        angular_velocity = np.zeros_like(position)
        fixed = None
        where = None
    else:
        clumps = None
        position, radius, names = particles_from_generator(p["generator"], str(path))
        position = np.asarray(position, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), position.shape[:1]).copy()
        names = np.broadcast_to(np.asarray(names), position.shape[:1])
        velocity = np.zeros_like(position)
        angular_velocity = np.zeros_like(position)
        fixed = None
        where = None
    unknown = sorted(set(names.tolist()) - set(material_names))
    if unknown:
        at = f"{where[names.tolist().index(unknown[0])]}: " if where else ""
        raise InputError(f"{at}material {unknown[0]!r} is not defined; defined materials: "
                         f"{', '.join(material_names)}", file=path,
                         key="particles.material" if p["file"] is not None
                         else "particles.generator.material")
    index = np.array([material_names.index(m) for m in names.tolist()], dtype=np.int32)
    source = "particles.file" if p["file"] is not None else "particles.generator"
    _check_radius_spread(radius, where, path, source)
    with np.errstate(all="ignore"):
        position = position + np.array(p["offset"])
    _check_precision(position, radius, path,
                     "particles.offset" if any(p["offset"]) else source)
    velocity = velocity + np.array(p["velocity"])
    angular_velocity = angular_velocity + np.array(p["angular_velocity"])
    if clumps is not None and "centre" in clumps:
        clumps["centre"] = clumps["centre"] + np.array(p["offset"])
    return position, radius, index, velocity, angular_velocity, fixed, p, where, clumps


CLUMP_GENERATOR_KEYS = {"clump", "compact"}


def _clump_generator(table, path):
    """``[particles.generator]`` with ``clump = {centres = [[x, y, z], ...], radii =
    [...]}`` (m) and ``compact`` in [0.5, 1] (default 1): copies of that clump packed in
    the generator's volume (``clumps.pack_clumps``). Returns (position, radius, material
    names, clumps: clump_of and the per-clump mass, centre and inertia at density 1)."""
    from .clumps import ClumpTemplate, pack_clumps
    from .generate import _GENERATOR_KEYS, volume_from_table
    prefix = "particles.generator"
    allowed = (_GENERATOR_KEYS - {"particle_radius", "size_distribution"}) | \
        CLUMP_GENERATOR_KEYS
    for key in table:
        if key not in allowed:
            why = (" (a clump generator packs the clump given; its radii are the "
                   "clump's)" if key in ("particle_radius", "size_distribution") else "")
            raise InputError(unknown_key(key, sorted(allowed)) + why, file=path,
                             key=f"{prefix}.{key}")
    shape = table["clump"]
    given = set(shape) if isinstance(shape, dict) else set()
    if given == {"centres", "radii"}:
        try:
            template = ClumpTemplate(shape["centres"], shape["radii"])
        except (ValueError, TypeError) as error:
            raise InputError(str(error).replace("clump template 'clump': ", ""), file=path,
                             key=f"{prefix}.clump") from None
    elif "file" in given and given <= {"file", "spheres", "scale", "resolution"}:
        template = _mesh_clump(shape, path, f"{prefix}.clump")
    else:
        raise InputError("expected a table {centres = [[x, y, z], ...], radii = [...]} (m) "
                         "or {file = \"grain.stl\", spheres = n, scale = s, resolution = "
                         "r} (an STL filled with spheres)", file=path, key=f"{prefix}.clump")
    compact = table.get("compact", 1.0)
    if not _is_number(compact) or not 0.5 <= compact <= 1.0:
        raise InputError(f"{compact!r}; allowed range [0.5, 1]", file=path,
                         key=f"{prefix}.compact")
    volume = volume_from_table(table, str(path), prefix)
    fraction = table.get("solids_fraction", 0.5)
    seed = table.get("seed", 0)
    overlap = table.get("max_overlap", 1e-3)
    # the packer's own ranges (generate.pack_spheres): solids_fraction below 0.66
    for key, value, low, high, closed in (("solids_fraction", fraction, 0.0, 0.66, False),
                                          ("max_overlap", overlap, 0.0, 0.05, True)):
        if not _is_number(value) or not (low < value <= high if closed else
                                         low < value < high):
            raise InputError(f"{value!r}; allowed range ({low:g}, {high:g}"
                             f"{']' if closed else ')'}", file=path, key=f"{prefix}.{key}")
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise InputError(f"{seed!r}; allowed: an integer >= 0", file=path,
                         key=f"{prefix}.seed")
    material = table.get("material")
    if not isinstance(material, str) or not material:
        raise InputError(f"{material!r}; give the name of a particle material", file=path,
                         key=f"{prefix}.material")
    try:
        packed = pack_clumps(volume, template, 1.0, solids_fraction=fraction, seed=seed,
                             compact=float(compact), max_overlap=overlap)
    except (ValueError, RuntimeError) as error:
        raise InputError(str(error), file=path, key=prefix) from None
    n = packed["radius"].size
    clumps = {k: packed[k] for k in ("clump_of", "mass", "centre", "inertia")}
    return packed["position"], packed["radius"], np.full(n, material, dtype=object), clumps


FAR_IN_RADII = 1e7   # |x| / r_min beyond which float64 keeps < 2e-9 of a radius


def _check_precision(position, radius, path, key):
    """InputError if particles lie so far from the origin that double precision cannot
    resolve a small fraction of a radius there (a 1e300 offset makes every bond length 0)."""
    far = float(np.max(np.abs(position))) if position.size else 0.0
    r_min = float(np.min(radius)) if radius.size else 0.0
    if not math.isfinite(far) or (r_min > 0 and far > FAR_IN_RADII * r_min):
        raise InputError(f"particles lie {far:.3g} m from the origin, more than "
                         f"{FAR_IN_RADII:.0e} times the smallest radius ({r_min:.3g} m): "
                         "double precision cannot resolve their contacts and bonds there; "
                         "move the scene near the origin", file=path, key=key)


RADIUS_SPREAD = 1e6   # largest / smallest radius beyond which time steps make no sense


def _check_radius_spread(radius, where, path, key):
    """InputError naming the particle (CSV line) whose radius is less than 1/RADIUS_SPREAD
    of the median: one such particle would set a time step a million times too small."""
    if not radius.size:
        return
    small = np.flatnonzero(radius < np.median(radius) / RADIUS_SPREAD)
    if small.size:
        k = int(small[np.argmin(radius[small])])
        at = f"{where[k]}: " if where else f"particle {k}: "
        raise InputError(f"{at}radius {float(radius[k])!r} m is less than "
                         f"1/{RADIUS_SPREAD:.0e} of "
                         f"the median radius {np.median(radius):.4g} m; allowed "
                         f"[{np.median(radius) / RADIUS_SPREAD:.3g}, ...] m", file=path,
                         key=key)


DENSITY_RANGE = (10.0, 25000.0)   # kg/m^3: aerogels to osmium; beyond, a unit slip
COINCIDENT = 1e-6      # centres closer than this times the smallest radius: the same place
DEEP_OVERLAP = 0.25    # overlap / smaller radius above which a contact starts violently


def _check_overlaps(position, radius, bonds, where, contacts, bonded_contacts, path, key,
                    clump_of=None):
    """InputError for two particles at the same place (a repeated row); with contacts, the
    warnings (list of str) for unbonded pairs overlapping by more than DEEP_OVERLAP of the
    smaller radius, which Hertz contacts push apart at high speed. ``where``: the CSV
    file and line of each particle, or None (generated)."""
    from scipy.spatial import cKDTree
    n = position.shape[0]
    if n < 2:
        return []
    name = (lambda k: where[k]) if where else (lambda k: f"particle {k}")  # noqa: E731
    tree = cKDTree(position)
    same = tree.query_pairs(COINCIDENT * float(radius.min()), output_type="ndarray")
    if same.size:
        i, j = sorted(int(v) for v in same[0])
        raise InputError(f"{name(i)} and {name(j)}: particles {i} and {j} are at the same "
                         f"place {position[i].tolist()} m (a repeated row?); "
                         f"{same.shape[0]} such pair(s)", file=path, key=key)
    if not contacts:
        return []
    pairs = tree.query_pairs(2.0 * float(radius.max()), output_type="ndarray")
    if not pairs.size:
        return []
    if bonds.shape[0] and not bonded_contacts:   # bonded pairs get no contact force
        def keys(p):
            p = np.sort(p, axis=1)
            return p[:, 0] * np.int64(n) + p[:, 1]
        pairs = pairs[~np.isin(keys(pairs), keys(bonds))]
        if not pairs.size:
            return []
    if clump_of is not None:   # a clump's members never touch each other
        ends = clump_of[pairs]
        pairs = pairs[(ends[:, 0] < 0) | (ends[:, 0] != ends[:, 1])]
        if not pairs.size:
            return []
    i, j = pairs[:, 0], pairs[:, 1]
    overlap = radius[i] + radius[j] - np.linalg.norm(position[j] - position[i], axis=1)
    depth = overlap / np.minimum(radius[i], radius[j])
    deep = np.flatnonzero(depth > DEEP_OVERLAP)
    if not deep.size:
        return []
    worst = deep[np.argmax(depth[deep])]
    a, b = sorted((int(i[worst]), int(j[worst])))
    return [f"{path}: {key}: {deep.size} unbonded particle pair(s) overlap by more than "
            f"{DEEP_OVERLAP:.0%} of the smaller radius at t = 0 (the most: {name(a)} and "
            f"{name(b)}, {depth[worst]:.0%}); their contact forces will throw them apart. "
            "Check the positions and radii, or bond them"]


def _check_plausible(position, radius, bonds, walls, where, path, key):
    """Warnings (list of str) for input that runs but is most likely a slip of units:
    bonded particles that overlap by more than the smaller radius, particles that sit
    closer than half a radius to their nearest neighbour, and particles that overlap a
    wall by more than DEEP_OVERLAP of their radius at t = 0. ``where``: the CSV file and
    line of each particle, or None (generated)."""
    from scipy.spatial import cKDTree
    from .walls import TRIANGLE, WallSet, _triangle_distance_sq, build_wall_pairs
    name = (lambda k: where[k]) if where else (lambda k: f"particle {k}")  # noqa: E731
    hint = ("radii or positions in the wrong unit (all lengths are in m)?")
    out = []
    n = position.shape[0]
    if bonds.shape[0]:
        i, j = bonds[:, 0], bonds[:, 1]
        overlap = radius[i] + radius[j] - np.linalg.norm(position[j] - position[i], axis=1)
        depth = overlap / np.minimum(radius[i], radius[j])
        deep = np.flatnonzero(depth > 1.0)
        if deep.size:
            worst = deep[np.argmax(depth[deep])]
            out.append(f"{path}: {key}: {deep.size} of {bonds.shape[0]} bonded pairs overlap by "
                       f"more than the smaller radius at t = 0 (the most: {name(int(i[worst]))} "
                       f"and {name(int(j[worst]))}, {depth[worst]:.3g} radii): {hint}")
    if n >= 2:
        spacing = cKDTree(position).query(position, k=2)[0][:, 1]
        if np.median(spacing) < 0.5 * np.median(radius):
            out.append(f"{path}: {key}: the particles' median spacing {np.median(spacing):.3g} "
                       f"m is less than half their median radius {np.median(radius):.3g} m: "
                       f"{hint}")
    if walls and n:
        with np.errstate(all="ignore"):   # a wall speed of 1e300 m/s: refused further on
            wall_set = WallSet(walls)
        rows, types = wall_set.elements(0.0), wall_set.element_type
        inside = {}     # wall index: the particles that overlap it deeply
        for p, e in build_wall_pairs(position, radius, 0.0, rows, types):
            if types[e] == TRIANGLE:
                distance = math.sqrt(_triangle_distance_sq(position[p], rows[e, 0],
                                                           rows[e, 1], rows[e, 2]))
            else:
                distance = float((position[p] - rows[e, 0]) @ rows[e, 1])
            if distance < (1.0 - DEEP_OVERLAP) * radius[p]:
                inside.setdefault(int(wall_set.element_wall[e]), set()).add(int(p))
        for w, particles in sorted(inside.items()):
            out.append(f"{path}: walls.{w}: {len(particles)} particle(s) overlap the wall by "
                       f"more than {DEEP_OVERLAP:.0%} of their radius at t = 0 (the first: "
                       f"{name(min(particles))}); the wall will throw them off. Move the "
                       f"wall or the particles, or: {hint}")
    return out


def _mesh_clump(table, path, key):
    """A clump template filled into an STL (``ClumpTemplate.from_mesh``): file (relative
    to the scene), spheres (2 to 1000, default 10), scale (to m, default 1), resolution
    (8 to 200, default 40)."""
    from .clumps import ClumpTemplate
    file = path.parent / str(table["file"])
    if not file.is_file():
        raise InputError(f"no such file: {file}", file=path, key=f"{key}.file")
    values = {}
    for name, default, low, high in (("spheres", 10, 2, 1000), ("resolution", 40, 8, 200)):
        value = table.get(name, default)
        if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
            raise InputError(f"{value!r}; allowed: an integer in [{low}, {high}]", file=path,
                             key=f"{key}.{name}")
        values[name] = value
    scale = table.get("scale", 1.0)
    if not _is_number(scale) or not scale > 0.0 or not math.isfinite(scale):
        raise InputError(f"{scale!r}; allowed: a number > 0", file=path, key=f"{key}.scale")
    try:
        return ClumpTemplate.from_mesh(file, values["spheres"], scale=float(scale),
                                       resolution=values["resolution"])
    except Exception as error:  # noqa: BLE001 - trimesh raises many kinds on a bad file
        raise InputError(f"cannot fill it with spheres: {error}", file=file,
                         key=f"{key}.file") from None


def _make_clumps(model, state, clumps, particles, where, path):
    """The scene's clumps (``clumps.make_clumps``): from the particle file's clump
    column, or the clump generator's (its masses and inertias at density 1 scaled by
    the material's)."""
    from .clumps import make_clumps
    key = "particles.file" if particles["file"] is not None else "particles.generator"
    clump_of = clumps["clump_of"]
    extra = {}
    if "mass" in clumps:
        density = model.materials[int(model.material[0])].density
        extra = dict(mass=clumps["mass"] * density, inertia=clumps["inertia"] * density,
                     centre=clumps["centre"])
    else:
        sizes = np.bincount(clump_of[clump_of >= 0])
        if np.any(sizes == 0):
            missing = int(np.flatnonzero(sizes == 0)[0])
            raise InputError(f"clump {missing} has no particle; number the clumps 0, 1, 2, "
                             "... without gaps", file=path, key=f"{key}.clump")
        if np.any(sizes == 1):
            lone = int(np.flatnonzero(sizes == 1)[0])
            row = int(np.flatnonzero(clump_of == lone)[0])
            at = f"{where[row]}: " if where else ""
            raise InputError(f"{at}clump {lone} has one particle; a clump needs at least 2 "
                             "(give a free sphere clump -1)", file=path, key=f"{key}.clump")
    try:
        return make_clumps(model, state, clump_of, **extra)
    except ValueError as error:
        raise InputError(str(error), file=path, key=f"{key}.clump") from None


def _bonds(table, position, radius, bond_material_names, path, clump_of=None):
    n = position.shape[0]
    empty = (np.zeros((0, 2), dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int32))
    if table is None:
        return empty
    b = _check_table(table, BOND_KEYS, "bonds", path)
    generated = b["max_gap"] is not None
    if (b["file"] is None) == (not generated):
        raise InputError("give exactly one of bonds.file or bonds.max_gap", file=path,
                         key="bonds")
    if b["file"] is not None:
        for key in ("diameter", "diameter_ratio", "max_per_particle", "material"):
            if b[key] is not None:
                raise InputError("only used with bonds.max_gap (bonds.csv has its own columns)",
                                 file=path, key=f"bonds.{key}")
        file = path.parent / b["file"]
        columns = _read_csv(read_bonds, file, "bonds.file", path)
        pairs = np.column_stack([columns["i"], columns["j"]]).astype(np.int64).reshape(-1, 2)
        diameter = columns["diameter"]
        names = list(columns["material"])
        lines = columns["line"].tolist()
        at = lambda k: f"{file.name} line {lines[k]}: "   # noqa: E731
    else:
        if b["material"] is None:
            raise InputError("missing required key (with bonds.max_gap)", file=path,
                             key="bonds.material")
        if (b["diameter"] is None) == (b["diameter_ratio"] is None):
            raise InputError("give exactly one of bonds.diameter or bonds.diameter_ratio",
                             file=path, key="bonds.diameter")
        # none within a clump: it is rigid
        pairs, diameter = bonds_from_gap(position, radius, b["max_gap"],
                                         diameter=b["diameter"],
                                         diameter_ratio=b["diameter_ratio"],
                                         max_per_particle=b["max_per_particle"],
                                         groups=clump_of)
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        diameter = np.asarray(diameter, dtype=np.float64).reshape(-1)
        names = [b["material"]] * pairs.shape[0]
        at = lambda k: ""   # noqa: E731
    where = "bonds.file" if b["file"] is not None else "bonds"
    if pairs.size:
        bad = np.flatnonzero((pairs < 0).any(1) | (pairs >= n).any(1))
        if bad.size:
            raise InputError(f"{at(bad[0])}bond {int(bad[0])} joins particles "
                             f"{pairs[bad[0]].tolist()}; "
                             f"indices must lie in [0, {n - 1}]", file=path, key=where)
        same = np.flatnonzero(pairs[:, 0] == pairs[:, 1])
        if same.size:
            raise InputError(f"{at(same[0])}bond {int(same[0])} joins particle "
                             f"{pairs[same[0], 0]} to itself",
                             file=path, key=where)
        key = np.sort(pairs, axis=1)
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        if np.any(counts > 1):
            dup = key[first[np.argmax(counts > 1)]]
            rows = np.flatnonzero((key == dup).all(axis=1))
            raise InputError(f"{at(rows[-1])}particles {dup.tolist()} are bonded more than "
                             f"once (duplicate of bond {int(rows[0])})", file=path, key=where)
        length = np.linalg.norm(position[pairs[:, 1]] - position[pairs[:, 0]], axis=1)
        zero = np.flatnonzero(length <= 0.0)
        if zero.size:
            raise InputError(f"{at(zero[0])}bond {int(zero[0])} joins particles "
                             f"{pairs[zero[0]].tolist()} at "
                             "the same position (initial length 0, must be > 0)", file=path,
                             key=where)
        # wider than both particles, or thinner than 1/RADIUS_SPREAD of the smaller
        ri, rj = radius[pairs[:, 0]], radius[pairs[:, 1]]
        low, high = 2.0 / RADIUS_SPREAD * np.minimum(ri, rj), 2.0 * np.maximum(ri, rj)
        odd = np.flatnonzero((diameter > 0) & ((diameter < low) | (diameter > high)))
        if odd.size:
            k = int(odd[0])
            why = ("wider than both its particles" if diameter[k] > high[k] else
                   f"less than 1/{RADIUS_SPREAD:.0e} of its particles'")
            raise InputError(f"{at(k)}bond {k} has diameter {float(diameter[k])!r} m, {why}; "
                             f"allowed [{low[k]:.3g}, {high[k]:.4g}] m", file=path,
                             key=where)
        nonpositive = np.flatnonzero(~(diameter > 0))
        if nonpositive.size:
            raise InputError(f"{at(nonpositive[0])}bond {int(nonpositive[0])} has diameter "
                             f"{float(diameter[nonpositive[0]])!r}; must be > 0", file=path,
                             key=where)
    unknown = sorted(set(names) - set(bond_material_names))
    if unknown:
        raise InputError(f"{at(names.index(unknown[0]))}bond material {unknown[0]!r} is "
                         "not defined; defined: "
                         f"{', '.join(bond_material_names) or '(none)'}", file=path,
                         key="bonds.material")
    index = np.array([bond_material_names.index(m) for m in names], dtype=np.int32)
    return pairs, diameter, index

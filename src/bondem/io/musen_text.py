"""MUSEN's text format (1.70: what cmusen's IMPORT_FROM_TEXT reads and EXPORT_TO_TEXT
writes, GeneralFunctions/SimResultsStorage/ImportFromText.cpp) to and from bondem scenes.

A line is a sequence of (command id, values) groups (MUSENDefinitions.h ETXTCommands):
an object line starts ``0 ID 1 TYPE`` (1 sphere, 9 solid bond, 14 triangular wall), then
``5`` geometry (sphere: radius, contact radius; bond: left, right, diameter, initial
length; wall: none), ``23`` compound, ``24`` activity interval (start, end, s) and, per
time point, ``2 TIME`` followed by ``12`` coordinates, ``15`` velocity, ``16`` angular
velocity (a wall's three vertices are 12, 31 and 16), ``18``, ``20``, ``31``, ``36``,
``37``. Scene lines: ``22`` domain (6 m), ``25``/``26``/``27`` geometries (name key mass
free-motion, motion, planes), ``28`` periodic boundaries, ``32`` compound (key name, then
property id / value pairs: 0 density, 7 Young's modulus, 8 normal and 9 tangential
strength, 10 Poisson ratio), ``33`` interaction (two keys, 200 restitution, 201
friction, 202 rolling friction). The models and the time stepping are in the cmusen
script (``MODEL_SB``, ``SIMULATION_STEP`` ...), read by ``read_script``.
"""
from __future__ import annotations

import itertools
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..physics import bond_models, contact_models
from ..physics.contact_hertz_musen import MUSEN_VDW_DMIN, MUSEN_VERSION, MUSEN_VERSIONS
from ..timestep import step_count
from .csv_files import float_text

SPHERE, SOLID_BOND, LIQUID_BOND, TRIANGULAR_WALL = 1, 9, 10, 14
DENSITY, VISCOSITY, YOUNG, NORMAL_STRENGTH, TANGENTIAL_STRENGTH, POISSON = 0, 2, 7, 8, 9, 10
RESTITUTION, FRICTION, ROLLING = 200, 201, 202
# MUSEN 1.70's interaction defaults (its export writes them for pairs a scene leaves out).
MUSEN_INTERACTION = {RESTITUTION: 0.6, FRICTION: 0.45, ROLLING: 0.05}
# Values of each command after its id; None: the rest is read by the command's own rule.
# numbers after each object command; 42-45 are MUSEN 1.71's on (principal stresses, a
# bond's torque, a wall's three corners, a bond's tangential overlap)
_WIDTH = {2: 1, 12: 3, 15: 3, 16: 3, 17: 3, 10: 3, 11: 3, 18: 1, 20: 3, 31: 4, 36: 9,
          37: 1, 23: 1, 24: 2, 42: 3, 43: 1, 44: 9, 45: 3}
_NAMES = {SPHERE: "sphere", SOLID_BOND: "solid bond", LIQUID_BOND: "liquid bond",
          TRIANGULAR_WALL: "triangular wall"}
# MUSEN's solid bond models that bondem has: each bond model's MUSEN declaration
BOND_MODELS = {m.MUSEN["model"]: m for m in bond_models.MODELS if getattr(m, "MUSEN", None)}
UNMAPPED = {29: "anisotropy", 30: "contact radius", 34: "mixture", 38: "analysis volume",
            39: "package generator", 41: "bonds generator"}
# MUSEN's contact models that bondem reproduces (MODEL_PP name -> contact model) and the
# wall model each runs with (physics/contact_*.py's MUSEN declarations)
CONTACT_MODELS = {m.MUSEN["pp"]: m.NAME for m in contact_models.MODELS
                  if "kind_pp" in getattr(m, "MUSEN", {})}
WALL_MODELS = {m.NAME: m.MUSEN["pw"] for m in contact_models.MODELS
               if "kind_pp" in getattr(m, "MUSEN", {})}
SURFACE_ENERGY = 11   # MUSEN material property PROPERTY_SURFACE_ENERGY (J/m^2)
SURFACE_TENSION = 13  # PROPERTY_SURFACE_TENSION, which MUSEN's PopovJKR reads as w


def musen_surface_energy(model, values):
    """{MUSEN property: value} of contact model ``model``'s keys in a material's
    ``values`` (JKR: its surface energy; Popov's JKR: the surface tension; van der
    Waals: MUSEN's w = A / (24 pi Dmin^2))."""
    if model == "jkr":
        return {SURFACE_ENERGY: float(values.get("surface_energy", 0.0))}
    if model == "popov_jkr":
        return {SURFACE_TENSION: float(values.get("surface_energy", 0.0))}
    if model == "vdw":
        return {SURFACE_ENERGY: float(values.get("hamaker_constant", 0.0))
                / (24 * math.pi * MUSEN_VDW_DMIN * MUSEN_VDW_DMIN)}
    return {}


def bondem_adhesion(model, props):
    """A material's contact model keys from its MUSEN properties ``props`` (the inverse of
    ``musen_surface_energy``, with MUSEN's own arithmetic for the Hamaker constant)."""
    if model == "popov_jkr":
        return ({"surface_energy": props[SURFACE_TENSION]} if SURFACE_TENSION in props
                else {})
    w = props.get(SURFACE_ENERGY)
    if w is None:
        return {}
    if model == "jkr":
        return {"surface_energy": w}
    if model == "vdw":
        return {"hamaker_constant": 24 * math.pi * MUSEN_VDW_DMIN * MUSEN_VDW_DMIN * w}
    return {}


@dataclass
class MusenObject:
    """One object of a MUSEN text file: its type, geometry values, compound, activity
    interval (s) and its first time point's (time, coordinates, velocity, angular
    velocity, quaternion) in SI units."""
    id: int
    type: int
    geometry: list = field(default_factory=list)
    compound: str = ""
    active: tuple = (0.0, 1e300)
    time: float | None = None
    coordinates: tuple = (0.0, 0.0, 0.0)
    velocity: tuple = (0.0, 0.0, 0.0)
    angular_velocity: tuple = (0.0, 0.0, 0.0)
    quaternion: tuple = (0.0, 0.0, 0.0, 0.0)
    times: int = 0


@dataclass
class MusenScene:
    """What a MUSEN text file holds: objects by id, compounds {key: {property id:
    value}}, interactions {(key, key): {property id: value}}, domain (6,) m, periodic
    boundaries (enabled, x, y, z, low (3,), high (3,)), geometries [(name, key, motion
    text, plane ids)], multispheres [[sphere ids]] (.mdem files only), and the lines
    bondem does not map (``unmapped``)."""
    objects: dict = field(default_factory=dict)
    compounds: dict = field(default_factory=dict)
    interactions: dict = field(default_factory=dict)
    domain: tuple | None = None
    periodic: tuple | None = None
    geometries: list = field(default_factory=list)
    unmapped: list = field(default_factory=list)
    multispheres: list = field(default_factory=list)


def _numbers(tokens, k, n, path, line):
    try:
        return [float(t) for t in tokens[k:k + n]], k + n
    except ValueError:
        raise InputError(f"expected {n} numbers after command {tokens[k - 1]}, got "
                         f"{' '.join(tokens[k:k + n])!r}", file=path, key=f"line {line}") from None


def read_text(path) -> MusenScene:
    """Parse a MUSEN text scene or export (every time point read; the first one kept)."""
    path = Path(path)
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise InputError("not a MUSEN text file (not text)", file=path) from None
    scene = MusenScene()
    for number, raw in enumerate(text.splitlines(), 1):
        tokens = raw.split()
        if not tokens:
            continue
        try:
            command = int(float(tokens[0]))
        except ValueError:
            raise InputError(f"expected a command id, got {tokens[0]!r}", file=path,
                             key=f"line {number}") from None
        if command == 0:
            _object_line(scene, tokens, path, number)
        elif command == 22:
            scene.domain = tuple(_numbers(tokens, 1, 6, path, number)[0])
        elif command == 28:
            values = _numbers(tokens, 1, 10, path, number)[0]
            scene.periodic = (bool(values[0]), *map(bool, values[1:4]), tuple(values[4:7]),
                              tuple(values[7:10]))
        elif command == 32:
            if len(tokens) < 3:
                raise InputError("compound line: expected KEY NAME [ID VALUE]...", file=path,
                                 key=f"line {number}")
            values = _numbers(tokens, 3, len(tokens) - 3, path, number)[0]
            scene.compounds[tokens[1]] = {int(values[k]): values[k + 1]
                                          for k in range(0, len(values) - 1, 2)}
        elif command == 33:
            values = _numbers(tokens, 3, len(tokens) - 3, path, number)[0]
            pair = tuple(sorted(tokens[1:3]))
            scene.interactions[pair] = {int(values[k]): values[k + 1]
                                        for k in range(0, len(values) - 1, 2)}
        elif command == 25:
            scene.geometries.append([tokens[1] if len(tokens) > 1 else "", tokens[2]
                                     if len(tokens) > 2 else "", "", []])
        elif command == 26 and scene.geometries:
            scene.geometries[-1][2] = " ".join(tokens[1:])
        elif command == 27 and scene.geometries:
            count = int(float(tokens[1]))
            scene.geometries[-1][3] = [int(float(t)) for t in tokens[2:2 + count]]
        elif command == 40:
            continue   # the package generator's configuration: nothing to run
        elif command in (29, 30) and all(float(t) == 0.0 for t in tokens[1:2]):
            continue   # anisotropy / extended contact radius switched off
        else:
            scene.unmapped.append(f"line {number}: command {command} "
                                  f"({UNMAPPED.get(command, 'unknown')})")
    return scene


def _object_line(scene, tokens, path, number):
    k = 0
    obj = None
    first_time = True
    while k < len(tokens):
        try:
            command = int(float(tokens[k]))
        except ValueError:
            raise InputError(f"expected a command id, got {tokens[k]!r}", file=path,
                             key=f"line {number}") from None
        k += 1
        if command == 0:
            ident = int(float(tokens[k]))
            k += 1
            continue
        if command == 1:
            obj = MusenObject(ident, int(float(tokens[k])))
            k += 1
            scene.objects[ident] = obj
            continue
        if obj is None:
            raise InputError("an object line needs '0 ID 1 TYPE' first", file=path,
                             key=f"line {number}")
        if command == 5:
            width = {SPHERE: 2, SOLID_BOND: 4, LIQUID_BOND: 4, TRIANGULAR_WALL: 0}.get(obj.type)
            if width is None:
                raise InputError(f"object type {obj.type}: unknown", file=path, key=f"line {number}")
            obj.geometry, k = _numbers(tokens, k, width, path, number)
            continue
        if command == 23:
            obj.compound = tokens[k]
            k += 1
            continue
        if command not in _WIDTH:
            raise InputError(f"unknown object command {command}", file=path, key=f"line {number}")
        values, k = _numbers(tokens, k, _WIDTH[command], path, number)
        if command == 24:
            obj.active = tuple(values)
        elif command == 2:
            if obj.times:
                first_time = False
            obj.times += 1
            if first_time:
                obj.time = values[0]
        elif first_time and command == 12:
            obj.coordinates = tuple(values)
        elif first_time and command == 15:
            obj.velocity = tuple(values)
        elif first_time and command == 16:
            obj.angular_velocity = tuple(values)
        elif first_time and command == 31:
            obj.quaternion = tuple(values)
        elif first_time and command == 44:
            # MUSEN 1.71 on writes a wall's corners as one command; 1.70 spread them over
            # the coordinates, quaternion and angular velocity, where the walls read them
            obj.coordinates = tuple(values[0:3])
            obj.quaternion = (*values[3:6], 0.0)
            obj.angular_velocity = tuple(values[6:9])


def read_series(lines):
    """Every object line of MUSEN text (an iterable of lines) with all its time points:
    ({id: (type, geometry values, compound, activity (start, end) s, [(time s, {command:
    values})])}, the other lines split in words). Numbers as written."""
    objects, scene = {}, []
    geometry_width = {SPHERE: 2, SOLID_BOND: 4, LIQUID_BOND: 4, TRIANGULAR_WALL: 0}
    for line in lines:
        words = line.split()
        if not words:
            continue
        if words[0] != "0":
            scene.append(words)
            continue
        kind, geometry, compound, activity, points = 0, [], "", (0.0, 1e300), []
        ident, k = int(words[1]), 2
        while k < len(words):
            command = int(float(words[k]))
            if command == 1:
                kind, k = int(words[k + 1]), k + 2
            elif command == 5:
                count = geometry_width[kind]
                geometry, k = [float(w) for w in words[k + 1:k + 1 + count]], k + 1 + count
            elif command == 23:
                compound, k = words[k + 1], k + 2
            elif command == 24:
                activity, k = (float(words[k + 1]), float(words[k + 2])), k + 3
            elif command == 2:
                points.append((float(words[k + 1]), {}))
                k += 2
            else:
                n = _WIDTH[command]
                points[-1][1][command] = [float(w) for w in words[k + 1:k + 1 + n]]
                k += 1 + n
        objects[ident] = (kind, geometry, compound, activity, points)
    return objects, scene


def read_script(path) -> dict:
    """The keys of a cmusen script that a scene needs ({KEY: rest of the line}), from its
    SIMULATOR job (or the whole file if it has none)."""
    out = {}
    job = None
    for raw in Path(path).read_text().splitlines():
        words = raw.split(None, 1)
        if not words:
            continue
        key, rest = words[0].upper(), (words[1].strip() if len(words) > 1 else "")
        if key == "JOB":
            job = {}
            continue
        if key == "COMPONENT" and rest.upper() == "SIMULATOR":
            out = job if job is not None else out
        (job if job is not None else out)[key] = rest
    return out


def _params(text):
    words = text.split()
    return {words[k].upper(): float(words[k + 1]) for k in range(0, len(words) - 1, 2)}


def _from_musen(value, kind, zero_is_inf):
    """A MODEL_SB_PARAMS number as the value of a bondem key of schema ``kind``."""
    if kind == "bool":
        return bool(value)
    return math.inf if zero_is_inf and value == 0.0 else value


def _to_musen(value, zero_is_inf):
    """The MODEL_SB_PARAMS text of a bondem key's value (inverse of ``_from_musen``)."""
    if isinstance(value, bool):
        return str(int(value))
    value = float(value)
    return "0" if zero_is_inf and math.isinf(value) else float_text(value)


def wall_motion(motion, end_time):
    """(scene keys, note or None) of a MUSEN geometry motion (key 26: type, intervals,
    then per interval t_begin t_end (s), velocity (m/s), rotation centre (m), rotation
    velocity (rad/s)), for a run ending at end_time (s). One translation interval over the
    whole run is a constant ``velocity``; several, a ``velocity_profile`` that jumps at the
    interval bounds and is 0 outside them; a single rotation over the whole run without
    translation, ``angular_velocity`` about ``rotation_center`` (named when its axis is
    skew). Anything else (force-dependent motion, rotation with translation) stays static
    and is named."""
    tokens = motion.split()
    if not tokens or not all(_is_number(t) for t in tokens):
        return {}, None
    values = [float(t) for t in tokens]
    kind, count = int(values[0]), int(values[1]) if len(values) > 1 else 0
    if kind == 0 or count == 0:
        return {}, None
    if kind != 1 or len(values) < 2 + 11 * count:
        return {}, "its force-dependent motion is not mapped (the wall is static)"
    intervals = [values[2 + 11 * k: 13 + 11 * k] for k in range(count)]
    moving = [iv for iv in intervals if any(iv[2:5]) or any(iv[8:11])]
    if not moving:
        return {}, None
    whole = len(moving) == 1 and moving[0][0] <= 0.0 and moving[0][1] >= end_time
    if any(any(iv[8:11]) for iv in moving):
        if whole and not any(moving[0][2:5]):
            spin = moving[0][8:11]
            keys = {"angular_velocity": spin, "rotation_center": moving[0][5:8]}
            if sum(1 for w in spin if w) == 1:
                return keys, None     # about one axis: MUSEN's per-step turn is exact
            return keys, ("its rotation about a skew axis is mapped (angular_velocity, "
                          "rotation_center); MUSEN turns it each step by Euler angles "
                          "x, y, z of w dt, not about the axis: O(dt^2) apart per step")
        return {}, "its rotation is not mapped (the wall is static)"
    if whole:
        return {"velocity": moving[0][2:5]}, None
    profile, now = [[0.0, 0.0, 0.0, 0.0]], 0.0
    for begin, end, vx, vy, vz, *_ in sorted(moving):
        begin = max(begin, now)
        profile += [[begin, 0.0, 0.0, 0.0], [begin, vx, vy, vz], [end, vx, vy, vz],
                    [end, 0.0, 0.0, 0.0]]
        now = end
    return {"velocity_profile": profile}, None


def _clumps_of(multispheres, index, notes):
    """{sphere id: clump number} of a file's multispheres that hold at least two of its
    spheres (each sphere in one), with a note of what was imported or left out."""
    clump, skipped = {}, 0
    for ids in multispheres:
        members = [i for i in dict.fromkeys(ids) if i in index and i not in clump]
        if len(members) < 2:
            skipped += 1
            continue
        number = len(set(clump.values()))
        clump.update({i: number for i in members})
    if clump:
        notes.append(f"{len(set(clump.values()))} multisphere(s) imported as rigid clumps "
                     "(MUSEN 1.74.2 stores them but its simulator moves their spheres as "
                     "free particles: drop the clump column of particles.csv to match it)")
    if skipped:
        notes.append(f"{skipped} multisphere(s) with fewer than two spheres of the scene "
                     "left out")
    return clump


def to_bondem(scene: MusenScene, script: dict | None, out_dir, *, end_time=None,
              musen_version=MUSEN_VERSION):
    """Write scene.toml, particles.csv, bonds.csv (and walls_N.stl) in ``out_dir``;
    returns the notes: every MUSEN setting that was not mapped, or mapped with a loss."""
    import tomli_w
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    script = script or {}
    notes = list(scene.unmapped)
    spheres = sorted((o for o in scene.objects.values() if o.type == SPHERE), key=lambda o: o.id)
    bonds = sorted((o for o in scene.objects.values() if o.type == SOLID_BOND),
                   key=lambda o: o.id)
    walls = sorted((o for o in scene.objects.values() if o.type == TRIANGULAR_WALL),
                   key=lambda o: o.id)
    others = [o for o in scene.objects.values() if o.type not in (SPHERE, SOLID_BOND,
                                                                     TRIANGULAR_WALL)]
    for o in others:
        notes.append(f"object {o.id}: {_NAMES.get(o.type, f'type {o.type}')} not mapped")
    if not spheres:
        raise InputError("no spheres (object type 1) in the MUSEN file", file=None)
    t0 = min(o.time for o in spheres if o.time is not None) if any(
        o.time is not None for o in spheres) else 0.0
    index = {o.id: k for k, o in enumerate(spheres)}

    # materials from compounds; contact properties from the pure interactions
    particle_compounds = sorted({o.compound for o in spheres})
    wall_compounds = sorted({o.compound for o in walls})
    bond_compounds = sorted({o.compound for o in bonds})
    materials = {}
    for key in sorted(set(particle_compounds) | set(wall_compounds)):
        props = scene.compounds.get(key)
        if props is None:
            raise InputError(f"compound {key!r} is used but not defined (command 32)",
                             file=None)
        pure = scene.interactions.get((key, key))
        if pure is None:
            pure = MUSEN_INTERACTION
            notes.append(f"interaction {key}-{key} not given: MUSEN's defaults "
                         "(restitution 0.6, friction 0.45, rolling friction 0.05)")
        materials[key] = {"density": props.get(DENSITY, 1000.0),
                          "young_modulus": props.get(YOUNG, 1e9),
                          "poisson_ratio": props.get(POISSON, 0.2),
                          "restitution": pure.get(RESTITUTION, MUSEN_INTERACTION[RESTITUTION]),
                          "friction": pure.get(FRICTION, MUSEN_INTERACTION[FRICTION]),
                          "rolling_friction": pure.get(ROLLING, MUSEN_INTERACTION[ROLLING])}
    for (a, b), props in scene.interactions.items():
        if a == b or a not in materials or b not in materials:
            continue
        for prop, name in ((RESTITUTION, "restitution"), (FRICTION, "friction"),
                           (ROLLING, "rolling_friction")):
            mean = 0.5 * (materials[a][name] + materials[b][name])
            if prop in props and not math.isclose(props[prop], mean, rel_tol=1e-12):
                notes.append(f"interaction {a}-{b}: {name} {props[prop]:g} is not the mean "
                             f"of the pure pairs ({mean:g}), which bondem uses")
    model_sb = script.get("MODEL_SB", "ModelSBElastic").split()[0] if bonds else "ModelSBElastic"
    if model_sb == "ModelSBLinearPlastic":
        # MUSEN 1.74.2 runs its linear plastic bond as its elastic bond unless the bond's
        # Young's modulus is 2 Pa or less (and registers it under the elastic bond's key)
        soft = sorted(k for k in {o.compound for o in bonds}
                      if scene.compounds.get(k, {}).get(YOUNG, 1e9) <= 2.0)
        if soft:
            raise InputError(f"solid bond model ModelSBLinearPlastic with bond Young's "
                             f"modulus <= 2 Pa (compound {soft[0]!r}): its loading and "
                             "unloading branches are not available in bondem",
                             file=None, key="MODEL_SB")
        notes.append("ModelSBLinearPlastic: MUSEN runs it as its elastic bond when the bond "
                     "Young's modulus exceeds 2 Pa (KLoad, KUnload unused): imported as the "
                     "elastic bond")
        model_sb = "ModelSBElastic"
    if model_sb not in BOND_MODELS:
        raise InputError(f"solid bond model {model_sb}: not available in bondem "
                         f"(allowed: {', '.join(BOND_MODELS)})", file=None, key="MODEL_SB")
    sb = _params(script.get("MODEL_SB_PARAMS", ""))
    criterion = int(sb.get("CONSIDER_BREAKAGE", 1))
    bond_materials = {}
    for key in bond_compounds:
        props = scene.compounds.get(key)
        if props is None:
            raise InputError(f"compound {key!r} is used but not defined (command 32)",
                             file=None)
        entry = {"young_modulus": props.get(YOUNG, 1e9), "poisson_ratio": props.get(POISSON, 0.2)}
        module = BOND_MODELS[model_sb]
        musen = module.MUSEN
        strengths = musen["strengths"]
        if isinstance(strengths, str):   # a switch among the model's parameters
            strengths = bool(sb.get(strengths.upper(), 0.0))
        if strengths:
            entry.update(normal_strength=props.get(NORMAL_STRENGTH, 1e7),
                         tangential_strength=props.get(TANGENTIAL_STRENGTH, 1e7),
                         breakage={0: "none", 1: "combined", 2: "separate"}.get(criterion,
                                                                             "combined"))
        else:
            entry["breakage"] = "none"   # MUSEN's model reads no strengths
        if module.NAME != "elastic":
            entry["model"] = module.NAME
        entry.update(musen.get("fixed", {}))
        entry.update(musen.get("defaults", {}))   # MUSEN's own defaults, where not given
        schema = module.PARAMETERS
        for prop, name in musen["properties"].items():
            if prop in props:
                entry[name] = props[prop]
        for word, name in musen["parameters"].items():
            if word.upper() in sb:     # cmusen reads the words in any case
                entry[name] = _from_musen(sb[word.upper()], schema[name][0],
                                          name in musen.get("zero_is_inf", ()))
        if "import" in musen:   # parameters that need more than a renaming
            musen["import"](sb, entry)
        bond_materials[key] = entry

    # multispheres as rigid clumps: MUSEN 1.74.2 stores them, but its simulator never
    # calls MoveMultispheres, so there their spheres move as free particles
    clump = _clumps_of(scene.multispheres, index, notes)
    # particles and bonds at the first time point
    rows = ["x,y,z,radius,material,vx,vy,vz,wx,wy,wz" + (",clump" if clump else "")]
    for o in spheres:
        rows.append(",".join(repr(float(c)) for c in o.coordinates) + f",{o.geometry[0]!r},"
                    f"{o.compound}," + ",".join(repr(float(c)) for c in o.velocity) + ","
                    + ",".join(repr(float(c)) for c in o.angular_velocity)
                    + (f",{clump.get(o.id, -1)}" if clump else ""))
        if o.geometry[1] != o.geometry[0]:
            notes.append(f"sphere {o.id}: contact radius {o.geometry[1]:g} differs from its "
                         "radius; bondem uses the radius")
    (out / "particles.csv").write_text("\n".join(rows) + "\n")
    brows = ["i,j,diameter,material"]
    dropped = 0
    lengths = []
    inside = 0
    for o in bonds:
        if o.active[1] <= t0:
            dropped += 1
            continue
        ends = [clump.get(int(e), -1) for e in o.geometry[:2]] if clump else [-1, -1]
        if ends[0] >= 0 and ends[0] == ends[1]:
            inside += 1     # a rigid clump needs no bond (and bondem refuses one)
            continue
        left, right = int(o.geometry[0]), int(o.geometry[1])
        if left not in index or right not in index:
            raise InputError(f"solid bond {o.id}: particle {left} or {right} is no sphere",
                             file=None)
        brows.append(f"{index[left]},{index[right]},{o.geometry[2]!r},{o.compound}")
        lengths.append((index[left], index[right], o.geometry[3]))
    if dropped:
        notes.append(f"{dropped} solid bonds already broken at t = {t0:g} s: left out")
    if inside:
        notes.append(f"{inside} solid bonds within a multisphere: left out (a clump is "
                     "rigid)")
    (out / "bonds.csv").write_text("\n".join(brows) + "\n")
    positions = np.array([o.coordinates for o in spheres])
    for i, j, l0 in lengths:
        if not math.isclose(float(np.linalg.norm(positions[j] - positions[i])), l0,
                            rel_tol=1e-9):
            notes.append("a bond's initial length differs from its particles' distance at "
                         "the start; bondem takes the distance")
            break

    simulation = {"end_time": end_time or float(script.get("END_TIME", 1e-3)),
                  "time_step": float(script["SIMULATION_STEP"]) if "SIMULATION_STEP" in script
                  else "auto", "musen_compat": True, "musen_version": musen_version}
    if end_time is None and "END_TIME" in script and "SIMULATION_STEP" in script:
        # MUSEN stops once its summed time reaches END_TIME, which scripts put half a step
        # short of a whole number of steps: bondem's end time is that whole number.
        dt = simulation["time_step"]
        simulation["end_time"] = math.ceil(simulation["end_time"] / dt - 1e-6) * dt
    if "SAVING_STEP" in script:
        simulation["save_every"] = float(script["SAVING_STEP"])
    if "EXT_ACCEL" in script:
        simulation["gravity"] = [float(v) for v in script["EXT_ACCEL"].split()[:3]]
    pp = script.get("MODEL_PP", "").split()
    pw = script.get("MODEL_PW", "").split()
    contact = CONTACT_MODELS.get(pp[0], "hertz_mindlin") if pp else "none"
    simulation["contact_model"] = contact
    if pp and pp[0] not in CONTACT_MODELS:
        notes.append(f"contact model {pp[0]}: not available; Hertz-Mindlin is used")
    if pw and contact != "none" and pw[0] != WALL_MODELS[contact]:
        notes.append(f"contact model {pw[0]}: bondem's walls follow {contact!r} as MUSEN's "
                     f"{WALL_MODELS[contact]}")
    for key, values in materials.items():
        values.update(bondem_adhesion(contact, scene.compounds.get(key, {})))
    if "CONNECTED_PP_CONTACT" in script:
        simulation["bonded_contacts"] = bool(int(float(script["CONNECTED_PP_CONTACT"])))
    elif contact != "none":
        simulation["bonded_contacts"] = True   # MUSEN's default (its ModelManager's)
    if scene.periodic and scene.periodic[0]:
        simulation["periodic"] = list(scene.periodic[1:4])
        simulation["box_low"], simulation["box_high"] = list(scene.periodic[4]), \
            list(scene.periodic[5])
    elif scene.domain is not None:
        simulation["box_low"], simulation["box_high"] = list(scene.domain[:3]), \
            list(scene.domain[3:])
    criterion = script.get("STOP_CRITERION", "").split()
    if criterion and criterion[0].upper() == "BROKEN_BONDS":
        try:
            simulation["stop_broken_bonds"] = int(float(criterion[1]))
        except (IndexError, ValueError):
            raise InputError(f"expected BROKEN_BONDS and a number of bonds, got "
                             f"{script['STOP_CRITERION']!r}", file=None,
                             key="STOP_CRITERION") from None
    elif criterion and criterion[0].upper() != "NONE":
        notes.append(f"STOP_CRITERION {script['STOP_CRITERION']}: unknown (MUSEN has NONE "
                     "and BROKEN_BONDS N); the run ends at END_TIME")
    if float(script.get("VARIABLE_TIME_STEP", "0") or 0) != 0.0:
        notes.append("VARIABLE_TIME_STEP: bondem's step is fixed (SIMULATION_STEP)")
    for key in ("VERLET_AUTO", "VERLET_COEF"):
        if key in script:
            notes.append(f"{key} {script[key]}: no counterpart (bondem's contact list: "
                         "docs/musen_migration.md)")
    data = {"simulation": simulation, "materials": materials}
    fluid, note = musen_fluid(script)
    if fluid:
        data["fluid"] = fluid
    if note:
        notes.append(note)
    if bond_materials:
        data["bond_materials"] = bond_materials
    data["particles"] = {"file": "particles.csv"}
    if len(brows) > 1:
        data["bonds"] = {"file": "bonds.csv"}

    # walls: each geometry's triangles (or the loose ones per compound) as an STL mesh
    if walls:
        import trimesh
        data["walls"] = []
        for k, (name, ids, motion) in enumerate(wall_groups(scene)):
            triangles = [scene.objects[i] for i in ids]
            keys, note = wall_motion(motion, simulation.get("end_time", math.inf))
            if note:
                notes.append(f"geometry {name}: {note}")
            vertices = np.array([[t.coordinates, t.quaternion[:3], t.angular_velocity]
                                 for t in triangles]).reshape(-1, 3)
            faces = np.arange(len(vertices)).reshape(-1, 3)
            mesh = trimesh.Trimesh(vertices, faces, process=True)
            file = f"walls_{k}.stl"
            mesh.export(out / file)
            compound = triangles[0].compound
            data["walls"].append({"type": "mesh", "file": file, "material": compound,
                                  **keys})
    (out / "scene.toml").write_bytes(tomli_w.dumps(data).encode())
    return notes


def wall_groups(scene):
    """The scene's walls as bondem walls: [(name, triangle ids, motion text)], one per
    geometry that has triangles, then the triangles of no geometry as one ("walls")."""
    walls = [o.id for o in sorted(scene.objects.values(), key=lambda o: o.id)
             if o.type == TRIANGULAR_WALL]
    groups = [(g[0] or g[1], [i for i in g[3] if i in scene.objects], g[2])
              for g in scene.geometries]
    grouped = {i for _, ids, _ in groups for i in ids}
    loose = [i for i in walls if i not in grouped]
    if loose:
        groups.append(("walls", loose, ""))
    return [g for g in groups if g[1]]


# MUSEN's external force models that bondem has: their parameters and defaults
# (ModelEFViscousField: kinematic viscosity m^2/s, density kg/m^3;
# ModelEFCentrifugalCasting: rad/s about y, kg/m^3, Pa s)
EXTERNAL_FORCES = {
    "ModelEFViscousField": {"MEDIUM_VISCOSITY": 1.34e-5, "MEDIUM_DENSITY": 1.28},
    "ModelEFCentrifugalCasting": {"ROTATION_VELOCITY": 1.0, "LIQUID_DENSITY": 1000.0,
                                  "LIQUID_VISCOSITY": 1.8e-3},
}


def musen_fluid(script):
    """(bondem [fluid] table or None, note or None) of a cmusen script's MODEL_EF:
    ModelEFViscousField (a still medium of kinematic viscosity MEDIUM_VISCOSITY and
    density MEDIUM_DENSITY) is the "musen_viscous" drag, ModelEFCentrifugalCasting (a
    liquid turning at ROTATION_VELOCITY about y) the "musen_centrifugal" one, both
    without buoyancy; another external force model is named in the note."""
    name = script.get("MODEL_EF", "").split()
    if not name:
        return None, None
    if name[0] not in EXTERNAL_FORCES:
        return None, f"external force model {name[0]}: not mapped (no such field in bondem)"
    values = dict(EXTERNAL_FORCES[name[0]])
    values.update({k: v for k, v in _params(script.get("MODEL_EF_PARAMS", "")).items()
                   if k in values})
    if name[0] == "ModelEFViscousField":
        density = values["MEDIUM_DENSITY"]
        return {"density": density, "viscosity": values["MEDIUM_VISCOSITY"] * density,
                "drag": "musen_viscous", "buoyancy": False}, None
    return {"density": values["LIQUID_DENSITY"], "viscosity": values["LIQUID_VISCOSITY"],
            "drag": "musen_centrifugal", "buoyancy": False,
            "spin": [0.0, values["ROTATION_VELOCITY"], 0.0]}, None


def _is_number(text):
    try:
        float(text)
        return True
    except ValueError:
        return False


def import_musen(text_file, out_dir, script_file=None, *, end_time=None,
                 musen_version=MUSEN_VERSION):
    """``bondem import musen``: a MUSEN text file (and its cmusen script) as a bondem scene
    in ``out_dir`` whose musen_compat follows MUSEN release ``musen_version`` (a text file
    does not say which MUSEN wrote it); returns (scene path, notes)."""
    if musen_version not in MUSEN_VERSIONS:
        raise InputError(f"value {musen_version!r}; allowed: "
                         + ", ".join(MUSEN_VERSIONS), key="--musen-version")
    text_file = Path(text_file)
    if not text_file.is_file():
        raise InputError("no such file", file=text_file)
    scene = read_text(text_file)
    script = read_script(script_file) if script_file else None
    try:
        notes = to_bondem(scene, script, out_dir, end_time=end_time,
                          musen_version=musen_version)
    except InputError as error:
        if error.file is None:
            raise InputError(error.reason, file=text_file, key=error.key) from None
        raise
    return Path(out_dir) / "scene.toml", notes


def write_script(scene, time_step, text_name, path):
    """A cmusen script for a bondem scene (dict of its TOML) with time step ``time_step``
    (s): import the text file ``text_name``, simulate with the scene's models (MUSEN 1.70
    names), END_TIME half a step short of the run's steps (MUSEN stops when its summed
    time reaches it). Returns the notes (settings MUSEN has no counterpart for)."""
    keys, notes = simulator_keys(scene, time_step)
    # "./": MUSEN 1.74 creates a result file's folder and fails on an empty name
    lines = ["JOB", "COMPONENT IMPORT_FROM_TEXT", f"SOURCE_FILE {text_name}",
             "RESULT_FILE ./scene_t0.mdem", "JOB", "COMPONENT SIMULATOR",
             "SOURCE_FILE ./scene_t0.mdem", "RESULT_FILE ./result.mdem",
             *(f"{k} {v}" for k, v in keys.items())]
    Path(path).write_text("\n".join(lines) + "\n")
    return notes


def simulator_keys(scene, time_step):
    """({cmusen SIMULATOR key: text}, notes) of a bondem scene (dict of its TOML) run with
    ``time_step`` (s); see ``write_script``."""
    notes = []
    simulation = scene.get("simulation", {})
    bond_tables = list(scene.get("bond_materials", {}).values())
    models = {t.get("model", "elastic") for t in bond_tables} or {"elastic"}
    criteria = {t.get("breakage", "combined") for t in bond_tables} or {"combined"}
    if len(models) > 1 or len(criteria) > 1:
        notes.append("MUSEN has one solid bond model and criterion per run: the first "
                     "bond material's are written")
    module = bond_models.BY_NAME[sorted(models)[0]]
    musen = getattr(module, "MUSEN", None)
    if musen is None:
        raise InputError(f"bond model {module.NAME!r} has no MUSEN counterpart",
                         key="model")
    sb = musen["model"]
    first = next((t for t in bond_tables if t.get("model", "elastic") == module.NAME), {})
    words = []
    if musen["strengths"] is True:
        words.append("CONSIDER_BREAKAGE "
                     f"{({'none': 0, 'combined': 1, 'separate': 2})[sorted(criteria)[0]]}")
    for word, name in musen["parameters"].items():
        value = first.get(name, module.PARAMETERS[name][1])
        words.append(f"{word} {_to_musen(value, name in musen.get('zero_is_inf', ()))}")
    if "export" in musen:
        text, note = musen["export"](first)
        words.append(text)
        if note:
            notes.append(note)
    if isinstance(musen["strengths"], str):
        finite = any(math.isfinite(float(first.get(k, math.inf)))
                     for k in ("normal_strength", "tangential_strength"))
        words.append(f"{musen['strengths']} {int(finite)}")
    params = " ".join(words)
    # the runner's count, so the exported MUSEN run is as long as bondem's
    steps = max(1, step_count(simulation.get("end_time", 1e-3), time_step))
    contact = simulation.get("contact_model", "hertz_mindlin")
    contacts = contact != "none"
    if contacts and contact not in WALL_MODELS:
        notes.append(f"contact_model = {contact!r}: written as MUSEN's Hertz-Mindlin")
    keys = {"SIMULATOR_TYPE": "CPU", "MODEL_SB": sb, "MODEL_SB_PARAMS": params}
    if contacts:
        module = contact_models.BY_NAME[contact if contact in WALL_MODELS else "hertz_mindlin"]
        keys.update(MODEL_PP=module.MUSEN["pp"], MODEL_PW=module.MUSEN["pw"],
                    CONNECTED_PP_CONTACT=str(int(bool(simulation.get("bonded_contacts",
                                                                     False)))))
    keys["SIMULATION_STEP"] = repr(time_step)
    if "save_every" in simulation:
        keys["SAVING_STEP"] = repr(float(simulation["save_every"]))
    keys["END_TIME"] = repr((steps - 0.5) * time_step)
    keys["EXT_ACCEL"] = " ".join(repr(float(g)) for g in
                                 simulation.get("gravity", [0.0, 0.0, 0.0]))
    keys["VARIABLE_TIME_STEP"] = "0"
    if float(simulation.get("damping", 0.0)):
        notes.append("local damping: MUSEN has none")
    for w, wall in enumerate(scene.get("walls", [])):
        if wall.get("own_friction"):
            notes.append(f"wall {w}: own_friction is not written (MUSEN's interaction "
                         "gets the mean of the two materials' friction)")
        moved = [k for k in ("velocity_profile", "servo") if wall.get(k) is not None]
        if moved:
            notes.append(f"wall {w}: its {moved[0]} is not written (MUSEN moves it by a "
                         "constant velocity only; written static)")
    return keys, notes


def export_musen(results_path, out_file, every=1):
    """``bondem export musen``: a results file as a MUSEN text file (compounds,
    interactions as the pairs' means, domain, spheres with every frame's coordinates,
    velocities and angular velocities, solid bonds with their activity interval, walls as
    triangles at t = 0: a plane as a square of twice the particles' extent) and a cmusen
    script beside it (``write_script``: FILE_script.txt). Returns (text file, script,
    notes)."""
    from .results import read_results
    data = read_results(results_path)
    scene = tomllib.loads(str(data["attrs"]["scene"]))
    lines = export_lines(data, scene, every)
    out_file = Path(out_file)
    out_file.parent.mkdir(parents=True, exist_ok=True)
    out_file.write_text("\n".join(lines) + "\n")
    script = out_file.with_name(out_file.stem + "_script.txt")
    notes = write_script(scene, float(data["attrs"]["time_step"]), out_file.name, script)
    return out_file, script, notes


def export_lines(data, scene, every=1):
    """The lines of MUSEN's text format for a results file's ``data`` (``read_results``)
    and its scene table (see ``export_musen``)."""
    names = [str(n) for n in data["materials/names"]]
    bond_names = [str(n) for n in data.get("bond_materials/names", [])]
    lines = []
    time = data["time"][::every]
    position = data["particles/position"][::every]
    velocity = data["particles/velocity"][::every]
    spin = data["particles/angular_velocity"][::every]
    radius = data["particles/radius"]
    material = data["particles/material"]
    n = radius.shape[0]
    for p in range(n):
        parts = ["0", str(p), "1", str(SPHERE), "5", float_text(radius[p]),
                 float_text(radius[p]), "23", names[material[p]], "24", "0", "1e+300"]
        for f in range(len(time)):
            parts += ["2", float_text(time[f]), "12", *map(float_text, position[f, p]),
                      "15", *map(float_text, velocity[f, p]),
                      "16", *map(float_text, spin[f, p])]
        lines.append(" ".join(parts))
    pairs = data["bonds/pairs"]
    for b in range(pairs.shape[0]):
        end = data["bonds/break_time"][b]
        parts = ["0", str(n + b), "1", str(SOLID_BOND), "5", str(int(pairs[b, 0])),
                 str(int(pairs[b, 1])), float_text(data["bonds/diameter"][b]),
                 float_text(data["bonds/initial_length"][b]), "23",
                 bond_names[data["bonds/material"][b]], "24", "0",
                 "1e+300" if np.isnan(end) else float_text(end), "2", float_text(time[0]),
                 "12", "0", "0", "0"]
        lines.append(" ".join(parts))
    ident = n + pairs.shape[0]
    extent = (position[0].min(axis=0), position[0].max(axis=0)) if n else (np.zeros(3),) * 2
    size = 2.0 * float(np.max(extent[1] - extent[0]) + 4.0 * radius.max(initial=0.0))
    wall_materials = []
    end_time = float(scene.get("simulation", {}).get("end_time", time[-1]))
    wall_position = data.get("walls/position")
    for w, wall in enumerate(scene.get("walls", [])):
        triangles = _wall_triangles(data, w, wall, size)
        spin = [float(v) for v in wall.get("angular_velocity", [0.0, 0.0, 0.0])]
        # a translating wall's frames: its t = 0 triangles carried along by its recorded
        # position (a turning wall: its t = 0 place, MUSEN moves it by its motion)
        travel = (np.asarray(wall_position[::every, w]) - wall_position[0, w]
                  if wall_position is not None and not any(spin)
                  else np.zeros((len(time), 3)))
        first = ident
        for a, b, c in triangles:
            # the activity interval: MUSEN 1.74 makes an object without one inactive
            parts = ["0", str(ident), "1", str(TRIANGULAR_WALL), "5", "23", wall["material"],
                     "24", "0", "1e+300"]
            for f, t in enumerate(time):
                d = travel[f]
                parts += ["2", float_text(t), "12", *map(float_text, np.add(a, d)), "31",
                          *map(float_text, np.add(b, d)), "0", "16",
                          *map(float_text, np.add(c, d))]
            lines.append(" ".join(parts))
            ident += 1
        lines.append(f"25 wall{w} wall{w} 0 0 0 0")
        velocity = [float(v) for v in wall.get("velocity", [0.0, 0.0, 0.0])]
        if any(velocity) or any(spin):
            # one time interval over the run: MUSEN's constant motion (type 1)
            centre = [float(v) for v in wall.get("rotation_center", [0.0, 0.0, 0.0])]
            lines.append("26 1 1 0 " + " ".join(map(float_text, [end_time, *velocity,
                                                                  *centre, *spin])))
        lines.append(f"27 {ident - first} " + " ".join(str(i) for i in range(first, ident)))
        wall_materials.append(wall["material"])
    simulation = scene.get("simulation", {})
    low = simulation.get("box_low")
    high = simulation.get("box_high")
    if low is None or high is None:
        span = size
        centre = 0.5 * (extent[0] + extent[1])
        low, high = list(centre - span), list(centre + span)
    lines.append("22 " + " ".join(float_text(v) for v in [*low, *high]))
    if any(simulation.get("periodic", [False] * 3)):
        lines.append("28 1 " + " ".join(str(int(v)) for v in simulation["periodic"]) + " "
                     + " ".join(float_text(v) for v in [*low, *high]))
    tables = scene.get("materials", {})
    simulation_model = simulation.get("contact_model", "hertz_mindlin")
    for key in names:
        props = tables.get(key, {})
        lines.append(f"32 {key} {key} {DENSITY} {float_text(props.get('density', 0.0))} "
                     f"{YOUNG} {float_text(props.get('young_modulus', 0.0))} "
                     f"{POISSON} {float_text(props.get('poisson_ratio', 0.3))}"
                     + "".join(f" {prop} {float_text(value)}" for prop, value in
                               musen_surface_energy(simulation_model, props).items()))
    density = float(tables.get(names[0], {}).get("density", 1000.0)) if names else 1000.0
    for key in bond_names:
        props = scene.get("bond_materials", {}).get(key, {})
        line = (f"32 {key} {key} {DENSITY} {float_text(density)} "
                f"{YOUNG} {float_text(props.get('young_modulus', 0.0))} "
                f"{POISSON} {float_text(props.get('poisson_ratio', 0.3))}")
        for name, prop in (("normal_strength", NORMAL_STRENGTH),
                           ("tangential_strength", TANGENTIAL_STRENGTH)):
            value = float(props.get(name, math.inf))
            line += f" {prop} {float_text(value if math.isfinite(value) else 1e300)}"
        module = bond_models.BY_NAME[props.get("model", "elastic")]
        for prop, name in getattr(module, "MUSEN", {}).get("properties", {}).items():
            value = float(props.get(name, module.PARAMETERS[name][1]))
            line += f" {prop} {float_text(value if math.isfinite(value) else 1e300)}"
        lines.append(line)
    defaults = {"restitution": 0.5, "friction": 0.3, "rolling_friction": 0.0}
    keys = sorted(set(names) | set(wall_materials))
    for a in range(len(keys)):
        for b in range(a, len(keys)):
            pa, pb = tables.get(keys[a], {}), tables.get(keys[b], {})
            values = [0.5 * (float(pa.get(k, d)) + float(pb.get(k, d)))
                      for k, d in defaults.items()]
            lines.append(f"33 {keys[a]} {keys[b]} {RESTITUTION} {float_text(values[0])} "
                         f"{FRICTION} {float_text(values[1])} {ROLLING} {float_text(values[2])}")
    return lines


def _wall_triangles(data, w, wall, size):
    """Triangles (a, b, c) in m of wall w of a results file at t = 0."""
    if wall.get("type") == "mesh":
        vertices = data[f"walls/geometry/mesh{w}/vertices"]
        triangles = data[f"walls/geometry/mesh{w}/triangles"]
        return [tuple(map(tuple, vertices[t].astype(float))) for t in triangles]
    point = np.asarray(data["walls/geometry/point"][w], dtype=float)
    normal = np.asarray(data["walls/geometry/normal"][w], dtype=float)
    normal = normal / np.linalg.norm(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    h = 0.5 * size
    corners = [point + h * (su * u + sv * v) for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    return [tuple(map(tuple, (corners[0], corners[1], corners[2]))),
            tuple(map(tuple, (corners[0], corners[2], corners[3])))]


# MUSEN's bond generator as a script adds it (its SBondClass defaults)
BOND_GENERATOR = {"active": True, "name": "", "compound": "", "min_distance": 0.0,
                  "max_distance": 1e-3, "diameter": 5e-4, "overlay": False,
                  "compounds": None}


def generate_bonds(scene, generators):
    """MUSEN's bonds generator (BondsGenerator.cpp) on ``scene`` (a MusenScene): its solid
    bonds removed, then for each active generator a bond between every pair of spheres
    whose surfaces are min_distance to max_distance (m) apart, of diameter min(diameter,
    both particles' diameters), initial length their distance, compound the generator's;
    without ``overlay`` no second bond between two particles; ``compounds`` (two lists)
    limits the pairs to one particle of each. Returns the number of bonds made."""
    from scipy.spatial import cKDTree
    free = sorted(i for i, o in scene.objects.items() if o.type == SOLID_BOND)
    for ident in free:
        del scene.objects[ident]
    spheres = sorted((o for o in scene.objects.values() if o.type == SPHERE),
                     key=lambda o: o.id)
    if not spheres:
        return 0
    position = np.array([o.coordinates for o in spheres])
    radius = np.array([o.geometry[0] for o in spheres])
    tree = cKDTree(position)
    connected = set()
    # MUSEN gives new objects the ids the removed bonds freed, then new ones
    fresh = itertools.chain(free, itertools.count(max(list(scene.objects) + free) + 1))
    made = 0
    for g in generators:
        if not g["active"]:
            continue
        reach = 2.0 * radius.max() + g["max_distance"]
        pairs = np.array(sorted(tree.query_pairs(reach)), dtype=np.int64).reshape(-1, 2)
        gap = np.linalg.norm(position[pairs[:, 1]] - position[pairs[:, 0]], axis=1) \
            - radius[pairs[:, 0]] - radius[pairs[:, 1]]
        keep = (gap >= g["min_distance"]) & (gap <= g["max_distance"])
        for (a, b), d in zip(pairs[keep], gap[keep]):
            left, right = spheres[a], spheres[b]
            if g["compounds"] is not None:
                first, second = g["compounds"]
                if not ((left.compound in first and right.compound in second)
                        or (right.compound in first and left.compound in second)):
                    continue
            key = (min(left.id, right.id), max(left.id, right.id))
            if not g["overlay"] and key in connected:
                continue
            connected.add(key)
            diameter = min(g["diameter"], 2.0 * radius[a], 2.0 * radius[b])
            ident = next(fresh)
            scene.objects[ident] = MusenObject(
                ident, SOLID_BOND, [float(left.id), float(right.id), float(diameter),
                                    float(d + radius[a] + radius[b])], g["compound"],
                (0.0, 1e300), time=left.time, times=1)
            made += 1
    return made


def package_volume(volume):
    """A MUSEN analysis volume (``musen_mdem.package_generators``) as a bondem container
    and its MUSEN volume (m^3, what MUSEN fills): a sphere, an axis-aligned box or a
    cylinder from its sizes about its mesh's centre, any other (a turned box, a hollow
    sphere, an STL volume) as the inside of its mesh."""
    from ..generate import Box, Cylinder, MeshVolume, Sphere
    triangles = volume["triangles"]
    if triangles.shape[0] == 0:
        raise InputError(f"analysis volume {volume['name']!r} has no mesh", file=None)
    centre = 0.5 * (triangles.reshape(-1, 3).min(axis=0) + triangles.reshape(-1, 3).max(axis=0))
    sizes, shape, rotation = list(volume["sizes"]), volume["shape"], volume["rotation"]
    if shape == 0 and sizes:
        return Sphere(centre, sizes[0]), 4.0 * math.pi * sizes[0] ** 3 / 3.0
    if shape == 1 and len(sizes) >= 3 and np.allclose(rotation, np.eye(3)):
        half = 0.5 * np.array(sizes[:3])
        return Box(centre - half, centre + half), sizes[0] * sizes[1] * sizes[2]
    if shape == 2 and len(sizes) >= 2:
        return (Cylinder(centre, sizes[0], sizes[1], tuple(rotation @ [0.0, 0.0, 1.0])),
                math.pi * sizes[0] ** 2 * sizes[1])
    import trimesh
    mesh = trimesh.Trimesh(triangles.reshape(-1, 3),
                           np.arange(triangles.shape[0] * 3).reshape(-1, 3), process=True)
    container = MeshVolume(mesh)
    return container, (4.0 * math.pi / 3.0 * (sizes[0] ** 3 - sizes[1] ** 3)
                       if shape == 3 and len(sizes) >= 2 else container.volume)


def generate_package(scene, generator, seed=0):
    """MUSEN's package generator on ``scene`` (a MusenScene): ``generator`` as
    ``musen_mdem.package_generators`` gives it. MUSEN's counts (per fraction, the whole
    part of (1 - porosity) V / sum_k f_k pi d_k^3 / 6 times f_i), packed by bondem's
    generator (``generate.pack_spheres``, seeded: MUSEN's own placement is random) inside
    the volume, overlaps below MUSEN's absolute limit, with the generator's initial
    velocity. Returns (number of spheres added, notes)."""
    from ..generate import pack_spheres
    notes = []
    volume, mixture = generator["volume"], generator["mixture"]
    if volume is None or mixture is None:
        raise InputError(f"package generator {generator['name']!r}: its "
                         f"{'volume' if volume is None else 'mixture'} is not in the file",
                         file=None)
    container, fill = package_volume(volume)
    fractions = [f for f in mixture["fractions"] if f[1] > 0 and f[3] > 0]
    solid = (1.0 - generator["porosity"]) * fill
    mean = sum(f[3] * math.pi / 6.0 * f[1] ** 3 for f in fractions)
    counts = [int(solid / mean * f[3]) for f in fractions]
    radii = np.repeat([0.5 * f[1] for f in fractions], counts)
    compounds = np.repeat([f[0] for f in fractions], counts)
    if radii.size == 0:
        return 0, notes
    if any(f[2] not in (0.0, f[1]) for f in fractions):
        notes.append(f"package generator {generator['name']!r}: contact diameters other "
                     "than the diameters are kept but not used by bondem")
    overlap = float(np.clip(generator["max_overlap"] / radii.min(), 1e-6, 0.05))
    position, radius = pack_spheres(container, radius=radii,
                                    solids_fraction=min(max(1.0 - generator["porosity"],
                                                            1e-6), 0.65),
                                    seed=seed, max_overlap=overlap)
    contact = np.repeat([0.5 * (f[2] or f[1]) for f in fractions], counts)
    ident = max(scene.objects, default=-1) + 1
    for k in range(radius.size):
        scene.objects[ident] = MusenObject(ident, SPHERE, [float(radius[k]),
                                                          float(contact[k])],
                                           str(compounds[k]), (0.0, 1e300), time=0.0,
                                           coordinates=tuple(map(float, position[k])),
                                           velocity=tuple(generator["velocity"]), times=1)
        ident += 1
    return int(radius.size), notes

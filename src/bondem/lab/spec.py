"""Lab spec files (TOML): the specimen and the test settings, checked at the edge like
scene files (every bad value an InputError naming the file and the key).

    [specimen]                  # one of: shape (generated), lattice, scene (a scene file;
                                # its body, shape then naming its geometry)
    shape = "cylinder"          # box [x,y,z] | cylinder [D,H] | disc [D,t] | sphere [D]
    size = [0.008, 0.016]       # m
    particle_radius = 5e-4      # m (or radius_distribution = {radius = [...], fraction = [...]})
    solids_fraction = 0.55
    seed = 1
    max_gap = 5e-5              # m, bonds within this surface gap
    diameter_ratio = 0.6
    consolidation_stress = 1e5  # Pa, optional
    contact_model = "hertz_mindlin"
    [specimen.material]         # the particles' material (scene keys)
    [specimen.bond_material]    # the bonds' material (scene keys); none with an adhesive
                                # contact_model (jkr, vdw, liquid_bridge): no bonds

    [test]                      # LabSettings keys; [test.platen_material] optional
    strain_rate = 10.0          # 1/s
"""
from __future__ import annotations

import copy
from pathlib import Path

from ..errors import InputError, unknown_key
from ..model import BondMaterial, Material
from ..physics import contact_models
from .procedures import RATE_CHECKS, RATE_RULES, STRESS_PATHS, LabSettings
from .specimen import ADHESIVE, lattice_specimen, make_specimen, specimen_from_scene

INF = float("inf")
SPECIMEN_KEYS = {
    "shape": ("str", None, ("box", "cylinder", "disc", "sphere"), None, None, None),
    "lattice": ("any", None, None, None, None, None),
    "scene": ("str", None, None, None, None, None),
    "size": ("any", None, None, None, None, None),
    "particle_radius": ("number", None, 0.0, INF, False, False),
    "radius": ("number", None, 0.0, INF, False, False),
    "radius_distribution": ("table", None, None, None, None, None),
    "solids_fraction": ("number", 0.55, 0.0, 0.66, False, False),
    "seed": ("int", 0, 0, INF, True, False),
    "max_gap": ("number", 0.0, 0.0, INF, True, False),
    "diameter_ratio": ("number", 0.5, 0.0, 1.0, False, True),
    "max_per_particle": ("int", None, 1, INF, True, False),
    "consolidation_stress": ("number", None, 0.0, INF, False, False),
    "contact_model": ("str", "hertz_mindlin", (*contact_models.NAMES, "none"), None, None,
                      None),
    "material": ("table", None, None, None, None, None),
    "bond_material": ("table", None, None, None, None, None),
}
TEST_KEYS = {
    "strain_rate": ("number", None, 0.0, INF, False, False),
    "rate_rule": ("str", "bonds", RATE_RULES, None, None, None),
    "post_peak": ("number", 0.7, 0.0, 1.0, False, False),
    "failure_bonds": ("number", None, 0.0, 1.0, True, False),
    "largest_fragment": ("number", 0.9, 0.0, 1.0, False, True),
    "ae_radius": ("number", 2.0, 0.0, INF, False, False),
    "jaws": ("number", 1.5, 0.0, INF, True, False),
    "rate_check": ("str", "warn", RATE_CHECKS, None, None, None),
    "flattened": ("number", 0.0, 0.0, 90.0, True, False),
    "stress_path": ("str", "constant_sigma3", STRESS_PATHS, None, None, None),
    "unload_at": ("any", [], None, None, None, None),
    "unload_to": ("number", 0.3, 0.0, 1.0, True, False),
    "max_strain": ("number", None, 0.0, 1.0, False, False),
    "damping": ("number", 0.7, 0.0, 1.0, True, False),
    "confining_stress": ("number", None, 0.0, INF, False, False),
    "ramp": ("number", 2.0, 0.0, INF, True, False),
    "gauge": ("any", [0.1, 0.25], None, None, None, None),
    "grip": ("number", 0.1, 0.0, 0.5, False, False),
    "samples": ("int", 2000, 1, INF, True, False),
    "frames": ("int", 20, 1, INF, True, False),
    "max_steps": ("int", 5_000_000, 1, INF, True, False),
    "safety_factor": ("number", 0.2, 0.0, 1.0, False, True),
    "backend": ("str", "cpu", ("cpu", "gpu"), None, None, None),
    "platen_material": ("table", None, None, None, None, None),
}


def _check(table, schema, where, path):
    """The scene's table check, with "any" keys (lists checked by the caller) passed on."""
    from ..scene import _check_table
    if not isinstance(table, dict):
        raise InputError("expected a table", file=path, key=where)
    for key in table:
        if key not in schema:
            raise InputError(unknown_key(key, schema), file=path,
                             key=f"{where}.{key}")
    loose = {k for k, v in schema.items() if v[0] == "any"}
    out = _check_table({k: v for k, v in table.items() if k not in loose},
                       {k: v for k, v in schema.items() if k not in loose}, where, path)
    for key in loose:
        out[key] = copy.deepcopy(table.get(key, schema[key][1]))
    return out


def _numbers(value, count, key, path, integer=False, positive=True):
    """``value`` if it is a list of ``count`` finite numbers > 0 (>= 0 unless
    ``positive``; integers if ``integer``), else an InputError naming ``key``."""
    ok = isinstance(value, list) and len(value) == count
    ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    ok = ok and all((v > 0 if positive else v >= 0) and v < INF for v in value)
    ok = ok and (not integer or all(isinstance(v, int) for v in value))
    if not ok:
        kind = "integer" if integer else "number"
        bound = ">= 1" if integer else "> 0" if positive else ">= 0"
        what = f"{kind}{'s' if count != 1 else ''} {bound}"
        raise InputError(f"value {value!r}: expected {count} {what}", file=path, key=key)
    return value


def _material(table, where, path, bond=False):
    from ..scene import BOND_MATERIAL_KEYS, MATERIAL_KEYS, _check_table
    if table is None:
        raise InputError("missing required table", file=path, key=where)
    values = _check_table(table, BOND_MATERIAL_KEYS if bond else MATERIAL_KEYS, where, path)
    try:
        return (BondMaterial if bond else Material)(**{k: v for k, v in values.items()
                                                       if v is not None})
    except (TypeError, ValueError) as error:
        raise InputError(str(error), file=path, key=where) from None


SIZES = {"box": 3, "cylinder": 2, "disc": 2, "sphere": 1}


def load_spec(path, overrides=None):
    """Read a lab spec file: returns (Specimen, LabSettings, text). overrides: {"dotted.key":
    value} applied before the checks (as ``bondem lab --set``)."""
    from ..scene import read_toml
    path = Path(path)
    data, text = read_toml(path, overrides, "lab spec")
    for key in data:
        if key not in ("specimen", "test"):
            raise InputError(unknown_key(key, ("specimen", "test")), file=path, key=key)
    if "specimen" not in data:
        raise InputError("missing required table", file=path, key="specimen")
    spec = _check(data["specimen"], SPECIMEN_KEYS, "specimen", path)
    test = _check(data.get("test", {}), TEST_KEYS, "test", path)
    return _specimen(spec, path), _settings(test, path), text


def _specimen(spec, path):
    kinds = [k for k in ("lattice", "scene") if spec[k] is not None]
    if not kinds and spec["shape"] is not None:
        kinds = ["shape"]
    if kinds != ["shape"] and spec["size"] is not None:
        raise InputError(f"size applies to generated specimens (shape), not to a {kinds[0]}",
                         file=path, key="specimen.size")
    if len(kinds) != 1:
        raise InputError("give exactly one of shape (a generated specimen), lattice [nx, ny, "
                         "nz] or scene (a scene file)", file=path, key="specimen.shape")
    if spec["scene"] is not None:
        scene = (path.parent / spec["scene"]).resolve()
        if not scene.is_file():
            raise InputError(f"value {spec['scene']!r}: no such file", file=path,
                             key="specimen.scene")
        # shape, if given, tells the scene body's geometry (for its cross-section)
        return specimen_from_scene(scene, shape=spec["shape"] or "box")
    material = _material(spec["material"], "specimen.material", path)
    # an adhesive contact model holds a body without bonds: the bond material is optional
    adhesive = spec["contact_model"] in ADHESIVE
    bond = (None if adhesive and spec["bond_material"] is None else
            _material(spec["bond_material"], "specimen.bond_material", path, bond=True))
    if spec["lattice"] is not None:
        counts = _numbers(spec["lattice"], 3, "specimen.lattice", path, integer=True)
        if spec["radius"] is None:
            raise InputError("a lattice needs radius (m)", file=path, key="specimen.radius")
        if spec["shape"] not in (None, "box", "cylinder"):
            raise InputError(f"value {spec['shape']!r}: a lattice is a box or a cylinder",
                             file=path, key="specimen.shape")
        return lattice_specimen(counts, spec["radius"], material, bond,
                                diameter_ratio=spec["diameter_ratio"],
                                contact_model=spec["contact_model"],
                                shape=spec["shape"] or "box")
    shape = spec["shape"]
    if spec["size"] is None:
        raise InputError("missing required key", file=path, key="specimen.size")
    size = _numbers(spec["size"], SIZES[shape], "specimen.size", path)
    if (spec["particle_radius"] is None) == (spec["radius_distribution"] is None):
        raise InputError("give exactly one of particle_radius (m) or radius_distribution",
                         file=path, key="specimen.particle_radius")
    try:
        return make_specimen(shape, size, particle_radius=spec["particle_radius"],
                             radius_distribution=spec["radius_distribution"],
                             solids_fraction=spec["solids_fraction"], seed=spec["seed"],
                             material=material, bond_material=bond, max_gap=spec["max_gap"],
                             diameter_ratio=spec["diameter_ratio"],
                             max_per_particle=spec["max_per_particle"],
                             consolidation_stress=spec["consolidation_stress"],
                             contact_model=spec["contact_model"])
    except (ValueError, RuntimeError) as error:
        raise InputError(f"cannot make the specimen: {error}", file=path,
                         key="specimen") from None


def _settings(test, path):
    gauge = _numbers(test["gauge"], 2, "test.gauge", path, positive=False)
    values = {k: v for k, v in test.items() if k not in ("gauge", "platen_material",
                                                          "unload_at")}
    values["gauge"] = tuple(float(v) for v in gauge)
    turns = test["unload_at"]
    if isinstance(turns, (int, float)) and not isinstance(turns, bool):
        turns = [turns]   # one platen strain
    if not isinstance(turns, list):
        raise InputError(f"value {turns!r}: expected a list of platen strains in (0, 1)",
                         file=path, key="test.unload_at")
    if turns:
        values["unload_at"] = tuple(float(v) for v in _numbers(
            turns, len(turns), "test.unload_at", path))
    if test["platen_material"] is not None:
        values["platen_material"] = _material(test["platen_material"],
                                              "test.platen_material", path)
    try:
        return LabSettings(**values)
    except ValueError as error:
        name = str(error).split(" ", 1)[0]
        raise InputError(str(error), file=path, key=f"test.{name}") from None

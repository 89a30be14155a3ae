"""MUSEN's .mdem files (format version 2, as MUSEN 1.70.0 to 1.74.2 write it) read and
written without MUSEN's code: scenes into bondem scenes, finished simulations into bondem
results files.

The layout (MUSEN's Modules/SimResultsStorage/MDEMFile.h): a 64-byte header (signature
0x12345678, format version, thread count 2, cluster size), two 1024-byte thread headers
("simulation info" and "time-dependent": name, size, the file offsets of up to 118
blocks), then the blocks. A thread is one byte stream cut into blocks of growing size
(cluster x 1, 1, 2, 3, 4, 6, 8, 12, ...). The first thread holds the zlib-compressed
ProtoSimulationStorage: objects, geometries, materials, models, the simulator's settings
and the table of time-dependent blocks; each such block, zlib-compressed at its offset in
the second thread, holds the saved time points with every object's coordinates,
velocities, forces ... The message tables below are the field numbers of MUSEN's
SimulationDescription.proto and MaterialsDatabase.proto (the format, written out here).

MUSEN's release is told apart by its model manager: 1.74 lists its models (field 9),
1.70 keeps one per kind (fields 1 to 5).
"""
from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path

import numpy as np

from ..errors import InputError
from .protowire import WireError, decode, encode, varint

SIGNATURE = 0x12345678
FORMAT_VERSION = 2
HEADER, THREAD_HEADER, BLOCKS_PER_THREAD = 64, 1024, 118
NORMAL_TEMPERATURE, NORMAL_PRESSURE = 273.15, 101325.0   # MUSEN's property evaluation
DEFAULT_ACTIVITY_END = 1e300
SPHERE, SOLID_BOND, TRIANGULAR_WALL = 1, 9, 14

_V = "ProtoVector"
TABLES = {
    "ProtoVector": {1: ("x", "double", False), 2: ("y", "double", False),
                    3: ("z", "double", False)},
    "ProtoQuaternion": {1: ("q0", "double", False), 2: ("q1", "double", False),
                        3: ("q2", "double", False), 4: ("q3", "double", False)},
    "ProtoMatrix": {1: ("v1", _V, False), 2: ("v2", _V, False), 3: ("v3", _V, False)},
    "ProtoGeometryMotionInterval": {1: ("version", "varint", False),
                                    2: ("velocity", _V, False),
                                    3: ("rot_velocity", _V, False),
                                    4: ("rot_center", _V, False),
                                    5: ("limit1", "double", False),
                                    6: ("limit2", "double", False),
                                    7: ("limit_type", "varint", False)},
    "ProtoGeometryMotion": {1: ("version", "varint", False), 2: ("type", "varint", False),
                            3: ("intervals", "ProtoGeometryMotionInterval", True)},
    "ProtoBaseGeometry": {1: ("version", "varint", False), 2: ("name", "string", False),
                          3: ("key", "string", False), 4: ("shape", "varint", False),
                          7: ("sizes", "double", True), 8: ("rotation", "ProtoMatrix", False),
                          9: ("motion", "ProtoGeometryMotion", False),
                          10: ("scaling", "double", False)},
    "ProtoRealGeometry": {1: ("version", "varint", False),
                          2: ("base_geometry", "ProtoBaseGeometry", False),
                          3: ("planes", "varint", True), 4: ("free_motion", _V, False),
                          5: ("mass", "double", False),
                          6: ("rotate_around_center", "bool", False)},
    "ProtoTimeDepVel": {1: ("time", "double", False), 2: ("velocity", _V, False),
                        3: ("rotVelocity", _V, False), 4: ("rotCenter", _V, False)},
    "ProtoRealGeometry_v0": {1: ("name", "string", False), 2: ("key", "string", False),
                             4: ("planes", "varint", True),
                             5: ("tdVal", "ProtoTimeDepVel", True),
                             6: ("mass", "double", False), 7: ("vFreeMotion", _V, False),
                             13: ("forceDependentVel", "bool", False)},
    "ProtoParticleInfo": {1: ("id", "varint", False), 2: ("type", "varint", False),
                          3: ("compound", "string", False),
                          5: ("encoded_properties", "bytes", False),
                          6: ("activity_start", "double", False),
                          7: ("activity_end", "double", False)},
    "ProtoStopCriteria": {2: ("types", "varint", True),
                          3: ("max_broken_bonds", "varint", False)},
    "ProtoSimulationInfo": {25: ("version", "varint", False),
                            1: ("file_version", "varint", False),
                            2: ("begin_time", "double", False),
                            3: ("end_time", "double", False),
                            4: ("simulation_volume_min", _V, False),
                            5: ("simulation_volume_max", _V, False),
                            6: ("particles", "ProtoParticleInfo", True),
                            7: ("real_geometry_v0", "ProtoRealGeometry_v0", True),
                            26: ("real_geometry", "ProtoRealGeometry", True),
                            8: ("analysis_volume_v0", "bytes", True),
                            24: ("analysis_volume", "ProtoAnalysisVolume", True),
                            9: ("savedTimePoints", "double", True),
                            10: ("multispheres", "ProtoMultisphere", True),
                            11: ("periodic_conditions_min", _V, False),
                            12: ("periodic_conditions_max", _V, False),
                            13: ("periodic_conditions_x", "bool", False),
                            14: ("periodic_conditions_y", "bool", False),
                            15: ("periodic_conditions_z", "bool", False),
                            17: ("periodic_conditions_enabled", "bool", False),
                            21: ("periodic_conditions_vel", _V, False),
                            18: ("anisotropy", "bool", False),
                            19: ("contact_radius", "bool", False),
                            20: ("selective_saving", "bool", False),
                            23: ("stop_criteria", "ProtoStopCriteria", False)},
    "ProtoModuleSimulator": {1: ("start_time", "double", False),
                             2: ("end_time", "double", False),
                             3: ("simulation_step", "double", False),
                             4: ("saving_step", "double", False),
                             5: ("external_acceleration", _V, False),
                             6: ("save_collisions", "bool", False),
                             7: ("simulator_type", "varint", False),
                             8: ("max_cells_number", "varint", False),
                             9: ("verlet_dist_coeff", "double", False),
                             10: ("verlet_auto_adjust", "bool", False),
                             12: ("flexible_time_step", "bool", False),
                             13: ("part_move_limit", "double", False),
                             14: ("time_step_factor", "double", False),
                             15: ("part_velocity_limit", "double", False)},
    "ProtoMusenModel": {1: ("key", "string", False), 2: ("path", "string", False),
                        4: ("params", "string", False)},
    "ProtoModuleModelManager": {8: ("version", "varint", False),
                                9: ("models", "ProtoMusenModel", True),
                                6: ("connected_pp_contact", "bool", False),
                                1: ("pp_model", "ProtoMusenModel", False),
                                2: ("pw_model", "ProtoMusenModel", False),
                                3: ("sb_model", "ProtoMusenModel", False),
                                4: ("lb_model", "ProtoMusenModel", False),
                                5: ("ef_model", "ProtoMusenModel", False),
                                7: ("ht_pp_model", "ProtoMusenModel", False)},
    "ProtoCorrelation": {1: ("t1", "double", False), 2: ("t2", "double", False),
                         3: ("p1", "double", False), 4: ("p2", "double", False),
                         5: ("corType", "varint", False), 6: ("parameter", "double", True)},
    "ProtoTPProperty": {1: ("propertyType", "varint", False),
                        2: ("correlation", "ProtoCorrelation", True)},
    "ProtoConstProperty": {1: ("propertyType", "varint", False),
                           2: ("value", "double", False)},
    "ProtoCompound": {1: ("compoundName", "string", False), 2: ("uniqueKey", "string", False),
                      3: ("authorName", "string", False), 6: ("phase", "varint", False),
                      7: ("constProperty", "ProtoConstProperty", True),
                      8: ("property", "ProtoTPProperty", True)},
    "ProtoInteraction": {1: ("compoundKey1", "string", False),
                         2: ("compoundKey2", "string", False),
                         3: ("property", "ProtoTPProperty", True)},
    "ProtoMaterialsDatabase": {1: ("compound", "ProtoCompound", True),
                               2: ("interaction", "ProtoInteraction", True),
                               3: ("mixture", "ProtoMixture", True)},
    "ProtoBondsGenerator": {1: ("name", "string", False),
                            2: ("material_key", "string", False),
                            3: ("obj_type", "varint", False),
                            4: ("min_length", "double", False),
                            5: ("max_length", "double", False),
                            6: ("property1", "double", False),
                            7: ("allow_overlap", "bool", False),
                            8: ("compound_specific", "bool", False),
                            9: ("partner_compounds1", "string", True),
                            10: ("partner_compounds2", "string", True),
                            11: ("activity", "bool", False)},
    "ProtoModuleBondsGenerator": {1: ("generators", "ProtoBondsGenerator", True)},
    # a multisphere: the ids of its spheres (int32; MUSEN writes ids >= 0)
    "ProtoMultisphere": {1: ("id", "varint", True)},
    "ProtoTriangle": {1: ("vert1", _V, False), 2: ("vert2", _V, False),
                      3: ("vert3", _V, False)},
    "ProtoAnalysisVolume": {1: ("version", "varint", False),
                            2: ("base_geometry", "ProtoBaseGeometry", False),
                            3: ("triangles", "ProtoTriangle", True),
                            4: ("center", _V, False)},
    "ProtoCompoundFraction": {1: ("fractionName", "string", False),
                              2: ("compoundKey", "string", False),
                              3: ("diameter", "double", False),
                              4: ("fraction", "double", False),
                              5: ("contact_diameter", "double", False)},
    "ProtoMixture": {1: ("uniqueKey", "string", False), 2: ("mixtureName", "string", False),
                     3: ("fraction", "ProtoCompoundFraction", True)},
    "ProtoPackageGenerator": {1: ("volume_name", "string", False),
                              8: ("mixture_key", "string", False),
                              10: ("porosity", "double", False),
                              11: ("max_overlap", "double", False),
                              12: ("max_iterations", "varint", False),
                              13: ("init_velocity", _V, False),
                              15: ("volume_active", "bool", False),
                              16: ("volume_key", "string", False),
                              17: ("inside_geometry", "bool", False)},
    "ProtoModulePackageGenerator": {1: ("generators", "ProtoPackageGenerator", True),
                                    2: ("simulator_type", "varint", False),
                                    3: ("verlet_coeff", "double", False)},
    "ProtoModulesData": {1: ("simulator", "ProtoModuleSimulator", False),
                         2: ("objects_generator", "bytes", False),
                         3: ("bonds_generator", "ProtoModuleBondsGenerator", False),
                         4: ("package_generator", "ProtoModulePackageGenerator", False),
                         5: ("model_manager", "ProtoModuleModelManager", False),
                         6: ("materials_database", "ProtoMaterialsDatabase", False)},
    "ProtoBlockDescriptor": {1: ("start_time", "double", False),
                             2: ("offset_in_file", "varint", False),
                             3: ("size", "varint", False),
                             4: ("uncompressed_size", "varint", False),
                             5: ("format", "varint", False)},
    "ProtoSimulationStorage": {1: ("info", "ProtoSimulationInfo", False),
                               2: ("modules_data", "ProtoModulesData", False),
                               3: ("data_blocks", "ProtoBlockDescriptor", True)},
    "ProtoTimeDependentProperties": {1: ("coord", _V, False), 3: ("vel", _V, False),
                                     4: ("angle_vel", _V, False),
                                     6: ("angle_accl", _V, False),
                                     8: ("total_torque", "double", False),
                                     9: ("temperature", "double", False),
                                     11: ("force", _V, False),
                                     12: ("quaternion", "ProtoQuaternion", False),
                                     13: ("stress_tensor", "ProtoMatrix", False)},
    "ProtoTimePoint": {1: ("time", "double", False),
                       2: ("particles", "ProtoTimeDependentProperties", True)},
    "ProtoBlockOfTimePoints": {2: ("time_points", "ProtoTimePoint", True)},
}


def block_size(index, cluster):
    """Bytes of a thread's block ``index`` (MUSEN's CMDEMFile::GetBlockSizeByIndex):
    cluster x 1, 1, 2, 3, 4, then alternately x 3/2 and x 4/3 in whole clusters."""
    if index == 0:
        return cluster
    if index < 5:
        return index * cluster
    value = 4
    for step in range(index - 4):
        value = value // 2 * 3 if step % 2 == 0 else value // 3 * 4
    return value * cluster


class MdemFile:
    """An open .mdem file: ``storage`` (the decoded ProtoSimulationStorage as dicts),
    ``version`` (the format version of its header) and its time-dependent blocks, read on
    demand. Any defect raises InputError naming the file."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            self.raw = self.path.read_bytes()
        except OSError as error:
            raise InputError(f"cannot read: {error.strerror}", file=self.path) from None
        if len(self.raw) < HEADER + 2 * THREAD_HEADER:
            self._fail("too short for a .mdem file (no headers)")
        signature, self.version, threads, self.cluster = struct.unpack_from("<4I", self.raw)
        if signature != SIGNATURE:
            self._fail("not a MUSEN .mdem file (no 0x12345678 signature)")
        if self.version not in (1, FORMAT_VERSION):
            self._fail(f".mdem format version {self.version}; readable: 1 and 2 (MUSEN "
                       "1.70.0 to 1.74.2)")
        if threads < 2 or self.cluster == 0 or self.cluster % 512:
            self._fail(f"damaged header ({threads} threads, cluster {self.cluster} bytes)")
        self.threads = []
        for k in range(2):
            at = HEADER + k * THREAD_HEADER
            size = struct.unpack_from("<Q", self.raw, at + 64)[0]
            offsets = struct.unpack_from(f"<{BLOCKS_PER_THREAD}Q", self.raw, at + 80)
            self.threads.append((size, offsets))
        storage = self._inflate(self._thread_bytes(0, 0, self.threads[0][0]), 2,
                                "the simulation info")
        self.storage = self._decode(storage, "ProtoSimulationStorage", "the simulation info")
        self.info = self.storage.get("info", {})
        self.modules = self.storage.get("modules_data", {})
        self.blocks = self.storage.get("data_blocks", [])
        if not self.blocks:
            self._fail("no time-dependent blocks (not a finished MUSEN save)")

    def _fail(self, reason):
        raise InputError(reason, file=self.path)

    def _thread_bytes(self, thread, start, size):
        """``size`` bytes of thread ``thread`` from its logical offset ``start``."""
        offsets = self.threads[thread][1]
        out, index, base = [], 0, 0
        end = start + size
        while base < end:
            if index >= BLOCKS_PER_THREAD:
                self._fail(f"thread {thread} is longer than its 118 blocks")
            length = block_size(index, self.cluster)
            lo, hi = max(start, base), min(end, base + length)
            if lo < hi:
                at = offsets[index]
                if at == 0 or at + (hi - base) > len(self.raw):
                    self._fail("truncated (a block lies past the end of the file)")
                out.append(self.raw[at + lo - base: at + hi - base])
            base += length
            index += 1
        return b"".join(out)

    def _inflate(self, data, fmt, what):
        if fmt == 1:       # MUSEN's kProtoBuf: stored as is
            return data
        stream = zlib.decompressobj()
        try:
            out = stream.decompress(data)
        except zlib.error:
            self._fail(f"{what} is damaged (its zlib stream does not inflate)")
        if not stream.eof:   # the stream's end carries its checksum
            self._fail(f"{what} is truncated (its zlib stream ends early)")
        return out

    def _decode(self, data, message, what):
        try:
            return decode(data, message, TABLES)
        except (WireError, RecursionError) as error:
            self._fail(f"{what} is damaged ({error})")

    def check(self):
        """Read and inflate every time-dependent block (its zlib checksum included):
        InputError if any is missing, truncated or damaged."""
        for k, block in enumerate(self.blocks):
            size = block.get("size", 0)
            if size > 0:
                data = self._thread_bytes(1, block.get("offset_in_file", 0), size)
                self._inflate(data, block.get("format", 2), f"time block {k}")

    def time_points(self):
        """Every saved time point, in order, as (time (s), [per-object dicts])."""
        for k, block in enumerate(self.blocks):
            size = block.get("size", 0)
            if size <= 0:
                continue
            data = self._thread_bytes(1, block.get("offset_in_file", 0), size)
            data = self._inflate(data, block.get("format", 2), f"time block {k}")
            points = self._decode(data, "ProtoBlockOfTimePoints", f"time block {k}")
            for point in points.get("time_points", []):
                yield point.get("time", 0.0), point.get("particles", [])


def vector(message, default=(0.0, 0.0, 0.0)):
    """A ProtoVector dict as a 3-tuple (proto3 leaves zeros out)."""
    if message is None:
        return default
    return (message.get("x", 0.0), message.get("y", 0.0), message.get("z", 0.0))


def property_value(prop):
    """A MUSEN property's value at 273.15 K and 101325 Pa: its first correlation whose
    interval holds that point (MUSEN's CTPProperty::GetValue); NaN if none."""
    for c in prop.get("correlation", []):
        if not (c.get("t1", 0.0) <= NORMAL_TEMPERATURE <= c.get("t2", 0.0)
                and c.get("p1", 0.0) <= NORMAL_PRESSURE <= c.get("p2", 0.0)):
            continue
        k = c.get("parameter", []) + [0.0, 0.0, 0.0]
        kind = c.get("corType", 0)
        if kind == 0:
            return k[0]
        if kind == 1:
            return NORMAL_TEMPERATURE * k[2] + NORMAL_PRESSURE * k[1] + k[0]
        if kind == 2:
            return math.exp(k[0] + k[1] / (NORMAL_TEMPERATURE + k[2]))
        if kind == 3:
            return k[0] * NORMAL_TEMPERATURE ** k[1]
        return math.nan
    return math.nan


def object_geometry(particle, version):
    """A MUSEN object's geometry numbers (sphere: radius, contact radius; bond: left id,
    right id, diameter, initial length; wall: none) from its encoded properties (binary in
    format 2, text before)."""
    data = particle.get("encoded_properties", b"")
    kind = particle.get("type", 0)
    if version < 2:
        return [float(t) for t in data.decode("ascii", "replace").split()]
    if kind == SPHERE and len(data) == 16:
        return list(struct.unpack("<2d", data))
    if kind in (SOLID_BOND, 13) and len(data) == 24:
        left, right, diameter, length = struct.unpack("<2I2d", data)
        return [float(left), float(right), diameter, length]
    if kind == TRIANGULAR_WALL:
        return []
    raise ValueError(f"object {particle.get('id', 0)}: {len(data)} bytes of geometry for "
                     f"type {kind}")


def _text(value):
    return repr(float(value))


def musen_release(mdem):
    """The MUSEN release whose simulation a file's models follow: "1.74.2" when its model
    manager lists its models (1.71 on), "1.70.0" when it keeps one per kind."""
    manager = mdem.modules.get("model_manager", {})
    return "1.74.2" if "models" in manager or "version" in manager else "1.70.0"


_MODEL_KINDS = (("ModelSB", "MODEL_SB"), ("ModelPP", "MODEL_PP"), ("ModelPW", "MODEL_PW"),
                ("ModelLB", "MODEL_LB"), ("ModelEF", "MODEL_EF"), ("ModelHTPP", "MODEL_HT_PP"))
_OLD_MODELS = {"sb_model": "MODEL_SB", "pp_model": "MODEL_PP", "pw_model": "MODEL_PW",
               "lb_model": "MODEL_LB", "ef_model": "MODEL_EF", "ht_pp_model": "MODEL_HT_PP"}


def _model_name(model):
    """A model's name (MUSEN stores a model's library path or, built in, its name)."""
    path = model.get("path", "")
    return Path(path.replace("\\", "/")).stem if path else ""


def script_of(mdem):
    """The cmusen script keys ({KEY: text}, as ``musen_text.read_script`` gives them) of a
    file's simulator settings and models."""
    simulator = mdem.modules.get("simulator", {})
    manager = mdem.modules.get("model_manager", {})
    script = {}
    if "simulation_step" in simulator:
        script["SIMULATION_STEP"] = _text(simulator["simulation_step"])
    if "saving_step" in simulator:
        script["SAVING_STEP"] = _text(simulator["saving_step"])
    if "end_time" in simulator:
        script["END_TIME"] = _text(simulator["end_time"])
    script["EXT_ACCEL"] = " ".join(_text(v) for v in
                                   vector(simulator.get("external_acceleration")))
    script["VARIABLE_TIME_STEP"] = "1" if simulator.get("flexible_time_step") else "0"
    # MUSEN's defaults (2, on) are what a script without these keys runs with
    if simulator.get("verlet_dist_coeff", 2.0) != 2.0:
        script["VERLET_COEF"] = _text(simulator["verlet_dist_coeff"])
    if not simulator.get("verlet_auto_adjust", "simulator" not in mdem.modules):
        script["VERLET_AUTO"] = "0"
    models = list(manager.get("models", []))
    models += [manager[k] for k in _OLD_MODELS if manager.get(k, {}).get("path")]
    for model in models:
        name = _model_name(model)
        for prefix, key in sorted(_MODEL_KINDS, key=lambda kv: -len(kv[0])):
            if name.startswith(prefix):
                if key not in script:    # the first model of a kind, with its own params
                    script[key] = name
                    if model.get("params", "").strip():
                        script[key + "_PARAMS"] = model["params"].strip()
                break
    if "MODEL_PP" in script:
        script["CONNECTED_PP_CONTACT"] = "1" if manager.get("connected_pp_contact") else "0"
    stop = mdem.info.get("stop_criteria", {})
    if 1 in stop.get("types", []):     # MUSEN's EStopCriteria::BROKEN_BONDS
        script["STOP_CRITERION"] = f"BROKEN_BONDS {stop.get('max_broken_bonds', 0)}"
    return script


def scene_of(mdem):
    """The file's scene (a ``musen_text.MusenScene``) at its first saved time point."""
    from .musen_text import MusenObject, MusenScene
    scene = MusenScene()
    info = mdem.info
    time, first = next(mdem.time_points(), (0.0, []))
    for k, particle in enumerate(info.get("particles", [])):
        kind = particle.get("type", 0)
        if kind == 0:
            continue     # a removed object
        ident = particle.get("id", 0)
        try:
            geometry = object_geometry(particle, mdem.version)
        except (ValueError, struct.error) as error:
            raise InputError(f"damaged object ({error})", file=mdem.path) from None
        obj = MusenObject(ident, kind, geometry, particle.get("compound", ""),
                          (particle.get("activity_start", 0.0),
                           particle.get("activity_end", 0.0)))
        values = first[ident] if ident < len(first) else {}
        obj.time = time
        obj.times = 1
        obj.coordinates = vector(values.get("coord"))
        obj.velocity = vector(values.get("vel"))
        obj.angular_velocity = vector(values.get("angle_vel"))
        q = values.get("quaternion", {})
        obj.quaternion = tuple(q.get(f"q{j}", 0.0) for j in range(4))
        scene.objects[ident] = obj
    low, high = info.get("simulation_volume_min"), info.get("simulation_volume_max")
    if low is not None or high is not None:
        scene.domain = (*vector(low), *vector(high))
    scene.periodic = (bool(info.get("periodic_conditions_enabled")),
                      bool(info.get("periodic_conditions_x")),
                      bool(info.get("periodic_conditions_y")),
                      bool(info.get("periodic_conditions_z")),
                      vector(info.get("periodic_conditions_min")),
                      vector(info.get("periodic_conditions_max")))
    if any(vector(info.get("periodic_conditions_vel"))):
        scene.unmapped.append("periodic boundaries: moving boundaries are not mapped")
    materials = mdem.modules.get("materials_database", {})
    for compound in materials.get("compound", []):
        props = {p.get("propertyType", 0): p.get("value", 0.0)
                 for p in compound.get("constProperty", [])}
        props.update({p.get("propertyType", 0): property_value(p)
                      for p in compound.get("property", [])})
        scene.compounds[compound.get("uniqueKey", "")] = props
    for interaction in materials.get("interaction", []):
        pair = tuple(sorted((interaction.get("compoundKey1", ""),
                             interaction.get("compoundKey2", ""))))
        scene.interactions[pair] = {p.get("propertyType", 0): property_value(p)
                                    for p in interaction.get("property", [])}
    for geometry in info.get("real_geometry", []):
        base = geometry.get("base_geometry", {})
        scene.geometries.append([base.get("name", "").replace(" ", "_"),
                                 base.get("key", ""), _motion_text(base.get("motion", {})),
                                 [int(p) for p in geometry.get("planes", [])]])
    for geometry in info.get("real_geometry_v0", []):
        scene.geometries.append([geometry.get("name", "").replace(" ", "_"),
                                 geometry.get("key", ""), "",
                                 [int(p) for p in geometry.get("planes", [])]])
        if geometry.get("tdVal"):
            scene.unmapped.append(f"geometry {geometry.get('name', '')}: the motion of an "
                                  "old-format geometry is not mapped (the wall is static)")
    scene.multispheres = [[int(i) for i in m.get("id", [])]
                          for m in info.get("multispheres", [])]
    for field, what in (("analysis_volume", "analysis volume"),
                        ("analysis_volume_v0", "analysis volume")):
        if info.get(field):
            scene.unmapped.append(f"{len(info[field])} {what}(s) not mapped")
    return scene


def package_tables(mdem):
    """({name and key: analysis volume}, {name and key: mixture}) of a .mdem file: a
    volume as {name, key, shape (0 sphere, 1 box, 2 cylinder, 3 hollow sphere, 5 STL),
    sizes (m), rotation (3x3), triangles (T,3,3) m}, a mixture as {name, key, fractions:
    [(compound, diameter, contact diameter (m), number fraction)]}."""
    volumes = {}
    for v in mdem.info.get("analysis_volume", []):
        base = v.get("base_geometry", {})
        rotation = base.get("rotation")
        matrix = (np.array([vector(rotation.get(f"v{k}")) for k in (1, 2, 3)])
                  if rotation else np.eye(3))
        triangles = np.array([[vector(t.get(f"vert{k}")) for k in (1, 2, 3)]
                              for t in v.get("triangles", [])]).reshape(-1, 3, 3)
        entry = {"name": base.get("name", ""), "key": base.get("key", ""),
                 "shape": base.get("shape", 0), "sizes": base.get("sizes", []),
                 "rotation": matrix, "triangles": triangles}
        volumes[entry["key"]] = volumes.setdefault(entry["name"], entry)
    mixtures = {}
    for m in mdem.modules.get("materials_database", {}).get("mixture", []):
        entry = {"name": m.get("mixtureName", ""), "key": m.get("uniqueKey", ""),
                 "fractions": [(f.get("compoundKey", ""), f.get("diameter", 0.0),
                                f.get("contact_diameter", 0.0), f.get("fraction", 0.0))
                               for f in m.get("fraction", [])]}
        mixtures[entry["key"]] = mixtures.setdefault(entry["name"], entry)
    return volumes, mixtures


def package_generators(mdem):
    """The package generators of a .mdem file: [{active, name, volume, mixture (as
    ``package_tables`` gives them; None when the file has no such key), porosity,
    max_overlap (m), velocity (m/s), inside_geometry}]."""
    volumes, mixtures = package_tables(mdem)
    out = []
    for g in mdem.modules.get("package_generator", {}).get("generators", []):
        out.append({"active": g.get("volume_active", False),
                    "name": g.get("volume_name", ""),
                    "volume": volumes.get(g.get("volume_key", "")),
                    "mixture": mixtures.get(g.get("mixture_key", "")),
                    "porosity": g.get("porosity", 0.0),
                    "max_overlap": g.get("max_overlap", 0.0),
                    "velocity": vector(g.get("init_velocity")),
                    "inside_geometry": g.get("inside_geometry", False)})
    return out


def bond_generators(mdem):
    """The bond generators a .mdem file keeps (MUSEN's SBondClass as a dict: active, name,
    compound, min_distance, max_distance (m, between the particles' surfaces), diameter
    (m), overlay, compound lists or None)."""
    out = []
    for g in mdem.modules.get("bonds_generator", {}).get("generators", []):
        specific = g.get("compound_specific", False)
        out.append({"active": g.get("activity", False), "name": g.get("name", ""),
                    "compound": g.get("material_key", ""),
                    "min_distance": g.get("min_length", 0.0),
                    "max_distance": g.get("max_length", 0.0),
                    "diameter": g.get("property1", 0.0),
                    "overlay": g.get("allow_overlap", False),
                    "compounds": ((g.get("partner_compounds1", []),
                                   g.get("partner_compounds2", [])) if specific else None)})
    return out


def _motion_text(motion):
    """A geometry's motion in MUSEN's text form (type, intervals, then per interval
    begin, end, velocity, rotation centre, rotation velocity; force-dependent ones: limit,
    limit type, the same three vectors)."""
    kind = motion.get("type", 0)
    intervals = motion.get("intervals", [])
    if kind == 0 or not intervals:
        return "0 0"
    words = [str(kind), str(len(intervals))]
    for iv in intervals:
        if kind == 1:
            words += [_text(iv.get("limit1", 0.0)), _text(iv.get("limit2", 0.0))]
        else:
            words += [_text(iv.get("limit1", 0.0)), str(iv.get("limit_type", 0))]
        for name in ("velocity", "rot_center", "rot_velocity"):
            words += [_text(v) for v in vector(iv.get(name))]
    return " ".join(words)


def import_mdem(path, out_dir, *, end_time=None, musen_version=None):
    """``bondem import musen FILE.mdem``: the scene of a MUSEN .mdem file (its first saved
    time point, its materials, models and simulator settings) as a bondem scene in
    ``out_dir``, in MUSEN-compatible mode for the release the file's models say
    (``musen_version`` overrides it); returns (scene path, notes)."""
    mdem = MdemFile(path)
    mdem.check()
    return _import_scene(mdem, out_dir, end_time, musen_version)


def _import_scene(mdem, out_dir, end_time=None, musen_version=None):
    """``import_mdem`` of an open, checked file."""
    from .musen_text import to_bondem
    release = musen_version or musen_release(mdem)
    script = script_of(mdem)
    try:
        notes = to_bondem(scene_of(mdem), script, out_dir, end_time=end_time,
                          musen_version=release)
    except InputError as error:
        if error.file is None:
            raise InputError(error.reason, file=mdem.path, key=error.key) from None
        raise
    if mdem.version < 2:
        notes.append(f".mdem format version {mdem.version}")
    return Path(out_dir) / "scene.toml", notes


def _rows(values, key, shape):
    """(count, *shape) array of one time-dependent property of a list of object dicts
    (absent: zeros)."""
    out = np.zeros((len(values), *shape))
    for k, v in enumerate(values):
        item = v.get(key)
        if item is None:
            continue
        if shape == ():
            out[k] = item
        elif key == "quaternion":
            out[k] = [item.get(f"q{j}", 0.0) for j in range(4)]
        else:
            out[k] = vector(item)
    return out


def break_modes(force, axis, area, normal_strength, tangential_strength):
    """Each broken bond's mode (1 tension, 2 compression, 3 shear) inferred from its last
    saved force before it broke (MUSEN saves no mode): force (B,3) N on particle i, axis
    (B,3) unit from i to j, area (B,) m^2, strengths (B,) Pa. Shear when the tangential
    stress is the larger fraction of its strength; else tension when the normal force
    pulls i toward j, compression when it pushes."""
    normal = np.einsum("ij,ij->i", force, axis)
    tangential = np.linalg.norm(force - normal[:, None] * axis, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        shear = tangential / (area * tangential_strength) > np.abs(normal) / (
            area * normal_strength)
    return np.where(shear, 3, np.where(normal >= 0.0, 1, 2)).astype(np.int8)


def import_mdem_results(path, out_dir, *, musen_version=None):
    """``bondem import musen RESULT.mdem --results``: the scene of a finished MUSEN
    simulation (as ``import_mdem``) and, in ``out_dir``/results.h5, every saved time point
    of it: the particles' positions, velocities, angular velocities and forces, the
    bonds' state and MUSEN's own bond forces (``/bonds/force``, on particle i), the walls'
    forces (summed over each geometry's triangles, on the wall) and positions (the
    centroid's travel). MUSEN keeps no bond moments (written as NaN), no break mode
    (inferred by ``break_modes``) and no energy counters (only the kinetic energy is
    written). MUSEN's tangential overlaps and total torques of the bonds are kept in
    ``/musen/``. Returns (results path, notes)."""
    import h5py
    from ..io.results import ResultsWriter
    from ..scene import load_scene
    from .musen_text import wall_groups
    mdem = MdemFile(path)
    mdem.check()
    scene_path, notes = _import_scene(mdem, out_dir, musen_version=musen_version)
    musen = scene_of(mdem)
    scene = load_scene(scene_path)
    sim = scene.make_simulation()
    objects = musen.objects
    spheres = sorted(i for i, o in objects.items() if o.type == SPHERE)
    t0 = next(mdem.time_points(), (0.0, []))[0]
    bonds = sorted(i for i, o in objects.items() if o.type == SOLID_BOND
                   and o.active[1] > t0)
    groups = wall_groups(musen)
    start = np.array([objects[i].active[0] for i in bonds])
    end = np.array([objects[i].active[1] for i in bonds])
    out = Path(out_dir)
    results = out / "results.h5"
    state = sim.state
    frames = {"bond_force": [], "overlap": [], "torque": [], "wall_force": [],
              "wall_centroid": []}
    names = list(sim.energy_terms())
    with ResultsWriter(results, sim, scene_text=scene.text, scene_name="scene.toml",
                       material_names=list(scene.data.get("materials", {})) or None,
                       bond_material_names=list(scene.data.get("bond_materials", {}))
                       or None) as writer:
        for time, values in mdem.time_points():
            if len(values) < len(mdem.info.get("particles", [])):
                values = values + [{}] * (len(mdem.info.get("particles", [])) - len(values))
            part = [values[i] for i in spheres]
            bond = [values[i] for i in bonds]
            state.time = time
            state.position[:] = _rows(part, "coord", (3,))
            state.velocity[:] = _rows(part, "vel", (3,))
            state.angular_velocity[:] = _rows(part, "angle_vel", (3,))
            sim.force[:] = _rows(part, "force", (3,))
            active = (start <= time) & (time <= end)
            newly = state.bond_active & ~active
            state.bond_break_time[newly] = end[newly]
            if newly.any():
                axis = state.position[sim.model.bond_pairs[newly, 1]] \
                    - state.position[sim.model.bond_pairs[newly, 0]]
                previous = frames["bond_force"][-1][newly] if frames["bond_force"] \
                    else np.zeros((int(newly.sum()), 3))
                table = sim.model.bond_material_table()
                material = sim.model.bond_material[newly]
                state.bond_break_mode[newly] = break_modes(
                    previous, axis / np.linalg.norm(axis, axis=1)[:, None],
                    np.pi * (0.5 * sim.model.bond_diameter[newly]) ** 2,
                    table["normal_strength"][material],
                    table["tangential_strength"][material])
            state.bond_active[:] = active
            frames["bond_force"].append(np.where(active[:, None],
                                                 _rows(bond, "force", (3,)), 0.0))
            frames["overlap"].append(_rows(bond, "angle_vel", (3,)))
            frames["torque"].append(_rows(bond, "total_torque", ()))
            frames["wall_force"].append(np.array(
                [_rows([values[i] for i in ids], "force", (3,)).sum(axis=0)
                 for _, ids, _ in groups]).reshape(-1, 3))
            frames["wall_centroid"].append(np.array(
                [np.mean([np.array([vector(values[i].get("coord")),
                                    _rows([values[i]], "quaternion", (4,))[0, :3],
                                    vector(values[i].get("angle_vel"))]).mean(axis=0)
                          for i in ids], axis=0) for _, ids, _ in groups]).reshape(-1, 3))
            translational, rotational = sim.kinetic_energy()
            energy = dict.fromkeys(names, np.nan)
            energy.update(kinetic_translational=translational, kinetic_rotational=rotational)
            writer.append(sim, energy)
    with h5py.File(results, "r+") as f:
        f["bonds/force"][...] = np.array(frames["bond_force"]).reshape(f["bonds/force"].shape)
        for name in ("bonds/normal_moment", "bonds/tangential_moment"):
            f[name][...] = np.nan
        if groups:
            centroid = np.array(frames["wall_centroid"])
            f["walls/force"][...] = np.array(frames["wall_force"])
            f["walls/position"][...] = f["walls/position"][0] + centroid - centroid[0]
            f["walls/torque"][...] = np.nan
        f["musen/bond_tangential_overlap"] = np.array(frames["overlap"]).reshape(
            -1, len(bonds), 3)
        f["musen/bond_tangential_overlap"].attrs["unit"] = "m"
        f["musen/bond_total_torque"] = np.array(frames["torque"]).reshape(-1, len(bonds))
        f["musen/bond_total_torque"].attrs["unit"] = "N m"
        f.attrs["source"] = f"MUSEN .mdem (format {mdem.version}): {Path(path).name}"
        f.attrs["musen_version"] = musen_version or musen_release(mdem)
    if len(bonds):
        notes.append("bond moments are not in a .mdem file (NaN); break modes inferred "
                     "from each bond's last saved force")
    return results, notes


# MUSEN's defaults for what a bondem scene does not set (a compound and an interaction as
# MUSEN's text import makes them: property id -> value at 273.15 K, 101325 Pa)
COMPOUND_DEFAULTS = {0: 1000.0, 1: 1000.0, 2: 0.1, 3: 0.5, 4: 0.0, 5: 1000.0,
                     6: 2260000.0, 7: 1e9, 8: 1e7, 9: 1e7, 10: 0.2, 11: 1.0, 12: 2e-05,
                     13: 0.7, 14: 1.7e-05, 15: 2e10}
INTERACTION_DEFAULTS = {200: 0.6, 201: 0.45, 202: 0.05, 203: 45.0, 204: 2e-09}
BLOCK_LIMIT = 64 << 20     # uncompressed bytes of time points per block
CLUSTER = 4096


def _vec(values):
    return {"x": float(values[0]), "y": float(values[1]), "z": float(values[2])}


def _property(kind, value):
    """A constant MUSEN property valid from 0 to 500 K and 0 to 1 MPa."""
    return {"propertyType": kind, "correlation": [{"t2": 500.0, "p2": 1e6,
                                                   "parameter": [float(value)]}]}


def _properties(words):
    return {int(float(words[k])): float(words[k + 1]) for k in range(3, len(words) - 1, 2)}


def mdem_storage(lines, keys):
    """(ProtoSimulationStorage dict without its blocks, [(time, [per-object dicts])]) of
    MUSEN text lines and cmusen SIMULATOR keys ({KEY: text})."""
    from .musen_text import read_series
    objects, scene = read_series(lines)
    count = max(objects) + 1 if objects else 0
    times = sorted({t for o in objects.values() for t, _ in o[4]})
    frames = [[{} for _ in range(count)] for _ in times]
    particles = []
    for ident in range(count):
        kind, geometry, compound, activity, points = objects[ident]
        if kind == SPHERE:
            encoded = struct.pack("<2d", *geometry)
        elif kind == SOLID_BOND:
            encoded = struct.pack("<2I2d", int(geometry[0]), int(geometry[1]), *geometry[2:])
        else:
            encoded = b""
        particles.append({"id": ident, "type": kind, "compound": compound,
                          "encoded_properties": encoded, "activity_start": activity[0],
                          "activity_end": activity[1]})
        by_time = dict(points)
        last = points[0][1] if points else {}
        for frame, t in zip(frames, times):
            values = by_time.get(t, last if kind == TRIANGULAR_WALL else {})
            record = {}
            if 12 in values:
                record["coord"] = _vec(values[12])
            if 15 in values:
                record["vel"] = _vec(values[15])
            if 16 in values:
                record["angle_vel"] = _vec(values[16])
            if kind == SPHERE:
                record["quaternion"] = {"q1": 1.0}   # MUSEN's orientation of a new sphere
            elif 31 in values:
                record["quaternion"] = dict(zip(("q0", "q1", "q2", "q3"), values[31]))
            frame[ident] = record
    info = {"version": 1, "particles": particles, "savedTimePoints": times,
            "end_time": times[-1] if times else 0.0}
    compounds, interactions, geometries = [], [], []
    for words in scene:
        command = int(words[0])
        if command == 22:
            box = [float(w) for w in words[1:7]]
            info["simulation_volume_min"], info["simulation_volume_max"] = \
                _vec(box[:3]), _vec(box[3:])
        elif command == 28:
            values = [float(w) for w in words[1:11]]
            info.update(periodic_conditions_enabled=bool(values[0]),
                        periodic_conditions_x=bool(values[1]),
                        periodic_conditions_y=bool(values[2]),
                        periodic_conditions_z=bool(values[3]),
                        periodic_conditions_min=_vec(values[4:7]),
                        periodic_conditions_max=_vec(values[7:10]))
        elif command == 32:
            props = {**COMPOUND_DEFAULTS, **_properties(words)}
            compounds.append({"compoundName": words[2], "uniqueKey": words[1],
                              "authorName": "bondem", "phase": 2,
                              "property": [_property(k, v) for k, v in sorted(props.items())]})
        elif command == 33:
            props = {**INTERACTION_DEFAULTS, **_properties(words)}
            interactions.append({"compoundKey1": words[1], "compoundKey2": words[2],
                                 "property": [_property(k, v)
                                              for k, v in sorted(props.items())]})
        elif command == 25:
            geometries.append({"version": 1, "base_geometry": {
                "version": 1, "name": words[1], "key": words[2], "scaling": 1.0,
                "rotation": {"v1": {"x": 1.0}, "v2": {"y": 1.0}, "v3": {"z": 1.0}},
                "motion": {"type": 0}}})
        elif command == 26 and geometries:
            values = [float(w) for w in words[1:]]
            geometries[-1]["base_geometry"]["motion"] = {"type": int(values[0]), "intervals": [
                {"limit1": values[2 + 11 * k], "limit2": values[3 + 11 * k],
                 "velocity": _vec(values[4 + 11 * k:7 + 11 * k]),
                 "rot_center": _vec(values[7 + 11 * k:10 + 11 * k]),
                 "rot_velocity": _vec(values[10 + 11 * k:13 + 11 * k])}
                for k in range(int(values[1]))]}
        elif command == 27 and geometries:
            geometries[-1]["planes"] = [int(w) for w in words[2:2 + int(words[1])]]
    # MUSEN needs an interaction for every pair of compounds (its text import adds the
    # missing ones with its defaults; a simulation of a .mdem file without them crashes)
    keys_given = [c["uniqueKey"] for c in compounds]
    have = {tuple(sorted((i["compoundKey1"], i["compoundKey2"]))) for i in interactions}
    for a in range(len(keys_given)):
        for b in range(a, len(keys_given)):
            pair = tuple(sorted((keys_given[a], keys_given[b])))
            if pair not in have:
                interactions.append({"compoundKey1": pair[0], "compoundKey2": pair[1],
                                     "property": [_property(k, v) for k, v in
                                                  sorted(INTERACTION_DEFAULTS.items())]})
    info["real_geometry"] = geometries
    accel = [float(w) for w in keys.get("EXT_ACCEL", "0 0 0").split()]
    simulator = {"end_time": float(keys.get("END_TIME", info["end_time"])),
                 "simulation_step": float(keys.get("SIMULATION_STEP", 1e-7)),
                 "saving_step": float(keys.get("SAVING_STEP", keys.get("END_TIME", 1e-3))),
                 "external_acceleration": _vec(accel), "simulator_type": 1,
                 "max_cells_number": 50, "verlet_dist_coeff": 2.0,
                 "verlet_auto_adjust": True, "part_move_limit": 1e-8,
                 "time_step_factor": 1.01}
    models = []
    for kind in ("MODEL_SB", "MODEL_PP", "MODEL_PW"):
        if kind in keys:
            models.append({"key": keys[kind], "path": keys[kind],
                           "params": keys.get(kind + "_PARAMS", "")})
    old = {"MODEL_SB": "sb_model", "MODEL_PP": "pp_model", "MODEL_PW": "pw_model"}
    manager = {"version": 1, "models": models,
               "connected_pp_contact": keys.get("CONNECTED_PP_CONTACT", "1") != "0",
               **{old[k]: {"key": keys[k], "path": keys[k],
                           "params": keys.get(k + "_PARAMS", "")} for k in old if k in keys}}
    storage = {"info": info, "modules_data": {
        "simulator": simulator, "model_manager": manager,
        "materials_database": {"compound": compounds, "interaction": interactions}}}
    return storage, list(zip(times, frames))


def write_mdem(path, storage, time_points):
    """Write a .mdem file (format 2) of ``storage`` (a ProtoSimulationStorage dict without
    its data blocks) and ``time_points`` [(time, [per-object dicts])]: the time points
    zlib-compressed in blocks of at most BLOCK_LIMIT bytes, the blocks of each thread laid
    out in MUSEN's sizes (``block_size``)."""
    blocks, data, descriptors = [], [], []
    current, size = [], 0
    for t, objects in time_points:
        point = encode({"time": t, "particles": objects}, "ProtoTimePoint", TABLES)
        if current and size + len(point) > BLOCK_LIMIT:
            blocks.append(current)
            current, size = [], 0
        current.append((t, point))
        size += len(point)
    if current or not blocks:
        blocks.append(current)
    offset = 0
    for block in blocks:
        body = b"".join(b"\x12" + varint(len(p)) + p for _, p in block)
        packed = zlib.compress(body, 1)
        descriptors.append({"start_time": block[0][0] if block else 0.0,
                            "offset_in_file": offset, "size": len(packed),
                            "uncompressed_size": len(body), "format": 2})
        data.append(packed)
        offset += len(packed)
    storage = dict(storage, data_blocks=descriptors)
    threads = [zlib.compress(encode(storage, "ProtoSimulationStorage", TABLES), 1),
               b"".join(data)]
    layout, at = [], HEADER + 2 * THREAD_HEADER
    chunks = []
    for stream in threads:
        offsets, k, start = [], 0, 0
        while start < len(stream) or k == 0:
            length = block_size(k, CLUSTER)
            offsets.append(at)
            chunks.append(stream[start:start + length].ljust(length, b"\0"))
            at += length
            start += length
            k += 1
        if k > BLOCKS_PER_THREAD:
            raise ValueError("too much data for a .mdem file's 118 blocks")
        layout.append((len(stream), offsets))
    header = struct.pack("<4I", SIGNATURE, FORMAT_VERSION, 2, CLUSTER).ljust(HEADER, b"\0")
    heads = b""
    for name, (size, offsets) in zip(("simulation info", "time-dependent"), layout):
        heads += (name.encode().ljust(64, b"\0") + struct.pack("<2Q", size, 0)
                  + struct.pack(f"<{BLOCKS_PER_THREAD}Q",
                                *offsets, *[0] * (BLOCKS_PER_THREAD - len(offsets))))
    Path(path).write_bytes(header + heads + b"".join(chunks))


def export_mdem(results_path, out_file, every=1):
    """``bondem export musen RESULTS --out FILE.mdem``: a results file as a MUSEN .mdem
    file (what ``export_musen`` writes as text: compounds, interactions, domain, spheres
    with every frame's coordinates, velocities and angular velocities, solid bonds with
    their activity intervals, walls as triangles at t = 0, static) with the scene's models
    and time stepping in its simulator settings, and a cmusen script beside it that runs
    it (FILE_script.txt). Returns (file, script, notes)."""
    import tomllib
    from .musen_text import export_lines, simulator_keys
    from .results import read_results
    data = read_results(results_path)
    scene = tomllib.loads(str(data["attrs"]["scene"]))
    keys, notes = simulator_keys(scene, float(data["attrs"]["time_step"]))
    storage, points = mdem_storage(export_lines(data, scene, every), keys)
    clump_of = data.get("particles/clump")
    if clump_of is not None:
        # the clumps as MUSEN's multispheres: the ids of their spheres (a sphere's id is
        # its particle index, export_lines'); MUSEN 1.74.2 keeps them but moves the
        # spheres as free particles
        clump_of = np.asarray(clump_of)
        storage["info"]["multispheres"] = [
            {"id": np.flatnonzero(clump_of == c).tolist()}
            for c in range(int(clump_of.max()) + 1)]
        notes.append(f"{int(clump_of.max()) + 1} clumps written as multispheres (MUSEN "
                     "1.74.2's simulator moves their spheres as free particles)")
    out_file = Path(out_file)
    out_file.parent.mkdir(parents=True, exist_ok=True)
    write_mdem(out_file, storage, points)
    script = out_file.with_name(out_file.stem + "_script.txt")
    script.write_text("\n".join(["JOB", "COMPONENT SIMULATOR", f"SOURCE_FILE ./{out_file.name}",
                                 f"RESULT_FILE ./{out_file.stem}_result.mdem",
                                 *(f"{k} {v}" for k, v in keys.items())]) + "\n")
    return out_file, script, notes

"""Particle and bond CSV files (SPEC 4).

particles.csv: header ``x,y,z,radius,material`` (m, m, m, m, material name), optionally
followed by ``vx,vy,vz`` (m/s), ``wx,wy,wz`` (rad/s) and ``fixed`` (0 or 1: 1 keeps the
particle's velocities as given, e.g. zero for a clamp). bonds.csv: header
``i,j,diameter,material`` with i, j 0-based rows of particles.csv, diameter in m and the
bond material's name. Columns may come in any order; names are case-sensitive. Errors
raise ``InputError`` naming the file, the line and the column.
"""
from __future__ import annotations

import csv
import io
import math

from pathlib import Path

import numpy as np

from ..errors import InputError, decode_text, unknown_key

PARTICLE_COLUMNS = ("x", "y", "z", "radius", "material")
VELOCITY_COLUMNS = ("vx", "vy", "vz")
ANGULAR_COLUMNS = ("wx", "wy", "wz")
FIXED_COLUMNS = ("fixed",)
CLUMP_COLUMNS = ("clump",)
BOND_COLUMNS = ("i", "j", "diameter", "material")



def float_text(x):
    """A float as the shortest text that reads back to the same double (``repr`` of a
    Python float: a NumPy scalar's repr is ``np.float64(...)`` from NumPy 2 on)."""
    return repr(float(x))

def _read(path, required, optional_groups, kinds):
    """Rows of a CSV file as dict of columns; kinds: column -> 'float' | 'positive' |
    'index' | 'name'."""
    try:
        raw = Path(path).read_bytes()
    except OSError as error:
        raise InputError(f"cannot open: {error.strerror}", file=str(path)) from None
    with io.StringIO(decode_text(raw, str(path)), newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader, None)
        if header is None:
            raise InputError("empty file; expected a header line "
                             + ",".join(required), file=str(path))
        header = [h.strip() for h in header]
        allowed = set(required).union(*optional_groups)
        for name in header:
            if name not in allowed:
                raise InputError("line 1: " + unknown_key(name, sorted(allowed), "column"),
                                 file=str(path), key=name)
        repeated = [name for k, name in enumerate(header) if name in header[:k]]
        if repeated:
            raise InputError(f"line 1: the column {repeated[0]!r} appears "
                             f"{header.count(repeated[0])} times; give each column once",
                             file=str(path), key=repeated[0])
        for name in required:
            if name not in header:
                raise InputError(f"line 1: missing column {name!r}; the header must name "
                                 + ",".join(required), file=str(path), key=name)
        for group in optional_groups:
            present = [g for g in group if g in header]
            if present and len(present) != len(group):
                raise InputError(f"line 1: columns {','.join(group)} come together; found "
                                 f"only {','.join(present)}", file=str(path))
        columns = {name: [] for name in header}
        lines = []
        for row in reader:
            line = reader.line_num
            if not row or all(not cell.strip() for cell in row):
                continue
            lines.append(line)
            if len(row) != len(header):
                raise InputError(f"line {line}: {len(row)} values, the header has "
                                 f"{len(header)}", file=str(path))
            for name, cell in zip(header, row):
                columns[name].append(_cell(cell.strip(), kinds[name], path, line, name))
    out = {}
    for name, values in columns.items():
        if kinds[name] == "name":
            out[name] = np.array(values, dtype=object)
        elif kinds[name] in ("index", "clump"):
            out[name] = np.array(values, dtype=np.int64)
        elif kinds[name] == "flag":
            out[name] = np.array(values, dtype=np.bool_)
        else:
            out[name] = np.array(values, dtype=np.float64)
    out["line"] = np.array(lines, dtype=np.int64)   # the file's line of each row
    return out


def _cell(text, kind, path, line, column):
    if kind == "name":
        if not text:
            raise InputError(f"line {line}: empty material name", file=str(path), key=column)
        return text
    if kind == "flag":
        if text not in ("0", "1"):
            raise InputError(f"line {line}: {text!r}; allowed: 0 or 1", file=str(path),
                             key=column)
        return int(text)
    if kind == "clump":
        # a clump index, -1 (or empty) for a free sphere
        if not text:
            return -1
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not -1 <= value < 2 ** 62:
            raise InputError(f"line {line}: {text!r}; allowed: a clump index >= 0, or -1 "
                             "(or empty) for a free sphere", file=str(path), key=column)
        return value
    if kind == "index":
        try:
            value = int(text)
        except ValueError:
            raise InputError(f"line {line}: {text!r} is not an integer index >= 0",
                             file=str(path), key=column) from None
        if not 0 <= value < 2 ** 62:
            shown = text if len(text) <= 20 else text[:20] + "..."
            raise InputError(f"line {line}: {shown} is not an integer index in [0, 2^62)",
                             file=str(path), key=column)
        return value
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"line {line}: {text!r} is not a number", file=str(path),
                         key=column) from None
    if not math.isfinite(value) or (kind == "positive" and value <= 0):
        allowed = "a finite number > 0" if kind == "positive" else "a finite number"
        raise InputError(f"line {line}: {text!r}; allowed: {allowed}", file=str(path),
                         key=column)
    return value


def read_particles(path):
    """Read particles.csv. Returns a dict of arrays: x, y, z, radius (m), material (names,
    object array), and vx, vy, vz (m/s), wx, wy, wz (rad/s), fixed (bool), clump (int64:
    the particle's clump, -1 for a free sphere) when present."""
    kinds = {name: "float" for name in ("x", "y", "z") + VELOCITY_COLUMNS + ANGULAR_COLUMNS}
    kinds.update(radius="positive", material="name", fixed="flag", clump="clump")
    data = _read(path, PARTICLE_COLUMNS, (VELOCITY_COLUMNS, ANGULAR_COLUMNS, FIXED_COLUMNS,
                                          CLUMP_COLUMNS), kinds)
    if data["x"].size == 0:
        raise InputError("no particle rows", file=str(path))
    return data


def read_bonds(path, n_particles=None):
    """Read bonds.csv. Returns a dict of arrays: i, j (int64), diameter (m), material
    (names). With ``n_particles`` the indices are checked against it, and i != j."""
    kinds = {"i": "index", "j": "index", "diameter": "positive", "material": "name"}
    data = _read(path, BOND_COLUMNS, (), kinds)
    same = np.flatnonzero(data["i"] == data["j"])
    if same.size:
        raise InputError(f"line {data['line'][same[0]]}: i = j = {data['i'][same[0]]}",
                         file=str(path), key="j")
    if n_particles is not None:
        for column in ("i", "j"):
            bad = np.flatnonzero(data[column] >= n_particles)
            if bad.size:
                raise InputError(f"line {data['line'][bad[0]]}: index {data[column][bad[0]]} "
                                 f"is outside "
                                 f"[0, {n_particles - 1}] (rows of the particle file)",
                                 file=str(path), key=column)
    return data



def write_particles(path, position, radius, material_names, velocity=None,
                    angular_velocity=None, clump=None):
    """Write particles.csv: position (N,3) m, radius (N,) m or one for all,
    material_names (N,) or one name; velocity (N,3) m/s and angular_velocity (N,3) rad/s
    optional (a given angular velocity without velocity writes zero velocities, as the
    columns come in order); clump (N,) int optional: each particle's clump, -1 for a free
    sphere."""
    position = np.asarray(position, dtype=np.float64).reshape(-1, 3)
    n = position.shape[0]
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (n,))
    names = np.broadcast_to(np.asarray(material_names, dtype=object), (n,))
    columns = [position[:, 0], position[:, 1], position[:, 2], radius]
    header = list(PARTICLE_COLUMNS)
    if velocity is not None or angular_velocity is not None:
        v = np.zeros((n, 3)) if velocity is None else np.asarray(velocity, float).reshape(n, 3)
        columns += [v[:, 0], v[:, 1], v[:, 2]]
        header += VELOCITY_COLUMNS
    if angular_velocity is not None:
        w = np.asarray(angular_velocity, float).reshape(n, 3)
        columns += [w[:, 0], w[:, 1], w[:, 2]]
        header += ANGULAR_COLUMNS
    # repr() of a float round-trips exactly
    numbers = [list(map(repr, c.tolist())) for c in columns]
    if clump is not None:
        numbers.append([str(int(c)) for c in np.asarray(clump).reshape(n)])
        header += CLUMP_COLUMNS
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(header)
        for k in range(n):
            row = [numbers[0][k], numbers[1][k], numbers[2][k], numbers[3][k], names[k]]
            row += [c[k] for c in numbers[4:]]
            writer.writerow(row)


def write_bonds(path, pairs, diameter, material_names):
    """Write bonds.csv: pairs (B,2) particle rows, diameter (B,) m or one for all,
    material_names (B,) or one name."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    b = pairs.shape[0]
    diameter = np.broadcast_to(np.asarray(diameter, dtype=np.float64), (b,))
    names = np.broadcast_to(np.asarray(material_names, dtype=object), (b,))
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(BOND_COLUMNS)
        writer.writerows(zip(pairs[:, 0].tolist(), pairs[:, 1].tolist(),
                             map(repr, diameter.tolist()), names))

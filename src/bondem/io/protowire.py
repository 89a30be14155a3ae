"""The protobuf wire format (protobuf.dev/programming-guides/encoding), read and written
against message tables of our own: {field number: (name, kind, repeated)}, kind one of
"double", "float", "varint", "sint" (zigzag), "bool", "string", "bytes" or the name of
another message in the same table set.

This is the whole of the format that MUSEN's files use (proto3, packed repeated scalars,
no groups, no maps); it lets bondem read and write .mdem files without MUSEN's generated
code or a compiled schema. A malformed buffer raises ``WireError``.
"""
from __future__ import annotations

import struct

VARINT, FIXED64, LENGTH, FIXED32 = 0, 1, 2, 5
_SCALAR_WIRE = {"double": FIXED64, "float": FIXED32, "varint": VARINT, "sint": VARINT,
                "bool": VARINT}
_D = struct.Struct("<d")
_F = struct.Struct("<f")
_VECTOR = struct.Struct("<xdxdxd")


class WireError(ValueError):
    """A buffer that is not a valid message of the table it is read against."""


def _varint(buf, k):
    value = shift = 0
    while True:
        if k >= len(buf):
            raise WireError("truncated varint")
        byte = buf[k]
        k += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, k
        shift += 7
        if shift > 63:
            raise WireError("varint longer than 10 bytes")


def _scalar(kind, wire, buf, k):
    """(value, next offset) of one scalar of ``kind`` sent with wire type ``wire``."""
    if kind == "double" and wire == FIXED64:
        if k + 8 > len(buf):
            raise WireError("truncated double")
        return _D.unpack_from(buf, k)[0], k + 8
    if kind == "float" and wire == FIXED32:
        if k + 4 > len(buf):
            raise WireError("truncated float")
        return _F.unpack_from(buf, k)[0], k + 4
    if kind in ("varint", "sint", "bool") and wire == VARINT:
        value, k = _varint(buf, k)
        if kind == "sint":
            value = (value >> 1) ^ -(value & 1)
        elif kind == "bool":
            value = bool(value)
        return value, k
    raise WireError(f"wire type {wire} for a field of kind {kind}")


def _skip(wire, buf, k):
    if wire == VARINT:
        return _varint(buf, k)[1]
    if wire == FIXED64:
        return k + 8
    if wire == FIXED32:
        return k + 4
    if wire == LENGTH:
        size, k = _varint(buf, k)
        return k + size
    raise WireError(f"unsupported wire type {wire}")


_VECTORS = {}


def _vector_names(kind, tables):
    """The field names of message ``kind`` if it is three doubles numbered 1, 2, 3 (read
    in one unpack), else None."""
    key = (id(tables), kind)
    if key not in _VECTORS:
        table = tables.get(kind)
        _VECTORS[key] = (tuple(table[f][0] for f in (1, 2, 3))
                         if table is not None and sorted(table) == [1, 2, 3]
                         and all(table[f][1:] == ("double", False) for f in (1, 2, 3))
                         else None)
    return _VECTORS[key]


def decode(buf, message, tables):
    """The message ``message`` of ``tables`` in ``buf`` (bytes) as a dict {field name:
    value}; repeated fields are lists, absent ones are absent, unknown fields are skipped.
    Nested messages are dicts."""
    table = tables[message]
    out = {}
    k, end = 0, len(buf)
    while k < end:
        key, k = _varint(buf, k)
        number, wire = key >> 3, key & 7
        spec = table.get(number)
        if spec is None:
            k = _skip(wire, buf, k)
            if k > end:
                raise WireError(f"field {number} runs past the end of {message}")
            continue
        name, kind, repeated = spec
        if wire == LENGTH:
            size, k = _varint(buf, k)
            if k + size > end:
                raise WireError(f"field {name} of {message} runs past its end")
            chunk = buf[k:k + size]
            k += size
            names = _vector_names(kind, tables) if size == 27 else None
            if names and chunk[0] == 0x09 and chunk[9] == 0x11 and chunk[18] == 0x19:
                # three doubles as fields 1, 2, 3 (a vector, MUSEN's commonest message)
                value = dict(zip(names, _VECTOR.unpack(chunk)))
            elif kind in tables:
                value = decode(chunk, kind, tables)
            elif kind == "string":
                try:
                    value = bytes(chunk).decode("utf-8")
                except UnicodeDecodeError:
                    raise WireError(f"field {name} of {message} is not UTF-8") from None
            elif kind == "bytes":
                value = bytes(chunk)
            elif repeated:     # packed scalars
                values, j = [], 0
                while j < size:
                    item, j = _scalar(kind, _SCALAR_WIRE[kind], chunk, j)
                    values.append(item)
                out.setdefault(name, []).extend(values)
                continue
            else:
                raise WireError(f"field {name} of {message}: length-delimited {kind}")
        else:
            if kind in tables or kind in ("string", "bytes"):
                raise WireError(f"field {name} of {message}: wire type {wire} for a {kind}")
            value, k = _scalar(kind, wire, buf, k)
        if repeated:
            out.setdefault(name, []).append(value)
        else:
            out[name] = value
    if k != end:
        raise WireError(f"{message} runs past its end")
    return out


def varint(value):
    """The bytes of ``value`` as a varint (negative values as 64-bit two's complement)."""
    value &= (1 << 64) - 1
    out = bytearray()
    while value >= 0x80:
        out.append(value & 0x7F | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def _put_varint(parts, value):
    parts.append(varint(value))


def encode(data, message, tables):
    """``data`` (a dict as ``decode`` returns) as the bytes of message ``message``, fields
    in number order, proto3 defaults (0, "", False, empty) left out."""
    parts = []
    for number, (name, kind, repeated) in sorted(tables[message].items()):
        if name not in data:
            continue
        value = data[name]
        values = value if repeated else [value]
        if kind in tables or kind in ("string", "bytes"):
            for item in values:
                if kind in tables:
                    body = encode(item, kind, tables)
                elif kind == "string":
                    body = item.encode("utf-8")
                else:
                    body = bytes(item)
                if not repeated and not body and kind not in tables:
                    continue
                _put_varint(parts, number << 3 | LENGTH)
                _put_varint(parts, len(body))
                parts.append(body)
            continue
        if repeated:
            if not values:
                continue
            body = []
            for item in values:
                _put_scalar(body, kind, item)
            body = b"".join(body)
            _put_varint(parts, number << 3 | LENGTH)
            _put_varint(parts, len(body))
            parts.append(body)
            continue
        if not value:
            continue
        _put_varint(parts, number << 3 | _SCALAR_WIRE[kind])
        _put_scalar(parts, kind, value)
    return b"".join(parts)


def _put_scalar(parts, kind, value):
    if kind == "double":
        parts.append(_D.pack(value))
    elif kind == "float":
        parts.append(_F.pack(value))
    elif kind == "sint":
        _put_varint(parts, (value << 1) ^ (value >> 63))
    else:
        _put_varint(parts, int(value))

"""The protobuf wire codec of io/protowire.py against the format's definition
(protobuf.dev/programming-guides/encoding): bytes worked out by hand from the spec, round
trips, unknown fields, damaged buffers."""
import struct

import numpy as np

import pytest

from bondem.io.protowire import WireError, decode, encode

TABLES = {
    "Vec": {1: ("x", "double", False), 2: ("y", "double", False), 3: ("z", "double", False)},
    "Msg": {1: ("count", "varint", False), 2: ("name", "string", False),
            3: ("values", "double", True), 4: ("at", "Vec", False),
            5: ("items", "Vec", True), 6: ("delta", "sint", False),
            7: ("flag", "bool", False), 8: ("blob", "bytes", False),
            9: ("ids", "varint", True), 10: ("ratio", "float", False)},
}


def test_bytes_of_the_specs_examples():
    # the spec's first example: field 1 = 150 is 08 96 01
    assert encode({"count": 150}, "Msg", TABLES) == bytes([0x08, 0x96, 0x01])
    assert decode(bytes([0x08, 0x96, 0x01]), "Msg", TABLES) == {"count": 150}
    # a string: tag 0x12, length, UTF-8 ("testing": the spec's example)
    assert encode({"name": "testing"}, "Msg", TABLES) == b"\x12\x07testing"
    # zigzag: -1 -> 1, 1 -> 2, -2 -> 3
    assert encode({"delta": -1}, "Msg", TABLES) == bytes([0x30, 0x01])
    assert encode({"delta": -2}, "Msg", TABLES) == bytes([0x30, 0x03])
    # packed doubles: one length-delimited field of 8-byte little-endian values
    assert encode({"values": [1.5, -2.0]}, "Msg", TABLES) == (
        bytes([0x1A, 0x10]) + struct.pack("<2d", 1.5, -2.0))
    # proto3 leaves defaults out
    assert encode({"count": 0, "name": "", "flag": False, "values": []}, "Msg", TABLES) == b""


def test_round_trip_of_every_kind():
    data = {"count": 2 ** 40 + 3, "name": "plane µ", "values": [0.1, 1e300, -3.5],
            "at": {"x": 1.0, "y": -2.0, "z": 3.25}, "items": [{"x": 1.0}, {"y": 2.0, "z": 0.5}],
            "delta": -123456789, "flag": True, "blob": b"\x00\xff\x10",
            "ids": [1, 300, 2 ** 33], "ratio": 0.5}
    assert decode(encode(data, "Msg", TABLES), "Msg", TABLES) == data


def test_unpacked_repeated_and_unknown_fields_are_read():
    # ids sent unpacked (one tag per value) as older writers do, then an unknown field 15
    # of every wire type, which is skipped
    buf = (bytes([0x48, 0x05, 0x48, 0x07]) + bytes([0x78, 0x01])
           + bytes([0x79]) + bytes(8) + bytes([0x7A, 0x02, 0xAA, 0xBB])
           + bytes([0x7D]) + bytes(4))
    assert decode(buf, "Msg", TABLES) == {"ids": [5, 7]}


@pytest.mark.parametrize("buf", [
    bytes([0x08]),                          # a varint without its bytes
    bytes([0x08, 0x96]),                    # a varint cut short
    bytes([0x12, 0x05, 0x61]),              # a string longer than the buffer
    bytes([0x22, 0x09, 0x09]) + bytes(2),   # a vector cut inside a double
    bytes([0x12, 0x02, 0xC3, 0x28]),        # a string that is not UTF-8
    bytes([0x0B]),                          # wire type 3 (groups) is not in the format
    bytes([0x08 | 0x01]) + bytes(8),        # field 1 (a varint) sent as 64 bits
    bytes([0x08]) + bytes([0xFF] * 11),     # a varint of 11 bytes
])
def test_damaged_buffers_raise_wire_errors(buf):
    with pytest.raises(WireError):
        decode(buf, "Msg", TABLES)


@pytest.fixture
def fresh_vectors(monkeypatch):
    """A fresh cache of which messages are plain vectors (it outlives a test otherwise)."""
    from bondem.io import protowire
    monkeypatch.setattr(protowire, "_VECTORS", {})
    return protowire


def test_varints_at_their_edges():
    # 127 fits in one byte, 128 needs two (80 01), 300 is the spec's AC 02
    assert encode({"count": 127}, "Msg", TABLES) == bytes([0x08, 0x7F])
    assert encode({"count": 128}, "Msg", TABLES) == bytes([0x08, 0x80, 0x01])
    assert encode({"count": 300}, "Msg", TABLES) == bytes([0x08, 0xAC, 0x02])
    # a negative int64 is ten bytes of two's complement (the spec's -1)
    assert encode({"count": -1}, "Msg", TABLES) == bytes([0x08] + [0xFF] * 9 + [0x01])
    # the largest uint64 is ten bytes and reads back
    top = 2 ** 64 - 1
    assert decode(encode({"count": top}, "Msg", TABLES), "Msg", TABLES) == {"count": top}
    # zigzag at the int64 edges
    for value in (-2 ** 63, 2 ** 63 - 1, -123):
        assert decode(encode({"delta": value}, "Msg", TABLES), "Msg", TABLES) == {"delta": value}
    assert decode(bytes([0x38, 0x01]), "Msg", TABLES)["flag"] is True


def test_defaults_left_out_do_not_stop_the_fields_after_them():
    assert encode({"count": 0, "name": "x"}, "Msg", TABLES) == b"\x12\x01x"
    assert encode({"name": "", "blob": b"\x01"}, "Msg", TABLES) == b"\x42\x01\x01"
    # a float and the field after it
    buf = bytes([0x55]) + struct.pack("<f", 0.5) + bytes([0x08, 0x03])
    assert decode(buf, "Msg", TABLES) == {"ratio": 0.5, "count": 3}
    assert encode({"name": "", "values": [2.0]}, "Msg", TABLES) == (
        bytes([0x1A, 0x08]) + struct.pack("<d", 2.0))
    assert encode({"values": [], "at": {"x": 0.0, "z": 1.0}}, "Msg", TABLES) == (
        bytes([0x22, 0x09, 0x19]) + struct.pack("<d", 1.0))
    assert decode(b"\x12\x07testing", "Msg", TABLES) == {"name": "testing"}


def test_unknown_fields_of_each_wire_type_are_skipped_exactly():
    # an unknown 32-bit field, then an unknown length-delimited one whose payload looks
    # like fields, each followed by a known field that must read right
    buf = (bytes([0x7D, 0x08, 0x09, 0x0A, 0x0B]) + bytes([0x08, 0x07])
           + bytes([0x7A, 0x03, 0x08, 0x09, 0x0A]) + bytes([0x30, 0x03]))
    assert decode(buf, "Msg", TABLES) == {"count": 7, "delta": -2}


@pytest.mark.parametrize("buf, message", [
    (bytes([0x19]) + bytes(4), "truncated double"),          # an unpacked double cut short
    (bytes([0x55]) + bytes(2), "truncated float"),           # field 10, a float cut short
    (bytes([0x08, 0x96]), "truncated varint"),
    (bytes([0x08]) + bytes([0xFF] * 11), "varint longer than 10 bytes"),
    (bytes([0x0D]) + bytes(4), "wire type 5 for a field of kind varint"),
    (bytes([0x50, 0x01]), "wire type 0 for a field of kind float"),
    (bytes([0x12, 0x05, 0x61]), "field name of Msg runs past its end"),
    (bytes([0x12, 0x02, 0xC3, 0x28]), "field name of Msg is not UTF-8"),
    (bytes([0x11]) + bytes(8), "field name of Msg: wire type 1 for a string"),
    (bytes([0x52, 0x01, 0x00]), "field ratio of Msg: length-delimited float"),
    (bytes([0x7B]), "unsupported wire type 3"),
    (bytes([0x79]) + bytes(4), "field 15 runs past the end of Msg"),
    (bytes([0x40, 0x01]), "field blob of Msg: wire type 0 for a bytes"),
])
def test_damaged_buffers_say_what_is_wrong(buf, message):
    with pytest.raises(WireError, match=f"^{message}$"):
        decode(buf, "Msg", TABLES)


def test_the_vector_shortcut_reads_as_the_rules_do(fresh_vectors, monkeypatch):
    """27-byte vectors are read in one unpack when their tags are x, y, z in order: every
    other 27-byte arrangement (repeated fields, other orders, other wire types) must read
    as the general rules read it, or fail as they fail."""
    rng = np.random.default_rng(11)
    tags = [0x09, 0x11, 0x19, 0x0A, 0x0D, 0x21]
    cases = [bytes([t0]) + rng.bytes(8) + bytes([t1]) + rng.bytes(8) + bytes([t2])
             + rng.bytes(8) for t0 in tags for t1 in tags for t2 in tags]

    def read(payload):
        try:
            return decode(bytes([0x22, 27]) + payload, "Msg", TABLES)
        except WireError:
            return "error"

    fast = [read(c) for c in cases]
    monkeypatch.setattr(fresh_vectors, "_vector_names", lambda kind, tables: None)
    slow = [read(c) for c in cases]
    assert any(f != "error" and "at" in f and len(f["at"]) == 3 for f in fast)
    for f, s, c in zip(fast, slow, cases):
        assert repr(f) == repr(s), c.hex()



def test_only_three_doubles_numbered_1_2_3_are_a_vector(fresh_vectors):
    tables = {"V": {1: ("a", "double", False), 2: ("b", "double", False),
                    3: ("c", "double", False)},
              "W": {1: ("a", "double", False), 2: ("b", "float", False),
                    3: ("c", "double", False)},
              "R": {1: ("a", "double", True), 2: ("b", "double", False),
                    3: ("c", "double", False)},
              "F": {1: ("a", "double", False), 2: ("b", "double", False),
                    4: ("c", "double", False)}}
    assert fresh_vectors._vector_names("V", tables) == ("a", "b", "c")
    for kind in ("W", "R", "F", "missing"):
        assert fresh_vectors._vector_names(kind, tables) is None
    # the same name in another set of tables is judged there
    assert fresh_vectors._vector_names("V", {"V": tables["W"]}) is None

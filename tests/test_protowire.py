"""The protobuf wire codec of io/protowire.py against the format's definition
(protobuf.dev/programming-guides/encoding): bytes worked out by hand from the spec, round
trips, unknown fields, damaged buffers."""
import struct

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

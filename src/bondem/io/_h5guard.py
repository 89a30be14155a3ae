"""Keep a results file openable by any HDF5 reader when its writer is killed.

An HDF5 writer marks the file "open for write" in its superblock (version 3, the one SWMR
needs) and clears the mark when it closes. SIGKILL gives it no chance: HDF5 then refuses
plain readers ("may use h5clear") although the file is consistent, since SWMR writes
metadata in an order that keeps it so. ``clear_open_flags`` does what ``h5clear -s``
does. Run as a script it is the writer's watchman: it blocks on a pipe whose other end
only the writer holds, and when the pipe closes (the writer closed the file, exited or
was killed) it clears the mark, if one is left.

Standard library only: the watchman starts in a few milliseconds, without NumPy or h5py.
"""
from __future__ import annotations

import os
import struct
import sys

SIGNATURE = b"\x89HDF\r\n\x1a\n"
_MASK = 0xFFFFFFFF


def _rot(x, k):
    return ((x << k) | (x >> (32 - k))) & _MASK


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 hash (hashlittle), HDF5's metadata checksum (H5checksum.c)."""
    length = len(data)
    a = b = c = (0xDEADBEEF + length + initval) & _MASK
    words = lambda k: int.from_bytes(data[k:k + 4].ljust(4, b"\0"), "little")  # noqa: E731
    offset = 0
    while length > 12:
        a, b, c = (a + words(offset)) & _MASK, (b + words(offset + 4)) & _MASK, \
            (c + words(offset + 8)) & _MASK
        a = (a - c) & _MASK; a ^= _rot(c, 4); c = (c + b) & _MASK      # noqa: E702
        b = (b - a) & _MASK; b ^= _rot(a, 6); a = (a + c) & _MASK      # noqa: E702
        c = (c - b) & _MASK; c ^= _rot(b, 8); b = (b + a) & _MASK      # noqa: E702
        a = (a - c) & _MASK; a ^= _rot(c, 16); c = (c + b) & _MASK     # noqa: E702
        b = (b - a) & _MASK; b ^= _rot(a, 19); a = (a + c) & _MASK     # noqa: E702
        c = (c - b) & _MASK; c ^= _rot(b, 4); b = (b + a) & _MASK      # noqa: E702
        offset += 12
        length -= 12
    if length == 0:
        return c
    tail = data[offset:offset + length]
    a = (a + words(offset)) & _MASK if len(tail) > 0 else a
    b = (b + words(offset + 4)) & _MASK if len(tail) > 4 else b
    c = (c + words(offset + 8)) & _MASK if len(tail) > 8 else c
    c ^= b; c = (c - _rot(b, 14)) & _MASK      # noqa: E702
    a ^= c; a = (a - _rot(c, 11)) & _MASK      # noqa: E702
    b ^= a; b = (b - _rot(a, 25)) & _MASK      # noqa: E702
    c ^= b; c = (c - _rot(b, 16)) & _MASK      # noqa: E702
    a ^= c; a = (a - _rot(c, 4)) & _MASK       # noqa: E702
    b ^= a; b = (b - _rot(a, 14)) & _MASK      # noqa: E702
    c ^= b; c = (c - _rot(b, 24)) & _MASK      # noqa: E702
    return c


def clear_open_flags(path) -> bool:
    """Clear the "open for write" marks of an HDF5 file whose writer is gone (what
    ``h5clear -s`` does) and make the superblock's end of allocated space (EOA) agree with
    the file's end (what ``h5clear --increment=0`` does).

    The EOA can lag either way when the writer is killed within a flush:
    - behind the file's end: SWMR writes an object before the metadata that points to it,
      and the superblock, which holds the EOA, may come last. SWMR readers accept such
      addresses; a plain reader stops with "addr overflow" on them, so the EOA is raised
      to the file's end. (A writer that reopened the file would otherwise also allocate
      new space over those objects.)
    - beyond the file's end: space allocated but not yet written; the file is extended
      to the EOA with zeros so that readers do not call it truncated.
    A file without the marks is left alone. Returns True if the file was changed. Only a
    version 2/3 superblock at offset 0 with 8-byte addresses and a valid checksum is
    touched; anything else is left as it is."""
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:
        return False
    try:
        block = os.pread(fd, 48, 0)
        if len(block) < 48 or block[:8] != SIGNATURE or block[8] not in (2, 3) \
                or block[9] != 8:
            return False
        (stored,) = struct.unpack_from("<I", block, 44)
        if lookup3(block[:44]) != stored:
            return False
        base, _, end = struct.unpack_from("<QQQ", block, 12)
        if block[11] == 0:
            return False    # closed by its writer (if short, damaged: not ours to mend)
        size = os.fstat(fd).st_size
        if size < base + end:
            os.ftruncate(fd, base + end)
        end = max(end, size - base)
        fixed = block[:11] + b"\0" + block[12:28] + struct.pack("<Q", end) + block[36:44]
        os.pwrite(fd, fixed + struct.pack("<I", lookup3(fixed)), 0)
        os.fsync(fd)
        return True
    finally:
        os.close(fd)


def main(argv=None):
    """``python _h5guard.py PATH``: wait until standard input closes, then clear PATH's
    marks (the writer either closed the file, leaving none, or died)."""
    path = (argv or sys.argv)[1]
    try:
        while sys.stdin.buffer.read(65536):
            pass
    except (OSError, KeyboardInterrupt):
        pass
    clear_open_flags(path)


if __name__ == "__main__":
    main()

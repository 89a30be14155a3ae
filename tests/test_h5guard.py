"""The watchman's superblock repair: an HDF5 file whose SWMR writer was killed opens
with plain h5py once ``clear_open_flags`` has run, with every flushed frame; the checksum
is HDF5's own (lookup3: the file's stored value is reproduced)."""
import os
import signal
import struct
import subprocess
import sys
import textwrap
import time

import h5py
import numpy as np
import pytest

from bondem.io._h5guard import clear_open_flags, lookup3

WRITER = textwrap.dedent("""
    import sys, h5py, numpy as np
    f = h5py.File(sys.argv[1], "w", libver="latest")
    d = f.create_dataset("x", shape=(0, 100), maxshape=(None, 100), chunks=(1, 100),
                         dtype="f8")
    f.swmr_mode = True
    i = 0
    while True:
        d.resize(i + 1, axis=0); d[i] = i; f.flush(); i += 1
        if i == 20: print("ready", flush=True)
""")


def test_lookup3_reproduces_hdf5s_superblock_checksum(tmp_path):
    path = tmp_path / "a.h5"
    with h5py.File(path, "w", libver="latest") as f:
        f["x"] = np.arange(3)
    block = path.read_bytes()[:48]
    assert block[8] == 3
    assert lookup3(block[:44]) == struct.unpack_from("<I", block, 44)[0]
    assert lookup3(b"") == 0xDEADBEEF and lookup3(b"", 1) == 0xDEADBEEF + 1


def test_killed_swmr_writer_file_opens_plainly_after_repair(tmp_path):
    path = tmp_path / "killed.h5"
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(path)],
                              stdout=subprocess.PIPE)
    assert writer.stdout.readline().strip() == b"ready"
    time.sleep(0.2)
    os.kill(writer.pid, signal.SIGKILL)
    writer.wait()
    with pytest.raises(OSError):
        h5py.File(path, "r")         # what HDF5 does without the watchman
    assert clear_open_flags(path)
    with h5py.File(path, "r") as f:
        rows = f["x"][()]
    assert rows.shape[0] >= 20
    np.testing.assert_array_equal(rows[:, 0], np.arange(rows.shape[0]))
    assert not clear_open_flags(path)   # nothing left to clear: the file is not touched

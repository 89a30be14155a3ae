"""Analysis of a results file that another process is still writing (HDF5 SWMR).

The writer below appends frames as bondem's writer does (datasets created first, then
SWMR mode, one frame at a time, flushed). It leaves one frame half written (in
/bonds/active but not yet in /time): readers must count only complete frames. A 4-particle
chain loses one bond per frame, so frame k has k + 1 fragments.
"""
import json
import subprocess
import sys
import textwrap
import time

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.analysis import Results, fragment_series, largest_fragment_fraction
from bondem.analysis import write_fragment_ids
from bondem.cli import main

WRITER = textwrap.dedent("""
    import sys, time, pathlib
    import h5py, numpy as np
    path, flags = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    def wait(name):
        for _ in range(600):
            if (flags / name).exists():
                return
            time.sleep(0.05)
        sys.exit(3)
    def frame(k):
        active = np.arange(3) >= k           # bond b broken from frame b + 1 on
        return active, np.column_stack([np.arange(4.0) * (1 + 0.1 * k), np.zeros(4), np.zeros(4)])
    def grow(f, key, value):
        d = f[key]
        d.resize(d.shape[0] + 1, axis=0)
        d[-1] = value
    f = h5py.File(path, "w", libver="latest")
    f["particles/radius"] = np.full(4, 0.5)
    f["bonds/pairs"] = np.array([[0, 1], [1, 2], [2, 3]])
    f.create_dataset("time", (0,), maxshape=(None,), dtype="f8", chunks=(64,))
    f.create_dataset("particles/position", (0, 4, 3), maxshape=(None, 4, 3), chunks=(1, 4, 3))
    f.create_dataset("bonds/active", (0, 3), maxshape=(None, 3), dtype=bool, chunks=(1, 3))
    f.swmr_mode = True
    for k in range(2):
        active, position = frame(k)
        grow(f, "bonds/active", active); grow(f, "particles/position", position)
        grow(f, "time", 1e-3 * k)
    active, position = frame(2)               # half written: no /time entry yet
    grow(f, "bonds/active", active); grow(f, "particles/position", position)
    f.flush()
    (flags / "ready").touch()
    wait("go")
    grow(f, "time", 2e-3)
    active, position = frame(3)
    grow(f, "bonds/active", active); grow(f, "particles/position", position)
    grow(f, "time", 3e-3)
    f.flush()
    (flags / "ready2").touch()
    wait("stop")
    f.close()
""")


def wait_for(flag, process):
    for _ in range(600):
        if flag.exists():
            return
        if process.poll() is not None:
            pytest.fail(f"writer exited with {process.returncode}")
        time.sleep(0.05)
    pytest.fail(f"writer never wrote {flag.name}")


def test_reading_while_another_process_writes(tmp_path):
    path = tmp_path / "results.h5"
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(path), str(tmp_path)])
    try:
        wait_for(tmp_path / "ready", writer)
        with Results(path) as results:
            assert results.file.swmr_mode
            assert results.n_frames == 2          # the third frame is not complete
            assert fragment_series(results)["fragments"].tolist() == [1, 2]
            (tmp_path / "go").touch()
            wait_for(tmp_path / "ready2", writer)
            assert results.refresh() == 4
            series = fragment_series(results)
            assert series["fragments"].tolist() == [1, 2, 3, 4]
            assert series["time"] == pytest.approx([0, 1e-3, 2e-3, 3e-3])
        assert largest_fragment_fraction(path) == pytest.approx(0.25)
        result = CliRunner().invoke(main, ["analyze", str(path), "--json", "--out",
                                           str(tmp_path / "analysis")])
        assert result.exit_code == 0, result.output
        assert json.loads(result.output)["fragments"] == 4
        # the writer owns the file: fragment ids go to a sidecar file
        written = write_fragment_ids(path)
        assert written == tmp_path / "results.fragments.h5"
        with h5py.File(written, "r") as f:
            ids = f["particles/fragment"][()]
        assert ids.shape == (4, 4) and [len(set(row)) for row in ids] == [1, 2, 3, 4]
    finally:
        (tmp_path / "stop").touch()
        writer.wait(timeout=30)
    assert writer.returncode == 0
    # once closed, the ids go into the results file itself
    assert write_fragment_ids(path) == path
    with h5py.File(path, "r") as f:
        assert np.array_equal(f["particles/fragment"][()], ids)

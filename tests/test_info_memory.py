"""`bondem info`'s memory estimate against the peak resident memory that `bondem run`
of the same scene really reaches (a bench lattice of 27 000 particles and 78 300 bonds
with contacts, in a process of its own)."""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

import bondem
from bondem.bench import lattice_system
from bondem.cli import main
from bondem.io.csv_files import write_bonds, write_particles

SCENE = """\
[simulation]
end_time = 2e-6
time_step = 1e-7
save_every = 1e-6
contact_model = "hertz_mindlin"
[materials.glass]
density = 2500.0
young_modulus = 1e8
poisson_ratio = 0.3
restitution = 0.5
friction = 0.3
[bond_materials.binder]
young_modulus = 1e8
poisson_ratio = 0.3
normal_strength = 1e30
tangential_strength = 1e30
[particles]
file = "particles.csv"
[bonds]
file = "bonds.csv"
"""

# VmHWM: the peak of this process's own memory. (ru_maxrss is not: Linux folds the
# memory of the process that exec'd into it, here pytest's, into it.)
MEASURE = ("import atexit, sys\n"
           "def peak():\n"
           "    line = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0]\n"
           "    print('PEAK_KIB', line.split()[1], file=sys.stderr)\n"
           "atexit.register(peak)\n"
           "from bondem.cli import main\n"
           "sys.argv = ['bondem'] + sys.argv[1:]\n"
           "main()\n")


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs Linux /proc")
def test_info_memory_estimate_is_within_a_quarter_of_the_peak(tmp_path):
    """The second of two runs: the first compiles what the cache lacks (Numba's compiler
    takes ~120 MiB more, once; `info` says so)."""
    model, state = lattice_system(30)
    write_particles(tmp_path / "particles.csv", state.position, model.radius, "glass",
                    velocity=state.velocity)
    write_bonds(tmp_path / "bonds.csv", model.bond_pairs, model.bond_diameter, "binder")
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    info = CliRunner().invoke(main, ["info", str(scene)])
    assert info.exit_code == 0, info.output
    estimate = float(re.search(r"memory estimate: ([\d.]+) MiB peak", info.output).group(1))
    env = dict(os.environ, PYTHONPATH=str(Path(bondem.__file__).parents[1]))
    for out in ("first", "second"):
        run = subprocess.run([sys.executable, "-c", MEASURE, "run", str(scene), "--out",
                              str(tmp_path / out), "--no-progress"], env=env,
                             capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
    peak = int(re.search(r"PEAK_KIB (\d+)", run.stderr).group(1)) / 1024   # KiB -> MiB
    assert abs(estimate - peak) < 0.25 * peak, (estimate, peak)

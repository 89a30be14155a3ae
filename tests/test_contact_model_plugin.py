"""A new contact model is one file in physics/: dropped into a copy of the package, it is
a ``contact_model`` for the API and the scene file, its parameters are material keys
(mixed by its rule), its reach widens the neighbour lists and the kernels run its law,
nothing else edited.

The test law is Hertz-Mindlin plus a constant attraction ``pull_force`` (N, mixed as the
mean) that acts out to a gap ``pull_range`` (m): two clamped unlike spheres 0.6 of the
range apart, four times the default Verlet skin (a fifth of the mean radius), are listed
and feel exactly the mean of the two pulls; 1.2 of the range apart nothing.
"""
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import bondem

MODEL = '''
"""Test contact model: Hertz-Mindlin plus a constant pull out to a range."""
import math

from ._registry import PAIR_MODEL, physics
from .contact_hertz import hertz_mindlin_law
from .vector import add, scale

NAME = "pulling"
PARAMETERS = {
    "pull_force": (("number", 0.0, 0.0, math.inf, True, False), "mean"),
    "pull_range": (("number", 1e-9, 0.0, math.inf, False, False), "mean"),
}
UNITS = {"pull_force": "N", "pull_range": "m"}
LAW = "pulling_law"
REACH = "pulling_reach"
HYSTERETIC = False


@physics
def pulling_reach(pair, q, r_star):
    return pair[q, PAIR_MODEL + 1]


@physics
def pulling_law(n, overlap, v_rel, w_rel, spring, pair, q, r_star, m_star, i_star, dt):
    pull = scale(n, pair[q, PAIR_MODEL])
    if overlap <= 0.0:
        return pull, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0
    force, torque, f_t, xi, energy = hertz_mindlin_law(n, overlap, v_rel, w_rel, spring,
                                                       pair, q, r_star, m_star, i_star, dt)
    return add(force, pull), torque, f_t, xi, energy
'''

SCRIPT = '''
import bondem
from bondem.contacts import ContactSettings
from bondem.scene import load_scene

a = bondem.Material(density=2500.0, young_modulus=1e8, pull_force=2e-6, pull_range=2e-3,
                    name="a")
b = bondem.Material(density=2500.0, young_modulus=1e8, pull_force=5e-6, pull_range=2e-3,
                    name="b")
for fraction in (0.6, 1.2):
    model, state = bondem.make_system([[0, 0, 0], [1e-3 + 2e-3 + fraction * 2e-3, 0, 0]],
                                      [1e-3, 2e-3], [a, b], material_index=[0, 1],
                                      fixed=[True, True])
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="pulling"))
    sim.step(1)
    print(f"force{fraction}", state.extra["contact_force"][0, 0] if
          state.extra["contact_pairs"].shape[0] else "unlisted")
scene = load_scene("scene.toml")
print("scene", scene.simulation_options["contact"].model, scene.model.materials[0].pull_force)
'''

SCENE = '''
[simulation]
end_time = 1e-5
contact_model = "pulling"

[materials.glass]
density = 2500.0
young_modulus = 1e8
pull_force = 3e-6

[particles]
file = "particles.csv"
'''


def test_a_contact_model_file_is_all_a_new_model_needs(tmp_path):
    package = Path(bondem.__file__).resolve().parent
    copy = tmp_path / "pkg" / "bondem"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nbi",
                                                                 "*.nbc"))
    (copy / "physics" / "contact_pulling.py").write_text(MODEL)
    (tmp_path / "scene.toml").write_text(textwrap.dedent(SCENE))
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-3,glass\n"
                                            "3e-3,0,0,1e-3,glass\n")
    env = {"PYTHONPATH": str(tmp_path / "pkg"), "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PATH": "/usr/bin:/bin", "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines())
    # the pair 0.6 of the range apart (1.2 mm), beyond the skin (0.3 mm): listed and pulled
    # with the mean of 2 and 5 uN towards each other (+x on particle 0)
    assert abs(float(lines["force0.6"]) - 3.5e-6) < 1e-18, lines
    assert lines["force1.2"] in ("unlisted", "0.0"), lines
    assert lines["scene"] == "pulling 3e-06"

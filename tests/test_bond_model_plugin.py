"""A new bond model is one file in physics/: dropped into a copy of the package, it is a
bond material ``model`` for the API and the scene file, with its own parameter, and the
kernels run its loads, nothing else edited.

The test model scales the elastic bond's normal force by ``normal_factor``; with a factor
of 4 the axial period of two bonded spheres, 2 pi sqrt((m/2) / k_n), halves (0.5 %).
A second, plastic one changes the springs themselves (SPRINGS, a per-bond column, ENERGY):
its normal force stops at ``cap_force`` and the bond keeps the plastic stretch; pulled to
1.5 times the yield stretch and pushed back to its initial length, it pushes with half the
cap, k (0 - delta_p) with delta_p = 0.5 cap / k, having booked cap delta_p as dissipated.
"""
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import bondem

MODEL = '''
"""Test bond model: the elastic bond, its normal force scaled by normal_factor."""
from ._registry import physics
from .bond_elastic import bond_loads_on_particles
from .vector import scale

NAME = "scaled"
PARAMETERS = {"normal_factor": ("number", 1.0, 0.0, float("inf"), False, False)}
UNITS = {"normal_factor": "-"}
LOADS = "scaled_loads"
STATE = None
VECTORISED = False


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    return {}


@physics
def scaled_loads(musen, r, length, initial_length, diameter, vi, vj, wi, wj, f_n, f_t, m_n,
                 m_t, normal_stiffness, shear_stiffness, materials, m):
    force_i, moment_i, moment_j = bond_loads_on_particles(
        r, scale(f_n, materials.normal_factor[m]), f_t, m_n, m_t)
    return force_i, moment_i, moment_j, 0.0
'''

PLASTIC = '''
"""Test bond model: the normal force capped at cap_force (N), the plastic stretch kept."""
from ._registry import physics
from .vector import scale

NAME = "capped"
PARAMETERS = {"cap_force": ("number", float("inf"), 0.0, float("inf"), False, True)}
UNITS = {"cap_force": "N"}
LOADS = None
SPRINGS = "capped_springs"
COLUMNS = ("plastic stretch (m)",)
ENERGY = "capped_energy"
STATE = ("J dissipated by the cap", "dissipated_capped")
VECTORISED = False


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    return {}


@physics
def capped_springs(musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode,
                   kn, kt, scatter, lp, plastic, unused, materials, m):
    cap = materials.cap_force[m]
    force = kn * (length - l0 - plastic)
    lost = 0.0
    if force > cap:
        moved = length - l0 - cap / kn
        lost = cap * (moved - plastic)
        plastic = moved
        force = cap
    elif force < -cap:
        moved = length - l0 + cap / kn
        lost = cap * (plastic - moved)
        plastic = moved
        force = -cap
    return scale(n, force), f_t, m_n, m_t, mode, plastic, unused, lost


@physics
def capped_energy(length, l0, kn, plastic, unused, materials, m):
    stretch = length - l0 - plastic
    return 0.5 * kn * stretch * stretch
'''

SCRIPT = '''
import numpy as np
import bondem
from bondem.scene import load_scene

def period(factor):
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    bond = bondem.BondMaterial(young_modulus=1e8, breakage="none", model="scaled",
                               normal_factor=factor)
    model, state = bondem.make_system([[0, 0, 0], [2e-3, 0, 0]], 1e-3, glass,
                                      velocity=[[-1e-4, 0, 0], [1e-4, 0, 0]],
                                      bonds=[[0, 1]], bond_diameter=1e-3, bond_material=bond)
    dt = 0.01 * min(bondem.time_scales(model).values())
    sim = bondem.Simulation(model, state, time_step=dt)
    signal = []
    for _ in range(3000):
        sim.step(1)
        signal.append(state.position[1, 0] - state.position[0, 0] - 2e-3)
    s = np.array(signal)
    k = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    crossings = (k + s[k] / (s[k] - s[k + 1])) * dt
    return (crossings[-1] - crossings[0]) / (len(crossings) - 1)

print("ratio", period(4.0) / period(1.0))

def capped():
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    bond = bondem.BondMaterial(young_modulus=1e8, breakage="none", model="capped",
                               cap_force=0.1)
    model, state = bondem.make_system([[0, 0, 0], [2e-3, 0, 0]], 1e-3, glass,
                                      velocity=[[0, 0, 0], [1e-3, 0, 0]], fixed=[True, True],
                                      bonds=[[0, 1]], bond_diameter=1e-3, bond_material=bond)
    k = 1e8 * np.pi * 0.25e-6 / 2e-3
    steps = int(round(1.5 * 0.1 / k / 1e-9))
    sim = bondem.Simulation(model, state, time_step=1e-6)
    sim.step(steps)
    state.velocity[1, 0] = -1e-3
    sim.step(steps + 1)
    print("capped", sim.bonds.loads.force_i[0, 0] / 0.1,
          sim.energy_terms()["dissipated_capped"] / (0.1 * 0.5 * 0.1 / k))

capped()
scene = load_scene("scene.toml")
print("scene", scene.model.bond_materials[0].model, scene.model.bond_materials[0].normal_factor)
'''

SCENE = '''
[simulation]
end_time = 1e-5
time_step = "auto"
contact_model = "none"

[materials.glass]
density = 2500.0
young_modulus = 1e8

[bond_materials.binder]
young_modulus = 1e8
model = "scaled"
normal_factor = 4.0

[particles]
file = "particles.csv"

[bonds]
file = "bonds.csv"
'''


def test_a_bond_model_file_is_all_a_new_model_needs(tmp_path):
    package = Path(bondem.__file__).resolve().parent
    copy = tmp_path / "pkg" / "bondem"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nbi",
                                                                 "*.nbc"))
    (copy / "physics" / "bond_scaled.py").write_text(MODEL)
    (copy / "physics" / "bond_capped.py").write_text(PLASTIC)
    (tmp_path / "scene.toml").write_text(textwrap.dedent(SCENE))
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-3,glass\n"
                                            "2e-3,0,0,1e-3,glass\n")
    (tmp_path / "bonds.csv").write_text("i,j,diameter,material\n0,1,1e-3,binder\n")
    env = {"PYTHONPATH": str(tmp_path / "pkg"), "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PATH": "/usr/bin:/bin", "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines())
    assert abs(float(lines["ratio"]) - 0.5) < 0.5 * 5e-3, lines
    assert lines["scene"] == "scaled 4.0"
    force, booked = map(float, lines["capped"].split())
    assert abs(force - -0.5) < 1e-2 and abs(booked - 1.0) < 1e-2, lines

"""A new bond or contact model is one file in physics/: dropped into a copy of the
package (one copy and one process for both, to compile once), it is a model for the API
and the scene file with its own parameters, and the kernels run it, nothing else edited.

A bond model is a bond material ``model`` for the API and the scene file, with its own
parameter, and the kernels run its loads.

The test model scales the elastic bond's normal force by ``normal_factor``; with a factor
of 4 the axial period of two bonded spheres, 2 pi sqrt((m/2) / k_n), halves (0.5 %).
A second, plastic one changes the springs themselves (SPRINGS, a per-bond column, ENERGY):
its normal force stops at ``cap_force`` and the bond keeps the plastic stretch; pulled to
1.5 times the yield stretch and pushed back to its initial length, it pushes with half the
cap, k (0 - delta_p) with delta_p = 0.5 cap / k, having booked cap delta_p as dissipated.

A contact model is a ``contact_model`` for the API and the scene file, its parameters are
material keys (mixed by its rule), its reach widens the neighbour lists and the kernels
run its law. The test law is Hertz-Mindlin plus a constant attraction ``pull_force`` (N,
mixed as the mean) that acts out to a gap ``pull_range`` (m): two clamped unlike spheres
0.6 of the range apart, four times the default Verlet skin (a fifth of the mean radius),
are listed and feel exactly the mean of the two pulls; 1.2 of the range apart nothing.

A field model is a scene table and a ``make_system`` keyword, the particle loop adds its
force and moment, the time step and the energy books see it. The test field is a
harmonic trap, F = -k (x - c), with a constant torque T: a sphere of mass m released
from rest oscillates with the period 2 pi sqrt(m / k) (0.5 %, at a hundredth of the
trap's time scale sqrt(m / k), which it declares), spins up as w = T t / I (t half a step behind the position's), and the
trap's work books its kinetic energy (to the leapfrog's O(dt^2) error).
"""
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

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

CONTACT_MODEL = '''
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

FIELD_MODEL = '''
"""Test field model: a harmonic trap F = -k (x - c) and a constant torque."""
import numpy as np

from ._registry import physics

NAME = "trap"
KEYS = {"stiffness": ("number", 0.0, 0.0, float("inf"), True, False),
        "center": ("vector3", [0.0, 0.0, 0.0], -float("inf"), float("inf"), False, False),
        "torque": ("vector3", [0.0, 0.0, 0.0], -float("inf"), float("inf"), False, False)}
ARRAY = "trap_array"
INPUTS = ()
FORCE = "trap_force"
MOMENT = "trap_moment"
CLUMPS = False


def trap_array(stiffness=0.0, center=(0.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0)):
    if stiffness < 0.0:
        raise ValueError(f"stiffness = {stiffness}; allowed [0, inf)")
    return np.array([stiffness, *center, *torque], dtype=np.float64)


def active(trap):
    return bool(np.any(trap[[0, 4, 5, 6]]))


def time_scales(trap, mass, radius):
    return {"trap": float(np.sqrt(mass / trap[0]).min())} if trap[0] > 0.0 else {}


@physics
def trap_force(trap, p, mass, radius, x, v, gravity):
    k = trap[0]
    return (-k * (x[0] - trap[1]), -k * (x[1] - trap[2]), -k * (x[2] - trap[3]))


@physics
def trap_moment(trap, inertia, w):
    return (trap[4], trap[5], trap[6])
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

from bondem.contacts import ContactSettings

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
scene = load_scene("contact_scene.toml")
print("contact_scene", scene.simulation_options["contact"].model,
      scene.model.materials[0].pull_force)

scene = load_scene("trap_scene.toml")
model, state = scene.model, scene.state
mass, inertia = model.mass[0], model.inertia[0]
print("trap_scale", bondem.time_scales(model)["trap"] / np.sqrt(mass / 1e5),
      bondem.stable_time_step(model)[1])
dt = 0.01 * np.sqrt(mass / 1e5)
sim = bondem.Simulation(model, state, time_step=dt)
signal = []
for _ in range(2000):
    sim.step(1)
    signal.append(state.position[0, 0] - 1e-3)
s = np.array(signal)
k = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
crossings = (k + s[k] / (s[k] - s[k + 1])) * dt
print("trap_period", (crossings[-1] - crossings[0]) / (len(crossings) - 1)
      / (2 * np.pi * np.sqrt(mass / 1e5)))
# the leapfrog's velocities lie half a step behind its positions (a first half kick)
print("trap_spin", state.angular_velocity[0, 2] / (2e-12 * (state.time - dt / 2) / inertia))
kinetic = 0.5 * mass * float(np.sum(state.velocity[0] ** 2))
print("trap_work", state.work_external / (kinetic + 0.5 * inertia
                                          * float(np.sum(state.angular_velocity[0] ** 2))))
from bondem.physics.field_trap import trap_array
model, state = bondem.make_system([[0, 0, 0]], 1e-3, a, trap=trap_array(2.0))
print("trap_api", model.fields["trap"][0], model.acting_fields)
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

CONTACT_SCENE = '''
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

TRAP_SCENE = '''
[simulation]
end_time = 1e-5
contact_model = "none"

[materials.glass]
density = 2500.0
young_modulus = 1e8

[particles]
file = "one.csv"

[trap]
stiffness = 1e5
center = [1e-3, 0.0, 0.0]
torque = [0.0, 0.0, 2e-12]
'''


@pytest.fixture(scope="module")
def plugged(tmp_path_factory):
    """The printed lines of SCRIPT run on a copy of the package with the test bond and
    contact models dropped into physics/."""
    tmp_path = tmp_path_factory.mktemp("plugins")
    package = Path(bondem.__file__).resolve().parent
    copy = tmp_path / "pkg" / "bondem"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nbi",
                                                                 "*.nbc"))
    (copy / "physics" / "bond_scaled.py").write_text(MODEL)
    (copy / "physics" / "bond_capped.py").write_text(PLASTIC)
    (copy / "physics" / "contact_pulling.py").write_text(CONTACT_MODEL)
    (copy / "physics" / "field_trap.py").write_text(FIELD_MODEL)
    (tmp_path / "trap_scene.toml").write_text(textwrap.dedent(TRAP_SCENE))
    (tmp_path / "one.csv").write_text("x,y,z,radius,material\n2e-3,0,0,1e-3,glass\n")
    (tmp_path / "scene.toml").write_text(textwrap.dedent(SCENE))
    (tmp_path / "contact_scene.toml").write_text(textwrap.dedent(CONTACT_SCENE))
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-3,glass\n"
                                            "2e-3,0,0,1e-3,glass\n")
    (tmp_path / "bonds.csv").write_text("i,j,diameter,material\n0,1,1e-3,binder\n")
    env = {"PYTHONPATH": str(tmp_path / "pkg"), "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PATH": "/usr/bin:/bin", "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return dict(line.split(" ", 1) for line in done.stdout.splitlines())


def test_a_bond_model_file_is_all_a_new_model_needs(plugged):
    lines = plugged
    assert abs(float(lines["ratio"]) - 0.5) < 0.5 * 5e-3, lines
    assert lines["scene"] == "scaled 4.0"
    force, booked = map(float, lines["capped"].split())
    assert abs(force - -0.5) < 1e-2 and abs(booked - 1.0) < 1e-2, lines


def test_a_contact_model_file_is_all_a_new_model_needs(plugged):
    lines = plugged
    # the pair 0.6 of the range apart (1.2 mm), beyond the skin (0.3 mm): listed and pulled
    # with the mean of 2 and 5 uN towards each other (+x on particle 0)
    assert abs(float(lines["force0.6"]) - 3.5e-6) < 1e-18, lines
    assert lines["force1.2"] in ("unlisted", "0.0"), lines
    assert lines["contact_scene"] == "pulling 3e-06"


def test_a_field_model_file_is_all_a_new_field_needs(plugged):
    lines = plugged
    scale, cause = lines["trap_scale"].split()
    assert float(scale) == pytest.approx(1.0, rel=1e-12) and cause == "trap", lines
    # symplectic Euler at omega dt = 0.01: the period is 2 pi / omega to (omega dt)^2 / 24
    assert abs(float(lines["trap_period"]) - 1.0) < 5e-3, lines
    assert float(lines["trap_spin"]) == pytest.approx(1.0, rel=1e-9), lines
    assert abs(float(lines["trap_work"]) - 1.0) < 1e-3, lines
    assert lines["trap_api"] == "2.0 ['trap']", lines

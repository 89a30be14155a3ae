"""A fluid whose velocity varies in space and time (a formula of x, y, z, t or a Python
function) and a local voidage for the drag laws (coupling.FlowField, expression.py,
docs/fields.md).

Closed forms: a sphere in an oscillating Stokes flow U sin(w t) answers with the amplitude
U / sqrt(1 + (w tau)^2) and the lag atan(w tau) (tau = m / (3 pi mu d)), each sphere of a
sheared oscillating flow at its own height's amplitude; Di Felice's drag takes the voidage
of the cell a sphere's centre lies in, 1 - (the spheres' volume there) / (the cell's).
"""
import math

import numpy as np
import pytest

import bondem
from bondem.coupling import FlowField, voidage_grid
from bondem.errors import InputError
from bondem.expression import flow_function
from bondem.model import Material, fluid_array, make_system
from bondem.scene import load_scene

RHO_P, MU, D = 2650.0, 1.3e-3, 8e-5
TAU = RHO_P * D * D / (18.0 * MU)   # Stokes relaxation time (s)


def glass():
    return Material(name="glass", density=RHO_P, young_modulus=1e9, poisson_ratio=0.3)


def test_an_oscillating_sheared_flow_drives_each_sphere_with_the_stokes_lag():
    """u_x = U sin(w t) (1 + z / h): a sphere at height z answers in Stokes drag with
    v = A_z / (1 + a^2) (sin w t - a cos w t + a e^(-t/tau)), A_z = U (1 + z / h),
    a = w tau: amplitude A_z / sqrt(1 + a^2), lag atan(a) (63.4 degrees at a = 2). The
    formula takes the time at the start of each step; the leapfrog's velocities are half
    a step behind."""
    u, h, a = 0.01, 2e-3, 2.0
    w = a / TAU
    heights = np.array([1e-3, 4e-3])
    position = np.column_stack([[0.0, 0.0], [0.0, 1e-3], heights])
    model, state = make_system(position, np.full(2, 0.5 * D), [glass()],
                               fluid=fluid_array(viscosity=MU, drag="stokes"))
    flow = FlowField(velocity=flow_function([f"{u} * sin({w} * t) * (1 + z / {h})", 0, 0]))
    sim = bondem.Simulation(model, state, time_step=TAU / 2000, force_time_step=True,
                            flow=flow)
    sim.run(until=12 * TAU)
    times, values = [], []
    for _ in range(200):
        sim.step(20)
        times.append(sim.state.time - 0.5 * sim.time_step)
        values.append(sim.state.velocity[:, 0].copy())
    times, values = np.array(times), np.array(values)
    basis = np.column_stack([np.sin(w * times), np.cos(w * times)])
    for k, z in enumerate(heights):
        (s, c), *_ = np.linalg.lstsq(basis, values[:, k], rcond=None)
        amplitude = u * (1 + z / h)
        assert math.hypot(s, c) == pytest.approx(amplitude / math.sqrt(1 + a * a), rel=2e-3)
        assert math.atan2(-c, s) == pytest.approx(math.atan(a), abs=2e-3)
    # the flow has no z part: the spheres stay at their heights
    np.testing.assert_array_equal(sim.state.position[:, 2], heights)


def test_a_python_function_flow_and_its_bad_answers():
    model, state = make_system(np.array([[0.0, 0.0, 0.0], [1e-3, 0, 0]]), np.full(2, 0.5 * D),
                               [glass()], fluid=fluid_array(viscosity=MU, drag="stokes"))
    flow = FlowField(velocity=lambda x, t: np.array([0.0, 0.003, 0.0]))
    sim = bondem.Simulation(model, state, time_step=TAU / 400, force_time_step=True,
                            flow=flow)
    # the flow is there before the first step (a frame saved at t = 0 shows its drag)
    np.testing.assert_array_equal(model.fluid_local[:, 1], 0.003)
    sim.run(until=15 * TAU)
    np.testing.assert_allclose(sim.state.velocity[:, 1], 0.003, rtol=1e-6)
    assert model.fluid_local.shape == (2, 4)
    for velocity, message in [(lambda x, t: np.zeros((2, 2)), "2 x 3"),
                              (lambda x, t: x / x[:, :1], "not finite at particle 0")]:
        with pytest.raises(ValueError, match=message), np.errstate(all="ignore"):
            FlowField(velocity=velocity).values(model, state.position, 0.0)
    for kwargs, message in [({}, "give a velocity"), ({"velocity": 3.0}, "function"),
                            ({"voidage_grid": ((0, 0, 0), (1, 1, -1), (2, 2, 2))}, "high"),
                            ({"voidage_grid": ((0, 0, 0), (1, 1, 1), (2, 0, 2))}, "cells"),
                            ({"voidage_grid": ((0, 0, 0), (1, 1, 1), (2, 2, 2)),
                              "voidage_floor": 0.0}, "voidage_floor")]:
        with pytest.raises(ValueError, match=message):
            FlowField(**kwargs)


def di_felice_force(rho, mu, d, slip, eps):
    """Di Felice's drag (N) on a sphere of diameter d at slip (m/s) in voidage eps."""
    re = rho * eps * slip * d / mu
    cd = (0.63 + 4.8 / math.sqrt(re)) ** 2
    chi = 3.7 - 0.65 * math.exp(-0.5 * (1.5 - math.log10(re)) ** 2)
    return 0.5 * rho * cd * math.pi / 4 * d * d * eps ** 2 * slip * slip * eps ** (-chi)


def test_di_felice_drag_sees_the_voidage_of_its_cell():
    """Three fixed spheres and a free one share a 2 mm cell of a 3 x 2 x 2 grid; a free
    sphere in another cell is alone there; one outside the grid sees eps = 1. The start-up
    step's velocity change, F / m dt / 2, is Di Felice's drag at each cell's voidage."""
    rho, mu, u = 1000.0, 1e-3, 0.05
    r = np.array([0.3e-3, 0.35e-3, 0.25e-3, 0.4e-3, 0.3e-3, 0.3e-3])
    position = np.array([[0.5e-3, 0.4e-3, 0.3e-3], [1.2e-3, 1.5e-3, 0.8e-3],
                         [1.6e-3, 0.5e-3, 1.4e-3], [0.9e-3, 1.0e-3, 1.1e-3],
                         [3.0e-3, 0.7e-3, 2.9e-3], [9e-3, 0.0, 0.0]])
    fixed = [True, True, True, False, False, False]
    model, state = make_system(position, r, [glass()], fixed=fixed,
                               fluid=fluid_array(density=rho, viscosity=mu,
                                                 velocity=(u, 0.0, 0.0), drag="di_felice",
                                                 buoyancy=False, voidage=0.6))
    low, high, cells = (0.0, 0.0, 0.0), (6e-3, 4e-3, 4e-3), (3, 2, 2)
    cell_volume = 2e-3 ** 3
    eps_shared = 1.0 - 4.0 / 3.0 * math.pi * np.sum(r[:4] ** 3) / cell_volume
    eps_alone = 1.0 - 4.0 / 3.0 * math.pi * r[4] ** 3 / cell_volume
    assert 0.7 < eps_shared < 0.95 < eps_alone < 1.0   # the fluid's own: 0.6
    np.testing.assert_allclose(voidage_grid(position, r, low, high, cells)[[0, 1], 0, [0, 1]],
                               [eps_shared, eps_alone], rtol=1e-14)
    flow = FlowField(voidage_grid=(low, high, cells))
    dt = 1e-7
    sim = bondem.Simulation(model, state, time_step=dt, force_time_step=True, flow=flow)
    sim.step(1)   # the start-up half kick: 0.5 dt of drag on a sphere at rest
    mass = RHO_P * 4.0 / 3.0 * math.pi * r ** 3
    for p, eps in ((3, eps_shared), (4, eps_alone), (5, 1.0)):
        expected = di_felice_force(rho, mu, 2 * r[p], u, eps) / mass[p] * 0.5 * dt
        assert sim.state.velocity[p, 0] == pytest.approx(expected, rel=1e-12)
    # a crowded cell is held at the floor: four of these spheres in one cell of 0.5 mm
    crowded = FlowField(voidage_grid=(low, (1e-3, 1e-3, 1e-3), (2, 2, 2)),
                        voidage_floor=0.35)
    local = crowded.values(model, np.array([[0.2e-3] * 3] * 4 + [[0.9e-3] * 3] * 2), 0.0)
    np.testing.assert_array_equal(local[:, 3], [0.35] * 4 + [0.35, 0.35])
    assert np.all(local[:, :3] == 0.0)


def test_a_flow_field_run_resumes_bit_identical(tmp_path):
    from bondem.io.checkpoint import read_checkpoint, write_checkpoint
    position = np.array([[0.0, 0.0, 0.0], [0.3e-3, 0.1e-3, 0.0], [-0.2e-3, 0.2e-3, 0.1e-3]])
    runs = []
    for split in (False, True):
        model, state = make_system(position, np.full(3, 0.5 * D), [glass()],
                                   gravity=(0.0, 0.0, -9.81),
                                   fluid=fluid_array(density=1000.0, viscosity=MU,
                                                     drag="di_felice"))
        flow = FlowField(velocity=flow_function(["0.01 * cos(300 * t) * y / 1e-3",
                                                 "0.002", "0.004 * x / 1e-3"]),
                         voidage_grid=((-1e-3, -1e-3, -1e-3), (1e-3, 1e-3, 1e-3), (3, 3, 3)))
        sim = bondem.Simulation(model, state, time_step=TAU / 50, force_time_step=True,
                                flow=flow)
        sim.step(301)
        if split:
            write_checkpoint(tmp_path / "c.npz", sim.state, frames=0)
            state = read_checkpoint(tmp_path / "c.npz")[0]
            sim = bondem.Simulation(model, state, time_step=TAU / 50, force_time_step=True,
                                    flow=flow)
        sim.step(300)
        runs.append(sim.state.arrays())
    for name, value in runs[0].items():
        np.testing.assert_array_equal(value, runs[1][name], err_msg=name, strict=True)
    assert np.abs(runs[0]["velocity"]).max() > 1e-3


SCENE = """
[simulation]
end_time = {end}
gravity = [0.0, 0.0, 0.0]
[materials.glass]
density = 2650.0
young_modulus = 1e9
poisson_ratio = 0.3
[particles]
file = "particles.csv"
[fluid]
viscosity = 1.3e-3
{fluid}
"""


def test_a_scene_flow_formula_and_local_voidage(tmp_path):
    """A scene's formula drags two spheres at their own heights' velocities, u_x = 0.5 z
    (s^-1); the local voidage reaches the Di Felice drag."""
    (tmp_path / "particles.csv").write_text(
        "x,y,z,radius,material\n0,0,1e-3,4e-5,glass\n1e-3,0,3e-3,4e-5,glass\n")
    (tmp_path / "scene.toml").write_text(SCENE.format(end=15 * TAU, fluid=(
        'drag = "stokes"\nvelocity = ["0.5 * z", 0, "0"]')))
    scene = load_scene(tmp_path / "scene.toml")
    sim = scene.make_simulation()
    sim.run(until=scene.end_time)
    np.testing.assert_allclose(sim.state.velocity[:, 0], [0.5e-3, 1.5e-3], rtol=1e-6)
    (tmp_path / "scene.toml").write_text(SCENE.format(end=1e-3, fluid=(
        'drag = "di_felice"\ndensity = 1000.0\nvoidage = "local"\n'
        'voidage_grid = {low = [-1e-3, -1e-3, 0], high = [2e-3, 1e-3, 4e-3], '
        'cells = [1, 1, 2], floor = 0.5}')))
    flow = load_scene(tmp_path / "scene.toml").simulation_options["flow"]
    assert flow.voidage_floor == 0.5 and flow.voidage_grid[2] == (1, 1, 2)
    eps = flow.values(scene.model, scene.state.position, 0.0)[:, 3]
    np.testing.assert_allclose(eps, 1 - 4 / 3 * math.pi * 4e-5 ** 3 / (3e-3 * 2e-3 * 2e-3),
                               rtol=1e-14)


@pytest.mark.parametrize("fluid, key, message", [
    ('drag = "stokes"\nvelocity = ["open(1)", 0, 0]', "fluid.velocity", "unknown function"),
    ('drag = "stokes"\nvelocity = ["x", 0]', "fluid.velocity", "3 components"),
    ('drag = "stokes"\nvelocity = ["x.y", 0, 0]', "fluid.velocity", "not allowed"),
    ('drag = "stokes"\nvoidage = "local"', "fluid.voidage_grid", "needs"),
    ('drag = "stokes"\nvoidage_grid = {low = [0, 0, 0], high = [1, 1, 1], cells = [1, 1, 1]}',
     "fluid.voidage_grid", 'voidage = "local"'),
    ('drag = "stokes"\nvoidage = "local"\nvoidage_grid = {low = [0, 0, 0], high = [1, 1, 1], '
     'cells = [1, 0, 1]}', "fluid.voidage_grid.cells", "3 integers >= 1"),
    ('drag = "stokes"\nvoidage = "local"\nvoidage_grid = {low = [0, 0, 0], high = [1, 0, 1], '
     'cells = [1, 1, 1]}', "fluid.voidage_grid.high", "must exceed"),
    ('drag = "stokes"\nvoidage = "local"\nvoidage_grid = {low = [0, 0, 0], high = [1, 1, 1], '
     'cells = [1, 1, 1], floor = 0}', "fluid.voidage_grid.floor", "(0.0, 1.0]"),
    ('drag = "stokes"\nvoidage = "loose"', "fluid.voidage", "expected a number"),
    ('velocity = ["z", 0, 0]', "fluid.drag", "acts through the drag; allowed: one of stokes"),
])
def test_bad_flow_formulas_and_voidage_grids_are_named(tmp_path, fluid, key, message):
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-4,glass\n")
    (tmp_path / "scene.toml").write_text(SCENE.format(end=1e-3, fluid=fluid))
    with pytest.raises(InputError) as error:
        load_scene(tmp_path / "scene.toml")
    assert error.value.key == key and message in str(error.value)
    assert "scene.toml" in str(error.value)



def test_a_bonded_cube_turns_with_half_the_shear_rate():
    """Eight bonded spheres at a cube's corners in a simple shear u = (gamma z, 0, 0),
    Stokes drag on each. Simple shear is a pure strain plus a rigid rotation at gamma / 2
    about +y; the strain exerts no torque on a body whose second moment of its drag
    centres is isotropic, as a cube's is in any orientation. So the cube ends translating
    with the flow at its centre, gamma z_c, and turning at gamma / 2 about y (to first
    order in dt / tau: 2e-4 here); in the pure strain (gamma / 2)(z, 0, x) it does not
    turn (1e-3 of gamma / 2 allowed for both)."""
    r, mu, gamma = 0.5e-3, 0.8, 40.0
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)],
                       dtype=float) * 2 * r
    position = corners - corners.mean(axis=0) + [1e-3, -2e-3, 3e-3]
    bonds = [[a, b] for a in range(8) for b in range(a + 1, 8)
             if np.isclose(np.linalg.norm(corners[a] - corners[b]), 2 * r)]
    mass = 1200.0 * 4 / 3 * math.pi * r ** 3
    tau = mass / (3 * math.pi * mu * 2 * r)
    for formula, turning in (([f"{gamma} * z", 0, 0], gamma / 2),
                             ([f"{gamma / 2} * z", 0, f"{gamma / 2} * x"], 0.0)):
        model, state = make_system(
            position, np.full(8, r),
            [Material(name="g", density=1200.0, young_modulus=1e7, poisson_ratio=0.3)],
            bonds=bonds, bond_diameter=0.6e-3,
            bond_material=bondem.BondMaterial(name="b", young_modulus=2e9,
                                              poisson_ratio=0.3),
            fluid=fluid_array(viscosity=mu, drag="stokes"))
        sim = bondem.Simulation(model, state, flow=FlowField(velocity=flow_function(formula)))
        assert sim.time_step < 2e-3 * tau
        sim.run(until=20 * tau)
        x, v = sim.state.position, sim.state.velocity
        c = x.mean(axis=0)
        # the rigid motion that fits the velocities: v_i = V + W x (x_i - c)
        rows = [np.hstack([np.eye(3), -np.cross(np.eye(3), x[i] - c)]) for i in range(8)]
        fit = np.linalg.lstsq(np.vstack(rows), v.ravel(), rcond=None)[0]
        if turning:   # (in the strain the centre accelerates away, the body lagging)
            np.testing.assert_allclose(fit[:3], [gamma * c[2], 0.0, 0.0], rtol=1e-8,
                                       atol=1e-12)
        assert fit[4] == pytest.approx(turning, abs=1e-3 * gamma / 2)
        assert abs(fit[3]) < 1e-9 and abs(fit[5]) < 1e-9

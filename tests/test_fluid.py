"""A fluid around the particles: drag and buoyancy (physics/field_fluid.py, docs/fields.md).

Closed forms: a sphere settling in a still fluid follows Stokes' exponential to its
terminal velocity (rho_p - rho_f) g d^2 / (18 mu); at Re ~ 100 it ends at the speed where
Schiller and Naumann's drag balances its weight less its buoyancy; at the fluid's density
it does not move; a bonded cluster in a uniform flow takes up the flow's velocity at the
rate its particles' drags sum to; the fluid's work closes the energy balance.
"""
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import bondem
from bondem.errors import InputError
from bondem.model import Material, fluid_array, make_system
from bondem.physics.field_fluid import drag_coefficient
from bondem.scene import load_scene

GRAVITY = (0.0, 0.0, -9.81)
# no flow grid, no per-particle fluid (Model's defaults)
NO_GRID = (np.zeros((1, 1, 1, 3)), np.zeros(6), (0.0, 0.0, 0.0, 0.0))


def settling(rho_p, d, fluid, gravity=GRAVITY):
    """One sphere at rest in ``fluid``."""
    glass = Material(name="glass", density=rho_p, young_modulus=1e9, poisson_ratio=0.3)
    return make_system(np.array([[1e-3, -2e-3, 5e-3]]), np.array([0.5 * d]), [glass],
                       gravity=gravity, fluid=fluid)


def test_stokes_settling_follows_the_exponential_to_the_terminal_velocity():
    rho_p, rho_f, mu, d = 2650.0, 998.0, 1.3e-3, 8e-5
    gravity = (0.8, 0.0, -9.81)   # a tilted g: the settling follows it, not an axis
    model, state = settling(rho_p, d, fluid_array(density=rho_f, viscosity=mu,
                                                  drag="stokes", buoyancy=True), gravity)
    tau = rho_p * d * d / (18.0 * mu)
    terminal = (rho_p - rho_f) * d * d / (18.0 * mu) * np.array(gravity)
    sim = bondem.Simulation(model, state, time_step=tau / 400, force_time_step=True)
    sim.run(until=tau)
    expected = terminal * (1.0 - math.exp(-sim.state.time / tau))
    np.testing.assert_allclose(sim.state.velocity[0], expected, rtol=5e-3, atol=0)
    sim.run(until=15 * tau)
    np.testing.assert_allclose(sim.state.velocity[0], terminal, rtol=5e-3, atol=0)
    # the walked distance: terminal (t - tau (1 - e^(-t / tau)))
    t = sim.state.time
    walked = terminal * (t - tau * (1.0 - math.exp(-t / tau)))
    np.testing.assert_allclose(sim.state.position[0] - [1e-3, -2e-3, 5e-3], walked,
                               rtol=5e-3, atol=0)


def test_schiller_naumann_terminal_velocity_at_re_100():
    rho_p, rho_f, mu, d = 2000.0, 1000.0, 1e-3, 1e-3
    weight = (rho_p - rho_f) * math.pi / 6.0 * d ** 3 * 9.81

    def balance(v):
        re = rho_f * v * d / mu
        return 0.5 * rho_f * drag_coefficient(2, re) * math.pi / 4 * d * d * v * v - weight

    terminal = brentq(balance, 1e-6, 10.0, xtol=1e-14)
    re = rho_f * terminal * d / mu
    assert 80.0 < re < 120.0
    # against the standard drag curve (Clift, Grace & Weber 1978: C_d = 1.09 at Re 100)
    assert drag_coefficient(2, 100.0) == pytest.approx(1.09, rel=0.02)
    model, state = settling(rho_p, d, fluid_array(density=rho_f, viscosity=mu,
                                                  drag="schiller_naumann", buoyancy=True))
    sim = bondem.Simulation(model, state, time_step=2e-5, force_time_step=True)
    sim.run(until=0.4)
    assert -sim.state.velocity[0, 2] == pytest.approx(terminal, rel=5e-3)
    assert np.all(sim.state.velocity[0, :2] == 0.0)


def test_a_particle_as_dense_as_the_fluid_floats():
    model, state = settling(1030.0, 2e-4, fluid_array(density=1030.0, viscosity=1e-3,
                                                      drag="schiller_naumann",
                                                      buoyancy=True))
    sim = bondem.Simulation(model, state, time_step=1e-5, force_time_step=True)
    sim.step(1000)
    assert np.abs(sim.state.velocity).max() < 1e-12 * 9.81 * sim.state.time
    # without buoyancy nor drag it falls freely (the leapfrog's velocity half a step
    # behind its time)
    model, state = settling(1030.0, 2e-4, fluid_array(density=1030.0, viscosity=1e-3,
                                                      drag="none", buoyancy=False))
    sim = bondem.Simulation(model, state, time_step=1e-5, force_time_step=True)
    sim.step(1000)
    assert sim.state.velocity[0, 2] == pytest.approx(-9.81 * (sim.state.time - 0.5e-5),
                                                     rel=1e-12)


def test_a_bonded_cluster_takes_up_a_uniform_flow_at_its_summed_drag_rate():
    """Four bonded spheres of two sizes at rest in a Stokes flow u, placed so that their
    drag centre is their mass centre (two large ones across x, two small ones across y:
    no torque, no spin): the momentum grows as sum_i 3 pi mu d_i (u - v_i) and the
    cluster moves as one, so its velocity is u (1 - exp(-t / T)), T = M / (3 pi mu sum
    d_i), between the large spheres' own relaxation time and the small ones'."""
    glass = Material(name="glass", density=2500.0, young_modulus=1e7, poisson_ratio=0.3)
    radius = np.array([1.5e-4, 1.5e-4, 1e-4, 1e-4])
    centre = np.array([3e-3, -1e-3, 2e-3])
    position = centre + np.array([[2e-4, 0.0, 0.0], [-2e-4, 0.0, 0.0], [0.0, 2.5e-4, 0.0],
                                  [0.0, -2.5e-4, 0.0]])
    bonds = np.array([[0, 2], [2, 1], [1, 3], [3, 0], [0, 1], [2, 3]])
    u = np.array([0.02, -0.01, 0.005])
    mu = 1.8e-3
    binder = bondem.BondMaterial(young_modulus=1e7, poisson_ratio=0.3, breakage="none")
    model, state = make_system(position, radius, glass, bonds=bonds, bond_diameter=1e-4,
                               bond_material=binder,
                               fluid=fluid_array(viscosity=mu, velocity=u, drag="stokes"))
    total = model.mass.sum()
    rate = 3.0 * math.pi * mu * 2.0 * radius.sum() / total
    sim = bondem.Simulation(model, state)
    sim.run(until=1.0 / rate)
    mean = (model.mass[:, None] * sim.state.velocity).sum(axis=0) / total
    np.testing.assert_allclose(mean, u * (1.0 - math.exp(-rate * sim.state.time)),
                               rtol=5e-3)
    # alone, the large spheres would lag and the small ones lead: the bonds hold them
    alone = 3.0 * math.pi * mu * 2.0 * radius / model.mass
    assert alone[0] < rate < alone[2]
    assert np.abs(sim.state.velocity - mean).max() < 1e-3 * np.abs(u).max()
    assert np.all(sim.state.bond_active)


def test_a_clump_settles_at_the_sum_of_its_spheres_stokes_drags():
    """Two touching unequal spheres, one rigid clump, its axis along gravity (their drags
    along it: no torque): it settles at (M - rho_f V) g / (6 pi mu (r_1 + r_2)), the
    clump's weight less its buoyancy over its members' summed Stokes drag coefficients;
    a rotating frame is refused for clumps (not modelled for them)."""
    from bondem.clumps import make_clumps
    rho_p, rho_f, mu, r1, r2 = 2500.0, 1000.0, 1e-3, 1e-4, 2e-4
    glass = Material(name="glass", density=rho_p, young_modulus=1e8, poisson_ratio=0.3)
    model, state = make_system([[0.0, 0.0, 0.0], [0.0, 0.0, r1 + r2]], [r1, r2], glass,
                               gravity=GRAVITY, fluid=fluid_array(
                                   density=rho_f, viscosity=mu, drag="stokes",
                                   buoyancy=True))
    model, state = make_clumps(model, state, [0, 0])
    volume = 4.0 / 3.0 * math.pi * (r1 ** 3 + r2 ** 3)
    drag = 6.0 * math.pi * mu * (r1 + r2)
    tau = rho_p * volume / drag
    sim = bondem.Simulation(model, state, time_step=tau / 200, force_time_step=True)
    sim.step(200 * 25)
    terminal = (rho_p - rho_f) * volume * GRAVITY[2] / drag
    assert state.clump_velocity[0] == pytest.approx([0.0, 0.0, terminal], rel=1e-9,
                                                    abs=1e-9 * abs(terminal))
    assert np.all(state.velocity[:, 2] == pytest.approx(terminal, rel=1e-9))
    model, state = make_system([[0.0, 0.0, 0.0], [0.0, 0.0, r1 + r2]], [r1, r2], glass,
                               frame=bondem.model.frame_array((0.0, 0.0, 10.0)))
    model, state = make_clumps(model, state, [0, 0])
    with pytest.raises(ValueError, match=r"\[frame\] does not act on clumps"):
        bondem.Simulation(model, state)


def test_the_fluid_work_closes_the_energy_balance():
    rho_p, rho_f, mu, d = 2500.0, 1.2, 1.8e-5, 2e-4
    model, state = settling(rho_p, d, fluid_array(density=rho_f, viscosity=mu,
                                                  velocity=(0.3, 0.0, 0.1),
                                                  drag="schiller_naumann", buoyancy=True))
    sim = bondem.Simulation(model, state, time_step=1e-4, force_time_step=True)
    before = sum(sim.kinetic_energy())
    sim.run(until=0.5)
    gained = sum(sim.kinetic_energy()) - before
    assert gained > 0.0
    assert sim.state.work_external == pytest.approx(gained, rel=1e-9)


def test_di_felice_is_dallavalles_drag_in_a_lone_particle_and_grows_in_a_bed():
    # eps = 1: C_d = (0.63 + 4.8 / sqrt(Re))^2 (Dallavalle), no voidage factor
    assert drag_coefficient(3, 100.0) == pytest.approx((0.63 + 0.48) ** 2, rel=1e-14)
    from bondem.physics.field_fluid import fluid_force
    for eps in (1.0, 0.6):
        fluid = fluid_array(density=1000.0, viscosity=1e-3, velocity=(0.1, 0.0, 0.0),
                            drag="di_felice", voidage=eps)
        force = fluid_force(fluid, *NO_GRID, 5e-4, 1e-6, (1e-3, 0.0, 0.0), (0.0, 0.0, 0.0),
                            GRAVITY)
        re = 1000.0 * eps * 0.1 * 1e-3 / 1e-3
        chi = 3.7 - 0.65 * math.exp(-0.5 * (1.5 - math.log10(re)) ** 2)
        expected = (0.5 * 1000.0 * drag_coefficient(3, re) * math.pi / 4 * 1e-6 * 0.01
                    * eps ** (2.0 - chi))
        assert force[0] == pytest.approx(expected, rel=1e-12)
        assert force[1] == 0.0 and force[2] == 0.0
    # the voidage factor eps^(2 - chi) > 1 for chi ~ 3.7: a bed drags harder
    dense = fluid_force(fluid_array(density=1000.0, viscosity=1e-3, velocity=(0.1, 0, 0),
                                    drag="di_felice", voidage=0.6), *NO_GRID, 5e-4, 1e-6,
                       (0, 0, 0), (0, 0, 0), GRAVITY)
    lone = fluid_force(fluid_array(density=1000.0, viscosity=1e-3, velocity=(0.1, 0, 0),
                                   drag="di_felice"), *NO_GRID, 5e-4, 1e-6, (0, 0, 0),
                      (0, 0, 0), GRAVITY)
    assert dense[0] > 2.0 * lone[0]


SCENE = """
[simulation]
end_time = 1e-3
gravity = [0.0, 0.0, -9.81]
[materials.glass]
density = 2500.0
young_modulus = 1e9
poisson_ratio = 0.3
[particles]
file = "particles.csv"
[fluid]
{fluid}
"""


@pytest.mark.parametrize("fluid, key, message", [
    ('drag = "stoke"\nviscosity = 1e-3', "fluid.drag", "schiller_naumann"),
    ('drag = "stokes"', "fluid.viscosity", "needs viscosity"),
    ('drag = "schiller_naumann"\nviscosity = 1e-3', "fluid.density", "needs density"),
    ('voidage = 0.0', "fluid.voidage", "voidage"),
    ('density = -1.0', "fluid.density", "density"),
    ('speed = 1.0', "fluid.speed", "allowed"),
])
def test_bad_fluid_keys_are_named(tmp_path, fluid, key, message):
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-4,glass\n")
    (tmp_path / "scene.toml").write_text(SCENE.format(fluid=fluid))
    with pytest.raises(InputError) as error:
        load_scene(tmp_path / "scene.toml")
    assert error.value.key == key and message in str(error.value)


def test_a_scene_fluid_buoys_by_default_and_sets_the_time_step(tmp_path):
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-4,glass\n")
    (tmp_path / "scene.toml").write_text(SCENE.format(
        fluid='density = 998.0\nviscosity = 1e-3\ndrag = "stokes"'))
    scene = load_scene(tmp_path / "scene.toml")
    assert scene.model.acting_fields == ["fluid"] and scene.model.fields["fluid"][6] == 1.0
    sim = scene.make_simulation()
    tau = 2500.0 * 2e-4 ** 2 / (18.0 * 1e-3)
    from bondem.timestep import time_scales
    assert time_scales(scene.model)["fluid_drag"] == pytest.approx(tau, rel=1e-12)
    assert sim.time_step <= 0.2 * tau


RUNS = Path(bondem.__file__).parent / "data" / "validation" / "musen-runs"


def test_musens_viscous_field_imports_and_reproduces_the_real_musen_run(tmp_path):
    """viscous_field: a run of the real MUSEN 1.74.2 with ModelEFViscousField (four
    spheres, one in each branch of its drag curve and one far into the last). Imported
    from its text scene and cmusen script, the scene's [fluid] is MUSEN's medium; run in
    MUSEN-compatible mode it follows MUSEN's positions and velocities to 1e-12 of their
    largest values (the refdata rows of bondem validate)."""
    from bondem.io.musen_text import import_musen
    from bondem.validation import refdata
    folder = RUNS / "viscous_field"
    path, notes = import_musen(folder / "musen_scene.txt", tmp_path,
                               folder / "musen_script.txt")
    import tomllib
    table = tomllib.loads(path.read_text())["fluid"]
    assert table == {"density": 1000.0, "viscosity": 1e-5 * 1000.0, "drag": "musen_viscous",
                     "buoyancy": False}
    assert (path.parent / "particles.csv").read_text() == \
        (folder / "particles.csv").read_text()
    run = next(r for r in refdata.discover(RUNS) if r.name == "viscous_field")
    rows = refdata.compare_run(run, None)
    assert len(rows) == 2 and all(r.passed for r in rows), rows
    # another external force model is named, not dropped
    script = tmp_path / "script.txt"
    script.write_text("MODEL_EF ModelEFHeatTransfer\n")
    _, notes = import_musen(folder / "musen_scene.txt", tmp_path / "other", script)
    assert any("ModelEFHeatTransfer: not mapped" in n for n in notes)


def rotation(axis_angle):
    """The rotation matrix of the rotation vector ``axis_angle`` (rad), Rodrigues."""
    angle = np.linalg.norm(axis_angle)
    k = axis_angle / angle
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def test_a_free_sphere_in_a_rotating_frame_moves_straight_in_the_inertial_one():
    """No force acts: in the inertial frame the sphere keeps its velocity and its spin.
    Seen from a frame turning at Omega about c (a skew axis), its position is
    R(-Omega t) (x_in(t) - c) + c and its spin R(-Omega t) w_in - Omega; the centrifugal,
    Coriolis and spin torques make exactly that as the step shrinks (the forces take the
    velocity half a step behind: first order, error ~ |Omega| dt |x - c|)."""
    from bondem.model import frame_array
    omega = np.array([0.3, -0.2, 2.0])
    center = np.array([0.1, -0.2, 0.05])
    x0 = np.array([0.4, 0.1, -0.3])
    v_in = np.array([0.05, 0.2, -0.1])
    w_in = np.array([3.0, -1.0, 0.5])
    glass = Material(name="glass", density=2500.0, young_modulus=1e9, poisson_ratio=0.3)
    errors = []
    for dt in (2e-5, 1e-5):
        model, state = make_system(x0[None], np.array([1e-3]), [glass],
                                   velocity=(v_in - np.cross(omega, x0 - center))[None],
                                   angular_velocity=(w_in - omega)[None],
                                   frame=frame_array(omega, center))
        sim = bondem.Simulation(model, state, time_step=dt, force_time_step=True)
        sim.run(until=0.5)
        t = sim.state.time
        exact = rotation(-omega * t) @ (x0 + v_in * t - center) + center
        error = np.abs(sim.state.position[0] - exact).max()
        assert error < np.linalg.norm(omega) * dt * np.linalg.norm(x0 - center)
        errors.append(error)
        spin = rotation(-omega * (t - 0.5 * dt)) @ w_in - omega
        assert np.abs(sim.state.angular_velocity[0] - spin).max() \
            < 10 * np.linalg.norm(omega) * dt * np.linalg.norm(w_in)
    assert 1.7 < errors[0] / errors[1] < 2.3   # first order


def load_example(name):
    import importlib.util
    path = Path(__file__).resolve().parents[1] / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_two_way_coupling_conserves_momentum_and_ends_at_the_mean_velocity():
    """examples/coupled_gas_column.py: particles at rest in a periodic gas column that
    moves; the solver gives each particle Stokes drag and its cell the opposite, for the
    interval bondem says the loads act (the first one half a step shorter: the start-up
    kick). With no other force the total momentum stays what it was at every exchange,
    and gas and particles end at P / (M_gas + M_particles)."""
    example = load_example("coupled_gas_column")
    sim, gas, grid = example.column()
    totals = []

    def solver(exchange):
        totals.append((sim.model.mass[:, None] * exchange.velocity).sum(axis=0)
                      + gas.momentum())
        if len(totals) == 1:
            assert exchange.interval == pytest.approx(9.5 * sim.time_step, rel=1e-12)
        assert exchange.voidage.shape == (1, 1, gas.cells)
        return gas(exchange)

    coupling = sim.couple(solver, every=10, grid=grid)
    sim.run(until=0.15)
    assert coupling.exchanges == 1500
    totals = np.array(totals)
    np.testing.assert_allclose(totals, np.broadcast_to(totals[0], totals.shape),
                               rtol=1e-12, atol=1e-22)
    mean = totals[0] / (sim.model.mass.sum() + gas.mass().sum())
    np.testing.assert_allclose(sim.state.velocity, np.broadcast_to(mean, (20, 3)),
                               rtol=5e-3, atol=1e-6)
    np.testing.assert_allclose(gas.u, np.broadcast_to(mean, gas.u.shape), rtol=5e-3,
                               atol=1e-6)
    # the coupling's work is booked: kinetic energy gained = work of the external loads
    assert sim.state.work_external == pytest.approx(sum(sim.kinetic_energy()), rel=1e-9)


def test_voidage_of_a_grid_and_bad_coupling_answers():
    from bondem.coupling import voidage_grid
    position = np.array([[0.5e-3, 0.5e-3, 0.5e-3], [1.5e-3, 0.2e-3, 0.7e-3],
                         [1.6e-3, 0.3e-3, 0.1e-3], [5e-3, 0.0, 0.0]])
    radius = np.array([1e-4, 2e-4, 1.5e-4, 3e-4])
    voidage = voidage_grid(position, radius, (0, 0, 0), (2e-3, 1e-3, 1e-3), (2, 1, 1))
    cell = 1e-9
    volume = 4 / 3 * np.pi * radius ** 3
    np.testing.assert_allclose(voidage[:, 0, 0], [1 - volume[0] / cell,
                                                  1 - (volume[1] + volume[2]) / cell])
    glass = Material(name="glass", density=2500.0, young_modulus=1e9, poisson_ratio=0.3)
    model, state = make_system(position[:3], radius[:3], [glass])
    sim = bondem.Simulation(model, state, time_step=1e-6, force_time_step=True)
    sim.couple(lambda exchange: np.zeros((2, 3)))
    with pytest.raises(ValueError, match="3 x 3 finite numbers"):
        sim.step(1)


def test_musens_centrifugal_casting_reproduces_the_real_musen_run(tmp_path):
    """centrifugal_casting: a run of the real MUSEN 1.74.2 with
    ModelEFCentrifugalCasting (a liquid turning at 60 rad/s about y). Imported, it is
    the "musen_centrifugal" drag with the liquid's spin; run in MUSEN-compatible mode it
    follows MUSEN to 1e-12 (the refdata rows of bondem validate)."""
    from bondem.io.musen_text import import_musen
    from bondem.validation import refdata
    import tomllib
    folder = RUNS / "centrifugal_casting"
    path, _ = import_musen(folder / "musen_scene.txt", tmp_path, folder / "musen_script.txt")
    assert tomllib.loads(path.read_text())["fluid"] == {
        "density": 1100.0, "viscosity": 0.002, "drag": "musen_centrifugal",
        "buoyancy": False, "spin": [0.0, 60.0, 0.0]}
    run = next(r for r in refdata.discover(RUNS) if r.name == "centrifugal_casting")
    rows = refdata.compare_run(run, None)
    assert len(rows) == 2 and all(r.passed for r in rows), rows


def test_the_centrifugal_law_against_its_formula_off_the_axis():
    """A sphere off a skew spin axis: Stokes drag in the turning liquid plus the net
    centrifugal force across the axis, each term from its definition."""
    from bondem.physics.field_fluid import fluid_force
    spin = np.array([1.0, 2.0, -0.5])
    x, v = np.array([0.01, -0.02, 0.005]), np.array([0.1, 0.0, -0.2])
    r, rho, mu = 4e-4, 1100.0, 2e-3
    mass = 2500.0 * 4 / 3 * np.pi * r ** 3
    fluid = fluid_array(density=rho, viscosity=mu, drag="musen_centrifugal", spin=spin)
    axis = spin / np.linalg.norm(spin)
    across = x - np.dot(x, axis) * axis
    expected = (6 * np.pi * mu * r * (np.cross(spin, x) - v)
                + (mass - rho * 4 / 3 * np.pi * r ** 3) * np.dot(spin, spin) * across)
    np.testing.assert_allclose(fluid_force(fluid, *NO_GRID, r, mass, tuple(x), tuple(v),
                                           GRAVITY), expected, rtol=1e-12)


def test_the_fields_force_is_saved_and_exported(tmp_path):
    """A sphere settling at its Stokes terminal velocity in a run through bondem run,
    beside a fixed one twice its size: results.h5 holds the fields' force on it, which
    then balances its weight (the drag and buoyancy of the last frame: (rho_p - rho_f) V g
    upward), ParaView's files carry it, and the report and bondem analyze show the
    fields' total and the share of the moving particles' weight they carry (1; the fixed
    sphere's weight, 8 times the other's, does not count)."""
    import h5py
    from click.testing import CliRunner
    from bondem.cli import main
    rho_p, rho_f, mu, d = 2650.0, 998.0, 1e-3, 1e-4
    (tmp_path / "particles.csv").write_text(
        f"x,y,z,radius,material,fixed\n0,0,0,{d / 2},glass,0\n0.01,0,0,{d},glass,1\n")
    tau = rho_p * d * d / (18 * mu)
    (tmp_path / "scene.toml").write_text(SCENE.format(
        fluid=f'density = {rho_f}\nviscosity = {mu}\ndrag = "stokes"').replace(
        "end_time = 1e-3", f"end_time = {20 * tau}\ntime_step = {tau / 50}\n"
        "force_time_step = true\nsave_every = " + repr(10 * tau)).replace(
        "density = 2500.0", f"density = {rho_p}"))
    runner = CliRunner()
    result = runner.invoke(main, ["run", str(tmp_path / "scene.toml"), "--out",
                                  str(tmp_path / "run"), "--no-progress"])
    assert result.exit_code == 0, result.output
    weight = (rho_p - rho_f) * math.pi / 6 * d ** 3 * 9.81
    with h5py.File(tmp_path / "run" / "results.h5", "r") as f:
        field = f["particles/field_force"][-1, 0]
        assert f["particles/field_force"].attrs["unit"] == "N"
    # at the terminal velocity the fluid carries the whole weight m g: drag (rho_p -
    # rho_f) V g plus buoyancy rho_f V g
    assert field[2] == pytest.approx(rho_p * math.pi / 6 * d ** 3 * 9.81, rel=1e-6)
    assert field[2] - rho_f * math.pi / 6 * d ** 3 * 9.81 == pytest.approx(weight, rel=1e-6)
    result = runner.invoke(main, ["export", "vtk", str(tmp_path / "run" / "results.h5"),
                                  "--out", str(tmp_path / "vtk")])
    assert result.exit_code == 0, result.output
    assert b'Name="field_force"' in (tmp_path / "vtk" / "particles_000002.vtp").read_bytes()
    from bondem.analysis.report import write_report
    from bondem.analysis.summary import summarize
    numbers = summarize(tmp_path / "run" / "results.h5")
    assert numbers["weight_carried_by_fields"] == pytest.approx(1.0, rel=1e-6)
    assert numbers["field_force_total"] == pytest.approx(rho_p * math.pi / 6 * d ** 3 * 9.81,
                                                         rel=1e-6)
    assert numbers["field_force_mean"] == pytest.approx(numbers["field_force_total"] / 2,
                                                        rel=1e-12)
    report, _ = write_report(tmp_path / "run" / "results.h5")
    text = report.read_text()
    assert '<figure id="fields">' in text
    assert "weight carried by fields" in text


def rotating_flow_grid(spin, low, high, shape):
    """Node values of the rigid rotation spin x x on a grid: (velocity, origin, spacing)."""
    axes = [np.linspace(low[a], high[a], shape[a]) for a in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    spacing = (np.array(high) - np.array(low)) / (np.array(shape) - 1)
    return np.cross(spin, nodes), np.array(low, dtype=float), spacing


def test_a_flow_grid_of_a_linear_field_drags_as_the_field_itself():
    """Trilinear interpolation reproduces a linear field exactly: a rigid rotation given
    on a coarse, uneven grid drags two spheres as the analytic spin does (to round-off),
    over a path that crosses many cells."""
    spin = np.array([20.0, -35.0, 50.0])
    low, high, shape = (-0.02, -0.015, -0.016), (0.02, 0.015, 0.012), (5, 4, 8)
    velocity, origin, spacing = rotating_flow_grid(spin, low, high, shape)
    runs = []
    for use_grid in (False, True):
        glass = Material(name="glass", density=2500.0, young_modulus=1e9,
                         poisson_ratio=0.3)
        model, state = make_system(np.array([[0.004, -0.003, 0.002], [-0.006, 0.005, 0.0]]),
                                   np.array([2e-4, 3e-4]), [glass],
                                   fluid=fluid_array(density=1000.0, viscosity=1e-3,
                                                     drag="schiller_naumann",
                                                     spin=(0.0, 0.0, 0.0) if use_grid
                                                     else spin))
        if use_grid:
            model.set_flow(velocity, origin, spacing)
        sim = bondem.Simulation(model, state, time_step=2e-5, force_time_step=True)
        sim.run(until=0.05)
        runs.append(sim.state.position.copy())
    travelled = np.abs(runs[0] - [[0.004, -0.003, 0.002], [-0.006, 0.005, 0.0]]).max()
    assert travelled > 2 * spacing.min()       # it crossed cells
    assert np.all((runs[0] > low) & (runs[0] < high))   # and stayed in the grid
    np.testing.assert_allclose(runs[1], runs[0], rtol=0, atol=1e-12 * travelled)


def test_flow_velocity_interpolates_and_holds_the_faces_outside():
    from bondem.physics.field_fluid import flow_velocity
    rng = np.random.default_rng(3)
    flow = rng.uniform(-1.0, 1.0, (3, 2, 4, 3))
    box = np.array([1.0, -2.0, 0.5, 0.1, 0.2, 0.05])
    node = lambda i, j, k: box[:3] + box[3:] * [i, j, k]  # noqa: E731
    # at a node: its value
    assert np.allclose(flow_velocity(flow, box, tuple(node(2, 1, 3))), flow[2, 1, 3])
    # the middle of a cell: the mean of its 8 nodes
    middle = tuple(node(0.5, 0.5, 1.5))
    assert np.allclose(flow_velocity(flow, box, middle), flow[0:2, 0:2, 1:3].mean(axis=(0, 1, 2)))
    # beyond the +x face and below the z origin: the face's values
    assert np.allclose(flow_velocity(flow, box, tuple(node(7.0, 1.0, -3.0))), flow[2, 1, 0])
    # no grid: nothing
    assert flow_velocity(flow, np.zeros(6), (0.0, 0.0, 0.0)) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("write, message", [
    (lambda f: f.create_dataset("speed", data=np.zeros((2, 2, 2, 3))), "no dataset 'velocity'"),
    (lambda f: f.create_dataset("velocity", data=np.zeros((2, 2, 2, 3))), "no attribute 'origin'"),
    (lambda f: f.create_dataset("velocity", data=np.zeros((2, 2, 3))), "(nx, ny, nz, 3)"),
])
def test_a_scene_flow_file_and_its_defects(tmp_path, write, message):
    import h5py
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0,0,0,1e-4,glass\n")
    fluid = 'density = 1000.0\nviscosity = 1e-3\ndrag = "stokes"\nvelocity_file = "flow.h5"'
    (tmp_path / "scene.toml").write_text(SCENE.format(fluid=fluid))
    with h5py.File(tmp_path / "flow.h5", "w") as f:
        f.attrs["spacing"] = [1e-3, 1e-3, 1e-3]
        write(f)
        if "velocity" in f and f["velocity"].ndim == 3:
            f.attrs["origin"] = [0.0, 0.0, 0.0]
    with pytest.raises(InputError) as error:
        load_scene(tmp_path / "scene.toml")
    assert error.value.key == "fluid.velocity_file" and message in str(error.value)
    # a good file: the grid is the model's
    velocity, origin, spacing = rotating_flow_grid(np.array([0.0, 0.0, 3.0]),
                                                   (-1e-3, -1e-3, -1e-3), (1e-3, 1e-3, 1e-3),
                                                   (3, 3, 3))
    with h5py.File(tmp_path / "flow.h5", "w") as f:
        f["velocity"] = velocity
        f["velocity"].attrs["origin"] = origin
        f["velocity"].attrs["spacing"] = spacing
    model = load_scene(tmp_path / "scene.toml").model
    assert np.array_equal(model.flow, velocity)
    assert np.array_equal(model.flow_box, np.r_[origin, spacing])


def test_a_drum_in_its_rotating_frame_moves_as_the_drum_turning_as_a_wall():
    """A bowl turning at 11 rad/s about a vertical axis off the origin, five spheres on
    its floor: in the bowl's frame (walls at rest, centrifugal and Coriolis forces) and in
    the laboratory (the bowl a turning mesh wall, the spheres carried round at first) the
    spheres take the same paths, the laboratory's mapped by R(-Omega t) (x - c) + c.
    Before they reach the side the two agree to 1e-6 m (the frame's forces are first order
    in Omega dt); after they have rolled into it and each other, to 2e-3 of the radius
    (first order: halving the step shrinks it, docs/fields.md)."""
    from bondem.validation.core import load_parameters
    from bondem.validation.fields import drum_runs
    d = load_parameters("fields")["drum"]
    start = np.array(d["positions"])
    rows = drum_runs(d, [0.1, d["time"]])
    (t1, x1, mapped1, _, _), (t2, x2, mapped2, w2, w_mapped2) = rows
    assert np.abs(x1 - mapped1).max() < 1e-6
    assert np.abs(x2 - mapped2).max() < 2e-3 * d["radius"]
    assert np.abs(w2 - w_mapped2).max() < 2e-2 * d["angular_velocity"]
    # the motion is not trivial: all thrown out against the side
    axis = np.array(d["center"])
    out = np.linalg.norm((x2 - axis)[:, :2], axis=1)
    assert np.all(out > np.linalg.norm(start[:, :2], axis=1) + 5e-3)
    assert np.all(out > d["radius"] - d["particle_radius"] - 1e-3)
    assert t2 == pytest.approx(d["time"])


@pytest.mark.parametrize("fluid_on, frame_on", [(True, True), (True, False), (False, True),
                                                (False, False)])
def test_the_acting_fields_forces_add_and_the_idle_ones_add_nothing(fluid_on, frame_on):
    """Stokes drag 3 pi mu d (u - v) and the frame's -m (Omega x (Omega x (x - c)) +
    2 Omega x v) on three spheres: both together add up, each alone is itself, neither
    gives zero (the loops call only the acting models: field_models.switches)."""
    from bondem.backends.cpu import field_force_array
    from bondem.model import frame_array
    mu, u = 1.3e-3, np.array([0.2, -0.1, 0.05])
    omega, center = np.array([0.4, -1.1, 2.5]), np.array([0.01, 0.02, -0.03])
    position = np.array([[0.1, 0.2, -0.05], [-0.3, 0.05, 0.2], [0.02, -0.2, 0.1]])
    velocity = np.array([[0.3, 0.1, -0.2], [0.0, -0.4, 0.1], [0.05, 0.05, 0.6]])
    radius = np.array([1e-3, 2e-3, 1.5e-3])
    glass = Material(name="glass", density=2500.0, young_modulus=1e9, poisson_ratio=0.3)
    fields = {}
    if fluid_on:
        fields["fluid"] = fluid_array(viscosity=mu, velocity=u, drag="stokes")
    if frame_on:
        fields["frame"] = frame_array(omega, center)
    model, state = make_system(position, radius, [glass], velocity=velocity, **fields)
    mass = 2500.0 * 4.0 / 3.0 * np.pi * radius ** 3
    expected = np.zeros((3, 3))
    if fluid_on:
        expected += 3.0 * np.pi * mu * (2.0 * radius)[:, None] * (u - velocity)
    if frame_on:
        arm = position - center
        expected -= mass[:, None] * (np.cross(omega, np.cross(omega, arm))
                                     + 2.0 * np.cross(omega, velocity))
    got = field_force_array(model, state)
    if fluid_on or frame_on:
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=0.0)
    else:
        assert np.all(got == 0.0)

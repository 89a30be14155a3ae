"""The results file (SPEC 6) written from constructed systems, without a simulation: each
dataset must hold what its definition says of the state appended (a bond's force is its
spring's stretch plus its tangential force, a broken bond carries nothing, a contact row
is a loaded contact, a wall's row is j = -1 - w), and the cuts of a resume and a rewrite
keep whole frames and the history evaluated before the checkpoint. The periodic box
starts off zero and is not symmetric; bond materials are not the defaults.

tests/test_results.py checks the same file against real runs."""
import fcntl
import types

import h5py
import numpy as np
import pytest

from bondem import BondMaterial, Material, make_system
from bondem._version import __version__
from bondem.io import results
from bondem.io.results import (FRAME_CHUNK_ROWS, ResultsWriter, UnreadableResults,
                               bond_forces, contact_rows, count_walls, open_results,
                               read_results, rewrite_results, write_wall_geometry)
from bondem.physics.field_frame import frame_array
from bondem.walls import MeshWall, PlaneWall, WallHistory

GLASS = Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, name="glass")
STEEL = Material(density=7800.0, young_modulus=2e9, poisson_ratio=0.28, name="steel")
BINDER = BondMaterial(young_modulus=3.0e7, poisson_ratio=0.25, name="binder")
CEMENT = BondMaterial(young_modulus=8.0e7, poisson_ratio=0.2, name="cement")
LOW, HIGH = np.array([-0.012, -0.5, -0.5]), np.array([0.009, 0.5, 0.5])  # x periodic, 0.021 m
POSITION = np.array([[-0.008, 0.0, 0.0], [-0.006, 0.001, 0.0], [0.0085, 0.0005, 0.0002],
                     [0.003, -0.002, 0.001]])
BONDS = np.array([[0, 1], [1, 2], [2, 3]])
DIAMETER = np.array([1.0e-3, 0.6e-3, 0.8e-3])


def system(**extra):
    """4 particles, 3 bonds (bond 1 across the periodic x boundary), two bond materials."""
    return make_system(POSITION.copy(), radius=[1e-3, 0.9e-3, 1.1e-3, 0.7e-3],
                       material=[GLASS, STEEL], material_index=[0, 1, 1, 0],
                       bonds=BONDS, bond_diameter=DIAMETER, bond_material=[BINDER, CEMENT],
                       bond_material_index=[1, 0, 1], periodic=[True, False, False],
                       box_low=LOW, box_high=HIGH, gravity=(0.0, -9.81, 0.5), **extra)


class FakeSim:
    """What the writer reads of a Simulation: model, state, walls, loads, energies."""

    def __init__(self, model, state, walls=(), energy=("kinetic", "bond_elastic")):
        self.model, self.state, self.walls = model, state, list(walls)
        self.time_step, self.time_step_cause = 2.5e-7, "bond 1 (Rayleigh)"
        self.force = np.zeros((model.n_particles, 3))
        self.energy = {name: 0.0 for name in energy}
        n = len(self.walls)
        self.wall_force = np.zeros((n, 3))
        self.wall_torque = np.zeros((n, 3))
        self.wall_history = WallHistory(n) if n else None
        self.contacts = types.SimpleNamespace(walls=types.SimpleNamespace(
            element_wall=np.array([1, 0, 1, 1])))   # element -> wall

    def energy_terms(self):
        return dict(self.energy)

    def wall_positions(self):
        return np.array([getattr(w, "point", np.zeros(3)) for w in self.walls]) + self.state.time


def plane():
    return PlaneWall((0.0, -0.004, 0.0), (0.0, 3.0, 4.0), STEEL, velocity=(0.0, 0.02, 0.0))


def mesh():
    vertices = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]])
    return MeshWall(vertices, [[0, 1, 2], [0, 1, 3]], GLASS, velocity=(0.001, 0.0, -0.002),
                    angular_velocity=(0.0, 0.0, 3.0), rotation_center=(0.005, 0.006, 0.007))


def hooke(stretched, young, diameter, initial):
    """E A (L - L0) / L0 along x_j - x_i: the bond's normal force on particle i (SPEC 2)."""
    length = np.linalg.norm(stretched)
    return young * np.pi * diameter ** 2 / 4.0 * (length - initial) / initial * stretched / length


def test_bond_force_is_the_stretched_spring_plus_the_tangential_force():
    model, state = system()
    across = POSITION[2] - POSITION[1] - [0.021, 0.0, 0.0]   # the nearest image, -x
    assert model.bond_initial_length[1] == pytest.approx(np.linalg.norm(across), rel=1e-15, abs=0)
    state.position[1] += [-0.0002, 0.0001, 0.0]     # bond 0 shortened, bond 1 stretched
    state.position[3] += [0.0, 0.0, 0.0004]
    state.bond_tangential_force[:] = [[0.0, 0.5, -0.25], [1.5, 0.0, 0.0], [-2.0, 0.0, 3.0]]
    force = bond_forces(model, state)
    first = hooke(state.position[1] - state.position[0], 8.0e7, 1.0e-3,
                  np.linalg.norm(POSITION[1] - POSITION[0]))
    second = hooke(state.position[2] - state.position[1] - [0.021, 0.0, 0.0], 3.0e7, 0.6e-3,
                   np.linalg.norm(across))
    third = hooke(state.position[3] - state.position[2], 8.0e7, 0.8e-3,
                  np.linalg.norm(POSITION[3] - POSITION[2]))
    assert first[0] < 0.0 < second[0]     # compressed pushes i away, stretched pulls it on
    np.testing.assert_allclose(force, [first + [0.0, 0.5, -0.25], second + [1.5, 0.0, 0.0],
                                       third + [-2.0, 0.0, 3.0]], rtol=1e-12, atol=0.0)
    state.bond_active[1] = False
    force = bond_forces(model, state)
    assert np.all(force[1] == 0.0) and np.all(force[0] != 0.0) and np.all(force[2] != 0.0)
    empty, _ = make_system(POSITION, radius=1e-3, material=GLASS)
    assert bond_forces(empty, _).shape == (0, 3)


def test_contact_rows_are_the_loaded_contacts_particle_pairs_first():
    model, state = system()
    sim = FakeSim(model, state, walls=[plane(), mesh()])
    state.extra["contact_pairs"] = np.array([[0, 1], [1, 3], [2, 3]])
    state.extra["contact_force"] = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 0.5],
                                             [0.0, 0.0, -1e-300]])
    state.extra["wall_pairs"] = np.array([[3, 0], [2, 1], [0, 3], [1, 2]])   # particle, element
    state.extra["wall_force_rows"] = np.array([[0.0, 4.0, 0.0], [0.0, 0.0, 0.0],
                                               [7.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    i, j, force = contact_rows(sim)
    # elements 0 and 3 belong to walls 1 and 1: j = -1 - wall
    assert i.tolist() == [1, 2, 3, 0] and j.tolist() == [3, 3, -2, -2]
    assert i.dtype == j.dtype == np.int64 and force.dtype == np.float64
    np.testing.assert_array_equal(force, [[1.0, -2.0, 0.5], [0.0, 0.0, -1e-300],
                                          [0.0, 4.0, 0.0], [7.0, 0.0, 0.0]])
    sim.contacts = None                      # no wall objects: only the particle pairs
    assert contact_rows(sim)[0].tolist() == [1, 2]
    state.extra["contact_pairs"] = np.zeros((0, 2), np.int64)
    state.extra["contact_force"] = np.zeros((0, 3))
    sim.contacts = types.SimpleNamespace(walls=types.SimpleNamespace(
        element_wall=np.array([0, 0, 1, 0])))
    i, j, force = contact_rows(sim)
    assert i.tolist() == [3, 0] and j.tolist() == [-1, -1]


def test_contact_rows_of_a_system_without_contacts_are_empty():
    model, state = system()
    for extra in ({}, {"contact_pairs": np.zeros((0, 2), np.int64),
                       "wall_pairs": np.zeros((0, 2), np.int64)}):
        state.extra = dict(extra)
        i, j, force = contact_rows(FakeSim(model, state))
        assert (i.shape, j.shape, force.shape) == ((0,), (0,), (0, 3))
        assert i.dtype == j.dtype == np.int64 and force.dtype == np.float64


def test_wall_geometry_holds_each_walls_kind_motion_and_mesh(tmp_path):
    with h5py.File(tmp_path / "g.h5", "w") as f:
        write_wall_geometry(f, [plane(), mesh()])
        g = f["walls/geometry"]
        assert g["type"][()].tolist() == [0, 1] and g["type"].dtype == np.int8
        np.testing.assert_array_equal(g["point"][()], [[0.0, -0.004, 0.0], [0.0, 0.0, 0.0]])
        np.testing.assert_allclose(g["normal"][()], [[0.0, 0.6, 0.8], [0.0, 0.0, 0.0]],
                                   rtol=1e-15)
        np.testing.assert_array_equal(g["velocity"][()], [[0.0, 0.02, 0.0],
                                                          [0.001, 0.0, -0.002]])
        np.testing.assert_array_equal(g["angular_velocity"][()], [[0.0] * 3, [0.0, 0.0, 3.0]])
        np.testing.assert_array_equal(g["rotation_center"][()], [[0.0] * 3,
                                                                 [0.005, 0.006, 0.007]])
        assert {k: g[k].attrs["unit"] for k in ("point", "normal", "velocity",
                                                "angular_velocity", "rotation_center")} == {
            "point": "m", "normal": "1", "velocity": "m/s", "angular_velocity": "rad/s",
            "rotation_center": "m"}
        assert "mesh0" not in g and g["mesh1/vertices"].attrs["unit"] == "m"
        np.testing.assert_array_equal(g["mesh1/vertices"][()], mesh().vertices)
        np.testing.assert_array_equal(g["mesh1/triangles"][()], [[0, 1, 2], [0, 1, 3]])
    with h5py.File(tmp_path / "none.h5", "w") as f:
        write_wall_geometry(f, [])
        assert f["walls/geometry/point"].shape == (0, 3)
    assert count_walls(types.SimpleNamespace()) == 0
    assert count_walls(types.SimpleNamespace(walls=None)) == 0
    assert count_walls(types.SimpleNamespace(walls=[plane(), mesh()])) == 2


@pytest.fixture
def written(tmp_path):
    """A file with 3 frames of a system with two walls, contacts, breaks and history."""
    model, state = system()
    sim = FakeSim(model, state, walls=[plane(), mesh()])
    path = tmp_path / "results.h5"
    frames = []
    with ResultsWriter(path, sim, scene_text="[scene]\n", scene_name="box/a.toml",
                       backend="cpu") as writer:
        for k in range(3):
            state.time = [1e-4, 2e-4, 3e-4][k]
            state.position[2, 1] += 1e-5 * (k + 1)
            state.velocity[0] = [0.1 * k, -0.2, 0.3]
            state.angular_velocity[3] = [0.0, 5.0 * k, 0.0]
            state.bond_normal_moment[:] = [[1e-6, 2e-6, 3e-6]] * 3
            state.bond_tangential_moment[:] = [[-4e-6, 0.0, 5e-6 * (k + 1)]] * 3
            sim.force[1] = [k, 2.0 * k, -1.0]
            sim.wall_force = np.array([[0.0, 3.0 * k, 0.0], [k, 0.0, 1.0]])
            sim.wall_torque = lambda k=k: np.array([[0.0, 0.0, 0.5 * k], [0.25, 0.0, 0.0]])
            sim.energy = {"kinetic": 1e-9 * (k + 1)}     # "bond_elastic" not given: NaN
            if k == 1:                 # bond 2 breaks in shear before frame 1
                state.bond_active[2] = False
                state.bond_break_time[2], state.bond_break_mode[2] = 1.5e-4, 3
            for t in (state.time - 6e-5, state.time - 2e-5):   # two history rows a frame
                sim.wall_history.record(t, np.full((2, 3), t), np.full((2, 3), -t))
            state.extra["contact_pairs"] = np.array([[0, 1], [1, 3]])[:k + 1]
            state.extra["contact_force"] = np.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])[:k + 1]
            frames.append((state.position.copy(), bond_forces(model, state)))
            writer.append(sim)
        assert writer.n_frames == 3
    return path, sim, frames


def test_a_new_file_has_every_dataset_its_constants_and_attributes(tmp_path):
    model, state = system()
    sim = FakeSim(model, state, walls=[plane()])
    path = tmp_path / "results.h5"
    with ResultsWriter(path, sim, scene_text="[scene]\nname = 'a'\n", backend="gpu",
                       scene_name="box/a.toml", material_names=["m0", "m1"]) as writer:
        assert writer.n_frames == 0
        assert not (tmp_path / "results.h5.new").exists()
    with h5py.File(path) as f:
        a = f.attrs
        assert (a["scene"], a["scene_name"], a["backend"], a["bondem_version"]) == (
            "[scene]\nname = 'a'\n", "box/a.toml", "gpu", __version__)
        assert a["time_step"] == 2.5e-7 and a["time_step_cause"] == "bond 1 (Rayleigh)"
        assert (a["n_particles"], a["n_bonds"], a["n_walls"]) == (4, 3, 1)
        assert a["periodic"].tolist() == [True, False, False]
        np.testing.assert_allclose(a["box_length"], [0.021, 1.0, 1.0], rtol=1e-15)
        assert a["gravity"].tolist() == [0.0, -9.81, 0.5]
        assert f["materials/names"].asstr()[()].tolist() == ["m0", "m1"]
        assert f["bond_materials/names"].asstr()[()].tolist() == ["binder", "cement"]
        np.testing.assert_array_equal(f["particles/radius"][()], [1e-3, 0.9e-3, 1.1e-3, 0.7e-3])
        assert f["particles/material"][()].tolist() == [0, 1, 1, 0]
        assert f["particles/material"].dtype == np.int32 == f["bonds/material"].dtype
        np.testing.assert_array_equal(f["particles/mass"][()], model.mass)
        assert f["bonds/pairs"][()].tolist() == BONDS.tolist()
        np.testing.assert_array_equal(f["bonds/diameter"][()], DIAMETER)
        np.testing.assert_array_equal(f["bonds/initial_length"][()], model.bond_initial_length)
        assert f["bonds/material"][()].tolist() == [1, 0, 1]
        assert np.all(np.isnan(f["bonds/break_time"][()])) and f["bonds/break_time"].shape == (3,)
        assert f["bonds/break_mode"][()].tolist() == [0, 0, 0]
        assert f["bonds/break_mode"].dtype == np.int8
        shapes = {"time": (0,), "particles/position": (0, 4, 3), "particles/velocity": (0, 4, 3),
                  "particles/angular_velocity": (0, 4, 3), "particles/force": (0, 4, 3),
                  "bonds/active": (0, 3), "bonds/force": (0, 3, 3),
                  "bonds/normal_moment": (0, 3, 3), "bonds/tangential_moment": (0, 3, 3),
                  "walls/force": (0, 1, 3), "walls/torque": (0, 1, 3),
                  "walls/position": (0, 1, 3), "walls/history/time": (0,),
                  "walls/history/force": (0, 1, 3), "walls/history/position": (0, 1, 3),
                  "energy/kinetic": (0,), "energy/bond_elastic": (0,), "contacts/end": (0,),
                  "contact_rows/i": (0,), "contact_rows/j": (0,), "contact_rows/force": (0, 3)}
        for name, shape in shapes.items():
            assert f[name].shape == shape, name
            assert f[name].maxshape[0] is None, name
            assert f[name].attrs["unit"] == ("J" if name.startswith("energy") else
                                             results.UNITS[name]), name
        assert f["bonds/active"].dtype == np.bool_
        assert f["contacts/end"].dtype == np.int64 == f["contact_rows/i"].dtype
        assert f["contact_rows/j"].dtype == np.int64
        for name in ("particles/radius", "particles/position", "contact_rows/force"):
            assert f[name].compression == "gzip" and f[name].shuffle, name
        # big runs: a frame's chunk of (N,3) rows is bounded
        assert f["particles/position"].chunks == (1, 4, 3)
        assert "particles/field_force" not in f and "particles/fixed" not in f
        assert "particles/clump" not in f and "clumps" not in f
    with ResultsWriter(tmp_path / "plain.h5", FakeSim(model, state), compression=None):
        pass
    with h5py.File(tmp_path / "plain.h5") as f:
        assert f["particles/position"].compression is None
        assert not f["particles/position"].shuffle and not f["particles/radius"].shuffle
        assert f["materials/names"].asstr()[()].tolist() == ["glass", "steel"]
        assert "walls/history" not in f and f["walls/force"].shape == (0, 0, 3)
        assert f.attrs["scene"] == "" and f.attrs["backend"] == "cpu"
        assert f.attrs["scene_name"] == ""


def test_big_frames_are_chunked_in_bounded_rows(tmp_path, monkeypatch):
    monkeypatch.setattr(results, "FRAME_CHUNK_ROWS", 3)
    model, state = system()
    with ResultsWriter(tmp_path / "r.h5", FakeSim(model, state)):
        pass
    with h5py.File(tmp_path / "r.h5") as f:
        assert f["particles/position"].chunks == (1, 3, 3)
        assert f["bonds/active"].chunks == (1, 3)
        assert f["time"].chunks == (1024,)
        assert f["contact_rows/force"].chunks == (4096, 3)
    assert FRAME_CHUNK_ROWS * 3 * 8 < 2 ** 21    # a chunk of (N,3) float64 under 2 MB


def test_frames_hold_the_states_appended(written):
    path, sim, frames = written
    data = read_results(path)
    assert data["time"].tolist() == [1e-4, 2e-4, 3e-4]
    for k, (position, force) in enumerate(frames):
        np.testing.assert_array_equal(data["particles/position"][k], position)
        np.testing.assert_array_equal(data["bonds/force"][k], force)
        np.testing.assert_array_equal(data["particles/velocity"][k, 0], [0.1 * k, -0.2, 0.3])
        np.testing.assert_array_equal(data["particles/angular_velocity"][k, 3],
                                      [0.0, 5.0 * k, 0.0])
        np.testing.assert_array_equal(data["particles/force"][k, 1], [k, 2.0 * k, -1.0])
        np.testing.assert_array_equal(data["walls/force"][k], [[0.0, 3.0 * k, 0.0],
                                                               [k, 0.0, 1.0]])
        np.testing.assert_array_equal(data["walls/torque"][k], [[0.0, 0.0, 0.5 * k],
                                                                [0.25, 0.0, 0.0]])
        t = data["time"][k]
        np.testing.assert_array_equal(data["walls/position"][k],
                                      [[t, -0.004 + t, t], [t] * 3])
    assert data["bonds/active"].tolist() == [[True] * 3, [True, True, False],
                                             [True, True, False]]
    assert np.all(data["bonds/force"][1:, 2] == 0.0) and np.all(data["bonds/force"][0, 2] != 0)
    # moments of a broken bond are not loads: zero; the intact ones as the state held them
    assert np.all(data["bonds/normal_moment"][1:, 2] == 0.0)
    assert np.all(data["bonds/tangential_moment"][1:, 2] == 0.0)
    np.testing.assert_array_equal(data["bonds/normal_moment"][2, :2], [[1e-6, 2e-6, 3e-6]] * 2)
    np.testing.assert_array_equal(data["bonds/tangential_moment"][2, 1], [-4e-6, 0.0, 5e-6 * 3])
    np.testing.assert_array_equal(data["bonds/normal_moment"][0, 2], [1e-6, 2e-6, 3e-6])
    assert data["energy/kinetic"].tolist() == [1e-9 * (k + 1) for k in range(3)]
    assert np.all(np.isnan(data["energy/bond_elastic"]))
    assert data["bonds/break_mode"].tolist() == [0, 0, 3]
    assert np.isnan(data["bonds/break_time"][:2]).all() and data["bonds/break_time"][2] == 1.5e-4
    # frame k's contacts: rows end[k-1]:end[k]; the unloaded contact is not a row
    assert data["contacts/end"].tolist() == [1, 2, 3]
    assert data["contact_rows/i"].tolist() == [0, 0, 0]
    assert data["contact_rows/j"].tolist() == [1, 1, 1]
    np.testing.assert_array_equal(data["contact_rows/force"], [[0.5, 0.0, 0.0]] * 3)
    # the history's rows, two per frame, before the frame's time
    np.testing.assert_allclose(data["walls/history/time"],
                               [4e-5, 8e-5, 1.4e-4, 1.8e-4, 2.4e-4, 2.8e-4], rtol=1e-12)
    np.testing.assert_array_equal(data["walls/history/force"][:, 1, 2],
                                  data["walls/history/time"])
    np.testing.assert_array_equal(data["walls/history/position"][:, 0, 0],
                                  -data["walls/history/time"])
    assert data["attrs"]["scene_name"] == "box/a.toml"
    assert data["walls/geometry/type"].tolist() == [0, 1]
    np.testing.assert_array_equal(data["walls/geometry/mesh1/triangles"], [[0, 1, 2], [0, 1, 3]])
    assert data["materials/names"].tolist() == ["glass", "steel"]
    assert data["materials/names"].dtype.kind == "U"


def test_a_break_later_than_the_last_written_one_is_written(tmp_path):
    """break_time and break_mode are rewritten when more bonds are broken than at the last
    frame, also when the same count of bonds broke at an earlier frame in the writer's own
    run (a bond that heals does not exist)."""
    model, state = system()
    sim = FakeSim(model, state)
    path = tmp_path / "r.h5"
    with ResultsWriter(path, sim) as writer:
        writer.append(sim)
        state.bond_active[0] = False
        state.bond_break_time[0], state.bond_break_mode[0] = 2e-6, 1
        writer.append(sim)
        with h5py.File(path) as f:
            assert f["bonds/break_mode"][()].tolist() == [1, 0, 0]
        state.bond_active[1] = False
        state.bond_break_time[1], state.bond_break_mode[1] = 3e-6, 2
        writer.append(sim)
    with h5py.File(path) as f:
        assert f["bonds/break_mode"][()].tolist() == [1, 2, 0]
        assert f["bonds/break_time"][:2].tolist() == [2e-6, 3e-6]


def test_energies_are_the_callers_when_given(tmp_path):
    model, state = system()
    sim = FakeSim(model, state)
    with ResultsWriter(tmp_path / "r.h5", sim) as writer:
        sim.energy = {"kinetic": 7.0, "bond_elastic": 8.0}
        writer.append(sim)
        writer.append(sim, energy={"kinetic": 1.0})
    data = read_results(tmp_path / "r.h5")
    assert data["energy/kinetic"].tolist() == [7.0, 1.0]
    assert data["energy/bond_elastic"][0] == 8.0 and np.isnan(data["energy/bond_elastic"][1])


def test_a_turning_frames_force_is_centrifugal_plus_coriolis(tmp_path):
    """F = -m w x (w x r) - 2 m w x v about the frame's centre: with w = (0, 0, W) and r
    in the xy-plane, m W^2 r outwards and 2 m W (v_y, -v_x, 0)."""
    w, centre = 40.0, np.array([0.001, -0.002, 0.0])
    model, state = system(frame=frame_array((0.0, 0.0, w), centre))
    model.fixed[3] = True
    state.velocity[1] = [0.3, -0.1, 0.0]
    sim = FakeSim(model, state)
    with ResultsWriter(tmp_path / "r.h5", sim) as writer:
        writer.append(sim)
    data = read_results(tmp_path / "r.h5")
    assert data["particles/fixed"].tolist() == [False, False, False, True]
    assert data["particles/field_force"].shape == (1, 4, 3)
    r = POSITION[1] - centre
    m = model.mass[1]
    expected = m * w ** 2 * np.array([r[0], r[1], 0.0]) + 2 * m * w * np.array([-0.1, -0.3, 0.0])
    np.testing.assert_allclose(data["particles/field_force"][0, 1], expected, rtol=1e-12,
                               atol=1e-15 * m * w ** 2)


def test_clumps_are_written_with_their_rigid_body_state(tmp_path):
    import dataclasses
    model, state = system()
    model = dataclasses.replace(model, clump_of=np.array([0, 0, -1, -1]),
                                clump_offset=np.zeros((4, 3)), clump_mass=np.array([3e-5]),
                                clump_inertia=np.array([[1e-12, 2e-12, 3e-12]]))
    state.clump_position = np.array([[0.001, 0.002, 0.003]])
    state.clump_orientation = np.array([[0.5, 0.5, 0.5, 0.5]])
    state.clump_velocity = np.array([[0.0, -1.0, 0.0]])
    state.clump_angular_momentum = np.array([[0.0, 0.0, 4e-9]])
    sim = FakeSim(model, state)
    with ResultsWriter(tmp_path / "r.h5", sim) as writer:
        writer.append(sim)
        state.clump_position = state.clump_position + 1e-3
        writer.append(sim)
    with h5py.File(tmp_path / "r.h5") as f:
        assert f["particles/clump"][()].tolist() == [0, 0, -1, -1]
        assert f["clumps/mass"][()].tolist() == [3e-5]
        assert f["clumps/inertia"].attrs["unit"] == "kg m^2"
        np.testing.assert_array_equal(f["clumps/position"][:, 0], [[0.001, 0.002, 0.003],
                                                                   [0.002, 0.003, 0.004]])
        assert f["clumps/orientation"].shape == (2, 1, 4)
        np.testing.assert_array_equal(f["clumps/orientation"][1, 0], [0.5] * 4)
        np.testing.assert_array_equal(f["clumps/velocity"][1, 0], [0.0, -1.0, 0.0])
        np.testing.assert_array_equal(f["clumps/angular_momentum"][0, 0], [0.0, 0.0, 4e-9])
        assert f["clumps/angular_momentum"].attrs["unit"] == "N m s"


def test_resume_cuts_frames_contact_rows_and_later_history(written):
    path, sim, _ = written
    state = sim.state
    state.time = 1.8e-4           # the checkpoint: after frame 1, at a history row's time
    state.bond_break_time[:] = [np.nan, 1.7e-4, 1.5e-4]
    state.bond_break_mode[:] = [0, 1, 3]
    writer = ResultsWriter(path, sim, resume_frames=2)
    try:
        assert writer.n_frames == 2 and writer.energy_names == ["bond_elastic", "kinetic"]
        with h5py.File(path) as f:
            assert f["time"][()].tolist() == [1e-4, 2e-4]
            assert f["particles/position"].shape[0] == f["bonds/force"].shape[0] == 2
            assert f["contacts/end"][()].tolist() == [1, 2]
            assert f["contact_rows/force"].shape == (2, 3)
            # rows evaluated before the checkpoint's time; the row at 1.8e-4 comes again
            np.testing.assert_allclose(f["walls/history/time"][()], [4e-5, 8e-5, 1.4e-4],
                                       rtol=1e-12)
            assert f["walls/history/force"].shape == (3, 2, 3)
            assert f["bonds/break_mode"][()].tolist() == [0, 1, 3]
            assert np.isnan(f["bonds/break_time"][0])
            assert f["bonds/break_time"][1:].tolist() == [1.7e-4, 1.5e-4]
        state.time = 2.5e-4
        writer.append(sim)
    finally:
        writer.close()
    data = read_results(path)
    assert data["time"].tolist() == [1e-4, 2e-4, 2.5e-4]
    assert data["contacts/end"].tolist() == [1, 2, 3]


def test_resume_needs_the_checkpoints_frames(written):
    path, sim, _ = written
    with pytest.raises(UnreadableResults) as error:
        ResultsWriter(path, sim, resume_frames=5)
    assert "holds 3 frames, the checkpoint needs 5" in str(error.value)
    assert str(path) in str(error.value)


def test_rewrite_keeps_the_whole_frames_and_rows(written):
    """A kill within an append leaves some datasets a row longer than /time (written
    last): those rows are not a frame. Likewise the wall history's time is written last."""
    path, _, _ = written
    with h5py.File(path, "r+") as f:
        for name in ("particles/position", "bonds/force"):
            f[name].resize(4, axis=0)
        f["walls/history/force"].resize(7, axis=0)
        f["contacts/end"][2] = 3
    assert rewrite_results(path) == 3
    with h5py.File(path) as f:
        assert f["particles/position"].shape[0] == f["bonds/force"].shape[0] == 3
        assert f["walls/history/force"].shape[0] == f["walls/history/time"].shape[0] == 6
        assert f["contact_rows/i"].shape == (3,)
        assert f.attrs["scene"] == "[scene]\n"
        assert f["particles/radius"].shape == (4,)
    assert rewrite_results(path, n_frames=1) == 1
    with h5py.File(path) as f:
        assert f["time"][()].tolist() == [1e-4] and f["contact_rows/j"].shape == (1,)
        assert f["walls/history/time"].shape == (6,)
    assert rewrite_results(path, n_frames=0, history_until=1e-4) == 0
    with h5py.File(path) as f:
        assert f["time"].shape == (0,) and f["contact_rows/force"].shape == (0, 3)
        np.testing.assert_allclose(f["walls/history/time"][()], [4e-5, 8e-5], rtol=1e-12)
    assert not (path.parent / "results.h5.rewrite").exists()


def test_files_that_are_not_results_are_named(tmp_path):
    scene = tmp_path / "cube.toml"
    scene.write_text("[simulation]\n")
    with pytest.raises(UnreadableResults) as error:
        open_results(scene)
    assert str(error.value) == (
        f"{scene}: this is a scene file, not results: give the results file its run "
        f"wrote, {tmp_path / 'cube' / 'results.h5'} (bondem run {scene} writes it)")
    text = tmp_path / "notes.TXT"
    text.write_text("hello\n")
    with pytest.raises(UnreadableResults) as error:
        read_results(text)
    assert str(error.value) == (f"{text}: not a results file (not HDF5): give the "
                                "results.h5 that bondem run wrote")
    scene_upper = tmp_path / "big.TOML"
    scene_upper.write_text("x = 1\n")
    with pytest.raises(UnreadableResults, match="this is a scene file"):
        open_results(scene_upper)
    missing = tmp_path / "gone.h5"
    with pytest.raises(UnreadableResults) as error:
        open_results(missing)
    assert str(error.value).startswith(f"{missing}: cannot open as HDF5 (")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = [1.0]
    with pytest.raises(UnreadableResults) as error:
        rewrite_results(other)
    assert str(error.value) == f"{other}: no /time dataset (not a bondem results file)"
    with pytest.raises(UnreadableResults) as error:
        rewrite_results(text)
    assert str(error.value).startswith(f"{text}: not a results file (not HDF5)")
    cut = tmp_path / "cut.h5"
    cut.write_bytes(other.read_bytes()[:1000])     # an HDF5 file cut short
    with pytest.raises(UnreadableResults) as error:
        open_results(cut)
    assert str(error.value).startswith(f"{cut}: cannot open as HDF5 (")
    assert not (tmp_path / "other.h5.rewrite").exists()


def test_hdf5_reason_is_the_text_in_brackets():
    assert results._hdf5_reason(OSError("Unable to open (file signature not found)")) == \
        "file signature not found"
    assert results._hdf5_reason(OSError("no brackets")) == "no brackets"
    assert results._hdf5_reason(OSError("Unable to open (bad (nested) thing)")) == \
        "bad (nested) thing"
    assert results._hdf5_reason(OSError("Unable to open (error in MAX)")) == "error in MAX"
    error = results._unreadable("x.h5", OSError("Unable to read (truncated)"), "cannot read")
    assert str(error) == "x.h5: cannot read (truncated)"


def test_a_held_lock_means_a_running_writer(written):
    path, _, _ = written
    lock = path.parent / results.LOCK_NAME
    assert not results._writer_running(path)          # no lock file
    lock.write_bytes(b"")
    assert not results._writer_running(path)          # a lock nobody holds
    with open(lock, "rb") as held:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert results._writer_running(path)
        with open_results(path) as f:                 # the live reader follows the writer
            assert f.swmr_mode and f["time"].shape == (3,)
        with open_results(path, live=False) as f:
            assert not f.swmr_mode
        fcntl.flock(held, fcntl.LOCK_UN)
    assert not results._writer_running(path)
    with open(lock, "rb") as held:                    # a reader's shared lock is no writer
        fcntl.flock(held, fcntl.LOCK_SH | fcntl.LOCK_NB)
        assert not results._writer_running(path)
    with open_results(path) as f:
        assert not f.swmr_mode


def test_the_watchman_ends_with_the_writer(tmp_path):
    model, state = system()
    writer = ResultsWriter(tmp_path / "r.h5", FakeSim(model, state))
    guard = writer._guard
    import os
    import time
    time.sleep(0.3)
    assert guard is not None and guard.poll() is None     # waits for the writer's pipe
    assert os.getsid(guard.pid) != os.getsid(0)
    writer.close()
    assert writer._guard is None and guard.poll() is not None
    writer.close()                                    # twice is harmless


def test_a_writer_killed_within_a_frame_leaves_a_readable_file(tmp_path):
    """The watchman lives in a session of its own: killing the writer's whole process
    group (Ctrl-C in a shell, a batch system) leaves it to clear the "open for write"
    mark, after which a plain reader opens the file with its whole frames."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path
    path = tmp_path / "r.h5"
    model, state = system()
    sim = FakeSim(model, state)
    with ResultsWriter(path, sim) as writer:      # the first frame from this process
        writer.append(sim)
    child = subprocess.Popen(
        [sys.executable, "-c", KILLED_WRITER, str(path), str(Path(__file__).parent)],
        stdout=subprocess.PIPE, start_new_session=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        assert child.stdout.readline().strip() == b"within a frame"
        with pytest.raises(OSError, match="already open for write"):
            h5py.File(path, "r")
        with open_results(path) as f:            # a live reader reads through SWMR
            assert f["time"].shape == (1,)
    finally:
        os.killpg(child.pid, signal.SIGKILL)
        child.wait()
    for _ in range(100):
        try:
            with h5py.File(path, "r") as f:
                assert f["time"][()].tolist() == [0.0]
            break
        except OSError:
            time.sleep(0.1)
    else:
        raise AssertionError("the open-for-write mark was not cleared")


KILLED_WRITER = """
import sys, time
sys.path.insert(0, sys.argv[2])
from test_results_writer import FakeSim, system
from bondem.io.results import ResultsWriter
model, state = system()
sim = FakeSim(model, state)
writer = ResultsWriter(sys.argv[1], sim, resume_frames=1)
handle = writer._open()
print("within a frame", flush=True)
time.sleep(60)
"""


def test_a_reader_holding_the_file_does_not_stop_the_writer(tmp_path):
    """HDFView or a notebook holds the file with HDF5's lock; the writer takes none."""
    import subprocess
    import sys
    model, state = system()
    sim = FakeSim(model, state)
    path = tmp_path / "r.h5"
    with ResultsWriter(path, sim) as writer:
        writer.append(sim)
        reader = subprocess.Popen(
            [sys.executable, "-c", "import sys, time, h5py\nf = h5py.File(sys.argv[1], 'r')\n"
             "print('reading', flush=True)\ntime.sleep(60)", str(path)],
            stdout=subprocess.PIPE)
        try:
            assert reader.stdout.readline().strip() == b"reading"
            state.time = 1e-6
            writer.append(sim)
        finally:
            reader.kill()
            reader.wait()
    assert read_results(path)["time"].tolist() == [0.0, 1e-6]


class DeviceArray:
    """A device array as numba.cuda gives it: only copy_to_host reads it."""

    def __init__(self, host):
        self.host = host

    def copy_to_host(self):
        return self.host.copy()


def test_a_gpu_simulations_device_arrays_and_contact_rows(tmp_path):
    model, state = system()
    sim = FakeSim(model, state)
    pulled = []
    sim.contacts = types.SimpleNamespace(walls=None, _pull_history=pulled.append)
    sim.backend_name = "gpu"
    sim.force = DeviceArray(np.arange(12.0).reshape(4, 3))
    with ResultsWriter(tmp_path / "r.h5", sim) as writer:
        writer.append(sim)
        assert pulled == [state]           # the device's contact rows, before they are read
        sim.backend_name = "cpu"
        sim.force = np.ones((4, 3))
        writer.append(sim)
        assert len(pulled) == 1            # the CPU's rows are the state's own
        del sim.backend_name               # a Simulation of before the GPU backend: the CPU
        writer.append(sim)
        assert len(pulled) == 1
    data = read_results(tmp_path / "r.h5")
    np.testing.assert_array_equal(data["particles/force"][0], np.arange(12.0).reshape(4, 3))
    bare = types.SimpleNamespace(model=model, state=state, force=np.zeros((4, 3)),
                                 time_step=1e-7, energy_terms=dict)
    with ResultsWriter(tmp_path / "bare.h5", bare) as writer:   # no walls, contacts, cause
        writer.append(bare)
    with h5py.File(tmp_path / "bare.h5") as f:
        assert f.attrs["time_step_cause"] == "" and f.attrs["n_walls"] == 0
        assert f["walls/force"].shape == (1, 0, 3) and f["walls/geometry/type"].shape == (0,)
        assert "energy" not in f and f["contacts/end"][()].tolist() == [0]


def test_one_wall_one_bond_and_one_history_row(tmp_path):
    model, state = make_system(POSITION[:2], radius=1e-3, material=GLASS, bonds=[[0, 1]],
                               bond_diameter=5e-4, bond_material=BINDER)
    state.position[1, 0] += 1e-5
    sim = FakeSim(model, state, walls=[plane()], energy=())
    sim.wall_force = np.array([[0.0, 0.0, 2.5]])
    sim.wall_torque = None
    sim.wall_positions = None
    sim.wall_history.record(0.0, np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 3)))
    path = tmp_path / "r.h5"
    with ResultsWriter(path, sim, bond_material_names=["glue"]) as writer:
        writer.append(sim)
        assert writer.energy_names == []
    with h5py.File(path) as f:
        assert f["walls/force"][0].tolist() == [[0.0, 0.0, 2.5]]
        assert f["walls/torque"][0].tolist() == [[0.0] * 3] == f["walls/position"][0].tolist()
        assert f["walls/history/force"][()].tolist() == [[[0.0, 0.0, 1.0]]]
        assert f["bond_materials/names"].asstr()[()].tolist() == ["glue"]
        assert f["walls/force"].chunks == (1, 1, 3) and f["bonds/force"].chunks == (1, 1, 3)
        assert f["bonds/break_mode"].attrs["unit"] == "1"
        expected = hooke(state.position[1] - state.position[0], 3e7, 5e-4,
                         np.linalg.norm(POSITION[1] - POSITION[0]))
        np.testing.assert_allclose(f["bonds/force"][0, 0], expected, rtol=1e-12)
        assert f["bonds/force"][0, 0, 0] > 0.0     # stretched: pulls particle 0 towards 1
    with ResultsWriter(path, sim, resume_frames=1) as writer:   # a file without energies
        assert writer.energy_names == [] and writer.n_frames == 1
    nobonds, state = make_system(POSITION, radius=1e-3, material=GLASS)
    sim = types.SimpleNamespace(model=nobonds, state=state, force=np.zeros((4, 3)),
                                time_step=1e-7, energy_terms=dict, walls=None)
    with ResultsWriter(tmp_path / "n.h5", sim) as writer:
        writer.append(sim)
    with h5py.File(tmp_path / "n.h5") as f:
        assert f["bonds/pairs"].shape == (0, 2) and f["bonds/force"].shape == (1, 0, 3)


def test_a_rewrite_that_fails_leaves_the_file_and_names_it(written):
    path, _, _ = written
    with h5py.File(path, "r+") as f:
        del f["walls/history/time"]     # the history's other rows without their times
    before = path.read_bytes()
    with pytest.raises(UnreadableResults) as error:
        rewrite_results(path, history_until=1.0)
    assert str(error.value).startswith(f"{path}: cannot read (")
    assert "doesn't exist" in str(error.value)      # HDF5's reason: the dataset missing
    assert path.read_bytes() == before and not (path.parent / "results.h5.rewrite").exists()

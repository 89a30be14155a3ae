"""The lab's specimens against their definitions: a specimen's extent, cross-sections and
solids fraction of each shape on bodies that are not symmetric (off the origin, radii that
differ, extents that differ along each axis), the simple cubic lattice's bonds counted
and measured, the cylinder cut from it, carving at exact boundaries, random specimens
inside their containers and the same for the same seed, and a scene's body taken whole.
Every message is compared whole."""
import math
import types

import numpy as np
import pytest

import bondem
import bondem.scene
import bondem.lab.specimen as specimen_module
from bondem.lab.specimen import (ADHESIVE, Specimen, _container, _inside, box_widths,
                                 lattice_specimen, make_specimen, specimen_from_scene)

GLASS = bondem.Material(density=2500.0, young_modulus=1e8)
BINDER = bondem.BondMaterial(young_modulus=2e8, normal_strength=3e6)


def _body(shape="box", **kwargs):
    """Three particles off the origin, radii 1, 2 and 0.5 mm: the surfaces span x from
    -1 to 5.5 mm, y from -2 to 2.5 and z from 1 to 8 (extents 6.5, 4.5 and 7 mm)."""
    position = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 6.0], [5.0, 2.0, 7.5]]) * 1e-3
    return Specimen(position, [1e-3, 2e-3, 0.5e-3], [[0, 1], [1, 2]], 8e-4, GLASS, BINDER,
                    shape=shape, **kwargs)


def test_a_specimen_takes_scalars_and_single_materials():
    body = _body()
    assert body.radius.tolist() == [1e-3, 2e-3, 0.5e-3]
    assert body.bond_diameter.tolist() == [8e-4, 8e-4] and body.bond_diameter.flags.writeable
    assert body.materials == [GLASS] and body.bond_materials == [BINDER]
    assert body.material_index.tolist() == [0, 0, 0]
    assert body.bond_material_index.tolist() == [0, 0]
    assert body.material_index.dtype == body.bond_material_index.dtype == np.int64
    assert body.bonds.dtype == np.int64 and body.position.dtype == np.float64
    assert (body.n_particles, body.n_bonds, body.shape) == (3, 2, "box")
    assert body.coordination() == pytest.approx(4.0 / 3.0, rel=1e-15)
    assert body.adhesive() is False and body.lattice is False
    assert body.contact_model == "hertz_mindlin" and body.notes == []
    flat = Specimen(np.zeros((2, 3)) + [[0, 0, 0], [2e-3, 0, 0]], 1e-3, [0, 1], 1e-3,
                    GLASS, BINDER)
    assert flat.bonds.tolist() == [[0, 1]]


@pytest.mark.parametrize("kwargs, message", [
    (dict(shape="cube"), "shape = 'cube'; allowed: box, cylinder, disc, sphere"),
    (dict(position=np.zeros((1, 3)), bonds=np.zeros((0, 2))),
     "a specimen needs bonded particles (or an adhesive contact model: jkr, liquid_bridge, "
     "popov_jkr, vdw); it has 1 particles and 0 bonds"),
    (dict(bonds=np.zeros((0, 2))),
     "a specimen needs bonded particles (or an adhesive contact model: jkr, liquid_bridge, "
     "popov_jkr, vdw); it has 2 particles and 0 bonds"),
])
def test_a_specimen_that_cannot_be_tested_is_refused(kwargs, message):
    settings = dict(position=[[0, 0, 0], [2e-3, 0, 0]], radius=1e-3, bonds=[[0, 1]],
                    bond_diameter=1e-3, materials=GLASS, bond_materials=BINDER)
    settings.update(kwargs)
    with pytest.raises(ValueError) as error:
        Specimen(**settings)
    assert str(error.value) == message


def test_an_adhesive_body_needs_no_bonds():
    assert ADHESIVE == ("jkr", "liquid_bridge", "popov_jkr", "vdw")
    body = Specimen([[0, 0, 0], [2e-3, 0, 0]], 1e-3, np.zeros((0, 2)), [], GLASS, [],
                    contact_model="jkr")
    assert body.adhesive() and body.n_bonds == 0 and body.coordination() == 0.0
    model, state = body.system()
    assert model.bond_pairs.shape[0] == 0 and state.position.shape == (2, 3)


def test_extent_cross_sections_and_solids_fraction_of_each_shape():
    low, high = _body().bounds()
    np.testing.assert_allclose(low, [-1e-3, -2e-3, 1e-3], rtol=1e-15, atol=1e-18)
    np.testing.assert_allclose(high, [5.5e-3, 2.5e-3, 8e-3], rtol=1e-15)
    size = np.array([6.5e-3, 4.5e-3, 7e-3])
    np.testing.assert_allclose(_body().size(), size, rtol=1e-14)
    volume = 4.0 / 3.0 * math.pi * (1e-9 + 8e-9 + 0.125e-9)
    box, cylinder, disc, sphere = (_body(s) for s in ("box", "cylinder", "disc", "sphere"))
    # a box: width times depth normal to the axis
    assert box.cross_section() == pytest.approx(6.5e-3 * 4.5e-3, rel=1e-14)
    assert box.cross_section(0) == pytest.approx(4.5e-3 * 7e-3, rel=1e-14)
    assert box.cross_section(1) == pytest.approx(6.5e-3 * 7e-3, rel=1e-14)
    assert box.solids_fraction() == pytest.approx(volume / np.prod(size), rel=1e-13)
    # a cylinder (axis z): the circle of the mean lateral extent
    assert cylinder.cross_section() == pytest.approx(math.pi / 4 * 5.5e-3 ** 2, rel=1e-14)
    assert cylinder.cross_section(0) == pytest.approx(math.pi / 4 * 5.75e-3 ** 2, rel=1e-14)
    assert cylinder.solids_fraction() == pytest.approx(
        volume / (math.pi / 4 * 5.5e-3 ** 2 * 7e-3), rel=1e-13)
    # a disc (axis y) loaded across its diameter along z: diameter times thickness
    assert disc.cross_section() == pytest.approx(6.5e-3 * 4.5e-3, rel=1e-14)
    assert disc.cross_section(1) == pytest.approx(math.pi / 4 * 6.75e-3 ** 2, rel=1e-14)
    assert disc.solids_fraction() == pytest.approx(
        volume / (math.pi / 4 * 6.75e-3 ** 2 * 4.5e-3), rel=1e-13)
    assert sphere.cross_section() == pytest.approx(math.pi / 4 * 5.5e-3 ** 2, rel=1e-14)
    assert sphere.solids_fraction() == pytest.approx(volume / (math.pi / 6 * 6e-3 ** 3),
                                                     rel=1e-13)


def test_a_copy_with_other_bond_materials():
    body = _body(notes=["first"])
    second = bondem.BondMaterial(young_modulus=1e9, normal_strength=5e6, name="second")
    body.bond_materials = [BINDER, second]
    changed = body.with_bond_material(young_modulus=4e8, scale_normal_strength=1.5)
    assert [m.young_modulus for m in changed.bond_materials] == [4e8, 4e8]
    assert [m.normal_strength for m in changed.bond_materials] == [4.5e6, 7.5e6]
    assert changed.bond_materials[1].name == "second"
    assert [m.young_modulus for m in body.bond_materials] == [2e8, 1e9]   # unchanged
    changed.notes.append("later")
    assert body.notes == ["first"]
    assert changed.position is body.position or np.array_equal(changed.position,
                                                               body.position)


def test_the_system_of_a_specimen():
    body = _body()
    fixed = np.array([True, False, False])
    velocity = np.array([[0, 0, 0], [0, 0, 0.5], [0, 0, 0]])
    model, state = body.system(fixed=fixed, velocity=velocity, damping=0.3)
    np.testing.assert_array_equal(state.position, body.position)
    np.testing.assert_array_equal(state.velocity, velocity)
    np.testing.assert_array_equal(model.radius, body.radius)
    assert model.bond_pairs.tolist() == [[0, 1], [1, 2]]
    np.testing.assert_allclose(model.bond_initial_length,
                               [math.sqrt(9 + 16) * 1e-3, math.sqrt(4 + 4 + 2.25) * 1e-3],
                               rtol=1e-14)
    np.testing.assert_array_equal(model.bond_diameter, [8e-4, 8e-4])
    assert model.bond_materials[0] == BINDER and model.materials[0] == GLASS
    assert model.fixed.tolist() == [True, False, False]
    assert model.damping == 0.3


# ---------------------------------------------------------------- the lattice

def test_a_lattice_of_chains():
    body = lattice_specimen((3, 4, 5), 1e-3, GLASS, BINDER, diameter_ratio=0.4)
    assert body.n_particles == 60 and body.lattice and body.shape == "box"
    # (nx - 1) ny nz + nx (ny - 1) nz + nx ny (nz - 1)
    assert body.n_bonds == 2 * 4 * 5 + 3 * 3 * 5 + 3 * 4 * 4
    lengths = np.linalg.norm(body.position[body.bonds[:, 1]] - body.position[body.bonds[:, 0]],
                             axis=1)
    np.testing.assert_allclose(lengths, 2e-3, rtol=1e-12)
    assert np.all(body.bonds[:, 0] < body.bonds[:, 1])
    assert body.bonds.tolist() == sorted(body.bonds.tolist())
    np.testing.assert_allclose(body.position.mean(axis=0), 0.0, atol=1e-18)
    np.testing.assert_allclose(body.size(), [6e-3, 8e-3, 10e-3], rtol=1e-14)   # n a
    np.testing.assert_allclose(body.bond_diameter, 0.8e-3, rtol=1e-15)
    assert body.notes == ["simple cubic lattice 3 x 4 x 5, spacing 0.002 m"]
    spaced = lattice_specimen((2, 1, 1), 1e-3, GLASS, BINDER, spacing=2.5e-3,
                              bond_diameter=1.2e-3, contact_model="linear")
    assert spaced.position.tolist() == [[-1.25e-3, 0.0, 0.0], [1.25e-3, 0.0, 0.0]]
    assert spaced.bond_diameter.tolist() == [1.2e-3] and spaced.contact_model == "linear"


def test_a_lattice_cut_to_a_cylinder_keeps_the_chains_within_its_radius():
    body = lattice_specimen((5, 6, 3), 1e-3, GLASS, BINDER, shape="cylinder")
    # centres within (min(5, 6) - 1) a / 2 = 4 mm of the z axis through the middle
    full = lattice_specimen((5, 6, 3), 1e-3, GLASS, BINDER)
    rho = np.hypot(full.position[:, 0], full.position[:, 1])
    kept = full.position[rho <= 4e-3 * (1 + 1e-9)]
    np.testing.assert_array_equal(body.position, kept)
    assert body.shape == "cylinder" and body.n_particles == kept.shape[0] < 90
    lengths = np.linalg.norm(body.position[body.bonds[:, 1]] - body.position[body.bonds[:, 0]],
                             axis=1)
    np.testing.assert_allclose(lengths, 2e-3, rtol=1e-12)
    # every pair of kept neighbours is bonded: count them directly
    gaps = np.linalg.norm(kept[:, None] - kept[None], axis=2)
    assert body.n_bonds == int(np.sum(np.isclose(gaps, 2e-3)) // 2)
    assert body.notes[0].endswith(", cut to a cylinder of centres within 0.004 m of the axis")


@pytest.mark.parametrize("counts, shape, message", [
    ((3, 3), "box", "counts = [3, 3]: expected three integers >= 1"),
    ((3, 0, 3), "box", "counts = [3, 0, 3]: expected three integers >= 1"),
    ((1, 1, 1), "box", "counts = [1, 1, 1]: expected three integers >= 1"),
    ((3, 3, 3), "disc", "shape = 'disc'; a lattice is a box or a cylinder"),
])
def test_a_lattice_that_cannot_be_made(counts, shape, message):
    with pytest.raises(ValueError) as error:
        lattice_specimen(counts, 1e-3, GLASS, BINDER, shape=shape)
    assert str(error.value) == message


# ---------------------------------------------------------------- containers and carving

def test_containers_of_each_shape():
    centre = np.array([1.0, -2.0, 0.5])
    box = _container("box", [2.0, 4.0, 6.0], centre)
    assert [b.tolist() for b in box.bounds()] == [[0.0, -4.0, -2.5], [2.0, 0.0, 3.5]]
    cylinder = _container("cylinder", [2.0, 5.0], centre)
    assert [b.tolist() for b in cylinder.bounds()] == [[0.0, -3.0, -2.0], [2.0, -1.0, 3.0]]
    disc = _container("disc", [4.0, 1.0], centre)
    assert [b.tolist() for b in disc.bounds()] == [[-1.0, -2.5, -1.5], [3.0, -1.5, 2.5]]
    sphere = _container("sphere", [3.0], centre)
    assert [b.tolist() for b in sphere.bounds()] == [[-0.5, -3.5, -1.0], [2.5, -0.5, 2.0]]


@pytest.mark.parametrize("shape, size, message", [
    ("box", [1.0, 2.0], "a box specimen's size is [x, y, z] (m)"),
    ("cylinder", [1.0], "a cylinder specimen's size is [diameter, height] (m)"),
    ("disc", [1.0, 2.0, 3.0], "a disc specimen's size is [diameter, thickness] (m)"),
    ("sphere", [1.0, 2.0], "a sphere specimen's size is [diameter] (m)"),
])
def test_a_container_of_the_wrong_size(shape, size, message):
    with pytest.raises(ValueError) as error:
        _container(shape, size, np.zeros(3))
    assert str(error.value) == message


def test_carving_keeps_the_whole_spheres_inside():
    """Binary-exact positions: a sphere touching the boundary from inside is kept, one
    poking out by 1/64 of its radius is not."""
    r = np.full(4, 0.25)
    box = np.array([[0.75, 0.0, 0.0], [0.0, -1.75, 0.0], [0.0, 0.0, 2.75],
                    [0.765625, 0.0, 0.0]])
    assert _inside("box", [2.0, 4.0, 6.0], box, r).tolist() == [True, True, True, False]
    cylinder = np.array([[0.45, 0.6, 0.0], [0.0, 0.0, 2.25], [0.0, 0.0, -2.265625],
                         [0.6, 0.8, 0.0]])
    # rho 0.75 + 0.25 = 1 on the radius; the last at rho 1
    assert _inside("cylinder", [2.0, 5.0], cylinder, r).tolist() == \
        [True, True, False, False]
    disc = np.array([[0.6, 0.0, 0.45], [0.0, 0.25, 0.0], [0.0, -0.265625, 0.0],
                     [1.75, 0.0, 0.0]])
    assert _inside("disc", [2.0, 1.0], disc, r).tolist() == [True, True, False, False]
    sphere = np.array([[0.75, 0.0, 1.0], [1.25, 0.0, 0.0], [0.0, -1.265625, 0.0],
                       [0.0, 0.0, 0.0]])         # |p| = 1.25 for the first two: touching
    assert _inside("sphere", [3.0], sphere, r).tolist() == [True, True, False, True]


# ---------------------------------------------------------------- random specimens

def test_a_random_box_specimen_inside_its_container():
    size = [4e-3, 3e-3, 5e-3]
    body = make_specimen("box", size, particle_radius=4e-4, material=GLASS,
                         bond_material=BINDER, max_gap=1e-4, seed=2, solids_fraction=0.4,
                         diameter_ratio=0.6)
    low, high = body.bounds()
    assert np.all(low >= -0.5 * np.array(size) - 1e-12)
    assert np.all(high <= 0.5 * np.array(size) + 1e-12)
    assert body.solids_fraction() > 0.3 and body.shape == "box"
    gaps = (np.linalg.norm(body.position[body.bonds[:, 0]] - body.position[body.bonds[:, 1]],
                           axis=1) - 8e-4)
    assert np.all(gaps <= 1e-4 + 1e-12) and body.n_bonds > body.n_particles
    np.testing.assert_allclose(body.bond_diameter, 0.6 * 8e-4, rtol=1e-14)
    assert body.notes == [f"{body.n_particles} particles, {body.n_bonds} bonds, coordination "
                          f"{body.coordination():.2f}, solids fraction "
                          f"{body.solids_fraction():.3f}"]
    specimen_module._geometries.clear()      # packed afresh, not the kept packing
    again = make_specimen("box", size, particle_radius=4e-4, material=GLASS,
                          bond_material=BINDER, max_gap=1e-4, seed=2, solids_fraction=0.4,
                          diameter_ratio=0.6)
    np.testing.assert_array_equal(again.position, body.position)
    other = make_specimen("box", size, particle_radius=4e-4, material=GLASS,
                          bond_material=BINDER, max_gap=1e-4, seed=3, solids_fraction=0.4)
    assert not np.array_equal(other.position, body.position)
    capped = make_specimen("box", size, particle_radius=4e-4, material=GLASS,
                           bond_material=BINDER, max_gap=1e-4, seed=2, solids_fraction=0.4,
                           max_per_particle=2)
    assert np.bincount(capped.bonds.ravel()).max() <= 2


def test_random_specimens_of_the_other_shapes():
    for shape, size, axis in (("cylinder", [4e-3, 5e-3], 2), ("disc", [5e-3, 2e-3], 1),
                              ("sphere", [5e-3], None)):
        body = make_specimen(shape, size, particle_radius=4e-4, material=GLASS,
                             bond_material=BINDER, max_gap=5e-5, seed=1, solids_fraction=0.35)
        assert body.shape == shape
        if axis is None:
            reach = np.linalg.norm(body.position, axis=1) + body.radius
            assert reach.max() <= 2.5e-3 + 1e-9
        else:
            lateral = [k for k in range(3) if k != axis]
            rho = np.hypot(*body.position[:, lateral].T) + body.radius
            assert rho.max() <= 0.5 * size[0] + 1e-9
            assert np.max(np.abs(body.position[:, axis]) + body.radius) <= 0.5 * size[1] + 1e-9


def test_an_adhesive_agglomerate_without_bonds_and_the_refusals():
    body = make_specimen("sphere", [4e-3], particle_radius=4e-4, material=GLASS,
                         bond_material=None, contact_model="vdw", seed=1, solids_fraction=0.35)
    assert body.n_bonds == 0 and body.bond_materials == [] and body.contact_model == "vdw"
    with pytest.raises(ValueError) as error:
        make_specimen("prism", [1.0], particle_radius=0.1, material=GLASS,
                      bond_material=BINDER)
    assert str(error.value) == "shape = 'prism'; allowed: box, cylinder, disc, sphere"
    with pytest.raises(ValueError) as error:
        make_specimen("sphere", [4e-3], particle_radius=4e-4, material=GLASS,
                      bond_material=None)
    assert str(error.value) == (
        "bond_material: required with contact_model = 'hertz_mindlin' (without bonds only "
        "an adhesive model holds a body: jkr, liquid_bridge, popov_jkr, vdw)")


# ---------------------------------------------------------------- walls and scenes

class _Wall:
    def __init__(self, normal, start, speed):
        self.normal, self.start, self.speed = np.array(normal, float), np.array(start), speed
        self.asked = 0

    def position(self, time):
        self.asked += 1
        return self.start + self.speed * time * self.normal


def test_box_widths_between_each_pair_of_planes_once_per_time():
    walls = [_Wall((1, 0, 0), (-1.0, 0, 0), 0.5), _Wall((-1, 0, 0), (3.0, 0, 0), 0.25),
             _Wall((0, 1, 0), (0, -2.0, 0), 0.0), _Wall((0, -1, 0), (0, 0.5, 0), 1.0),
             _Wall((0, 0, 1), (0, 0, 1.0), 0.0), _Wall((0, 0, -1), (0, 0, 1.5), 0.0)]
    sim = types.SimpleNamespace(state=types.SimpleNamespace(time=0.0))
    width = box_widths(sim, walls)
    assert (width(0), width(1), width(2)) == (4.0, 2.5, 0.5)
    assert [w.asked for w in walls] == [1] * 6      # one look per wall per time
    sim.state.time = 2.0
    assert (width(0), width(1)) == (2.5, 0.5)
    assert [w.asked for w in walls] == [2] * 6


SCENE = """
[simulation]
end_time = 1e-4
contact_model = "linear"
[materials.glass]
density = 2500.0
young_modulus = 1e8
[bond_materials.binder]
young_modulus = 3e8
normal_strength = 1e6
[particles]
generator = { shape = "box", low = [-2e-3, -2e-3, -2e-3], high = [2e-3, 2e-3, 3e-3], \
particle_radius = 5e-4, solids_fraction = 0.4, seed = 3, material = "glass" }
[bonds]
max_gap = 1e-4
diameter_ratio = 0.5
material = "binder"
"""


def test_a_scenes_body_as_a_specimen(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE)
    scene = bondem.scene.load_scene(path)
    body = specimen_from_scene(path, shape="cylinder")
    assert body.shape == "cylinder" and body.contact_model == "linear"
    assert body.notes == [f"from {path}"]
    np.testing.assert_array_equal(body.position, scene.state.position)
    np.testing.assert_array_equal(body.radius, scene.model.radius)
    np.testing.assert_array_equal(body.bonds, scene.model.bond_pairs)
    np.testing.assert_allclose(body.bond_diameter, 5e-4, rtol=1e-14)
    assert body.materials[0].density == 2500.0 and body.bond_materials[0].young_modulus == 3e8
    assert body.material_index.dtype == body.bond_material_index.dtype == np.int64
    assert body.n_bonds > 0 and set(body.bond_material_index.tolist()) == {0}
    longer = specimen_from_scene(path, {"simulation.contact_model": "hertz_mindlin"})
    assert longer.contact_model == "hertz_mindlin" and longer.shape == "box"


def test_consolidation_presses_a_packing_to_its_stress():
    """Six servo planes press a loose packing to an isotropic 20 kPa: the walls' stress
    errors, reported as it goes, end within the tolerance, and the packing is denser,
    inside its first box; with too few steps it says it did not get there."""
    from bondem.generate import Box, pack_spheres
    from bondem.lab.specimen import consolidate
    position, radius = pack_spheres(Box([-2e-3, -2e-3, -2e-3], [2e-3, 2e-3, 2.5e-3]),
                                    radius=4e-4, solids_fraction=0.35, seed=4)
    before = Specimen(position, radius, [[0, 1]], 1e-4, GLASS, BINDER).solids_fraction()
    errors = []
    pressed, reached = consolidate(position, radius, GLASS, 2e4, max_steps=60_000,
                                   tolerance=0.05,
                                   progress=lambda done, total, error: errors.append(
                                       (done, total, error)))
    assert reached and errors[-1][2] <= 0.05 and errors[0][2] > 0.05
    assert [e[0] for e in errors] == list(range(0, 500 * len(errors), 500))
    assert {e[1] for e in errors} == {60_000}
    after = Specimen(pressed, radius, [[0, 1]], 1e-4, GLASS, BINDER).solids_fraction()
    assert after > before + 0.05
    low, high = (pressed - radius[:, None]).min(axis=0), (pressed + radius[:, None]).max(axis=0)
    assert np.all(low >= (position - radius[:, None]).min(axis=0) - 1e-9)
    assert np.all(high <= (position + radius[:, None]).max(axis=0) + 1e-9)
    _, short = consolidate(position, radius, GLASS, 2e4, max_steps=500)
    assert short is False


def test_a_consolidated_specimen_is_carved_to_its_shape():
    body = make_specimen("cylinder", [4e-3, 5e-3], particle_radius=4e-4, material=GLASS,
                         bond_material=BINDER, max_gap=5e-5, seed=2, solids_fraction=0.35,
                         consolidation_stress=2e4, consolidation_steps=60_000)
    assert body.notes[0] == "consolidated to 2e+04 Pa"
    rho = np.hypot(body.position[:, 0], body.position[:, 1]) + body.radius
    assert rho.max() <= 2e-3 + 1e-12
    assert np.max(np.abs(body.position[:, 2]) + body.radius) <= 2.5e-3 + 1e-12
    # the packing was made with a margin of two radii around the cylinder's box, then cut
    assert body.n_particles > 40 and body.solids_fraction() > 0.4
    short = make_specimen("box", [3e-3, 3e-3, 3e-3], particle_radius=4e-4, material=GLASS,
                          bond_material=BINDER, max_gap=5e-5, seed=2, solids_fraction=0.35,
                          consolidation_stress=2e4, consolidation_steps=500)
    assert short.notes[0] == "consolidated to 2e+04 Pa (not reached within the step limit)"
    low, high = short.bounds()
    assert np.all(low >= -1.5e-3 - 1e-12) and np.all(high <= 1.5e-3 + 1e-12)


# ---------------------------------------------------------------- second round

def test_whole_numbers_become_the_kernels_types():
    body = Specimen([[0, 0, 0], [2, 0, 0], [4, 0, 0], [6, 0, 0]], 1, [[0.0, 1.0], [1.0, 2.0],
                                                                   [2.0, 3.0]], 1,
                    GLASS, BINDER)
    assert body.position.dtype == body.radius.dtype == body.bond_diameter.dtype == np.float64
    assert body.bonds.dtype == np.int64 and body.bonds.tolist() == [[0, 1], [1, 2], [2, 3]]
    assert body.bond_material_index.tolist() == [0, 0, 0]
    assert body.position.flags.c_contiguous


def test_the_system_keeps_each_particles_and_bonds_material():
    steel = bondem.Material(density=7800.0, young_modulus=2e11)
    glue = bondem.BondMaterial(young_modulus=5e8)
    body = Specimen([[0, 0, 0], [2e-3, 0, 0], [4e-3, 0, 0]], 1e-3, [[0, 1], [1, 2]], 1e-3,
                    [GLASS, steel], [BINDER, glue], material_index=[0, 1, 0],
                    bond_material_index=[1, 0])
    model, _ = body.system()
    assert model.material.tolist() == [0, 1, 0] and model.bond_material.tolist() == [1, 0]
    assert model.mass[1] / model.mass[0] == pytest.approx(7800.0 / 2500.0, rel=1e-14)
    one = Specimen([[0, 0, 0], [2e-3, 0, 0]], 1e-3, [[0, 1]], 1e-3, GLASS, BINDER)
    assert one.system()[0].bond_pairs.tolist() == [[0, 1]]       # a single bond is kept


def test_a_lattice_by_default_and_one_with_centres_on_its_cut():
    body = lattice_specimen((2, 2, 2), 1e-3, GLASS, BINDER)
    np.testing.assert_allclose(body.bond_diameter, 2e-3, rtol=1e-15)   # diameter_ratio 1
    assert body.contact_model == "hertz_mindlin"
    assert body.materials == [GLASS] and body.bond_materials == [BINDER]
    # 5 x 5 chains: the centres (+-4 mm, 0) and (0, +-4 mm) lie exactly on the cut
    square = lattice_specimen((5, 5, 2), 1e-3, GLASS, BINDER, shape="cylinder")
    rho = np.hypot(square.position[:, 0], square.position[:, 1])
    assert np.sum(np.isclose(rho, 4e-3)) == 8 and square.n_particles == 2 * 13
    assert square.notes == ["simple cubic lattice 5 x 5 x 2, spacing 0.002 m, cut to a "
                            "cylinder of centres within 0.004 m of the axis"]


def test_carving_a_thick_disc():
    r = np.full(3, 0.25)
    disc = np.array([[1.0, 0.0, 0.0], [0.0, 0.75, 0.0], [0.0, 0.0, 0.75]])
    assert _inside("disc", [2.0, 2.0], disc, r).tolist() == [False, True, True]


def test_the_documented_defaults_of_a_random_specimen():
    size = [9e-3, 9e-3, 9e-3]           # room enough for the default fraction 0.55
    default = make_specimen("box", size, particle_radius=5e-4, material=GLASS,
                            bond_material=BINDER)
    explicit = make_specimen("box", size, particle_radius=5e-4, material=GLASS,
                             bond_material=BINDER, solids_fraction=0.55, seed=0, max_gap=0.0,
                             diameter_ratio=0.5)
    np.testing.assert_array_equal(default.position, explicit.position)
    np.testing.assert_array_equal(default.bonds, explicit.bonds)
    np.testing.assert_allclose(default.bond_diameter, 0.5e-3, rtol=1e-15)
    assert default.materials == [GLASS] and default.bond_materials == [BINDER]
    spread = {"type": "table", "radius": [4e-4, 6e-4], "fraction": [0.5, 0.5]}
    mixed = make_specimen("box", [5e-3] * 3, radius_distribution=spread, material=GLASS,
                          bond_material=BINDER, max_gap=5e-5, solids_fraction=0.4, seed=5)
    assert set(np.round(mixed.radius, 12).tolist()) == {4e-4, 6e-4}


def test_a_consolidated_specimen_of_two_sizes_is_repeatable_and_reports_progress():
    spread = {"type": "table", "radius": [4e-4, 5e-4], "fraction": [0.5, 0.5]}
    seen = []
    settings = dict(radius_distribution=spread, material=GLASS, bond_material=BINDER,
                    max_gap=5e-5, solids_fraction=0.35, seed=7, consolidation_stress=2e4,
                    consolidation_steps=1500)
    first = make_specimen("box", [4e-3, 4e-3, 4e-3], progress=lambda *a: seen.append(a),
                          **settings)
    second = make_specimen("box", [4e-3, 4e-3, 4e-3], **settings)
    np.testing.assert_array_equal(first.position, second.position)
    assert [s[:2] for s in seen] == [(0, 1500), (500, 1500), (1000, 1500)]
    assert set(np.round(first.radius, 12).tolist()) == {4e-4, 5e-4}


def test_consolidation_is_frictionless_whatever_the_material():
    """Hertz contacts without friction, rolling friction, at a restitution of 0.5: the
    particles' own values do not change the packing, bit for bit."""
    from bondem.generate import Box, pack_spheres
    from bondem.lab.specimen import consolidate
    position, radius = pack_spheres(Box([-1.5e-3] * 3, [1.5e-3] * 3), radius=4e-4,
                                    solids_fraction=0.35, seed=2)
    rough = bondem.Material(density=2500.0, young_modulus=1e8, friction=0.6,
                            rolling_friction=0.2, restitution=0.9)
    smooth = bondem.Material(density=2500.0, young_modulus=1e8, friction=0.0,
                             rolling_friction=0.0, restitution=0.5)
    a, _ = consolidate(position, radius, rough, 2e4, max_steps=1000)
    b, _ = consolidate(position, radius, smooth, 2e4, max_steps=1000)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, position)
    unmoved, reached = consolidate(position, radius, smooth, 2e4, max_steps=0)
    assert reached is False and np.array_equal(unmoved, position)


def test_a_scene_without_contacts_gives_a_specimen_without_them(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.replace('contact_model = "linear"', 'contact_model = "none"'))
    assert specimen_from_scene(path).contact_model == "none"


def test_a_scene_of_two_materials_keeps_each_particles_and_bonds(tmp_path):
    (tmp_path / "particles.csv").write_text("x,y,z,radius,material\n0.0,0.0,0.0,0.001,glass\n"
                                            "0.002,0.0,0.0,0.001,steel\n"
                                            "0.004,0.0,0.0,0.001,glass\n")
    (tmp_path / "bonds.csv").write_text("i,j,diameter,material\n0,1,0.001,glue\n"
                                        "1,2,0.0005,binder\n")
    path = tmp_path / "scene.toml"
    path.write_text("""
[simulation]
end_time = 1e-4
[materials.glass]
density = 2500.0
young_modulus = 1e8
[materials.steel]
density = 7800.0
young_modulus = 2e11
[bond_materials.binder]
young_modulus = 1e8
[bond_materials.glue]
young_modulus = 3e8
[particles]
file = "particles.csv"
[bonds]
file = "bonds.csv"
""")
    body = specimen_from_scene(path)
    densities = [body.materials[k].density for k in body.material_index]
    moduli = [body.bond_materials[k].young_modulus for k in body.bond_material_index]
    assert densities == [2500.0, 7800.0, 2500.0] and moduli == [3e8, 1e8]
    assert body.bond_diameter.tolist() == [1e-3, 5e-4]
    model, _ = body.system()
    assert model.mass[1] / model.mass[0] == pytest.approx(7800.0 / 2500.0, rel=1e-14)


def test_a_consolidated_specimen_depends_on_its_seed():
    settings = dict(particle_radius=4e-4, material=GLASS, bond_material=BINDER, max_gap=5e-5,
                    solids_fraction=0.35, consolidation_stress=2e4, consolidation_steps=500)
    one = make_specimen("box", [3e-3] * 3, seed=1, **settings)
    other = make_specimen("box", [3e-3] * 3, seed=2, **settings)
    assert one.n_particles != other.n_particles or \
        not np.array_equal(one.position, other.position)


def test_a_packing_is_made_once_for_specimens_that_differ_only_in_their_bonds(
        monkeypatch):
    """A calibration varies the bonds of one packing: make_specimen packs it once per
    process, and each specimen gets arrays of its own."""
    packed = []

    def counting(*args, **kwargs):
        packed.append(kwargs["seed"])
        return pack(*args, **kwargs)

    pack = specimen_module.pack_spheres
    monkeypatch.setattr(specimen_module, "pack_spheres", counting)
    specimen_module._geometries.clear()
    shape = dict(particle_radius=4e-4, material=GLASS, max_gap=1e-4, solids_fraction=0.4,
                 diameter_ratio=0.6)
    first = make_specimen("cylinder", [3e-3, 4e-3], bond_material=BINDER, seed=5, **shape)
    stiffer = bondem.BondMaterial(young_modulus=9e8, normal_strength=1e6)
    second = make_specimen("cylinder", [3e-3, 4e-3], bond_material=stiffer, seed=5, **shape)
    assert packed == [5]
    np.testing.assert_array_equal(second.position, first.position)
    np.testing.assert_array_equal(second.bonds, first.bonds)
    assert second.bond_materials[0].young_modulus == 9e8 and second.notes == first.notes
    first.position[0, 0] = 1.0          # a specimen's arrays are its own
    first.notes.append("changed")
    third = make_specimen("cylinder", [3e-3, 4e-3], bond_material=BINDER, seed=5, **shape)
    assert third.position[0, 0] == second.position[0, 0] != 1.0
    assert "changed" not in third.notes
    # another seed, size, gap or fraction is another packing
    make_specimen("cylinder", [3e-3, 4e-3], bond_material=BINDER, seed=6, **shape)
    make_specimen("cylinder", [3e-3, 4.2e-3], bond_material=BINDER, seed=5, **shape)
    make_specimen("cylinder", [3e-3, 4e-3], bond_material=BINDER, seed=5,
                  **{**shape, "max_gap": 2e-4})
    assert packed == [5, 6, 5, 5]
    # only GEOMETRIES packings are kept: the oldest goes first
    for seed in range(10, 10 + specimen_module.GEOMETRIES):
        make_specimen("cylinder", [3e-3, 4e-3], bond_material=BINDER, seed=seed, **shape)
    make_specimen("cylinder", [3e-3, 4e-3], bond_material=stiffer, seed=5, **shape)
    assert packed[-1] == 5 and len(specimen_module._geometries) == \
        specimen_module.GEOMETRIES

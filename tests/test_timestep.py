"""Time scales and the stable time step (bondem.timestep, SPEC section 1) against their
formulas, on a system with nothing alike: particles of three radii and two materials
(Poisson's ratios 0.22 and 0.35), bonds of different lengths, diameters, moduli and
models; the smallest of each kind must come from the right particle or bond."""
import math

import numpy as np
import pytest

import bondem
from bondem.model import fluid_array, frame_array, make_system
from bondem.physics import bond_kelvin
from bondem.timestep import stable_time_step, step_count, time_scales

GLASS = bondem.Material(name="glass", density=2500.0, young_modulus=6e10, poisson_ratio=0.22)
RUBBER = bondem.Material(name="rubber", density=1100.0, young_modulus=5e6,
                         poisson_ratio=0.35)
STIFF = bondem.BondMaterial(name="stiff", young_modulus=4e10)
SOFT = bondem.BondMaterial(name="soft", young_modulus=2e8, model="kelvin", viscosity=3e-6)


def system(**kwargs):
    position = [[0.0, 0.0, 0.0], [3e-3, 0.0, 0.0], [3e-3, 5e-3, 0.0]]
    radius = [1e-3, 2e-3, 3e-3]
    return make_system(position, radius, [GLASS, RUBBER], material_index=[0, 0, 1],
                       bonds=[[0, 1], [1, 2]], bond_diameter=[1e-3, 2.5e-3],
                       bond_material=[STIFF, SOFT], bond_material_index=[0, 1], **kwargs)


def rayleigh(radius, material):
    g = material.young_modulus / (2 * (1 + material.poisson_ratio))
    return (math.pi * radius * math.sqrt(material.density / g)
            / (0.1631 * material.poisson_ratio + 0.8766))


def sphere(radius, density):
    mass = density * 4.0 / 3.0 * math.pi * radius ** 3
    return mass, 0.4 * mass * radius ** 2


def test_each_time_scale_from_its_formula():
    model, _ = system()
    scales = time_scales(model)
    # Rayleigh: the smallest glass sphere (1 mm) against the 3 mm rubber one
    assert scales["rayleigh"] == pytest.approx(min(rayleigh(1e-3, GLASS),
                                                   rayleigh(3e-3, RUBBER)), rel=1e-12)
    assert rayleigh(1e-3, GLASS) < rayleigh(3e-3, RUBBER)
    m0, i0 = sphere(1e-3, 2500.0)
    m1, i1 = sphere(2e-3, 2500.0)
    m2, i2 = sphere(3e-3, 1100.0)
    axial, bending = [], []
    for (ma, ia), (mb, ib), length, d, young in (((m0, i0), (m1, i1), 3e-3, 1e-3, 4e10),
                                                 ((m1, i1), (m2, i2), 5e-3, 2.5e-3, 2e8)):
        area, second = math.pi * d ** 2 / 4, math.pi * d ** 4 / 64
        axial.append(math.sqrt(ma * mb / (ma + mb) * length / (young * area)))
        bending.append(math.sqrt(ia * ib / (ia + ib) * length / (young * second)))
    assert scales["bond_axial"] == pytest.approx(min(axial), rel=1e-12)
    assert scales["bond_bending"] == pytest.approx(min(bending), rel=1e-12)
    # the Kelvin bond's dashpot, of its own bond only: m_red / (eta E A / L0)
    m_red = m1 * m2 / (m1 + m2)
    assert scales["bond_dashpot"] == pytest.approx(
        m_red / (3e-6 * 2e8 * math.pi * 2.5e-3 ** 2 / 4 / 5e-3), rel=1e-12)
    assert set(scales) == {"rayleigh", "bond_axial", "bond_bending", "bond_dashpot"}
    assert "bond_dashpot" not in time_scales(model, musen_compat=True)


def test_the_stable_step_is_the_safety_factor_of_the_smallest_scale():
    model, _ = system()
    scales = time_scales(model)
    cause = min(scales, key=scales.get)
    step, named = stable_time_step(model)
    assert named == cause and step == pytest.approx(0.2 * scales[cause], rel=1e-15)
    step, named = stable_time_step(model, safety_factor=0.05)
    assert step == pytest.approx(0.05 * scales[cause], rel=1e-15)


def test_a_bond_model_is_asked_about_its_own_bonds(monkeypatch):
    asked = []

    def scales(model, bonds, reduced_mass, musen_compat=False):
        asked.append((bonds.tolist(), reduced_mass.tolist(), musen_compat))
        return {"bond_probe": 1.0}
    monkeypatch.setattr(bond_kelvin, "time_scales", scales)
    model, _ = system()
    assert time_scales(model, musen_compat=True)["bond_probe"] == 1.0
    m1, m2 = sphere(2e-3, 2500.0)[0], sphere(3e-3, 1100.0)[0]
    ((bonds, reduced, compat),) = asked
    assert bonds == [1] and compat is True
    assert reduced == pytest.approx([m1 * m2 / (m1 + m2)], rel=1e-12)


def test_a_dashpot_that_limits_the_step_only_outside_musen_compatibility():
    # eta = 3e-3 s: the dashpot stops its pair in m_red / (eta k_n), far below the rest
    model, _ = system()
    model.bond_materials[1] = bondem.BondMaterial(name="soft", young_modulus=2e8,
                                                  model="kelvin", viscosity=3e-3)
    scales = time_scales(model)
    assert stable_time_step(model) == (pytest.approx(0.2 * scales["bond_dashpot"],
                                                     rel=1e-15), "bond_dashpot")
    step, cause = stable_time_step(model, musen_compat=True)
    assert cause != "bond_dashpot" and step > 0.2 * scales["bond_dashpot"]
    assert cause == min((k for k in scales if k != "bond_dashpot"), key=scales.get)


def test_fields_add_their_scales_and_particles_alone_have_rayleighs():
    fluid = fluid_array(density=1000.0, viscosity=2e-3, drag="stokes")
    model, _ = make_system([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [1e-3, 4e-4], GLASS,
                           fluid=fluid, frame=frame_array((0.0, 3.0, 4.0)))
    scales = time_scales(model)
    mass = 2500.0 * 4.0 / 3.0 * math.pi * 4e-4 ** 3
    assert set(scales) == {"rayleigh", "fluid_drag", "frame_rotation"}
    assert scales["fluid_drag"] == pytest.approx(mass / (6 * math.pi * 2e-3 * 4e-4),
                                                 rel=1e-12)
    assert scales["frame_rotation"] == pytest.approx(0.2, rel=1e-15)
    assert scales["rayleigh"] == pytest.approx(rayleigh(4e-4, GLASS), rel=1e-12)
    empty, _ = make_system(np.zeros((0, 3)), np.zeros(0), GLASS)
    assert time_scales(empty) == {"rayleigh": math.inf}


@pytest.mark.parametrize("end, step, count", [
    (1e-3, 3e-7, 3333),          # 3333.33: the nearest whole number
    (1e-3, 2.9999e-7, 3333),
    (0.3, 0.1, 3),               # 2.9999999999999996 steps in floating point
    (1e-3, 6e-7, 1667),          # 1666.67
    (0.0, 1e-6, 0),
    (-1.0, 1e-6, 0),
])
def test_step_count_is_the_nearest_whole_number(end, step, count):
    assert step_count(end, step) == count and isinstance(step_count(end, step), int)

"""Constants and closed forms shared by the bond physics tests."""
import numpy as np

import bondem

RADIUS = 1e-3          # m
SPACING = 2e-3         # m, bond initial length of a touching pair
BOND_DIAMETER = 1e-3   # m


def bond_constants(material, diameter=BOND_DIAMETER, length=SPACING):
    """(E A/L0, G A/L0, G J/L0, E I/L0) and (A, I, J) of a bond, by the SPEC's formulas."""
    radius = diameter / 2
    area = np.pi * radius ** 2
    second = np.pi * radius ** 4 / 4
    polar = np.pi * radius ** 4 / 2
    shear_modulus = material.young_modulus / (2 * (1 + material.poisson_ratio))
    stiffness = (material.young_modulus * area / length, shear_modulus * area / length,
                 shear_modulus * polar / length, material.young_modulus * second / length)
    return stiffness, (area, second, polar)


def pairs_along_x(n, material, speed=1e-3):
    """(model, state): n bonded pairs 10 mm apart along y, each of length SPACING along x,
    particle 2k clamped and 2k+1 pulled along +x at ``speed`` (m/s), both fixed."""
    position = np.zeros((2 * n, 3))
    position[0::2, 1] = position[1::2, 1] = np.arange(n) * 10e-3
    position[1::2, 0] = SPACING
    velocity = np.zeros((2 * n, 3))
    velocity[1::2, 0] = speed
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3)
    return bondem.make_system(position, RADIUS, glass, velocity=velocity,
                              fixed=np.ones(2 * n, bool),
                              bonds=np.column_stack([np.arange(0, 2 * n, 2),
                                                     np.arange(1, 2 * n, 2)]),
                              bond_diameter=BOND_DIAMETER, bond_material=material)

"""Constants and closed forms shared by the bond physics tests."""
import numpy as np

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

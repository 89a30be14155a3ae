"""Shared fixtures: the materials used across the physics tests."""
import pytest

import bondem


@pytest.fixture
def glass():
    return bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, name="glass")


@pytest.fixture
def binder():
    return bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, breakage="none",
                               name="binder")

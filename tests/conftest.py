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


@pytest.fixture(autouse=True)
def _close_figures():
    """Every figure a test made is closed after it (figures, reports and the lab keep
    pyplot figures open for their caller; the suite otherwise passes 20 and warns)."""
    yield
    import sys
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")

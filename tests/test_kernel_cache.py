"""Cached kernels are refreshed when a physics source they inline changes, wherever the
cache lives (NUMBA_CACHE_DIR too): bondem's kernel files get a locator whose stamp holds
a digest of the physics sources."""
from bondem import _kernel_cache
from bondem._kernel_cache import PhysicsAwareLocator, physics_digest


def test_physics_edit_changes_the_stamp_of_bondem_kernels(tmp_path):
    (tmp_path / "physics").mkdir()
    law = tmp_path / "physics" / "triangle.py"
    law.write_text("def f(): return 1\n")
    first = physics_digest(tmp_path)
    assert physics_digest(tmp_path) == first
    law.write_text("def f(): return 2\n")
    second = physics_digest(tmp_path)
    assert second != first
    # the loop bodies are inlined too
    (tmp_path / "backends").mkdir()
    (tmp_path / "backends" / "loops.py").write_text("def g(): return 1\n")
    third = physics_digest(tmp_path)
    assert third != second
    # and the CPU backend's compile options, which the other kernel modules import
    (tmp_path / "backends" / "cpu.py").write_text("_serial = {}\n")
    assert physics_digest(tmp_path) != third


def test_bondem_kernels_use_the_physics_aware_stamp():
    from bondem.backends import cpu
    from bondem import walls
    locators = _kernel_cache._numba_locators()
    assert locators[0] is PhysicsAwareLocator
    for dispatcher in (cpu.elastic_bonds, cpu.integrate, walls._wall_pass):
        locator = dispatcher._cache._impl.locator
        assert isinstance(locator, PhysicsAwareLocator)
        stamp = locator.get_source_stamp()
        assert stamp[1] == physics_digest() and stamp[0] == locator._inner.get_source_stamp()
    # a function outside the package keeps Numba's own locator
    import numba

    @numba.njit(cache=True)
    def outside(x):
        return x + 1
    assert PhysicsAwareLocator.from_function(outside.py_func, __file__) is None

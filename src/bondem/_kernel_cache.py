"""Numba's cache and the physics that bondem's cached kernels inline.

Numba keys a cached kernel on its own source file only (its mtime and size, or from
0.68 a hash of it), but bondem's kernels inline the functions of ``bondem/physics`` and
the loop bodies of ``backends/loops.py``: after an edit of those a cached kernel would
keep the old code. ``install`` puts a cache
locator in front of Numba's own for the files of this package; it finds the cache folder
as Numba's locators do (NUMBA_CACHE_DIR included) and adds a digest of the physics
sources to the stamp, so that a physics edit makes every cached bondem kernel stale,
wherever the cache lives. Run from ``bondem.physics`` on import, that is before any kernel
module decorates its kernels (Numba picks a kernel's locator when it decorates it).
"""
import hashlib
from pathlib import Path

from numba.core import caching

PACKAGE = Path(__file__).resolve().parent


# What the cached kernels inline besides their own file: the physics, the loop bodies,
# and the CPU backend's compile options and helpers, which the other kernel modules import.
INLINED = ("physics/*.py", "backends/loops.py", "backends/cpu.py", "backends/raw.py")


def physics_digest(package=PACKAGE):
    """SHA-256 (hex) of the sources every cached kernel inlines (``INLINED``)."""
    sources = sorted(path for pattern in INLINED for path in Path(package).glob(pattern))
    return hashlib.sha256(b"".join(path.read_bytes() for path in sources)).hexdigest()


def _numba_locators():
    """Numba's list of locator classes (named CacheImpl from 0.68, _CacheImpl before)."""
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")
    return impl._locator_classes


class PhysicsAwareLocator(caching._CacheLocator):
    """Numba's own locator for a bondem source file, its stamp extended by the physics
    digest (see the module docstring)."""

    digest = None

    def __init__(self, inner, digest):
        self._inner = inner
        self._digest = digest

    def ensure_cache_path(self):
        return self._inner.ensure_cache_path()

    def get_cache_path(self):
        return self._inner.get_cache_path()

    def get_source_stamp(self):
        return (self._inner.get_source_stamp(), self._digest)

    def get_disambiguator(self):
        return self._inner.get_disambiguator()

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            inside = Path(py_file).resolve().is_relative_to(PACKAGE)
        except (OSError, ValueError):
            inside = False
        if not inside:
            return None
        for other in _numba_locators():
            if other is cls:
                continue
            inner = other.from_function(py_func, py_file)
            if inner is not None:
                if cls.digest is None:
                    cls.digest = physics_digest()
                return cls(inner, cls.digest)
        return None


def install():
    """Put ``PhysicsAwareLocator`` first in Numba's locator list (once)."""
    locators = _numba_locators()
    if PhysicsAwareLocator not in locators:
        locators.insert(0, PhysicsAwareLocator)

"""Physics as small pure functions on scalars and 3-tuples, one definition for all backends.

Importing this package registers every law; ``compile_physics(jit)`` compiles them.
"""
from . import vector, rotation, bond_elastic  # noqa: F401  (registration order matters)
from . import bond_elastic_musen, bond_kelvin  # noqa: F401
from . import contact_hertz, contact_linear, triangle  # noqa: F401
from ._registry import compile_physics, physics
from .. import _kernel_cache

# Before any kernel module decorates a cached kernel that inlines these functions.
_kernel_cache.install()

__all__ = ["compile_physics", "physics"]

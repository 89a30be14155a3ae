"""Physics as small pure functions on scalars and 3-tuples, one definition for all backends.

Importing this package registers every law; ``compile_physics(jit)`` compiles them.
"""
from . import vector, rotation, bond_elastic  # noqa: F401  (registration order matters)
from . import bond_elastic_musen  # noqa: F401
from . import bond_models  # noqa: F401  (imports every other physics/bond_*.py model)
from . import contact_hertz, contact_hertz_musen, contact_linear, triangle  # noqa: F401
from . import contact_models  # noqa: F401  (imports every other physics/contact_*.py model)
from . import field_models  # noqa: F401  (imports every physics/field_*.py model)
from . import rigid_body  # noqa: F401
from ._registry import compile_physics, physics
from .. import _kernel_cache

# Before any kernel module decorates a cached kernel that inlines these functions.
_kernel_cache.install()

__all__ = ["compile_physics", "physics"]

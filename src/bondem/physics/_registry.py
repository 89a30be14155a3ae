"""One definition of each physics function, compiled for every backend.

Physics functions are plain Python on scalars and 3-tuples, so tests can call them with
plain numbers. ``compile_physics(jit)`` rebuilds every registered function in a namespace
where its callees are the compiled versions, then applies the target's decorator: the
CPU backend passes ``numba.njit``, the CUDA backend ``numba.cuda.jit(device=True)``.
"""
import types
from types import SimpleNamespace

_REGISTERED = []

# Columns of the contact laws' pair table (physics/contact_models.py): the materials'
# mixed properties, the linear law's k_n setting, then the model's own parameters.
PAIR_E_STAR, PAIR_G_STAR, PAIR_BETA, PAIR_FRICTION, PAIR_ROLLING, PAIR_STIFFNESS = range(6)
PAIR_MODEL = 6

# Marks a parameter without a default in a bond model's PARAMETERS schema.
REQUIRED = object()


def physics(function):
    """Register a pure physics function (scalars and 3-tuples in, tuples out)."""
    _REGISTERED.append(function)
    return function


def compile_physics(jit, substitute=None):
    """Return a namespace with every registered function compiled by ``jit``.

    Functions are rebuilt in registration order, so a function may call any function
    registered before it; each sees the compiled callee under the callee's own name.
    ``substitute`` maps a callee's name to another registered function's name that its
    callers see instead (the CPU's vectorised bond loop swaps in a branch-free twist).
    """
    return compile_functions(_REGISTERED, jit, substitute=substitute)


def compile_functions(functions, jit, base=None, substitute=None, given=None):
    """``compile_physics`` for any list of plain functions: each is rebuilt with the
    compiled functions of ``base`` (a namespace, e.g. compiled physics) and of the
    functions before it as its callees, then compiled by ``jit``. ``given`` maps a
    function's name to a compiled function that this target uses in its place (the CPU's
    unchecked row access, backends/raw.py)."""
    compiled = dict(vars(base)) if base is not None else {}
    substitute = substitute or {}
    given = given or {}
    for function in functions:
        if function.__name__ in given:
            compiled[function.__name__] = given[function.__name__]
            continue
        namespace = dict(function.__globals__)
        namespace.update(compiled)
        namespace.update({name: compiled[other] for name, other in substitute.items()
                          if other in compiled})
        rebuilt = types.FunctionType(function.__code__, namespace, function.__name__,
                                     function.__defaults__, function.__closure__)
        rebuilt.__qualname__ = function.__qualname__
        rebuilt.__module__ = function.__module__
        compiled[function.__name__] = jit(rebuilt)
    return SimpleNamespace(**compiled)

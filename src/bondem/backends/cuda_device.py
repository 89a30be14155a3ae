"""What both CUDA modules build their kernels from: the CPU backend's loop bodies
(``backends/loops.py``) compiled as CUDA device functions, the launch shape, and the
launch itself (``launch``: numba-cuda's, or prepared once and reused).
``cuda.py`` (bonds, integration) and ``cuda_contacts.py`` (contacts, walls) import this
module; neither imports the other at import time."""
import os
import weakref

import numba
import numpy as np
from numba import cuda

from . import loops

K = loops.compile_loops(cuda.jit(device=True), cuda.jit(device=True))

THREADS = 128  # threads per block: a multiple of the warp, small enough for any register use


def blocks(n):
    """Blocks of THREADS threads that cover ``n`` items (at least one block)."""
    return max(1, (n + THREADS - 1) // THREADS)


# ---------------------------------------------------------------------------------------
# Launching: numba-cuda marshals every array argument on every launch (measured on an
# H200: ~0.4 ms host time per launch of the bond kernel's 440 parameters, ~0.26 ms for
# integrate, against 22 us with the parameters marshalled once; docs/gpu.md). A step
# passes the same device arrays each time, so a prepared launch keeps their parameters
# and re-marshals only the scalars. It reuses numba-cuda internals (the overload's
# _prepare_args, cuda.core's launch); on any mismatch or failure the plain launch runs.
# Off unless BONDEM_CUDA_PREPARED_LAUNCH=1 until the device cases pass with it on a GPU.
# ---------------------------------------------------------------------------------------
PREPARED_LAUNCH = (os.environ.get("BONDEM_CUDA_PREPARED_LAUNCH") == "1"
                   and not numba.config.ENABLE_CUDASIM)
_prepared = {}   # kernel -> PreparedLaunch, or None where it cannot be prepared


def launch(kernel, n, *args):
    """``kernel[blocks(n), THREADS](*args)``: one thread per item of ``n``; prepared
    (parameters marshalled once) when ``PREPARED_LAUNCH`` is on and the arrays are the
    ones of the kernel's last launch."""
    grid = blocks(n)
    prepared = _prepared.get(kernel) if PREPARED_LAUNCH else None
    if prepared is not None and prepared.launch(grid, args):
        return
    kernel[grid, THREADS](*args)
    if PREPARED_LAUNCH and _prepared.get(kernel, True) is not None:
        _prepared[kernel] = PreparedLaunch.renewed(kernel, args, prepared)


def _leaves(args):
    """The arguments' leaves in order (tuples, named ones too, opened)."""
    for arg in args:
        if isinstance(arg, tuple):
            yield from _leaves(arg)
        else:
            yield arg


def _is_device_array(value):
    return hasattr(value, "__cuda_array_interface__") and not isinstance(value, np.ndarray)


def _typed_leaves(types_, args):
    """(numba type, value) of each leaf, tuples opened as numba-cuda's _prepare_args does."""
    for ty, value in zip(types_, args):
        if isinstance(value, tuple):
            yield from _typed_leaves(ty, value)
        else:
            yield ty, value


def _raw_launch(overload):
    """launch(grid, params): cuda.core's launch of ``overload`` on the default stream, as
    numba-cuda's own ``_Kernel.launch`` does it."""
    from numba.cuda import dispatcher as internals
    function = overload._codelibrary.get_cufunc().kernel
    stream = internals.driver._to_core_stream(0)
    cooperative = ("is_cooperative" if internals.CUDA_CORE_GE_1_0 else "cooperative_launch")
    configs = {}

    def raw(grid, params):
        if grid not in configs:
            configs[grid] = internals.LaunchConfig(grid=(grid, 1, 1), block=(THREADS, 1, 1),
                                                   shmem_size=0, **{cooperative: False})
        internals.launch(stream, configs[grid], function, *params)
    return raw


class PreparedLaunch:
    """A compiled kernel's launch with its device arrays' parameters marshalled once.

    ``params`` is the parameter list numba-cuda would pass, with ``None`` at each scalar's
    slot; ``arrays`` holds (leaf index, weak reference) of the device arrays it was made
    from (weak: a finished simulation's arrays are freed; then no launch matches, and
    their pointers in ``params`` are never used), ``scalars`` (leaf index, slot, numba
    type, Python type) of each scalar.
    """

    def __init__(self, overload, n_leaves, arrays, params, scalars, raw_launch):
        self.overload, self.n_leaves, self.arrays = overload, n_leaves, arrays
        self.params, self.scalars, self.raw_launch = params, scalars, raw_launch
        self.builds = 1   # how often this kernel was prepared (``renewed`` carries both)
        self.hits = 0     # and launched prepared

    @classmethod
    def renewed(cls, kernel, args, old=None, raw_launch=None):
        """``build`` after a launch that ``old`` (the kernel's last prepared form, or None)
        did not match; None (plain launches from now on) after four preparations with
        fewer than four prepared launches each: a preparation costs about a plain launch,
        so a kernel whose arrays change that often (a moving wall's uploads) gains little."""
        builds = old.builds if old is not None else 0
        hits = old.hits if old is not None else 0
        if builds >= 4 and hits < 4 * builds:
            return None
        fresh = cls.build(kernel, args, raw_launch)
        if fresh is not None:
            fresh.builds, fresh.hits = builds + 1, hits
        return fresh

    @classmethod
    def build(cls, kernel, args, raw_launch=None):
        """The prepared form of ``kernel`` for ``args`` (after a plain launch compiled it),
        or None where an argument is neither a device array nor a one-parameter scalar,
        or numba-cuda's internals are not the expected ones."""
        try:
            overload = kernel.overloads.get(tuple(kernel.typeof_pyval(a) for a in args))
            if overload is None:
                return None
            params, arrays, scalars = [], [], []
            leaves = list(_typed_leaves(overload.argument_types, args))
            for i, (ty, value) in enumerate(leaves):
                if _is_device_array(value):
                    overload._prepare_args(ty, value, 0, [], params)
                    arrays.append((i, weakref.ref(value)))
                elif isinstance(value, (bool, int, float, np.number, np.bool_)):
                    one = []
                    overload._prepare_args(ty, value, 0, [], one)
                    if len(one) != 1:
                        return None
                    scalars.append((i, len(params), ty, type(value)))
                    params.append(None)
                else:
                    return None          # a host array is copied per launch: not prepared
            return cls(overload, len(leaves), arrays, params, scalars,
                       raw_launch or _raw_launch(overload))
        except Exception:                # other numba-cuda internals: plain launches
            return None

    def launch(self, grid, args):
        """Launch on ``grid`` blocks if ``args`` holds the same arrays and scalars of the
        same types; returns whether it launched."""
        leaves = list(_leaves(args))
        if len(leaves) != self.n_leaves or any(leaves[i] is not a() for i, a in self.arrays):
            return False
        params = list(self.params)
        for i, slot, ty, kind in self.scalars:
            if type(leaves[i]) is not kind:
                return False
            one = []
            self.overload._prepare_args(ty, leaves[i], 0, [], one)
            params[slot] = one[0]
        self.raw_launch(grid, params)
        self.hits += 1
        return True

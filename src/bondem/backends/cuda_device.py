"""What both CUDA modules build their kernels from: the CPU backend's loop bodies
(``backends/loops.py``) compiled as CUDA device functions, and the launch shape.
``cuda.py`` (bonds, integration) and ``cuda_contacts.py`` (contacts, walls) import this
module; neither imports the other at import time."""
from numba import cuda

from . import loops

K = loops.compile_loops(cuda.jit(device=True), cuda.jit(device=True))

THREADS = 128  # threads per block: a multiple of the warp, small enough for any register use


def blocks(n):
    """Blocks of THREADS threads that cover ``n`` items (at least one block)."""
    return max(1, (n + THREADS - 1) // THREADS)

"""Backends: loops that apply the physics functions over all bonds, contacts, particles.

A backend object gives ``Simulation`` what it runs: ``bond_law(model)``,
``integrator(model)``, ``load_arrays(n)`` (the force and moment scratch), ``step(...)``
(one time step, ``integrate.step``'s signature), ``to_host(state)`` (refresh the host
state after a batch of steps), ``check_laws(laws)`` and ``synchronize()``.
"""
import numpy as np

from ..integrate import step as _step

BACKENDS = ("cpu", "gpu")


class CpuBackend:
    """Numba loops on the CPU (``backends/cpu.py``); the host state is the state."""

    name = "cpu"

    def __init__(self, model, state):
        pass

    def bond_law(self, model):
        from .cpu import ElasticBonds
        return ElasticBonds(model)

    def integrator(self, model):
        from .cpu import Integrator
        return Integrator(model)

    def contact_law(self, model, settings, walls):
        """The contact and wall law (``cpu_contacts.ContactLaw``) for this backend."""
        from .cpu_contacts import ContactLaw
        return ContactLaw(model, settings, walls)

    def load_arrays(self, n_particles):
        return np.zeros((n_particles, 3)), np.zeros((n_particles, 3))

    def step(self, *args, **kwargs):
        _step(*args, **kwargs)

    def to_host(self, state):
        """Nothing to copy: the CPU kernels work on the host state."""

    def to_device(self, state):
        """Nothing to copy: the CPU kernels work on the host state."""

    def check_laws(self, laws):
        for law in laws:
            if getattr(law, "backend", "cpu") != self.name:
                raise ValueError(f"backend = 'cpu': law {type(law).__name__} is for backend "
                                 f"{law.backend!r}")

    def synchronize(self):
        """CPU kernels return when done."""


def select_backend(name, model, state):
    """The backend object named ``name`` ("cpu" or "gpu") for this model and state.

    Raises ValueError for an unknown name and cuda.BackendUnavailable for "gpu" without a
    CUDA device (or numba's simulator, NUMBA_ENABLE_CUDASIM=1).
    """
    if name == "cpu":
        return CpuBackend(model, state)
    if name == "gpu":
        from .cuda import GpuBackend
        return GpuBackend(model, state)
    raise ValueError(f"backend = {name!r}; allowed: " + ", ".join(repr(b) for b in BACKENDS))

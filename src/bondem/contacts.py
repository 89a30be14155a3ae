"""Contact settings and the contact law the Simulation runs (SPEC section 3).

``ContactSettings`` chooses the pair law (``physics.contact_hertz`` / ``contact_linear``);
the backend's contact law (``backends.cpu_contacts.ContactLaw``, ``cuda_contacts.
ContactLawGpu``, which import this module, never the other way round) is the object in
``Simulation.laws``: each step it refreshes the Verlet lists
(``neighbors``, ``walls``) when particles or walls moved enough to close a listed margin
(``cpu_contacts.ContactLaw._needs_rebuild``), computes every
listed contact and adds the loads per particle.

All contact history lives in ``state.extra`` as NumPy arrays, so a checkpoint of
``state.arrays()`` resumes bit for bit:
    contact_pairs (M,2) int64        Verlet list of particle pairs (i < j, sorted)
    contact_spring (M,3) m           tangential spring of each pair (0 when apart)
    contact_reference_position (N,3) m  positions at the last rebuild
    contact_reference_time (1,) s    time of the last rebuild (walls move from there)
    contact_force, contact_moment_i, contact_moment_j (M,3)  last loads of each pair (N, N m)
    contact_energy (M,) J            energy stored in each pair at the last evaluation
    contact_counters (4,)            [dissipated J, work of walls J, rebuilds, time of the
                                     last evaluation s]
    wall_pairs (K,2) int64           (particle, wall element) candidates, sorted
    wall_spring (K,3) m              tangential spring of each wall candidate
    wall_force_rows, wall_moment_rows (K,3), wall_energy_rows (K,)  as for pairs
    contact_tangential (M,3), wall_tangential (K,3) N  MUSEN-compatible runs only
                                     (MUSEN_*_HISTORY): the tangential force of the last
                                     sticking step, which MUSEN's law applies while a
                                     contact slides
The last loads and energies serve the work balance that books the dissipated energy:
per contact, minus the work of its loads over the step (trapezoidal) minus the change of
its stored energy; with the leapfrog this closes the energy balance to O(dt^2).
Everything else (CSR indices, bond lookup) is derived from these and rebuilt on demand.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .physics import contact_models
from .physics.contact_linear import LINEAR_REFERENCE_OVERLAP

PAIR_HISTORY = {"contact_spring": (3,), "contact_force": (3,), "contact_moment_i": (3,),
                "contact_moment_j": (3,), "contact_energy": ()}
WALL_HISTORY = {"wall_spring": (3,), "wall_force_rows": (3,), "wall_moment_rows": (3,),
                "wall_energy_rows": ()}
# Kept by MUSEN-compatible runs only (ContactLaw.history): no SPEC run carries them.
MUSEN_PAIR_HISTORY = {"contact_tangential": (3,)}
MUSEN_WALL_HISTORY = {"wall_tangential": (3,)}
# The contact models (physics/contact_models.py) by name, and "none": -1.
MODELS = {**{m.NAME: m.CODE for m in contact_models.MODELS}, "none": -1}


def contact_cutoff(radius, skin=None, reach=0.0):
    """(cut-off 2 r_max + reach + skin, skin) in m of the pair search for particle radii
    ``radius`` (m); skin: the Verlet skin (m), default a fifth of the mean radius; reach:
    the contact law's longest range beyond contact (m, ``contact_reach``)."""
    radius = np.asarray(radius, dtype=np.float64)
    if skin is None:
        skin = 0.2 * float(radius.mean()) if radius.size else 0.0
    return 2.0 * float(radius.max(initial=0.0)) + reach + skin, skin


def material_parameters(module, material):
    """{key: value} of contact model ``module``'s PARAMETERS for a Material."""
    return {key: float(getattr(material, key)) for key in module.PARAMETERS}


def contact_reach(module, pair, radius_max):
    """Longest gap (m) across which contact model ``module`` acts, over the rows of its
    pair table ``pair``, for R* up to ``radius_max`` (m; a REACH grows with R*): 0 for a
    law without REACH."""
    reach_of = getattr(module, "REACH", None)
    if not reach_of or radius_max <= 0.0:
        return 0.0
    function = getattr(module, reach_of)
    return max(float(function(pair, q, radius_max)) for q in range(pair.shape[0]))


@dataclass(frozen=True)
class ContactSettings:
    """Contact options.

    model: "hertz_mindlin" | "linear" | "none" (no particle-particle contacts; walls then
    use Hertz-Mindlin); bonded_pairs: also give contact forces to pairs joined by an intact
    bond; rolling_resistance: apply the materials' rolling friction; skin: Verlet skin (m),
    None for 0.2 times the mean radius; linear_stiffness: k_n (N/m) of the linear model,
    None for the Hertz stiffness at an overlap of 1 % of R* (see contact_linear).
    """
    model: str = "hertz_mindlin"
    bonded_pairs: bool = False
    rolling_resistance: bool = True
    skin: float | None = None
    linear_stiffness: float | None = None

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"contact model = {self.model!r}; allowed: "
                             + ", ".join(repr(k) for k in MODELS))
        if self.skin is not None and not (self.skin > 0.0 and math.isfinite(self.skin)):
            raise ValueError(f"contact skin = {self.skin!r} m; allowed range (0, inf)")
        if self.linear_stiffness is not None and not (
                self.linear_stiffness > 0.0 and math.isfinite(self.linear_stiffness)):
            raise ValueError(f"contact linear_stiffness = {self.linear_stiffness!r} N/m; "
                             "allowed range (0, inf)")


def contact_time_scales(model, settings):
    """Extra time scales (s) of the contact law: for the linear model sqrt(m*/k_n) of the
    lightest self-pair (m* = m/2), and the contact model's own ``time_scales(model)`` if it
    declares one; Hertz-Mindlin is covered by the Rayleigh step."""
    if settings is None or model.n_particles == 0 or settings.model == "none":
        return {}
    module = contact_models.BY_NAME[settings.model]
    scales = dict(module.time_scales(model)) if hasattr(module, "time_scales") else {}
    if settings.model != "linear":
        return scales
    table = model.material_table()
    young = table["young_modulus"][model.material]
    poisson = table["poisson_ratio"][model.material]
    if settings.linear_stiffness is not None:
        stiffness = np.full(model.n_particles, settings.linear_stiffness)
    else:
        e_star = young / (2.0 * (1.0 - poisson ** 2))
        stiffness = (2.0 * e_star * math.sqrt(LINEAR_REFERENCE_OVERLAP)
                     * 0.5 * model.radius)
    scales["contact_linear"] = float(np.sqrt(0.5 * model.mass / stiffness).min())
    return scales

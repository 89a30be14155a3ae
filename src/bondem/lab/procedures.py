"""The five laboratory tests, each one function: ``uniaxial`` (UCS), ``triaxial``,
``brazilian``, ``direct_tension`` and ``agglomerate`` (compression between two plates).

Each builds a Simulation of the specimen with its boundary (frictionless platens on a
velocity ramp, servo walls, or gripped end layers), runs it in samples of a few steps,
reads the loads and the specimen's own particles at every sample, stops a given fraction
of the peak after the peak or at a strain limit, and returns a ``LabResult``: the curve
(one row per sample) and the numbers a lab report gives. Definitions: docs/lab.md.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import time as clock
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..analysis.walls import force_mismatch
from ..contacts import ContactSettings
from ..physics.contact_linear import LINEAR_REFERENCE_OVERLAP
from ..model import Material
from ..physics.bond_elastic import COMPRESSION, SHEAR, TENSION
from ..simulation import Simulation
from ..walls import MeshWall, PlaneWall, Servo, VelocityProfile
from . import cracks as cracks_mod
from . import measure
from .membrane import membrane_forces
from .output import STRESS
from .specimen import box_widths

TESTS = ("ucs", "triaxial", "brazilian", "tension", "agglomerate")
STRESS_PATHS = ("constant_sigma3", "constant_mean")
RATE_RULES = ("bonds", "wave")
RATE_CHECKS = ("warn", "repeat", "off")
AE_RADIUS_DEFAULT = 2.0   # mean particle diameters: an AE event's source (Hazzard & Young)


@dataclass
class LabSettings:
    """Settings of a lab test (defaults in brackets).

    strain_rate: 1/s of the platen gap (each platen moves at half of it times the height)
    [None: by ``rate_rule``]; rate_rule: the rate when strain_rate is None, "bonds" (no
    faster than the weakest bond material's failure strain min(sigma_n, sigma_t) / E_b
    over 100 times a compression wave takes to cross the specimen, nor than "wave":
    quasi-static from 1 to 30 MPa bonds, with up to 50 times the steps of "wave" for
    sigma_b / E_b = 1e-3) or "wave" (5e-4 per such time: fast, but it overstates the
    strength of weak bonds) [bonds];
    post_peak: stop once the stress has fallen to this fraction of the peak after it, with
    at least ``failure_bonds`` of the bonds broken since the loading began (not by a
    triaxial test's confinement) [0.7]; failure_bonds: that fraction
    [0.01: a local break at a platen contact is not the failure; agglomerate 0.1: a chip
    is not its breakage]; largest_fragment: the agglomerate's drop counts as its breakage
    only once its largest fragment holds at most this fraction of the mass [0.9];
    ae_radius: an acoustic-emission event's source radius in mean particle diameters [2];
    jaws (Brazilian): the curved jaws' radius in disc diameters, 0 for flat platens [1.5,
    ISRM]; flattened (Brazilian): the loading angle 2 alpha (degrees) of a disc with flat
    ends between flat platens, 0 for none [0]; rate_check: "warn" (a kinetic-energy
    ratio above 0.01 before the peak is warned of), "repeat" (also the test again at half
    the rate, warning when the strength moves by more than 2 % or E by more than 0.5 %)
    or "off" [warn];
    stress_path (triaxial): "constant_sigma3" or "constant_mean" (sigma_3 follows
    p0 - q / 3, so that the mean stress stays at the confinement's) [constant_sigma3];
    unload_at (triaxial): platen strains at which the platens turn back, unloading to
    ``unload_to`` of the deviator stress there [0.3] and reloading [none];
    max_strain: stop at this
    axial strain (platen or grip strain; for the agglomerate the plate displacement over
    the diameter) [0.05; Brazilian 0.1, agglomerate 0.2]; damping: local (non-viscous) damping
    coefficient [0.7, as PFC's default]; confining_stress: Pa, triaxial only;
    platen_material: the platens' Material [the particles' with no friction];
    ramp: the platens reach their speed over this many wave-crossing times [2];
    gauge: the gauge bands, fractions of the height from each end [(0.1, 0.25)];
    grip: fraction of the height gripped at each end in direct tension [0.1];
    samples: samples up to max_strain [2000]; frames: frames written to a results file
    [20]; max_steps: a bound on the steps [5e6]; safety_factor: of the time step [0.2];
    backend: "cpu" or "gpu".
    """
    strain_rate: float | None = None
    rate_rule: str = "bonds"
    post_peak: float = 0.7
    failure_bonds: float | None = None
    largest_fragment: float = 0.9
    ae_radius: float = AE_RADIUS_DEFAULT
    jaws: float = 1.5
    flattened: float = 0.0
    rate_check: str = "warn"
    stress_path: str = "constant_sigma3"
    unload_at: tuple = ()
    unload_to: float = 0.3
    max_strain: float | None = None
    damping: float = 0.7
    confining_stress: float | None = None
    platen_material: Material | None = None
    ramp: float = 2.0
    gauge: tuple = (0.1, 0.25)
    grip: float = 0.1
    samples: int = 2000
    frames: int = 20
    max_steps: int = 5_000_000
    safety_factor: float = 0.2
    backend: str = "cpu"

    def __post_init__(self):
        checks = [("post_peak", 0.0, 1.0), ("largest_fragment", 0.0, 1.0 + 1e-12),
                  ("ae_radius", 0.0, math.inf),
                  ("damping", -1e-300, 1.0),
                  ("ramp", -1e-300, math.inf), ("grip", 0.0, 0.5),
                  ("safety_factor", 0.0, 1.0)]
        for name, low, high in checks:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and low < value < high
                    or (name == "safety_factor" and value == 1.0)):
                raise ValueError(f"{name} = {value!r}; allowed range ({max(low, 0):g}, {high:g})")
        if not (isinstance(self.jaws, (int, float)) and (self.jaws == 0.0 or self.jaws > 0.5)
                and math.isfinite(self.jaws)):
            raise ValueError(f"jaws = {self.jaws!r}; 0 (flat platens) or a radius > 0.5 "
                             f"disc diameters")
        if not (isinstance(self.flattened, (int, float)) and 0.0 <= self.flattened < 90.0):
            raise ValueError(f"flattened = {self.flattened!r}; a loading angle in [0, 90) "
                             f"degrees")
        if self.rate_rule not in RATE_RULES:
            raise ValueError(f"rate_rule = {self.rate_rule!r}; allowed: "
                             f"{', '.join(RATE_RULES)}")
        if self.rate_check not in RATE_CHECKS:
            raise ValueError(f"rate_check = {self.rate_check!r}; allowed: "
                             f"{', '.join(RATE_CHECKS)}")
        if self.stress_path not in STRESS_PATHS:
            raise ValueError(f"stress_path = {self.stress_path!r}; allowed: "
                             f"{', '.join(STRESS_PATHS)}")
        if not all(isinstance(v, (int, float)) and 0.0 < v < 1.0 for v in self.unload_at):
            raise ValueError(f"unload_at = {list(self.unload_at)!r}; platen strains in (0, 1)")
        if not (isinstance(self.unload_to, (int, float)) and 0.0 <= self.unload_to < 1.0):
            raise ValueError(f"unload_to = {self.unload_to!r}; allowed range [0, 1)")
        if self.failure_bonds is not None and not (isinstance(self.failure_bonds, (int, float))
                                                   and 0.0 <= self.failure_bonds < 1.0):
            raise ValueError(f"failure_bonds = {self.failure_bonds!r}; allowed range [0, 1)")
        if self.max_strain is not None and not 0.0 < self.max_strain < 1.0:
            raise ValueError(f"max_strain = {self.max_strain!r}; allowed range (0, 1)")
        if self.strain_rate is not None and not (self.strain_rate > 0.0
                                                 and math.isfinite(self.strain_rate)):
            raise ValueError(f"strain_rate = {self.strain_rate!r}; must be > 0 (1/s)")
        if self.confining_stress is not None and not (self.confining_stress > 0.0
                                                      and math.isfinite(self.confining_stress)):
            raise ValueError(f"confining_stress = {self.confining_stress!r}; must be > 0 Pa")
        if not (0.0 <= self.gauge[0] < self.gauge[1] <= 0.5):
            raise ValueError(f"gauge = {self.gauge!r}; expected 0 <= low < high <= 0.5")
        for name in ("samples", "frames", "max_steps"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} = {getattr(self, name)!r}; must be >= 1")


@dataclass
class LabResult:
    """A finished test: ``curve`` {column: (S,) array} one row per sample (units in
    ``units``), ``numbers`` {name: value} (SI units, see ``units``), the settings used,
    notes, and the final state for the specimen picture: ``position`` (N,3) m, ``bonds``
    (B,2) and ``broken`` (B,) bool; ``cracks``: the crack log {column: (K,) array} (one
    row per broken bond, lab/cracks.py's COLUMNS) and ``ae`` the AE events grouped from it
    ({column: (E,) array}); ``fragments`` (agglomerate): every fragment's particles, mass
    (kg) and size (m), largest first; ``contacts``: the contacts loaded in the last step
    ({"i", "j", "force"} as ``Results.contacts``). ``no_failure``: None when the specimen failed, else
    why it has no strength (its strength numbers are then NaN)."""
    test: str
    curve: dict
    numbers: dict
    units: dict
    settings: dict
    notes: list = field(default_factory=list)
    position: np.ndarray | None = None
    bonds: np.ndarray | None = None
    broken: np.ndarray | None = None
    break_mode: np.ndarray | None = None
    no_failure: str | None = None
    cracks: dict | None = None
    ae: dict | None = None
    fragments: dict | None = None
    radius: np.ndarray | None = None
    contacts: dict | None = None

    def write(self, out_dir, figures=True):
        """Write lab.csv (the curve), lab.json (numbers, units, settings, notes) and the
        figures into ``out_dir``; returns {name: path}."""
        from .output import write_result
        return write_result(self, out_dir, figures=figures)


def _estimate_wave_time(specimen, axis):
    """Time (s) a compression wave takes to cross the specimen along ``axis``, from an
    estimate of its modulus: sum over bonds of k_n L^2 / (5 V) (the Voigt average of
    axial springs), and its bulk density."""
    size = specimen.size()
    volume = float(np.prod(size))
    if specimen.n_bonds:
        length = np.linalg.norm(specimen.position[specimen.bonds[:, 1]]
                                - specimen.position[specimen.bonds[:, 0]], axis=1)
        young = np.array([m.young_modulus for m in specimen.bond_materials])[
            specimen.bond_material_index]
        area = math.pi * 0.25 * specimen.bond_diameter ** 2
        stiffness = young * area / length
    else:
        # an adhesive agglomerate: its touching pairs as springs of Hertz's stiffness at
        # an overlap of LINEAR_REFERENCE_OVERLAP R* (contact_linear's default)
        from ..neighbors import build_pairs
        r = specimen.radius
        pairs = build_pairs(specimen.position, r, 1e-3 * float(r.mean()),
                            np.zeros(3, bool), np.zeros(3), np.zeros(3))
        length = np.linalg.norm(specimen.position[pairs[:, 1]]
                                - specimen.position[pairs[:, 0]], axis=1)
        m = specimen.materials[0]
        e_star = m.young_modulus / (2.0 * (1.0 - m.poisson_ratio ** 2))
        r_star = r[pairs[:, 0]] * r[pairs[:, 1]] / (r[pairs[:, 0]] + r[pairs[:, 1]])
        stiffness = 2.0 * e_star * math.sqrt(LINEAR_REFERENCE_OVERLAP) * r_star
    modulus = float(np.sum(stiffness * length * length) / (5.0 * volume))
    density = np.array([m.density for m in specimen.materials])[specimen.material_index]
    mass = float(np.sum(density * 4.0 / 3.0 * math.pi * specimen.radius ** 3))
    return size[axis] / math.sqrt(modulus / (mass / volume))


def _platen_material(specimen, settings):
    if settings.platen_material is not None:
        return settings.platen_material
    return dataclasses.replace(specimen.materials[0], friction=0.0, rolling_friction=0.0)


class _Probe:
    """Per-sample readings of a running test (positions, bonds, energies)."""

    def __init__(self, sim, axis, settings, exclude=None):
        self.sim, self.axis = sim, axis
        state = sim.state
        self.position0 = state.position.copy()
        self.near, self.far = measure.gauge_groups(state.position, axis, settings.gauge)
        self.band = measure.middle_band(state.position, axis)
        self.gauge0 = measure.gauge_length(state.position, self.near, self.far, axis)
        self.moving = np.ones(sim.model.n_particles, bool)
        if exclude is not None:
            self.moving[exclude] = False
        self.seen = np.zeros(sim.model.n_bonds, bool)
        self.cracks = []

    def log_cracks(self):
        """Keep the bonds broken since the last sample as crack events: where (the bond's
        midpoint now, m), when, how, and the loads of its last intact step (the normal
        force as E_b A_b times the bond strain)."""
        state, model = self.sim.state, self.sim.model
        new = np.flatnonzero((state.bond_break_mode != 0) & ~self.seen)
        if new.size == 0:
            return
        self.seen[new] = True
        i, j = model.bond_pairs[new, 0], model.bond_pairs[new, 1]
        middle = 0.5 * (state.position[i] + state.position[j])
        l0 = model.bond_initial_length[new]
        strain = (state.bond_previous_length[new] - l0) / l0
        young = np.array([m.young_modulus for m in model.bond_materials])[
            model.bond_material[new]]
        area = math.pi * 0.25 * model.bond_diameter[new] ** 2
        self.cracks.append({
            "time": state.bond_break_time[new], "x": middle[:, 0], "y": middle[:, 1],
            "z": middle[:, 2], "mode": state.bond_break_mode[new].astype(np.float64),
            "bond": new.astype(np.float64), "energy": state.bond_break_energy[new],
            "bond_strain": strain, "normal_force": young * area * strain,
            "tangential_force": np.linalg.norm(state.bond_tangential_force[new], axis=1),
            "twisting_moment": np.linalg.norm(state.bond_normal_moment[new], axis=1),
            "bending_moment": np.linalg.norm(state.bond_tangential_moment[new], axis=1)})

    def gauge_strain(self):
        """Extension of the gauge length (positive when it lengthens)."""
        now = measure.gauge_length(self.sim.state.position, self.near, self.far, self.axis)
        return (now - self.gauge0) / self.gauge0

    def lateral(self):
        return measure.lateral_strain(self.position0, self.sim.state.position, self.band,
                                      self.axis)

    def broken(self):
        self.log_cracks()
        mode = self.sim.state.bond_break_mode
        return (int(np.count_nonzero(mode == TENSION)),
                int(np.count_nonzero(mode == COMPRESSION)),
                int(np.count_nonzero(mode == SHEAR)))

    def energy_ratio(self):
        """Kinetic energy of the free particles over the elastic energy stored."""
        state, model = self.sim.state, self.sim.model
        m = self.moving
        kinetic = 0.5 * float(np.sum(model.mass[m] * np.einsum(
            "ij,ij->i", state.velocity[m], state.velocity[m]))) + 0.5 * float(np.sum(
                model.inertia[m] * np.einsum("ij,ij->i", state.angular_velocity[m],
                                             state.angular_velocity[m])))
        elastic = self.sim.bond_energy()
        return kinetic / elastic if elastic > 0.0 else math.nan


class _Runner:
    """The sample loop shared by the tests: steps, readings, stop rule, frames."""

    def __init__(self, sim, settings, steps_to_limit, out_dir, scene_text):
        self.sim, self.settings = sim, settings
        self.every = max(1, int(steps_to_limit // settings.samples))
        self.rows = []
        self.pending = []
        self.writer = None
        if out_dir is not None:
            from pathlib import Path

            from ..io.results import ResultsWriter
            out_dir = Path(out_dir)
            out_dir.mkdir(parents=True, exist_ok=True)
            self.writer = ResultsWriter(out_dir / "results.h5", sim, scene_text=scene_text,
                                        backend=settings.backend, scene_name="lab")
            self.writer.append(sim)
        self.frame_every = max(1, int(settings.samples // settings.frames))
        self.started = clock.monotonic()
        self.membrane = None

    def step(self):
        if self.membrane is None:
            self.sim.step(self.every)
            return
        self.membrane.advance(self.every)

    def wall_force(self, last):
        """Mean force (W,3) N on each wall over the steps since the last sample (``last``
        when none changed); the rows go on to the results file."""
        time, force, position = self.sim.wall_history.take()
        if self.writer is not None:
            self.pending.append((time, force, position))
        return force.mean(axis=0) if force.shape[0] else last

    def _flush(self):
        """Write the wall rows kept since the last frame (one file opening per frame)."""
        if self.pending:
            self.writer.append_wall_rows(*(np.concatenate(parts) for parts in
                                           zip(*self.pending)))
            self.pending = []

    def sample(self, row):
        self.rows.append(row)
        if self.writer is not None and len(self.rows) % self.frame_every == 0:
            self._flush()
            self.writer.append(self.sim)

    def finish(self):
        if self.writer is not None:
            self._flush()
            self.writer.append(self.sim)
            self.writer.close()
        curve = {k: np.array([r[k] for r in self.rows], dtype=np.float64)
                 for k in self.rows[0]} if self.rows else {}
        return curve, clock.monotonic() - self.started


MAX_STRAIN = {"ucs": 0.05, "triaxial": 0.05, "tension": 0.05, "brazilian": 0.1,
              "agglomerate": 0.2}
RATE = 5e-4   # strain per wave-crossing time of rate_rule "wave", the fastest rule
# rate_rule "bonds": wave-crossing times to the weakest bonds' failure strain. Measured on
# examples/lab_rock.toml with 1 MPa bonds: over 38 of them, halving the rate still moved
# the UCS by 2.5 %; over 100, by 0.7-1.0 % (the "wave" rate's UCS was 55 % too high).
BOND_RATE_WAVES = 100.0


def default_rate(specimen, settings, wave):
    """Strain rate (1/s) of the platen gap: ``settings.strain_rate``, or by its
    ``rate_rule`` RATE per wave-crossing time ``wave`` (s), for "bonds" no faster than the
    failure strain min(sigma_n, sigma_t) / E_b of the weakest bond material in use over
    BOND_RATE_WAVES wave-crossing times."""
    if settings.strain_rate is not None:
        return settings.strain_rate
    per_wave = RATE
    if settings.rate_rule == "bonds" and specimen.n_bonds:
        used = np.unique(np.asarray(specimen.bond_material_index))
        strain = min(min(m.normal_strength, m.tangential_strength) / m.young_modulus
                     for m in (specimen.bond_materials[int(i)] for i in used))
        per_wave = min(RATE, strain / BOND_RATE_WAVES)
    return per_wave / wave


# wave-crossing times over which the platens turn back in a cycle (over 2, the unloading
# modulus of a lattice came out 13 % low: the turn sends a wave; over 10, within 0.5 %)
REVERSAL_RAMP = 10.0
SERVO_GAIN = 0.15   # of the dead-beat gain 1 / (k dt), k the wall's contact stiffness
SERVO_INTEGRAL = 30   # steps: the servos' integral time (0.3 / 0 oscillates; measured)


FAILURE_BONDS = {"agglomerate": 0.1}   # others 0.01


def _limits(settings, test, specimen):
    """The settings with the test's default strain limit and failure fraction filled in;
    warns of a coarse specimen (``resolution_note``) before the test starts."""
    coarse = resolution_note(specimen)
    if coarse is not None:
        warnings.warn(coarse, stacklevel=4)
    if settings.max_strain is None:
        settings = dataclasses.replace(settings, max_strain=MAX_STRAIN[test])
    if settings.failure_bonds is None:
        settings = dataclasses.replace(settings, failure_bonds=FAILURE_BONDS.get(test, 0.01))
    return settings


UNBONDED_MIN_STRAIN = 0.05
# The load lost: past a peak the platens' stress at most LOAD_LOST of it, with at least
# LOST_DAMAGE of failure_bonds broken (so that no transient of the first contacts counts).
# Measured: a 36 x 9 mm disc between flat frictionless platens slid out whole (224 of
# 29183 bonds broken, its largest piece 99 % of the mass) and ran on to its strain limit,
# 652275 steps (38 minutes), reported as "no fall past a peak"; with the rule it stops at
# 186875 (8 minutes)
LOAD_LOST, LOST_DAMAGE = 0.02, 0.1
WHOLE = 0.9   # a specimen whose largest piece holds more of the mass did not break apart


def load_lost(stress, broken, n_bonds, top, settings):
    """Whether the load is lost past the peak (``LOAD_LOST``, ``LOST_DAMAGE``): stress and
    top (its peak so far) in Pa, broken of n_bonds."""
    return (top > 0.0 and stress <= LOAD_LOST * top
            and broken >= max(1.0, LOST_DAMAGE * settings.failure_bonds * n_bonds))


def _stop(stress, broken, n_bonds, strain, settings, top, pieces=None, largest_piece=None):
    """Stop rule: past the peak, with at least failure_bonds of the bonds broken (without
    bonds: past a platen strain of UNBONDED_MIN_STRAIN), below post_peak of it, and (an
    agglomerate: ``pieces`` = (fragments of 2+ particles, largest fragment's mass
    fraction) given) its largest fragment at most largest_fragment of the mass; or at the
    strain limit. Short of that fall, where the load is lost (``load_lost``; a failing
    specimen's loss is such a fall) and ``largest_piece`` is given (a function returning
    the largest fragment's mass fraction, called only then): below WHOLE the specimen
    broke apart (a failure), else it left the platens whole ("load lost": no failure)."""
    if strain >= settings.max_strain:
        return "strain limit"
    # without bonds (an adhesive agglomerate) the fall past the peak, once the platens
    # have pressed it by UNBONDED_MIN_STRAIN (before, the start's transients rule)
    failing = (strain >= UNBONDED_MIN_STRAIN if n_bonds == 0
               else broken >= max(1.0, settings.failure_bonds * n_bonds))
    if failing and top > 0.0 and stress <= settings.post_peak * top:
        if pieces is None or n_bonds == 0:
            return "post-peak"
        count, largest = pieces
        if largest <= settings.largest_fragment:
            return (f"post-peak (breakage: {100.0 * broken / n_bonds:.3g} % of the bonds "
                    f"broken, {count} fragments of 2+ particles, the largest "
                    f"{100.0 * largest:.3g} % of the mass)")
    elif largest_piece is not None and \
            load_lost(stress, broken, n_bonds, top, settings):
        largest = largest_piece()
        if largest < WHOLE:
            return (f"post-peak (the load lost with {100.0 * broken / n_bonds:.3g} % of the "
                    f"bonds broken: the specimen broke apart, its largest piece "
                    f"{100.0 * largest:.3g} % of the mass)")
        return "load lost"
    return None


def _common_numbers(curve, strain_key, stress_key, lateral_key=None):
    stress, strain = curve[stress_key], curve[strain_key]
    k = measure.peak(stress)
    out = {"peak_stress": float(stress[k]), "strain_at_peak": float(strain[k])}
    out.update(measure.moduli(strain, stress, curve[lateral_key] if lateral_key else None))
    broken = curve["broken_tension"] + curve["broken_compression"] + curve["broken_shear"]
    out["crack_initiation_stress"] = measure.crack_initiation(stress, broken)
    if "volumetric_strain" in curve:
        out["crack_damage_stress"] = cracks_mod.crack_damage(stress,
                                                             curve["volumetric_strain"])
    out["broken_bonds_at_peak"] = int(broken[k])
    out["broken_bonds_final"] = int(broken[-1])
    before = slice(0, k + 1)
    live = stress[before] >= 0.2 * stress[k]
    ratio = curve["kinetic_ratio"][before][live]
    out["kinetic_energy_ratio"] = float(np.nanmax(ratio)) if ratio.size and np.isfinite(
        ratio).any() else math.nan
    return out


UNITS = {"time": "s", "axial_stress": "Pa", "axial_strain": "1", "platen_strain": "1",
         "lateral_strain": "1", "volumetric_strain": "1", "force_top": "N",
         "force_bottom": "N", "force": "N", "displacement": "m", "gap": "m",
         "tensile_stress": "Pa", "deviator_stress": "Pa", "lateral_stress": "Pa",
         "broken_tension": "1", "broken_compression": "1", "broken_shear": "1",
         "kinetic_ratio": "1", "peak_stress": "Pa", "strain_at_peak": "1",
         "young_modulus_secant": "Pa", "young_modulus_tangent": "Pa", "poisson_ratio": "1",
         "crack_initiation_stress": "Pa", "broken_bonds_at_peak": "1",
         "broken_bonds_final": "1", "kinetic_energy_ratio": "1",
         "platen_force_mismatch": "1", "end_crack_fraction": "1", "fragments": "1",
         "fragments_multi": "1",
         "largest_fragment_fraction": "1",
         "strain_rate": "1/s", "time_step": "s", "steps": "1", "wall_time": "s",
         "tensile_strength": "Pa", "ucs": "Pa", "breakage_force": "N",
         "displacement_at_peak": "m", "confining_stress": "Pa",
         "peak_deviator_stress": "Pa", "confining_stress_error": "1",
         "confining_stress_error_final": "1", "confinement_axial_strain": "1",
         "confinement_lateral_strain": "1", "unloading_modulus": "Pa", "mean_stress": "Pa",
         "loading": "1",
         "mismatch": "1", "largest_stress": "Pa", "crack_damage_stress": "Pa",
         "cracks": "1", "ae_events": "1", "b_value": "1", "breakage_energy": "J",
         "applied_energy": "J", "fragment_size_d50": "m", "fragment_size_d10": "m",
         "loose_particles": "1", "diameter": "m", "thickness": "m",
         "height": "m",
         "cross_section": "m^2", "n_particles": "1", "n_bonds": "1"}


def _simulation(specimen, settings, walls=(), fixed=None, velocity=None):
    model, state = specimen.system(fixed=fixed, velocity=velocity, damping=settings.damping)
    contact = ContactSettings(model=specimen.contact_model)
    return Simulation(model, state, contact=contact, walls=walls,
                      safety_factor=settings.safety_factor, backend=settings.backend)


def _platens(specimen, settings, axis, speed, wave_time, material):
    """Two frictionless planes touching the specimen's ends along ``axis``, each moving in
    at ``speed`` (m/s) after a linear ramp over ``settings.ramp`` wave-crossing times."""
    low, high = specimen.bounds()
    ramp = settings.ramp * wave_time
    walls = []
    for point, sign in ((low, 1.0), (high, -1.0)):
        normal = np.zeros(3)
        normal[axis] = sign
        v = speed * normal   # along the normal: into the specimen
        if ramp > 0.0:
            motion = VelocityProfile([0.0, ramp], [np.zeros(3), v])
        else:
            motion = VelocityProfile([0.0], [v])
        walls.append(PlaneWall(point, normal, material, motion=motion, own_friction=True))
    return walls


MIN_ACROSS = 10   # particles across the smallest dimension below which results are coarse


def resolution_note(specimen):
    """A warning (str) when fewer than MIN_ACROSS particle diameters span the specimen's
    smallest dimension (its strength and modulus then depend on the packing's details);
    None otherwise, and for a lattice."""
    if specimen.lattice:
        return None
    size = specimen.size()
    across = float(np.min(size)) / (2.0 * float(np.mean(specimen.radius)))
    if across >= MIN_ACROSS:
        return None
    return (f"only {across:.3g} particle diameters across the specimen's smallest "
            f"dimension ({float(np.min(size)):.4g} m; at least {MIN_ACROSS} advised): its "
            f"numbers depend on the packing's details")


JAW_SEGMENTS = 96   # facets along a jaw's arc


def _jaws(specimen, settings, speed, wave, material):
    """ISRM's curved jaws for the Brazilian test: two cylindrical mesh surfaces of radius
    ``settings.jaws`` disc diameters (1.5: ISRM), their axes along the disc's (y) on the
    disc's side (concave: each curves around the disc, as ISRM's do), their apexes
    touching the disc's top and bottom, each spanning one diameter across and the
    thickness with a margin, moving in along z as ``_platens`` do. Each jaw touches the
    particle that reaches deepest into its arc: the disc's lowest (highest) one for a round
    disc, the outer rows of a flat-ended one. Each wall's reference point is its apex."""
    low, high = specimen.bounds()
    centre = 0.5 * (low + high)
    diameter = float(high[2] - low[2])
    r_jaw = settings.jaws * diameter
    margin = 0.25 * float(high[1] - low[1]) + 2.0 * float(np.max(specimen.radius))
    x = centre[0] + np.linspace(-0.5, 0.5, JAW_SEGMENTS + 1) * diameter
    rise = r_jaw - np.sqrt(r_jaw ** 2 - (x - centre[0]) ** 2)
    # the apex at which a particle touches the arc from inside: its centre r_jaw - r from
    # the arc's axis (r_jaw > D / 2 keeps every particle within reach)
    reach = np.sqrt((r_jaw - specimen.radius) ** 2 - (specimen.position[:, 0] - centre[0]) ** 2)
    z = specimen.position[:, 2]
    apexes = (float(np.min(z - r_jaw + reach)), float(np.max(z + r_jaw - reach)))
    ramp = settings.ramp * wave
    walls = []
    for apex, sign in zip(apexes, (-1.0, 1.0)):
        vertices = []
        for y in (low[1] - margin, high[1] + margin):
            # concave: the jaw rises towards the disc away from its apex and cradles it
            vertices.append(np.column_stack([x, np.full_like(x, y), apex - sign * rise]))
        vertices = np.concatenate(vertices)
        n = JAW_SEGMENTS + 1
        k = np.arange(JAW_SEGMENTS)
        triangles = np.concatenate([np.column_stack([k, k + 1, k + n]),
                                    np.column_stack([k + 1, k + n + 1, k + n])])
        v = np.array([0.0, 0.0, -sign * speed])   # into the disc
        motion = (VelocityProfile([0.0, ramp], [np.zeros(3), v]) if ramp > 0.0 else
                  VelocityProfile([0.0], [v]))
        walls.append(MeshWall(vertices, triangles, material, motion=motion,
                              rotation_center=(centre[0], centre[1], apex),
                              own_friction=True))
    return walls


def flatten_disc(specimen, angle):
    """The disc with flat ends for the flattened Brazilian test (Wang et al. 2004): the
    particles whose centres lie beyond (D / 2) cos(alpha) of its centre along z removed,
    2 alpha = ``angle`` (degrees) the loading angle, with their bonds."""
    low, high = specimen.bounds()
    middle = 0.5 * (low[2] + high[2])
    half = 0.5 * float(high[2] - low[2]) * math.cos(math.radians(0.5 * angle))
    keep = np.abs(specimen.position[:, 2] - middle) <= half - specimen.radius
    new = np.cumsum(keep) - 1
    bonded = keep[specimen.bonds[:, 0]] & keep[specimen.bonds[:, 1]]
    return dataclasses.replace(
        specimen, position=specimen.position[keep], radius=specimen.radius[keep],
        bonds=new[specimen.bonds[bonded]], bond_diameter=specimen.bond_diameter[bonded],
        material_index=specimen.material_index[keep],
        bond_material_index=specimen.bond_material_index[bonded],
        notes=[*specimen.notes, f"flattened to a loading angle of {angle:g} degrees "
                                f"({int(np.count_nonzero(~keep))} particles cut off)"])


def _finish(test, specimen, settings, sim, runner, numbers, stop, notes):
    curve, wall_time = runner.finish()
    state = sim.state
    coarse = resolution_note(specimen)
    if coarse is not None:
        notes = [*notes, f"warning: {coarse}"]
    cracks, ae = _crack_log(runner, curve, specimen, settings)
    numbers.update({"cracks": int(cracks["time"].size), "ae_events": int(ae["time"].size),
                    "b_value": cracks_mod.b_value(ae["magnitude"])})
    if curve:
        curve["ae_events"] = np.searchsorted(np.sort(ae["time"]), curve["time"],
                                             side="right").astype(np.float64)
    count, multi, largest = measure.fragments(sim.model.bond_pairs, state.bond_active,
                                              sim.model.mass)
    numbers.update({"fragments": count, "fragments_multi": multi,
                    "largest_fragment_fraction": largest,
                    "time_step": sim.time_step, "steps": int(state.step),
                    "wall_time": wall_time, "n_particles": specimen.n_particles,
                    "n_bonds": specimen.n_bonds})
    notes = [*specimen.notes, *notes, f"stopped: {stop}"]
    result = LabResult(test, curve, numbers, {k: UNITS.get(k, "") for k in (*curve, *numbers)},
                       _settings_dict(settings), notes, state.position.copy(),
                       sim.model.bond_pairs.copy(), ~state.bond_active.copy(),
                       state.bond_break_mode.copy(), cracks=cracks, ae=ae,
                       radius=sim.model.radius.copy(), contacts=_contacts(sim))
    if runner.writer is not None:
        _write_cracks(runner.writer.path, cracks, ae)
    if not stop.startswith("post-peak"):
        broken = f"{int(np.count_nonzero(~state.bond_active))} of {sim.model.n_bonds} bonds"
        result.no_failure = "the specimen did not fail: " + (
            f"its load fell to {100 * LOAD_LOST:g} % of the peak with {broken} broken and "
            f"its largest piece {100 * largest:.3g} % of the mass: it left the platens "
            f"whole (slid or rolled out from between them)" if stop == "load lost" else
            f"stopped at the {stop} with {broken} broken and no fall past a peak (to "
            f"{settings.post_peak:g} of it, or to {PEAK_PASSED:g} of it at the end with "
            f"{100 * settings.failure_bonds:g} % of the bonds broken)")
    return result


def _crack_log(runner, curve, specimen, settings):
    """The crack events (``cracks.COLUMNS``, by time) and the AE events grouped from them:
    within ``settings.ae_radius`` mean particle diameters of an event's crack and within
    the time a compression wave takes to cross that distance of its latest crack."""
    parts = runner.probe.cracks
    cracks = ({k: np.concatenate([p[k] for p in parts]) for k in parts[0]} if parts else
              {k: np.zeros(0) for k in cracks_mod.COLUMNS if k not in
               ("axial_strain", "platen_strain", "event")})
    order = np.argsort(cracks["time"], kind="stable")
    cracks = {k: v[order] for k, v in cracks.items()}
    for key in ("axial_strain", "platen_strain"):
        cracks[key] = (np.interp(cracks["time"], curve["time"], curve[key])
                       if curve and cracks["time"].size else np.zeros(cracks["time"].size))
    radius = settings.ae_radius * 2.0 * float(np.mean(specimen.radius))
    position = np.stack([cracks["x"], cracks["y"], cracks["z"]], axis=1)
    label = cracks_mod.group_events(cracks["time"], position, radius,
                                    radius / runner.wave_speed)
    cracks["event"] = label.astype(np.float64)
    return cracks, cracks_mod.events(cracks["time"], position, cracks["energy"], label)


def _contacts(sim):
    """The contacts that carried a load in the last step (io.results.contact_rows)."""
    from ..io.results import contact_rows
    i, j, force = contact_rows(sim)
    return {"i": i, "j": j, "force": force}


def _write_cracks(path, cracks, ae):
    """The crack log and the AE events into results file ``path`` (/lab/cracks,
    /lab/ae_events: one dataset per column, units as attributes)."""
    import h5py
    try:   # no file lock, as the results writer (a reader may hold the file open)
        handle = h5py.File(path, "r+", locking=False)
    except TypeError:
        handle = h5py.File(path, "r+")
    with handle as f:
        if "lab" in f:
            del f["lab"]
        for name, table in (("cracks", cracks), ("ae_events", ae)):
            group = f.create_group(f"lab/{name}")
            for key, values in table.items():
                data = group.create_dataset(key, data=np.asarray(values))
                data.attrs["unit"] = cracks_mod.UNITS.get(key, {
                    "cracks": "1", "magnitude": "1"}.get(key, ""))


def _honest(result):
    """A test that did not fail has no strength: its strength numbers become NaN (null in
    lab.json, missing in calibration) and ``no_failure`` says why; largest_stress keeps
    the largest stress (or force) the curve reached."""
    result.numbers["largest_stress"] = result.numbers.get("peak_stress", math.nan)
    stress = result.curve.get(STRESS[result.test])
    n_bonds = result.numbers.get("n_bonds", 0)
    if result.no_failure is not None and stress is not None and stress.size and n_bonds:
        # a confined specimen may keep a residual strength above post_peak: past a peak
        # it fell from by PEAK_PASSED, with failure_bonds broken, it failed all the same
        top = float(np.max(stress))
        broken = result.numbers.get("broken_bonds_final", 0)
        if top > 0.0 and stress[-1] <= PEAK_PASSED * top and \
                broken >= max(1.0, result.settings["failure_bonds"] * n_bonds):
            result.notes.append(f"failed: past the peak the stress fell to "
                                f"{stress[-1] / top:.3g} of it (a residual strength) with "
                                f"{broken} bonds broken")
            result.no_failure = None
    if result.no_failure is not None:
        for name in STRENGTHS:
            if name in result.numbers:
                result.numbers[name] = math.nan
        result.notes.append(f"no strength: {result.no_failure}")
    result.units = {k: UNITS.get(k, "") for k in (*result.curve, *result.numbers)}
    if result.test == "agglomerate":   # a force, not a stress
        result.units.update(peak_stress="N", largest_stress="N")
    return result


PEAK_PASSED = 0.9   # a stress at most this fraction of the peak at the end: a peak passed
# what only a specimen that failed has (a curve stopped at its strain limit has none)
STRENGTHS = ("ucs", "tensile_strength", "peak_deviator_stress", "breakage_force",
             "peak_stress", "strain_at_peak", "displacement_at_peak")


def _settings_dict(settings):
    out = {}
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        out[f.name] = (value.__dict__ if isinstance(value, Material) else
                       list(value) if isinstance(value, tuple) else value)
    return out


def _compression(test, specimen, settings, axis, out_dir, scene_text, confining=None):
    """UCS (confining None) and the loading stage of a triaxial test."""
    wave = _estimate_wave_time(specimen, axis)
    rate = default_rate(specimen, settings, wave)
    height = float(specimen.size()[axis])
    material = _platen_material(specimen, settings)
    speed = 0.5 * rate * height
    notes = []
    membrane, lateral_walls = None, []
    if confining is None:
        jaws = test == "brazilian" and settings.jaws > 0.0 and settings.flattened == 0.0
        walls = (_jaws(specimen, settings, speed, wave, material) if jaws else
                 _platens(specimen, settings, axis, speed, wave, material))
        sim = _simulation(specimen, settings, walls)
    elif specimen.shape == "cylinder":
        sim, walls, membrane, confine_note = _membrane_confine(specimen, settings, axis,
                                                               speed, material, wave)
        notes.append(confine_note)
        for w in walls:
            w.motion.hold(speed, ramp=settings.ramp * wave)
    else:
        sim, walls, lateral_walls, confine_note = _confine(specimen, settings, axis, speed,
                                                           material, wave)
        notes.append(confine_note)
        for w in walls:
            w.motion.hold(speed, ramp=settings.ramp * wave)
    bottom, top = walls[0], walls[1]
    probe = _Probe(sim, axis, settings)
    gap0 = top.position(sim.state.time)[axis] - bottom.position(sim.state.time)[axis]
    area0 = specimen.cross_section(axis)
    steps_to_limit = settings.max_strain / rate / sim.time_step
    runner = _Runner(sim, settings, steps_to_limit, out_dir, scene_text)
    runner.probe, runner.wave_speed = probe, height / wave
    runner.membrane = membrane
    # the walls' rows of a confining stage go to the results file, not into the first
    # sample's mean force
    force = runner.wall_force(np.zeros((len(sim.walls), 3)))
    top_stress, stop = 0.0, None
    # bonds a confining stage broke are no failure under the deviator: the stop rule
    # counts those broken since (a confinement that broke 8 % of them once stopped the
    # test at its first dip of a few kPa)
    broken_before = int(np.count_nonzero(np.isin(sim.state.bond_break_mode,
                                                 (TENSION, COMPRESSION, SHEAR))))
    sigma3 = confining            # the confining stress applied now (its path may move it)
    turns = sorted(settings.unload_at) if confining is not None else []
    cycle = None                  # while a cycle runs: the deviator stress at its turn
    while stop is None and sim.state.step < settings.max_steps:
        runner.step()
        force = runner.wall_force(force)
        t = sim.state.time
        f_bottom, f_top = -force[0, axis], force[1, axis]
        gap = top.position(t)[axis] - bottom.position(t)[axis]
        row = {"time": t, "force_bottom": f_bottom, "force_top": f_top, "gap": gap,
               "platen_strain": (gap0 - gap) / gap0, "axial_strain": -probe.gauge_strain(),
               "lateral_strain": probe.lateral()}
        if confining is None:
            row["axial_stress"] = 0.5 * (f_bottom + f_top) / area0
        elif membrane is not None:
            row["cross_section"] = membrane.cross_section()
            sigma1 = 0.5 * (f_bottom + f_top) / row["cross_section"]
            row["axial_stress"] = sigma1
            row["deviator_stress"] = sigma1 - sigma3
            row["lateral_stress"] = membrane.lateral_stress()
            row["lateral_stress_worst"] = abs(row["lateral_stress"] / sigma3 - 1.0)
        else:
            widths = _lateral_widths(lateral_walls, t, axis)
            area = widths[0] * widths[1]
            sigma1 = 0.5 * (f_bottom + f_top) / area
            lateral_force = [-np.dot(force[2 + k], w.normal) for k, w in enumerate(lateral_walls)]
            faces = [gap * widths[1], gap * widths[1], gap * widths[0], gap * widths[0]]
            row["axial_stress"] = sigma1
            row["deviator_stress"] = sigma1 - sigma3
            row["lateral_stress"] = float(np.mean(np.array(lateral_force) / np.array(faces)))
            row["lateral_stress_worst"] = float(max(abs(f / a / sigma3 - 1.0)
                                                    for f, a in zip(lateral_force, faces)))
        if confining is not None:
            row["confining_stress"] = sigma3
            row["mean_stress"] = (sigma1 + 2.0 * row["lateral_stress"]) / 3.0
            q = row["deviator_stress"]
            if settings.stress_path == "constant_mean":
                # p = (sigma_1 + 2 sigma_3) / 3 held at the confinement's: sigma_3 = p0 - q / 3
                sigma3 = max(confining - q / 3.0, 1e-6 * confining)
                if membrane is not None:
                    membrane.pressure = sigma3
                for w in lateral_walls:
                    w.motion.target_stress = sigma3
            if cycle is None and turns and row["platen_strain"] >= turns[0]:
                cycle = q
                for w in walls[:2]:
                    w.motion.hold(-speed, ramp=REVERSAL_RAMP * wave)
            elif cycle is not None and walls[0].motion.held_speed < 0.0 and \
                    q <= settings.unload_to * cycle:
                for w in walls[:2]:
                    w.motion.hold(speed, ramp=REVERSAL_RAMP * wave)
            elif cycle is not None and walls[0].motion.held_speed > 0.0 and q >= cycle:
                cycle = None
                turns.pop(0)
            row["loading"] = -1.0 if walls[0].motion.held_speed < 0.0 else 1.0
        row["volumetric_strain"] = row["axial_strain"] - 2.0 * row["lateral_strain"]
        pieces = None   # an agglomerate's: (fragments of 2+, largest one's mass fraction)
        if test == "agglomerate":
            count, multi, largest = measure.fragments(sim.model.bond_pairs,
                                                      sim.state.bond_active, sim.model.mass)
            row["fragments"], row["fragments_multi"] = float(count), float(multi)
            pieces = multi, largest
        tension, compression, shear = probe.broken()
        row.update({"broken_tension": tension, "broken_compression": compression,
                    "broken_shear": shear, "kinetic_ratio": probe.energy_ratio()})
        runner.sample(row)
        key = "axial_stress" if confining is None else "deviator_stress"
        top_stress = max(top_stress, row[key])
        if cycle is not None:
            continue   # an unloading-reloading cycle is no failure
        stop = _stop(row[key], tension + compression + shear - broken_before,
                     sim.model.n_bonds, row["platen_strain"], settings, top_stress, pieces,
                     None if pieces else lambda: measure.fragments(
                         sim.model.bond_pairs, sim.state.bond_active, sim.model.mass)[2])
    return sim, runner, rate, stop or "max_steps", notes


def _lateral_widths(lateral_walls, t, axis):
    """Distances (m) between the two lateral wall pairs."""
    out = []
    for pair in (lateral_walls[0:2], lateral_walls[2:4]):
        k = int(np.argmax(np.abs(pair[0].normal)))
        out.append(abs(pair[1].position(t)[k] - pair[0].position(t)[k]))
    return out


def wall_stiffness(sim, specimen, material):
    """stiffness(w): the sum (N/m) of the Hertz tangent stiffnesses 2 E* sqrt(R d) of wall
    w's contacts in the last step, each d from its force F = 4/3 E* sqrt(R) d^1.5 (what a
    servo's gain is tuned to; computed once per step for all walls)."""
    platen = material
    particle = specimen.materials[0]
    e_star = 1.0 / ((1.0 - particle.poisson_ratio ** 2) / particle.young_modulus
                    + (1.0 - platen.poisson_ratio ** 2) / platen.young_modulus)
    cache = {}

    def stiffness(w):
        now = sim.state.step
        if cache.get("step") != now:
            extra = sim.state.extra
            n_walls = len(sim.walls)
            total = np.zeros(n_walls)
            if "wall_pairs" in extra and extra["wall_pairs"].shape[0]:
                pairs = extra["wall_pairs"]
                force = np.linalg.norm(extra["wall_force_rows"], axis=1)
                root = np.sqrt(sim.model.radius[pairs[:, 0]])
                k = 2.0 * e_star * root * np.cbrt(3.0 * force / (4.0 * e_star * root))
                owner = sim.contacts.walls.element_wall[pairs[:, 1]]
                total = np.bincount(owner, weights=k, minlength=n_walls)
            cache.update(step=now, total=total)
        return float(cache["total"][w])

    return stiffness


def _servo_plane(point, k, sign, material, sigma):
    """A plane through ``point`` facing ``sign`` along axis k, servo-controlled to the
    stress sigma (Pa); ``_tune_servos`` sets its area, gain and speed cap."""
    normal = np.zeros(3)
    normal[k] = sign
    return PlaneWall(point, normal, material, motion=Servo(
        target_stress=sigma, area=1.0, stiffness=lambda: 0.0, max_velocity=1.0,
        tolerance=0.005, fraction=SERVO_GAIN), own_friction=True)


def _tune_servos(sim, specimen, material, walls, areas, speed):
    """Each servo wall's area (a function, m^2), its gain tuned to its contacts' Hertz
    stiffness (``wall_stiffness``), its speed cap (4 times the platen speed, at least
    1e-3 r per step) and its integral time."""
    dt = sim.time_step
    stiffness = wall_stiffness(sim, specimen, material)
    cap = max(4.0 * speed, 1e-3 * float(np.mean(specimen.radius)) / dt)
    for index, (w, area) in enumerate(zip(walls, areas)):
        w.motion.area = area
        w.motion.stiffness = (lambda i=index: stiffness(i))
        w.motion.max_velocity = cap
        w.motion.integral_time = SERVO_INTEGRAL * dt


def _settle(sim, walls, advance, wave, least, max_steps):
    """Advance (``advance(steps)``) in blocks of half a wave-crossing time (at least
    ``least`` steps) until every servo of ``walls`` holds its target after at least 20
    wave-crossing times (the specimen settles), at most 500; returns (steps, reached)."""
    probe_time, limit = 20.0 * wave, 500.0 * wave
    block = max(least, int(0.5 * wave / sim.time_step))
    steps, reached = 0, False
    while steps < max_steps and sim.state.time < limit:
        advance(block)
        steps += block
        reached = all(w.motion.reached for w in walls)
        if sim.state.time > probe_time and reached:
            break
    return steps, reached


def _confine(specimen, settings, axis, speed, material, wave):
    """Six servo walls (two platens, four lateral) press a box specimen to the confining
    stress; returns (simulation, platens, lateral walls, note) once every wall holds it."""
    if specimen.shape != "box":
        raise ValueError("a triaxial test needs a box specimen (plane lateral walls) or a "
                         "cylinder (a membrane)")
    sigma = settings.confining_stress
    low, high = specimen.bounds()
    walls = [_servo_plane(point, k, sign, material, sigma)
             for k in [axis] + [k for k in range(3) if k != axis]
             for point, sign in ((low, 1.0), (high, -1.0))]
    sim = _simulation(specimen, settings, walls)
    width = box_widths(sim, walls)
    areas = []
    for w in walls:
        k = int(np.argmax(np.abs(w.normal)))
        others = [j for j in range(3) if j != k]
        areas.append(lambda o=others: width(o[0]) * width(o[1]))
    _tune_servos(sim, specimen, material, walls, areas, speed)
    steps, reached = _settle(sim, walls, sim.step, wave, 10, settings.max_steps)
    worst = max(abs(w.motion.error) for w in walls)
    return sim, walls[:2], walls[2:], (f"confined to {sigma:.4g} Pa in {steps} steps "
                                       f"(worst wall {100 * worst:.2g} % off"
                                       + ("" if reached else "; not settled") + ")")


KINETIC_LIMIT = 0.01   # kinetic over elastic energy before the peak: above, not quasi-static
RATE_STRENGTH_TOLERANCE = 0.02   # a strength that moves more at half the rate: warned of
RATE_MODULUS_TOLERANCE = 0.005
STRENGTH_OF = {"ucs": "ucs", "triaxial": "peak_deviator_stress",
               "brazilian": "tensile_strength", "tension": "tensile_strength",
               "agglomerate": "breakage_force"}


def _rate_checked(run):
    """The test ``run`` with its rate checked (``settings.rate_check``): "warn" notes and
    warns when the kinetic-energy ratio before the peak exceeds KINETIC_LIMIT; "repeat"
    also runs the test again at half the strain rate and reports how much the strength
    and the secant modulus moved (rate_change_strength, rate_change_modulus), warning
    above 2 % and 0.5 %; "off" does neither."""
    @functools.wraps(run)
    def checked(specimen, settings=None, **options):
        result = run(specimen, settings, **options)
        settings = settings or LabSettings()
        if settings.rate_check == "off":
            return result
        test, n = result.test, result.numbers
        problems = []
        ratio = n.get("kinetic_energy_ratio", math.nan)
        if ratio > KINETIC_LIMIT:
            problems.append(f"the kinetic energy reached {ratio:.3g} of the elastic energy "
                            f"before the peak (above {KINETIC_LIMIT:g}): not quasi-static")
        if settings.rate_check == "repeat":
            half = dataclasses.replace(settings, strain_rate=0.5 * n["strain_rate"],
                                       rate_check="off")
            slow = run(specimen, half).numbers
            for key, name, tolerance in ((STRENGTH_OF[test], "strength",
                                          RATE_STRENGTH_TOLERANCE),
                                         ("young_modulus_secant", "modulus",
                                          RATE_MODULUS_TOLERANCE)):
                if not (math.isfinite(n.get(key, math.nan)) and n[key] != 0.0
                        and math.isfinite(slow.get(key, math.nan))):
                    continue   # no strength (or modulus) in one of the runs: nothing to say
                change = slow[key] / n[key] - 1.0
                n[f"rate_change_{name}"] = change
                result.units[f"rate_change_{name}"] = "1"
                if not abs(change) <= tolerance:
                    problems.append(f"at half the strain rate its {key} moved by "
                                    f"{100 * change:.3g} % (more than {100 * tolerance:g} %)")
        for problem in problems:
            warnings.warn(f"{test}: {problem}; lower test.strain_rate", stacklevel=2)
            result.notes.insert(len(result.notes) - 1, f"warning: {problem}")
        return result

    return checked


MEMBRANE_EVERY = 10   # steps between updates of the membrane's forces


class _Membrane:
    """The membrane of a cylindrical triaxial test (lab/membrane.py): every MEMBRANE_EVERY
    steps the confining pressure is put on the outermost particles between the platens
    as the model's external forces (read by the integrator every step)."""

    def __init__(self, sim, axis, pressure, cell, platens):
        self.sim, self.axis, self.pressure, self.cell = sim, axis, pressure, cell
        self.platens = platens
        self.surface = self.radius = self.gap = 0.0
        self.update()

    def update(self):
        sim, axis = self.sim, self.axis
        t = sim.state.time
        low = self.platens[0].position(t)[axis]
        high = self.platens[1].position(t)[axis]
        force, self.surface, self.radius = membrane_forces(
            sim.state.position, sim.model.radius, axis, low, high, self.pressure, self.cell)
        sim.model.external_force[...] = force
        self.gap = high - low

    def advance(self, steps):
        """Take ``steps`` steps, the membrane's forces renewed every MEMBRANE_EVERY."""
        while steps > 0:
            n = min(steps, MEMBRANE_EVERY)
            self.sim.step(n)
            self.update()
            steps -= n

    def cross_section(self):
        """The specimen's current cross-section pi R^2 (m^2): the mean area the
        membrane's polygons enclose (lab/membrane.py)."""
        return math.pi * self.radius ** 2

    def lateral_stress(self):
        """The confining stress the membrane applies over the current lateral surface
        2 pi R gap (Pa): sigma_3 times the share of its rows pressed (a row of fewer than
        three vertices encloses nothing and is not)."""
        nominal = 2.0 * math.pi * self.radius * self.gap
        return self.pressure * self.surface / nominal if nominal > 0.0 else math.nan


def _membrane_confine(specimen, settings, axis, speed, material, wave):
    """A cylinder in a membrane (lab/membrane.py) between two servo platens pressed to the
    confining stress; returns (simulation, platens, membrane, note) once the platens hold
    it. The strains of this isotropic stage go into the note and into ``membrane``
    (axial_strain from the gauge bands, lateral_strain from the middle band)."""
    if settings.backend != "cpu":
        raise ValueError("the membrane triaxial test runs on the CPU backend (the "
                         "membrane's forces are renewed on the host)")
    sigma = settings.confining_stress
    low, high = specimen.bounds()
    platens = [_servo_plane(point, axis, sign, material, sigma)
               for point, sign in ((low, 1.0), (high, -1.0))]
    sim = _simulation(specimen, settings, platens)
    membrane = _Membrane(sim, axis, sigma, 2.0 * float(np.mean(specimen.radius)), platens)
    _tune_servos(sim, specimen, material, platens, [membrane.cross_section] * 2, speed)
    probe = _Probe(sim, axis, settings)
    steps, reached = _settle(sim, platens, membrane.advance, wave, MEMBRANE_EVERY,
                             settings.max_steps)
    membrane.axial_strain = -probe.gauge_strain()
    membrane.lateral_strain = -probe.lateral()
    worst = max(abs(w.motion.error) for w in platens)
    return sim, platens, membrane, (
        f"confined in a membrane to {sigma:.4g} Pa in {steps} steps (platens "
        f"{100 * worst:.2g} % off" + ("" if reached else "; not settled") + "; strains "
        f"axial {membrane.axial_strain:.4g}, lateral {membrane.lateral_strain:.4g})")


@_rate_checked
def uniaxial(specimen, settings=None, *, out_dir=None, scene_text="", axis=2):
    """Unconfined compression (UCS) between frictionless platens along ``axis``.

    Axial stress: the mean of both platen forces over the initial cross-section; axial
    strain from the gauge bands (and ``platen_strain`` from the platen gap); lateral strain
    from the particles of the middle band. Numbers: ucs (the peak, Pa), strain_at_peak,
    young_modulus_secant and _tangent at 50 % of the peak (Pa), poisson_ratio,
    crack_initiation_stress, platen_force_mismatch (analysis.walls.force_mismatch: the
    largest |F_top - F_bottom| up to the peak over the peak's mean force),
    kinetic_energy_ratio, broken bonds, fragments."""
    settings = _limits(settings or LabSettings(), "ucs", specimen)
    sim, runner, rate, stop, notes = _compression("ucs", specimen, settings, axis, out_dir,
                                                  scene_text)
    result = _finish("ucs", specimen, settings, sim, runner, {}, stop, notes)
    result.numbers.update(_common_numbers(result.curve, "axial_strain", "axial_stress",
                                          "lateral_strain"))
    result.numbers.update({"ucs": result.numbers["peak_stress"], "strain_rate": rate,
                           "cross_section": specimen.cross_section(axis),
                           "height": float(specimen.size()[axis]),
                           "platen_force_mismatch": _mismatch(result.curve, "axial_stress")})
    return _honest(result)


def _mismatch(curve, key):
    """The platens' force mismatch (analysis.walls.force_mismatch, the one definition)
    up to the peak of ``key``; NaN without a compressive force there."""
    value = force_mismatch(curve["force_top"], curve["force_bottom"],
                           measure.peak(curve[key]))
    return math.nan if value is None else value


@_rate_checked
def triaxial(specimen, settings=None, *, out_dir=None, scene_text="", axis=2):
    """Confined compression. A cylinder: a flexible membrane (lab/membrane.py) and two
    servo platens press it to ``settings.confining_stress``; a box: six servo walls. Then
    the platens load it at the strain rate while the membrane (or the four lateral walls,
    on their current areas) holds the confining stress. Numbers as ``uniaxial`` on the
    deviator stress q = sigma_1 - sigma_3 (peak_deviator_stress); confining_stress_error:
    the largest relative deviation of the lateral stress from the target before the peak,
    confining_stress_error_final: over the whole test; a cylinder's
    confinement_axial_strain and confinement_lateral_strain: the strains of the isotropic
    stage (extension positive)."""
    settings = _limits(settings or LabSettings(), "triaxial", specimen)
    if settings.confining_stress is None:   # else it would run as an unconfined test
        raise ValueError("a triaxial test needs confining_stress (Pa)")
    sim, runner, rate, stop, notes = _compression("triaxial", specimen, settings, axis,
                                                  out_dir, scene_text,
                                                  confining=settings.confining_stress)
    result = _finish("triaxial", specimen, settings, sim, runner, {}, stop, notes)
    curve = result.curve
    if not curve:   # max_steps ran out while confining: no sample, no numbers, and why
        return _honest(result)
    result.numbers.update(_common_numbers(curve, "axial_strain", "deviator_stress",
                                          "lateral_strain"))
    k = measure.peak(curve["deviator_stress"])
    result.numbers.update({
        "peak_deviator_stress": result.numbers["peak_stress"],
        "peak_stress": float(curve["axial_stress"][k]), "strain_rate": rate,
        "confining_stress": settings.confining_stress,
        "confining_stress_error": float(np.max(curve["lateral_stress_worst"][:k + 1])),
        "confining_stress_error_final": float(np.max(curve["lateral_stress_worst"])),
        "platen_force_mismatch": _mismatch(curve, "deviator_stress")})
    if settings.unload_at:
        result.numbers["unloading_modulus"] = measure.unloading_modulus(
            curve["axial_strain"], curve["deviator_stress"], curve["loading"])
    if runner.membrane is not None:
        result.numbers.update({
            "confinement_axial_strain": -runner.membrane.axial_strain,
            "confinement_lateral_strain": -runner.membrane.lateral_strain})
    return _honest(result)


@_rate_checked
def brazilian(specimen, settings=None, *, out_dir=None, scene_text=""):
    """Brazilian test: a disc (axis y) compressed across its diameter along z between
    ISRM's curved jaws (``settings.jaws`` diameters in radius; 0: flat platens), or, with
    ``settings.flattened`` (the loading angle 2 alpha, degrees), a disc with flat ends
    between flat platens. Tensile strength 2 F_peak / (pi D t) (flattened: times
    cos^3 alpha, Wang et al. 2004), D the diameter (extent along z), t the thickness
    (extent along y); the curve's tensile_stress is that of the mean jaw force and its
    strain the jaws' displacement over D."""
    settings = _limits(settings or LabSettings(), "brazilian", specimen)
    if specimen.shape not in ("disc", "cylinder", "box"):
        raise ValueError("a Brazilian test needs a disc specimen")
    axis = 2
    size = specimen.size()
    diameter, thickness = float(size[2]), float(size[1])
    factor = 1.0
    if settings.flattened > 0.0:
        specimen = flatten_disc(specimen, settings.flattened)
        factor = math.cos(math.radians(0.5 * settings.flattened)) ** 3
    sim, runner, rate, stop, notes = _compression("brazilian", specimen, settings, axis,
                                                  out_dir, scene_text)
    result = _finish("brazilian", specimen, settings, sim, runner, {}, stop, notes)
    curve = result.curve
    mean = 0.5 * (curve["force_top"] + curve["force_bottom"])
    curve["force"] = mean
    curve["tensile_stress"] = factor * 2.0 * mean / (math.pi * diameter * thickness)
    curve["displacement"] = diameter * curve["platen_strain"]
    k = measure.peak(curve["tensile_stress"])
    broken = curve["broken_tension"] + curve["broken_compression"] + curve["broken_shear"]
    result.numbers.update({
        "tensile_strength": float(curve["tensile_stress"][k]),
        "peak_stress": float(curve["tensile_stress"][k]),
        "breakage_force": float(mean[k]), "displacement_at_peak": float(curve["displacement"][k]),
        "strain_at_peak": float(curve["platen_strain"][k]),
        "crack_initiation_stress": measure.crack_initiation(curve["tensile_stress"], broken),
        "broken_bonds_at_peak": int(broken[k]), "broken_bonds_final": int(broken[-1]),
        "diameter": diameter, "thickness": thickness, "strain_rate": rate,
        "platen_force_mismatch": _mismatch(curve, "tensile_stress")})
    ends = end_crack_fraction(result.cracks, float(curve["time"][k]), specimen.position,
                              diameter, axis)
    result.numbers["end_crack_fraction"] = ends
    crushed = crushed_note(ends)
    if crushed is not None:
        warnings.warn(f"brazilian: {crushed}", stacklevel=3)
        result.notes.insert(-1, f"warning: {crushed}")
    return _honest(result)


END_CRACKS = 0.5   # a Brazilian disc with more of its cracks at the loaded ends: crushed


def crushed_note(ends):
    """The warning for a Brazilian disc with the fraction ``ends`` of its cracks up to the
    peak near a loaded end (``end_crack_fraction``), or None at most END_CRACKS (or NaN:
    no cracks)."""
    if not ends > END_CRACKS:
        return None
    return (f"{100 * ends:.0f} % of the cracks up to the peak lie within 0.4 R of a loaded "
            f"end: the disc crushed under its loads before it split, so its tensile "
            f"strength is not a Brazilian one (the bonds under the few particles that "
            f"carry the load broke first, in bending or shear; parallel bonds whose "
            f"bending adds nothing to their stress, moment_factor = 0, crack nearer the "
            f"centre; docs/lab.md)")


def end_crack_fraction(cracks, peak_time, position, diameter, axis=2):
    """Fraction of the cracks up to ``peak_time`` (s) that lie within 0.4 R of a loaded
    end: farther than 0.6 R along ``axis`` from the disc's centre (the middle of the
    particles' extent ``position`` (N,3) m; R half the ``diameter``, m). ISRM's test is
    valid when the disc splits from its centre; NaN with no crack up to the peak."""
    before = cracks["time"] <= peak_time
    if not np.any(before):
        return math.nan
    along = position[:, axis]
    centre = 0.5 * (float(along.min()) + float(along.max()))
    key = "xyz"[axis]
    far = np.abs(cracks[key][before] - centre) > 0.6 * 0.5 * diameter
    return float(np.count_nonzero(far)) / float(np.count_nonzero(before))


@_rate_checked
def agglomerate(specimen, settings=None, *, out_dir=None, scene_text=""):
    """An agglomerate pressed between two plates along z (Kozhar et al. 2015): force
    against the decrease of the plate gap; breakage_force is the peak force before the
    force falls to post_peak of it; displacement_at_peak in m."""
    settings = _limits(settings or LabSettings(), "agglomerate", specimen)
    sim, runner, rate, stop, notes = _compression("agglomerate", specimen, settings, 2,
                                                  out_dir, scene_text)
    result = _finish("agglomerate", specimen, settings, sim, runner, {}, stop, notes)
    curve = result.curve
    curve["force"] = 0.5 * (curve["force_top"] + curve["force_bottom"])
    curve["displacement"] = float(specimen.size()[2]) * curve["platen_strain"]
    k = measure.peak(curve["force"])
    broken = curve["broken_tension"] + curve["broken_compression"] + curve["broken_shear"]
    # the plates' work: both plates move in, each by half the gap's decrease
    work = 0.5 * (curve["force"][1:] + curve["force"][:-1]) * np.diff(curve["displacement"])
    curve["applied_energy"] = np.r_[0.0, np.cumsum(work)]
    table = measure.fragment_table(sim.model.bond_pairs, sim.state.bond_active,
                                   sim.model.radius, sim.model.mass)
    result.fragments = table
    result.numbers.update({
        "breakage_energy": float(curve["applied_energy"][k]),
        "applied_energy": float(curve["applied_energy"][-1]),
        "fragment_size_d50": measure.size_at(table["size"], table["mass"], 0.5),
        "fragment_size_d10": measure.size_at(table["size"], table["mass"], 0.1),
        "loose_particles": int(np.count_nonzero(table["particles"] == 1)),
        "breakage_force": float(curve["force"][k]), "peak_stress": float(curve["force"][k]),
        "displacement_at_peak": float(curve["displacement"][k]),
        "strain_at_peak": float(curve["platen_strain"][k]),
        "broken_bonds_at_peak": int(broken[k]), "broken_bonds_final": int(broken[-1]),
        "diameter": float(specimen.size()[2]), "strain_rate": rate,
        "platen_force_mismatch": _mismatch(curve, "force")})
    return _honest(result)


@_rate_checked
def direct_tension(specimen, settings=None, *, out_dir=None, scene_text="", axis=2):
    """Direct tension: the particles within ``settings.grip`` of the height at each end
    (at least the end layer) are gripped and pulled apart, each end at half the strain
    rate times the height (after the ramp). Stress: the mean of both grips' forces over the
    cross-section; axial strain from the gauge bands (extension positive), lateral strain
    from the middle band (its contraction gives Poisson's ratio). Numbers: tensile_strength
    (the peak), E secant and tangent, poisson_ratio, crack initiation, broken bonds."""
    settings = _limits(settings or LabSettings(), "tension", specimen)
    z = specimen.position[:, axis]
    low, high = z.min(), z.max()
    h = high - low
    reach = max(settings.grip * h, 1e-9 * h)
    bottom = np.flatnonzero(z <= low + reach)
    top = np.flatnonzero(z >= high - reach)
    fixed = np.zeros(specimen.n_particles, bool)
    fixed[bottom] = fixed[top] = True
    height = float(specimen.size()[axis])
    wave = _estimate_wave_time(specimen, axis)
    rate = default_rate(specimen, settings, wave)
    speed = 0.5 * rate * height
    sim = _simulation(specimen, settings, fixed=fixed)
    ramp = settings.ramp * wave
    probe = _Probe(sim, axis, settings, exclude=fixed)
    grip0 = float(sim.state.position[top, axis].mean() - sim.state.position[bottom, axis].mean())
    area = specimen.cross_section(axis)
    steps_to_limit = settings.max_strain / rate / sim.time_step
    runner = _Runner(sim, settings, steps_to_limit, out_dir, scene_text)
    runner.probe, runner.wave_speed = probe, height / wave
    top_stress, stop = 0.0, None
    from ..io.results import _host
    while stop is None and sim.state.step < settings.max_steps:
        t = sim.state.time
        v = speed * (min(1.0, t / ramp) if ramp > 0.0 else 1.0)
        sim.state.velocity[top, axis] = v
        sim.state.velocity[bottom, axis] = -v
        if settings.backend != "cpu":
            sim.backend.to_device(sim.state)
        runner.step()
        load = _host(sim.force)
        f_top = -float(load[top, axis].sum())
        f_bottom = float(load[bottom, axis].sum())
        grip = float(sim.state.position[top, axis].mean()
                     - sim.state.position[bottom, axis].mean())
        row = {"time": sim.state.time, "force_bottom": f_bottom, "force_top": f_top,
               "platen_strain": (grip - grip0) / grip0, "axial_strain": probe.gauge_strain(),
               "lateral_strain": -probe.lateral()}
        row["tensile_stress"] = 0.5 * (f_top + f_bottom) / area
        tension, compression, shear = probe.broken()
        row.update({"broken_tension": tension, "broken_compression": compression,
                    "broken_shear": shear, "kinetic_ratio": probe.energy_ratio()})
        runner.sample(row)
        top_stress = max(top_stress, row["tensile_stress"])
        stop = _stop(row["tensile_stress"], tension + compression + shear,
                     sim.model.n_bonds, row["platen_strain"], settings, top_stress)
    result = _finish("tension", specimen, settings, sim, runner, {}, stop or "max_steps",
                     [f"gripped {bottom.size} + {top.size} particles"])
    result.numbers.update(_common_numbers(result.curve, "axial_strain", "tensile_stress",
                                          "lateral_strain"))
    result.numbers.update({"tensile_strength": result.numbers["peak_stress"],
                           "strain_rate": rate, "cross_section": area, "height": height,
                           "platen_force_mismatch": _mismatch(result.curve,
                                                              "tensile_stress")})
    return _honest(result)


RUNNERS = {"ucs": uniaxial, "triaxial": triaxial, "brazilian": brazilian,
           "tension": direct_tension, "agglomerate": agglomerate}

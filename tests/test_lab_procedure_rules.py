"""The lab procedures' rules on constructed inputs and on tiny lattices (a few hundred
steps each): settings at their bounds with their messages, the stop rule, the honest
report of a test that did not fail, the platens' and jaws' geometry, the servos' tuning,
the rate check, the wave time of a lattice in closed form (Voigt: E = sum k L^2 / (5 V)),
and a simple cubic lattice's closed forms in each test (E = k_n / a, Poisson's ratio 0,
sigma_t = sigma_b A_b / a^2). tests/test_lab.py runs the same tests on bigger specimens."""
import dataclasses
import math
import time
import types
import warnings

import h5py
import numpy as np
import pytest

import bondem
from bondem.lab import procedures as pr
from bondem.lab import lattice_specimen
from bondem.lab.membrane import membrane_forces
from bondem.lab.procedures import LabResult, LabSettings
from bondem.walls import PlaneWall

R = 1e-3
GLASS = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, friction=0.3)
BINDER = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=1e6,
                             tangential_strength=1e6)
A_BOND = math.pi * (0.5 * R) ** 2            # bond diameter half the particle diameter
MODULUS = 1e8 * A_BOND / (2 * R) ** 2        # the chains' E = k_n / a over a^2 per chain
STRENGTH = 1e6 * A_BOND / (2 * R) ** 2


@pytest.fixture(scope="module")
def lattice():
    return lattice_specimen((3, 3, 5), R, GLASS, BINDER, diameter_ratio=0.5)


# a bound on the steps well above the few thousand each test takes: a run whose stop rule
# is broken ends in seconds
QUIET = dict(samples=60, rate_check="off", max_steps=20_000)


@pytest.mark.parametrize("key, value, message", [
    ("post_peak", 0.0, "post_peak = 0.0; allowed range (0, 1)"),
    ("post_peak", 1.0, "post_peak = 1.0; allowed range (0, 1)"),
    ("post_peak", "0.5", "post_peak = '0.5'; allowed range (0, 1)"),
    ("largest_fragment", 1.001, "largest_fragment = 1.001; allowed range (0, 1)"),
    ("ae_radius", 0.0, "ae_radius = 0.0; allowed range (0, inf)"),
    ("damping", 1.0, "damping = 1.0; allowed range (0, 1)"),
    ("damping", -0.1, "damping = -0.1; allowed range (0, 1)"),
    ("ramp", -1.0, "ramp = -1.0; allowed range (0, inf)"),
    ("ramp", -0.5, "ramp = -0.5; allowed range (0, inf)"),
    ("grip", 0.5, "grip = 0.5; allowed range (0, 0.5)"),
    ("safety_factor", 1.5, "safety_factor = 1.5; allowed range (0, 1)"),
    ("safety_factor", 0.0, "safety_factor = 0.0; allowed range (0, 1)"),
    ("jaws", 0.5, "jaws = 0.5; 0 (flat platens) or a radius > 0.5 disc diameters"),
    ("jaws", math.inf, "jaws = inf; 0 (flat platens) or a radius > 0.5 disc diameters"),
    ("jaws", "1", "jaws = '1'; 0 (flat platens) or a radius > 0.5 disc diameters"),
    ("flattened", 90.0, "flattened = 90.0; a loading angle in [0, 90) degrees"),
    ("flattened", -1.0, "flattened = -1.0; a loading angle in [0, 90) degrees"),
    ("rate_check", "always", "rate_check = 'always'; allowed: warn, repeat, off"),
    ("rate_rule", "auto", "rate_rule = 'auto'; allowed: bonds, wave"),
    ("stress_path", "constant_p", "stress_path = 'constant_p'; allowed: constant_sigma3, "
                                  "constant_mean"),
    ("unload_at", (0.01, 1.0), "unload_at = [0.01, 1.0]; platen strains in (0, 1)"),
    ("unload_at", (0.0,), "unload_at = [0.0]; platen strains in (0, 1)"),
    ("unload_to", 1.0, "unload_to = 1.0; allowed range [0, 1)"),
    ("unload_to", -0.1, "unload_to = -0.1; allowed range [0, 1)"),
    ("failure_bonds", 1.0, "failure_bonds = 1.0; allowed range [0, 1)"),
    ("failure_bonds", -0.01, "failure_bonds = -0.01; allowed range [0, 1)"),
    ("max_strain", 1.0, "max_strain = 1.0; allowed range (0, 1)"),
    ("max_strain", 0.0, "max_strain = 0.0; allowed range (0, 1)"),
    ("strain_rate", 0.0, "strain_rate = 0.0; must be > 0 (1/s)"),
    ("strain_rate", math.inf, "strain_rate = inf; must be > 0 (1/s)"),
    ("confining_stress", -1.0, "confining_stress = -1.0; must be > 0 Pa"),
    ("confining_stress", 0.0, "confining_stress = 0.0; must be > 0 Pa"),
    ("confining_stress", math.nan, "confining_stress = nan; must be > 0 Pa"),
    ("gauge", (0.3, 0.2), "gauge = (0.3, 0.2); expected 0 <= low < high <= 0.5"),
    ("gauge", (0.2, 0.2), "gauge = (0.2, 0.2); expected 0 <= low < high <= 0.5"),
    ("gauge", (-0.1, 0.2), "gauge = (-0.1, 0.2); expected 0 <= low < high <= 0.5"),
    ("gauge", (0.1, 0.6), "gauge = (0.1, 0.6); expected 0 <= low < high <= 0.5"),
    ("samples", 0, "samples = 0; must be >= 1"),
    ("frames", 0, "frames = 0; must be >= 1"),
    ("max_steps", 0, "max_steps = 0; must be >= 1"),
])
def test_settings_are_refused_beyond_their_bounds(key, value, message):
    with pytest.raises(ValueError) as error:
        LabSettings(**{key: value})
    assert str(error.value) == message


def test_settings_at_their_bounds_are_taken():
    s = LabSettings(largest_fragment=1.0, safety_factor=1.0, damping=0.0, ramp=0.0,
                    jaws=0.0, flattened=0.0, unload_to=0.0, failure_bonds=0.0,
                    gauge=(0.0, 0.5), samples=1, frames=1, max_steps=1, unload_at=(0.5,))
    assert (s.largest_fragment, s.safety_factor, s.jaws) == (1.0, 1.0, 0.0)
    assert LabSettings(jaws=0.51).jaws == 0.51 and LabSettings(flattened=89.9).flattened == 89.9
    d = LabSettings()
    assert (d.strain_rate, d.post_peak, d.failure_bonds, d.largest_fragment, d.ae_radius,
            d.jaws, d.flattened, d.rate_check, d.stress_path, d.unload_at, d.unload_to,
            d.max_strain, d.damping, d.confining_stress, d.platen_material, d.ramp, d.gauge,
            d.grip, d.samples, d.frames, d.max_steps, d.safety_factor, d.backend) == (
        None, 0.7, None, 0.9, 2.0, 1.5, 0.0, "warn", "constant_sigma3", (), 0.3, None, 0.7,
        None, None, 2.0, (0.1, 0.25), 0.1, 2000, 20, 5_000_000, 0.2, "cpu")


def test_each_test_has_its_strain_limit_and_failure_fraction(lattice):
    for test, strain in (("ucs", 0.05), ("triaxial", 0.05), ("tension", 0.05),
                         ("brazilian", 0.1), ("agglomerate", 0.2)):
        s = pr._limits(LabSettings(), test, lattice)
        assert s.max_strain == strain
        assert s.failure_bonds == (0.1 if test == "agglomerate" else 0.01)
    s = pr._limits(LabSettings(max_strain=0.3, failure_bonds=0.0), "ucs", lattice)
    assert (s.max_strain, s.failure_bonds) == (0.3, 0.0)


def settings(**kw):
    return LabSettings(**{"max_strain": 0.05, "failure_bonds": 0.01, "post_peak": 0.7,
                          "largest_fragment": 0.9, **kw})


def test_the_stop_rule():
    s = settings()
    # the strain limit, whatever else
    assert pr._stop(1.0, 0, 100, 0.05, s, 2.0) == "strain limit"
    assert pr._stop(1.0, 0, 100, 0.0499, s, 2.0) is None     # too few broken
    # past the peak with at least 1 % of the bonds broken, at most 0.7 of the peak
    assert pr._stop(1.4, 1, 100, 0.01, s, 2.0) == "post-peak"
    assert pr._stop(1.41, 1, 100, 0.01, s, 2.0) is None
    assert pr._stop(1.4, 1, 1000, 0.01, s, 2.0) is None      # 1 of 1000 is 0.1 %
    assert pr._stop(1.4, 10, 1000, 0.01, s, 2.0) == "post-peak"
    assert pr._stop(1.4, 9, 1000, 0.01, s, 2.0) is None
    assert pr._stop(-1.0, 5, 10, 0.01, s, 0.0) is None       # never loaded
    # a specimen without bonds: past a platen strain of 0.05 ... which is the strain limit
    loose = settings(max_strain=0.1)
    assert pr._stop(0.5, 0, 0, 0.05, loose, 1.0) == "post-peak"
    assert pr._stop(0.5, 0, 0, 0.0499, loose, 1.0) is None
    # an agglomerate: also its largest fragment at most 0.9 of the mass
    text = pr._stop(1.0, 20, 100, 0.01, s, 2.0, pieces=(3, 0.9))
    assert text == ("post-peak (breakage: 20 % of the bonds broken, 3 fragments of 2+ "
                    "particles, the largest 90 % of the mass)")
    assert pr._stop(1.0, 20, 100, 0.01, s, 2.0, pieces=(3, 0.91)) is None
    assert pr._stop(1.0, 0, 0, 0.06, loose, 2.0, pieces=(1, 1.0)) == "post-peak"


def test_a_lost_load_is_a_split_or_a_specimen_that_left_the_platens():
    """Past a peak of 1 MPa the load falls to 2 % of it (20 kPa) with at least a tenth of
    the failure fraction of the bonds broken (here 1 % of 29183 bonds: 29.183, so 30):
    the load is lost. Broken apart (largest piece below 0.9 of the mass) that is a
    failure; whole, the specimen left the platens ("load lost", no strength)."""
    s = settings()
    assert pr.load_lost(2.0e4, 224, 29183, 1.0e6, s)          # the disc that slid out
    assert pr.load_lost(1.9e4, 30, 29183, 1.0e6, s)
    assert not pr.load_lost(1.9e4, 29, 29183, 1.0e6, s)     # the first contacts' transients
    assert not pr.load_lost(2.01e4, 224, 29183, 1.0e6, s)
    assert not pr.load_lost(-1.0, 224, 29183, 0.0, s)       # never loaded
    assert pr.load_lost(0.0, 1, 10, 1.0, s)                 # at least one bond
    assert not pr.load_lost(0.0, 0, 10, 1.0, s)
    assert pr._stop(0.0, 224, 29183, 0.013, s, 1.0e6, largest_piece=lambda: 0.99) == "load lost"
    assert pr._stop(0.0, 224, 29183, 0.013, s, 1.0e6, largest_piece=lambda: 0.9) == "load lost"
    assert pr._stop(0.0, 224, 29183, 0.013, s, 1.0e6, largest_piece=lambda: 0.52) == (
        "post-peak (the load lost with 0.768 % of the bonds broken: the specimen broke "
        "apart, its largest piece 52 % of the mass)")
    # the strain limit first
    assert pr._stop(0.0, 224, 29183, 0.05, s, 1.0e6, largest_piece=lambda: 0.99) == "strain limit"


def curve(stress, strain=None, **columns):
    n = len(stress)
    out = {"axial_stress": np.asarray(stress, float),
           "axial_strain": np.asarray(strain if strain is not None else
                                      np.arange(1, n + 1) * 1e-3, float),
           "broken_tension": np.zeros(n), "broken_compression": np.zeros(n),
           "broken_shear": np.zeros(n), "kinetic_ratio": np.full(n, 1e-3)}
    out.update({k: np.asarray(v, float) for k, v in columns.items()})
    return out


def test_the_common_numbers_of_a_curve():
    stress = [5e4, 2e5, 3e5, 4e5, 3e5]
    c = curve(stress, broken_tension=[0, 0, 1, 2, 5], broken_shear=[0, 0, 0, 1, 1],
              broken_compression=[0, 0, 0, 1, 2],
              kinetic_ratio=[0.5, 0.002, 0.003, 0.001, 0.9])
    n = pr._common_numbers(c, "axial_strain", "axial_stress")
    assert (n["peak_stress"], n["strain_at_peak"]) == (4e5, 4e-3)
    assert n["young_modulus_secant"] == pytest.approx(1e8, rel=1e-12)
    # bonds broken in every mode count
    assert (n["broken_bonds_at_peak"], n["broken_bonds_final"]) == (4, 8)
    assert n["crack_initiation_stress"] == 3e5          # where the first bond broke
    # before the peak, where the stress is at least 0.2 of it (the start's transients not)
    assert n["kinetic_energy_ratio"] == 0.003
    c["axial_stress"][0] = 8e4                           # 0.2 of the peak: counted
    assert pr._common_numbers(c, "axial_strain", "axial_stress")[
        "kinetic_energy_ratio"] == 0.5
    c["axial_stress"][0] = 5e4
    assert "crack_damage_stress" not in n
    c["kinetic_ratio"][:] = np.nan
    assert math.isnan(pr._common_numbers(c, "axial_strain", "axial_stress")[
        "kinetic_energy_ratio"])
    c = curve([1e5, 2e5, 3e5, 4e5, 3e5], volumetric_strain=[1e-3, 2e-3, 2.5e-3, 2e-3, 1e-3],
              lateral_strain=[2e-4, 4e-4, 6e-4, 8e-4, 9e-4])    # expansion positive
    n = pr._common_numbers(c, "axial_strain", "axial_stress", "lateral_strain")
    assert n["poisson_ratio"] == pytest.approx(0.2, rel=1e-9)
    assert n["crack_damage_stress"] == 3e5


def result(test="ucs", stress=(1.0, 3.0, 2.0), broken=2, n_bonds=100, no_failure="why",
           failure_bonds=0.01, **numbers):
    key = pr.STRESS[test]
    return LabResult(test, {key: np.asarray(stress, float)},
                     {"peak_stress": 3.0, "ucs": 3.0, "strain_at_peak": 0.1,
                      "n_bonds": n_bonds, "broken_bonds_final": broken, "steps": 9,
                      **numbers},
                     {}, {"failure_bonds": failure_bonds}, ["stopped: strain limit"],
                     no_failure=no_failure)


def test_a_test_that_did_not_fail_has_no_strength():
    r = pr._honest(result())
    assert r.no_failure is None        # fell to 2/3 <= 0.9 of the peak with 2 bonds broken
    assert r.numbers["ucs"] == 3.0 and r.numbers["largest_stress"] == 3.0
    assert r.notes[-1] == ("failed: past the peak the stress fell to 0.667 of it (a residual "
                           "strength) with 2 bonds broken")
    for kept in (result(stress=(1.0, 3.0, 2.71)), result(broken=0),
                 result(broken=1, n_bonds=200), result(stress=(-1.0, -2.0)),
                 result(n_bonds=0)):
        r = pr._honest(kept)
        assert r.no_failure == "why" and math.isnan(r.numbers["ucs"])
        assert math.isnan(r.numbers["peak_stress"]) and math.isnan(r.numbers["strain_at_peak"])
        assert r.numbers["largest_stress"] == 3.0 and r.notes[-1] == "no strength: why"
        assert r.numbers["steps"] == 9
    r = pr._honest(result(stress=(1.0, 3.0, 2.7)))
    assert r.no_failure is None                      # 0.9 of the peak itself
    r = pr._honest(result(broken=2, n_bonds=200, failure_bonds=0.01))
    assert r.no_failure is None
    # at least one bond broken, however few failure_bonds asks for; stresses below 1 Pa
    r = pr._honest(result(stress=(0.1, 0.3, 0.2), broken=1, n_bonds=10))
    assert r.no_failure is None and r.numbers["ucs"] == 3.0
    # a specimen that never carried a load did not fail, whatever broke
    r = pr._honest(result(stress=(0.0, 0.0, 0.0), broken=5))
    assert r.no_failure == "why" and math.isnan(r.numbers["ucs"])
    failed = pr._honest(result(no_failure=None))
    assert failed.numbers["ucs"] == 3.0 and failed.notes == ["stopped: strain limit"]
    assert failed.units["ucs"] == "Pa" and failed.units["axial_stress"] == "Pa"
    chip = pr._honest(result("agglomerate", no_failure=None))
    assert chip.units["peak_stress"] == "N" and chip.units["largest_stress"] == "N"
    # a test that stopped before any sample: no curve, no peak, and why
    empty = pr._honest(LabResult("ucs", {}, {}, {}, {}, [], no_failure="x"))
    assert math.isnan(empty.numbers["largest_stress"]) and empty.no_failure == "x"
    assert empty.notes == ["no strength: x"]


def unit_of(name):
    """A quantity's SI unit from what it is (its name), not from the table."""
    if name in ("strain_rate",):
        return "1/s"
    if name in ("time", "time_step", "wall_time"):
        return "s"
    if name == "cross_section":
        return "m^2"
    if name.endswith(("_ratio", "_mismatch", "_error", "_final", "_fraction")) or name in (
            "mismatch", "loading", "b_value", "steps", "cracks", "ae_events",
            "fragments", "fragments_multi", "loose_particles", "n_particles", "n_bonds",
            "largest_fragment_fraction", "kinetic_ratio") or name.startswith("broken_") \
            or "strain" in name:
        return "1"
    if "energy" in name:
        return "J"
    if "force" in name:
        return "N"
    if "stress" in name or "strength" in name or "modulus" in name or name == "ucs":
        return "Pa"
    if name in ("displacement", "gap", "diameter", "thickness", "height",
                "displacement_at_peak") or name.startswith("fragment_size"):
        return "m"
    raise AssertionError(name)


def test_every_unit_is_the_quantitys():
    assert {k: pr.UNITS[k] for k in pr.UNITS} == {k: unit_of(k) for k in pr.UNITS}


def test_the_settings_as_a_table():
    s = LabSettings(gauge=(0.05, 0.2), platen_material=GLASS, unload_at=(0.01,))
    table = pr._settings_dict(s)
    assert table["gauge"] == [0.05, 0.2] and table["unload_at"] == [0.01]
    assert table["platen_material"] == GLASS.__dict__ and table["samples"] == 2000
    assert list(table) == [f.name for f in dataclasses.fields(LabSettings)]


def test_a_coarse_specimen_is_named(lattice):
    assert pr.resolution_note(lattice) is None
    coarse = dataclasses.replace(lattice, lattice=False)
    text = pr.resolution_note(coarse)
    assert text == ("only 3 particle diameters across the specimen's smallest dimension "
                    "(0.006 m; at least 10 advised): its numbers depend on the packing's "
                    "details")
    with pytest.warns(UserWarning, match="only 3 particle diameters"):
        pr._limits(LabSettings(), "ucs", coarse)
    with pytest.warns(UserWarning, match="only 3 particle diameters"):
        r = pr.uniaxial(coarse, LabSettings(max_strain=0.001, **QUIET))
    assert f"warning: {text}" in r.notes      # the result keeps the warning
    wide = lattice_specimen((11, 11, 11), R, GLASS, BINDER, diameter_ratio=0.5)
    assert pr.resolution_note(dataclasses.replace(wide, lattice=False)) is None
    narrow = lattice_specimen((9, 10, 10), R, GLASS, BINDER, diameter_ratio=0.5)
    assert pr.resolution_note(dataclasses.replace(narrow, lattice=False)).startswith(
        "only 9 particle")


def test_a_lattices_wave_time_in_closed_form(lattice):
    # 3 x 3 x 5 spheres, spacing a = 2 R: 96 bonds of stiffness E_b A_b / a
    a = 2 * R
    bonds = 3 * 3 * 4 + 2 * (3 * 2 * 5)
    volume = (3 * a) * (3 * a) * (5 * a)
    modulus = bonds * (1e8 * A_BOND / a) * a * a / (5 * volume)
    density = 45 * 2500 * 4 / 3 * math.pi * R ** 3 / volume
    for axis, length in ((2, 5 * a), (0, 3 * a)):
        assert pr._estimate_wave_time(lattice, axis) == pytest.approx(
            length / math.sqrt(modulus / density), rel=1e-12)
    # without bonds: each touching pair a Hertz spring at an overlap of 1 % of R*
    sticky = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                             surface_energy=0.1)
    loose = dataclasses.replace(lattice, bonds=np.zeros((0, 2), np.int64),
                                bond_diameter=np.zeros(0),
                                bond_material_index=np.zeros(0, np.int64),
                                materials=[sticky], contact_model="jkr")
    e_star = 1e8 / (2 * (1 - 0.09))
    k = 2 * e_star * math.sqrt(0.01) * (R / 2)
    modulus = bonds * k * a * a / (5 * volume)
    assert pr._estimate_wave_time(loose, 2) == pytest.approx(
        5 * a / math.sqrt(modulus / density), rel=1e-12)
    # radii 0.8 R and 1.2 R in a chequerboard: every touching pair has R* = 0.48 R
    index = np.rint((lattice.position - lattice.position.min(axis=0)) / a).astype(int)
    small = index.sum(axis=1) % 2 == 1
    mixed = dataclasses.replace(loose, radius=np.where(small, 0.8 * R, 1.2 * R))
    volume = float(np.prod(mixed.size()))
    k = 2 * e_star * math.sqrt(0.01) * 0.48 * R
    mass = 2500 * 4 / 3 * math.pi * R ** 3 * (small.sum() * 0.8 ** 3 + (~small).sum() * 1.2 ** 3)
    assert pr._estimate_wave_time(mixed, 2) == pytest.approx(
        mixed.size()[2] / math.sqrt(bonds * k * a * a / (5 * volume) / (mass / volume)),
        rel=1e-12)


def test_platens_touch_the_ends_and_ramp_to_their_speed(lattice):
    walls = pr._platens(lattice, LabSettings(ramp=2.0), 2, 0.01, 1e-4, GLASS)
    low, high = lattice.bounds()
    bottom, top = walls
    np.testing.assert_array_equal(bottom.point, low)
    np.testing.assert_array_equal(top.point, high)
    assert bottom.normal.tolist() == [0, 0, 1] and top.normal.tolist() == [0, 0, -1]
    assert bottom.velocity_at(0.0).tolist() == [0, 0, 0]
    assert bottom.velocity_at(1e-4).tolist() == [0, 0, 0.005]
    assert top.velocity_at(2e-4).tolist() == [0, 0, -0.01]
    assert top.velocity_at(5e-4).tolist() == [0, 0, -0.01]
    walls = pr._platens(lattice, LabSettings(ramp=0.0), 0, 0.01, 1e-4, GLASS)
    assert walls[0].normal.tolist() == [1, 0, 0]
    assert walls[1].velocity_at(0.0).tolist() == [-0.01, 0, 0]
    assert walls[0].material is GLASS
    frictionless = pr._platen_material(lattice, LabSettings())
    assert (frictionless.friction, frictionless.rolling_friction) == (0.0, 0.0)
    assert frictionless.young_modulus == GLASS.young_modulus
    assert pr._platen_material(lattice, LabSettings(platen_material=GLASS)) is GLASS


def test_jaws_are_arcs_of_their_radius_touching_the_disc(lattice):
    # a disc away from the origin: its centre is no special point
    lattice = dataclasses.replace(lattice, position=lattice.position + [0.003, -0.002, 0.001])
    low, high = lattice.bounds()
    diameter = high[2] - low[2]
    walls = pr._jaws(lattice, LabSettings(jaws=1.5, ramp=1.0), 0.01, 1e-4, GLASS)
    assert len(walls) == 2
    # the lattice's flat ends: each jaw touches the outer rows' particles, 2 mm off the
    # middle, whose surfaces' lowest points lie 15 - sqrt(14^2 - 2^2) - 1 mm = 0.144 mm
    # above the arc's apex (the arc's axis 14 mm from their centres)
    drop = 1.5 * diameter - math.sqrt((1.5 * diameter - R) ** 2 - (2 * R) ** 2) - R
    assert drop == pytest.approx(1.44e-4, rel=1e-2)
    for wall, apex, sign in ((walls[0], low[2] - drop, -1.0), (walls[1], high[2] + drop, 1.0)):
        v = wall.vertices
        assert v.shape == (2 * (pr.JAW_SEGMENTS + 1), 3)
        assert wall.triangles.shape == (2 * pr.JAW_SEGMENTS, 3)
        x = v[:, 0] - 0.5 * (low[0] + high[0])
        # a circle of radius 1.5 D through the apex, curving around the disc (concave)
        np.testing.assert_allclose((v[:, 2] - apex + sign * 1.5 * diameter) ** 2 + x ** 2,
                                   (1.5 * diameter) ** 2, rtol=1e-12)
        assert np.all(-sign * (v[:, 2] - apex) >= -1e-15)
        assert np.isclose(np.abs(x).max(), 0.5 * diameter, rtol=1e-12)
        margin = 0.25 * (high[1] - low[1]) + 2 * R
        assert sorted(set(np.round(v[:, 1], 12))) == [round(low[1] - margin, 12),
                                                      round(high[1] + margin, 12)]
        assert wall.rotation_center.tolist() == pytest.approx(
            [0.5 * (low[0] + high[0]), 0.5 * (low[1] + high[1]), apex], rel=1e-12)
        assert wall.velocity_at(1e-3).tolist() == [0, 0, -sign * 0.01]
        assert wall.velocity_at(0.5e-4).tolist() == [0, 0, -sign * 0.005]
    walls = pr._jaws(lattice, LabSettings(jaws=1.5, ramp=0.0), 0.01, 1e-4, GLASS)
    assert walls[0].velocity_at(0.0).tolist() == [0, 0, 0.01]



@pytest.mark.parametrize("loader", ["platens", "jaws"])
def test_a_sphere_slides_on_the_platens_and_jaws_without_friction(lattice, loader):
    """The lab's platens and jaws are frictionless whatever the particles' friction: a
    GLASS sphere (friction 0.3) sliding along y on the bottom platen, or along the bottom
    jaw's apex line, under gravity keeps its speed and does not spin. With the pair
    friction the mean of the two (0.15) it would lose 0.15 g t = 0.015 m/s in 0.01 s."""
    v0, g = 0.05, 9.81
    material = pr._platen_material(lattice, LabSettings())
    if loader == "platens":
        wall = pr._platens(lattice, LabSettings(ramp=0.0), 2, 0.0, 1e-4, material)[0]
    else:
        wall = pr._jaws(lattice, LabSettings(jaws=1.5, ramp=0.0), 0.0, 1e-4, material)[0]
    low, high = lattice.bounds()
    mass = 2500.0 * 4 / 3 * math.pi * R ** 3
    e_star = 1 / (2 * (1 - 0.09) / 1e8)
    resting = (3 * mass * g / (4 * e_star * math.sqrt(R))) ** (2 / 3)
    centre = 0.5 * (low + high)
    if loader == "jaws":
        # the concave jaw's apex is a vertex between two facets of slope s = (D / 96) /
        # (2 R_jaw) that carry half the weight each; the jaw sits 0.144 mm below the
        # lattice's flat end (it touches the outer rows)
        s = (10e-3 / pr.JAW_SEGMENTS) / (2 * 15e-3)
        drop = 15e-3 - math.sqrt(14e-3 ** 2 - 2e-3 ** 2) - R
        expected = low[2] - drop + R * math.sqrt(1 + s * s) - resting * 0.5 ** (2 / 3)
    else:
        expected = low[2] + R - resting
    model, state = bondem.make_system([[centre[0], low[1] + 2 * R, expected]], R,
                                      GLASS, velocity=[[0, v0, 0]], gravity=(0, 0, -g))
    sim = bondem.Simulation(model, state, walls=[wall])
    sim.run(until=0.01)
    assert state.time == pytest.approx(0.01, rel=1e-3)
    assert state.velocity[0, 1] == pytest.approx(v0, rel=1e-12)
    assert np.abs(state.angular_velocity[0]).max() < 1e-9
    assert state.position[0, 2] == pytest.approx(expected, rel=0, abs=0.1 * resting)


def test_a_sphere_in_the_jaw_swings_as_a_pendulum_of_the_jaws_radius(lattice):
    """ISRM's jaws are concave: a frictionless sphere let go on the bottom jaw 2 mm off its
    apex slides back and forth through it as a pendulum of length L = R_jaw - R (15 - 1
    mm for the 10 mm disc), period T = 2 pi sqrt(L / g) (sliding, not rolling: no spin).
    On a convex jaw it would slide off."""
    g, offset = 9.81, 2e-3
    material = pr._platen_material(lattice, LabSettings())
    wall = pr._jaws(lattice, LabSettings(jaws=1.5, ramp=0.0), 0.0, 1e-4, material)[0]
    low, high = lattice.bounds()
    r_jaw = 1.5 * (high[2] - low[2])
    centre = 0.5 * (low + high)
    length = r_jaw - R
    # on the arc, at rest against it
    # the jaw touches the lattice's outer rows, below its flat end
    assert wall.rotation_center[2] < low[2]
    axis = np.array([centre[0], wall.rotation_center[2] + r_jaw])
    angle = math.asin(offset / length)
    start = [centre[0] + offset, centre[1], axis[1] - length * math.cos(angle)]
    model, state = bondem.make_system([start], R, GLASS, gravity=(0, 0, -g))
    sim = bondem.Simulation(model, state, walls=[wall])
    period = 2 * math.pi * math.sqrt(length / g)
    sim.run(until=0.25 * period)
    # through the apex at the pendulum's speed sqrt(2 g L (1 - cos angle))
    assert abs(state.position[0, 0] - centre[0]) < 0.03 * offset
    assert abs(state.velocity[0, 0]) == pytest.approx(
        math.sqrt(2 * g * length * (1 - math.cos(angle))), rel=0.03)
    sim.run(until=0.5 * period)
    assert state.position[0, 0] - centre[0] == pytest.approx(-offset, rel=0.03)
    assert np.abs(state.angular_velocity[0]).max() < 1e-9


def test_a_flattened_disc_loses_its_ends(lattice):
    # z spacing 2 mm, 5 layers: centres at -4, -2, 0, 2, 4 mm; D = 10 mm
    flat = pr.flatten_disc(lattice, 2 * math.degrees(math.acos(0.85)))
    # half = 5 mm x 0.85 = 4.25 mm: centres within 4.25 - 1 mm of the middle stay
    assert flat.n_particles == 27 and np.abs(flat.position[:, 2]).max() == pytest.approx(2e-3)
    assert flat.n_bonds == 3 * 3 * 2 + 2 * (3 * 2 * 3)
    assert flat.notes[-1] == f"flattened to a loading angle of " \
                             f"{2 * math.degrees(math.acos(0.85)):g} degrees (18 particles " \
                             f"cut off)"
    assert flat.bonds.max() == 26 and flat.bond_material_index.shape == (flat.n_bonds,)
    assert pr.flatten_disc(lattice, 0.0).n_particles == 45


def test_lateral_widths_are_the_gaps_between_wall_pairs():
    walls = [PlaneWall((-0.003, 0, 0), (1, 0, 0), GLASS, velocity=(0.001, 0, 0)),
             PlaneWall((0.004, 0, 0), (-1, 0, 0), GLASS),
             PlaneWall((0, 0.002, 0), (0, -1, 0), GLASS),
             PlaneWall((0, -0.0035, 0), (0, 1, 0), GLASS)]
    assert pr._lateral_widths(walls, 1.0, 2) == pytest.approx([0.006, 0.0055], rel=1e-12)


def test_a_walls_stiffness_is_the_sum_of_its_hertz_contacts(lattice):
    platen = bondem.Material(density=7800.0, young_modulus=2e9, poisson_ratio=0.25)
    e_star = 1 / ((1 - 0.09) / 1e8 + (1 - 0.0625) / 2e9)
    radius = np.array([1e-3, 2e-3, 1.5e-3])
    d = np.array([1e-6, 4e-6, 2e-6])              # the overlaps behind the forces
    force = 4 / 3 * e_star * np.sqrt(radius) * d ** 1.5
    rows = np.zeros((3, 3))
    rows[:, 2] = force
    sim = types.SimpleNamespace(
        state=types.SimpleNamespace(step=5, extra={"wall_pairs": np.array([[0, 0], [1, 2],
                                                                           [2, 1]]),
                                                   "wall_force_rows": rows}),
        model=types.SimpleNamespace(radius=radius), walls=[0, 1],
        contacts=types.SimpleNamespace(walls=types.SimpleNamespace(
            element_wall=np.array([0, 1, 1]))))
    stiffness = pr.wall_stiffness(sim, lattice, platen)
    k = 2 * e_star * np.sqrt(radius * d)
    assert stiffness(0) == pytest.approx(k[0], rel=1e-12)
    assert stiffness(1) == pytest.approx(k[1] + k[2], rel=1e-12)
    sim.state.extra["wall_force_rows"] = 4 * rows     # the same step: what was computed
    assert stiffness(1) == pytest.approx(k[1] + k[2], rel=1e-12)
    sim.state.step = 6
    assert stiffness(1) == pytest.approx((k[1] + k[2]) * 4 ** (1 / 3), rel=1e-12)
    sim.state.extra = {}
    sim.state.step = 7
    assert stiffness(0) == 0.0 and stiffness(1) == 0.0


def test_servo_walls_are_tuned_to_the_specimen(lattice):
    wall = pr._servo_plane((0.0, 0.0, -0.005), 2, 1.0, GLASS, 2e5)
    servo = wall.motion
    assert wall.normal.tolist() == [0.0, 0.0, 1.0] and servo.target_stress == 2e5
    assert (servo.tolerance, servo.fraction) == (0.005, pr.SERVO_GAIN)
    assert pr._servo_plane((0, 0, 0), 0, -1.0, GLASS, 1.0).normal.tolist() == [-1, 0, 0]
    sim = types.SimpleNamespace(time_step=1e-5, state=types.SimpleNamespace(step=0, extra={}),
                                walls=[0, 1], model=types.SimpleNamespace(radius=lattice.radius))
    walls = [pr._servo_plane((0, 0, 0), 2, 1.0, GLASS, 1.0) for _ in range(2)]
    areas = [lambda: 1.0, lambda: 2.0]
    pr._tune_servos(sim, lattice, GLASS, walls, areas, 0.05)
    for w, area in zip(walls, areas):
        assert w.motion.area is area and w.motion.integral_time == 30 * 1e-5
        assert w.motion.max_velocity == 0.2                      # 4 times the speed
        assert w.motion.stiffness() == 0.0
    pr._tune_servos(sim, lattice, GLASS, walls, areas, 1e-6)
    assert walls[0].motion.max_velocity == pytest.approx(1e-3 * R / 1e-5, rel=1e-12)


class Clock:
    """A simulation whose servos reach their targets at ``reached_at`` (s)."""

    def __init__(self, reached_at, dt=1e-6):
        self.time_step, self.reached_at = dt, reached_at
        self.state = types.SimpleNamespace(time=0.0)
        self.walls = [types.SimpleNamespace(motion=types.SimpleNamespace(reached=False))]

    def advance(self, steps):
        self.state.time += steps * self.time_step
        self.walls[0].motion.reached = self.state.time >= self.reached_at


def test_settling_lasts_twenty_wave_times_and_at_most_five_hundred():
    sim = Clock(reached_at=0.0)
    steps, reached = pr._settle(sim, sim.walls, sim.advance, 1e-4, 10, 10 ** 9)
    # blocks of half a wave time (50 steps) until past 20 wave times
    assert reached and steps == 2050 and sim.state.time == pytest.approx(2.05e-3)
    sim = Clock(reached_at=3e-3)
    steps, reached = pr._settle(sim, sim.walls, sim.advance, 1e-4, 10, 10 ** 9)
    assert reached and steps == 3000
    sim = Clock(reached_at=1.0)
    steps, reached = pr._settle(sim, sim.walls, sim.advance, 1e-4, 10, 10 ** 9)
    assert not reached and steps == 50000 and sim.state.time == pytest.approx(0.05)
    sim = Clock(reached_at=1.0)
    assert pr._settle(sim, sim.walls, sim.advance, 1e-4, 10, 120) == (150, False)
    sim = Clock(reached_at=1.0)                 # the bound reached exactly: no more blocks
    assert pr._settle(sim, sim.walls, sim.advance, 1e-4, 10, 100) == (100, False)
    sim = Clock(reached_at=0.0)
    steps, _ = pr._settle(sim, sim.walls, sim.advance, 1e-5, 40, 10 ** 9)
    assert steps % 40 == 0 and steps == 240                # blocks of at least 40 steps


def fake_run(numbers, calls):
    def run(specimen, settings=None, **options):
        calls.append((settings, options))
        n = dict(numbers[len(calls) - 1])
        return LabResult("ucs", {}, n, {}, {}, ["a", "stopped: post-peak"])
    return run


def test_the_rate_check():
    calls = []
    checked = pr._rate_checked(fake_run([{"kinetic_energy_ratio": 0.02, "ucs": 1.0,
                                          "strain_rate": 0.1}], calls))
    with pytest.warns(UserWarning) as caught:
        r = checked("specimen", out_dir="x")
    assert str(caught[0].message) == ("ucs: the kinetic energy reached 0.02 of the elastic "
                                      "energy before the peak (above 0.01): not "
                                      "quasi-static; lower test.strain_rate")
    assert r.notes == ["a", "warning: the kinetic energy reached 0.02 of the elastic energy "
                            "before the peak (above 0.01): not quasi-static",
                       "stopped: post-peak"]
    assert calls == [(None, {"out_dir": "x"})]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for ratio in (0.01, math.nan):
            calls = []
            r = pr._rate_checked(fake_run([{"kinetic_energy_ratio": ratio}], calls))("s")
            assert len(r.notes) == 2
        calls = []
        off = pr._rate_checked(fake_run([{"kinetic_energy_ratio": 0.5}], calls))
        assert len(off("s", LabSettings(rate_check="off")).notes) == 2
    calls = []
    repeat = pr._rate_checked(fake_run([
        {"ucs": 2.0, "young_modulus_secant": 1e9, "strain_rate": 0.1},
        {"ucs": 2.03, "young_modulus_secant": 1.004e9}], calls))
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # within 2 % and 0.5 %: nothing to say
        r = repeat("s", LabSettings(rate_check="repeat", samples=7))
    assert calls[1][0] == dataclasses.replace(LabSettings(rate_check="repeat", samples=7),
                                              strain_rate=0.05, rate_check="off")
    assert r.numbers["rate_change_strength"] == pytest.approx(0.015, rel=1e-9)
    assert r.numbers["rate_change_modulus"] == pytest.approx(0.004, rel=1e-9)
    assert r.units == {"rate_change_strength": "1", "rate_change_modulus": "1"}
    calls = []
    repeat = pr._rate_checked(fake_run([
        {"ucs": 2.0, "young_modulus_secant": 1e9, "strain_rate": 0.1},
        {"ucs": 1.9, "young_modulus_secant": 1.006e9}], calls))
    with pytest.warns(UserWarning) as caught:
        r = repeat("s", LabSettings(rate_check="repeat"))
    assert [str(w.message) for w in caught] == [
        "ucs: at half the strain rate its ucs moved by -5 % (more than 2 %); lower "
        "test.strain_rate",
        "ucs: at half the strain rate its young_modulus_secant moved by 0.6 % (more than "
        "0.5 %); lower test.strain_rate"]
    for first, second in (({"ucs": math.nan}, {"ucs": 1.0}), ({"ucs": 0.0}, {"ucs": 1.0}),
                          ({"ucs": 1.0}, {"ucs": math.nan}), ({}, {"ucs": 1.0})):
        calls = []
        r = pr._rate_checked(fake_run([{**first, "strain_rate": 1.0}, second], calls))(
            "s", LabSettings(rate_check="repeat"))
        assert "rate_change_strength" not in r.numbers and "rate_change_modulus" not in \
            r.numbers


# --- tiny lattices, a few hundred steps each ---------------------------------------

def test_direct_tension_of_a_lattice_breaks_at_the_bond_strength(lattice, tmp_path):
    r = pr.direct_tension(lattice, LabSettings(samples=600, rate_check="off", max_steps=20_000,
                                               rate_rule="wave"), out_dir=tmp_path)
    n = r.numbers
    assert n["tensile_strength"] == pytest.approx(STRENGTH, rel=0.03)
    assert n["young_modulus_secant"] == pytest.approx(MODULUS, rel=0.03)
    assert n["strain_at_peak"] == pytest.approx(1e6 / 1e8, rel=0.05)
    assert abs(n["poisson_ratio"]) < 0.01
    assert n["cross_section"] == pytest.approx(36e-6, rel=1e-12, abs=0) and n["height"] == 0.01
    assert r.no_failure is None and "stopped: post-peak" in r.notes
    assert "gripped 9 + 9 particles" in r.notes
    wave = pr._estimate_wave_time(lattice, 2)
    assert n["strain_rate"] == pytest.approx(pr.RATE / wave, rel=1e-12, abs=0)
    c = r.curve
    assert np.all(np.diff(c["time"]) > 0) and c["tensile_stress"][-1] <= 0.7 * c[
        "tensile_stress"].max()
    np.testing.assert_allclose(c["tensile_stress"], 0.5 * (c["force_top"] + c["force_bottom"])
                               / 36e-6, rtol=1e-12)
    # the grips stretch the specimen: strain of the grips and of the gauge both positive
    assert c["platen_strain"][-1] > 0 and c["axial_strain"][np.argmax(c["tensile_stress"])] > 0
    assert n["broken_bonds_final"] >= 9 and r.cracks["time"].size == n["cracks"]
    assert set(np.unique(r.cracks["mode"])) <= {1.0}
    assert n["platen_force_mismatch"] < 0.05
    with h5py.File(tmp_path / "results.h5") as f:
        assert f["lab/cracks/time"].shape == (n["cracks"],)
        assert f["lab/cracks/time"].attrs["unit"] == "s"
        assert f["lab/ae_events/magnitude"].attrs["unit"] == "1"
        assert f["time"].shape[0] >= 2 and f.attrs["scene_name"] == "lab"
        assert "walls/history" not in f          # gripped, not loaded by walls
    assert r.units["tensile_strength"] == "Pa" and r.settings["samples"] == 600
    # the final state: the lattice's bonds, those broken as the crack log has them
    assert r.bonds.tolist() == lattice.bonds.tolist()
    broken = np.flatnonzero(r.broken)
    assert broken.size == n["broken_bonds_final"] == n["cracks"]
    np.testing.assert_array_equal(r.break_mode != 0, r.broken)
    np.testing.assert_array_equal(r.radius, lattice.radius)
    assert r.position.shape == (45, 3)
    # pulled apart: every chain is the same, so all 4 x 9 axial bonds break at once and
    # the 5 layers of 9 particles come apart
    assert np.ptp(r.position[:, 2]) > np.ptp(lattice.position[:, 2])
    assert broken.size == 36 and n["fragments"] == 5 and n["fragments_multi"] == 5
    assert n["largest_fragment_fraction"] == pytest.approx(0.2, rel=1e-12)
    # each crack: its bond, at the middle of its particles, in tension at the strength
    cracks = r.cracks
    assert sorted(cracks["bond"].astype(int).tolist()) == broken.tolist()
    i, j = lattice.bonds[cracks["bond"].astype(int)].T
    middle = 0.5 * (r.position[i] + r.position[j])
    for k, name in enumerate("xyz"):
        # the particles hardly move after the break (the samples that follow)
        np.testing.assert_allclose(cracks[name], middle[:, k], atol=0.05 * R)
    assert np.all(np.diff(cracks["time"]) >= 0)
    np.testing.assert_allclose(cracks["bond_strain"], 1e6 / 1e8, rtol=0.05)
    np.testing.assert_allclose(cracks["normal_force"], 1e8 * A_BOND * cracks["bond_strain"],
                               rtol=1e-12)
    assert np.all(cracks["energy"] > 0) and np.all(cracks["tangential_force"] >= 0)
    assert np.all(cracks["twisting_moment"] >= 0) and np.all(cracks["bending_moment"] >= 0)
    # AE events: each counted at the first sample at or after its time
    ae_time = np.sort(r.ae["time"])
    assert c["ae_events"][-1] == n["ae_events"] == ae_time.size >= 1
    np.testing.assert_array_equal(c["ae_events"],
                                  [np.count_nonzero(ae_time <= t) for t in c["time"]])
    from bondem.lab import cracks as cracks_module
    b = cracks_module.b_value(r.ae["magnitude"])
    assert n["b_value"] == b or (math.isnan(n["b_value"]) and math.isnan(b))
    # no crack before the peak (the chains break together): no crack initiation stress
    stress = c["tensile_stress"]
    top = int(np.argmax(stress))
    assert c["broken_tension"][top] == 0 and math.isnan(n["crack_initiation_stress"])
    # the kinetic-energy ratio: its largest value up to the peak, once past 20 % of it
    live = stress[:top + 1] >= 0.2 * stress[top]
    assert n["kinetic_energy_ratio"] == np.nanmax(c["kinetic_ratio"][:top + 1][live])
    assert r.units["wall_time"] == "s" and n["wall_time"] > 0
    assert r.units["kinetic_energy_ratio"] == "1" and r.units["time"] == "s"
    assert set(r.units) == set(c) | set(n)
    assert set(r.contacts) == {"i", "j", "force"}
    assert r.contacts["force"].shape == (r.contacts["i"].size, 3)


def test_a_specimen_that_left_the_platens_whole_has_no_strength(lattice, monkeypatch):
    """Stopped as "load lost" (the stop rule forced at the first sample), the lattice,
    whole, has no UCS and the reason names the loss, the bonds and its largest piece."""
    monkeypatch.setattr(pr, "_stop", lambda *args, **kwargs: "load lost")
    r = pr.uniaxial(lattice, LabSettings(max_strain=0.004, failure_bonds=0.025, **QUIET))
    assert math.isnan(r.numbers["ucs"]) and r.no_failure == (
        "the specimen did not fail: its load fell to 2 % of the peak with 0 of 96 bonds "
        "broken and its largest piece 100 % of the mass: it left the platens whole (slid "
        "or rolled out from between them)")
    assert "stopped: load lost" in r.notes


def test_a_uniaxial_lattice_has_the_chains_modulus_and_keeps_its_width(lattice, tmp_path):
    out = tmp_path / "lab" / "uniaxial"          # folders that do not exist yet
    started = time.monotonic()
    r = pr.uniaxial(lattice, LabSettings(max_strain=0.004, failure_bonds=0.025, **QUIET),
                    out_dir=out, scene_text="# the spec's text")
    elapsed = time.monotonic() - started
    n = r.numbers
    assert 0.0 < n["wall_time"] <= elapsed
    assert n["young_modulus_secant"] == pytest.approx(MODULUS, rel=0.03)
    assert abs(n["poisson_ratio"]) < 0.01
    assert n["cross_section"] == pytest.approx(36e-6, rel=1e-12, abs=0) and n["height"] == 0.01
    assert math.isnan(n["ucs"]) and r.no_failure == (
        "the specimen did not fail: stopped at the strain limit with 0 of 96 bonds broken "
        "and no fall past a peak (to 0.7 of it, or to 0.9 of it at the end with 2.5 % of "
        "the bonds broken)")
    c = r.curve
    np.testing.assert_allclose(c["axial_stress"], 0.5 * (c["force_top"] + c["force_bottom"])
                               / 36e-6, rtol=1e-12)
    np.testing.assert_allclose(c["volumetric_strain"],
                               c["axial_strain"] - 2 * c["lateral_strain"], rtol=1e-12)
    gap0 = 0.01
    np.testing.assert_allclose(c["platen_strain"], (gap0 - c["gap"]) / gap0, rtol=1e-9,
                               atol=1e-15)
    assert c["platen_strain"][-1] >= 0.004 and c["axial_strain"][-1] > 0
    assert n["platen_force_mismatch"] < 0.05 and n["steps"] > 0
    assert n["time_step"] > 0 and n["n_particles"] == 45 and n["n_bonds"] == 96
    assert n["fragments"] == 1 and n["largest_fragment_fraction"] == pytest.approx(1.0)
    with h5py.File(out / "results.h5") as f:
        assert f.attrs["scene"] == "# the spec's text"
        assert f["walls/history/time"].shape[0] > 0
        assert f["walls/history/time"][-1] <= f["time"][-1]


def test_a_triaxial_box_holds_its_confinement(lattice):
    r = pr.triaxial(lattice, LabSettings(confining_stress=1e5, max_strain=0.004, **QUIET))
    n, c = r.numbers, r.curve
    assert n["confining_stress"] == 1e5 and n["confining_stress_error_final"] < 0.05
    assert np.allclose(c["confining_stress"], 1e5)
    np.testing.assert_allclose(c["deviator_stress"], c["axial_stress"] - 1e5, rtol=1e-12)
    np.testing.assert_allclose(c["mean_stress"], (c["axial_stress"] + 2 * c["lateral_stress"])
                               / 3, rtol=1e-12)
    assert any(note.startswith("confined to 1e+05 Pa in ") for note in r.notes)
    assert n["young_modulus_secant"] > 0
    assert np.all(c["loading"] == 1.0) and "unloading_modulus" not in n
    assert n["peak_stress"] == pytest.approx(n["largest_stress"], rel=1e-12) or math.isnan(
        n["peak_stress"])


def test_a_constant_mean_stress_path_lowers_sigma3_by_a_third_of_q(lattice):
    r = pr.triaxial(lattice, LabSettings(confining_stress=1e5, max_strain=0.004,
                                         stress_path="constant_mean", **QUIET))
    c = r.curve
    # each row's sigma_3 is set from the row before: p0 - q / 3
    expected = np.maximum(1e5 - c["deviator_stress"][:-1] / 3, 0.1)
    np.testing.assert_allclose(c["confining_stress"][1:], expected, rtol=1e-12)
    assert c["confining_stress"][-1] < 0.9e5


def test_an_unloading_cycle_turns_the_platens_back(lattice):
    r = pr.triaxial(lattice, LabSettings(confining_stress=1e5, max_strain=0.006,
                                         unload_at=(0.002,), unload_to=0.5, **QUIET))
    c, n = r.curve, r.numbers
    loading = c["loading"]
    assert loading[0] == 1.0 and (loading == -1.0).any() and loading[-1] == 1.0
    turn = np.flatnonzero(loading == -1.0)[0]
    assert c["platen_strain"][turn] >= 0.002 > c["platen_strain"][turn - 1]
    # unloaded to half the deviator stress of the turn before reloading
    q = c["deviator_stress"]
    # reloaded once the deviator stress fell to half that of the turn
    back = np.flatnonzero((loading[1:] == 1.0) & (loading[:-1] == -1.0))[0] + 1
    assert q[back] <= 0.5 * q[turn] < q[back - 1]
    assert n["unloading_modulus"] > 0


def test_a_triaxial_test_needs_a_box_or_a_cylinder_and_a_stress(lattice):
    with pytest.raises(ValueError) as error:
        pr.triaxial(lattice, LabSettings(**QUIET))
    assert str(error.value) == "a triaxial test needs confining_stress (Pa)"
    with pytest.raises(ValueError) as error:
        pr.triaxial(dataclasses.replace(lattice, shape="sphere"),
                    LabSettings(confining_stress=1e5, **QUIET))
    assert str(error.value) == ("a triaxial test needs a box specimen (plane lateral walls) or "
                                "a cylinder (a membrane)")
    with pytest.raises(ValueError) as error:
        pr.triaxial(dataclasses.replace(lattice, shape="cylinder"),
                    LabSettings(confining_stress=1e5, backend="gpu", **QUIET))
    assert str(error.value) == ("the membrane triaxial test runs on the CPU backend (the "
                                "membrane's forces are renewed on the host)")
    with pytest.raises(ValueError) as error:
        pr.brazilian(dataclasses.replace(lattice, shape="sphere"), LabSettings(**QUIET))
    assert str(error.value) == "a Brazilian test needs a disc specimen"


def test_a_brazilian_test_between_flat_platens(lattice):
    r = pr.brazilian(lattice, LabSettings(jaws=0.0, max_strain=0.01, **QUIET))
    c, n = r.curve, r.numbers
    assert (n["diameter"], n["thickness"]) == (0.01, 0.006)
    mean = 0.5 * (c["force_top"] + c["force_bottom"])
    np.testing.assert_allclose(c["force"], mean, rtol=1e-12)
    np.testing.assert_allclose(c["tensile_stress"], 2 * mean / (math.pi * 0.01 * 0.006),
                               rtol=1e-12)
    np.testing.assert_allclose(c["displacement"], 0.01 * c["platen_strain"], rtol=1e-12)
    k = int(np.argmax(c["tensile_stress"]))
    if r.no_failure is None:
        assert n["tensile_strength"] == c["tensile_stress"][k]
        assert n["breakage_force"] == mean[k]
    assert n["largest_stress"] == pytest.approx(c["tensile_stress"].max(), rel=1e-12)
    flat = pr.brazilian(lattice, LabSettings(flattened=2 * math.degrees(math.acos(0.85)),
                                             max_strain=0.01, **QUIET))
    c = flat.curve
    mean = 0.5 * (c["force_top"] + c["force_bottom"])
    np.testing.assert_allclose(c["tensile_stress"], 0.85 ** 3 * 2 * mean
                               / (math.pi * 0.01 * 0.006), rtol=1e-12)
    assert flat.numbers["n_particles"] == 27
    assert any(note.startswith("flattened to a loading angle") for note in flat.notes)


def test_jaws_press_a_lattice_disc(lattice):
    r = pr.brazilian(lattice, LabSettings(max_strain=0.004, **QUIET))
    assert r.curve["force"].max() > 0 and r.numbers["n_particles"] == 45


def test_an_agglomerate_between_plates(lattice):
    r = pr.agglomerate(lattice, LabSettings(max_strain=0.02, **QUIET))
    c, n = r.curve, r.numbers
    np.testing.assert_allclose(c["displacement"], 0.01 * c["platen_strain"], rtol=1e-12)
    work = np.r_[0.0, np.cumsum(0.5 * (c["force"][1:] + c["force"][:-1])
                                * np.diff(c["displacement"]))]
    np.testing.assert_allclose(c["applied_energy"], work, rtol=1e-12)
    assert n["applied_energy"] == c["applied_energy"][-1] and n["diameter"] == 0.01
    assert r.fragments["mass"].sum() == pytest.approx(45 * 2500 * 4 / 3 * math.pi * R ** 3,
                                                      rel=1e-12, abs=0)
    assert n["loose_particles"] == int(np.count_nonzero(r.fragments["particles"] == 1))
    assert "fragments_multi" in c and r.units["peak_stress"] == "N"
    assert n["fragments"] >= 1


def test_a_run_ends_at_its_step_bound(lattice):
    r = pr.uniaxial(lattice, LabSettings(samples=60, rate_check="off", max_steps=40))
    assert "stopped: max_steps" in r.notes and r.curve["time"].size == 1   # one sample
    assert r.no_failure.startswith("the specimen did not fail: stopped at the max_steps")
    r = pr.direct_tension(lattice, LabSettings(samples=60, rate_check="off", max_steps=40))
    assert "stopped: max_steps" in r.notes


def test_a_lattice_cylinder_in_its_membrane(lattice):
    """The membrane holds sigma_3 on the current lateral surface; the isotropic stage
    shortens the chains by sigma_3 / E, and loading them gives E = k_n / a."""
    cylinder = lattice_specimen((5, 5, 5), R, GLASS, BINDER, diameter_ratio=0.5,
                                shape="cylinder")
    r = pr.triaxial(cylinder, LabSettings(confining_stress=1e5, max_strain=0.004, **QUIET))
    c, n = r.curve, r.numbers
    np.testing.assert_allclose(c["lateral_stress"], 1e5, rtol=1e-9)
    assert n["confining_stress_error_final"] < 1e-9
    np.testing.assert_allclose(c["axial_stress"], 0.5 * (c["force_top"] + c["force_bottom"])
                               / c["cross_section"], rtol=1e-12)
    np.testing.assert_allclose(c["deviator_stress"], c["axial_stress"] - 1e5, rtol=1e-12)
    np.testing.assert_allclose(c["lateral_stress_worst"], np.abs(c["lateral_stress"] / 1e5
                                                                 - 1.0), atol=1e-15)
    # the platens' force against the gauge strain: the chains' E_b A_b / a each, N_c of
    # them (one per particle of a layer): E N_c a^2 (the membrane's cross-section, which
    # steps as the outermost particles change cells, does not enter)
    force, eps = 0.5 * (c["force_top"] + c["force_bottom"]), c["axial_strain"]
    live = force > force[0] + 0.2 * (force.max() - force[0])
    chains = cylinder.n_particles // 5
    assert np.polyfit(eps[live], force[live], 1)[0] == pytest.approx(
        MODULUS * chains * (2 * R) ** 2, rel=0.03)
    assert n["confinement_axial_strain"] == pytest.approx(-1e5 / MODULUS, rel=0.2)
    assert n["confinement_lateral_strain"] < 0
    note = next(t for t in r.notes if t.startswith("confined in a membrane to 1e+05 Pa in "))
    assert note.endswith(f"strains axial {-n['confinement_axial_strain']:.4g}, lateral "
                         f"{-n['confinement_lateral_strain']:.4g})")
    assert "not settled" not in note
    import re
    found = re.fullmatch(r"confined in a membrane to 1e\+05 Pa in (\d+) steps \(platens "
                         r"(\S+) % off; strains axial \S+, lateral \S+\)", note)
    assert found is not None and float(found.group(2)) < 0.5


def test_the_membrane_takes_every_step_and_renews_its_forces(lattice):
    """_Membrane.advance(n) takes n steps (one as well), the pressure's forces renewed
    every MEMBRANE_EVERY steps and after the last: those of the current positions, with no
    net force, every row pressed."""
    cylinder = lattice_specimen((5, 5, 5), R, GLASS, BINDER, diameter_ratio=0.5,
                                shape="cylinder")
    platens = pr._platens(cylinder, LabSettings(), 2, 0.0, 1e-4, GLASS)
    sim = pr._simulation(cylinder, LabSettings(), platens)
    membrane = pr._Membrane(sim, 2, 1e5, 2 * R, platens)
    for steps, total in ((1, 1), (pr.MEMBRANE_EVERY + 3, pr.MEMBRANE_EVERY + 4)):
        membrane.advance(steps)
        assert sim.state.step == total
    force = sim.model.external_force
    t = sim.state.time
    expected, surface, radius = membrane_forces(
        sim.state.position, sim.model.radius, 2, platens[0].position(t)[2],
        platens[1].position(t)[2], 1e5, 2 * R)
    assert np.array_equal(force, expected) and np.count_nonzero(force[:, 0]) > 0
    assert (membrane.surface, membrane.radius) == (surface, radius)
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-12 * np.abs(force).sum())
    assert membrane.gap == pytest.approx(0.01, rel=1e-12)
    assert membrane.lateral_stress() == pytest.approx(1e5, rel=1e-12)


def test_the_kinetic_energy_ratio_of_moving_particles_over_the_bonds_energy(lattice):
    """Kinetic energy (1/2 m v^2 + 1/2 I w^2, I = 2/5 m R^2) of the particles that are
    not held over the bonds' elastic energy: the lattice stretched by 1e-3 along z stores
    1/2 k (a 1e-3)^2 in each of its 4 x 9 axial bonds, k = E_b A_b / a."""
    sim = pr._simulation(lattice, LabSettings(), [])
    sim.state.position[:, 2] *= 1.001
    rng = np.random.default_rng(3)
    v, w = rng.normal(size=(45, 3)) * 1e-3, rng.normal(size=(45, 3))
    sim.state.velocity[:], sim.state.angular_velocity[:] = v, w
    held = np.arange(9)                      # the bottom layer, held
    probe = pr._Probe(sim, 2, LabSettings(), exclude=held)
    mass = 2500 * 4 / 3 * math.pi * R ** 3
    free = np.ones(45, bool)
    free[held] = False
    kinetic = 0.5 * mass * np.sum(v[free] ** 2) + 0.5 * 0.4 * mass * R ** 2 * np.sum(w[free] ** 2)
    k = 1e8 * A_BOND / (2 * R)
    elastic = 36 * 0.5 * k * (2 * R * 1e-3) ** 2
    assert probe.energy_ratio() == pytest.approx(kinetic / elastic, rel=1e-6)
    everyone = pr._Probe(sim, 2, LabSettings())
    kinetic_all = 0.5 * mass * np.sum(v ** 2) + 0.2 * mass * R ** 2 * np.sum(w ** 2)
    assert everyone.energy_ratio() == pytest.approx(kinetic_all / elastic, rel=1e-6)
    sim.state.position[:, 2] /= 1.001        # nothing stored: no ratio
    assert math.isnan(pr._Probe(sim, 2, LabSettings()).energy_ratio())


def test_a_triaxial_box_that_is_not_square(tmp_path):
    """A 3 x 4 x 5 lattice box: sigma_1 and each lateral wall's stress on their own current
    faces (x: 8 mm wide, y: 6 mm), the chains' modulus in the deviatoric stage (the
    frictionless walls carry no shear), the isotropic stage held at sigma_3."""
    box = lattice_specimen((3, 4, 5), R, GLASS, BINDER, diameter_ratio=0.5)
    r = pr.triaxial(box, LabSettings(confining_stress=1e5, max_strain=0.004, samples=200,
                                     rate_check="off", max_steps=20_000))
    c, n = r.curve, r.numbers
    # the first sample: sigma_1 = sigma_3 (isotropic), on the 6 x 8 mm face
    assert c["axial_stress"][0] == pytest.approx(1e5, rel=0.005)
    assert n["confining_stress_error_final"] < 0.01
    np.testing.assert_allclose(c["lateral_stress"], 1e5, rtol=0.01)
    assert n["young_modulus_secant"] == pytest.approx(MODULUS, rel=0.03)
    assert abs(n["poisson_ratio"]) < 0.02
    note = next(t for t in r.notes if t.startswith("confined to 1e+05 Pa in "))
    import re
    found = re.fullmatch(r"confined to 1e\+05 Pa in (\d+) steps \(worst wall (\S+) % off\)",
                         note)
    assert found is not None and float(found.group(2)) < 0.5   # held within 0.5 % (0.005)
    assert not note.endswith("; not settled)")
    cut = pr.triaxial(box, LabSettings(confining_stress=1e5, max_strain=0.004, samples=20,
                                       rate_check="off", max_steps=100))
    note = next(t for t in cut.notes if t.startswith("confined to 1e+05 Pa in "))
    assert note.endswith("; not settled)")
    # the step bound ran out while confining: an honest report without numbers
    assert cut.curve == {} and cut.no_failure.startswith(
        "the specimen did not fail: stopped at the max_steps with 0 of ")
    assert math.isnan(cut.numbers["largest_stress"]) and cut.numbers["steps"] >= 100


def test_curved_jaws_press_the_outer_rows_of_a_flat_ended_disc(lattice):
    """ISRM's concave jaws (radius 1.5 D) placed to touch a 3 x 3 lattice "disc" (flat
    ends) touch its two outer rows only (its middle row lies 0.144 mm above the arc's
    apex, beyond the test's 0.04 mm), flat platens all three: at the same small
    displacement the jaws push the six outer chains of nine: 2/3 of the platens' force if
    the chains were free (less 2.5 % for the contacts' 8 degree tilt), more as the bonds'
    shear drags the middle chains along (measured 0.74), below the platens' force;
    flattened discs go between flat platens."""
    settings = dict(max_strain=0.004, samples=40, rate_check="off", max_steps=20_000)
    jaws = pr.brazilian(lattice, LabSettings(**settings)).curve
    flat = pr.brazilian(lattice, LabSettings(jaws=0.0, **settings)).curve
    d = 0.5 * min(jaws["displacement"].max(), flat["displacement"].max())
    at_jaws = np.interp(d, jaws["displacement"], jaws["force"])
    at_flat = np.interp(d, flat["displacement"], flat["force"])
    assert 0.97 * 2.0 / 3.0 < at_jaws / at_flat < 0.85
    # the jaws' facets: a strip over the arc, its area the arc's polygon times its width
    walls = pr._jaws(lattice, LabSettings(), 0.01, 1e-4, GLASS)
    for wall in walls:
        v, t = wall.vertices, wall.triangles
        n = pr.JAW_SEGMENTS + 1
        arc = np.sum(np.hypot(np.diff(v[:n, 0]), np.diff(v[:n, 2])))
        width = v[n, 1] - v[0, 1]
        area = 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]),
                                    axis=1)
        assert area.sum() == pytest.approx(arc * width, rel=1e-12)
        assert sorted(set(t.ravel().tolist())) == list(range(2 * n))
        assert wall.own_friction


def test_samples_and_frames_are_spaced_by_the_steps_to_the_strain_limit(lattice, tmp_path):
    """``samples`` rows up to max_strain: with more samples than steps, one row a step;
    a frame every samples // frames rows, and the first and last states."""
    r = pr.uniaxial(lattice, LabSettings(samples=10 ** 7, max_steps=50, rate_check="off"))
    assert r.curve["time"].size == r.numbers["steps"] == 50
    for frames, every in ((60, 1), (20, 3), (7, 8)):
        out = tmp_path / str(frames)
        r = pr.uniaxial(lattice, LabSettings(samples=60, frames=frames, max_strain=0.004,
                                             rate_check="off", max_steps=20_000), out_dir=out)
        rows = r.curve["time"].size
        assert 60 <= rows <= 80        # a strain-limit run: about ``samples`` rows
        with h5py.File(out / "results.h5") as f:
            assert f["time"].shape[0] == 1 + rows // every + 1
            assert f["time"][0] == 0.0 and f["time"][-1] == r.curve["time"][-1]


def test_the_bonds_rate_rule_reaches_the_weakest_bonds_failure_strain_over_100_waves(lattice):
    """rate_rule "bonds": strain per wave-crossing time min(5e-4, eps_b / 100), eps_b the
    smallest min(sigma_n, sigma_t) / E_b among the bond materials the bonds use (the
    default); "wave" 5e-4; an explicit strain_rate wins."""
    wave = 3.7e-5                                       # s
    bonds = LabSettings(rate_rule="bonds")
    shear_weak = lattice.with_bond_material(young_modulus=2.0e9, normal_strength=5.0e6,
                                            tangential_strength=3.0e6)   # eps_b 1.5e-3
    assert pr.default_rate(shear_weak, bonds, wave) == pytest.approx(1.5e-5 / wave,
                                                                    rel=1e-12)
    tension_weak = lattice.with_bond_material(young_modulus=2.0e9, normal_strength=1.0e6,
                                              tangential_strength=4.0e6)   # eps_b 5e-4
    assert pr.default_rate(tension_weak, bonds, wave) == pytest.approx(5e-6 / wave,
                                                                      rel=1e-12)
    strong = lattice.with_bond_material(young_modulus=1e9, normal_strength=1e8,
                                        tangential_strength=1e8)   # eps_b / 100 = 1e-3
    assert pr.default_rate(strong, bonds, wave) == pytest.approx(5e-4 / wave, rel=1e-12)
    assert pr.default_rate(shear_weak, LabSettings(), wave) == pytest.approx(1.5e-5 / wave,
                                                                            rel=1e-12)
    assert pr.default_rate(shear_weak, LabSettings(rate_rule="wave"),
                           wave) == pytest.approx(5e-4 / wave, rel=1e-12)
    assert pr.default_rate(shear_weak, LabSettings(strain_rate=7.0, rate_rule="bonds"),
                           wave) == 7.0
    # two bond materials, the weak one unused: only the bonds' own materials count
    weak = dataclasses.replace(BINDER, young_modulus=1e9, normal_strength=1e5,
                               tangential_strength=1e5)
    used = dataclasses.replace(BINDER, young_modulus=1e9, normal_strength=2e7,
                               tangential_strength=3e7)   # eps_b / 100 = 2e-4
    mixed = dataclasses.replace(lattice, bond_materials=[weak, used],
                                bond_material_index=np.ones(lattice.n_bonds, np.int64))
    assert pr.default_rate(mixed, bonds, wave) == pytest.approx(2e-4 / wave, rel=1e-12)
    mixed.bond_material_index[3] = 0
    assert pr.default_rate(mixed, bonds, wave) == pytest.approx(1e-6 / wave, rel=1e-12)


def test_the_bonds_rate_rule_moves_the_platens_at_that_rate(lattice):
    """The lattice's platens move at half the rate times the height: over the first
    samples of a bonds-rule test, the platen strain grows at eps_b / 100 per
    wave-crossing time once the ramp is over."""
    weak = lattice.with_bond_material(tangential_strength=0.4e6)   # eps_b 4e-3 (E_b 1e8)
    settings = LabSettings(rate_rule="bonds", max_strain=0.002, **QUIET)
    result = pr.uniaxial(weak, settings)
    wave = pr._estimate_wave_time(weak, 2)
    assert result.numbers["strain_rate"] == pytest.approx(4e-5 / wave, rel=1e-12)
    t, strain = result.curve["time"], result.curve["platen_strain"]
    late = t > 3.0 * wave   # past the ramp of 2 wave-crossing times
    slope = np.polyfit(t[late], strain[late], 1)[0]
    assert slope == pytest.approx(4e-5 / wave, rel=0.02)

"""The lab's crack log and acoustic emission against definitions and closed forms.

A bond of stiffness k_n = E_b A_b / L0 that breaks in tension at sigma_b held the elastic
energy (sigma_b A_b)^2 / (2 k_n) = sigma_b^2 A_b L0 / (2 E_b); alone, it is one AE event
whose energy magnitude is (log10 E - 4.8) / 1.5 (Kanamori 1977). Aki's b-value of a
Gutenberg-Richter sample (magnitudes above M_min exponential with rate b ln 10) returns
its b. Cracks far apart in space or in time are separate events.
"""
import dataclasses
import json
import math
import warnings

import h5py
import numpy as np
import pytest

import bondem
from bondem.lab import LabSettings, direct_tension, lattice_specimen, uniaxial
from bondem.lab import cracks

RADIUS = 1e-3
E_BOND = 1e8
STRENGTH = 1e6
RATIO = 0.5
GLASS = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, friction=0.3)
BINDER = bondem.BondMaterial(young_modulus=E_BOND, poisson_ratio=0.3,
                             normal_strength=STRENGTH, tangential_strength=STRENGTH)


def test_magnitude_is_kanamoris_energy_magnitude():
    # log10 E = 1.5 M + 4.8: 10^4.8 J is magnitude 0, every factor 10^1.5 one unit more
    assert cracks.magnitude(10.0 ** 4.8) == pytest.approx(0.0, abs=1e-12)
    assert cracks.magnitude(10.0 ** 6.3) == pytest.approx(1.0, rel=1e-12)
    assert cracks.magnitude(1e-6) == pytest.approx((-6.0 - 4.8) / 1.5, rel=1e-12)


def test_b_value_of_a_gutenberg_richter_sample():
    rng = np.random.default_rng(5)
    for b in (0.7, 1.6):
        m = -4.0 + rng.exponential(1.0 / (b * math.log(10.0)), size=40_000)
        # the estimator's standard error is b / sqrt(n): 0.5 % here
        assert cracks.b_value(m) == pytest.approx(b, rel=0.02)
        assert cracks.b_value(m, minimum=-3.5) == pytest.approx(b, rel=0.03)
    assert math.isnan(cracks.b_value(np.linspace(-3.0, -2.0, 9)))   # too few events


def test_cracks_group_by_distance_and_time():
    # a chain of three cracks 0.8 mm apart (each within 1 mm of the last) within the
    # window, one crack 5 mm away at the same time, and one at the chain's start point
    # after the window has closed: three events
    time = np.array([0.0, 1e-6, 2e-6, 1e-6, 9e-6])
    position = np.array([[0, 0, 0], [0.8e-3, 0, 0], [1.6e-3, 0, 0], [5e-3, 0, 0],
                         [0, 0, 0]], float)
    label = cracks.group_events(time, position, radius=1e-3, window=3e-6)
    assert label.tolist() == [0, 0, 0, 1, 2]
    energy = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    ae = cracks.events(time, position, energy, label)
    assert ae["cracks"].tolist() == [3, 1, 1]
    np.testing.assert_allclose(ae["energy"], [6.0, 4.0, 5.0])
    np.testing.assert_allclose(ae["x"], [0.8e-3, 5e-3, 0.0])
    np.testing.assert_allclose(ae["time"], [0.0, 1e-6, 9e-6])
    # a longer window joins the last crack to the chain's event
    assert cracks.group_events(time, position, 1e-3, 1e-5).tolist() == [0, 0, 0, 1, 0]


def test_crack_damage_is_where_the_volume_turns_to_dilatancy():
    strain = np.linspace(0.0, 1.0, 101)
    stress = 10.0 * strain - 5.0 * strain ** 2                   # peak at strain 1
    volumetric = strain * (0.62 - strain)                         # largest at 0.31
    assert cracks.crack_damage(stress, volumetric) == pytest.approx(
        10.0 * 0.31 - 5.0 * 0.31 ** 2, rel=1e-12)
    assert math.isnan(cracks.crack_damage(stress, strain))       # compacting to the peak


def test_one_bond_in_tension_is_one_event_with_its_energys_magnitude(tmp_path):
    specimen = lattice_specimen((1, 1, 2), RADIUS, GLASS, BINDER, diameter_ratio=RATIO)
    result = direct_tension(specimen, out_dir=tmp_path)
    area = math.pi * (RATIO * RADIUS) ** 2
    length = 2.0 * RADIUS
    stored = STRENGTH ** 2 * area * length / (2.0 * E_BOND)
    log, ae = result.cracks, result.ae
    assert log["time"].size == 1 == result.numbers["broken_bonds_final"]
    assert int(log["mode"][0]) == 1                                # tension
    # the step before the break: the bond at (just below) its strength
    assert log["bond_strain"][0] == pytest.approx(STRENGTH / E_BOND, rel=0.01)
    assert log["normal_force"][0] == pytest.approx(STRENGTH * area, rel=0.01)
    assert log["energy"][0] == pytest.approx(stored, rel=0.02)
    assert ae["cracks"].tolist() == [1] and result.numbers["ae_events"] == 1
    assert ae["magnitude"][0] == pytest.approx((math.log10(stored) - 4.8) / 1.5,
                                               abs=0.01)
    assert log["time"][0] == pytest.approx(ae["time"][0]) and log["time"][0] > 0.0
    # the grip strain at the break: the bond's strain (the grips are its two particles)
    assert log["platen_strain"][0] == pytest.approx(STRENGTH / E_BOND, rel=0.03)
    paths = result.write(tmp_path, figures=False)
    with h5py.File(tmp_path / "results.h5", "r") as f:
        np.testing.assert_array_equal(f["lab/cracks/energy"][...], log["energy"])
        units = {"time": "s", "x": "m", "y": "m", "z": "m", "energy": "J", "cracks": "1",
                 "magnitude": "1"}
        assert {k: d.attrs["unit"] for k, d in f["lab/ae_events"].items()} == units
        assert f["lab/cracks/time"].attrs["unit"] == "s"
        assert f["lab/cracks/bending_moment"].attrs["unit"] == "N m"
    rows = paths["cracks_csv"].read_text().splitlines()
    assert rows[0].startswith("time (s),x (m)") and len(rows) == 2


def test_every_broken_bond_is_one_crack_in_a_lattice_that_fails(tmp_path):
    specimen = lattice_specimen((3, 3, 6), RADIUS, GLASS, BINDER, diameter_ratio=RATIO)
    result = direct_tension(specimen, out_dir=tmp_path, settings=LabSettings(frames=2))
    n = result.numbers
    assert n["cracks"] == n["broken_bonds_final"] == result.cracks["time"].size > 0
    assert result.cracks["event"].max() + 1 == n["ae_events"]
    assert int(result.ae["cracks"].sum()) == n["cracks"]
    np.testing.assert_allclose(result.ae["energy"].sum(), result.cracks["energy"].sum(),
                               rtol=1e-12)
    # the curve's cumulative AE count ends at the number of events
    assert result.curve["ae_events"][-1] == n["ae_events"]
    assert np.all(np.diff(result.curve["ae_events"]) >= 0)
    result.write(tmp_path)
    saved = json.loads((tmp_path / "lab.json").read_text())
    assert saved["failed"] is True and saved["no_failure"] is None
    assert (tmp_path / "lab_ae.png").is_file()


@pytest.mark.parametrize("ae_radius, events", [(0.9, 18), (1.1, 2)])
def test_the_ae_radius_is_in_particle_diameters(ae_radius, events):
    """A 3 x 3 x 6 lattice pulled apart breaks the 9 bonds of each of two layers in one
    step. Neighbouring bonds of a layer lie one lattice spacing (one diameter) apart and
    the layers 4 diameters apart: within 0.9 diameters every crack is its own event,
    within 1.1 each layer is one event of 9 cracks."""
    specimen = lattice_specimen((3, 3, 6), RADIUS, GLASS, BINDER, diameter_ratio=RATIO)
    result = direct_tension(specimen, settings=LabSettings(ae_radius=ae_radius))
    assert result.numbers["cracks"] == 18 and np.unique(result.cracks["time"]).size == 1
    assert result.numbers["ae_events"] == events
    assert result.ae["cracks"].tolist() == [18 // events] * events


def test_a_weak_bond_breaks_first_and_each_bond_is_one_crack():
    """One bond of the middle layer at 0.6 of the others' strength breaks first; its
    layer's other eight follow in later samples. Each broken bond is logged once, when
    it breaks, whatever samples follow."""
    specimen = lattice_specimen((3, 3, 6), RADIUS, GLASS, BINDER, diameter_ratio=RATIO)
    middle = 0.5 * (specimen.position[specimen.bonds[:, 0]]
                    + specimen.position[specimen.bonds[:, 1]])
    centre = 0.5 * (specimen.position.min(axis=0) + specimen.position.max(axis=0))
    weak = int(np.argmin(np.abs(middle - centre).sum(axis=1)))
    index = np.zeros(specimen.n_bonds, np.int64)
    index[weak] = 1
    weaker = dataclasses.replace(BINDER, normal_strength=0.6 * STRENGTH,
                                 tangential_strength=0.6 * STRENGTH)
    specimen = dataclasses.replace(specimen, bond_materials=[BINDER, weaker],
                                   bond_material_index=index)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")        # the layer's break is not quasi-static
        result = direct_tension(specimen)
    log, n = result.cracks, result.numbers
    assert n["cracks"] == n["broken_bonds_final"] == 9
    assert np.unique(log["bond"]).size == 9 and int(log["bond"][0]) == weak
    assert log["time"][0] < log["time"][1]
    assert np.all(np.abs(log["z"] - centre[2]) < 0.1 * RADIUS)   # all in the middle layer


def test_a_test_that_does_not_fail_writes_null_strengths(tmp_path):
    specimen = lattice_specimen((3, 3, 6), RADIUS, GLASS, BINDER, diameter_ratio=RATIO)
    result = uniaxial(specimen, LabSettings(max_strain=0.002, samples=200))
    result.write(tmp_path, figures=False)
    saved = json.loads((tmp_path / "lab.json").read_text())
    assert saved["failed"] is False and "strain limit" in saved["no_failure"]
    assert saved["numbers"]["ucs"] is None and saved["numbers"]["largest_stress"] > 0.0
    assert result.cracks["time"].size == 0 and saved["numbers"]["ae_events"] == 0


def test_the_rate_is_checked_by_a_run_at_half_the_rate():
    """The lattice's tensile strength at the default rate moves by less than 2 % at half
    the rate (its closed form does not depend on it); a hundred times the default rate is
    not quasi-static and is warned of, with the kinetic-energy ratio."""
    specimen = lattice_specimen((3, 3, 6), RADIUS, GLASS, BINDER, diameter_ratio=RATIO)
    result = direct_tension(specimen, LabSettings(rate_check="repeat", samples=500))
    n = result.numbers
    assert abs(n["rate_change_strength"]) < 0.02 and abs(n["rate_change_modulus"]) < 0.005
    assert not any("half the strain rate" in note for note in result.notes)
    fast = 100.0 * n["strain_rate"]
    with pytest.warns(UserWarning, match="not quasi-static"):
        hasty = direct_tension(specimen, LabSettings(strain_rate=fast, samples=200))
    assert hasty.numbers["kinetic_energy_ratio"] > 0.01
    assert any("not quasi-static" in note for note in hasty.notes)


def test_the_rate_check_reruns_at_half_the_rate_and_warns_above_its_limits():
    """The check around a test (a stand-in lab test here): the second run is at half the
    first's strain rate; a 3 % strength change, a 1 % modulus change and a kinetic-energy
    ratio of 0.02 are each above their limits (2 %, 0.5 %, 0.01) and each warned of."""
    from bondem.lab.procedures import LabResult, _rate_checked
    rates = []

    def stand_in(specimen, settings=None):
        rate = settings.strain_rate or 10.0
        rates.append(rate)
        slow = rate < 10.0
        numbers = {"strain_rate": rate, "ucs": 1.03e6 if slow else 1e6,
                   "young_modulus_secant": 1.01e9 if slow else 1e9,
                   "kinetic_energy_ratio": 0.02}
        return LabResult("ucs", {}, numbers, {}, {}, notes=["stopped: post-peak"])

    with pytest.warns(UserWarning) as caught:
        result = _rate_checked(stand_in)(None, LabSettings(rate_check="repeat"))
    assert rates == [10.0, 5.0]
    assert result.numbers["rate_change_strength"] == pytest.approx(0.03)
    assert result.numbers["rate_change_modulus"] == pytest.approx(0.01)
    messages = " ".join(str(w.message) for w in caught)
    assert "0.02 of the elastic energy" in messages and "ucs moved by 3 %" in messages
    assert "young_modulus_secant moved by 1 %" in messages
    assert result.notes[-1] == "stopped: post-peak" and len(result.notes) == 4
    quiet = _rate_checked(stand_in)(None, LabSettings(rate_check="off"))
    assert quiet.notes == ["stopped: post-peak"]

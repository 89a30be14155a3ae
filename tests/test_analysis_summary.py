"""The key numbers and the time table of a run (bondem.analysis.summary) on a constructed
results file whose every number is known: six particles of unequal masses in a chain
whose bonds break one per frame in three modes, two plates closing, energy terms, and a
field's forces; each key number is the last frame's, each column one row per frame."""
import numpy as np
import pytest

from bondem.analysis import Results
from bondem.analysis import summary
from bondem.analysis.walls import wall_curve
from resultsfile import write_static

TIME = np.array([0.0, 0.5e-3, 1.0e-3, 1.5e-3])
MASS = np.array([4.0, 5.0, 6.0, 1.0, 2.0, 3.0]) * 1e-6
PAIRS = [[0, 1], [1, 2], [3, 4], [4, 5], [2, 3]]
# bond 4 (2-3) breaks in tension by frame 1, bond 3 (4-5) in shear by frame 2, bonds 0
# (0-1, compression) and 1 (1-2, tension) by frame 3
ACTIVE = np.array([[1, 1, 1, 1, 1], [1, 1, 1, 1, 0], [1, 1, 1, 0, 0], [0, 0, 1, 0, 0]],
                  dtype=bool)
MODE = [2, 1, 0, 3, 1]


def a_run(tmp_path, walls=True, energy=True, name="run.h5"):
    k = np.arange(4)
    walls_force = np.zeros((4, 2, 3))
    walls_force[:, 0, 2] = -np.array([0.0, 3.0, 5.0, 4.0])   # N, pushed down
    walls_force[:, 1, 2] = np.array([0.0, 3.3, 5.5, 4.4])    # N, pushed up
    walls_position = np.zeros((4, 2, 3))
    walls_position[:, 0, 2] = -1e-3
    walls_position[:, 1, 2] = 7e-3 - 2e-4 * k
    terms = {"kinetic_translational": np.array([1.0, 0.8, 0.5, 0.4]),
             "bond_elastic": np.array([0.0, 0.1, 0.3, 0.3]),
             "dissipated_damping": np.array([0.0, 0.1, 0.2, 0.35])}
    position = np.arange(18, dtype=float).reshape(6, 3) * 1e-3
    return write_static(tmp_path / name, position, 5e-4, PAIRS, ACTIVE, time=TIME,
                        mass=MASS, break_mode=MODE,
                        walls=(walls_force, walls_position) if walls else None,
                        energy=terms if energy else None)


def test_the_key_numbers_are_the_last_frames(tmp_path):
    path = a_run(tmp_path)
    with Results(path) as results:
        curve = wall_curve(results)
        numbers = summary.key_numbers(results)
        data = summary.analyze(results)
    # fragments at the end: {0}, {1}, {2}, {3, 4}, {5}; the largest {2}: 6 of 21 ug
    expected = {"frames": 4, "final_time": 1.5e-3, "particles": 6, "bonds": 5,
                "intact_bond_fraction": pytest.approx(0.2, rel=1e-15), "broken_tension": 2, "broken_compression": 1,
                "broken_shear": 1, "fragments": 5, "fragments_multi": 1,
                "largest_fragment_fraction": pytest.approx(6.0 / 21.0, rel=1e-12),
                "first_break_time": 0.5e-3, "peak_wall_force": curve["peak_force"],
                "displacement_at_peak_force": curve["displacement_at_peak_force"],
                "plate_gap_at_peak_force": curve["gap_at_peak_force"],
                "plate_force_mismatch": curve["force_mismatch"],
                "energy_balance_error": data["energy"]["max_relative_error"],
                "energy_reference": data["energy"]["reference"]}
    assert numbers == expected
    assert curve["partner"] == 0 and curve["peak_force"] == pytest.approx(5.25)
    assert data["energy"]["reference"] == 1.0
    assert type(numbers["fragments"]) is int and type(numbers["final_time"]) is float
    assert summary.summarize(path) == expected


def test_a_run_without_walls_energy_or_bonds(tmp_path):
    path = a_run(tmp_path, walls=False, energy=False)
    with Results(path) as results:
        numbers = summary.key_numbers(results)
    assert numbers["peak_wall_force"] is None and numbers["displacement_at_peak_force"] is None
    assert "plate_gap_at_peak_force" not in numbers and "plate_force_mismatch" not in numbers
    assert numbers["energy_balance_error"] is None and numbers["energy_reference"] is None
    path = write_static(tmp_path / "loose.h5", np.zeros((3, 3)), 1e-3, np.zeros((0, 2)),
                        np.zeros((2, 0), dtype=bool), time=[0.0, 2.0], mass=np.ones(3))
    with Results(path) as results:
        numbers = summary.key_numbers(results)
    assert numbers["intact_bond_fraction"] is None and numbers["first_break_time"] is None
    assert numbers["fragments"] == 3 and numbers["fragments_multi"] == 0
    assert numbers["final_time"] == 2.0 and numbers["bonds"] == 0
    # a file of no frames yet (a run stopped before its first): only what is known
    path = write_static(tmp_path / "none.h5", np.zeros((0, 2, 3)), 1e-3, [[0, 1]],
                        np.zeros((0, 1), dtype=bool), time=np.zeros(0), mass=np.ones(2))
    with Results(path) as results:
        numbers = summary.key_numbers(results)
    assert numbers == {"frames": 0, "final_time": None, "particles": 2, "bonds": 1,
                       "peak_wall_force": None, "displacement_at_peak_force": None,
                       "energy_balance_error": None, "energy_reference": None}


def fields_data():
    total = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 2.0], [3.0, 0.0, 4.0], [0.0, 6.0, 8.0]])
    return {"time": TIME, "total": total, "mean": np.array([0.0, 0.5, 0.8, 1.7]),
            "weight_carried": np.array([0.0, 0.2, 0.6, 0.9])}


def test_the_fields_key_numbers_and_columns(tmp_path):
    path = a_run(tmp_path)
    with Results(path) as results:
        data = summary.analyze(results)
        data["fields"] = fields_data()
        numbers = summary.key_numbers(results, data)
        columns = summary.time_series(data)
        data["fields"]["weight_carried"] = None
        without = summary.key_numbers(results, data)
        without_columns = summary.time_series(data)
    assert numbers["field_force_total"] == 10.0          # |(0, 6, 8)|
    assert numbers["field_force_mean"] == 1.7 and numbers["weight_carried_by_fields"] == 0.9
    assert "weight_carried_by_fields" not in without and without["field_force_total"] == 10.0
    np.testing.assert_array_equal(columns["field_force_x"], [0.0, 1.0, 3.0, 0.0])
    np.testing.assert_array_equal(columns["field_force_y"], [0.0, 2.0, 0.0, 6.0])
    np.testing.assert_array_equal(columns["field_force_z"], [0.0, 2.0, 4.0, 8.0])
    np.testing.assert_array_equal(columns["field_force_mean"], [0.0, 0.5, 0.8, 1.7])
    np.testing.assert_array_equal(columns["weight_carried_by_fields"], [0.0, 0.2, 0.6, 0.9])
    assert "weight_carried_by_fields" not in without_columns


def test_the_time_table_one_row_per_frame(tmp_path):
    with Results(a_run(tmp_path)) as results:
        data = summary.analyze(results)
        curve = data["wall"]
    columns = summary.time_series(data)
    assert list(columns) == [
        "time", "fragments", "fragments_multi", "largest_fragment_fraction", "broken",
        "broken_fraction", "broken_tension", "broken_compression", "broken_shear",
        "energy_bond_elastic", "energy_dissipated_damping", "energy_kinetic_translational",
        "energy_stored", "energy_work", "energy_losses", "energy_residual",
        "energy_relative_error", "wall_displacement", "wall_force", "plate_gap",
        "wall_force_loading", "wall_force_partner"]
    np.testing.assert_array_equal(columns["time"], TIME)
    np.testing.assert_array_equal(columns["fragments"], [1, 2, 3, 5])
    np.testing.assert_array_equal(columns["fragments_multi"], [1, 2, 2, 1])
    np.testing.assert_allclose(columns["largest_fragment_fraction"],
                               [1.0, 15 / 21, 15 / 21, 6 / 21], rtol=1e-12)
    np.testing.assert_array_equal(columns["broken"], [0, 1, 2, 4])
    np.testing.assert_allclose(columns["broken_fraction"], [0.0, 0.2, 0.4, 0.8])
    np.testing.assert_array_equal(columns["broken_tension"], [0, 1, 1, 2])
    np.testing.assert_array_equal(columns["broken_shear"], [0, 0, 1, 1])
    np.testing.assert_array_equal(columns["broken_compression"], [0, 0, 0, 1])
    np.testing.assert_array_equal(columns["energy_bond_elastic"], [0.0, 0.1, 0.3, 0.3])
    np.testing.assert_array_equal(columns["energy_residual"], data["energy"]["residual"])
    for name in ("stored", "work", "losses", "relative_error"):
        np.testing.assert_array_equal(columns[f"energy_{name}"], data["energy"][name])
    np.testing.assert_array_equal(columns["wall_displacement"], curve["displacement"])
    np.testing.assert_array_equal(columns["wall_force"], curve["force"])
    np.testing.assert_array_equal(columns["plate_gap"], curve["gap"])
    np.testing.assert_array_equal(columns["wall_force_loading"], curve["force_wall"])
    np.testing.assert_array_equal(columns["wall_force_partner"], curve["force_partner"])
    np.testing.assert_allclose(columns["plate_gap"], 8e-3 - 2e-4 * np.arange(4), rtol=1e-12)
    # one plate only: no gap, no partner's columns
    data["wall"] = dict(curve, partner=None)
    assert "plate_gap" not in summary.time_series(data)


def test_the_table_file_and_the_numbers_as_text(tmp_path):
    path = tmp_path / "table.csv"
    summary.write_table({"time": [0.0, 1.5e-3], "broken": [0, 3],
                         "energy_work": [1.0 / 3.0, 2e-12]}, path)
    assert path.read_text() == ("time,broken,energy_work\n0,0,0.3333333333\n"
                                "0.0015,3,2e-12\n")
    summary.write_table({}, tmp_path / "empty.csv")
    assert (tmp_path / "empty.csv").read_text() == ""
    assert summary.format_number("final_time", 1.23456e-3) == "0.001235 s"
    assert summary.format_number("fragments", 12) == "12 fragments"
    assert summary.format_number("broken_shear", 2) == "2 bonds"
    assert summary.format_number("peak_wall_force", None) == "n/a"
    assert summary.format_number("something_new", 0.5) == "0.5"
    assert summary.format_number("something_new", 7) == "7"

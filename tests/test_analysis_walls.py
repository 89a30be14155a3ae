"""Wall force against displacement and the energy balance's bookkeeping on constructed
files with known answers (compression between a fixed and a moving plate)."""
import numpy as np
import pytest

from bondem.analysis import Results, energy_balance, force_mismatch, key_numbers, wall_curve
from bondem.analysis.figures import build_figures

from resultsfile import write_static

N_FRAMES = 21


@pytest.fixture
def plates(tmp_path):
    """Two particles bonded, squeezed by plate 1 moving down 0.1 mm per frame from
    z = 3 mm; plate 0 fixed at z = 0. The body pushes plate 1 up with a force that rises
    linearly (1 N per frame) until frame 12, then falls; the bond breaks at frame 9."""
    k = np.arange(N_FRAMES)
    force_up = np.where(k <= 12, k * 1.0, 12.0 - 3.0 * (k - 12))
    walls_force = np.zeros((N_FRAMES, 2, 3))
    walls_force[:, 1, 2] = force_up
    walls_force[:, 0, 2] = -force_up
    walls_position = np.zeros((N_FRAMES, 2, 3))
    walls_position[:, 1, 2] = 3e-3 - 1e-4 * k
    active = (k < 9)[:, None]
    position = [[0, 0, 1e-3], [0, 0, 2e-3]]
    work = np.cumsum(force_up * 1e-4)  # J, plate work, kinetic energy starts at 0
    energy = {"kinetic_translational": np.zeros(N_FRAMES), "bond_elastic": 0.6 * work,
              "work_walls": work, "dissipated_contacts": 0.4 * work}
    return write_static(tmp_path / "plates.h5", position, 5e-4, [[0, 1]], active,
                        time=k * 1e-4, break_mode=[1], walls=(walls_force, walls_position),
                        energy=energy)


def test_force_displacement_curve(plates):
    with Results(plates) as results:
        curve = wall_curve(results)
        fixed = wall_curve(results, wall=0)
        with pytest.raises(IndexError):
            wall_curve(results, wall=2)
    assert curve["wall"] == 1                     # the plate that moved
    assert curve["displacement"] == pytest.approx(1e-4 * np.arange(N_FRAMES))
    assert curve["peak_index"] == 12 and curve["peak_force"] == pytest.approx(12.0)
    assert curve["displacement_at_peak_force"] == pytest.approx(1.2e-3)
    assert curve["partner"] == 0                  # the fixed anvil it presses against
    assert curve["gap"] == pytest.approx(3e-3 - 1e-4 * np.arange(N_FRAMES))
    assert curve["gap_at_peak_force"] == pytest.approx(1.8e-3)
    assert curve["force_mismatch"] == pytest.approx(0.0)
    assert curve["first_break_index"] == 9 and curve["first_break_force"] == pytest.approx(9)
    assert curve["first_break_displacement"] == pytest.approx(0.9e-3)
    assert fixed["displacement"].tolist() == [0.0] * N_FRAMES
    assert fixed["peak_force"] == pytest.approx(12.0)   # |F| for a wall that stays


def test_the_peak_between_two_frames_comes_from_the_wall_history(plates):
    """The run's per-step wall history (/walls/history) holds a row between frames 12 and
    13, at t = 1.25e-3 s, where the plate pushed 12.5 N (the frames saw 12 N
    and 9 N): the peak, its displacement, gap and time are the history's."""
    import h5py
    k = np.arange(N_FRAMES)
    time = np.sort(np.r_[k * 1e-4, 1.25e-3])
    push = np.where(time <= 1.25e-3, time / 1e-4, 12.0 - 3.0 * (time - 1.2e-3) / 1e-4)
    push[time == 1.3e-3] = 9.0
    force = np.zeros((len(time), 2, 3))
    force[:, 1, 2], force[:, 0, 2] = push, -push
    position = np.zeros((len(time), 2, 3))
    position[:, 1, 2] = 3e-3 - time   # 0.1 mm per 1e-4 s
    with h5py.File(plates, "a") as f:
        for name, values in (("time", time), ("force", force), ("position", position)):
            f[f"walls/history/{name}"] = values
    with Results(plates) as results:
        curve = wall_curve(results)
        numbers = key_numbers(results)
        fixed = wall_curve(results, wall=0)
        assert "wall" in build_figures(results)
    assert curve["peak_force"] == pytest.approx(12.5) and curve["peak_time"] == 1.25e-3
    assert curve["displacement_at_peak_force"] == pytest.approx(1.25e-3)
    assert curve["gap_at_peak_force"] == pytest.approx(1.75e-3)
    assert curve["peak_index"] in (12, 13)
    assert numbers["peak_wall_force"] == pytest.approx(12.5)
    # the fixed plate read on its own: |F| against time, and no displacement to report
    assert fixed["peak_force"] == pytest.approx(12.5)
    assert fixed["displacement_at_peak_force"] is None


def test_two_plates_closing_use_the_gap_and_both_forces(tmp_path):
    """Plates at z = 0 and z = 4 mm close at 0.1 and 0.2 mm per frame: the displacement is
    the gap's decrease (0.3 mm per frame, not one plate's travel), the force the mean of
    the two plates' forces (here 10 % apart: the upper one reads 1.1 times the lower)."""
    k = np.arange(N_FRAMES)
    push = np.where(k <= 8, 2.0 * k, 16.0 - (k - 8))   # N on the lower plate, downwards
    walls_force = np.zeros((N_FRAMES, 2, 3))
    walls_force[:, 0, 2] = -push
    walls_force[:, 1, 2] = 1.1 * push
    walls_position = np.zeros((N_FRAMES, 2, 3))
    walls_position[:, 0, 2] = 1e-4 * k
    walls_position[:, 1, 2] = 4e-3 - 2e-4 * k
    path = write_static(tmp_path / "two.h5", [[0, 0, 1e-3], [0, 0, 2e-3]], 5e-4, [[0, 1]],
                        np.ones((N_FRAMES, 1), bool), time=k * 1e-4,
                        walls=(walls_force, walls_position))
    with Results(path) as results:
        curve = wall_curve(results)
        numbers = key_numbers(results)
    assert curve["wall"] == 1 and curve["partner"] == 0
    assert curve["displacement"] == pytest.approx(3e-4 * k)
    assert curve["gap"] == pytest.approx(4e-3 - 3e-4 * k)
    assert curve["force"] == pytest.approx(1.05 * push)
    assert curve["peak_index"] == 8 and curve["peak_force"] == pytest.approx(16.8)
    assert numbers["displacement_at_peak_force"] == pytest.approx(2.4e-3)
    assert numbers["plate_gap_at_peak_force"] == pytest.approx(1.6e-3)
    assert numbers["plate_force_mismatch"] == pytest.approx(1.6 / 16.8)


def test_energy_balance_of_a_run_from_rest_uses_the_work(plates):
    with Results(plates) as results:
        balance = energy_balance(results)
        numbers = key_numbers(results)
        figures = build_figures(results, frames=(0, -1))
    assert balance["reference"] == pytest.approx(balance["work"].max())
    assert balance["max_relative_error"] == pytest.approx(0.0, abs=1e-12)
    assert numbers["peak_wall_force"] == pytest.approx(12.0)
    assert numbers["energy_balance_error"] == pytest.approx(0.0, abs=1e-12)
    assert figures["wall"][1]["peak_index"] == 12
    assert figures["bodies"][1][1]["n_fragments"] == 2


def test_unbalanced_energy_is_reported(tmp_path):
    # 10 % of the initial kinetic energy vanishes without a loss term recording it
    kinetic = np.array([1.0, 0.5, 0.0])
    energy = {"kinetic_translational": kinetic, "bond_elastic": np.array([0.0, 0.45, 0.9])}
    path = write_static(tmp_path / "leak.h5", [[0, 0, 0], [1, 0, 0]], 0.5, [[0, 1]],
                        np.ones((3, 1), bool), energy=energy)
    with Results(path) as results:
        balance = energy_balance(results)
    assert balance["relative_error"] == pytest.approx([0.0, -0.05, -0.1])
    assert balance["max_relative_error"] == pytest.approx(0.1)
    # bondem run says so at the end of such a run, with what to change
    from bondem.commands.run import energy_warning
    message = energy_warning(path)
    assert "off by 10.0% of the reference energy" in message and "safety_factor" in message
    energy["bond_elastic"] = np.array([0.0, 0.48, 0.96])      # 4 %: within the tolerance
    fine = write_static(tmp_path / "fine.h5", [[0, 0, 0], [1, 0, 0]], 0.5, [[0, 1]],
                        np.ones((3, 1), bool), energy=energy)
    assert energy_warning(fine) is None
    no_energy = write_static(tmp_path / "bare.h5", [[0, 0, 0]], 0.5, np.zeros((0, 2)),
                             np.ones((2, 0), bool))
    with Results(no_energy) as results:
        assert energy_balance(results) is None and wall_curve(results) is None
        assert key_numbers(results)["fragments"] == 1


def _file(tmp_path, name, force, position, time=None):
    frames = force.shape[0]
    return write_static(tmp_path / name, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], 0.5, [[0, 1]],
                        np.ones((frames, 1), bool),
                        time=np.arange(frames) * 1e-4 if time is None else time,
                        walls=(force, position))


def test_the_facing_plate_is_found_among_other_walls_away_from_the_origin(tmp_path):
    """Four walls, none at the origin (module docstring's definitions, three frames):
    wall 0 loads along u = (0.6, 0, -0.8) by 0.2 mm per frame; wall 1 slides across it
    (u . u1 = 0: no partner; it travels less than wall 0); wall 2 stands still and is pushed along u by 40 mN; wall 3
    closes along -u by 0.1 mm per frame (the partner: moving walls come first). The
    displacement is the gap's decrease 0.3 mm per frame, the gap starts at
    |(p3 - p0) . u| = 5.2 mm, forces are mN (below 1 N)."""
    u = np.array([0.6, 0.0, -0.8])
    k = np.arange(3)
    start = np.array([[1e-3, 2e-3, 5e-3], [-4e-3, 1e-3, 2e-3], [7e-3, -3e-3, -1e-3],
                      [4.12e-3, 2e-3, 0.84e-3]])
    position = np.repeat(start[None], 3, axis=0)
    position[:, 0] += 2e-4 * k[:, None] * u
    position[:, 1] += 1e-4 * k[:, None] * np.array([0.0, 1.0, 0.0])
    position[:, 3] -= 1e-4 * k[:, None] * u
    push = np.array([0.010, 0.030, 0.020])            # N, compressive on wall 0
    force = np.zeros((3, 4, 3))
    force[:, 0] = -push[:, None] * u                   # the body pushes wall 0 back
    force[:, 3] = np.array([0.012, 0.024, 0.020])[:, None] * u   # and wall 3 along +u
    force[:, 2] = 0.040 * u                            # the anvil that is not the partner
    path = _file(tmp_path, "four.h5", force, position)
    with Results(path) as results:
        curve = wall_curve(results)
        with pytest.raises(IndexError, match="out of range: the file has 4 walls"):
            wall_curve(results, wall=4)
    gap0 = abs(float((start[3] - start[0]) @ u))
    assert gap0 == pytest.approx(5.2e-3, rel=1e-12)
    assert curve["wall"] == 0 and curve["partner"] == 3
    np.testing.assert_allclose(curve["displacement"], 3e-4 * k, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(curve["gap"], gap0 - 3e-4 * k, rtol=1e-12)
    mean = 0.5 * (push + np.array([0.012, 0.024, 0.020]))
    np.testing.assert_allclose(curve["force"], mean, rtol=1e-12)
    np.testing.assert_allclose(curve["force_magnitude"], push, rtol=1e-12)
    np.testing.assert_allclose(curve["time"], k * 1e-4)
    assert curve["peak_index"] == 1 and curve["peak_force"] == pytest.approx(0.027)
    # mismatch up to the peak over the peak force: |0.010 - 0.012|, |0.030 - 0.024|
    assert curve["force_mismatch"] == pytest.approx(0.006 / 0.027, rel=1e-12)
    assert curve["gap_at_peak_force"] == pytest.approx(gap0 - 3e-4, rel=1e-12)
    for key in ("first_break_index", "first_break_force", "first_break_displacement"):
        assert curve[key] is None                          # no bond broke


def test_the_anvil_is_the_still_wall_pushed_hardest(tmp_path):
    """No wall closes in: of two still walls the one the body pushes along u (mean 5 mN)
    is the counterpart, not the one without load nor one pushed the other way; a single
    frame is a curve too (its own peak), no frames none. Wall 0 loads along -z."""
    position = np.zeros((2, 3, 3))
    position[:, 0] = [[0.0, 0.0, 3e-3], [0.0, 0.0, 2.9e-3]]
    position[:, 1] = [2e-3, 0.0, -1e-3]
    position[:, 2] = [-2e-3, 0.0, -1e-3]
    force = np.zeros((2, 3, 3))
    force[:, 0] = [[0.0, 0.0, 0.004], [0.0, 0.0, 0.006]]
    force[:, 1] = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]   # still and unloaded
    force[:, 2] = [[0.0, 0.0, -0.004], [0.0, 0.0, -0.006]]   # pushed along u
    with Results(_file(tmp_path, "anvil.h5", force, position)) as results:
        curve = wall_curve(results)
    assert curve["partner"] == 2
    assert curve["gap"] == pytest.approx([4e-3, 3.9e-3])
    one = _file(tmp_path, "one.h5", force[:1], position[:1])
    with Results(one) as results:
        single = wall_curve(results)
    assert single["peak_force"] == pytest.approx(0.004) and single["partner"] is None
    with Results(_file(tmp_path, "none.h5", force[:0], position[:0], time=np.zeros(0))) \
            as results:
        assert wall_curve(results) is None
    # a still wall the body does not push is no anvil (the only other wall here)
    with Results(_file(tmp_path, "unloaded.h5", force[:, :2], position[:, :2])) as results:
        assert wall_curve(results)["partner"] is None


def test_the_mismatch_stops_at_the_peak_and_a_curve_without_load_has_none(tmp_path):
    """Two plates closing, per-step history: the mismatch counts the rows up to and with
    the peak (1.2 N apart there; 2.0 N right after it does not count), frames and
    history alike; with no load at all there is no peak force to compare with."""
    import h5py
    k = np.arange(6)
    position = np.zeros((6, 2, 3))
    position[:, 0, 2] = 1e-3 + 1e-4 * k
    position[:, 1, 2] = 5e-3 - 1e-4 * k
    lower = np.array([0.0, 1.0, 2.0, 4.0, 3.0, 1.0])     # N on the lower plate
    upper = lower + np.array([0.0, 0.1, 0.2, 1.2, 2.0, 0.1])
    force = np.zeros((6, 2, 3))
    force[:, 0, 2], force[:, 1, 2] = -lower, upper
    path = _file(tmp_path, "frames.h5", force, position)
    with Results(path) as results:
        curve = wall_curve(results)
    peak = 0.5 * (4.0 + 5.2)
    assert curve["peak_index"] == 3 and curve["peak_force"] == pytest.approx(peak)
    assert curve["force_mismatch"] == pytest.approx(1.2 / peak, rel=1e-12)
    with h5py.File(path, "a") as f:
        f["walls/history/time"] = k * 1e-4
        f["walls/history/force"] = force
        f["walls/history/position"] = position
    with Results(path) as results:
        curve = wall_curve(results)
    assert curve["force_mismatch"] == pytest.approx(1.2 / peak, rel=1e-12)
    quiet = _file(tmp_path, "quiet.h5", np.zeros((6, 2, 3)), position)
    with Results(quiet) as results:
        curve = wall_curve(results)
    assert curve["peak_force"] == 0.0 and curve["force_mismatch"] is None
    # the history's branch too: no load, then loads of mN (the mismatch still counts)
    for scale, expected in ((0.0, None), (1e-3, 1.2 / peak)):
        quiet = _file(tmp_path, f"quiet{scale}.h5", scale * force, position)
        with h5py.File(quiet, "a") as f:
            f["walls/history/time"] = k * 1e-4
            f["walls/history/force"] = scale * force
            f["walls/history/position"] = position
        with Results(quiet) as results:
            curve = wall_curve(results)
        assert curve["peak_force"] == pytest.approx(scale * peak)
        assert curve["force_mismatch"] == (None if expected is None else
                                           pytest.approx(expected, rel=1e-12))


def test_the_whole_history_is_read_past_the_number_of_frames(tmp_path):
    """A run's history has a row every step, far more than its frames: two plates closing
    at 10 um per 1e-5 s from z = 1 mm and 5 mm, frames every tenth row (5), history rows
    every 1e-5 s (41), the lower plate's load rising 0.5 N per row to 17 N at row 34
    (t = 0.34 ms, after the fourth frame), then falling 1 N per row; the upper plate reads
    0.1 N more, 0.8 N more at row 25 (between frames). A 42nd row of force and position
    whose time is not yet written (a writer within a row) does not count."""
    import h5py
    j = np.arange(41)
    push = np.where(j <= 34, 0.5 * j, 17.0 - (j - 34))
    delta = np.where(j == 25, 0.8, 0.1)
    force, position = np.zeros((42, 2, 3)), np.zeros((42, 2, 3))
    force[:41, 0, 2], force[:41, 1, 2] = -push, push + delta
    force[41, :, 2] = -100.0, 100.0
    position[:41, 0, 2], position[:41, 1, 2] = 1e-3 + 1e-5 * j, 5e-3 - 1e-5 * j
    path = _file(tmp_path, "steps.h5", force[:41:10], position[:41:10])
    with h5py.File(path, "a") as f:
        f["walls/history/time"] = j * 1e-5
        f["walls/history/force"] = force
        f["walls/history/position"] = position
    with Results(path) as results:
        assert results.n_frames == 5
        curve = wall_curve(results)
        numbers = key_numbers(results)
    peak = 17.0 + 0.05
    assert curve["peak_force"] == pytest.approx(peak, rel=1e-12)
    assert curve["peak_time"] == pytest.approx(3.4e-4, rel=1e-12)
    assert curve["displacement_at_peak_force"] == pytest.approx(6.8e-4, rel=1e-12)
    assert curve["gap_at_peak_force"] == pytest.approx(4e-3 - 6.8e-4, rel=1e-12)
    assert curve["peak_index"] == 3
    assert curve["force_mismatch"] == pytest.approx(0.8 / peak, rel=1e-12)
    assert numbers["plate_force_mismatch"] == pytest.approx(0.8 / peak, rel=1e-12)
    assert numbers["peak_wall_force"] == pytest.approx(peak, rel=1e-12)


def test_force_mismatch_is_the_largest_difference_up_to_the_peak_over_its_mean_force():
    """The one definition the lab and the analysis share: forces of 3, 5, 9.5 and 7 N on
    one platen against 1, 6, 8.5 and 10 N on the other peak (the mean 9.0 N) at the
    third sample; the 2 N apart at the first count, the 3 N after the peak do not.
    At a given peak (a stress's, which need not be the force's) the same up to it."""
    a, b = np.array([3.0, 5.0, 9.5, 7.0]), np.array([1.0, 6.0, 8.5, 10.0])
    assert force_mismatch(a, b) == pytest.approx(2.0 / 9.0, rel=1e-15)
    assert force_mismatch(b, a) == pytest.approx(2.0 / 9.0, rel=1e-15)
    assert force_mismatch(a, b, peak=1) == pytest.approx(2.0 / 5.5, rel=1e-15)
    assert force_mismatch(a, b, peak=3) == pytest.approx(3.0 / 8.5, rel=1e-15)
    assert force_mismatch(np.array([0.0, 1e-3]), np.array([0.0, 3e-3])) == pytest.approx(1.0)
    assert force_mismatch(np.zeros(3), np.zeros(3)) is None
    assert force_mismatch([-1.0, -2.0], [-1.0, -3.0]) is None   # never compressed
    assert force_mismatch([], []) is None


def test_the_curve_is_computed_in_double_precision_whatever_the_file_stores(tmp_path):
    """A file whose wall datasets are float32 (another writer's): gap, forces and the peak
    are the float64 arithmetic of the stored values, not float32's (1e-7 apart)."""
    import h5py
    k = np.arange(4)
    position = np.zeros((4, 2, 3))
    position[:, 0, 2] = 1.1e-3 + 1.3e-4 * k
    position[:, 1, 2] = 5.3e-3 - 0.7e-4 * k
    force = np.zeros((4, 2, 3))
    force[:, 0, 2] = -np.array([0.1, 0.7, 1.3, 0.9])
    force[:, 1, 2] = np.array([0.11, 0.73, 1.37, 0.93])
    path = _file(tmp_path, "single.h5", force, position)
    with h5py.File(path, "a") as f:
        for name, values in (("force", force), ("position", position)):
            del f[f"walls/{name}"]
            f[f"walls/{name}"] = values.astype(np.float32)
            f[f"walls/history/{name}"] = values.astype(np.float32)
        f["walls/history/time"] = (k * 1e-4).astype(np.float32)
    stored_f = force.astype(np.float32).astype(np.float64)
    stored_x = position.astype(np.float32).astype(np.float64)
    with Results(path) as results:
        curve = wall_curve(results)
    gap = (stored_x[0, 1, 2] - stored_x[0, 0, 2]) - (
        (stored_x[:, 0, 2] - stored_x[0, 0, 2]) - (stored_x[:, 1, 2] - stored_x[0, 1, 2]))
    np.testing.assert_allclose(curve["gap"], gap, rtol=1e-15)
    mean = 0.5 * (-stored_f[:, 0, 2] + stored_f[:, 1, 2])
    np.testing.assert_allclose(curve["force"], mean, rtol=1e-15)
    assert curve["peak_force"] == pytest.approx(mean[2], rel=1e-15)
    assert curve["gap_at_peak_force"] == pytest.approx(gap[2], rel=1e-15)
    assert curve["peak_time"] == float(np.float32(2e-4))


def test_energy_balance_by_its_definition_on_constructed_records(tmp_path):
    """stored(t) - stored(0) = work - losses + residual; the reference is the initial
    kinetic energy, translational plus rotational (3 J here), else the largest |work|, else
    none (relative error 0). Groups without a recorded term are zero series, and a file
    with no frames gives the same keys with empty series."""
    two = [[0, 0, 0], [1, 0, 0]]
    energy = {"kinetic_translational": np.array([2.0, 1.5, 1.0]),
              "kinetic_rotational": np.array([1.0, 0.25, 0.5]),
              "bond_elastic": np.array([0.0, 0.9, 1.2])}
    path = write_static(tmp_path / "spin.h5", two, 0.5, [[0, 1]], np.ones((3, 1), bool),
                        energy=energy)
    with Results(path) as results:
        balance = energy_balance(results)
    stored = np.array([3.0, 2.65, 2.7])
    np.testing.assert_allclose(balance["stored"], stored)
    np.testing.assert_array_equal(balance["work"], np.zeros(3))
    np.testing.assert_array_equal(balance["losses"], np.zeros(3))   # no loss recorded
    np.testing.assert_allclose(balance["residual"], stored - 3.0)
    assert balance["reference"] == 3.0
    np.testing.assert_allclose(balance["relative_error"], (stored - 3.0) / 3.0)
    assert balance["max_relative_error"] == pytest.approx(0.35 / 3.0)
    # only rotation at the start and a wall's work: the reference is the spin's energy
    spin_only = {"kinetic_rotational": np.array([4.0, 3.0]), "work_walls": np.array([0.0, -6.0]),
                 "dissipated_contacts": np.array([0.0, 0.5])}
    path = write_static(tmp_path / "spin_only.h5", two, 0.5, [[0, 1]],
                        np.ones((2, 1), bool), energy=spin_only)
    with Results(path) as results:
        balance = energy_balance(results)
    assert balance["reference"] == 4.0
    np.testing.assert_allclose(balance["residual"], [0.0, -1.0 + 6.0 + 0.5])
    # nothing moving and no work: no reference to measure against
    still = {"kinetic_translational": np.zeros(2), "bond_elastic": np.array([0.0, 1e-9])}
    path = write_static(tmp_path / "still.h5", two, 0.5, [[0, 1]], np.ones((2, 1), bool),
                        energy=still)
    with Results(path) as results:
        balance = energy_balance(results)
    assert balance["reference"] == 0.0 and balance["max_relative_error"] == 0.0
    assert balance["relative_error"].shape == (2,)
    np.testing.assert_array_equal(balance["relative_error"], np.zeros(2))
    # no frames at all
    path = write_static(tmp_path / "empty.h5", two, 0.5, [[0, 1]], np.ones((0, 1), bool),
                        time=np.zeros(0), energy={"kinetic_translational": np.zeros(0)})
    with Results(path) as results:
        balance = energy_balance(results)
    assert set(balance) == {"time", "terms", "stored", "work", "losses", "residual",
                            "reference", "relative_error", "max_relative_error"}
    assert balance["reference"] == 0.0 and balance["max_relative_error"] == 0.0
    for key in ("time", "stored", "work", "losses", "residual", "relative_error"):
        assert balance[key].shape == (0,), key
    assert set(balance["terms"]) == {"kinetic_translational"}

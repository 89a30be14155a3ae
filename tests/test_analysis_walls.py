"""Wall force against displacement and the energy balance's bookkeeping on constructed
files with known answers (compression between a fixed and a moving plate)."""
import numpy as np
import pytest

from bondem.analysis import Results, energy_balance, key_numbers, wall_curve
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

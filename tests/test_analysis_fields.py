"""The fields' force in a results file (analysis/fields.py) against its definition, on
constructed files: the total per frame, the mean and largest magnitude per particle, and
the share of the moving particles' weight carried, -F . g / (M |g|^2), under a tilted
gravity with a fixed particle left out; files without the data give None.
"""
import h5py
import numpy as np
import pytest

from bondem.analysis import Results
from bondem.analysis.fields import field_series
from bondem.analysis.figures import build_figures
from bondem.analysis.summary import analyze, key_numbers, time_series

from resultsfile import write_static

GRAVITY = np.array([0.8, -0.3, -9.81])   # m/s^2, not along an axis
MASS = np.array([2e-6, 3.5e-6, 5e-6, 1.2e-6])   # kg; particle 2 fixed
FIXED = np.array([False, False, True, False])


def forces():
    """(F=3, N=4, 3) N: frame k's forces, different in every component."""
    rng = np.random.default_rng(4)
    out = rng.uniform(-2e-5, 2e-5, (3, 4, 3))
    out[:, 2] = 0.0   # a fixed particle feels no field force
    return out


def make(tmp_path, gravity=GRAVITY, fixed=FIXED, field=True, name="r.h5"):
    path = write_static(tmp_path / name, np.zeros((4, 3)), 1e-4, [[0, 1]],
                        [[True], [True], [False]], time=np.array([0.0, 1e-3, 2.5e-3]),
                        mass=MASS)
    with h5py.File(path, "a") as f:
        if field:
            f["particles/field_force"] = forces()
        if fixed is not None:
            f["particles/fixed"] = fixed
        if gravity is not None:
            f.attrs["gravity"] = gravity
    return path


def test_the_series_follow_their_definitions(tmp_path):
    with Results(make(tmp_path)) as results:
        series = field_series(results)
    f = forces()
    np.testing.assert_allclose(series["time"], [0.0, 1e-3, 2.5e-3], rtol=0)
    for k in range(3):
        total = sum(f[k, p] for p in range(4))
        np.testing.assert_allclose(series["total"][k], total, rtol=1e-14, atol=0)
        sizes = [float(np.sqrt(f[k, p] @ f[k, p])) for p in range(4)]
        assert series["mean"][k] == pytest.approx(sum(sizes) / 4, rel=1e-14)
        assert series["largest"][k] == pytest.approx(max(sizes), rel=1e-14)
        weight = (MASS[0] + MASS[1] + MASS[3]) * float(GRAVITY @ GRAVITY)
        assert series["weight_carried"][k] == pytest.approx(-(total @ GRAVITY) / weight,
                                                            rel=1e-13)
    assert series["total"].shape == (3, 3) and series["mean"].shape == (3,)


def test_a_bed_held_up_carries_its_weight(tmp_path):
    """Forces that balance each moving particle's weight exactly: the share is 1."""
    path = make(tmp_path)
    with h5py.File(path, "a") as f:
        up = -MASS[:, None] * GRAVITY * (~FIXED)[:, None]
        f["particles/field_force"][...] = np.broadcast_to(up, (3, 4, 3))
    with Results(path) as results:
        series = field_series(results)
        numbers = key_numbers(results)
    np.testing.assert_allclose(series["weight_carried"], 1.0, rtol=1e-14)
    assert numbers["weight_carried_by_fields"] == pytest.approx(1.0, rel=1e-14)
    weight = np.linalg.norm(GRAVITY) * MASS[~FIXED].sum()
    assert numbers["field_force_total"] == pytest.approx(weight, rel=1e-14)
    assert numbers["field_force_mean"] == pytest.approx(
        np.linalg.norm(GRAVITY) * MASS[~FIXED].sum() / 4, rel=1e-14)


def test_missing_data_gives_none(tmp_path):
    for kwargs, carried in (({"gravity": None}, None), ({"gravity": np.zeros(3)}, None),
                            ({"fixed": None}, None),
                            ({"fixed": np.ones(4, dtype=bool)}, None)):
        with Results(make(tmp_path, name=f"{len(list(tmp_path.iterdir()))}.h5",
                          **kwargs)) as results:
            series = field_series(results)
            assert series is not None and series["weight_carried"] is carried
            numbers = key_numbers(results)
            assert "field_force_total" in numbers
            assert "weight_carried_by_fields" not in numbers
            columns = time_series(analyze(results))
            assert "weight_carried_by_fields" not in columns
            assert "field_force_z" in columns
    with Results(make(tmp_path, field=False, name="none.h5")) as results:
        assert field_series(results) is None
        numbers = key_numbers(results)
        assert "field_force_total" not in numbers
        figures = build_figures(results)
        assert "fields" not in figures
        assert not any(k.startswith("field") for k in time_series(analyze(results)))


def test_time_series_and_figure(tmp_path):
    with Results(make(tmp_path)) as results:
        data = analyze(results)
        columns = time_series(data)
        figures = build_figures(results, data=data)
    f = forces()
    for k, axis in enumerate("xyz"):
        np.testing.assert_allclose(columns[f"field_force_{axis}"], f[:, :, k].sum(axis=1),
                                   rtol=1e-14, atol=0)
    np.testing.assert_allclose(columns["field_force_mean"],
                               np.linalg.norm(f, axis=2).mean(axis=1), rtol=1e-14)
    assert len(columns["weight_carried_by_fields"]) == 3
    fig = figures["fields"][0]
    assert len(fig.axes) == 2
    lines = fig.axes[0].get_lines()
    np.testing.assert_allclose(lines[2].get_ydata(), f[:, :, 2].sum(axis=1), rtol=1e-14)
    np.testing.assert_allclose(lines[0].get_xdata(), [0.0, 1.0, 2.5], rtol=1e-14)


def test_single_precision_and_integer_flags_are_read_as_double_and_bool(tmp_path):
    """Another writer's file: float32 forces summed in double (as the float64 sums of
    the float32 values), the fixed flags stored as 0/1 bytes."""
    path = make(tmp_path, fixed=None)
    single = forces().astype(np.float32)
    with h5py.File(path, "a") as f:
        del f["particles/field_force"]
        f["particles/field_force"] = single
        f["particles/fixed"] = FIXED.astype(np.uint8)
    with Results(path) as results:
        series = field_series(results)
    exact = single.astype(np.float64)
    np.testing.assert_allclose(series["total"], exact.sum(axis=1), rtol=1e-15, atol=1e-22)
    weight = MASS[~FIXED].sum() * float(GRAVITY @ GRAVITY)
    np.testing.assert_allclose(series["weight_carried"],
                               -(exact.sum(axis=1) @ GRAVITY) / weight, rtol=1e-14)


def test_a_file_without_particles(tmp_path):
    path = tmp_path / "empty.h5"
    with h5py.File(path, "w") as f:
        f["time"] = np.array([0.0, 1e-3])
        f["particles/radius"] = np.zeros(0)
        f["particles/mass"] = np.zeros(0)
        f["particles/position"] = np.zeros((2, 0, 3))
        f["particles/field_force"] = np.zeros((2, 0, 3))
        f["bonds/pairs"] = np.zeros((0, 2), dtype=np.int64)
        f["bonds/active"] = np.zeros((2, 0), dtype=bool)
    with Results(path) as results:
        series = field_series(results)
    assert series["mean"].tolist() == [0.0, 0.0] and series["largest"].tolist() == [0.0, 0.0]
    assert series["total"].tolist() == [[0.0] * 3] * 2

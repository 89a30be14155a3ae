"""Analysis of a real run: a bonded block whose halves fly apart (tests/resultsfile.py).

References: the 33 bonds across the middle plane are the only breakable ones and all of
them break, so the end state is exactly two fragments of 18 equal particles (largest
fraction 1/2) and every broken bond lies on the middle plane. The energy balance
stored(t) - stored(0) = work - losses closes up to the leapfrog's O(dt) error (kinetic
energy at half steps): < 1 % of the initial kinetic energy at safety factor 0.01, and the
error halves when dt halves (first order).
"""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from bondem.analysis import (Results, analyze, broken_bond_fraction, energy_balance,
                             key_numbers, largest_fragment_fraction, radial_breakage,
                             time_series)
from bondem.analysis.figures import build_figures, save_figures
from bondem.analysis.report import write_report
from bondem.cli import main

from resultsfile import record_run, two_halves, write

UNTIL, EVERY = 4e-4, 1e-5


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    import bondem
    glass = bondem.Material(density=2500.0, young_modulus=1e8, name="glass")
    sim, cut = two_halves(glass)
    frames = record_run(sim, UNTIL, EVERY)
    path = write(tmp_path_factory.mktemp("run") / "results.h5", sim.model, frames)
    return path, sim, cut


def test_fragments_and_breakage_of_the_run(run_file):
    path, sim, cut = run_file
    assert not sim.state.bond_active[cut].any() and sim.state.bond_active[~cut].all()
    assert largest_fragment_fraction(path, frame=0) == 1.0
    assert largest_fragment_fraction(path) == pytest.approx(0.5, rel=1e-12)
    assert broken_bond_fraction(path) == pytest.approx(cut.mean(), rel=1e-12)
    with Results(path) as results:
        data = analyze(results)
        radial = radial_breakage(results)
        numbers = key_numbers(results, data)
    fragments, broken = data["fragments"], data["broken"]
    assert fragments["fragments"][0] == 1 and fragments["fragments"][-1] == 2
    assert fragments["largest_count"][-1] == 18
    assert np.all(np.diff(fragments["fragments"]) >= 0)  # bonds never heal
    assert broken["broken"][-1] == cut.sum() == 33
    modes = broken["tension"] + broken["compression"] + broken["shear"]
    assert np.array_equal(modes, broken["broken"]) and not broken["unknown"].any()
    assert broken["tension"][-1] == np.count_nonzero(sim.state.bond_break_mode == 1)
    # every broken bond has its centre on the middle plane x = 3 mm (centre of mass)
    assert radial["centre"][0] == pytest.approx(3e-3, rel=1e-12)
    assert np.array_equal(radial["broken"], cut)
    assert numbers["fragments"] == 2 and numbers["intact_bond_fraction"] == pytest.approx(
        1 - 33 / len(cut))
    assert numbers["frames"] == round(UNTIL / EVERY) + 1


def test_energy_balance_closes_with_damping_and_breakage(run_file):
    path, _, _ = run_file
    with Results(path) as results:
        balance = energy_balance(results)
    terms = balance["terms"]
    initial = terms["kinetic_translational"][0]
    assert balance["reference"] == initial > 0
    # the run must really dissipate and break: otherwise the test proves little
    assert terms["dissipated_damping"][-1] > 0.2 * initial
    assert terms["released_breakage"][-1] > 0.1 * initial
    assert balance["max_relative_error"] < 0.01
    residual = (balance["stored"] - balance["stored"][0] - balance["work"] + balance["losses"])
    assert np.allclose(balance["residual"], residual)


def test_energy_residual_is_first_order_in_the_time_step():
    import bondem
    glass = bondem.Material(density=2500.0, young_modulus=1e8, name="glass")
    errors = []
    for factor in (0.04, 0.02):
        sim, _ = two_halves(glass, safety_factor=factor)
        e0 = sim.energy_terms()
        worst = [0.0]

        def watch(s):
            e = s.energy_terms()
            stored = lambda x: (x["kinetic_translational"] + x["kinetic_rotational"]  # noqa
                                + x["bond_elastic"])
            residual = (stored(e) - stored(e0) - e["work_external"] + e["dissipated_damping"]
                        + e["released_breakage"])
            worst[0] = max(worst[0], abs(residual) / e0["kinetic_translational"])
        sim.run(UNTIL, every=EVERY, callback=watch)
        errors.append(worst[0])
    assert 1.6 < errors[0] / errors[1] < 2.4


def test_figures_and_their_data(run_file, tmp_path):
    path, _, cut = run_file
    with Results(path) as results:
        figures = build_figures(results, frames=(0, -1))
        n_frames = results.n_frames
        series = time_series(analyze(results))
    assert {"fragments", "breakage", "radial", "energy", "size_distribution",
            "bodies"} <= set(figures)
    assert "wall" not in figures  # no walls in this run
    assert len(figures["fragments"][1]["time"]) == n_frames
    assert figures["breakage"][1]["broken"][-1] == cut.sum()
    sizes = figures["size_distribution"][1]
    assert sizes["counts"].tolist() == [18, 18]
    assert sizes["cumulative"] == pytest.approx([0.5, 1.0])
    assert sizes["particles"].tolist() == [18] and sizes["number"].tolist() == [2]
    first, last = figures["bodies"][1]
    assert first["n_fragments"] == 1 and last["n_fragments"] == 2
    left = first["x"] < 3e-3
    assert len(set(last["labels"][left])) == 1 and set(last["labels"][left]) != set(
        last["labels"][~left])
    assert last["x"][~left].min() - last["x"][left].max() > first["x"][~left].min() - \
        first["x"][left].max()  # halves moved apart
    for key in ("time", "fragments", "broken_tension", "energy_residual",
                "energy_kinetic_translational"):
        assert len(series[key]) == n_frames
    written = save_figures(figures, tmp_path / "fig")
    for paths in written.values():
        assert [p.suffix for p in paths] == [".png", ".pdf"]
        assert all(p.stat().st_size > 1000 for p in paths)


def test_report_and_cli(run_file, tmp_path):
    path, _, _ = run_file
    out, numbers = write_report(path, tmp_path / "report.html", frames=(0, 20, -1))
    text = out.read_text()
    assert text.count("data:image/png;base64,") == 6  # bodies, fragments, breakage,
    assert 'id="energy"' in text and 'id="wall"' not in text  # radial, energy, sizes
    assert "<link" not in text and "<script" not in text      # self-contained
    assert numbers["fragments"] == 2
    import h5py
    import shutil
    for periodic, shown in (([False] * 3, False), ([True, False, False], True)):
        copy = shutil.copy(path, tmp_path / f"periodic{sum(periodic)}.h5")
        with h5py.File(copy, "a") as f:
            f.attrs["periodic"], f.attrs["box_length"] = periodic, [7e-3, 1.0, 1.0]
        text = write_report(copy, tmp_path / "box.html", frames=(0,))[0].read_text()
        assert ("box_length" in text) == shown   # the placeholder of a box not periodic
    runner = CliRunner()
    result = runner.invoke(main, ["analyze", str(path), "--out", str(tmp_path / "a"),
                                  "--json"])
    assert result.exit_code == 0, result.output
    printed = json.loads(result.output)
    assert printed["fragments"] == 2 and printed["broken_tension"] + printed[
        "broken_shear"] + printed["broken_compression"] == 33
    assert printed["energy_balance_error"] < 0.01
    header = (tmp_path / "a" / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time" and "largest_fragment_fraction" in header
    table = np.loadtxt(tmp_path / "a" / "timeseries.csv", delimiter=",", skiprows=1)
    assert table.shape == (printed["frames"], len(header))
    assert (tmp_path / "a" / "bodies.pdf").is_file()
    result = runner.invoke(main, ["analyze", str(path), "--out", str(tmp_path / "b")])
    assert result.exit_code == 0 and "largest fragment fraction" in result.output
    result = runner.invoke(main, ["report", str(path), "--out", str(tmp_path / "r.html"),
                                  "--frames", "0,-1"])
    assert result.exit_code == 0 and (tmp_path / "r.html").is_file()
    for bad in ("0,x", "999"):
        result = runner.invoke(main, ["report", str(path), "--frames", bad])
        assert result.exit_code == 2 and "--frames" in result.output
    result = runner.invoke(main, ["analyze", str(tmp_path / "missing.h5")])
    assert result.exit_code == 2 and "missing.h5" in result.output


def test_body_plot_of_fragments_spread_along_one_axis_stays_readable():
    """Fragments 120 mm apart along x and 2 mm tall: the panel keeps its size (not a thin
    strip, as equal axes by shrinking the box drew it) and no two tick labels overlap."""
    from bondem.analysis.figures import plot_bodies
    rng = np.random.default_rng(3)
    x = np.r_[rng.uniform(-0.061, -0.059, 20), rng.uniform(0.059, 0.061, 20)]
    picture = {"x": x, "y": rng.uniform(0.0, 2e-3, 40), "depth": rng.uniform(size=40),
               "radius": np.full(40, 2.5e-4), "labels": np.repeat([0, 1], 20),
               "sizes": np.array([20, 20]), "time": 1e-3, "n_fragments": 2, "view": "xz"}
    fig = plot_bodies([picture, picture])
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        box = ax.get_window_extent()
        assert 0.5 < box.width / box.height < 2.0, (box.width, box.height)
        for axis in (ax.xaxis, ax.yaxis):
            boxes = [t.get_window_extent(renderer) for t in axis.get_ticklabels()
                     if t.get_visible() and t.get_text()]
            assert len(boxes) >= 2
            for a, b in zip(boxes, boxes[1:]):
                assert not a.overlaps(b), (a, b)
        assert ax.get_xlabel() == "x (mm)"
        low, high = ax.get_xlim()
        assert low <= -60.0 and high >= 60.0          # every particle shown, in mm
    import matplotlib.pyplot as plt
    plt.close(fig)


def test_first_break_time_is_the_exact_break_time(run_file):
    path, sim, cut = run_file
    with Results(path) as results:
        numbers = key_numbers(results)
        first_frame = results.time[np.argmax(~results.active().all(axis=1))]
    assert numbers["first_break_time"] == np.nanmin(sim.state.bond_break_time)
    assert numbers["first_break_time"] <= first_frame

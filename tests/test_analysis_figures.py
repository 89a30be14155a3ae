"""The run's figures (bondem.analysis.figures) read back from their artists, on data and
files whose every number is known: what each curve plots in the units on its axes, the
labels and scales a reader relies on, which figures a file gets, the body's discs to
scale with far particles under near ones, fragment colours (grey for loose particles),
and the saved files."""
import matplotlib.colors
import numpy as np
import pytest

from bondem.analysis import Results
from bondem.analysis.figures import (MODE_COLOURS, body_picture_data, build_figures,
                                     fragment_colours, plot_bodies, plot_breakage,
                                     plot_energy, plot_fields, plot_fragments, plot_radial,
                                     plot_size_distribution, plot_wall, save_figures)

from resultsfile import write_static

TIME = np.array([0.0, 2e-4, 5e-4, 9e-4])


def _lines(ax):
    return {line.get_label(): line for line in ax.get_lines()}


def _rgb(artist_colour):
    return tuple(np.round(matplotlib.colors.to_rgb(artist_colour), 6))


def test_fragments_against_time_on_two_axes():
    series = {"time": TIME, "fragments": np.array([1, 2, 5, 9]),
              "fragments_multi": np.array([1, 2, 2, 3]),
              "largest_fraction": np.array([1.0, 0.7, 0.55, 0.4])}
    fig = plot_fragments(series)
    assert tuple(fig.get_size_inches()) == (6.0, 3.6)
    ax, right = fig.axes
    lines = _lines(ax)
    assert list(lines) == ["all fragments", "fragments of 2+ particles"]
    np.testing.assert_allclose(lines["all fragments"].get_xdata(), TIME * 1e3, rtol=1e-15)
    assert lines["all fragments"].get_ydata().tolist() == [1, 2, 5, 9]
    assert lines["fragments of 2+ particles"].get_ydata().tolist() == [1, 2, 2, 3]
    assert lines["fragments of 2+ particles"].get_linestyle() == "--"
    assert all(line.get_drawstyle() == "steps-post" for line in ax.get_lines())
    assert _rgb(lines["all fragments"].get_color()) == _rgb("tab:blue")
    assert _rgb(lines["fragments of 2+ particles"].get_color()) == _rgb("tab:cyan")
    largest = right.get_lines()[0]
    assert largest.get_label() == "largest fragment"
    assert largest.get_ydata().tolist() == [1.0, 0.7, 0.55, 0.4]
    assert right.get_ylim() == (0.0, 1.05)
    assert ax.get_xlabel() == "time (ms)" and ax.get_ylabel() == "fragments"
    assert right.get_ylabel() == "largest fragment mass fraction"
    legend = ax.get_legend()
    assert [t.get_text() for t in legend.get_texts()] == [
        "all fragments", "fragments of 2+ particles", "largest fragment"]
    assert legend._loc == 7   # center right


def test_broken_bonds_by_mode_only_those_that_broke():
    series = {"time": TIME, "broken": np.array([0, 1, 4, 6]),
              "tension": np.array([0, 1, 3, 4]), "compression": np.zeros(4, int),
              "shear": np.array([0, 0, 1, 2]), "unknown": np.zeros(4, int)}
    fig = plot_breakage(series)
    ax = fig.axes[0]
    lines = _lines(ax)
    assert list(lines) == ["all", "tension", "shear"]
    assert lines["all"].get_ydata().tolist() == [0, 1, 4, 6]
    assert lines["shear"].get_ydata().tolist() == [0, 0, 1, 2]
    np.testing.assert_allclose(lines["tension"].get_xdata(), TIME * 1e3, rtol=1e-15)
    for name in ("tension", "shear"):
        assert _rgb(lines[name].get_color()) == _rgb(MODE_COLOURS[name])
    assert _rgb(lines["all"].get_color()) == (0.0, 0.0, 0.0)
    assert ax.get_ylabel() == "broken bonds" and ax.get_xlabel() == "time (ms)"
    series["unknown"] = np.array([0, 0, 0, 1])
    assert "unknown" in _lines(plot_breakage(series).axes[0])


def test_the_energy_balance_and_its_residual():
    balance = {"time": TIME, "terms": {"kinetic_translational": np.array([4.0, 3, 2, 1]),
                                       "bond_elastic": np.array([0.0, 0.5, 1.0, 0.5]),
                                       "work_walls": np.zeros(4)},
               "stored": np.array([4.0, 3.5, 3.0, 1.5]), "work": np.array([0, 0.1, 0.2, 0.3]),
               "losses": np.array([0.0, 0.4, 0.8, 2.0]),
               "relative_error": np.array([0.0, 0.01, -0.02, 0.05])}
    fig = plot_energy(balance)
    assert tuple(fig.get_size_inches()) == (6.0, 5.5)
    ax, low = fig.axes
    lines = _lines(ax)
    # the terms that are not all zero, in alphabetical order, then the balance
    assert list(lines) == ["bond elastic", "kinetic translational", "stored",
                           "stored - work + losses"]
    np.testing.assert_allclose(lines["stored - work + losses"].get_ydata(),
                               [4.0, 3.8, 3.6, 3.2], rtol=1e-15)
    assert lines["stored - work + losses"].get_linestyle() == ":"
    np.testing.assert_allclose(low.get_lines()[0].get_ydata(), [0, 1, -2, 5], rtol=1e-12)
    np.testing.assert_allclose(low.get_lines()[0].get_xdata(), TIME * 1e3, rtol=1e-15)
    assert ax.get_ylabel() == "energy (J)" and low.get_ylabel() == "residual (%)"
    assert low.get_xlabel() == "time (ms)"


def test_the_fields_force_and_the_weight_it_carries():
    series = {"time": TIME, "total": np.array([[0, 0, 1e-3], [1e-4, 0, 2e-3],
                                               [2e-4, -1e-4, 3e-3], [0, 0, 4e-3]]),
              "mean": np.array([1e-5, 2e-5, 3e-5, 4e-5]),
              "weight_carried": np.array([0.25, 0.5, 0.75, 1.0])}
    fig = plot_fields(series)
    assert tuple(fig.get_size_inches()) == pytest.approx((6.0, 2.6 + 3.8))
    top, low = fig.axes
    lines = _lines(top)
    assert list(lines) == ["total x", "total y", "total z", "mean |F| per particle"]
    assert lines["total y"].get_ydata().tolist() == [0, 0, -1e-4, 0]
    assert lines["mean |F| per particle"].get_ydata().tolist() == [1e-5, 2e-5, 3e-5, 4e-5]
    assert low.get_lines()[0].get_ydata().tolist() == [0.25, 0.5, 0.75, 1.0]
    assert np.asarray(low.get_lines()[1].get_ydata()).tolist() == [1.0, 1.0]   # held up
    assert top.get_ylabel() == "fluid/field force (N)"
    assert low.get_ylabel() == "weight carried (-)" and low.get_xlabel() == "time (ms)"
    series["weight_carried"] = None
    fig = plot_fields(series)
    assert len(fig.axes) == 1 and fig.axes[0].get_xlabel() == "time (ms)"
    assert tuple(fig.get_size_inches()) == pytest.approx((6.0, 4.5))


def _curve(**changes):
    curve = {"wall": 1, "partner": 0, "time": TIME,
             "displacement": np.array([0.0, 1e-4, 2e-4, 3e-4]),
             "force": np.array([0.0, 2.0, 5.0, 3.0]),
             "force_wall": np.array([0.0, 2.2, 5.5, 3.0]),
             "force_partner": np.array([0.0, 1.8, 4.5, 3.0]),
             "displacement_at_peak_force": 2.5e-4, "peak_time": 6e-4, "peak_force": 5.5,
             "first_break_index": 2}
    curve.update(changes)
    return curve


def test_the_wall_force_against_the_gap_its_travel_or_time():
    ax = plot_wall(_curve()).axes[0]
    lines = _lines(ax)
    assert list(lines) == ["wall 1 (loading)", "wall 0", "mean of both", "peak 5.5 N",
                           "first broken bond"]
    np.testing.assert_allclose(lines["mean of both"].get_xdata(), [0, 0.1, 0.2, 0.3],
                               rtol=1e-12)
    assert lines["wall 0"].get_ydata().tolist() == [0.0, 1.8, 4.5, 3.0]
    # the peak between frames, from the history; the first break at its frame
    assert lines["peak 5.5 N"].get_xdata() == pytest.approx(0.25)
    assert lines["peak 5.5 N"].get_marker() == "v"
    assert lines["first broken bond"].get_xdata() == pytest.approx(0.2)
    assert lines["first broken bond"].get_ydata() == pytest.approx(5.0)
    assert ax.get_xlabel() == "displacement: decrease of the plate gap (mm)"
    assert ax.get_ylabel() == "compressive force (N)"
    ax = plot_wall(_curve(partner=None, first_break_index=None)).axes[0]
    assert list(_lines(ax)) == ["_child0", "peak 5.5 N"]
    assert ax.get_xlabel() == "travel of wall 1 (mm)"
    # a wall that stays: |F| against time
    ax = plot_wall(_curve(partner=None, displacement=np.zeros(4))).axes[0]
    lines = _lines(ax)
    np.testing.assert_allclose(lines["_child0"].get_xdata(), TIME * 1e3, rtol=1e-15)
    assert lines["peak 5.5 N"].get_xdata() == pytest.approx(0.6)
    assert lines["first broken bond"].get_xdata() == pytest.approx(0.5)
    assert ax.get_xlabel() == "time (ms)" and ax.get_ylabel() == "|force| on wall 1 (N)"


def test_the_size_distribution_on_linear_and_logarithmic_counts():
    data = {"time": 1.5e-3, "masses": np.array([1e-9, 2e-9, 7e-9]),
            "cumulative": np.array([0.1, 0.3, 1.0]), "particles": np.array([1, 2, 7]),
            "number": np.array([5, 2, 1]), "counts": np.array([7, 2, 2, 1, 1, 1, 1, 1])}
    fig = plot_size_distribution(data)
    assert tuple(fig.get_size_inches()) == (8.0, 3.6)
    assert fig._suptitle.get_text() == "t = 1.5 ms, 3 fragments"
    ax, right = fig.axes
    sieve = ax.get_lines()[0]
    assert sieve.get_xdata().tolist() == [1e-9, 1e-9, 2e-9, 7e-9]
    assert sieve.get_ydata().tolist() == [0.0, 0.1, 0.3, 1.0]
    assert ax.get_xscale() == "log" and ax.get_ylim() == (0.0, 1.05)
    assert ax.get_xlabel() == "fragment mass (kg)"
    assert ax.get_ylabel() == "cumulative mass fraction"
    bars = right.patches
    assert [b.get_height() for b in bars] == [5, 2, 1]
    assert [b.get_x() + b.get_width() / 2 for b in bars] == pytest.approx([1, 2, 7])
    assert right.get_xscale() == "linear" and right.get_xlabel() == "particles per fragment"
    assert right.get_ylabel() == "fragments"
    # above 20 particles: bars of equal width on a logarithmic axis, each about its count
    data.update(particles=np.array([1, 30, 400]), number=np.array([9, 2, 1]))
    right = plot_size_distribution(data).axes[1]
    assert right.get_xscale() == "log"
    for bar, count in zip(right.patches, (1, 30, 400)):
        assert bar.get_x() == pytest.approx(count / 1.25, rel=1e-12)
        assert bar.get_x() + bar.get_width() == pytest.approx(count * 1.25, rel=1e-12)


def test_radial_breakage_bars_per_shell():
    radial = {"edges": np.array([0.0, 0.25, 0.5, 0.75, 1.0]),
              "broken_fraction": np.array([0.0, 0.1, np.nan, 0.6])}
    ax = plot_radial(radial).axes[0]
    assert [b.get_height() for b in ax.patches] == [0.0, 0.1, 0.0, 0.6]
    assert [b.get_x() for b in ax.patches] == [0.0, 0.25, 0.5, 0.75]
    assert [b.get_width() for b in ax.patches] == [0.25] * 4
    assert ax.get_xlim() == (0.0, 1.0) and ax.get_ylabel() == "fraction of bonds broken"


def test_fragment_colours_skip_grey_and_leave_loose_particles_grey():
    labels = np.array([0, 1, 0, 2, 8, 9])
    sizes = np.array([2, 1, 3, 1, 1, 1, 1, 1, 4, 2])
    colours = fragment_colours(labels, sizes)
    palette = [c for k, c in enumerate(matplotlib.colormaps["tab10"].colors) if k != 7]
    assert colours[0].tolist() == [*palette[0], 1.0] == colours[2].tolist()
    assert colours[1].tolist() == [0.75, 0.75, 0.75, 1.0]   # fragment 1: one particle
    assert colours[3].tolist() == [*palette[2], 1.0]        # fragment 2: three
    assert colours[4].tolist() == [*palette[8], 1.0]
    assert colours[5].tolist() == [*palette[0], 1.0]        # the ninth colour wraps


def _two_pieces(path, frames=2):
    """Three particles off the origin, bonded 0-1 and 1-2; bond 1-2 broken at frame 1;
    masses 1, 2, 4 ug."""
    position = np.array([[1e-3, 2e-3, 3e-3], [2e-3, 1e-3, 5e-3], [4e-3, 6e-3, 2e-3]])
    return write_static(path, position, np.array([3e-4, 4e-4, 5e-4]), [[0, 1], [1, 2]],
                        [[True, True], [True, False]][:frames], time=TIME[:frames],
                        mass=np.array([1e-9, 2e-9, 4e-9]), break_mode=[0, 1])


def test_body_pictures_project_on_the_view_and_draw_far_particles_first(tmp_path):
    path = _two_pieces(tmp_path / "r.h5")
    with Results(path) as results:
        xz = body_picture_data(results, -1)
        yz = body_picture_data(results, 0, view="yz")
    assert xz["x"].tolist() == [1e-3, 2e-3, 4e-3] and xz["y"].tolist() == [3e-3, 5e-3, 2e-3]
    assert xz["depth"].tolist() == [2e-3, 1e-3, 6e-3]
    assert xz["time"] == 2e-4 and xz["n_fragments"] == 2 and xz["view"] == "xz"
    assert xz["labels"].tolist() == [1, 1, 0] and xz["sizes"].tolist() == [1, 2]
    assert yz["x"].tolist() == [2e-3, 1e-3, 6e-3] and yz["depth"].tolist() == [1e-3, 2e-3,
                                                                               4e-3]
    assert yz["n_fragments"] == 1
    fig = plot_bodies([yz, xz])
    assert tuple(fig.get_size_inches()) == pytest.approx((7.2, 3.8))
    left, right = fig.axes
    discs = right.collections[0]
    # deepest first (y = 6, 2, 1 mm): particles 2, 0, 1
    np.testing.assert_allclose(discs.get_offsets(), [[4, 2], [1, 3], [2, 5]], rtol=1e-12)
    np.testing.assert_allclose(discs._widths * 2, [1.0, 0.6, 0.8], rtol=1e-12)
    colours = fragment_colours(xz["labels"], xz["sizes"])[[2, 0, 1]]
    np.testing.assert_allclose(discs.get_facecolor(), colours)
    assert right.get_title() == "t = 0.2 ms, 2 fragments"
    assert right.get_xlabel() == "x (mm)" and right.get_ylabel() == "z (mm)"
    assert left.get_xlabel() == "y (mm)" and left.get_title() == "t = 0 ms, 1 fragments"
    # every disc inside the drawn range
    x0, x1 = right.get_xlim()
    assert x0 <= 1.0 - 0.3 and x1 >= 4.0 + 0.5


def test_a_file_gets_the_figures_that_apply_and_they_are_saved(tmp_path):
    path = _two_pieces(tmp_path / "r.h5")
    with Results(path) as results:
        figures = build_figures(results, frames=(0, 1, -1))
    assert set(figures) == {"fragments", "breakage", "radial", "size_distribution", "bodies"}
    sizes = figures["size_distribution"][1]
    assert sizes["masses"].tolist() == pytest.approx([3e-9, 4e-9], rel=1e-12)
    assert sizes["time"] == 2e-4
    np.testing.assert_allclose(sizes["cumulative"], [3 / 7, 1.0], rtol=1e-12)
    assert sizes["particles"].tolist() == [1, 2] and sizes["number"].tolist() == [1, 1]
    assert sizes["counts"].tolist() == [1, 2]
    assert [p["time"] for p in figures["bodies"][1]] == [0.0, 2e-4, 2e-4]
    written = save_figures(figures, tmp_path / "a" / "b", formats=("png", "pdf"))
    assert written["radial"] == [tmp_path / "a" / "b" / "radial.png",
                                 tmp_path / "a" / "b" / "radial.pdf"]
    header = written["radial"][0].read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n"
    assert (int.from_bytes(header[16:20], "big"), int.from_bytes(header[20:24], "big")) == (
        720, 432)   # 6 x 3.6 inches at 120 dpi
    assert written["radial"][1].read_bytes()[:5] == b"%PDF-"
    # without bonds: no breakage or radial figures
    bare = write_static(tmp_path / "bare.h5", [[0, 0, 0], [1e-3, 0, 0]], 3e-4,
                        np.zeros((0, 2)), np.zeros((1, 0), bool), mass=np.ones(2))
    with Results(bare) as results:
        assert set(build_figures(results)) == {"fragments", "size_distribution", "bodies"}


def props(line):
    """What a reader sees of a line: colour (RGB), width, style, marker and its size,
    steps."""
    return (_rgb(line.get_color()), line.get_linewidth(), line.get_linestyle(),
            line.get_marker(), line.get_markersize(), line.get_drawstyle())


def _integer_ticks(axis):
    return axis.get_major_locator()._integer


def _constrained(fig):
    return type(fig.get_layout_engine()).__name__ == "ConstrainedLayoutEngine"


def _legend_style(ax):
    legend = ax.get_legend()
    return {t.get_fontsize() for t in legend.get_texts()}, legend._ncols


STEP, PLAIN = "steps-post", "default"


def test_the_figures_look_as_designed():
    """Colours, widths, styles and markers of every line, legends, layouts and tick rules:
    what distinguishes the curves of one figure from each other in print."""
    series = {"time": TIME, "fragments": np.array([1, 2, 5, 9]),
              "fragments_multi": np.array([1, 2, 2, 3]),
              "largest_fraction": np.array([1.0, 0.7, 0.55, 0.4])}
    fig = plot_fragments(series)
    ax, right = fig.axes
    lines = _lines(ax)
    assert props(lines["all fragments"]) == (_rgb("tab:blue"), 1.5, "-", "None", 6.0, STEP)
    assert props(lines["fragments of 2+ particles"]) == (_rgb("tab:cyan"), 1.5, "--", "None",
                                                         6.0, STEP)
    assert props(right.get_lines()[0]) == (_rgb("tab:red"), 1.5, "-", "None", 6.0, STEP)
    assert _rgb(right.yaxis.label.get_color()) == _rgb("tab:red")
    assert _integer_ticks(ax.yaxis) and _constrained(fig)
    assert _legend_style(ax) == ({8.0}, 1)

    series = {"time": TIME, "broken": np.array([0, 1, 4, 6]),
              "tension": np.array([0, 1, 3, 4]), "compression": np.array([0, 0, 0, 1]),
              "shear": np.array([0, 0, 1, 2]), "unknown": np.array([0, 0, 0, 1])}
    fig = plot_breakage(series)
    ax = fig.axes[0]
    lines = _lines(ax)
    assert props(lines["all"]) == ((0.0, 0.0, 0.0), 1.5, "-", "None", 6.0, STEP)
    for name in ("tension", "compression", "shear", "unknown"):
        assert props(lines[name]) == (_rgb(MODE_COLOURS[name]), 1.5, "-", "None", 6.0, STEP)
    assert _integer_ticks(ax.yaxis) and _constrained(fig)
    assert _legend_style(ax) == ({8.0}, 1)
    assert tuple(fig.get_size_inches()) == (6.0, 3.6)

    balance = {"time": TIME, "terms": {"kinetic_translational": np.array([4.0, 3, 2, 1])},
               "stored": np.array([4.0, 3.5, 3.0, 1.5]), "work": np.zeros(4),
               "losses": np.zeros(4), "relative_error": np.zeros(4)}
    fig = plot_energy(balance)
    ax, low = fig.axes
    lines = _lines(ax)
    np.testing.assert_allclose(lines["kinetic translational"].get_xdata(), TIME * 1e3)
    assert lines["kinetic translational"].get_linewidth() == 1.0
    assert props(lines["stored"]) == ((0.0, 0.0, 0.0), 2.0, "-", "None", 6.0, PLAIN)
    np.testing.assert_allclose(lines["stored"].get_xdata(), TIME * 1e3)
    assert props(lines["stored - work + losses"]) == ((0.0, 0.0, 0.0), 2.0, ":", "None", 6.0,
                                                      PLAIN)
    np.testing.assert_allclose(lines["stored - work + losses"].get_xdata(), TIME * 1e3)
    assert _rgb(low.get_lines()[0].get_color()) == _rgb("tab:purple")
    assert _legend_style(ax) == ({7.0}, 2) and _constrained(fig)
    # the residual's panel a third as tall, on the same time axis
    assert ax.get_position().height == pytest.approx(3 * low.get_position().height, rel=0.05)
    assert low.get_shared_x_axes().joined(ax, low)

    series = {"time": TIME, "total": np.zeros((4, 3)), "mean": np.zeros(4),
              "weight_carried": np.full(4, 0.5)}
    fig = plot_fields(series)
    top, low = fig.axes
    lines = _lines(top)
    for axis in "xyz":
        assert lines[f"total {axis}"].get_linewidth() == 1.2
        np.testing.assert_allclose(lines[f"total {axis}"].get_xdata(), TIME * 1e3)
    assert props(lines["mean |F| per particle"]) == ((0.0, 0.0, 0.0), 1.0, "--", "None", 6.0,
                                                     PLAIN)
    np.testing.assert_allclose(lines["mean |F| per particle"].get_xdata(), TIME * 1e3)
    carried, full = low.get_lines()
    assert _rgb(carried.get_color()) == _rgb("tab:purple")
    np.testing.assert_allclose(carried.get_xdata(), TIME * 1e3)
    assert props(full)[:3] == (_rgb("0.6"), 0.8, ":")
    assert _legend_style(top) == ({7.0}, 2) and _constrained(fig)
    assert low.get_shared_x_axes().joined(top, low)

    ax = plot_wall(_curve()).axes[0]
    lines = _lines(ax)
    assert props(lines["wall 1 (loading)"])[:3] == (_rgb("tab:blue"), 0.8, "-")
    assert props(lines["wall 0"])[:3] == (_rgb("tab:green"), 0.8, "-")
    np.testing.assert_allclose(lines["wall 0"].get_xdata(), [0, 0.1, 0.2, 0.3])
    np.testing.assert_allclose(lines["wall 1 (loading)"].get_xdata(), [0, 0.1, 0.2, 0.3])
    assert props(lines["mean of both"])[:3] == ((0.0, 0.0, 0.0), 1.5, "-")
    assert props(lines["peak 5.5 N"])[:5] == (_rgb("tab:red"), 1.5, "None", "v", 9.0)
    assert props(lines["first broken bond"])[:5] == (_rgb("tab:orange"), 1.5, "None", "o",
                                                     8.0)
    assert _legend_style(ax) == ({8.0}, 1)
    fig = plot_wall(_curve(partner=None))
    assert props(fig.axes[0].get_lines()[0])[:3] == ((0.0, 0.0, 0.0), 1.5, "-")
    assert tuple(fig.get_size_inches()) == (6.0, 3.6) and _constrained(fig)

    data = {"time": 1e-3, "masses": np.array([1e-9, 2e-9]), "cumulative": np.array([0.3, 1.0]),
            "particles": np.array([1, 20]), "number": np.array([5, 1]),
            "counts": np.array([20, 1, 1, 1, 1, 1])}
    fig = plot_size_distribution(data)
    ax, right = fig.axes
    assert props(ax.get_lines()[0]) == (_rgb("tab:blue"), 1.5, "-", ".", 6.0, STEP)
    assert [a.get_subplotspec().get_geometry() for a in (ax, right)] == [(1, 2, 0, 0),
                                                                         (1, 2, 1, 1)]
    # twenty particles at most: plain bars at the counts, integer ticks
    for bar in right.patches:
        assert _rgb(bar.get_facecolor()) == _rgb("tab:orange")
        assert tuple(bar.get_edgecolor()) == (0.0, 0.0, 0.0, 1.0)   # drawn, black
    assert right.get_xscale() == "linear" and _integer_ticks(right.xaxis)
    assert _integer_ticks(right.yaxis) and fig._suptitle.get_fontsize() == 9.0
    assert _constrained(fig)
    data["particles"] = np.array([1, 21])
    right = plot_size_distribution(data).axes[1]
    assert right.get_xscale() == "log"
    assert right.xaxis.get_major_locator()._base == 10.0
    assert right.xaxis.get_major_formatter().fmt == "%d"
    assert _rgb(right.patches[0].get_facecolor()) == _rgb("tab:orange")
    assert tuple(right.patches[0].get_edgecolor()) == (0.0, 0.0, 0.0, 1.0)

    radial = {"edges": np.array([0.0, 0.5, 1.0]), "broken_fraction": np.array([0.2, 0.4])}
    fig = plot_radial(radial)
    ax = fig.axes[0]
    assert _rgb(ax.patches[0].get_facecolor()) == _rgb("tab:orange")
    assert tuple(ax.patches[0].get_edgecolor()) == (0.0, 0.0, 0.0, 1.0)
    assert ax.get_xlabel() == "bond position r / R (centre of mass to outer radius, t = 0)"
    assert _constrained(fig)


def test_the_body_is_drawn_to_scale_in_tight_limits():
    """Particles spread along the vertical axis: its limits are the discs' extremes
    exactly (no margin), the horizontal ones widened about them for equal scales; discs
    edged in black, their diameters in data units; four and five ticks; no grey among
    fragments of several particles."""
    n = 10
    picture = {"time": 1e-3, "x": np.linspace(0, 1e-3, n), "y": np.linspace(0, 9e-3, n),
               "depth": np.arange(n) * 1e-4, "radius": np.full(n, 2.5e-4),
               "labels": np.arange(n), "sizes": np.full(n, 2), "n_fragments": n,
               "view": "xz"}
    fig = plot_bodies([picture])
    ax = fig.axes[0]
    fig.canvas.draw()
    assert ax.get_ylim() == pytest.approx((-0.25, 9.25), rel=1e-9)
    x0, x1 = ax.get_xlim()
    assert x0 < -0.25 and x1 > 1.25
    assert (x1 - x0) == pytest.approx(9.5 * ax.bbox.width / ax.bbox.height, rel=1e-6)
    discs = ax.collections[0]
    assert _rgb(discs.get_edgecolor()[0]) == (0.0, 0.0, 0.0)
    assert discs.get_linewidths().tolist() == [0.3]
    assert discs.get_offset_transform() is ax.transData
    assert discs._units == "xy"    # diameters in data units (mm), not points
    grey = _rgb(matplotlib.colormaps["tab10"].colors[7])
    assert grey not in {_rgb(c) for c in discs.get_facecolor()}
    assert len({_rgb(c) for c in discs.get_facecolor()}) == 9   # the palette's nine
    assert ax.xaxis.get_major_locator()._nbins == 4
    assert ax.yaxis.get_major_locator()._nbins == 5
    assert ax.title.get_fontsize() == 9.0 and _constrained(fig)


def test_every_figure_of_a_file_with_walls_energy_and_fields(tmp_path):
    """A file with walls, energy terms and field forces gets their figures, each with the
    data the analysis gives; the bodies in the view asked for; saved twice in one
    folder."""
    from bondem.analysis import analyze
    path = _two_pieces(tmp_path / "r.h5", frames=2)
    import h5py
    with h5py.File(path, "a") as f:
        f["walls/force"] = np.array([[[0, 0, 1.0]], [[0, 0, 2.0]]])
        f["walls/position"] = np.array([[[0, 0, 0.0]], [[0, 0, 1e-4]]])
        f["energy/kinetic_translational"] = np.array([1e-6, 0.5e-6])
        f["particles/field_force"] = np.ones((2, 3, 3)) * 1e-6
    with Results(path) as results:
        data = analyze(results)
        figures = build_figures(results, frames=(0,), view="xy", data=data)
    assert set(figures) == {"fragments", "breakage", "radial", "energy", "wall", "fields",
                            "size_distribution", "bodies"}
    for name in ("energy", "wall", "fields"):
        assert figures[name][1] is data[name]
        assert isinstance(figures[name][0], matplotlib.figure.Figure)
    assert figures["energy"][0].axes[0].get_ylabel() == "energy (J)"
    assert figures["wall"][0].axes[0].get_ylabel() == "compressive force (N)"
    assert figures["fields"][0].axes[0].get_ylabel() == "fluid/field force (N)"
    picture, = figures["bodies"][1]
    assert picture["view"] == "xy" and picture["y"].tolist() == [2e-3, 1e-3, 6e-3]
    for _ in range(2):
        written = save_figures(figures, tmp_path / "figs", formats=("png",))
    assert sorted(written) == sorted(figures)

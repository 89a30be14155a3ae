"""A lab test's files and figures (bondem.lab.output) from constructed results: lab.csv and
lab.json read back exactly (units in the header, NaN as null, NumPy integers as
integers), the tables' units, and each figure's data read from its artists: the curve in
the units on its axes, the peak where the stress is largest (not at an end), one crack
curve per mode, the sieve curve, the AE counts and Aki's line, the failure picture's
slice one particle diameter either side of the middle, its force chains by magnitude."""
import csv
import json
import math

import numpy as np
import pytest

from bondem.lab.cracks import b_value
from bondem.lab.output import (CAPTIONS, MODE_COLOURS, build_lab_figures, particle_modes,
                               write_result)
from bondem.lab.procedures import UNITS, LabResult

STRAIN = np.array([0.0, 1e-3, 2e-3, 3e-3, 4e-3, 5e-3])
STRESS = np.array([0.0, 0.7e6, 1.3e6, 1.1e6, 0.6e6, 0.2e6])     # peak at the third sample


def ucs_result(**changes):
    curve = {"time": STRAIN * 10.0, "axial_strain": STRAIN, "platen_strain": 1.25 * STRAIN,
             "axial_stress": STRESS, "volumetric_strain": np.array([0, 4, 6, 5, 2, -3]) * 1e-4,
             "broken_tension": np.array([0.0, 0, 2, 9, 15, 20]),
             "broken_compression": np.array([0.0, 0, 0, 1, 1, 2]),
             "broken_shear": np.array([0.0, 1, 1, 3, 7, 8]),
             "kinetic_ratio": np.array([0.0, 1e-3, 2e-3, 0.5, 0.25, 0.125])}
    numbers = {"ucs": np.float64(1.3e6), "steps": np.int64(9280), "poisson_ratio": math.nan,
               "young_modulus_secant": 7e8, "crack_initiation_stress": np.float32(0.5e6)}
    fields = dict(test="ucs", curve=curve, numbers=numbers, units=UNITS,
                  settings={"strain_rate": 20.0, "damping": 0.7}, notes=["stopped: post-peak"])
    fields.update(changes)
    return LabResult(**fields)


def test_lab_csv_and_json_hold_the_curve_and_numbers_exactly(tmp_path):
    result = ucs_result()
    result.curve["odd_column"] = np.array([1 / 3, 2 / 3, 1.0, 4 / 3, 5 / 3, 2.0])
    out = tmp_path / "a" / "b"
    for _ in range(2):   # a folder two levels down, written twice
        paths = write_result(result, out, figures=False)
    assert paths == {"csv": out / "lab.csv", "json": out / "lab.json"}
    with open(out / "lab.csv", newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["time (s)", "axial_strain (1)", "platen_strain (1)",
                       "axial_stress (Pa)", "volumetric_strain (1)", "broken_tension (1)",
                       "broken_compression (1)", "broken_shear (1)", "kinetic_ratio (1)",
                       "odd_column (1)"]
    assert len(rows) == 7
    table = np.array([[float(v) for v in row] for row in rows[1:]])
    for k, column in enumerate(result.curve):
        assert table[:, k].tolist() == result.curve[column].tolist(), column
    data = json.loads((out / "lab.json").read_text())
    assert data["test"] == "ucs"
    assert data["numbers"] == {"ucs": 1.3e6, "steps": 9280, "poisson_ratio": None,
                               "young_modulus_secant": 7e8,
                               "crack_initiation_stress": float(np.float32(0.5e6))}
    assert type(data["numbers"]["steps"]) is int
    assert data["units"] == {"ucs": "Pa", "steps": "1", "poisson_ratio": "1",
                             "young_modulus_secant": "Pa", "crack_initiation_stress": "Pa"}
    assert data["settings"] == {"strain_rate": 20.0, "damping": 0.7}
    assert data["notes"] == ["stopped: post-peak"]
    assert data["failed"] is True and data["no_failure"] is None
    assert data["captions"] == CAPTIONS
    assert (out / "lab.json").read_text().startswith('{\n  "test": "ucs",\n  "numbers": {\n')
    # no samples: a header of no columns, and no figures
    write_result(ucs_result(curve={}), tmp_path / "empty", figures=False)
    assert (tmp_path / "empty" / "lab.csv").read_bytes() == b"\r\n"
    # a test that did not fail, with numbers nested in lists and dicts
    result = ucs_result(no_failure="strain limit",
                        numbers={"pair": (np.int32(3), np.float64(math.inf)),
                                 "nested": {"a": [np.int64(2), 0.5, math.nan]}},
                        units={})
    write_result(result, tmp_path / "c", figures=False)
    data = json.loads((tmp_path / "c" / "lab.json").read_text())
    assert data["failed"] is False and data["no_failure"] == "strain limit"
    assert data["numbers"] == {"pair": [3, None], "nested": {"a": [2, 0.5, None]}}
    assert data["units"] == {"pair": "", "nested": ""}


def test_the_tables_carry_their_units(tmp_path):
    cracks = {"time": np.array([1e-4, 2e-4]), "x": np.array([1e-3, -2e-3]),
              "mode": np.array([1.0, 3.0]), "energy": np.array([1e-9, 3e-9]),
              "twisting_moment": np.array([1e-6, 0.0]), "event": np.array([0.0, 0.0])}
    ae = {"time": np.array([1e-4]), "energy": np.array([4e-9]), "magnitude": np.array([-8.2]),
          "cracks": np.array([2.0])}
    fragments = {"particles": np.array([40.0, 1.0]), "mass": np.array([2e-5, 5e-7]),
                 "size": np.array([3e-3, 1e-3]), "shape_factor": np.array([0.9, 1.0])}
    result = ucs_result(cracks=cracks, ae=ae, fragments=fragments)
    paths = write_result(result, tmp_path, figures=False)
    expected = {"cracks_csv": ("lab_cracks.csv", cracks, "time (s),x (m),mode (1),energy (J),"
                               "twisting_moment (N m),event (1)"),
                "ae_csv": ("lab_ae.csv", ae, "time (s),energy (J),magnitude (1),cracks (1)"),
                "fragments_csv": ("lab_fragments.csv", fragments,
                                  "particles (1),mass (kg),size (m),shape_factor (1)")}
    for key, (name, table, header) in expected.items():
        assert paths[key] == tmp_path / name
        with open(tmp_path / name, newline="") as handle:
            rows = list(csv.reader(handle))
        assert ",".join(rows[0]) == header
        values = np.array([[float(v) for v in row] for row in rows[1:]])
        np.testing.assert_array_equal(values, np.column_stack(list(table.values())))
    assert (tmp_path / "lab_cracks.csv").read_text().count("\n") == 3
    # a log without columns: a header of none
    write_result(ucs_result(cracks={}), tmp_path / "none", figures=False)
    assert (tmp_path / "none" / "lab_cracks.csv").read_bytes() == b"\r\n"


def _line(ax, label):
    found = [line for line in ax.lines if line.get_label() == label]
    assert len(found) == 1, [line.get_label() for line in ax.lines]
    return np.asarray(found[0].get_xdata(), float), np.asarray(found[0].get_ydata(), float)


def _style(ax, label):
    """(line style, marker, colour as RGB) of the one line labelled ``label``."""
    import matplotlib.colors
    line, = [line for line in ax.lines if line.get_label() == label]
    return (line.get_linestyle(), line.get_marker(),
            tuple(matplotlib.colors.to_rgb(line.get_color())))


def test_the_stress_strain_volumetric_and_crack_figures_read_back():
    figures = build_lab_figures(ucs_result())
    assert set(figures) == {"stress_strain", "volumetric", "cracks"}
    ax = figures["stress_strain"].axes[0]
    x, y = _line(ax, "gauge")
    np.testing.assert_allclose(x, STRAIN * 100.0, rtol=1e-15)
    np.testing.assert_allclose(y, STRESS * 1e-6, rtol=1e-15)
    x, y = _line(ax, "platens")
    np.testing.assert_allclose(x, 125.0 * STRAIN, rtol=1e-15)
    x, y = _line(ax, "peak 1.3 MPa")
    assert x.tolist() == pytest.approx([0.2]) and y.tolist() == pytest.approx([1.3])
    assert ax.get_xlabel() == "axial strain (%)" and ax.get_ylabel() == "axial stress (MPa)"
    import matplotlib.colors
    assert _style(ax, "gauge")[0] == "-" and _style(ax, "platens")[0] == "--"
    assert _style(ax, "peak 1.3 MPa") == ("None", "o", matplotlib.colors.to_rgb("C3"))
    assert tuple(figures["stress_strain"].get_size_inches()) == (6.0, 4.0)
    ax = figures["volumetric"].axes[0]
    x, y = ax.lines[0].get_xdata(), ax.lines[0].get_ydata()
    np.testing.assert_allclose(x, STRAIN * 100.0, rtol=1e-15)
    np.testing.assert_allclose(y, [0, 0.04, 0.06, 0.05, 0.02, -0.03], rtol=1e-12)
    assert ax.get_xlabel() == "axial strain (%)"
    assert ax.get_ylabel() == "volumetric strain (%)"
    ax = figures["cracks"].axes[0]
    result = ucs_result()
    for mode in ("tension", "compression", "shear"):
        x, y = _line(ax, mode)
        np.testing.assert_allclose(x, 125.0 * STRAIN, rtol=1e-15)
        assert y.tolist() == result.curve[f"broken_{mode}"].tolist()
    assert ax.get_xlabel() == "platen strain (%)" and ax.get_ylabel() == "broken bonds"
    # tension: grips, and no volumetric figure without its column
    curve = {k: v for k, v in ucs_result().curve.items() if k != "volumetric_strain"}
    curve["tensile_stress"] = curve.pop("axial_stress")
    figures = build_lab_figures(ucs_result(test="tension", curve=curve))
    assert set(figures) == {"stress_strain", "cracks"}
    ax = figures["stress_strain"].axes[0]
    _line(ax, "grips")
    assert ax.get_ylabel() == "tensile stress (MPa)"
    assert figures["cracks"].axes[0].get_xlabel() == "grip strain (%)"
    assert build_lab_figures(ucs_result(curve={})) == {}


def test_the_agglomerate_figures_in_newtons_and_millimetres():
    """Force against the plates' displacement, the sieve curve and the mass per size
    class of three fragments, both fragment counts against the applied energy."""
    displacement = np.array([0.0, 1e-4, 2e-4, 3e-4, 4e-4])
    curve = {"time": displacement * 10.0, "displacement": displacement,
             "platen_strain": displacement / 6e-3, "force": np.array([0.0, 4.0, 9.0, 3.0, 2.0]),
             "broken_tension": np.zeros(5), "broken_compression": np.zeros(5),
             "broken_shear": np.zeros(5), "applied_energy": np.array([0, 2, 8, 14, 17]) * 1e-4,
             "fragments": np.array([1.0, 1, 4, 9, 12]),
             "fragments_multi": np.array([1.0, 1, 2, 3, 3])}
    fragments = {"particles": np.array([300.0, 20.0, 1.0]), "mass": np.array([6.0, 3.0, 1.0]),
                 "size": np.array([4e-3, 1.5e-3, 0.5e-3])}
    result = LabResult(test="agglomerate", curve=curve, numbers={}, units=UNITS, settings={},
                       fragments=fragments)
    figures = build_lab_figures(result)
    assert set(figures) == {"stress_strain", "cracks", "fragments"}
    ax = figures["stress_strain"].axes[0]
    x, y = _line(ax, "displacement")
    np.testing.assert_allclose(x, [0, 0.1, 0.2, 0.3, 0.4], rtol=1e-12)
    assert y.tolist() == [0.0, 4.0, 9.0, 3.0, 2.0]
    x, y = _line(ax, "peak 9 N")
    assert x.tolist() == pytest.approx([0.2]) and y.tolist() == [9.0]
    assert ax.get_xlabel() == "displacement (mm)" and ax.get_ylabel() == "force (N)"
    assert tuple(figures["fragments"].get_size_inches()) == (12.0, 4.0)
    left, middle, right = figures["fragments"].axes
    assert [a.get_subplotspec().get_geometry() for a in (left, middle, right)] == [
        (1, 3, 0, 0), (1, 3, 1, 1), (1, 3, 2, 2)]
    assert left.lines[0].get_drawstyle() == "steps-post"
    assert left.get_xlabel() == middle.get_xlabel() == "fragment size (mm)"
    assert middle.get_ylabel() == "mass fraction per size class"
    assert middle.get_xscale() == "log" and right.get_ylabel() == "fragments"
    # eleven logarithmic classes from 0.99 of the smallest to 1.01 of the largest size
    edges = [patch.get_x() for patch in middle.patches]
    assert len(edges) == 11
    np.testing.assert_allclose(edges, np.geomspace(0.495, 4.04, 12)[:-1], rtol=1e-12)
    np.testing.assert_allclose(middle.patches[-1].get_x() + middle.patches[-1].get_width(),
                               4.04, rtol=1e-12)
    x, y = left.lines[0].get_xdata(), left.lines[0].get_ydata()
    np.testing.assert_allclose(x, [0.5, 1.5, 4.0], rtol=1e-12)
    np.testing.assert_allclose(y, [0.1, 0.4, 1.0], rtol=1e-12)
    assert left.get_xscale() == "log" and left.get_ylabel() == "mass fraction passing"
    heights = np.array([patch.get_height() for patch in middle.patches])
    assert heights.sum() == pytest.approx(1.0, rel=1e-12)
    assert sorted(heights[heights > 0].tolist()) == pytest.approx([0.1, 0.3, 0.6])
    x, y = _line(right, "of 2+ particles")
    np.testing.assert_allclose(x, [0, 0.2, 0.8, 1.4, 1.7], rtol=1e-12)
    assert y.tolist() == [1, 1, 2, 3, 3]
    x, y = _line(right, "all, loose particles included")
    np.testing.assert_allclose(x, [0, 0.2, 0.8, 1.4, 1.7], rtol=1e-12)
    assert y.tolist() == [1, 1, 4, 9, 12]
    assert _style(right, "all, loose particles included")[0] == "--"
    # a size just below a class edge stays in its class (sizes drawn in mm)
    just_below = np.geomspace(0.495, 4.04, 12)[5] * (1 - 5e-4) * 1e-3
    result.fragments = {"particles": np.array([300.0, 20.0, 1.0]),
                        "mass": np.array([6.0, 3.0, 1.0]),
                        "size": np.array([4e-3, just_below, 0.5e-3])}
    middle = build_lab_figures(result)["fragments"].axes[1]
    heights = [patch.get_height() for patch in middle.patches]
    assert heights == pytest.approx([0.1, 0, 0, 0, 0.3, 0, 0, 0, 0, 0, 0.6], abs=1e-15)
    result.fragments = fragments
    # without the applied energy (or without the table) there is no fragments figure
    result.curve = {k: v for k, v in curve.items() if k != "applied_energy"}
    assert "fragments" not in build_lab_figures(result)
    result.curve, result.fragments = curve, None
    assert "fragments" not in build_lab_figures(result)
    assert right.get_xlabel() == "applied energy (mJ)"


def test_the_ae_figure_counts_events_and_draws_akis_line():
    magnitudes = np.array([-7.0, -7.5, -6.1, -7.9, -6.8, -7.2, -7.7, -6.5, -7.1, -7.4,
                           -6.9, np.nan])
    result = ucs_result(ae={"magnitude": magnitudes})
    result.curve["ae_events"] = np.array([0.0, 0, 2, 5, 9, 11])
    figure = build_lab_figures(result)["ae"]
    assert tuple(figure.get_size_inches()) == (9.0, 4.0)
    ax_left, ax_right = figure.axes
    assert [a.get_subplotspec().get_geometry() for a in (ax_left, ax_right)] == [
        (1, 2, 0, 0), (1, 2, 1, 1)]
    assert ax_left.get_ylabel() == "AE events" and ax_right.get_xlabel() == "magnitude"
    assert ax_right.get_ylabel() == "events of at least this magnitude"
    assert ax_right.get_yscale() == "log"
    x, y = ax_left.lines[0].get_xdata(), ax_left.lines[0].get_ydata()
    np.testing.assert_allclose(x, 125.0 * STRAIN, rtol=1e-15)
    assert y.tolist() == [0, 0, 2, 5, 9, 11]
    assert ax_left.get_xlabel() == "platen strain (%)"
    x, y = _line(ax_right, "events")
    finite = np.sort(magnitudes[np.isfinite(magnitudes)])
    assert x.tolist() == finite.tolist() and y.tolist() == list(range(11, 0, -1))
    assert _style(ax_right, "events")[:2] == ("None", ".")
    b = b_value(finite)
    x, y = _line(ax_right, f"b = {b:.3g}")
    assert x.tolist() == finite.tolist()
    np.testing.assert_allclose(y, 11 * 10.0 ** (-b * (finite - finite[0])), rtol=1e-12)
    # fewer than ten events: no b-value, no line
    result.ae = {"magnitude": magnitudes[:5]}
    ax_right = build_lab_figures(result)["ae"].axes[1]
    assert [line.get_label() for line in ax_right.lines] == ["events"]
    # events without their count against strain: no figure
    del result.curve["ae_events"]
    assert "ae" not in build_lab_figures(result)


def test_particle_modes_take_the_mode_most_of_their_broken_bonds_broke_in():
    """Each particle's mode is the one most of its broken bonds broke in; a tie takes the
    lower mode; a particle with intact bonds only has none."""
    bonds = np.array([[0, 1], [2, 0], [0, 4], [3, 1], [2, 3], [5, 0]])
    mode = np.array([1, 2, 3, 0, 0, 1])
    # 0: tension (0-1), compression (2-0), shear (0-4), tension (5-0): tension;
    # 1: tension; 2: compression; 3: none; 4: shear; 5: tension
    assert particle_modes(6, bonds, mode).tolist() == [1, 1, 2, 0, 3, 1]
    tie = particle_modes(3, np.array([[0, 1], [0, 2]]), np.array([3, 2]))
    assert tie.tolist() == [2, 3, 2]


def test_the_failure_picture_slices_the_middle_and_draws_the_force_chains():
    """Particles of 0.5 mm radius off the origin, y from 10 to 20 mm (median 15 mm): the
    slice holds those within one diameter (1 mm) of the median, coloured by their mode;
    the force chains join contacts with both particles in the slice, widths 0.3 + 3 |F| /
    max."""
    y = np.array([15.0, 15.9, 14.2, 16.5, 10.0, 20.0, 14.9]) * 1e-3
    position = np.column_stack([np.arange(7) * 1e-3 + 2e-3, y, np.arange(7)[::-1] * 1e-3])
    bonds = np.array([[0, 4], [1, 5], [2, 3], [6, 5]])
    break_mode = np.array([1, 3, 2, 0])
    contacts = {"i": np.array([0, 1, 0, 2, 6, 2]), "j": np.array([1, 3, 6, -1, 2, 0]),
                "force": np.array([[0, 0, 2e-3], [0, 1e-3, 0], [4e-3, 0, 0], [0, 0, 9.0],
                                   [1e-3, 0, 0], [0, 3e-3, 0]])}
    result = ucs_result(position=position, bonds=bonds, break_mode=break_mode,
                        radius=np.full(7, 5e-4), contacts=contacts)
    fig = build_lab_figures(result)["specimen"]
    assert tuple(fig.get_size_inches()) == (10.0, 5.0)
    space, cut = fig.axes
    assert [a.get_subplotspec().get_geometry() for a in (space, cut)] == [(1, 2, 0, 0),
                                                                           (1, 2, 1, 1)]
    points = space.collections[0]
    np.testing.assert_allclose(np.column_stack(points._offsets3d), position * 1e3,
                               rtol=1e-12)
    import matplotlib.colors
    modes = [1, 3, 2, 2, 1, 3, 0]     # every particle's, as particle_modes gives them
    # (the colours as given: get_facecolor() of a 3D scatter is depth-sorted and shaded)
    np.testing.assert_allclose(points._facecolors[:, :3],
                               [matplotlib.colors.to_rgb(MODE_COLOURS[m]) for m in modes])
    assert points.get_sizes().tolist() == [6] and points.get_depthshade() is True
    assert (space.get_xlabel(), space.get_ylabel(), space.get_zlabel()) == (
        "x (mm)", "y (mm)", "z (mm)")
    # the box in the specimen's proportions: 6 x 10 x 6 mm
    aspect = np.asarray(space.get_box_aspect())
    np.testing.assert_allclose(aspect / aspect[1], [0.6, 1.0, 0.6], rtol=1e-9)
    shown = {c.get_label(): c.get_offsets() for c in cut.collections
             if c.get_label() in ("intact", "tension", "compression", "shear")}
    # in the slice: 0 (tension), 1 (shear), 2 (compression), 6 (intact); 3, 4, 5 out
    assert sorted(shown) == ["compression", "intact", "shear", "tension"]
    np.testing.assert_allclose(shown["tension"], position[[0]][:, [0, 2]] * 1e3)
    np.testing.assert_allclose(shown["shear"], position[[1]][:, [0, 2]] * 1e3)
    np.testing.assert_allclose(shown["compression"], position[[2]][:, [0, 2]] * 1e3)
    np.testing.assert_allclose(shown["intact"], position[[6]][:, [0, 2]] * 1e3)
    assert all(c.get_sizes().tolist() == [12] for c in cut.collections
               if c.get_label() in shown)
    colours = {c.get_label(): c.get_facecolor()[0] for c in cut.collections
               if c.get_label() in shown}
    import matplotlib.colors
    for mode, name in ((1, "tension"), (3, "shear")):
        assert tuple(colours[name][:3]) == pytest.approx(
            matplotlib.colors.to_rgb(MODE_COLOURS[mode]))
    chains = [c for c in cut.collections if c.get_label() == "contact forces"]
    assert len(chains) == 1
    segments = chains[0].get_segments()
    # pairs 0-1, 0-6, 6-2 and 2-0 lie in the slice; 1-3 does not, the wall contact is
    # no pair (and its 9 N do not set the scale)
    expected = [(0, 1), (0, 6), (6, 2), (2, 0)]
    assert len(segments) == 4
    for segment, (i, j) in zip(segments, expected):
        np.testing.assert_allclose(segment, position[[i, j]][:, [0, 2]] * 1e3, rtol=1e-12)
    np.testing.assert_allclose(chains[0].get_linewidths(),
                               [0.3 + 3.0 * 0.5, 0.3 + 3.0, 0.3 + 3.0 * 0.25,
                                0.3 + 3.0 * 0.75], rtol=1e-12)
    assert tuple(chains[0].get_color()[0]) == (0.0, 0.0, 0.0, 0.6)
    assert cut.get_xlabel() == "x (mm)" and cut.get_ylabel() == "z (mm)"
    assert cut.get_title() == "slice through the middle"
    legend = cut.get_legend()
    assert legend._loc == 1 and {t.get_fontsize() for t in legend.get_texts()} == {8.0}
    assert cut.get_aspect() == 1.0


def test_the_slice_stays_on_the_specimen_when_fragments_fly_off():
    """A disc of 0.5 mm spheres in 7 layers y = -2.4 ... 2.4 mm (20 each) and three
    fragments flown to y = -40 mm: the middle of the range (-18.8 mm) lies off the disc;
    the slice holds the three layers within one diameter (1 mm) of the disc's middle
    plane, y = 0: 60 particles."""
    rng = np.random.default_rng(3)
    layers = np.repeat(np.arange(-3, 4) * 0.8e-3, 20)
    disc = np.column_stack([rng.uniform(-8e-3, 8e-3, 140), layers,
                            rng.uniform(-8e-3, 8e-3, 140)])
    flown = np.array([[0.0, -40e-3, 9e-3], [1e-3, -39e-3, 9e-3], [2e-3, -40e-3, -9e-3]])
    position = np.vstack([disc, flown])
    result = ucs_result(position=position, bonds=np.zeros((0, 2), int),
                        break_mode=np.zeros(0, int), radius=np.full(143, 5e-4))
    cut = build_lab_figures(result)["specimen"].axes[1]
    shown = np.vstack([c.get_offsets() for c in cut.collections])
    middle = disc[np.abs(layers) < 1e-3]
    assert len(shown) == len(middle) == 60
    np.testing.assert_allclose(np.sort(shown[:, 0]), np.sort(middle[:, 0] * 1e3))


def test_the_slice_reaches_one_diameter_or_a_twentieth_of_the_height():
    """Without radii the slice reaches 5 % of the specimen's extent along y either side of
    the median (here 15.625 mm +- 0.78125 mm, exact in binary: a particle on the edge is
    in), with radii one mean diameter; without break modes every particle is intact;
    without contacts no chains."""
    y = np.array([7.8125, 15.625, 16.40625, 16.4375, 14.84375, 23.4375, 14.8125]) * 1e-3
    position = np.column_stack([np.arange(7) * 1e-3, y, np.arange(7)[::-1] * 2e-3])
    result = ucs_result(position=position, bonds=np.zeros((0, 2), int))
    cut = build_lab_figures(result)["specimen"].axes[1]
    shown = {c.get_label(): c.get_offsets() for c in cut.collections}
    assert list(shown) == ["intact"]
    np.testing.assert_allclose(shown["intact"], position[[1, 2, 4]][:, [0, 2]] * 1e3)
    # with radii of 2^-11 m the slice reaches one diameter, 0.9765625 mm, either side:
    # 16.6 mm is in, 16.6018 mm (0.9768 mm from the median) is out, 14.8125 now in
    position[2, 1], position[3, 1] = 16.6e-3, 16.6018e-3
    result = ucs_result(position=position, bonds=np.zeros((0, 2), int),
                        radius=np.full(7, 2.0 ** -11))
    cut = build_lab_figures(result)["specimen"].axes[1]
    shown = {c.get_label(): c.get_offsets() for c in cut.collections}
    np.testing.assert_allclose(shown["intact"], position[[1, 2, 4, 6]][:, [0, 2]] * 1e3)


def test_write_result_saves_each_figure_as_a_png_of_its_size(tmp_path):
    paths = write_result(ucs_result(), tmp_path)
    for name in ("stress_strain", "volumetric", "cracks"):
        assert paths[name] == tmp_path / f"lab_{name}.png"
        header = paths[name].read_bytes()[:24]
        assert header[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = int.from_bytes(header[16:20], "big"), int.from_bytes(header[20:24],
                                                                             "big")
        assert (width, height) == (600, 400)   # 6 x 4 inches at 100 dpi

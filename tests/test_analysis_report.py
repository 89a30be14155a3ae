"""The HTML report (bondem.analysis.report) of constructed results files, parsed back: its
title, the key numbers as key_numbers gives them, the scene's settings with their units
from the stored TOML, the run's attributes, every figure inlined as a PNG with its
caption in order, and the lab section from a lab.json beside the results."""
import base64
import json
from html.parser import HTMLParser

import h5py
import numpy as np
import pytest

from bondem.analysis import Results, key_numbers
from bondem.analysis.report import (CAPTIONS, _cell, lab_html, render_html, scene_html,
                                    wall_caption, write_report)
from bondem.analysis.summary import format_number

from resultsfile import write_static


class Page(HTMLParser):
    """Tables ({id or position: [[cell text]]}), figures ([(id, alt, PNG bytes, caption)]),
    headings ([(tag, text)]) and the title of an HTML page."""

    def __init__(self, text):
        super().__init__()
        self.tables, self.figures, self.headings, self.items = {}, [], [], []
        self.title, self._text, self._row, self._table = None, None, None, None
        self._figure, self._count = None, 0
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "table":
            self._table = attrs.get("id") or f"table{self._count}"
            self._count += 1
            self.tables[self._table] = []
        elif tag == "tr":
            self._row = []
            self.tables[self._table].append(self._row)
        elif tag in ("td", "th", "h1", "h2", "h3", "title", "figcaption", "li", "p"):
            self._text = ""
        elif tag == "figure":
            self._figure = [attrs.get("id"), None, None, None]
        elif tag == "img":
            self._figure[1] = attrs["alt"]
            prefix = "data:image/png;base64,"
            assert attrs["src"].startswith(prefix)
            self._figure[2] = base64.b64decode(attrs["src"][len(prefix):])

    def handle_data(self, data):
        if self._text is not None:
            self._text += data

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self._row.append(self._text)
        elif tag in ("h1", "h2", "h3"):
            self.headings.append((tag, self._text))
        elif tag == "title":
            self.title = self._text
        elif tag == "figcaption":
            self._figure[3] = self._text
        elif tag == "figure":
            self.figures.append(tuple(self._figure))
        elif tag == "li":
            self.items.append(self._text)
        elif tag == "table":
            self._table = None
        if tag in ("td", "th", "h1", "h2", "h3", "title", "figcaption", "li", "p"):
            self._text = None


SCENE = """
[simulation]
end_time = 2e-3
save_every = 5e-4
gravity = [0.0, 0.0, -9.81]

[materials.glass]
density = 2500.0
young_modulus = 6.5e10

[materials.steel]
density = 7800.0
friction = 0.3

[bond_materials.cement]
normal_strength = 5e6

[particles]
file = "particles.csv"

[[walls]]
type = "plane"
point = [0.0, 0.0, 0.0]

[[walls]]
normal = [0.0, 0.0, -1.0]
velocity = [0.0, 0.0, -0.1]
"""


def plates_file(path, *, attrs=None, extras=False):
    """Two bonded particles squeezed between a fixed plate (wall 0, z = 0) and one moving
    down 0.1 mm per frame from z = 3 mm (wall 1); the bond breaks at frame 3 of 5.
    ``extras``: energy terms and field forces too."""
    k = np.arange(5)
    force = np.zeros((5, 2, 3))
    force[:, 1, 2] = [0.0, 1.5, 3.0, 2.0, 0.5]
    force[:, 0, 2] = -force[:, 1, 2]
    walls_position = np.zeros((5, 2, 3))
    walls_position[:, 1, 2] = 3e-3 - 1e-4 * k
    energy = ({"kinetic_translational": 1e-6 * k, "work_walls": 1e-6 * k} if extras
              else None)
    write_static(path, [[0, 0, 1e-3], [0, 0, 2e-3]], 5e-4, [[0, 1]], (k < 3)[:, None],
                 time=k * 1e-4, mass=np.array([1e-6, 2e-6]), break_mode=[1],
                 walls=(force, walls_position), energy=energy)
    with h5py.File(path, "a") as f:
        if extras:
            f["particles/field_force"] = np.ones((5, 2, 3)) * 1e-6
        for key, value in (attrs or {}).items():
            f.attrs[key] = value
    return path


def test_the_report_of_a_run_holds_its_numbers_scene_attributes_and_figures(tmp_path):
    attrs = {"scene": SCENE, "scene_name": "squeeze.toml", "time_step": 1.23456e-7,
             "time_step_cause": "bonds", "bondem_version": "9.9", "note": "x" * 300,
             "box_length": np.ones(3), "periodic": np.zeros(3, bool)}
    path = plates_file(tmp_path / "run.h5", attrs=attrs)
    out, numbers = write_report(path, tmp_path / "deep" / "er" / "page.html", frames=(1, -1))
    assert out == tmp_path / "deep" / "er" / "page.html"
    with Results(path) as results:
        assert numbers == key_numbers(results)
    page = Page(out.read_text(encoding="utf-8"))
    assert page.title == "bondem: squeeze.toml"
    assert page.tables["key-numbers"] == [[k.replace("_", " "), format_number(k, v)]
                                          for k, v in numbers.items()]
    # the attributes without the scene, its name and the unused box; cut at 200 characters
    attributes = dict(map(tuple, page.tables["attributes"]))
    assert attributes["note"] == "x" * 200 and attributes["bondem_version"] == "9.9"
    assert attributes["time_step"] == str(1.23456e-7)
    assert "periodic" in attributes
    assert not {"scene", "scene_name", "box_length"} & set(attributes)
    # the scene's tables, with units, in the TOML's order
    tables = [t for key, t in page.tables.items() if key.startswith("table")]
    simulation, materials, bonds, particles, walls = tables
    assert simulation == [["key", "value", "unit"], ["end_time", "0.002", "s"],
                          ["save_every", "0.0005", "s"], ["gravity", "[0, 0, -9.81]", "m/s^2"],
                          ["time_step", "1.235e-07 (auto; limited by bonds)", "s"]]
    assert materials == [["name", "density (kg/m^3)", "young_modulus (Pa)", "friction (-)"],
                         ["glass", "2500", "6.5e+10", "default"],
                         ["steel", "7800", "default", "0.3"]]
    assert bonds == [["name", "normal_strength (Pa)"], ["cement", "5e+06"]]
    assert particles == [["key", "value"], ["file", "particles.csv"]]
    assert walls == [["wall", "normal", "point", "type", "velocity"],
                     ["0", "", "[0, 0, 0]", "plane", ""],
                     ["1", "[0, 0, -1]", "", "", "[0, 0, -0.1]"]]
    assert [h[1] for h in page.headings if h[0] == "h3"] == [
        "Simulation and time", "Particle materials", "Bond materials", "Particles",
        "Walls (m, m/s)"]    # no [bonds] table in the scene
    # figures in the report's order, each a PNG of its figure's size, with its caption;
    # the wall's caption names the two plates
    names = [f[0] for f in page.figures]
    assert names == [n for n in ("bodies", "fragments", "breakage", "radial", "energy",
                                 "wall", "fields", "size_distribution") if n in names]
    assert names == ["bodies", "fragments", "breakage", "radial", "wall",
                     "size_distribution"]
    for name, alt, png, caption in page.figures:
        assert alt == name and png[:8] == b"\x89PNG\r\n\x1a\n"
        if name != "wall":
            assert caption == CAPTIONS[name]
    with Results(path) as results:
        from bondem.analysis import wall_curve
        expected = wall_caption(wall_curve(results))
    assert dict((f[0], f[3]) for f in page.figures)["wall"] == expected
    assert "walls 0 and 1" in expected or "walls 1 and 0" in expected
    assert not [h for h in page.headings if h[1].startswith("Laboratory")]


def test_the_default_name_and_place_and_frames_checked_first(tmp_path):
    folder = tmp_path / "case"
    folder.mkdir()
    path = plates_file(folder / "results.h5")
    out, _ = write_report(path)
    assert out == folder / "results_report.html"
    page = Page(out.read_text(encoding="utf-8"))
    # results.h5 takes its folder's name; no scene stored
    assert page.title == "bondem: case"
    assert "(no scene stored in the results file)" in out.read_text()
    other = plates_file(tmp_path / "drop.h5")
    assert Page(write_report(other)[0].read_text()).title == "bondem: drop.h5"
    with pytest.raises(IndexError, match="frame 5 out of range: 5 complete frames"):
        write_report(other, tmp_path / "never.html", frames=(0, 5))
    assert not (tmp_path / "never.html").exists()


def test_scene_tables_from_toml_and_the_run_attributes():
    assert scene_html("", {}) == "<p>(no scene stored in the results file)</p>"
    assert scene_html("[simulation\nx = ", {}) == (
        "<p>(the scene stored in the results file is not valid TOML)</p>")
    # a time step given in the scene, reported with the one used
    page = Page(scene_html("[simulation]\ntime_step = 1e-7\ndamping = 0.1\n",
                           {"time_step": 9.87654e-8}))
    assert page.tables["table0"] == [["key", "value", "unit"],
                                     ["time_step", "9.877e-08 (1e-07; limited by ?)", "s"],
                                     ["damping", "0.1", "-"]]
    assert _cell(0.000123456) == "0.0001235" and _cell([1, 2.5, [3.0]]) == "[1, 2.5, [3]]"
    assert _cell({"a": 1.23456, "b": "x"}) == "a = 1.235, b = x" and _cell(7) == "7"


def test_wall_captions_say_what_the_axes_are():
    two = {"partner": 3, "wall": 1, "displacement": np.array([0.0, 1e-4])}
    assert wall_caption(two) == (
        "Compressive force of walls 1 and 3 and their mean against the decrease of the gap "
        "between them; the first broken bond and the peak of the mean force are marked.")
    one = {"partner": None, "wall": 2, "displacement": np.array([0.0, 1e-4])}
    assert wall_caption(one) == ("Compressive force on wall 2 against its travel; the first "
                                 "broken bond and the peak force are marked.")
    still = {"partner": None, "wall": 0, "displacement": np.zeros(3)}
    assert wall_caption(still) == (
        "Magnitude of the force on wall 0 (it does not move) against time; the first broken "
        "bond and the peak force are marked.")


def test_the_lab_section_from_lab_json_and_its_figures(tmp_path):
    assert lab_html(tmp_path) == ""
    png = b"\x89PNG\r\n\x1a\n" + bytes(range(40))
    (tmp_path / "lab_cracks.png").write_bytes(png)
    (tmp_path / "lab_ae.png").write_bytes(png[::-1])
    (tmp_path / "lab.json").write_text(json.dumps({
        "test": "ucs", "numbers": {"ucs": 1.25e6, "poisson_ratio": None, "steps": 9280},
        "units": {"ucs": "Pa", "steps": "1"}, "notes": ["stopped: post-peak", "a <b>"],
        "captions": {"cracks": "Cracks & modes.", "ae": "AE.", "volumetric": "absent"}}))
    text = lab_html(tmp_path)
    page = Page(text)
    assert page.headings == [("h2", "Laboratory test: ucs")]
    assert page.tables["table0"] == [["quantity", "value", "unit"], ["ucs", "1.25e+06", "Pa"],
                                     ["poisson ratio", "n/a", ""], ["steps", "9280", "1"]]
    assert page.items == ["stopped: post-peak", "a <b>"]
    assert page.figures == [("lab_cracks", "lab cracks", png, "Cracks & modes."),
                            ("lab_ae", "lab ae", png[::-1], "AE.")]
    # an older lab.json without captions: the four figures it had, without captions
    (tmp_path / "lab.json").write_text(json.dumps({"test": "tension", "numbers": {}}))
    (tmp_path / "lab_specimen.png").write_bytes(png)
    page = Page(lab_html(tmp_path))
    assert page.figures == [("lab_cracks", "lab cracks", png, ""),
                            ("lab_specimen", "lab specimen", png, "")]
    # the section sits after the key numbers in the page of a lab folder's results
    path = plates_file(tmp_path / "results.h5")
    out, _ = write_report(path)
    headings = [h[1] for h in Page(out.read_text()).headings if h[0] == "h2"]
    assert headings == ["Key numbers", "Laboratory test: tension", "Scene", "Figures", "Run"]


def test_render_html_escapes_and_takes_given_captions():
    text = render_html("a <title> & more", {"peak_wall_force": 1.23456, "bonds": 3,
                                            "first_break_time": None},
                       {"bodies": b"\x89PNG-1"}, {"k<": "v>"}, "",
                       captions={"bodies": "Mine <here>."}, extra="<h2>Extra</h2>")
    page = Page(text)
    assert page.title == "a <title> & more"
    assert page.tables["key-numbers"] == [["peak wall force", "1.235 N"], ["bonds", "3 bonds"],
                                          ["first break time", "n/a"]]
    assert page.tables["attributes"] == [["k<", "v>"]]
    assert page.figures == [("bodies", "bodies", b"\x89PNG-1", "Mine <here>.")]
    assert [h[1] for h in page.headings if h[0] == "h2"] == [
        "Key numbers", "Extra", "Scene", "Figures", "Run"]
    assert text.startswith("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">")


def _png_size(png):
    return int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")


def test_every_figure_that_applies_at_its_size_and_the_bodies_at_the_frames(tmp_path):
    """Energy terms and field forces add their figures, in the report's order; each PNG at
    100 dpi; three frames make the bodies figure three panels wide; a periodic run keeps
    its box's length, a file that only names a box drops it."""
    path = plates_file(tmp_path / "run.h5", extras=True,
                       attrs={"periodic": np.array([True, False, False]),
                              "box_length": np.array([1e-2, 1.0, 1.0])})
    out, _ = write_report(path, frames=(0, 2, -1))
    page = Page(out.read_text())
    assert [f[0] for f in page.figures] == ["bodies", "fragments", "breakage", "radial",
                                            "energy", "wall", "fields", "size_distribution"]
    pngs = {f[0]: f[2] for f in page.figures}
    assert _png_size(pngs["fragments"]) == (600, 360)     # 6 x 3.6 inches at 100 dpi
    assert _png_size(pngs["bodies"]) == (1080, 380)       # 3 panels of 3.6 x 3.8 inches
    attributes = dict(map(tuple, page.tables["attributes"]))
    assert attributes["box_length"] == str(np.array([1e-2, 1.0, 1.0]))
    named = plates_file(tmp_path / "named.h5", attrs={"box_length": np.ones(3)})
    page = Page(write_report(named)[0].read_text())
    assert "box_length" not in dict(map(tuple, page.tables["attributes"]))
    # no walls: no wall figure, and its caption is not asked for
    bare = write_static(tmp_path / "bare.h5", [[0, 0, 0], [1e-3, 0, 0]], 3e-4, [[0, 1]],
                        [[True], [False]], mass=np.ones(2))
    page = Page(write_report(bare)[0].read_text())
    assert "wall" not in [f[0] for f in page.figures]


def test_the_html_is_written_exactly(monkeypatch):
    from bondem.analysis.report import _table
    assert _table([["a", 1.23456], [[1, 2.5], {"k": 0.5}]], ("x<", "y")) == (
        "<table><tr><th>x&lt;</th><th>y</th></tr><tr><td>a</td><td>1.235</td></tr>\n"
        "<tr><td>[1, 2.5]</td><td>k = 0.5</td></tr></table>")
    scene = ("[simulation]\nseed = 3\n[materials.a]\ncolour = 'red'\ndensity = 1.0\n"
             "[bonds]\nfile = 'b.csv'\n[[walls]]\ntype = 'plane'\n")
    assert scene_html(scene, {}) == "\n".join([
        "<h3>Simulation and time</h3><table><tr><th>key</th><th>value</th><th>unit</th></tr>"
        "<tr><td>seed</td><td>3</td><td></td></tr></table>",
        "<h3>Particle materials</h3><table><tr><th>name</th><th>colour</th>"
        "<th>density (kg/m^3)</th></tr><tr><td>a</td><td>red</td><td>1</td></tr></table>",
        "<h3>Bonds</h3><table><tr><th>key</th><th>value</th></tr>"
        "<tr><td>file</td><td>b.csv</td></tr></table>",
        "<h3>Walls (m, m/s)</h3><table><tr><th>wall</th><th>type</th></tr>"
        "<tr><td>0</td><td>plane</td></tr></table>"])
    # the stamp in UTC whatever the local zone
    import time
    from datetime import datetime, timedelta, timezone
    monkeypatch.setenv("TZ", "Asia/Tokyo")
    time.tzset()
    try:
        before = datetime.now(timezone.utc).replace(second=0, microsecond=0)
        text = render_html("t", {"a": 1, "b": 2}, {"x": b"1", "mystery": b"2"},
                           {"k": 1, "l": 2})
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
    import re
    stamp = re.search(r"<p>bondem report, (\d{4}-\d{2}-\d{2} \d{2}:\d{2}) UTC</p>", text)
    written = datetime.strptime(stamp.group(1), "%Y-%m-%d %H:%M").replace(tzinfo=timezone.utc)
    assert before <= written <= before + timedelta(minutes=2)
    assert '<table id="attributes"><tr><td>k</td><td>1</td></tr>\n<tr><td>l</td>' in text
    assert ('<table id="key-numbers"><tr><td>a</td><td>1</td></tr>\n'
            '<tr><td>b</td><td>2</td></tr></table>\n\n<h2>Scene' in text)
    assert "<p>(no scene stored in the results file)</p>" in text
    assert '</figcaption></figure>\n<figure id="mystery">' in text
    assert Page(text).figures[1] == ("mystery", "mystery", b"2", "mystery")


def test_the_lab_section_s_html_and_its_defaults(tmp_path):
    png = b"\x89PNG\r\n\x1a\n" + bytes(8)
    for name in ("stress_strain", "volumetric"):
        (tmp_path / f"lab_{name}.png").write_bytes(png)
    (tmp_path / "lab.json").write_text(json.dumps({"notes": ["a", "b"]}))
    text = lab_html(tmp_path)
    data = base64.b64encode(png).decode("ascii")
    assert text == (
        '<h2 id="lab">Laboratory test: </h2><table><tr><th>quantity</th><th>value</th>'
        "<th>unit</th></tr></table><ul><li>a</li><li>b</li></ul>"
        f'<figure id="lab_stress_strain"><img alt="lab stress_strain" '
        f'src="data:image/png;base64,{data}"><figcaption></figcaption></figure>'
        f'<figure id="lab_volumetric"><img alt="lab volumetric" '
        f'src="data:image/png;base64,{data}"><figcaption></figcaption></figure>')
    (tmp_path / "lab.json").write_text(json.dumps({"numbers": {"ucs": 2.0}}))
    assert Page(lab_html(tmp_path)).tables["table0"][1] == ["ucs", "2", ""]


def _envelope_folder(folder, spec_text):
    """A ``bondem lab envelope`` folder as write_envelope writes it, for a material of
    c = 1 MPa, phi = 30 degrees: peaks on sigma_1 = 2 c cos(phi) / (1 - sin(phi))
    + sigma_3 (1 + sin(phi)) / (1 - sin(phi)) = 3.4641e6 Pa + 3 sigma_3, a third test
    that did not fail."""
    import math
    from bondem.lab.envelope import mohr_coulomb, write_envelope
    phi, c = math.radians(30.0), 1e6
    tests = []
    for s3, failed in ((1e5, None), (4e5, None), (9e5, "strain limit 0.05 reached")):
        s1 = 2 * c * math.cos(phi) / (1 - math.sin(phi)) + s3 * 3.0
        tests.append({"confining_stress": s3, "peak_stress": s1, "peak_deviator_stress": s1 - s3,
                      "strain_at_peak": 0.0123, "young_modulus_secant": 2.5e8,
                      "confining_stress_error_final": 0.004, "broken_bonds_final": 17.0,
                      "n_particles": 300.0, "no_failure": failed})
    spec = folder.parent / "rock.toml"
    spec.write_text(spec_text)
    fit = mohr_coulomb([1e5, 4e5], [t["peak_stress"] for t in tests[:2]])
    write_envelope({"tests": tests, "fit": fit, "failed": {9e5: tests[2]["no_failure"]},
                    "spec": str(spec), "spec_text": spec_text,
                    "overrides": {"specimen.seed": 4}}, folder)
    return spec


def test_the_envelope_section_and_report_from_an_envelope_folder(tmp_path):
    from click.testing import CliRunner
    from bondem.analysis.report import envelope_html
    from bondem.cli import main
    folder = tmp_path / "env"
    assert envelope_html(folder) == ""
    spec = _envelope_folder(folder, "[specimen]\nlattice = [3, 3, 6]  # a <b> & c\n")
    page = Page(envelope_html(folder))
    assert page.headings == [("h2", "Mohr-Coulomb envelope"), ("h3", "Triaxial tests")]
    fit = page.tables["table0"]
    assert fit[0] == ["quantity", "value", "unit"]
    # the criterion's own c and phi come back (intercept 2 c cos / (1 - sin), slope 3)
    assert fit[1:] == [["cohesion", "1e+06", "Pa"], ["friction angle", "30", "degree"],
                       ["r squared", "1", "1"], ["intercept", "3.464e+06", "Pa"],
                       ["slope", "3", "1"]]
    tests = page.tables["table1"]
    assert tests[0] == ["sigma_3 (Pa)", "peak sigma_1 (Pa)", "peak q (Pa)",
                        "axial strain at peak", "E (secant) (Pa)", "sigma_3 error at the end",
                        "broken bonds", "failed"]
    assert tests[1] == ["1e+05", "3.764e+06", "3.664e+06", "0.0123", "2.5e+08", "0.004",
                        "17", "yes"]
    assert tests[3][0] == "9e+05" and tests[3][-1] == "strain limit 0.05 reached"
    assert page.items == ["sigma_3 = 9e+05 Pa is left out of the fit: strain limit 0.05 "
                          "reached"]
    png = (folder / "lab_envelope.png").read_bytes()
    assert png.startswith(b"\x89PNG") and page.figures[0][:3] == (
        "lab_envelope", "lab envelope", png)
    # a lab folder holding an envelope too shows both, the lab test first
    (folder / "lab.json").write_text(json.dumps({"test": "triaxial", "numbers": {}}))
    assert [h[1] for h in Page(lab_html(folder)).headings] == [
        "Laboratory test: triaxial", "Mohr-Coulomb envelope", "Triaxial tests"]
    (folder / "lab.json").unlink()
    # `bondem report FOLDER`: the page of the envelope and the spec it ran, whole
    result = CliRunner().invoke(main, ["report", str(folder)])
    assert result.exit_code == 0, result.output
    out = folder / "envelope_report.html"
    assert result.output == f"report -> {out}\n"
    text = out.read_text()
    whole = Page(text)
    assert whole.title == "bondem: Mohr-Coulomb envelope of rock"
    assert [h[1] for h in whole.headings] == ["bondem: Mohr-Coulomb envelope of rock",
                                              "Mohr-Coulomb envelope", "Triaxial tests",
                                              "Lab spec"]
    assert ('<pre id="spec">[specimen]\nlattice = [3, 3, 6]  # a &lt;b&gt; &amp; c\n</pre>'
            in text)
    assert f"<p>{spec}, with specimen.seed = 4</p>" in text
    # a folder with neither results.h5 nor an envelope is refused by name
    (tmp_path / "empty").mkdir()
    result = CliRunner().invoke(main, ["report", str(tmp_path / "empty")])
    assert result.exit_code == 2 and "without results.h5" in result.output


def test_an_envelope_without_a_line_says_why(tmp_path):
    from bondem.analysis.report import envelope_html
    from bondem.lab.envelope import write_envelope
    tests = [{"confining_stress": s3, "peak_stress": 5e6 + 0.5 * s3, "no_failure": None}
             for s3 in (1e5, 6e5)]
    from bondem.lab.envelope import mohr_coulomb
    fit = mohr_coulomb([1e5, 6e5], [t["peak_stress"] for t in tests])
    for t in tests:
        t.update(dict.fromkeys(("peak_deviator_stress", "strain_at_peak", "young_modulus_secant",
                                "confining_stress_error_final", "broken_bonds_final",
                                "n_particles"), 1.0))
    write_envelope({"tests": tests, "fit": fit, "failed": {}}, tmp_path)
    page = Page(envelope_html(tmp_path))
    assert page.tables["table0"][1:3] == [["cohesion", "n/a", "Pa"],
                                          ["friction angle", "n/a", "degree"]]
    assert page.items == ["No Mohr-Coulomb line: the peaks' sigma_1 rises by 0.5 times "
                          "sigma_3, less than 1 (no friction)."]

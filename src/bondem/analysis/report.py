"""One self-contained HTML report per run: key numbers, figures inlined as base64 PNG,
and the body at chosen frames with fragments coloured. No external files or scripts."""
from __future__ import annotations

import base64
import html
import io
from datetime import datetime, timezone
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from .figures import build_figures
from .results import Results
from .summary import analyze, key_numbers
from ..physics import bond_models

CAPTIONS = {
    "bodies": "The body at the chosen frames, projected on the x-z plane; each fragment "
              "has its own colour, single particles are grey.",
    "fragments": "Fragments (connected components of intact bonds) and the mass fraction "
                 "of the largest fragment.",
    "breakage": "Broken bonds over time by mode (SPEC 2).",
    "radial": "Fraction of bonds broken in each radial shell of the body at t = 0.",
    "energy": "Energy balance: stored energy against the work done and the losses; the "
              "residual is relative to the initial kinetic energy.",
    "wall": "Force on the walls; the first broken bond and the peak force are marked.",
    "fields": "The fluid's (drag, buoyancy) and a rotating frame's force on the particles: "
              "their sum per axis and the mean magnitude per particle; below, the share of "
              "the moving particles' weight they carry (1: held up by the fluid).",
    "size_distribution": "Fragment sizes at the last frame: cumulative mass distribution "
                         "and number of fragments by particle count.",
}


def wall_caption(curve):
    """Caption of the wall figure for this curve (what its axes are)."""
    if curve["partner"] is not None:
        return (f"Compressive force of walls {curve['wall']} and {curve['partner']} and their "
                "mean against the decrease of the gap between them; the first broken bond "
                "and the peak of the mean force are marked.")
    if curve["displacement"].any():
        return (f"Compressive force on wall {curve['wall']} against its travel; the first "
                "broken bond and the peak force are marked.")
    return (f"Magnitude of the force on wall {curve['wall']} (it does not move) against "
            "time; the first broken bond and the peak force are marked.")


def _cell(value):
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list):
        return "[" + ", ".join(_cell(v) for v in value) + "]"
    if isinstance(value, dict):
        return ", ".join(f"{k} = {_cell(v)}" for k, v in value.items())
    return str(value)


def _table(rows, header):
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "\n".join("<tr>" + "".join(f"<td>{html.escape(_cell(c))}</td>" for c in row)
                     + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


SIMULATION_UNITS = {"end_time": "s", "time_step": "s", "save_every": "s", "gravity": "m/s^2",
                    "damping": "-", "safety_factor": "-", "checkpoint_minutes": "min"}
MATERIAL_UNITS = {"density": "kg/m^3", "young_modulus": "Pa", "poisson_ratio": "-",
                  "restitution": "-", "friction": "-", "rolling_friction": "-",
                  **bond_models.units()}


def scene_html(scene_text, attrs):
    """HTML tables of a scene's settings (simulation and time, materials, bond materials,
    particles, bonds, walls) from its TOML text and the results file's attributes."""
    import tomllib
    try:
        scene = tomllib.loads(scene_text) if scene_text else {}
    except tomllib.TOMLDecodeError:
        return "<p>(the scene stored in the results file is not valid TOML)</p>"
    parts = []
    simulation = dict(scene.get("simulation", {}))
    if "time_step" in attrs:
        simulation["time_step"] = (f"{float(attrs['time_step']):.4g} "
                                   f"({simulation.get('time_step', 'auto')}; "
                                   f"limited by {attrs.get('time_step_cause', '?')})")
    if simulation:
        parts.append("<h3>Simulation and time</h3>" + _table(
            [(k, v, SIMULATION_UNITS.get(k, "")) for k, v in simulation.items()],
            ("key", "value", "unit")))
    for key, title in (("materials", "Particle materials"), ("bond_materials", "Bond materials")):
        tables = scene.get(key, {})
        if tables:
            names = list(dict.fromkeys(k for t in tables.values() for k in t))
            header = ["name"] + [f"{n} ({MATERIAL_UNITS[n]})" if n in MATERIAL_UNITS else n
                                 for n in names]
            rows = [[name] + [t.get(n, "default") for n in names] for name, t in tables.items()]
            parts.append(f"<h3>{title}</h3>" + _table(rows, header))
    for key, title in (("particles", "Particles"), ("bonds", "Bonds")):
        if scene.get(key):
            parts.append(f"<h3>{title}</h3>" + _table(list(scene[key].items()), ("key", "value")))
    walls = scene.get("walls", [])
    if walls:
        names = sorted({k for w in walls for k in w})
        rows = [[k] + [w.get(n, "") for n in names] for k, w in enumerate(walls)]
        parts.append("<h3>Walls (m, m/s)</h3>" + _table(rows, ["wall"] + names))
    return "\n".join(parts) or "<p>(no scene stored in the results file)</p>"


def _png_figure(path, name, alt, caption):
    """A <figure> with the PNG file ``path`` inlined ("" when there is no such file)."""
    if not path.is_file():
        return ""
    return (f'<figure id="{name}"><img alt="{alt}" '
            f'src="data:image/png;base64,{base64.b64encode(path.read_bytes()).decode("ascii")}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


# envelope.json's test columns shown: (key, heading, unit)
ENVELOPE_COLUMNS = (("confining_stress", "sigma_3", "Pa"), ("peak_stress", "peak sigma_1", "Pa"),
                    ("peak_deviator_stress", "peak q", "Pa"),
                    ("strain_at_peak", "axial strain at peak", "1"),
                    ("young_modulus_secant", "E (secant)", "Pa"),
                    ("confining_stress_error_final", "sigma_3 error at the end", "1"),
                    ("broken_bonds_final", "broken bonds", "1"))


def envelope_html(folder):
    """The "Mohr-Coulomb envelope" section from a ``bondem lab envelope`` folder's
    envelope.json (the fit: cohesion Pa, friction angle degrees, R^2; each triaxial test's
    peak) and lab_envelope.png (Mohr circles and the line); empty without envelope.json."""
    import json
    path = Path(folder) / "envelope.json"
    if not path.is_file():
        return ""
    data = json.loads(path.read_text())
    fit, units = data.get("fit", {}), data.get("units", {})
    rows = [(k.replace("_", " "), "n/a" if fit[k] is None else fit[k], units.get(k, ""))
            for k in ("cohesion", "friction_angle", "r_squared", "intercept", "slope")
            if k in fit]
    notes = []
    if fit.get("friction_angle") is None and fit.get("slope") is not None:
        notes.append(f"No Mohr-Coulomb line: the peaks' sigma_1 rises by {fit['slope']:.3g} "
                     f"times sigma_3, less than 1 (no friction).")
    tests = data.get("tests", [])
    cells = [[t.get(k) if t.get(k) is not None else "n/a" for k, _, _ in ENVELOPE_COLUMNS]
             + [t.get("no_failure") or "yes"] for t in tests]
    header = [f"{h} ({u})" if u != "1" else h for _, h, u in ENVELOPE_COLUMNS] + ["failed"]
    notes += [f"sigma_3 = {float(p):.4g} Pa is left out of the fit: {why}"
              for p, why in data.get("failed", {}).items()]
    items = "".join(f"<li>{html.escape(n)}</li>" for n in notes)
    return ('<h2 id="envelope">Mohr-Coulomb envelope</h2>'
            + _table(rows, ("quantity", "value", "unit"))
            + "<h3>Triaxial tests</h3>" + _table(cells, header)
            + (f"<ul>{items}</ul>" if items else "")
            + _png_figure(Path(folder) / "lab_envelope.png", "lab_envelope", "lab envelope",
                          "Mohr circles at the peaks of the triaxial tests and the "
                          "least-squares Mohr-Coulomb line through them."))


def write_envelope_report(folder, out=None):
    """Write the HTML report of a ``bondem lab envelope`` folder (envelope.json): the
    envelope section and the lab spec it ran, to ``out`` (default envelope_report.html in
    the folder). Returns the report's path."""
    import json
    folder = Path(folder)
    out = folder / "envelope_report.html" if out is None else Path(out)
    data = json.loads((folder / "envelope.json").read_text())
    spec, text = data.get("spec"), data.get("spec_text")
    body = envelope_html(folder)
    if text:
        body += (f"<h2>Lab spec</h2><p>{html.escape(str(spec))}"
                 + (f", with {html.escape(_cell(data['overrides']))}"
                    if data.get("overrides") else "")
                 + f'</p><pre id="spec">{html.escape(text)}</pre>')
    name = Path(spec).stem if spec else folder.name
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(_page(f"bondem: Mohr-Coulomb envelope of {name}", body), encoding="utf-8")
    return out


def lab_html(folder):
    """The "Laboratory test" section from a ``bondem lab`` folder's lab.json and its
    figures, and the envelope's (envelope_html) when the folder holds one; empty when it
    holds neither."""
    import json
    path = Path(folder) / "lab.json"
    if not path.is_file():
        return envelope_html(folder)
    data = json.loads(path.read_text())
    # lab.json names its figures and their captions (lab/output.py writes them)
    captions = data.get("captions") or dict.fromkeys(
        ("stress_strain", "volumetric", "cracks", "specimen"), "")
    units = data.get("units", {})
    rows = [(k.replace("_", " "), "n/a" if v is None else v, units.get(k, ""))
            for k, v in data.get("numbers", {}).items()]
    figures = [_png_figure(Path(folder) / f"lab_{name}.png", f"lab_{name}",
                           f"lab {name}", caption)
               for name, caption in captions.items()]
    notes = "".join(f"<li>{html.escape(str(n))}</li>" for n in data.get("notes", []))
    return (f'<h2 id="lab">Laboratory test: {html.escape(str(data.get("test", "")))}</h2>'
            + _table(rows, ("quantity", "value", "unit")) + f"<ul>{notes}</ul>"
            + "".join(figures) + envelope_html(folder))


def render_html(title, numbers, images, attrs=None, scene_text="", captions=None,
                extra=""):
    """HTML text: ``numbers`` {name: value} as a table with units, the scene's settings
    (``scene_text``, TOML), ``images`` {name: PNG bytes} inlined with their captions
    (``captions`` {name: text} overriding the defaults), ``attrs`` {name: value} of the
    results file; ``extra``: HTML of further sections (the lab test's)."""
    from .summary import format_number
    captions = {**CAPTIONS, **(captions or {})}
    rows = "\n".join(
        f"<tr><td>{html.escape(k.replace('_', ' '))}</td>"
        f"<td>{html.escape(format_number(k, v))}</td></tr>" for k, v in numbers.items())
    meta = "\n".join(
        f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v)[:200])}</td></tr>"
        for k, v in (attrs or {}).items())
    figures = "\n".join(
        f'<figure id="{name}"><img alt="{name}" src="data:image/png;base64,'
        f'{base64.b64encode(png).decode("ascii")}"><figcaption>'
        f"{html.escape(captions.get(name, name))}</figcaption></figure>"
        for name, png in images.items())
    return _page(title, f"""<h2>Key numbers</h2><table id="key-numbers">{rows}</table>
{extra}
<h2>Scene</h2><div id="scene">{scene_html(scene_text, attrs or {})}</div>
<h2>Figures</h2>{figures}
<h2>Run</h2><table id="attributes">{meta}</table>""")


def _page(title, body):
    """A whole HTML page: the title, the time it was written, ``body`` (HTML)."""
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:auto;padding:1em}}
table{{border-collapse:collapse}}td{{border:1px solid #ccc;padding:2px 8px}}
img{{max-width:100%}}figure{{margin:1.5em 0}}figcaption{{color:#444}}</style></head>
<body><h1>{html.escape(title)}</h1><p>bondem report, {stamp}</p>
{body}</body></html>
"""


def write_report(path, out=None, frames=(0, -1)):
    """Write the HTML report of results file ``path`` to ``out`` (default
    ``<stem>_report.html`` next to it), showing the body at ``frames`` (indices among
    the complete frames, negative from the end). Returns (report path, key numbers)."""
    path = Path(path)
    out = path.with_name(path.stem + "_report.html") if out is None else Path(out)
    with Results(path) as results:
        for frame in frames:
            results.frame_index(frame)  # IndexError before any work
        data = analyze(results)
        numbers = key_numbers(results, data)
        figures = build_figures(results, frames, data=data)
        all_attrs = results.attrs
        attrs = {k: v for k, v in all_attrs.items() if k not in ("scene", "scene_name")}
        if not np.any(attrs.get("periodic", False)):
            attrs.pop("box_length", None)   # a placeholder of 1 m without a periodic cell
        scene_text = str(all_attrs.get("scene", ""))
        scene_name = str(all_attrs.get("scene_name", "")) or (
            path.parent.name if path.name == "results.h5" else path.name)
    order = ("bodies", "fragments", "breakage", "radial", "energy", "wall", "fields",
             "size_distribution")
    images = {}
    for name in order:
        if name in figures:
            buffer = io.BytesIO()
            figures[name][0].savefig(buffer, format="png", dpi=100)
            images[name] = buffer.getvalue()
    for fig, _ in figures.values():
        plt.close(fig)
    out.parent.mkdir(parents=True, exist_ok=True)
    captions = {"wall": wall_caption(data["wall"])} if data["wall"] is not None else {}
    out.write_text(render_html(f"bondem: {scene_name}", numbers, images, attrs, scene_text,
                               captions, extra=lab_html(path.parent)), encoding="utf-8")
    return out, numbers

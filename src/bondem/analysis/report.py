"""One self-contained HTML report per run: key numbers, figures inlined as base64 PNG,
and the body at chosen frames with fragments coloured. No external files or scripts."""
from __future__ import annotations

import base64
import html
import io
from datetime import datetime, timezone
from pathlib import Path

import matplotlib.pyplot as plt

from .figures import build_figures
from .results import Results
from .summary import analyze, key_numbers

CAPTIONS = {
    "bodies": "The body at the chosen frames, projected on the x-z plane; each fragment "
              "has its own colour, single particles are grey.",
    "fragments": "Fragments (connected components of intact bonds) and the mass fraction "
                 "of the largest fragment.",
    "breakage": "Broken bonds over time by mode (SPEC 2).",
    "radial": "Fraction of bonds broken in each radial shell of the body at t = 0.",
    "energy": "Energy balance: stored energy against the work done and the losses; the "
              "residual is relative to the initial kinetic energy.",
    "wall": "Force on the moving wall against its displacement; the first broken bond and "
            "the peak force are marked.",
    "size_distribution": "Fragment sizes at the last frame: cumulative mass distribution "
                         "and number of fragments by particle count.",
}
UNITS = {"final_time": "s", "first_break_time": "s", "peak_wall_force": "N",
         "peak_wall_displacement": "m", "energy_reference": "J"}


def _format(value):
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def render_html(title, numbers, images, attrs=None):
    """HTML text: ``numbers`` {name: value} as a table, ``images`` {name: PNG bytes}
    inlined with their captions, ``attrs`` {name: value} of the results file."""
    rows = "\n".join(
        f"<tr><td>{html.escape(k.replace('_', ' '))}</td><td>{html.escape(_format(v))}"
        f"</td><td>{UNITS.get(k, '')}</td></tr>" for k, v in numbers.items())
    meta = "\n".join(
        f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v)[:200])}</td></tr>"
        for k, v in (attrs or {}).items())
    figures = "\n".join(
        f'<figure id="{name}"><img alt="{name}" src="data:image/png;base64,'
        f'{base64.b64encode(png).decode("ascii")}"><figcaption>'
        f"{html.escape(CAPTIONS.get(name, name))}</figcaption></figure>"
        for name, png in images.items())
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:auto;padding:1em}}
table{{border-collapse:collapse}}td{{border:1px solid #ccc;padding:2px 8px}}
img{{max-width:100%}}figure{{margin:1.5em 0}}figcaption{{color:#444}}</style></head>
<body><h1>{html.escape(title)}</h1><p>bondem report, {stamp}</p>
<h2>Key numbers</h2><table id="key-numbers">{rows}</table>
<h2>Figures</h2>{figures}
<h2>Run</h2><table id="attributes">{meta}</table></body></html>
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
        attrs = {k: v for k, v in results.attrs.items() if "scene" not in k}
    order = ("bodies", "fragments", "breakage", "radial", "energy", "wall",
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
    out.write_text(render_html(f"bondem run: {path.name}", numbers, images, attrs),
                   encoding="utf-8")
    return out, numbers

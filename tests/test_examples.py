"""The first hour: every example scene runs (at reduced size where it is long), with a
physical check of what it shows; every TOML snippet of the docs parses; every command
the README shows names files that exist, and its Python example runs."""
import re
import shlex
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from bondem.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]


def _run(scene, out, *settings):
    args = ["run", str(scene), "--out", str(out), "--no-progress"]
    for setting in settings:
        args += ["--set", setting]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    return out / "results.h5"


@pytest.mark.parametrize("path", DOCS, ids=lambda p: p.name)
def test_every_toml_snippet_of_the_docs_parses(path):
    for block in re.findall(r"```toml\n(.*?)```", path.read_text(), re.S):
        tomllib.loads(block)


def test_readme_commands_name_files_that_exist():
    text = (ROOT / "README.md").read_text()
    commands = [line.split("#")[0].strip() for block in re.findall(r"```bash\n(.*?)```",
                                                                   text, re.S)
                for line in block.replace("\\\n", " ").splitlines()]
    commands = [c for c in commands if c.startswith("bondem ")]
    assert len(commands) >= 10
    scenes = set()
    for command in commands:
        words = shlex.split(command)
        assert words[1] in ("info", "run", "export", "generate", "analyze", "report",
                            "validate", "bench", "study", "demo", "lab", "calibrate"), command
        for word in words:
            if word.endswith(".toml"):
                assert (ROOT / word).is_file(), command
                scenes.add(word)
            if word.endswith("results.h5"):
                # made by a run of a scene the README shows first
                assert any(word.startswith(s[:-5] + "/") for s in scenes), command
    result = CliRunner().invoke(main, ["info", str(EXAMPLES / "impact.toml"), "--set",
                                       "particles.velocity=[0,0,-2]"])
    assert result.exit_code == 0 and "particles:       5" in result.output, result.output


def test_readme_python_example_runs():
    block = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)[0]
    namespace = {}
    exec(compile(block.replace("print(", "(lambda *a: None)("), "README", "exec"), namespace)
    state = namespace["state"]
    # the two spheres move apart at 0.02 m/s: the bond pulls them back (momentum stays 0)
    assert state.bond_active.all()
    np.testing.assert_allclose(state.velocity.sum(axis=0), 0.0, atol=1e-15)


def test_cantilever_settles_at_the_beam_deflection(tmp_path):
    """Euler-Bernoulli with the spheres' weights as point loads at x_k = k L0:
    w_tip = sum m g x_k^2 (3 L - x_k) / (6 E I); bonded spheres add a little shear
    compliance (the example's comment: 14.9 um against bondem's 15.0 um)."""
    results = _run(EXAMPLES / "cantilever.toml", tmp_path / "c")
    with h5py.File(results, "r") as f:
        z = f["particles/position"][-1, :, 2]
        mass = f["particles/mass"][()]
    radius, spacing, young = 1e-3, 2e-3, 1e8
    inertia = np.pi * (2 * radius) ** 4 / 64
    x = spacing * np.arange(1, 11)
    length = x[-1]
    expected = np.sum(mass[1:] * 9.81 * x ** 2 * (3 * length - x)) / (6 * young * inertia)
    assert z[0] == 0.0
    assert -z[-1] == pytest.approx(expected, rel=0.03)
    assert -z[-1] > expected            # shear only adds deflection


def test_drop_falls_freely_until_it_lands(tmp_path):
    """First 10 ms of the drop (the plate is 5 mm below): the centre of mass falls as
    z0 - g t^2 / 2 and the bonds stay intact."""
    results = _run(EXAMPLES / "drop.toml", tmp_path / "d", "simulation.end_time=0.01",
                   "simulation.save_every=0.0025")
    with h5py.File(results, "r") as f:
        t = f["time"][()]
        mass = f["particles/mass"][()]
        z = f["particles/position"][:, :, 2] @ mass / mass.sum()
        active = f["bonds/active"][-1]
    np.testing.assert_allclose(z - z[0], -0.5 * 9.81 * t ** 2, rtol=1e-3, atol=1e-9)
    assert active.all()


def test_compression_example_loads_both_plates(tmp_path):
    """The first 1.5 ms: the plates close by 0.3 mm, both carry a compressive force and
    the analysis uses the gap between them."""
    from bondem.analysis import Results, wall_curve
    results = _run(EXAMPLES / "compression.toml", tmp_path / "p", "simulation.end_time=1.5e-3")
    with Results(results) as opened:
        curve = wall_curve(opened)
    assert curve["partner"] is not None
    assert curve["displacement"][-1] == pytest.approx(0.3e-3, rel=1e-3)
    assert curve["gap"][-1] == pytest.approx(6e-3 - 0.3e-3, rel=1e-3)
    assert curve["force_wall"].max() > 0 and curve["force_partner"].max() > 0


def test_the_readme_s_generated_body_feeds_its_scene(tmp_path):
    """The README's 'bondem generate' command (as written there, into a copy of examples/)
    and then examples/generated_body.toml: the scene reads the body's CSV files, every
    generated particle and bond, and its plates both press the body."""
    import shutil
    from bondem.analysis import Results, wall_curve
    text = (ROOT / "README.md").read_text().replace("\\\n", " ")
    (line,) = [l for l in text.splitlines() if l.startswith("bondem generate ")]
    words = shlex.split(line.split("#")[0])
    assert words[words.index("--out") + 1] == "examples/body"
    words[words.index("--out") + 1] = str(tmp_path / "body")
    made = CliRunner().invoke(main, words[1:])
    assert made.exit_code == 0, made.output
    shutil.copy(EXAMPLES / "generated_body.toml", tmp_path)
    n = len((tmp_path / "body" / "particles.csv").read_text().splitlines()) - 1
    bonds = len((tmp_path / "body" / "bonds.csv").read_text().splitlines()) - 1
    assert 300 < n < 1000 and bonds > n
    results = _run(tmp_path / "generated_body.toml", tmp_path / "g",
                   "simulation.end_time=1.5e-3")
    with Results(results) as opened:
        assert (opened.n_particles, opened.n_bonds) == (n, bonds)
        curve = wall_curve(opened)
    assert curve["force_wall"].max() > 0 and curve["force_partner"].max() > 0


def test_impact_example_runs_and_breaks_bonds(tmp_path):
    results = _run(EXAMPLES / "impact.toml", tmp_path / "i", "simulation.end_time=2e-4",
                   "particles.velocity=[0,0,-20]")
    with h5py.File(results, "r") as f:
        assert f["time"].shape[0] > 2
        assert not f["bonds/active"][-1].all()       # 20 m/s breaks bonds at the plate


def test_study_example_runs_at_reduced_size(tmp_path):
    text = (EXAMPLES / "study_cluster_impact.toml").read_text()
    text = text.replace("n = 60", "n = 2").replace("duration = [3e-3]", "duration = [3e-4]")
    assert "n = 2" in text and "duration = [3e-4]" in text
    study = tmp_path / "study.toml"
    study.write_text(text)
    result = CliRunner().invoke(main, ["study", str(study), "--workers", "1",
                                       "--no-progress", "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    rows = (tmp_path / "s" / "table.csv").read_text().strip().splitlines()
    assert len(rows) == 3


def test_report_is_titled_by_the_scene_and_lists_it(tmp_path):
    from bondem.analysis.report import write_report
    results = _run(EXAMPLES / "compression.toml", tmp_path / "r", "simulation.end_time=3e-4")
    out, numbers = write_report(results, tmp_path / "report.html")
    page = out.read_text()
    assert "<title>bondem: examples/compression.toml</title>" in page
    for text in ("Particle materials", "Bond materials", "binder", "steel", "Walls",
                 "limited by", "decrease of the gap", "displacement at peak force"):
        assert text in page, text
    assert " N</td>" in page and " m</td>" in page     # numbers carry their units

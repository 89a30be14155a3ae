"""Malformed scenes, CSV files and command lines, generated: every case ends with exit
status 0 (the input was valid after all) or 2 with one line that names the file, and
never with a traceback. `bondem info` loads and checks everything a run would."""
import itertools
import math
import tomllib
from pathlib import Path

import pytest
import tomli_w
from click.testing import CliRunner

from bondem.cli import main

# A NumPy warning printed in the middle of a command's output is a defect too.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
BASE = tomllib.loads((EXAMPLES / "cantilever.toml").read_text())
BASE["walls"] = [{"type": "plane", "point": [0.0, 0.0, -5e-3], "normal": [0.0, 0.0, 1.0],
                  "material": "glass"}]
BASE["simulation"]["contact_model"] = "hertz_mindlin"
PARTICLES = (EXAMPLES / "cantilever_particles.csv").read_text()
BONDS = (EXAMPLES / "cantilever_bonds.csv").read_text()

BAD_VALUES = [-1, 0, 0.5, 2, 1e300, -1e300, math.nan, math.inf, -math.inf, "text", "", True,
              [1.0, 2.0], [1.0, 2.0, 3.0], ["a", "b", "c"], {"a": 1}, 10 ** 400, -(10 ** 30)]


def _leaves(table, prefix=()):
    for key, value in table.items():
        if isinstance(value, dict):
            yield from _leaves(value, prefix + (key,))
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            for k, item in enumerate(value):
                yield from _leaves(item, prefix + (key, k))
        else:
            yield prefix + (key,)


def _set(table, path, value):
    node = table
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value


def _scene_cases():
    paths = list(_leaves(BASE))
    extra = [("simulation", "save_every"), ("simulation", "damping"),
             ("simulation", "periodic"), ("simulation", "box_low"), ("particles", "velocity"),
             ("materials", "glass", "poisson_ratio"), ("bonds", "max_gap"),
             ("walls", 0, "velocity"), ("simulation", "max_steps")]
    for path, value in itertools.product(paths + extra, BAD_VALUES):
        yield f"{'.'.join(map(str, path))}={value!r:.20}", path, value


def _write(folder, scene, particles=PARTICLES, bonds=BONDS):
    text = tomli_w.dumps(scene) if isinstance(scene, dict) else scene
    path = folder / "scene.toml"
    path.write_text(text) if isinstance(text, str) else path.write_bytes(text)
    (folder / "cantilever_particles.csv").write_text(particles) if isinstance(particles, str) \
        else (folder / "cantilever_particles.csv").write_bytes(particles)
    (folder / "cantilever_bonds.csv").write_text(bonds) if isinstance(bonds, str) \
        else (folder / "cantilever_bonds.csv").write_bytes(bonds)
    return path


def _check(args, file_name):
    result = CliRunner().invoke(main, args)
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        f"{args}: {result.exception!r}\n{result.output}"
    assert result.exit_code in (0, 2), (args, result.output)
    if result.exit_code == 2:
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1, (args, result.stderr)
        assert file_name in lines[0], (args, lines[0])
    return result.exit_code


def _dumpable(value):
    try:
        tomli_w.dumps({"v": value})
        return True
    except (TypeError, ValueError):
        return False


def test_scene_values(tmp_path):
    """Every scalar key of a scene with contacts, walls and CSV files set to each of 18
    bad values (about 470 scenes); the ones `info` accepts also run (briefly: 20 steps),
    ending with exit status 0, or 1 and a one-line message if they blow up."""
    codes, accepted = [], []
    for label, path, value in _scene_cases():
        scene = tomllib.loads(tomli_w.dumps(BASE))
        _set(scene, path, value)
        if not _dumpable(value):
            continue
        codes.append(_check(["info", str(_write(tmp_path, scene))], "scene.toml"))
        if codes[-1] == 0:
            accepted.append((label, scene))
    assert len(codes) > 400 and codes.count(2) > 0.9 * len(codes)
    for k, (label, scene) in enumerate(accepted):
        scene["simulation"].update(end_time=2e-5, save_every=1e-5, time_step=1e-6,
                                   force_time_step=True)
        result = CliRunner().invoke(main, ["run", str(_write(tmp_path, scene)), "--out",
                                           str(tmp_path / f"run{k}"), "--no-progress"])
        assert result.exception is None or isinstance(result.exception, SystemExit), \
            f"{label}: {result.exception!r}"
        assert result.exit_code in (0, 1, 2), (label, result.output)
        if result.exit_code:    # one line says why (warning lines about the input may precede it)
            lines = [line for line in result.stderr.strip().splitlines()
                     if not line.startswith("bondem: warning:")]
            assert len(lines) == 1, (label, result.stderr)


CSV_CASES = {
    "empty": ("", None), "header only": ("x,y,z,radius,material\n", None),
    "missing column": ("x,y,z,material\n0,0,0,glass\n", None),
    "unknown column": (PARTICLES.replace("fixed", "fixd"), None),
    "text cell": (PARTICLES.replace("0.001", "one", 1), None),
    "negative radius": (PARTICLES.replace("0.001", "-0.001", 1), None),
    "nan": (PARTICLES.replace("0.001", "nan", 1), None),
    "huge": (PARTICLES.replace("0.001", "1" + "0" * 400, 1), None),
    "short row": (PARTICLES.replace(",glass,1", ",glass", 1), None),
    "fixed 2": (PARTICLES.replace(",glass,1", ",glass,2", 1), None),
    "binary": (b"\x00\x01\x02\xff\xfe", None),
    "utf-16": (PARTICLES.encode("utf-16"), None),
    "coincident": (PARTICLES.replace("0.002,0.0", "0.0,0.0", 1), None),
    "bond self": (None, BONDS.replace("0,1,", "0,0,", 1)),
    "bond index": (None, BONDS.replace("0,1,", "0,99,", 1)),
    "bond negative": (None, BONDS.replace("0,1,", "-1,1,", 1)),
    "bond float index": (None, BONDS.replace("0,1,", "0.5,1,", 1)),
    "bond duplicate": (None, BONDS + "1,0,0.002,binder\n"),
    "bond diameter": (None, BONDS.replace("0.002", "0", 1)),
    "bond material": (None, BONDS.replace("binder", "glue", 1)),
    "bond huge diameter": (None, BONDS.replace("0.002", "1e300", 1)),
    "bond huge index": (None, BONDS.replace("0,1,", "0," + "9" * 40 + ",", 1)),
    "bond empty": (None, ""),
}


@pytest.mark.parametrize("label", sorted(CSV_CASES))
def test_csv_files(tmp_path, label):
    particles, bonds = CSV_CASES[label]
    scene = _write(tmp_path, BASE, PARTICLES if particles is None else particles,
                   BONDS if bonds is None else bonds)
    name = "cantilever_particles.csv" if particles is not None else "cantilever_bonds.csv"
    code = _check(["info", str(scene)], "scene.toml")
    assert code == 2 or label == "coincident"


def test_scene_texts_and_command_lines(tmp_path):
    scene = _write(tmp_path, BASE)
    texts = ["", "[simulation", "x = ", "[simulation]\nend_time = 1e-3\n",
             "[[simulation]]\nend_time = 1\n", "simulation = 3\n", "[materials]\nglass = 1\n",
             tomli_w.dumps({**BASE, "walls": {"a": 1}}), tomli_w.dumps({**BASE, "walls": [1]}),
             tomli_w.dumps({**BASE, "extra": 1}), tomli_w.dumps({**BASE, "bonds": 1}),
             tomli_w.dumps({**BASE, "particles": {"file": "missing.csv"}})]
    for k, text in enumerate(texts):
        path = tmp_path / f"t{k}.toml"
        path.write_text(text)
        _check(["info", str(path)], f"t{k}.toml")
    for setting in ["=1", "a", "simulation.end_time=", "simulation.end_time=[1", "x.y.z=1",
                    "walls.5.velocity=[0,0,1]", "walls.x.velocity=1",
                    "simulation.end_time.x=1", "materials.glass=3", "simulation=1",
                    "particles.velocity=[1e400,0,0]", "simulation.gravity=[nan,0,0]"]:
        result = CliRunner().invoke(main, ["info", str(scene), "--set", setting])
        assert result.exit_code in (0, 2) and result.exception is None \
            or isinstance(result.exception, SystemExit), (setting, result.output)
        if result.exit_code == 2:
            assert len(result.stderr.strip().splitlines()) == 1, (setting, result.stderr)


CELL_VALUES = ["", "nan", "inf", "-inf", "-1", "0", "1e400", "1" + "0" * 400, "text",
               "0x10", "1e-300", "2.5", "1,2"]


def _cell_cases():
    """Every cell of the 4th row of each CSV file replaced by each of CELL_VALUES."""
    for name, text in (("cantilever_particles.csv", PARTICLES),
                       ("cantilever_bonds.csv", BONDS)):
        lines = text.splitlines()
        header = lines[0].split(",")
        for column in range(len(header)):
            for value in CELL_VALUES:
                row = lines[3].split(",")
                row[column] = value
                changed = lines[:3] + [",".join(row)] + lines[4:]
                yield f"{name}:{header[column]}={value:.12}", name, "\n".join(changed) + "\n"


def test_csv_cells(tmp_path):
    """130 CSV files with one bad cell: a refusal names the CSV file and its line 4;
    a value that is fine after all (a radius of 2.5 m, fixed = 0) runs through `info`."""
    codes = []
    for label, name, text in _cell_cases():
        particles = text if name == "cantilever_particles.csv" else PARTICLES
        bonds = text if name == "cantilever_bonds.csv" else BONDS
        scene = _write(tmp_path, BASE, particles, bonds)
        result = CliRunner().invoke(main, ["info", str(scene)])
        assert result.exception is None or isinstance(result.exception, SystemExit), \
            f"{label}: {result.exception!r}"
        assert result.exit_code in (0, 2), (label, result.output)
        codes.append(result.exit_code)
        if result.exit_code == 2:
            lines = result.stderr.strip().splitlines()
            assert len(lines) == 1, (label, result.stderr)
            assert name in lines[0] and "line 4" in lines[0], (label, lines[0])
    assert len(codes) == 130 and codes.count(2) > 0.7 * len(codes)


def test_generator_values(tmp_path):
    """Each number of a packing generator (container centre and radius, particle radius,
    solids fraction, seed, overlap) set to each bad value: exit 0 or 2 with one line
    naming the file, never a traceback (radius = 1e300 overflowed the container's volume,
    particle_radius = 1e-300 divided by zero)."""
    scene = tomllib.loads((EXAMPLES / "compression.toml").read_text())
    scene["particles"]["generator"].update(particle_radius=8e-4, max_overlap=1e-3)
    scene["simulation"]["end_time"] = 1e-5
    codes = []
    for key in ("center", "radius", "particle_radius", "solids_fraction", "seed",
                "max_overlap"):
        for value in BAD_VALUES + [1e-300, 1e-30, 10 ** 19]:
            if not _dumpable(value):
                continue
            changed = tomllib.loads(tomli_w.dumps(scene))
            changed["particles"]["generator"][key] = value
            codes.append(_check(["info", str(_write(tmp_path, changed))], "scene.toml"))
    assert codes.count(2) > 0.8 * len(codes)

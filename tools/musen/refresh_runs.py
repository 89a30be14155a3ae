"""Re-run MUSEN reference folders (the shared and the packaged ones, made with MUSEN 1.70.0)
with another cmusen build, e.g. 1.74.2's from tools/musen/build_musen.sh, and turn its
export into the same CSV files (make_refdata.py's, in ../shared/tools/musen).

    python tools/musen/refresh_runs.py CMUSEN OUT FOLDER [FOLDER ...]

Each FOLDER's musen_scene.txt and musen_script.txt are copied into OUT/NAME, adapted to
the newer cmusen, run there and exported. What the adaptation does, and why:
- every object gets its activity interval "24 0 1e+300": MUSEN 1.70's text import made an
  object without one active for ever, 1.74's makes it active from 0 to 0 (the particles
  then stand still);
- the export's RESULT_FILE gets a folder ("./"): 1.74 creates the result's folder and
  fails on an empty one;
- the export's codes moved (1.74: a bond's tangential overlap 45, its torque 43, a wall's
  corners 44, a particle's principal stresses 42): they are read with 1.74's arities and
  the bond codes mapped back to make_refdata.py's.
"""
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

SHARED = Path(__file__).resolve().parents[3] / "shared" / "tools" / "musen"
sys.path.insert(0, str(SHARED))
import make_refdata  # noqa: E402  (../shared/tools/musen)

# MUSEN 1.74's export codes: arity, and what make_refdata.py reads a bond's values under
make_refdata.ARITY.update({42: 3, 43: 1, 44: 9, 45: 3})
BOND_CODES = {45: 16, 43: 12}
_parse = make_refdata.parse_export


def parse_export(path):
    """make_refdata.parse_export of a 1.74 export, bond codes mapped to 1.70's."""
    objects = _parse(path)
    for obj in objects.values():
        if obj.get("type") == make_refdata.SOLID_BOND:
            for frame in obj["frames"].values():
                for new, old in BOND_CODES.items():
                    if new in frame:
                        frame[old] = frame.pop(new)
    return objects


make_refdata.parse_export = parse_export
# numbers after code 5 (the geometry) by object type: sphere, solid bond, triangular wall
GEOMETRY_SIZE = {make_refdata.SPHERE: 2, make_refdata.SOLID_BOND: 4,
                 make_refdata.TRIANGULAR_WALL: 0}


def adapt(source, target):
    """Copy a reference folder's MUSEN scene and script into ``target`` for MUSEN 1.74."""
    target.mkdir(parents=True, exist_ok=True)
    lines = []
    for line in (source / "musen_scene.txt").read_text().splitlines():
        words = line.split()
        # "0 ID 1 TYPE 5 GEOMETRY... 23 COMPOUND [24 START END] ...": ids and geometry can
        # be any number, so the codes are found by position
        if words and words[0] == "0" and words[2] == "1" and words[4] == "5":
            k = 5 + GEOMETRY_SIZE[int(words[3])]
            assert words[k] == "23", line
            if words[k + 2] != "24":
                words = words[:k + 2] + ["24", "0", "1e+300"] + words[k + 2:]
                line = " ".join(words)
        lines.append(line)
    (target / "musen_scene.txt").write_text("\n".join(lines) + "\n")
    script = (source / "musen_script.txt").read_text().replace(
        "RESULT_FILE musen_export.txt", "RESULT_FILE ./musen_export.txt")
    (target / "musen_script.txt").write_text(script)


def write_scene(name, scene, folder):
    """make_refdata.write of ``scene`` (a function returning its dict) under ``name`` into
    ``folder`` (make_refdata writes into the working directory); returns its dict."""
    make_refdata.SCENES[name] = scene
    with tempfile.TemporaryDirectory() as work:
        here = Path.cwd()
        try:
            os.chdir(work)
            s = make_refdata.write(name)
        finally:
            os.chdir(here)
        shutil.copytree(Path(work) / name, folder, dirs_exist_ok=True)
    return s


def credit(text, name, tool, tag="v1.74.2"):
    """SCENE.md ``text`` with its "Reference run ..." sentence naming the cmusen of MUSEN
    tag ``tag`` and the bondem ``tool`` (tools/musen/TOOL) that made run ``name``."""
    return re.sub(r"Reference run .*?reference folder\.",
                  f"Reference run `{name}` made with the real MUSEN: cmusen built from "
                  f"github.com/msolids/musen tag `{tag}` (MUSEN {tag[1:]}) by bondem's "
                  "`tools/musen/build_musen.sh` (CPU-only build), run as `cmusen -t=1 "
                  "-s=musen_script.txt` (one thread, SIMULATOR_TYPE CPU). Made with "
                  f"`python tools/musen/{tool} CMUSEN OUT {name}`.", text, flags=re.S)


def make_runs(cmusen, out, names, write, kept):
    """For each name: ``write(name, folder)`` the scene into OUT/NAME.source, adapt it to
    1.74's import into OUT/NAME (with the ``kept`` bondem files), run cmusen there and
    export make_refdata's CSV files."""
    out = Path(out)
    for name in names:
        source = out / (name + ".source")
        shutil.rmtree(source, ignore_errors=True)
        write(name, source)
        target = out / name
        shutil.rmtree(target, ignore_errors=True)
        adapt(source, target)
        for file in kept:
            shutil.copy(source / file, target / file)
        shutil.rmtree(source)
        make_refdata.run(str(target), cmusen)
        make_refdata.export(str(target))


def main(cmusen, out, folders):
    out = Path(out)
    for folder in map(Path, folders):
        target = out / folder.name
        shutil.rmtree(target, ignore_errors=True)
        adapt(folder, target)
        make_refdata.run(str(target), cmusen)
        make_refdata.export(str(target))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3:])

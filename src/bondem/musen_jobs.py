"""cmusen job scripts run by bondem: ``bondem run script.txt``.

A script is a list of jobs, each opened by ``JOB`` (or ``NEW_JOB``), as MUSEN's
ScriptInterface/ScriptAnalyzer.cpp reads them: ``COMPONENT`` (IMPORT_FROM_TEXT, SIMULATOR,
EXPORT_TO_TEXT, ...), ``SOURCE_FILE``, ``RESULT_FILE`` and the component's keys (MODEL_SB,
MODEL_SB_PARAMS, SIMULATION_STEP, SAVING_STEP, END_TIME, EXT_ACCEL, STOP_CRITERION,
VERLET_COEF ...). File names are relative to the script's folder.

What each job does here:
- IMPORT_FROM_TEXT: the text scene becomes the source of the jobs that read its
  RESULT_FILE (no .mdem file is written).
- BONDS_GENERATOR: MUSEN's bond generator (``musen_text.generate_bonds``) on its source:
  the source's bonds removed, the generators of a .mdem source with the job's
  ``BOND_GEN_MATERIAL|MINDIST|MAXDIST|DIAMETER|OVERLAY INDEX VALUE`` lines over them;
  the scene goes on to the jobs that read its RESULT_FILE.
- SIMULATOR: its source (an imported text scene, or a .mdem file on disk) with the job's
  keys over the file's own settings, imported as a bondem scene (MUSEN-compatible mode)
  into the folder named like RESULT_FILE without its suffix, and run there (results.h5).
- EXPORT_TO_TEXT: a run of this script written in MUSEN's text format (``bondem export
  musen``).
- PACKAGE_GENERATOR: on a .mdem source, its package generators (volume, mixture,
  porosity, overlap, initial velocity; the job's ``PACK_GEN_* INDEX VALUE`` lines over
  them) with MUSEN's particle counts, packed by bondem's generator
  (``musen_text.generate_package``); the scene goes on like a bonds generator's.
Other components (the snapshot generator, the results analyzer) stop the script before
anything runs, naming the job.

Jobs are run in order. Simulations that read nothing another job of the script writes are
independent: with ``workers`` above 1 they run side by side as a Dask ensemble.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError

COMPONENTS = ("IMPORT_FROM_TEXT", "PACKAGE_GENERATOR", "BONDS_GENERATOR", "SIMULATOR",
              "EXPORT_TO_TEXT")
OTHER_COMPONENTS = ("RESULTS_ANALYZER", "SNAPSHOT_GENERATOR")
SCENE_MAKERS = ("IMPORT_FROM_TEXT", "PACKAGE_GENERATOR", "BONDS_GENERATOR")
BOND_GEN_KEYS = {"BOND_GEN_MATERIAL": "compound", "BOND_GEN_MINDIST": "min_distance",
                 "BOND_GEN_MAXDIST": "max_distance", "BOND_GEN_DIAMETER": "diameter",
                 "BOND_GEN_OVERLAY": "overlay"}
_SYNONYMS = {"RESULTS_FILE": "RESULT_FILE", "SIMULATION_TSTEP": "SIMULATION_STEP",
             "SAVING_TSTEP": "SAVING_STEP", "MODEL_EXT_FORCE": "MODEL_EF",
             "MODEL_EXT_FORCE_PARAMS": "MODEL_EF_PARAMS"}


@dataclass
class Job:
    """One job of a script: its number (from 1), component, source and result files
    (absolute), its other keys ({KEY: rest of the line}, the last one given) and every
    line of them in order ([(KEY, rest)], for keys given per generator)."""
    number: int
    component: str = "SIMULATOR"
    source: Path | None = None
    result: Path | None = None
    keys: dict = field(default_factory=dict)
    lines: list = field(default_factory=list)


def is_script(path):
    """Whether ``path`` is a cmusen script (a text file whose first key is JOB,
    NEW_JOB or COMPONENT) rather than a scene."""
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            for line in handle:
                words = line.split()
                if words:
                    return words[0].upper() in ("JOB", "NEW_JOB", "COMPONENT")
    except OSError:
        return False
    return False


def read_jobs(path):
    """The jobs of a cmusen script, in order; InputError naming the line of an unknown
    component."""
    path = Path(path)
    folder = path.parent
    jobs = []
    for number, raw in enumerate(path.read_text(errors="replace").splitlines(), 1):
        words = raw.split(None, 1)
        if not words or words[0].startswith(("#", "//")):
            continue
        key = words[0].upper()
        key = _SYNONYMS.get(key, key)
        rest = words[1].strip() if len(words) > 1 else ""
        if key in ("JOB", "NEW_JOB"):
            jobs.append(Job(len(jobs) + 1))
            continue
        if not jobs:    # cmusen opens a job for a first line that is not JOB
            jobs.append(Job(1))
        job = jobs[-1]
        if key == "COMPONENT":
            value = rest.upper()
            if value not in COMPONENTS + OTHER_COMPONENTS:
                raise InputError(f"component {rest!r}; allowed: "
                                 + ", ".join(COMPONENTS + OTHER_COMPONENTS), file=path,
                                 key=f"line {number}")
            job.component = value
        elif key == "SOURCE_FILE":
            job.source = (folder / rest).resolve()
        elif key == "RESULT_FILE":
            job.result = (folder / rest).resolve()
        else:
            job.keys[key] = rest
            job.lines.append((key, rest))
    for job in jobs:
        if job.component in OTHER_COMPONENTS:
            raise InputError(f"job {job.number}: component {job.component} is not run by "
                             f"bondem (it runs {', '.join(COMPONENTS)}: "
                             "docs/musen_migration.md)", file=path)
        if job.source is None or job.result is None:
            raise InputError(f"job {job.number} ({job.component}): needs SOURCE_FILE and "
                             "RESULT_FILE", file=path)
    return jobs


def run_folder(result):
    """The folder of a SIMULATOR job's run: its RESULT_FILE without the suffix."""
    return result.with_suffix("")


def plan(jobs, path):
    """Check the script before anything runs: every source exists or is written by an
    earlier job. Returns {job number: the numbers of the jobs it reads}."""
    written = {}
    needs = {}
    for job in jobs:
        maker = written.get(job.source)
        if maker is None and not job.source.is_file():
            raise InputError(f"job {job.number} ({job.component}): SOURCE_FILE "
                             f"{job.source} does not exist and no earlier job writes it",
                             file=path)
        needs[job.number] = {maker.number} if maker is not None else set()
        if maker is not None:
            needs[job.number] |= needs[maker.number]
        if job.component == "EXPORT_TO_TEXT" and (maker is None
                                                  or maker.component != "SIMULATOR"):
            raise InputError(f"job {job.number}: EXPORT_TO_TEXT exports a run of this "
                             "script (a SIMULATOR job's RESULT_FILE)", file=path)
        if job.component == "PACKAGE_GENERATOR" and (maker is not None
                                                     or job.source.suffix.lower() != ".mdem"):
            raise InputError(f"job {job.number}: PACKAGE_GENERATOR reads a .mdem file (its "
                             "volumes, mixtures and generators)", file=path)
        if job.component in ("SIMULATOR", "BONDS_GENERATOR") and maker is not None \
                and maker.component not in SCENE_MAKERS:
            raise InputError(f"job {job.number}: a {job.component} job reads a scene (a "
                             ".mdem file or the result of an "
                             f"{', '.join(SCENE_MAKERS)} job), not a run", file=path)
        if job.component == "IMPORT_FROM_TEXT" and maker is not None:
            raise InputError(f"job {job.number}: IMPORT_FROM_TEXT reads a text file",
                             file=path)
        written[job.result] = job
    return needs


def source_scene(job, scenes):
    """(MusenScene, script keys, MUSEN release or None, file) of the scene job ``job``
    reads: an earlier job's (``scenes``: {RESULT_FILE: (scene, keys, release, file)})
    or a .mdem file's. A copy: the job may change it."""
    import copy
    from .io.musen_mdem import MdemFile, musen_release, scene_of, script_of
    if job.source in scenes:
        return copy.deepcopy(scenes[job.source])
    mdem = MdemFile(job.source)
    mdem.check()
    return scene_of(mdem), script_of(mdem), musen_release(mdem), job.source


def generators_of(job, source):
    """The bond generators of BONDS_GENERATOR job ``job``: those of the .mdem file its
    scene comes from (``source``), then
    the job's BOND_GEN_<KEY> INDEX VALUE lines over them (index from 1; a new index adds a
    generator with MUSEN's defaults)."""
    from .io.musen_mdem import MdemFile, bond_generators
    from .io.musen_text import BOND_GENERATOR
    generators = (bond_generators(MdemFile(source)) if source.suffix.lower() == ".mdem"
                  and source.is_file() else [])
    for key, rest in job.lines:
        if key not in BOND_GEN_KEYS:
            continue
        words = rest.split(None, 1)
        try:
            index = _index(words[0])
            value = words[1].strip()
            if key != "BOND_GEN_MATERIAL":
                value = float(value)
        except (IndexError, ValueError):
            raise InputError(f"job {job.number}: expected {key} INDEX VALUE, got "
                             f"{rest!r}", key=key) from None
        while len(generators) <= index:
            generators.append(dict(BOND_GENERATOR))
        name = BOND_GEN_KEYS[key]
        generators[index][name] = bool(value) if name == "overlay" else value
    return generators


def package_job(job):
    """The package generators of PACKAGE_GENERATOR job ``job``: its .mdem source's, with
    the job's PACK_GEN_VOLUME|MIXTURE|POROSITY|OVERLAP|VELOCITY|INSIDE INDEX VALUE lines
    over them (index from 1; a volume or mixture by name or key)."""
    from .io.musen_mdem import MdemFile, package_generators, package_tables
    mdem = MdemFile(job.source)
    generators = package_generators(mdem)
    volumes, mixtures = package_tables(mdem)
    for key, rest in job.lines:
        if not key.startswith("PACK_GEN_"):
            continue
        words = rest.split()
        try:
            index = _index(words[0])
            value = words[1:]
            while len(generators) <= index:
                generators.append({"active": True, "name": "Generator", "volume": None,
                                   "mixture": None, "porosity": 0.5, "max_overlap": 1e-7,
                                   "velocity": (0.0, 0.0, 0.0), "inside_geometry": False})
            g = generators[index]
            if key == "PACK_GEN_VOLUME":
                g["volume"] = _named(volumes, " ".join(value), job, key)
            elif key == "PACK_GEN_MIXTURE":
                g["mixture"] = _named(mixtures, " ".join(value), job, key)
            elif key == "PACK_GEN_POROSITY":
                g["porosity"] = float(value[0])
                if not 0.0 < g["porosity"] < 1.0:
                    raise ValueError(value[0])
            elif key == "PACK_GEN_OVERLAP":
                g["max_overlap"] = float(value[0])
                if not g["max_overlap"] > 0.0:
                    raise ValueError(value[0])
            elif key == "PACK_GEN_VELOCITY":
                g["velocity"] = tuple(float(v) for v in value[:3])
                if len(g["velocity"]) != 3:
                    raise ValueError(rest)
            elif key == "PACK_GEN_INSIDE":
                g["inside_geometry"] = bool(int(float(value[0])))
        except InputError:
            raise
        except (IndexError, ValueError):
            raise InputError(f"job {job.number}: expected {key} INDEX VALUE (porosity in "
                             "(0, 1), overlap > 0 m, velocity 3 numbers m/s), got "
                             f"{rest!r}", key=key) from None
    return generators


def _index(word):
    """A generator's index of a script line (from 1) as a list index."""
    index = int(word) - 1
    if index < 0:
        raise ValueError(word)
    return index


def _named(table, name, job, key):
    if name not in table:
        raise InputError(f"job {job.number}: {key} {name!r} is not in the file (it has: "
                         f"{', '.join(sorted(table)) or 'none'})", file=job.source, key=key)
    return table[name]


def import_job(job, scenes):
    """Write the scene of SIMULATOR job ``job`` into its run folder; returns (scene
    path, notes). The job's keys go over the source's own settings."""
    from .io.musen_text import to_bondem
    folder = run_folder(job.result)
    scene, script, release, source = source_scene(job, scenes)
    script.update(job.keys)
    try:
        notes = to_bondem(scene, script, folder,
                          **({"musen_version": release} if release else {}))
    except InputError as error:
        raise InputError(f"job {job.number}: {error.reason}", file=source,
                         key=error.key) from None
    return folder / "scene.toml", notes


def _simulate(scene_path, out_dir):
    """Run one imported scene into ``out_dir`` (a Dask task: module level)."""
    from .runner import run_scene
    from .scene import load_scene
    return str(run_scene(load_scene(scene_path), out_dir, progress=False, overwrite=True))


def run_script(path, *, workers=1, echo=print):
    """Run every job of cmusen script ``path`` (see the module docstring); simulations
    that depend on no other job of it run side by side on ``workers`` Dask processes when
    ``workers`` > 1. Returns {job number: what it wrote}."""
    from .io.musen_text import export_musen
    from .lab.series import ensemble
    path = Path(path)
    jobs = read_jobs(path)
    needs = plan(jobs, path)
    from .io.musen_text import generate_bonds, read_text
    scenes = {}
    written = {}
    simulations = []
    for job in jobs:    # every scene first: a bad one stops the script before any run
        if job.component == "IMPORT_FROM_TEXT":
            scenes[job.result] = (read_text(job.source), {}, None, job.source)
            written[job.number] = job.source
            echo(f"job {job.number}: {job.component} {job.source.name} (read by the "
                 "jobs that follow)")
        elif job.component == "PACKAGE_GENERATOR":
            from .io.musen_text import generate_package
            scene, script, release, source = source_scene(job, scenes)
            made = 0
            for generator in package_job(job):
                if generator["active"]:
                    try:
                        count, notes = generate_package(scene, generator)
                    except InputError as error:
                        raise InputError(f"job {job.number}: {error.reason}",
                                         file=job.source) from None
                    except (ValueError, RuntimeError) as error:   # the packer's limits
                        raise InputError(f"job {job.number}: package generator "
                                         f"{generator['name']!r}: {error}",
                                         file=job.source) from None
                    made += count
                    for note in notes:
                        echo(f"job {job.number}: note: {note}")
            scenes[job.result] = (scene, script, release, source)
            written[job.number] = job.result
            echo(f"job {job.number}: {job.component}: {made} particles (read by the jobs "
                 "that follow)")
        elif job.component == "BONDS_GENERATOR":
            scene, script, release, source = source_scene(job, scenes)
            made = generate_bonds(scene, generators_of(job, source))
            scenes[job.result] = (scene, script, release, source)
            written[job.number] = job.result
            echo(f"job {job.number}: {job.component}: {made} bonds (read by the jobs "
                 "that follow)")
        elif job.component == "SIMULATOR":
            scene_path, notes = import_job(job, scenes)
            for note in notes:
                echo(f"job {job.number}: note: {note}")
            simulations.append((job, scene_path))
    runs = {job.result: run_folder(job.result) for job, _ in simulations}
    independent = [s for s in simulations
                   if not any(jobs[n - 1].component == "SIMULATOR"
                              for n in needs[s[0].number])]
    if workers > 1 and len(independent) > 1:
        done = ensemble(_simulate, [(str(p), str(run_folder(j.result)))
                                    for j, p in independent], scheduler=None,
                        workers=workers)
        for (job, _), result in zip(independent, done):
            written[job.number] = Path(result)
            echo(f"job {job.number}: {job.component} -> {result}")
    for job in jobs:
        if job.number in written:
            continue
        if job.component == "SIMULATOR":
            scene_path = next(p for j, p in simulations if j is job)
            written[job.number] = Path(_simulate(scene_path, run_folder(job.result)))
            echo(f"job {job.number}: {job.component} -> {written[job.number]}")
        elif job.component == "EXPORT_TO_TEXT":
            job.result.parent.mkdir(parents=True, exist_ok=True)
            export_musen(runs[job.source] / "results.h5", job.result)
            written[job.number] = job.result
            echo(f"job {job.number}: {job.component} -> {job.result}")
    return written

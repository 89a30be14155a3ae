"""cmusen job scripts run by bondem: ``bondem run script.txt``.

A script is a list of jobs, each opened by ``JOB`` (or ``NEW_JOB``), as MUSEN's
ScriptInterface/ScriptAnalyzer.cpp reads them: ``COMPONENT`` (IMPORT_FROM_TEXT, SIMULATOR,
EXPORT_TO_TEXT, ...), ``SOURCE_FILE``, ``RESULT_FILE`` and the component's keys (MODEL_SB,
MODEL_SB_PARAMS, SIMULATION_STEP, SAVING_STEP, END_TIME, EXT_ACCEL, STOP_CRITERION,
VERLET_COEF ...). File names are relative to the script's folder.

What each job does here:
- IMPORT_FROM_TEXT: the text scene becomes the source of the jobs that read its
  RESULT_FILE (no .mdem file is written).
- SIMULATOR: its source (an imported text scene, or a .mdem file on disk) with the job's
  keys over the file's own settings, imported as a bondem scene (MUSEN-compatible mode)
  into the folder named like RESULT_FILE without its suffix, and run there (results.h5).
- EXPORT_TO_TEXT: a run of this script written in MUSEN's text format (``bondem export
  musen``).
Other components (package, bonds and snapshot generators, the results analyzer) stop the
script before anything runs, naming the job.

Jobs are run in order. Simulations that read nothing another job of the script writes are
independent: with ``workers`` above 1 they run side by side as a Dask ensemble.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError

COMPONENTS = ("IMPORT_FROM_TEXT", "SIMULATOR", "EXPORT_TO_TEXT")
OTHER_COMPONENTS = ("PACKAGE_GENERATOR", "BONDS_GENERATOR", "RESULTS_ANALYZER",
                    "SNAPSHOT_GENERATOR")
_SYNONYMS = {"RESULTS_FILE": "RESULT_FILE", "SIMULATION_TSTEP": "SIMULATION_STEP",
             "SAVING_TSTEP": "SAVING_STEP", "MODEL_EXT_FORCE": "MODEL_EF",
             "MODEL_EXT_FORCE_PARAMS": "MODEL_EF_PARAMS"}


@dataclass
class Job:
    """One job of a script: its number (from 1), component, source and result files
    (absolute) and its other keys ({KEY: rest of the line}, the last one given)."""
    number: int
    component: str = "SIMULATOR"
    source: Path | None = None
    result: Path | None = None
    keys: dict = field(default_factory=dict)


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
    for job in jobs:
        if job.component in OTHER_COMPONENTS:
            raise InputError(f"job {job.number}: component {job.component} is not run by "
                             f"bondem (it runs {', '.join(COMPONENTS)}; bondem generate "
                             "packs and bonds: docs/musen_migration.md)", file=path)
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
        if job.component == "SIMULATOR" and maker is not None \
                and maker.component != "IMPORT_FROM_TEXT":
            raise InputError(f"job {job.number}: a SIMULATOR job reads a scene (a .mdem "
                             "file or an IMPORT_FROM_TEXT job's result), not another run",
                             file=path)
        if job.component == "IMPORT_FROM_TEXT" and maker is not None:
            raise InputError(f"job {job.number}: IMPORT_FROM_TEXT reads a text file",
                             file=path)
        written[job.result] = job
    return needs


def import_job(job, sources):
    """Write the scene of SIMULATOR job ``job`` into its run folder; returns (scene
    path, notes). ``sources``: {RESULT_FILE of an IMPORT_FROM_TEXT job: its text file}."""
    from .io.musen_mdem import MdemFile, musen_release, scene_of, script_of
    from .io.musen_text import read_text, to_bondem
    folder = run_folder(job.result)
    if job.source in sources:    # a text scene: the job's keys are its whole script
        source = sources[job.source]
        scene, script, release = read_text(source), dict(job.keys), None
    else:                        # a .mdem file: the job's keys over the file's settings
        source = job.source
        mdem = MdemFile(source)
        mdem.check()
        scene, script, release = scene_of(mdem), script_of(mdem), musen_release(mdem)
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
    sources = {job.result: job.source for job in jobs
               if job.component == "IMPORT_FROM_TEXT"}
    written = {}
    simulations = []
    for job in jobs:
        if job.component == "SIMULATOR":
            scene_path, notes = import_job(job, sources)
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
        if job.component == "IMPORT_FROM_TEXT":
            written[job.number] = job.source
            echo(f"job {job.number}: {job.component} {job.source.name} (read by the "
                 "jobs that follow)")
        elif job.component == "SIMULATOR":
            scene_path = next(p for j, p in simulations if j is job)
            written[job.number] = Path(_simulate(scene_path, run_folder(job.result)))
            echo(f"job {job.number}: {job.component} -> {written[job.number]}")
        elif job.component == "EXPORT_TO_TEXT":
            job.result.parent.mkdir(parents=True, exist_ok=True)
            export_musen(runs[job.source] / "results.h5", job.result)
            written[job.number] = job.result
            echo(f"job {job.number}: {job.component} -> {job.result}")
    return written

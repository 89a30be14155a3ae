"""Run a scene to its end time: frames to results.h5, checkpoints, progress bar, resume.

Frames are taken every ``save_every`` seconds of simulated time, rounded to whole steps
(frame k at step k * stride, plus the last step), so an interrupted and a resumed run see
the same frame schedule. Steps run in batches of about a second of wall time; after a
batch, a checkpoint is taken when at least ``checkpoint_minutes`` of wall time have passed
since the last one (also between frames: resume continues to the next frame), and at the
end.
"""
from __future__ import annotations

import math
import os
import signal
import time
from pathlib import Path

from .errors import BackendUnavailable, InputError
from .status import SimulationBlowUp
from .io.checkpoint import read_checkpoint, write_checkpoint
from .io.results import LOCK_NAME, ResultsWriter
from .timestep import step_count

RESULTS_NAME = "results.h5"
CHECKPOINT_NAME = "checkpoint.npz"
LAST_GOOD_NAME = "last_good_state.npz"
PREVIOUS_NAME = "previous_run"   # an overwritten run, kept until the new one finishes
# What a run and the commands after it (analyze, report, export vtk) write in its folder:
# a fresh run with overwrite clears them all, so no stale analysis outlives its results.
STALE_OUTPUTS = (RESULTS_NAME, CHECKPOINT_NAME, LAST_GOOD_NAME, "results.fragments.h5",
                 "results_report.html", "results_analysis", "vtk")
FIRST_BATCH = 16       # steps in the first batch (it includes the JIT compilation)
BATCH_SECONDS = 1.0    # wall-clock target of a batch of steps


class EnergyWatch:
    """Blow-up detection by energy, checked at every frame: a non-finite energy term, or
    energy created from nothing, residual = stored - stored_0 - work + losses (J, the
    energy balance of ``analysis.energy``), above GROWTH times what the start and the
    loads account for: the stored energy at the first frame plus the contacts' elastic
    energy at the second (known only once contacts were evaluated), or the largest work
    done so far. A stable run keeps the residual at a few per cent of that (the demo:
    0.4 %); a time step 9 times the stable one created 110 times the initial energy and
    booked it as broken bonds' energy."""

    GROWTH = 10.0

    def __init__(self):
        self.first = None
        self.baseline = None
        self.most_work = 0.0

    def check(self, sim):
        """Raise SimulationBlowUp when the energy of ``sim`` says the run blew up; return
        its energy terms ({name: J}, for the frame that the results writer appends)."""
        from .analysis.results import ENERGY_LOSSES, ENERGY_STORED, ENERGY_WORK
        terms = sim.energy_terms()
        bad = [name for name, value in terms.items() if not math.isfinite(value)]
        if bad:
            raise SimulationBlowUp(f"simulation blew up at t = {sim.state.time:.6g} s: "
                                   f"energy {bad[0]} is {terms[bad[0]]}")

        def total(names):
            return sum(terms.get(name, 0.0) for name in names)
        stored, work = total(ENERGY_STORED), total(ENERGY_WORK)
        self.most_work = max(self.most_work, abs(work))
        if self.first is None:
            self.first = stored
            return terms
        if self.baseline is None:
            self.baseline = self.first + terms.get("contact_elastic", 0.0)
        created = stored - self.first - work + total(ENERGY_LOSSES)
        allowed = self.GROWTH * max(self.baseline, self.most_work)
        if created > allowed:
            raise SimulationBlowUp(
                f"simulation blew up at t = {sim.state.time:.6g} s: {created:.4g} J of "
                f"energy appeared from nothing (start {self.baseline:.4g} J, work "
                f"{self.most_work:.4g} J): reduce the time step")
        return terms


class RunFailed(RuntimeError):
    """The simulation blew up; the message says where the last good state was kept."""


class RunInterrupted(RuntimeError):
    """SIGINT (Ctrl-C) or SIGTERM stopped the run after its current batch of steps: the
    checkpoint holds that state and the results file every frame so far (the message
    says both); ``signal_number`` is the signal's."""

    def __init__(self, message, signal_number):
        super().__init__(message)
        self.signal_number = signal_number


class _StopSignals:
    """Within ``with``: the first SIGINT or SIGTERM only asks the run to stop after its
    batch (``requested`` holds the signal), so the run can write a checkpoint and close
    the results file; a second one stops at once as Python would. Outside the main thread
    (where handlers cannot be set) nothing changes."""

    def __init__(self):
        self.requested = None
        self._previous = {}

    def _handle(self, number, frame):
        if self.requested is not None:      # asked twice: do not wait for the batch
            raise KeyboardInterrupt
        self.requested = number

    def __enter__(self):
        for number in (signal.SIGINT, signal.SIGTERM):
            try:
                self._previous[number] = signal.signal(number, self._handle)
            except ValueError:    # not the main thread
                break
        return self

    def __exit__(self, *exc):
        for number, handler in self._previous.items():
            signal.signal(number, handler)


def default_out_dir(scene_path) -> Path:
    """Next to the scene, named after it: ``dir/impact.toml`` -> ``dir/impact``."""
    scene_path = Path(scene_path)
    return scene_path.parent / scene_path.stem


def frame_schedule(scene, time_step):
    """(total steps, steps between frames) of a scene run with ``time_step`` (s)."""
    total = step_count(scene.end_time, time_step)
    stride = max(1, int(round(scene.save_every / time_step)))
    return total, stride


def clear_outputs(out_dir, overwrite):
    """Refuse (InputError naming --overwrite) a folder that holds an earlier run's results
    or checkpoint, unless ``overwrite``: then move the run's files and the analysis,
    report and ParaView output made from them (``STALE_OUTPUTS``) into
    ``out_dir/previous_run``, where they stay until the new run finishes, so that a new run
    that fails (or is killed) has not destroyed the old one. If ``previous_run`` is already
    there, the run that left it never finished: its files are removed instead and the
    finished run in ``previous_run`` is kept."""
    import shutil
    out_dir = Path(out_dir)
    for leftover in (RESULTS_NAME + ".new", RESULTS_NAME + ".rewrite"):
        (out_dir / leftover).unlink(missing_ok=True)   # of a writer killed while making them
    present = [name for name in STALE_OUTPUTS if (out_dir / name).exists()]
    if not present:
        return
    if not overwrite:
        raise InputError(f"the folder holds results of an earlier run ({', '.join(present)}); "
                         "give --overwrite to replace them, --resume to continue that run, "
                         "or another --out", file=out_dir, key="--out")
    previous = out_dir / PREVIOUS_NAME
    keep = not previous.exists()
    if keep:
        previous.mkdir()
    for name in present:
        target = out_dir / name
        if keep:
            os.replace(target, previous / name)
        elif target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        else:
            target.unlink()


def _finished(out_dir):
    """The run in ``out_dir`` reached its end: an overwritten run kept for safety goes."""
    import shutil
    shutil.rmtree(Path(out_dir) / PREVIOUS_NAME, ignore_errors=True)


def _kept_previous(out_dir):
    previous = Path(out_dir) / PREVIOUS_NAME
    return (f"; the earlier run's files are kept in {previous} until a run here finishes"
            if previous.is_dir() else "")


def run_scene(scene, out_dir, *, progress=True, resume=False, checkpoint_minutes=None,
              stop_after_frames=None, overwrite=False) -> Path:
    """Run ``scene`` (from ``load_scene``) and write ``out_dir/results.h5``.

    progress: show a tqdm bar (simulated time, steps/s, intact bonds); resume: continue
    from ``out_dir/checkpoint.npz`` and truncate the results to its frame;
    checkpoint_minutes: wall-clock minutes between checkpoints (default: the scene's
    ``simulation.checkpoint_minutes``; 0 means after every batch of steps); stop_after_frames: stop
    (as if killed) after that many frames in this call, for tests; overwrite: replace an
    earlier run's results in ``out_dir`` (and its stale analysis, report and vtk output)
    instead of refusing them. Returns the results path. Raises InputError (bad resume, or
    a folder with results without overwrite), RunFailed (blow-up; the last good state is
    kept in ``out_dir/last_good_state.npz`` and every frame up to it in the results) or
    RunInterrupted (SIGINT or SIGTERM in the main thread: a checkpoint of the state
    reached is written and the results file closed first).
    """
    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise InputError("exists and is not a folder; give a folder", file=out_dir,
                         key="--out") from None
    except OSError as error:
        raise InputError(f"cannot create the folder ({error.strerror})", file=out_dir,
                         key="--out") from None
    lock = _lock_folder(out_dir)
    try:
        with _StopSignals() as stop:
            return _run_locked(scene, out_dir, progress, resume, checkpoint_minutes,
                               stop_after_frames, overwrite, stop)
    finally:
        lock.close()


def _lock_folder(out_dir):
    """An open file holding an exclusive lock on ``out_dir`` (its ``.bondem.lock``):
    a second run into the same folder is an InputError instead of two writers mixing
    their frames in one file. The lock goes with the process, also when it is killed."""
    try:
        handle = open(out_dir / LOCK_NAME, "a")
    except OSError as error:
        raise InputError(f"cannot write into the folder ({error.strerror})", file=out_dir,
                         key="--out") from None
    try:
        import fcntl
    except ImportError:   # not POSIX: no lock
        return handle
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        raise InputError("another bondem run is writing into this folder; wait for it or "
                         "give another --out", file=out_dir, key="--out") from None
    return handle


def _run_locked(scene, out_dir, progress, resume, checkpoint_minutes, stop_after_frames,
                overwrite, stop):
    results_path = out_dir / RESULTS_NAME
    checkpoint_path = out_dir / CHECKPOINT_NAME
    minutes = scene.checkpoint_minutes if checkpoint_minutes is None else checkpoint_minutes
    watch = EnergyWatch()
    if resume:
        if not checkpoint_path.is_file() or not results_path.is_file():
            raise InputError("nothing to resume: no checkpoint.npz and results.h5 there",
                             file=out_dir, key="--resume")
        try:
            state, frames, scene_text, _ = read_checkpoint(checkpoint_path)
        except Exception as error:  # noqa: BLE001 - any damage: empty, cut, not a zip
            raise InputError(f"cannot read the checkpoint ({type(error).__name__}: {error}); "
                             "run afresh with --overwrite", file=checkpoint_path,
                             key="--resume") from None
        if scene_text != scene.text:
            raise InputError("the scene (with its --set values) differs from the one the "
                             "checkpoint was written with; give the same scene and the same "
                             "--set options to resume, or run afresh with --overwrite",
                             file=scene.path, key="--resume")
        _check_checkpoint_shapes(scene, state, checkpoint_path)
        sim = _simulation(scene, state)
        try:
            writer = ResultsWriter(results_path, sim, resume_frames=frames)
        except ValueError as error:   # UnreadableResults, or fewer frames than the checkpoint
            reason = getattr(error, "reason", str(error))
            raise InputError(f"{reason}; run afresh with --overwrite", file=results_path,
                             key="--resume") from None
        watch.check(sim)                        # the first frame: the checkpoint's
    else:
        clear_outputs(out_dir, overwrite)
        sim = _simulation(scene)
        try:
            writer = ResultsWriter(results_path, sim, scene_text=scene.text,
                                   backend=scene.backend, scene_name=_scene_name(scene.path),
                                   material_names=list(scene.data.get("materials", {}))
                                   or None,
                                   bond_material_names=list(scene.data.get("bond_materials",
                                                                           {})) or None)
            writer.append(sim, watch.check(sim))   # the first frame: t = 0
            write_checkpoint(checkpoint_path, sim.state, frames=writer.n_frames,
                             scene_text=scene.text)
        except SimulationBlowUp as error:
            raise RunFailed(f"{error}{_kept_previous(out_dir)}") from None
        except OSError as error:
            raise RunFailed(f"cannot write into {out_dir} ({error.strerror or error})"
                            f"{_kept_previous(out_dir)}") from None
    state_steps, stride = frame_schedule(scene, sim.time_step)
    total = state_steps
    bar = _progress_bar(progress, total, sim.state.step)
    last_checkpoint = time.monotonic()
    good = sim.state.copy()
    frames_here = 0
    try:
        batch = FIRST_BATCH
        rate = float("inf")   # steps/s of the last batch (unknown before the first)
        while sim.state.step < total:
            if stop_after_frames is not None and frames_here >= stop_after_frames:
                return results_path
            start_step = sim.state.step
            to_frame = min(stride - start_step % stride, total - start_step)
            steps = min(to_frame, batch)
            started = time.monotonic()
            # A batch far slower than the last ones is Numba compiling a kernel that this
            # scene needs only now (the first step, the first wall contact, ...).
            notice = (_compile_notice(bar, max(1.0, 3.0 * steps / rate))
                      if bar is not None else None)
            try:
                sim.step(steps)
                terms = watch.check(sim) if steps == to_frame else None
            except SimulationBlowUp as error:
                write_checkpoint(out_dir / LAST_GOOD_NAME, good, frames=writer.n_frames,
                                 scene_text=scene.text)
                raise RunFailed(f"{error}. The results hold every frame up to "
                                f"t = {good.time:.6g} s; that state is kept in "
                                f"{out_dir / LAST_GOOD_NAME}{_kept_previous(out_dir)}") \
                    from None
            now = time.monotonic()
            # batches of about BATCH_SECONDS, so that checkpoints and the progress bar
            # keep to the wall clock even when frames are hours apart
            if notice is None or not notice.said:
                rate = steps / max(now - started, 1e-9)
            batch = (max(1, min(2 * batch, int(rate * BATCH_SECONDS))) if rate < float("inf")
                     else 2 * batch)
            try:
                if steps == to_frame:
                    writer.append(sim, terms)
                else:
                    writer.append_wall_history(sim)
            except OSError as error:   # a full disk, a folder gone
                raise RunFailed(f"cannot write {results_path} ({error.strerror or error}) "
                                f"at t = {sim.state.time:.6g} s; it holds every frame up "
                                f"to t = {good.time:.6g} s, and the checkpoint lets "
                                f"--resume continue once there is room"
                                f"{_kept_previous(out_dir)}") from None
            if steps == to_frame:
                frames_here += 1
                good = sim.state.copy()
            if notice is not None:
                notice.cancel()
            if notice is not None and notice.said:
                # Restart the clock after a compilation, so that the rate and the ETA are
                # the run's own.
                bar.initial = 0
                bar.set_description("bondem", refresh=False)
                bar.reset(total=total)
                bar.initial = bar.n = bar.last_print_n = sim.state.step
                bar.refresh()
            elif bar is not None:
                bar.update(sim.state.step - start_step)
                bar.set_postfix_str(f"t={sim.state.time:.4g} s, intact bonds="
                                    f"{int(sim.state.bond_active.sum())}/"
                                    f"{sim.model.n_bonds}", refresh=False)
            if now - last_checkpoint >= 60.0 * minutes or sim.state.step >= total:
                try:
                    write_checkpoint(checkpoint_path, sim.state, frames=writer.n_frames,
                                     scene_text=scene.text)
                except OSError as error:
                    raise RunFailed(f"cannot write {checkpoint_path} "
                                    f"({error.strerror or error}); the results hold every "
                                    f"frame up to t = {good.time:.6g} s"
                                    f"{_kept_previous(out_dir)}") from None
                last_checkpoint = now
            if (scene.stop_broken_bonds is not None and steps == to_frame
                    and sim.state.step < total
                    and int((~sim.state.bond_active).sum()) > scene.stop_broken_bonds):
                # MUSEN's STOP_CRITERION BROKEN_BONDS: checked at each saved frame
                write_checkpoint(checkpoint_path, sim.state, frames=writer.n_frames,
                                 scene_text=scene.text)
                break
            if stop.requested is not None and sim.state.step < total:
                _interrupted(stop.requested, sim, writer, good, total, checkpoint_path,
                             scene.text, out_dir)
    finally:
        writer.close()
        if bar is not None:
            bar.close()
    _finished(out_dir)
    return results_path


def _interrupted(number, sim, writer, good, total, checkpoint_path, scene_text, out_dir):
    """Write the checkpoint of a run stopped by signal ``number`` and raise
    RunInterrupted saying what was kept."""
    name = signal.Signals(number).name
    try:
        write_checkpoint(checkpoint_path, sim.state, frames=writer.n_frames,
                         scene_text=scene_text)
    except OSError as error:
        raise RunFailed(f"stopped by {name}, but cannot write {checkpoint_path} "
                        f"({error.strerror or error}); the results hold every frame up to "
                        f"t = {good.time:.6g} s{_kept_previous(out_dir)}") from None
    raise RunInterrupted(
        f"stopped by {name} at t = {sim.state.time:.6g} s (step {sim.state.step} of "
        f"{total}); kept: {writer.n_frames} frames up to t = {good.time:.6g} s in "
        f"{writer.path}, and the state at t = {sim.state.time:.6g} s in {checkpoint_path}"
        f"{_kept_previous(out_dir)}", number)


def _check_checkpoint_shapes(scene, state, path):
    """InputError if the checkpoint's particles or bonds are not the scene's (the scene
    text matches, but a particle or bond file beside it changed)."""
    n, b = scene.model.n_particles, scene.model.n_bonds
    if state.position.shape != (n, 3) or state.bond_active.shape != (b,):
        raise InputError(f"holds {state.position.shape[0]} particles and "
                         f"{state.bond_active.shape[0]} bonds, the scene "
                         f"{n} and {b} (its particle or bond file changed); run afresh "
                         "with --overwrite", file=path, key="--resume")


def _scene_name(path):
    """The scene as a report title names it: its folder and file, e.g. 'examples/impact.toml'
    or 'bondem-demo/scene.toml'."""
    path = Path(path).resolve()
    return f"{path.parent.name}/{path.name}" if path.parent.name else path.name


def _simulation(scene, state=None):
    """scene.make_simulation(state); a backend this machine lacks is an InputError that
    names the scene key."""
    try:
        return scene.make_simulation(state)
    except BackendUnavailable as error:
        raise InputError(str(error), file=scene.path, key="simulation.backend") from None


def _compile_notice(bar, after):
    """A started timer that, if the batch of steps is still running after ``after``
    seconds, says on the progress bar that kernels are compiling; ``.said`` tells whether
    it did."""
    import threading

    def say():
        timer.said = True
        bar.set_description("compiling kernels (first run only)", refresh=True)
    timer = threading.Timer(after, say)
    timer.said = False
    timer.daemon = True
    timer.start()
    return timer


def _progress_bar(progress, total, initial):
    if not progress:
        return None
    from tqdm import tqdm
    return tqdm(total=total, initial=initial, unit="step", dynamic_ncols=True,
                desc="bondem", mininterval=0.5)

"""Run one case from an empty tube to a case file: run length, progress, checkpoints, failures."""

from __future__ import annotations

import contextlib
import hashlib
import logging
import math
import os
import pickle
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
import xarray as xr
import yaml

from analysis.contract import RESTART
from analysis.timeseries import MeanError, mean_error

from .case import Case, defaults, flatten
from .contact import DASHPOT_RESOLVED_RATIO, DASHPOT_WARNING
from .kernels.cache import compile_lock
from .output import DiskFullError, Recorder, global_attributes, out_of_space, write_atomically
from .simulation import FeedBlocked, Simulation, SimulationError, check_threads

log = logging.getLogger("plugsim")

MAX_OVERLAP = 0.2  # fraction of d: beyond this the contact law (and the run) is meaningless
# A wedge's over-compression builds up over frames: at the end of the frame before the one in which
# it passed the bound, a contact was already this fraction of MAX_OVERLAP deep (a collision's
# overlap comes and goes within one contact time, ~0.1 ms of a 10 ms frame).
PERSISTENT = 0.5
# A contact closing slower than this fraction of omega delta (omega = sqrt(k_n/m)) carries less
# than 1 % of its spring's energy as approach: it is pressed, not struck.
QUASI_STATIC = 0.1


class RunError(RuntimeError):
    """A run stopped for a numerical reason; the message is one line."""


class InitialStateError(ValueError):
    """A warm-start file that cannot start this case (missing state, other grains or tube)."""


class OutputPathError(ValueError):
    """An output path that cannot receive the case file (a directory, a missing or read-only folder)."""


class OutputExistsError(ValueError):
    """A file at the output that this run would replace with another result (the message names
    each difference)."""


class NoSpaceError(RuntimeError):
    """The disk filled during a run; the message (one line) names the filesystem, the file being
    written and the checkpoint kept."""


class RunInterrupted(BaseException):  # not swallowed by broad `except Exception` (numba compile)
    """SIGINT or SIGTERM stopped a run; `checkpoint` is the file it resumes from (None: nothing saved)."""

    def __init__(self, signum: int, time: float | None, checkpoint: Path | None):
        super().__init__(signal.Signals(signum).name)
        self.signum, self.time, self.checkpoint = signum, time, checkpoint


def checkpoint_path(out: Path) -> Path:
    return out.with_name(out.name + ".ckpt")


def extends_only(key: str) -> bool:
    """Whether a case key only sets how long a run goes or when it saves (every run.* key but the
    seed): the trajectory up to any time does not depend on it, so a run can be continued with
    another value."""
    return key.startswith("run.") and key != "run.seed"


# keys that change neither a run's trajectory nor when it stops: a finished file is the same result
NO_EFFECT = ("run.checkpoint_interval", "run.progress_interval", "run.warm_start_any")


def case_digest(case: Case) -> str:
    """Digest of what determines a run's trajectory: the keys but those that only extend it, and
    the engine version."""
    from . import __version__
    values = {key: value for key, value in case.items() if not extends_only(key)}
    text = yaml.safe_dump(values, sort_keys=True) + __version__
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def check_output_path(out: Path) -> None:
    """Raise OutputPathError unless a case file can be written at `out` (tried with a probe file)."""
    if out.is_dir():
        raise OutputPathError(f"output {out} is a directory: give a file name, e.g. {out / 'case.nc'}")
    folder = out.parent
    if not folder.is_dir():
        raise OutputPathError(f"output {out}: the directory {folder} does not exist")
    try:
        handle, probe = tempfile.mkstemp(prefix=f".{out.name}.probe-", dir=folder)
        os.close(handle)
        os.unlink(probe)
    except OSError as err:
        raise OutputPathError(f"output {out}: cannot write in {folder} ({err.strerror})") from None


def kernels_compiled() -> bool:
    """Whether numba's on-disk cache holds the main kernels for their current source (else the
    first step compiles them, for up to two minutes)."""
    from .kernels import contacts, slices, stepper
    try:
        return all(kernel._cache._cache_file._load_index()
                   for kernel in (stepper.advance, stepper.rebuild, contacts.evaluate_contacts,
                                  slices.accumulate_slices))
    except Exception:  # numba internals changed: do not guess, announce nothing
        return True


class SteadyWindow(NamedTuple):
    """A steady window [start, end] (s) with the pressure drop (Pa) and the grain mass flows out
    of and into the tube (kg/s) over it."""

    start: float
    end: float
    pressure_drop: MeanError
    outflow: MeanError
    inflow: MeanError


def steady_window(recorder: Recorder, case: Case) -> SteadyWindow | None:
    """The earliest steady window [start, now], or None if not yet steady.

    Candidate starts open run.steady_settle after the first grains leave the tube, then every half
    run.steady_min_window; a window is at least that long. It is steady when (a) the standard
    error of its mean pressure drop (analysis.timeseries.mean_error) is below run.steady_rel_error
    of the mean, or with run.steady_pressure_drop_error set at most that (per tube length), the
    window covering run.steady_min_correlation_times correlation times; with
    run.steady_n_particles_error set, the standard error of the mean grains in the tube at most
    that too; and (b)
    the tube neither fills nor drains: grains go in and come out (mean outflow above twice its
    error), the mean outflow equals the mean inflow within twice their combined error, or within
    one grain over the window (the mass books count whole grains), and the mean grains in the
    tube of the window's halves differ by less than twice the error of that difference, or by
    one grain. The hold-up test is needed: the error of the mean of a rate series counts the
    hold-up's fluctuations as if they accumulated, so the outflow test alone passes a tube filling
    at 4 % of the feed over a 2 s window (tests/engine/test_run.py).
    """
    t = np.asarray(recorder.times)
    out = np.asarray(recorder.series["mass_out"])
    if not len(t) or out[-1] <= 0:
        return None
    first = t[np.argmax(out > 0)] + case["run.steady_settle"]
    length, tol = case["run.steady_min_window"], case["run.steady_rel_error"]
    absolute = case["run.steady_pressure_drop_error"] * case["tube.length"]  # Pa/m -> Pa (the series')
    times, interval = case["run.steady_min_correlation_times"], case["output.interval"]
    dp = np.asarray(recorder.series["pressure_drop"])
    into = np.asarray(recorder.series["mass_in"])
    grains = np.asarray(recorder.series["n_particles"], dtype=float)
    grain = case["particles.density"] * math.pi / 6 * case["particles.diameter"] ** 3
    for start in np.arange(first, t[-1] - length + 1e-9, 0.5 * length):
        k = int(np.argmax(t >= start))
        pressure = mean_error(dp[k:], interval, times)
        precise = pressure.error <= absolute if absolute > 0 else pressure.error < tol * pressure.mean
        if not (pressure.converged and pressure.mean > 0 and precise):
            continue
        outflow = mean_error(np.diff(out[k:]) / interval, interval, times)
        inflow = mean_error(np.diff(into[k:]) / interval, interval, times)
        if _balanced(outflow, inflow, t[-1] - t[k], grain) and _level(
                grains[k:], interval, times, case["run.steady_n_particles_error"]):
            return SteadyWindow(float(start), float(t[-1]), pressure, outflow, inflow)
    return None


def _level(grains: np.ndarray, interval: float, times: float, precision: float = 0.0) -> bool:
    """The grains in the tube do not drift: the means of the series' halves differ by at most
    twice the error of their difference (2 x the error of the whole mean: each half has half the
    samples) or by one grain; with `precision` > 0 the error of the whole mean is at most that."""
    hold = mean_error(grains, interval, times)
    if not hold.converged or (precision > 0 and hold.error > precision):
        return False
    half = len(grains) // 2
    drift = abs(grains[half:].mean() - grains[:half].mean())
    return drift <= 4 * hold.error or drift <= 1.0


def _balanced(outflow: MeanError, inflow: MeanError, duration: float, grain: float) -> bool:
    """Mass out equals mass fed (kg/s) over `duration` s within twice the combined standard error,
    or within one `grain` (kg); a tube that delivers nothing measurable is not balanced."""
    if not (outflow.converged and inflow.converged and inflow.mean > 0):
        return False
    if outflow.mean <= 2 * outflow.error:
        return False
    gap = abs(outflow.mean - inflow.mean)
    return gap <= 2 * math.hypot(outflow.error, inflow.error) or gap * duration <= grain


class Progress:
    """Progress of a run: a tqdm bar on a terminal; otherwise (quiet, or output to a log file) an
    INFO line every `log_interval` seconds of wall time (run.progress_interval; 0: every frame), so
    that a workflow job's log shows it."""

    def __init__(self, total: float, quiet: bool, initial: float = 0.0, log_interval: float = 60.0):
        self.bar = None
        self.total, self.done, self.log_interval = total, initial, log_interval
        self.started = self.last_log = time.monotonic()
        if not quiet and sys.stderr.isatty():
            from tqdm import tqdm
            self.bar = tqdm(total=round(total, 6), initial=round(initial, 6), unit="s(sim)",
                            bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} s [{elapsed}<{remaining}] {postfix}",
                            file=sys.stderr)

    def update(self, sim: Simulation, step: float) -> None:
        self.done += step
        if self.bar is not None:
            self.bar.update(step)
            self.bar.set_postfix_str(f"grains {sim.n_particles}, dp {sim.pressure_drop / 100:.1f} hPa")
            return
        now = time.monotonic()
        if now - self.last_log >= self.log_interval:
            self.last_log = now
            log.info("t = %.2f of at most %.2f s simulated, %d grains, pressure drop %.1f hPa, %.0f s wall",
                     self.done, self.total, sim.n_particles, sim.pressure_drop / 100, now - self.started)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _save_checkpoint(path: Path, sim: Simulation, recorder: Recorder, digest: str, cpu_s: float,
                     stop=None) -> None:
    """Pickle the run to `path` (replaced only when complete; DiskFullError keeps the older one).
    `cpu_s`: CPU seconds of the run so far, all its parts. `stop`: (case, stop_reason, steady
    window) of a run that has ended but whose file could not be written."""
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as handle:
            pickle.dump({"digest": digest, "sim": sim, "recorder": recorder, "stop": stop, "cpu_s": cpu_s},
                        handle, protocol=5)
        os.replace(tmp, path)
    except OSError as err:
        if out_of_space(err, path.parent):
            raise DiskFullError(path) from err
        raise
    finally:
        if tmp.exists():
            tmp.unlink()


def _load_checkpoint(path: Path, digest: str, case: Case):
    """(sim, recorder, stop, cpu_s) of the checkpoint `path` of this case, or None; stop:
    (stop_reason, steady window) when it holds the end of a run whose file was not written, for the
    same keys; cpu_s: CPU seconds of the run so far (NaN from a checkpoint that did not count them)."""
    if not path.exists():
        return None
    with open(path, "rb") as handle:
        state = pickle.load(handle)
    if state.get("digest") != digest:
        log.warning("ignoring checkpoint %s: it belongs to a different case configuration", path)
        return None
    stop = state.get("stop")
    return (state["sim"], state["recorder"], (stop[1:] if stop and stop[0] == case else None),
            state.get("cpu_s", math.nan))


def restart_state(sim: Simulation, digest: str) -> xr.Dataset:
    """The engine's full state (the pickled Simulation) as a byte variable of the case file, from
    which a longer run continues bit for bit."""
    var = RESTART["restart_state"]
    data = np.frombuffer(pickle.dumps(sim, protocol=5), dtype=var.dtype)
    return xr.Dataset({var.name: (var.dims, data, {"long_name": var.long_name, "units": var.units,
                                                   "digest": digest})})


def _load_finished(out: Path, case: Case, digest: str, frames: int):
    """(sim, recorder, None, cpu_s) at the end of the finished case file `out` when it can be
    continued to `frames` output frames of `case`: same digest, stopped for lack of time, fewer
    frames; cpu_s: the CPU seconds of the run that wrote it, all its parts."""
    if not out.is_file():
        return None
    try:
        with xr.open_dataset(out) as ds:
            if ("restart_state" not in ds or ds.restart_state.attrs.get("digest") != digest
                    or ds.attrs.get("stop_reason") not in ("duration", "max_duration")
                    or ds.sizes["time"] - 1 >= frames):
                return None
            sim = pickle.loads(ds.restart_state.values.tobytes())
            cpu_s = float(ds.attrs.get("cpu_time_total_s", math.nan))
            return sim, Recorder.from_dataset(ds.load(), case, sim), None, cpu_s
    except Exception as err:  # unreadable, or a state the code cannot load: run from the start
        log.warning("not continuing %s (%s): running from the start", out, str(err).splitlines()[0])
        return None


def _same_start(there: str, here: str | Path | None) -> bool:
    """Whether the warm-start file recorded in a case file (resolved path, or as given) is `here`."""
    here = "" if here is None else str(here)
    if not there or not here:
        return there == here
    return there == here or Path(there).resolve() == Path(here).resolve()


def _spelt(value) -> str:
    """A key's value as --set takes it (true, not True)."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def finished_case(out: Path, case: Case, initial_state: str | Path | None) -> str | None:
    """What to do with a file already at `out`: None when there is none, or when this run continues
    it to a longer run.duration; the one-line notice when it holds this very run (nothing to do).
    Raises OutputExistsError, naming each key that differs (file -> this run), when the run would
    replace it with another result."""
    if not out.exists():
        return None
    from . import __version__
    try:
        with xr.open_dataset(out, engine="netcdf4") as ds:
            attrs, end = dict(ds.attrs), float(ds.time.values[-1])
            digest = ds.restart_state.attrs.get("digest") if "restart_state" in ds else None
        raw = yaml.safe_load(attrs["config_yaml"])
    except Exception:  # not a readable case file: not replaced unasked either
        raise OutputExistsError(f"output {out} exists and is not a plugsim case file; --overwrite replaces "
                                f"it, or choose another --out") from None
    there = {**defaults(), **flatten(raw if isinstance(raw, dict) else {})}
    here = dict(case.items())
    changed = {key: (there.get(key, "(none)"), here.get(key, "(none)")) for key in sorted(set(there) | set(here))
               if key not in NO_EFFECT and there.get(key) != here.get(key)}
    if attrs.get("engine_version") != __version__:
        changed["engine version"] = (attrs.get("engine_version"), __version__)
    start = digest.partition(":")[2] if digest else str(attrs.get("initial_state", ""))
    if not _same_start(start, initial_state):
        changed["--initial-state"] = (start or "(none)", str(initial_state or "(none)"))
    reason = attrs.get("stop_reason")
    done = f"{out} is complete (stop_reason {reason}, t = {end:.3f} s): nothing to do (--overwrite runs it again)"
    if not changed:
        return done
    longer = "run.duration" in changed and changed["run.duration"][1] > changed["run.duration"][0]
    if longer and all(extends_only(key) for key in changed):
        if len(changed) == 1 and reason in ("steady", "blocked"):
            return done  # it ended on its own before the old run.duration, as it would before the new
        if reason in ("duration", "max_duration"):
            if digest is None:
                raise OutputExistsError(f"output {out} holds a finished run without the state to continue it "
                                        f"(no restart_state); --overwrite runs the case again from the start")
            return None
    differences = ", ".join(f"{key} {_spelt(old)} -> {_spelt(new)}" for key, (old, new) in changed.items())
    raise OutputExistsError(f"output {out} holds a finished run (stop_reason {reason}, t = {end:.3f} s) that "
                            f"this one would replace (file -> this run): {differences}; --overwrite "
                            f"replaces it, or choose another --out")


class _Signals:
    """SIGINT and SIGTERM while a run is inside it: before `armed` (nothing new to save) they stop
    it at once; afterwards the first one is noted in `received`, for the loop to save a checkpoint at
    the next frame boundary, and a second one stops it at once."""

    def __init__(self, early_exit=None):
        self.armed, self.received, self.previous = False, None, {}
        self.early_exit = early_exit

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                self.previous[signum] = signal.signal(signum, self._handle)
        return self

    def _handle(self, signum, frame):
        if not self.armed or self.received is not None:
            interrupted = RunInterrupted(signum, None, None)
            if self.early_exit is not None:
                # an exception raised here can be lost inside numba's compiler (a C callback
                # ignores it), so a caller that may end the process does so at once
                self.early_exit(interrupted)
            raise interrupted
        self.received = signum

    def __exit__(self, *exc):
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)
        return False


def read_initial_state(path: str | Path, case: Case) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, velocities, angular velocities of the grains at the end of case file `path`, for
    a warm start of `case`; grains beyond case's tube length are left out. Raises
    InitialStateError (naming the file and the mismatch) when the grains or the tube
    cross-section differ, or the file is not a case file, and, unless run.warm_start_any, when
    the tube length or inclination differ (with it, logs one line saying what changed)."""
    path = Path(path)
    if not path.exists():
        raise InitialStateError(f"initial state {path}: no such file")
    if not path.is_file():
        raise InitialStateError(f"initial state {path}: not a file (a case file .nc is needed)")
    try:
        ds = xr.open_dataset(path, engine="netcdf4")
    except (OSError, ValueError):
        raise InitialStateError(f"initial state {path}: not a NetCDF case file (as plugsim run writes)") from None
    with ds:
        if "final_position" not in ds:
            raise InitialStateError(f"initial state {path}: no final_position (written by plugsim >= 0.2)")
        for attr, key in (("tube_diameter", "tube.diameter"), ("particle_diameter", "particles.diameter"),
                          ("particle_density", "particles.density")):
            if attr not in ds.attrs:
                raise InitialStateError(f"initial state {path}: no {attr} attribute (not a plugsim case file)")
            if not math.isclose(float(ds.attrs[attr]), case[key], rel_tol=1e-9):
                raise InitialStateError(f"initial state {path}: {key} = {float(ds.attrs[attr]):g} there, "
                                 f"{case[key]:g} here; a warm start needs the same grains and tube cross-section")
        changed = []
        for attr, key, unit in (("inclination_deg", "tube.inclination_deg", "degree"), ("tube_length", "tube.length", "m")):
            if attr not in ds.attrs:
                raise InitialStateError(f"initial state {path}: no {attr} attribute (not a plugsim case file)")
            if not math.isclose(float(ds.attrs[attr]), case[key], rel_tol=1e-9, abs_tol=1e-12):
                changed.append(f"{key} = {float(ds.attrs[attr]):g} there, {case[key]:g} here ({unit})")
        pos, vel, omg = (ds[name].values.astype(float) for name in
                         ("final_position", "final_velocity", "final_angular_velocity"))
    keep = pos[:, 0] <= case["tube.length"]
    if changed and not case["run.warm_start_any"]:
        raise InitialStateError(f"initial state {path}: {'; '.join(changed)}; a warm start across tube length or "
                                f"inclination drops grains or turns gravity: --set run.warm_start_any=true "
                                f"accepts it")
    if changed:
        dropped = int((~keep).sum())
        log.warning("warm start from %s: %s: %d of %d grains kept, %d beyond x = %g m dropped", path,
                    "; ".join(changed), len(pos) - dropped, len(pos), dropped, case["tube.length"])
    return pos[keep], vel[keep], omg[keep]


def run_case(case: Case, out: str | Path, quiet: bool = True, initial_state: str | Path | None = None,
             threads: int = 1, early_exit=None, overwrite: bool = False) -> Path:
    """Run `case` from an empty tube, or from the grains at the end of the case file
    `initial_state` (warm start), or from its checkpoint, or continue the finished case file `out`
    to a longer run.duration, and write the case file `out`. A file at `out` that holds this run
    is left as it is (logged); one that this run would replace with another result raises
    OutputExistsError unless `overwrite` (then the case runs from the start, or from its
    checkpoint). `threads`: numba threads for the contact forces (a resumed run keeps its
    checkpoint's). SIGINT and SIGTERM save a checkpoint at the next frame boundary and raise
    RunInterrupted; before the first frame (nothing to save) they call `early_exit(RunInterrupted)`
    if given (the command line ends the process there), then raise. A full disk raises
    NoSpaceError, the last checkpoint kept."""
    with _Signals(early_exit) as signals:
        return _run_case(case, Path(out), quiet, initial_state, threads, signals, overwrite)


def _run_case(case: Case, out: Path, quiet: bool, initial_state: str | Path | None, threads: int,
              signals: _Signals, overwrite: bool) -> Path:
    check_threads(threads)
    check_output_path(out)
    if not overwrite:
        done = finished_case(out, case, initial_state)
        if done:
            log.warning("%s", done)  # shown with --quiet too: the command did nothing
            return out
    start = read_initial_state(initial_state, case) if initial_state else None
    digest = case_digest(case) + (f":{Path(initial_state).resolve()}" if initial_state else "")
    ckpt = checkpoint_path(out)
    interval, duration = case["output.interval"], case["run.duration"]
    frames = int(round(duration / interval))
    resumed = _load_checkpoint(ckpt, digest, case)
    if resumed and len(resumed[1].times) - 1 > frames:
        log.warning("ignoring checkpoint %s: it is past run.duration = %g s", ckpt, duration)
        resumed = None
    saved = resumed[0].time if resumed else None  # simulated time of the checkpoint on disk
    if resumed:
        log.info("resuming %s from t = %.3f s", out, resumed[0].time)
    elif not overwrite:
        resumed = _load_finished(out, case, digest, frames)
        if resumed:
            log.info("continuing %s from its end, t = %.3f s, to %g s", out, resumed[0].time, duration)

    def no_space(err: DiskFullError, t: float) -> NoSpaceError:
        kept = (f"checkpoint {ckpt} (t = {saved:.3f} s) kept: free space there and run the same command to resume"
                if saved is not None and ckpt.exists() else "no checkpoint saved: free space there and run the same "
                "command to start again")
        return NoSpaceError(f"{err}; the run stopped at t = {t:.3f} s, {kept}")

    # A run that finds the kernels uncompiled holds the cache's lock until its first frame is done,
    # so that they are compiled and saved by one process; another such run waits, then loads them
    # (docs/decisions/0022).
    first_compile = contextlib.ExitStack()
    if not kernels_compiled():
        first_compile.enter_context(compile_lock(on_wait=lambda: log.info(
            "waiting for another run compiling the kernels into the same cache")))
        if kernels_compiled():  # that run has finished them
            first_compile.close()
        else:
            log.info("compiling kernels (first run only, up to two minutes)")
    stop = None
    try:
        if resumed:
            sim, recorder, stop, cpu_before = resumed
            sim.case = recorder.case = case  # differs at most in keys that only extend a run
        else:
            sim, recorder, cpu_before = Simulation(case, threads), Recorder(case), 0.0
            if start is not None:
                sim.add_particles(*start)
                log.info("warm start from %s: %d grains", initial_state, len(start[0]))
            recorder.sample(sim)
    except BaseException:
        first_compile.close()
        raise
    if not sim.model.dashpot_resolved:
        log.warning("case %s: tangential dashpot gamma_t dt/(m/7) = %.2f above %.2f: %s", out.name,
                    sim.model.dashpot_step_ratio, DASHPOT_RESOLVED_RATIO, DASHPOT_WARNING)
    log.info("case %s: dt = %.3g s, %d gas nodes, feed %.3g kg/h, until %s", out.name, sim.dt,
             case["gas.nodes_x"] * case["gas.nodes_y"] * case["gas.nodes_z"] if case["gas.enabled"] else 0,
             case["feed.mass_flow_kg_h"], "steady" if case["run.until_steady"] else f"{case['run.duration']} s")
    progress = Progress(frames * interval, quiet, initial=(len(recorder.times) - 1) * interval,
                        log_interval=case["run.progress_interval"])
    last_save = started = time.monotonic()
    cpu_started = time.process_time()

    def cpu_total() -> float:
        """CPU seconds of the run, its earlier parts included (NaN if one of them was not counted)."""
        return cpu_before + time.process_time() - cpu_started

    reason, window = stop or ("duration", None)  # stop: the run had ended, its file not written
    previous_overlap = sim.overlap  # at the end of the last frame: the wedge test's build-up
    if case["run.until_steady"] and resumed and not stop:  # a longer run continued: steady already?
        window = steady_window(recorder, case)
    try:
        for _ in range(len(recorder.times) - 1, frames if window is None and not stop else 0):
            sim.advance(interval)
            recorder.sample(sim)
            first_compile.close()  # the kernels of a frame are compiled and saved
            wedged = _check_health(sim, recorder.series["piston_force"][-1], previous_overlap)
            if wedged:
                raise wedged
            previous_overlap = sim.overlap
            sim.reset_max_overlap()  # the frame's largest overlap is recorded and checked
            signals.armed = True  # before the progress line: a signal sent on seeing it saves a checkpoint
            progress.update(sim, interval)
            if case["run.until_steady"]:
                window = steady_window(recorder, case)
                if window:
                    break
            if signals.received is not None:
                _save_checkpoint(ckpt, sim, recorder, digest, cpu_total())
                raise RunInterrupted(signals.received, sim.time, ckpt)
            if case["run.checkpoint_interval"] > 0 and time.monotonic() - last_save > case["run.checkpoint_interval"]:
                _save_checkpoint(ckpt, sim, recorder, digest, cpu_total())
                saved, last_save = sim.time, time.monotonic()
    except FeedBlocked as err:  # a result, not a failure: the file says so (stop_reason blocked)
        _check_health(sim, previous_overlap=previous_overlap)  # unless the state is broken: a failure
        reason = "blocked"
        log.warning("case %s: %s; the run ends here", out.name, err)
    except SimulationError as err:
        raise RunError(str(err)) from err
    except DiskFullError as err:
        raise no_space(err, sim.time) from None
    except RunInterrupted as err:
        if err.checkpoint is None and ckpt.exists():
            err.checkpoint = ckpt  # stopped before a new frame: the older checkpoint still resumes
        raise
    finally:
        first_compile.close()
        progress.close()
    if window:
        reason = "steady"
    elif case["run.until_steady"] and reason != "blocked":
        reason = "max_duration"
    wall = time.monotonic() - started
    extra = {"stop_reason": reason, "time_step": sim.dt,
             # dashpot_resolved 0 (ratio above DASHPOT_RESOLVED_RATIO, explicit spin kick): a packed
             # bed in this case is not converged in the step
             "dashpot_step_ratio": sim.model.dashpot_step_ratio,
             "dashpot_resolved": int(sim.model.dashpot_resolved),
             # wall time of this process's part of the run (after a resume: since the resume)
             "wall_time_s": wall, "resumed": int(bool(resumed)),
             # CPU time of the same part: the cost measure of the work-precision study (less
             # sensitive than wall time to other jobs sharing the machine)
             "cpu_time_s": time.process_time() - cpu_started,
             # CPU time of the whole run, its earlier parts (checkpoints, a shorter run continued)
             # included: what the case cost; NaN when a part was saved without its count
             "cpu_time_total_s": cpu_total(),
             "threads": sim.threads,
             "initial_state": str(initial_state or ""),
             "initial_particles": 0 if start is None else len(start[0]),
             # mass in the tube = initial_mass + mass_in - mass_out
             "initial_mass": 0.0 if start is None else len(start[0]) * sim.model.mass,
             "blocked_time": sim.time if reason == "blocked" else math.nan,
             **_steady_attributes(window)}
    try:
        write_atomically(recorder.dataset(global_attributes(case, extra)).merge(Recorder.final_state(sim))
                         .merge(restart_state(sim, digest)), out)
    except DiskFullError as err:
        try:  # the end of the run, to write its file from once space is freed
            _save_checkpoint(ckpt, sim, recorder, digest, cpu_total(), stop=(case, reason, window))
            saved = sim.time
        except DiskFullError:
            pass  # the older checkpoint, if any, is still there
        raise no_space(err, sim.time) from None
    if ckpt.exists():
        ckpt.unlink()
    log.info("wrote %s (%s, t = %.3f s)", out, reason, sim.time)
    return out


def _steady_attributes(window: SteadyWindow | None) -> dict:
    """Case-file attributes of the steady window (NaN without one): its start and end (s), the
    mean pressure drop and its standard error (Pa), its correlation time (s), the mean grain mass
    flows out and in (kg/s)."""
    nan = math.nan
    if window is None:
        return dict.fromkeys(("steady_start", "steady_end", "steady_pressure_drop",
                              "steady_pressure_drop_sem", "steady_correlation_time",
                              "steady_outflow", "steady_inflow"), nan)
    return {"steady_start": window.start, "steady_end": window.end,
            "steady_pressure_drop": window.pressure_drop.mean,
            "steady_pressure_drop_sem": window.pressure_drop.error,
            "steady_correlation_time": window.pressure_drop.tau_s,
            "steady_outflow": window.outflow.mean, "steady_inflow": window.inflow.mean}


def _check_health(sim: Simulation, piston_force: float = math.nan,
                  previous_overlap: float = 0.0) -> FeedBlocked | None:
    """Raise RunError if the state is broken (a non-finite pressure drop, an overlap beyond
    MAX_OVERLAP d since the last reset); an overlap beyond it that is the enforced feed wedging a
    column (feed_wedged, given the largest overlap at the previous frame's end, m) is returned as
    FeedBlocked instead, with `piston_force` (N, the mean over the frame) and the gas force in its
    message."""
    d = 2 * sim.model.radius
    if not math.isfinite(sim.pressure_drop):
        raise RunError(f"the pressure drop became non-finite at t = {sim.time:.4f} s")
    if sim.max_overlap <= MAX_OVERLAP * d:
        return None
    if feed_wedged(sim, previous_overlap):
        return FeedBlocked(
            f"the tube is blocked at t = {sim.time:.4f} s: the enforced feed pressed the column it pushes "
            f"to an overlap of {sim.max_overlap / d:.2f} d, beyond the bound {MAX_OVERLAP} d (piston "
            f"force {piston_force:.2f} N, gas force on the grains {sim.gas_force:.3f} N, "
            f"{sim.n_particles} grains)")
    raise RunError(f"grain overlap {sim.max_overlap / d:.2f} d exceeds the bound {MAX_OVERLAP} d at "
                   f"t = {sim.time:.4f} s: the time step or stiffness is unsuitable for this case")


def feed_wedged(sim: Simulation, previous_overlap: float) -> bool:
    """Whether the overlap beyond the run guard in the frame just ended is the enforced feed
    wedging a column the gas and walls hold, not a step or stiffness too coarse for a collision
    (docs/decisions/0020-wedged-column-is-blocked.md).

    The over-compression built up: the largest overlap at the previous frame's end,
    `previous_overlap` (m), was at least PERSISTENT x MAX_OVERLAP d. And at this frame's end each
    contact at least that deep (none if the column has just slipped) is quasi-static (closes
    slower than QUASI_STATIC omega delta; a blown-up column vibrates at the contact frequency) and
    hangs on the piston (its grain touches, through a chain of touching grains, a feed grain or a
    grain on the inlet wall, which holds the column between two feed layers)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    depth = PERSISTENT * MAX_OVERLAP * 2 * sim.model.radius
    if previous_overlap < depth:
        return False
    c = sim.contacts()
    deep = c["overlap"] >= depth
    if not deep.any():
        return True
    omega = math.sqrt(sim.model.stiffness / sim.model.mass)
    if np.any(np.abs(c["closing"][deep]) >= QUASI_STATIC * omega * c["overlap"][deep]):
        return False
    pair = c["j"] >= 0
    n = len(c["in_feed"])
    graph = coo_matrix((np.ones(pair.sum()), (c["i"][pair], c["j"][pair])), shape=(n, n))
    label = connected_components(graph, directed=False)[1]
    held = np.zeros(n, dtype=bool)
    held[c["in_feed"]] = True
    held[c["i"][c["inlet"]]] = True
    return bool(np.isin(label[c["i"][deep]], label[held]).all())

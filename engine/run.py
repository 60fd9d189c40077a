"""Run one case from an empty tube to a case file: run length, progress, checkpoints, failures."""

from __future__ import annotations

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

from analysis.timeseries import MeanError, mean_error

from .case import Case
from .contact import DASHPOT_RESOLVED_RATIO, DASHPOT_WARNING
from .output import Recorder, global_attributes, write_atomically
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
    of the mean, the window covering run.steady_min_correlation_times correlation times, and (b)
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
    times, interval = case["run.steady_min_correlation_times"], case["output.interval"]
    dp = np.asarray(recorder.series["pressure_drop"])
    into = np.asarray(recorder.series["mass_in"])
    grains = np.asarray(recorder.series["n_particles"], dtype=float)
    grain = case["particles.density"] * math.pi / 6 * case["particles.diameter"] ** 3
    for start in np.arange(first, t[-1] - length + 1e-9, 0.5 * length):
        k = int(np.argmax(t >= start))
        pressure = mean_error(dp[k:], interval, times)
        if not (pressure.converged and pressure.mean > 0 and pressure.error < tol * pressure.mean):
            continue
        outflow = mean_error(np.diff(out[k:]) / interval, interval, times)
        inflow = mean_error(np.diff(into[k:]) / interval, interval, times)
        if _balanced(outflow, inflow, t[-1] - t[k], grain) and _level(grains[k:], interval, times):
            return SteadyWindow(float(start), float(t[-1]), pressure, outflow, inflow)
    return None


def _level(grains: np.ndarray, interval: float, times: float) -> bool:
    """The grains in the tube do not drift: the means of the series' halves differ by at most
    twice the error of their difference (2 x the error of the whole mean: each half has half the
    samples) or by one grain."""
    hold = mean_error(grains, interval, times)
    if not hold.converged:
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
    INFO line every `log_interval` seconds of wall time, so that a workflow job's log shows it."""

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


def _save_checkpoint(path: Path, sim: Simulation, recorder: Recorder, digest: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as handle:
            pickle.dump({"digest": digest, "sim": sim, "recorder": recorder}, handle, protocol=5)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _load_checkpoint(path: Path, digest: str):
    if not path.exists():
        return None
    with open(path, "rb") as handle:
        state = pickle.load(handle)
    if state.get("digest") != digest:
        log.warning("ignoring checkpoint %s: it belongs to a different case configuration", path)
        return None
    return state["sim"], state["recorder"]


def restart_state(sim: Simulation, digest: str) -> xr.Dataset:
    """The engine's full state (the pickled Simulation) as a byte variable of the case file, from
    which a longer run continues bit for bit."""
    data = np.frombuffer(pickle.dumps(sim, protocol=5), dtype=np.uint8)
    return xr.Dataset({"restart_state": ("restart_byte", data, {
        "long_name": "full engine state at the end of the run (pickled), to continue it to a longer "
                     "run.duration", "units": "1", "digest": digest})})


def _load_finished(out: Path, case: Case, digest: str, frames: int):
    """(sim, recorder) at the end of the finished case file `out` when it can be continued to
    `frames` output frames of `case`: same digest, stopped for lack of time, fewer frames."""
    if not out.is_file():
        return None
    try:
        with xr.open_dataset(out) as ds:
            if ("restart_state" not in ds or ds.restart_state.attrs.get("digest") != digest
                    or ds.attrs.get("stop_reason") not in ("duration", "max_duration")
                    or ds.sizes["time"] - 1 >= frames):
                return None
            sim = pickle.loads(ds.restart_state.values.tobytes())
            return sim, Recorder.from_dataset(ds.load(), case, sim)
    except Exception as err:  # unreadable, or a state the code cannot load: run from the start
        log.warning("not continuing %s (%s): running from the start", out, str(err).splitlines()[0])
        return None


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
    cross-section differ, or the file is not a case file."""
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
        pos, vel, omg = (ds[name].values.astype(float) for name in
                         ("final_position", "final_velocity", "final_angular_velocity"))
    keep = pos[:, 0] <= case["tube.length"]
    return pos[keep], vel[keep], omg[keep]


def run_case(case: Case, out: str | Path, quiet: bool = True, initial_state: str | Path | None = None,
             threads: int = 1, early_exit=None) -> Path:
    """Run `case` from an empty tube, or from the grains at the end of the case file
    `initial_state` (warm start), or from its checkpoint, or continue the finished case file `out`
    to a longer run.duration, and write the case file `out`. `threads`: numba threads for the
    contact forces (a resumed run keeps its checkpoint's). SIGINT and SIGTERM save a checkpoint at
    the next frame boundary and raise RunInterrupted; before the first frame (nothing to save) they
    call `early_exit(RunInterrupted)` if given (the command line ends the process there), then raise."""
    with _Signals(early_exit) as signals:
        return _run_case(case, Path(out), quiet, initial_state, threads, signals)


def _run_case(case: Case, out: Path, quiet: bool, initial_state: str | Path | None, threads: int,
              signals: _Signals) -> Path:
    check_threads(threads)
    check_output_path(out)
    start = read_initial_state(initial_state, case) if initial_state else None
    digest = case_digest(case) + (f":{Path(initial_state).resolve()}" if initial_state else "")
    ckpt = checkpoint_path(out)
    interval, duration = case["output.interval"], case["run.duration"]
    frames = int(round(duration / interval))
    resumed = _load_checkpoint(ckpt, digest)
    if resumed and len(resumed[1].times) - 1 > frames:
        log.warning("ignoring checkpoint %s: it is past run.duration = %g s", ckpt, duration)
        resumed = None
    if resumed:
        log.info("resuming %s from t = %.3f s", out, resumed[0].time)
    else:
        resumed = _load_finished(out, case, digest, frames)
        if resumed:
            log.info("continuing %s from its end, t = %.3f s, to %g s", out, resumed[0].time, duration)
    if not kernels_compiled():
        log.info("compiling kernels (first run only, up to two minutes)")
    if resumed:
        sim, recorder = resumed
        sim.case = recorder.case = case  # differs at most in keys that only extend a run
    else:
        sim, recorder = Simulation(case, threads), Recorder(case)
        if start is not None:
            sim.add_particles(*start)
            log.info("warm start from %s: %d grains", initial_state, len(start[0]))
        recorder.sample(sim)
    if not sim.model.dashpot_resolved:
        log.warning("case %s: tangential dashpot gamma_t dt/(m/7) = %.2f above %.2f: %s", out.name,
                    sim.model.dashpot_step_ratio, DASHPOT_RESOLVED_RATIO, DASHPOT_WARNING)
    log.info("case %s: dt = %.3g s, %d gas nodes, feed %.3g kg/h, until %s", out.name, sim.dt,
             case["gas.nodes_x"] * case["gas.nodes_y"] * case["gas.nodes_z"] if case["gas.enabled"] else 0,
             case["feed.mass_flow_kg_h"], "steady" if case["run.until_steady"] else f"{case['run.duration']} s")
    progress = Progress(frames * interval, quiet, initial=(len(recorder.times) - 1) * interval)
    last_save = started = time.monotonic()
    cpu_started = time.process_time()
    reason, window = "duration", None
    previous_overlap = sim.overlap  # at the end of the last frame: the wedge test's build-up
    if case["run.until_steady"] and resumed:  # a longer run continued: steady already?
        window = steady_window(recorder, case)
    try:
        for _ in range(len(recorder.times) - 1, frames if window is None else 0):
            sim.advance(interval)
            recorder.sample(sim)
            wedged = _check_health(sim, recorder.series["piston_force"][-1], previous_overlap)
            if wedged:
                raise wedged
            previous_overlap = sim.overlap
            sim.reset_max_overlap()  # the frame's largest overlap is recorded and checked
            progress.update(sim, interval)
            signals.armed = True
            if case["run.until_steady"]:
                window = steady_window(recorder, case)
                if window:
                    break
            if signals.received is not None:
                _save_checkpoint(ckpt, sim, recorder, digest)
                raise RunInterrupted(signals.received, sim.time, ckpt)
            if case["run.checkpoint_interval"] > 0 and time.monotonic() - last_save > case["run.checkpoint_interval"]:
                _save_checkpoint(ckpt, sim, recorder, digest)
                last_save = time.monotonic()
    except FeedBlocked as err:  # a result, not a failure: the file says so (stop_reason blocked)
        _check_health(sim, previous_overlap=previous_overlap)  # unless the state is broken: a failure
        reason = "blocked"
        log.warning("case %s: %s; the run ends here", out.name, err)
    except SimulationError as err:
        raise RunError(str(err)) from err
    except RunInterrupted as err:
        if err.checkpoint is None and ckpt.exists():
            err.checkpoint = ckpt  # stopped before a new frame: the older checkpoint still resumes
        raise
    finally:
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
             "threads": sim.threads,
             "initial_state": str(initial_state or ""),
             "initial_particles": 0 if start is None else len(start[0]),
             # mass in the tube = initial_mass + mass_in - mass_out
             "initial_mass": 0.0 if start is None else len(start[0]) * sim.model.mass,
             "blocked_time": sim.time if reason == "blocked" else math.nan,
             **_steady_attributes(window)}
    write_atomically(recorder.dataset(global_attributes(case, extra)).merge(Recorder.final_state(sim))
                     .merge(restart_state(sim, digest)), out)
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

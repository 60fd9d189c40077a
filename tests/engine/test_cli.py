"""The `plugsim` command line: bad input (exit 2, one line, before any work), interrupts and resume,
continuing a run to a longer duration, --version, the compile notice."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import engine
from engine import Case
from engine.cli import main
from engine.run import case_digest, checkpoint_path, kernels_compiled, run_case

ROOT = Path(__file__).resolve().parents[2]
CASE = ROOT / "config" / "cases" / "horizontal.yaml"
# grains only in a 2.1 cm tube: ~0.3 s of CPU per 0.1 s simulated once it is full
TINY = ["gas.enabled=false", "tube.length=0.021"]


def sets(overrides):
    return [arg for o in overrides for arg in ("--set", o)]


def plugsim(*args, **kw):
    return subprocess.run([sys.executable, "-m", "engine.cli", *args], capture_output=True, text=True, **kw)


@pytest.fixture
def refused(tmp_path, capsys, monkeypatch):
    """Run `plugsim ARGS` in tmp_path; assert exit 2, one line on stderr, nothing written; return it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "broken.yaml").write_text("tube:\n  length: [0.5\n")
    (tmp_path / "notes.txt").write_text("not a case file\n")
    (tmp_path / "fitted.yaml").write_text("all_cases:\n  gas.viscosty: 6.0e-05\n")

    def run(*args):
        before = set(tmp_path.iterdir())
        try:
            code = main([str(a) for a in args])
        except SystemExit as exit_:  # argparse's own errors
            code = exit_.code
        assert code == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1, lines
        assert set(tmp_path.iterdir()) == before, "bad input must not leave files"
        return lines[0]
    return run


@pytest.mark.parametrize("args, message", [
    (["run", "broken.yaml", "--out", "x.nc"],
     "case file 'broken.yaml' is not valid YAML: line 3, column 1: expected ',' or ']'"),
    (["check", "broken.yaml"], "case file 'broken.yaml' is not valid YAML: line 3"),
    (["check", "."], "case file '.' is not a file"),
    (["check", CASE, "--set", "gas.viscosity=[1,"], "override 'gas.viscosity=[1,': the value is not valid YAML"),
    (["run", CASE, "--out", "x.nc", "--set", "run.duration=0.005"],
     "run.duration = 0.005 s must be >= output.interval = 0.01 s"),
    (["run", CASE, "--out", "x.nc", "--initial-state", "missing.nc"], "initial state missing.nc: no such file"),
    (["run", CASE, "--out", "x.nc", "--initial-state", "."], "initial state .: not a file"),
    (["run", CASE, "--out", "x.nc", "--initial-state", "notes.txt"],
     "initial state notes.txt: not a NetCDF case file"),
    (["run", CASE, "--out", "x.nc", "--initial-state", "broken.yaml"],
     "initial state broken.yaml: not a NetCDF case file"),
    (["run", CASE, "--out", "."], "output . is a directory"),
    (["run", CASE, "--out", "no/such/dir/x.nc"], "output no/such/dir/x.nc: the directory no/such/dir does not exist"),
    # /proc refuses new files even to root, who may write in any ordinary directory
    (["run", CASE, "--out", "/proc/x.nc"], "output /proc/x.nc: cannot write in /proc"),
    (["run", CASE, "--out", "x.nc", "--threads", "0"], "--threads: threads = 0: allowed 1 to"),
    (["run", CASE], "plugsim run: error: the following arguments are required: --out"),
    (["check", CASE, "--overlay", "notes.txt"], "overlay 'notes.txt' must hold a mapping `all_cases`"),
    (["check", CASE, "--overlay", "missing.yaml"], "overlay 'missing.yaml' cannot be read"),
    (["check", CASE, "--overlay", "fitted.yaml"], "overlay 'fitted.yaml': unknown key 'gas.viscosty' (did you mean 'gas.viscosity'?)"),
    (["bench", "--steps", "0"], "plugsim bench: error: --steps = 0: allowed 1 or more"),
    (["bench", "--repeats", "-1"], "plugsim bench: error: --repeats = -1: allowed 1 or more"),
    (["bench", "--threads", "999"], "plugsim bench: error: --threads: threads = 999"),
    (["bench", "--write-lammps", "/proc/lammps"], "plugsim bench: error: --write-lammps /proc/lammps: cannot create"),
])
def test_bad_input_exits_2_with_one_line_before_any_work(refused, args, message):
    assert message in refused(*args)


def test_overlay_keys_apply_before_set(tmp_path, capsys):
    """A calibration's fitted.yaml (`all_cases`) sets its keys; --set still wins."""
    overlay = tmp_path / "fitted.yaml"
    overlay.write_text("all_cases:\n  gas.viscosity: 6.0e-05\n  particles.friction: 0.4\n  wall.friction: 0.4\n")
    import argparse

    from engine.cli import _case
    args = argparse.Namespace(case=str(CASE), overlay=[str(overlay)], set=["particles.friction=0.3"])
    case = _case(args)
    assert case["gas.viscosity"] == 6.0e-05 and case["wall.friction"] == 0.4 and case["particles.friction"] == 0.3
    assert main(["check", str(CASE), "--overlay", str(overlay)]) == 0


def test_a_directory_as_output_is_refused_before_the_run(tmp_path):
    """Checked up front: a run that would take minutes is refused in the time of the start-up."""
    started = time.monotonic()
    res = plugsim("run", str(CASE), "--out", str(tmp_path), "--set", "run.duration=1000")
    assert res.returncode == 2 and res.stderr.strip().splitlines() == [
        f"plugsim: error: output {tmp_path} is a directory: give a file name, e.g. {tmp_path / 'case.nc'}"]
    assert time.monotonic() - started < 60  # 1000 s simulated would take hours


def test_keys_into_a_closed_pipe_ends_quietly():
    """`plugsim keys | head`: the reader goes away; no BrokenPipeError traceback, the status of a
    process ended by SIGPIPE (141) as other Unix tools give."""
    proc = subprocess.Popen([sys.executable, "-m", "engine.cli", "keys"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # before it writes: its first write meets a pipe with no reader
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141 and err == ""


def test_run_help_names_every_way_a_run_starts(capsys):
    """`plugsim --help` and `plugsim run --help` say that a run starts from an empty tube, resumes
    from its checkpoint, continues a finished file to a longer duration or warm-starts, and that a
    finished file is not replaced without --overwrite."""
    for argv in (["--help"], ["run", "--help"]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 0
        text = " ".join(capsys.readouterr().out.split())
        for words in ("empty tube", "checkpoint", "--initial-state"):
            assert words in text, f"plugsim {' '.join(argv)}: {words!r} missing"
        if argv == ["run", "--help"]:
            for words in ("resumes from its checkpoint", "continues OUT from its end", "warm start",
                          "unless --overwrite"):
                assert words in text, f"plugsim run --help: {words!r} missing"


def test_version_is_the_package_version_everywhere(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out == f"plugsim {engine.__version__}\n"
    # pyproject.toml reads it from engine.__version__ (no second copy of the number)
    import tomllib
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "engine.__version__"}
    from setuptools.config.pyprojecttoml import read_configuration
    with pytest.warns(Warning):  # setuptools calls its [tool.setuptools] support beta
        resolved = read_configuration(ROOT / "pyproject.toml", expand=True)["project"]["version"]
    assert resolved == engine.__version__


def test_checkpoint_digest_ignores_only_the_keys_that_extend_a_run():
    case = Case.from_yaml(CASE)
    same = case.with_overrides(["run.duration=60", "run.until_steady=true", "run.steady_rel_error=0.01",
                                "run.checkpoint_interval=5"])
    assert case_digest(same) == case_digest(case)
    for changed in ("run.seed=1", "particles.friction=0.3", "output.slice_width=0.007"):
        assert case_digest(case.with_overrides([changed])) != case_digest(case), changed


def test_a_finished_run_continues_to_a_longer_duration_bit_for_bit(tmp_path):
    """`plugsim run CASE --out X.nc --set run.duration=LONGER` on a finished X.nc continues from its
    stored state: the same file as one run made at once to the longer duration."""
    snapshots = ["output.snapshots=true", "output.snapshot_x_min=0", "output.snapshot_x_max=0.015",
                 "output.snapshot_interval=0.05", "output.tube_snapshot_interval=0.05"]
    once, continued = tmp_path / "once.nc", tmp_path / "continued.nc"
    run_case(Case.from_yaml(CASE, TINY + snapshots + ["run.duration=0.3"]), once)
    run_case(Case.from_yaml(CASE, TINY + snapshots + ["run.duration=0.15"]), continued)
    with xr.open_dataset(continued) as short:
        first_part = short.attrs["cpu_time_total_s"]
    res = plugsim("run", str(CASE), "--out", str(continued), *sets(TINY + snapshots + ["run.duration=0.3"]))
    assert res.returncode == 0, res.stderr
    assert f"continuing {continued} from its end, t = 0.150 s, to 0.3 s" in res.stderr
    with xr.open_dataset(once) as a, xr.open_dataset(continued) as b:
        assert a.attrs["resumed"] == 0 and b.attrs["resumed"] == 1
        assert b.attrs["config_yaml"] == a.attrs["config_yaml"] and b.sizes["time"] == 31
        # the cost of the whole run: the first part's CPU seconds carried into the continued file
        assert b.attrs["cpu_time_total_s"] == pytest.approx(first_part + b.attrs["cpu_time_s"], abs=0.05)
        for name in a.data_vars:  # restart_state included: the engine's state at the end
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)
    # another configuration is refused (test below); with --overwrite it starts over (not mixed)
    res = plugsim("run", str(CASE), "--out", str(continued), "--overwrite",
                  *sets(TINY + snapshots + ["run.duration=0.3", "run.seed=1"]))
    assert res.returncode == 0 and "continuing" not in res.stderr
    with xr.open_dataset(continued) as b:
        assert b.attrs["resumed"] == 0 and b.attrs["seed"] == 1


def test_a_finished_case_is_never_replaced_unasked(tmp_path):
    """The same command again says the file is complete and does nothing; a shorter run.duration or
    other keys are refused (exit 2, one line naming each key, file -> this run) and the file is
    untouched; --overwrite replaces it."""
    out = tmp_path / "x.nc"
    run_case(Case.from_yaml(CASE, TINY + ["run.duration=0.1"]), out)
    before = out.stat()

    def untouched():
        after = out.stat()
        return (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)

    res = plugsim("run", str(CASE), "--out", str(out), *sets(TINY + ["run.duration=0.1"]))
    assert res.returncode == 0, res.stderr
    assert res.stderr.strip().splitlines() == [
        f"plugsim: {out} is complete (stop_reason duration, t = 0.100 s): nothing to do (--overwrite runs it again)"]
    assert untouched()
    for extra, differences in ((["run.duration=0.05"], "run.duration 0.1 -> 0.05"),
                               (["particles.friction=0.3", "run.seed=1"],
                                "particles.friction 0.5 -> 0.3, run.seed 0 -> 1")):
        res = plugsim("run", str(CASE), "--out", str(out), *sets(TINY + ["run.duration=0.1"] + extra))
        lines = res.stderr.strip().splitlines()
        assert res.returncode == 2 and len(lines) == 1, lines
        assert lines[0].startswith(f"plugsim: error: output {out} holds a finished run (stop_reason duration, "
                                   f"t = 0.100 s) that this one would replace (file -> this run): {differences}; "
                                   "--overwrite replaces it"), lines
        assert untouched() and not checkpoint_path(out).exists()
    res = plugsim("run", str(CASE), "--out", str(out), "--overwrite", *sets(TINY + ["run.duration=0.05"]))
    assert res.returncode == 0, res.stderr
    with xr.open_dataset(out) as ds:
        assert ds.sizes["time"] == 6 and ds.attrs["resumed"] == 0


def _wait_for(proc, text, timeout=120, count=1):
    """Read proc's stderr lines until `count` of them contain `text`; return the lines read."""
    lines, seen, deadline = [], 0, time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        seen += text in line
        if seen == count:
            return lines
    raise AssertionError(f"{text!r} not seen {count} times in {lines}")


PROGRESS = " s simulated, "  # in a run's progress line (engine.run.Progress)


def test_sigterm_and_sigint_save_a_checkpoint_and_resume_to_the_uninterrupted_result(tmp_path):
    """SIGTERM, then SIGINT of the resumed run, each sent on seeing a progress line (one per frame,
    run.progress_interval=0): each run exits (143, 130) with one line naming the checkpoint and
    the command, and the run resumed twice equals the uninterrupted one bit for bit. The first run
    asks for 0.5 s, the resumed ones for 0.6 s: a checkpoint continues to a longer duration. No
    periodic checkpoint (default interval, 120 s): the checkpoints are the interrupts'."""
    out = tmp_path / "x.nc"
    keys = TINY + ["run.progress_interval=0"]
    command = {d: ["run", str(CASE), "--out", str(out), *sets(keys + [f"run.duration={d}"])] for d in ("0.5", "0.6")}
    reference = tmp_path / "reference.nc"
    run_case(Case.from_yaml(CASE, keys + ["run.duration=0.6"]), reference)
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    for signum, args in ((signal.SIGTERM, command["0.5"]), (signal.SIGINT, command["0.6"])):
        proc = subprocess.Popen([sys.executable, "-m", "engine.cli", *args], stderr=subprocess.PIPE, text=True,
                                env=env)
        started = _wait_for(proc, "case x.nc: dt")  # the last line before the first frame
        assert ("resuming" in started[0]) == (signum == signal.SIGINT), started
        # on the third frame's line the run is armed (a checkpoint is due at the next frame's end),
        # and at least 46 of its 50 (resumed: 56) frames are still to run
        _wait_for(proc, PROGRESS, count=3)
        proc.send_signal(signum)
        rest = [line for line in proc.stderr.read().strip().splitlines() if PROGRESS not in line]
        assert proc.wait(timeout=60) == 128 + signum, rest
        assert len(rest) == 1 and rest[0].startswith(f"plugsim: interrupted by {signum.name} at t = "), rest
        assert rest[0].endswith(f"checkpoint {checkpoint_path(out)}; resume with the same command: plugsim "
                                + " ".join(args)), rest
        assert checkpoint_path(out).exists() and not out.exists()
    res = plugsim(*command["0.6"], env=env)
    assert res.returncode == 0, res.stderr
    assert "compiling kernels" not in res.stderr  # the cache is warm by now
    assert not checkpoint_path(out).exists()
    with xr.open_dataset(reference) as a, xr.open_dataset(out) as b:
        assert b.attrs["resumed"] == 1
        for name in a.data_vars:
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def test_a_cold_kernel_cache_is_announced_and_an_interrupt_while_compiling_ends_at_once(tmp_path):
    """An empty numba cache (NUMBA_CACHE_DIR): the progress output says that the kernels compile;
    Ctrl-C during the compile stops at once with one line (no frame yet, nothing to save)."""
    run_case(Case.from_yaml(CASE, TINY + ["run.duration=0.01"]), tmp_path / "warm.nc")
    assert kernels_compiled()  # the cache of the kernels' source folder now holds them
    out = tmp_path / "x.nc"
    proc = subprocess.Popen([sys.executable, "-m", "engine.cli", "run", str(CASE), "--out", str(out)],
                            stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache")))
    _wait_for(proc, "plugsim: compiling kernels (first run only, up to two minutes)")
    time.sleep(2.0)  # inside the compile (it takes a minute or more)
    proc.send_signal(signal.SIGINT)
    rest = proc.stderr.read().strip().splitlines()
    assert proc.wait(timeout=60) == 130
    # the run's own info line (time step, nodes) may come first: the compile of the gas kernels
    # while the case is set up can end before the signal; the interruption is one line, no traceback
    assert len(rest) <= 2 and not any("Traceback" in line for line in rest), rest
    assert rest[-1].startswith("plugsim: interrupted by SIGINT before any new frame, "
                               "nothing saved; start again with: plugsim run "), rest
    assert not out.exists() and not checkpoint_path(out).exists()


class _NoSpace:
    """os.statvfs of a full filesystem (4 kB blocks, none free)."""

    f_frsize, f_bfree, f_bavail = 4096, 0, 0


def _full_disk(monkeypatch):
    monkeypatch.setattr(os, "statvfs", lambda path: _NoSpace())


def test_a_full_disk_at_the_case_file_is_one_line_and_the_run_resumes_from_its_end(tmp_path, capsys, monkeypatch):
    """netCDF4 reports a full disk as "NetCDF: HDF error" (no errno): one line naming the
    filesystem and the file, exit 1, no file at OUT, the end of the run kept as the checkpoint;
    the same command then writes the file, equal to an uninterrupted run."""
    args = ["run", str(CASE), "--out", str(tmp_path / "x.nc"), *sets(TINY + ["run.duration=0.05"])]
    reference = run_case(Case.from_yaml(CASE, TINY + ["run.duration=0.05"]), tmp_path / "reference.nc")

    def hdf_error(ds, path, *a, **kw):
        Path(path).write_bytes(b"\x89HDF partial")
        raise RuntimeError("NetCDF: HDF error")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", hdf_error)
    _full_disk(monkeypatch)
    assert main(args) == 1
    from engine.output import filesystem
    mount, kind = filesystem(tmp_path)
    out, ckpt = tmp_path / "x.nc", checkpoint_path(tmp_path / "x.nc")
    assert capsys.readouterr().err.splitlines() == [
        f"plugsim: error: no space left on {mount} ({kind}) writing {out}; the run stopped at t = 0.050 s, "
        f"checkpoint {ckpt} (t = 0.050 s) kept: free space there and run the same command to resume"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reference.nc", "x.nc.ckpt"]
    monkeypatch.undo()  # space freed
    assert main(args) == 0 and not ckpt.exists()
    with xr.open_dataset(reference) as a, xr.open_dataset(out) as b:
        assert b.attrs["resumed"] == 1 and b.attrs["stop_reason"] == "duration"
        for name in a.data_vars:
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)



def test_a_full_disk_at_a_checkpoint_keeps_the_previous_one(tmp_path, capsys, monkeypatch):
    """Periodic checkpoints every frame; the third finds the disk full (ENOSPC): exit 1, one line,
    the checkpoint of t = 0.02 s kept, from which the same command resumes."""
    import errno
    import pickle

    out = tmp_path / "x.nc"
    args = ["run", str(CASE), "--out", str(out), *sets(TINY + ["run.duration=0.05", "run.checkpoint_interval=1e-9"])]
    dump, calls = pickle.dump, []

    def filling(obj, handle, *a, **kw):
        calls.append(1)
        if len(calls) == 3:
            handle.write(b"partial")
            raise OSError(errno.ENOSPC, "No space left on device")
        return dump(obj, handle, *a, **kw)

    monkeypatch.setattr(pickle, "dump", filling)
    assert main(args) == 1
    ckpt = checkpoint_path(out)
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("plugsim: error: no space left on "), lines
    assert lines[0].endswith(f" writing {ckpt}; the run stopped at t = 0.030 s, checkpoint {ckpt} (t = 0.020 s) "
                             "kept: free space there and run the same command to resume"), lines
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.nc.ckpt"]
    monkeypatch.undo()  # space freed
    assert main(args) == 0 and not ckpt.exists()
    with xr.open_dataset(out) as ds:
        assert ds.attrs["resumed"] == 1 and ds.sizes["time"] == 6

"""SIGINT to snakemake stops a running case within seconds: the case keeps its checkpoint, logs one
line, and the next snakemake resumes it (workflow/scripts/running.py, simulate.py)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from tests.workflow.test_workflow import ROOT, SNAKEMAKE, scratch

CASE = "results/cases/h_stop/base.nc"
LOG = "logs/simulate/h_stop/base.log"


def case_processes(work: Path) -> list[int]:
    """pids of the simulate scripts running in `work`."""
    pids = []
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            cmdline = (proc / "cmdline").read_bytes()
            cwd = os.readlink(proc / "cwd")
        except OSError:
            continue
        if b"simulate.py" in cmdline and cwd == str(work):
            pids.append(int(proc.name))
    return pids


def wait_for(condition, timeout: float, what: str, proc: subprocess.Popen | None = None) -> None:
    end = time.monotonic() + timeout
    while not condition():
        if proc is not None and proc.poll() is not None:
            pytest.fail(f"snakemake ended (status {proc.returncode}) before {what}")
        if time.monotonic() > end:
            pytest.fail(f"not within {timeout} s: {what}")
        time.sleep(0.2)


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc for the case processes")
def test_sigint_to_snakemake_stops_the_case_which_resumes_on_the_next_run(tmp_path):
    work = scratch(tmp_path)
    # a 3 cm tube, checkpointing every half second of wall time so that the test knows when the
    # run is past its first frame; 2 s simulated, far longer than the test waits
    (work / "config/stop.yaml").write_text(yaml.safe_dump({"sweeps": {"h_stop": {
        "base": "config/cases/horizontal.yaml", "position": 0.015,
        "overrides": {"tube.length": 0.03, "gas.nodes_x": 9, "run.duration": 2.0,
                      "run.until_steady": False, "run.checkpoint_interval": 0.5}}}}))
    command = [*SNAKEMAKE, "--snakefile", str(ROOT / "Snakefile"), CASE, "--cores", "1",
               "--configfile", "config/stop.yaml"]
    ckpt = work / (CASE + ".ckpt")
    with open(tmp_path / "first.out", "w") as out:
        # its own session: the signal goes to snakemake alone, as `kill -INT <pid>` sends it; SIGINT at
        # its default, as a terminal starts snakemake: a test run started in the background of a
        # script (`pytest &`) ignores SIGINT, and snakemake would inherit that and keep it for the
        # cases (the next test)
        first = subprocess.Popen(command, cwd=work, stdout=out, stderr=subprocess.STDOUT,
                                 start_new_session=True,
                                 preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        try:
            wait_for(ckpt.exists, 300, "the case saved a checkpoint", first)
            first.send_signal(signal.SIGINT)
            sent = time.monotonic()
            first.wait(timeout=30)
            stopped_after = time.monotonic() - sent
        finally:
            if first.poll() is None:
                first.kill()
    assert stopped_after < 10, f"snakemake took {stopped_after:.1f} s to stop"
    assert case_processes(work) == []
    lines = (work / LOG).read_text().strip().splitlines()
    assert "Traceback" not in "\n".join(lines)
    assert "interrupted by SIGINT at t = " in lines[-1] and "the next snakemake resumes it" in lines[-1]
    assert ckpt.exists() and not (work / CASE).exists()

    second = subprocess.run(command, cwd=work, capture_output=True, text=True, timeout=600)
    assert second.returncode == 0, second.stderr[-3000:]
    log = (work / LOG).read_text()
    assert "resuming" in log and (work / CASE).exists() and not ckpt.exists()


def test_a_signal_snakemake_ignores_stays_ignored_for_the_cases():
    # `nohup snakemake … &` from a script starts snakemake with SIGINT ignored; forwarding it
    # anyway stopped the running cases while snakemake went on to start the next ones
    code = ("import signal; from workflow.scripts import running; running.forward_signals(); "
            "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN, "
            "callable(signal.getsignal(signal.SIGTERM)))")
    ignore_sigint = lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)  # noqa: E731
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          preexec_fn=ignore_sigint, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True"]

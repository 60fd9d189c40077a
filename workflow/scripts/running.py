"""Stopping the running cases when snakemake is told to stop.

Snakemake runs a `script:` job as a child process and, on SIGINT or SIGTERM, only stops scheduling
and waits for it: a case would run on to its end. So each simulate job registers its process here
(`registered`, in its own process group, so that a terminal's Ctrl-C does not reach it twice), and
the Snakefile's `onstart` installs `forward_signals`, which passes SIGINT and SIGTERM to every
registered case before Snakemake's own handling. A case saves its checkpoint at the next frame
and ends with one log line (workflow/scripts/simulate.py); the next `snakemake` resumes it.
"""

from __future__ import annotations

import os
import signal
import socket
from contextlib import contextmanager
from pathlib import Path

REGISTRY = Path(".snakemake/plugsim-running-cases")  # one file per running case: <host>-<pid>


def entry_name(pid: int) -> str:
    """A case's entry: the host too, since cluster jobs on other nodes share the directory."""
    return f"{socket.gethostname()}-{pid}"


@contextmanager
def registered(case_file: str):
    """Register this process as a running case for the signal forwarder while the block runs."""
    try:
        os.setpgid(0, 0)
    except OSError:  # already a group leader (e.g. started by a shell with job control)
        pass
    REGISTRY.mkdir(parents=True, exist_ok=True)
    entry = REGISTRY / entry_name(os.getpid())
    entry.write_text(case_file)
    try:
        yield
    finally:
        entry.unlink(missing_ok=True)


def running_cases() -> dict[int, str]:
    """pid -> case file of every registered case whose process still runs a simulate job."""
    out = {}
    host = socket.gethostname()
    for entry in REGISTRY.glob("*") if REGISTRY.is_dir() else []:
        name, _, pid = entry.name.rpartition("-")
        if name != host:
            continue
        try:
            pid = int(pid)
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes() if Path("/proc").is_dir() else b"simulate"
        except (ValueError, OSError):  # not a pid, or the process is gone (a stale entry)
            entry.unlink(missing_ok=True)
            continue
        if b"simulate" in cmdline:  # not a process that reused the pid of a finished case
            out[pid] = entry.read_text()
    return out


def forward(signum: int) -> list[int]:
    """Send `signum` to every running case; their pids."""
    sent = []
    for pid in running_cases():
        try:
            os.kill(pid, signum)
            sent.append(pid)
        except ProcessLookupError:
            pass
    return sent


def forward_signals() -> None:
    """Make SIGINT and SIGTERM reach the running cases first, then Snakemake's own handlers
    (SIGINT: KeyboardInterrupt, SIGTERM: its graceful stop). A signal snakemake ignores stays
    ignored for the cases too: a job started in the background of a script (`nohup snakemake … &`)
    ignores SIGINT, and forwarding it would stop the cases while snakemake starts the next ones.
    Call in the main thread, after Snakemake installed its handlers (the Snakefile's `onstart`)."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        previous = signal.getsignal(signum)
        if previous == signal.SIG_IGN:
            continue

        def handler(num, frame, previous=previous):
            forward(num)
            if callable(previous):
                previous(num, frame)
            elif previous == signal.SIG_DFL:
                signal.signal(num, signal.SIG_DFL)
                os.kill(os.getpid(), num)

        signal.signal(signum, handler)

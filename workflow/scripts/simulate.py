"""Rule simulate: run one case (base case YAML + overrides) from an empty tube to its case file.

Standalone:
    python workflow/scripts/simulate.py --input base=config/cases/horizontal.yaml \
        --output case=/tmp/h.nc --params 'overrides={run.duration: 0.5, gas.enabled: false}'
"""

import os
import time
from contextlib import nullcontext

from _helpers import Standalone, setup_logging, snakemake_or_cli
from running import REGISTRY, entry_name, registered


def stopped(log, err, out: str):
    """End the job with one log line after SIGINT/SIGTERM (no traceback): where the run stopped and
    that the next snakemake resumes it from its checkpoint. Exits 128 + the signal's number."""
    where = f" at t = {err.time:.3f} s" if err.time is not None else ""
    if err.checkpoint is None:
        log.warning("interrupted by %s before its first frame, nothing saved; the next snakemake "
                    "starts %s again", err, out)
    else:
        log.warning("interrupted by %s%s, checkpoint %s; the next snakemake resumes it", err, where,
                    err.checkpoint)
    for handler in log.root.handlers:
        handler.flush()
    (REGISTRY / entry_name(os.getpid())).unlink(missing_ok=True)
    os._exit(128 + err.signum)  # also from inside a signal handler (numba's compiler may swallow a raise)


def main(smk) -> None:
    log = setup_logging(smk)
    import numba

    # The job's threads (1 in the rule: cases run side by side; `snakemake --set-threads simulate=2`
    # threads each case's contact forces), capped to what numba can run (NUMBA_NUM_THREADS)
    threads = max(1, min(int(smk.threads), numba.config.NUMBA_NUM_THREADS))
    from engine.case import Case
    from engine.run import RunInterrupted, run_case

    overrides = dict(smk.params.overrides or {})
    case = Case.from_yaml(smk.input.base).with_overrides(list(overrides.items()))
    log.info("case %s with overrides %s", smk.input.base, overrides)
    start = time.perf_counter()
    initial_state = smk.input.get("initial_state")
    if initial_state:
        log.info("warm start from %s", initial_state)
    out = smk.output.case
    # Snakemake decides when a case is (re)made (missing, --forcerun, changed params or engine
    # source) and removes the old file before the job; overwrite=True so that a file still there
    # (a remote executor's copy, a job run by hand) can never turn such a rerun into a refusal.
    # A checkpoint of the same case still resumes. Under snakemake, its SIGINT/SIGTERM reach this
    # case through workflow/scripts/running.py.
    with nullcontext() if isinstance(smk, Standalone) else registered(out):
        try:
            run_case(case, out, quiet=True, initial_state=initial_state, threads=threads,
                     overwrite=True, early_exit=lambda err: stopped(log, err, out))
        except RunInterrupted as err:
            stopped(log, err, out)
    log.info("wrote %s in %.1f s wall", out, time.perf_counter() - start)


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "simulate"))

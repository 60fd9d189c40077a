"""Rule simulate: run one case (base case YAML + overrides) from an empty tube to its case file.

Standalone:
    python workflow/scripts/simulate.py --input base=config/cases/horizontal.yaml \
        --output case=/tmp/h.nc --params 'overrides={run.duration: 0.5, gas.enabled: false}'
"""

import time

from _helpers import setup_logging, snakemake_or_cli


def main(smk) -> None:
    log = setup_logging(smk)
    import numba

    # The job's threads (1 in the rule: cases run side by side; `snakemake --set-threads simulate=2`
    # threads each case's contact forces), capped to what numba can run (NUMBA_NUM_THREADS)
    threads = max(1, min(int(smk.threads), numba.config.NUMBA_NUM_THREADS))
    from engine.case import Case
    from engine.run import run_case

    overrides = dict(smk.params.overrides or {})
    case = Case.from_yaml(smk.input.base).with_overrides(list(overrides.items()))
    log.info("case %s with overrides %s", smk.input.base, overrides)
    start = time.perf_counter()
    initial_state = smk.input.get("initial_state")
    if initial_state:
        log.info("warm start from %s", initial_state)
    # Snakemake decides when a case is (re)made (missing, --forcerun, changed params or engine
    # source) and removes the old file before the job; overwrite=True so that a file still there
    # (a remote executor's copy, a job run by hand) can never turn such a rerun into a refusal.
    # A checkpoint of the same case still resumes.
    run_case(case, smk.output.case, quiet=True, initial_state=initial_state, threads=threads, overwrite=True)
    log.info("wrote %s in %.1f s wall", smk.output.case, time.perf_counter() - start)


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "simulate"))

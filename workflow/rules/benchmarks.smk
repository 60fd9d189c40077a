# Stage 7: the engine benchmark (particle-steps per second on the standard dense case), recorded
# next to the per-job wall times of this run (results/benchmarks/jobs/<rule>/..., collected into
# results/benchmarks/timings.csv when the workflow succeeds).


rule bench:
    """`plugsim bench --json --no-compile` (run as python -m engine.bench) on this machine."""
    output:
        json=report("results/benchmarks/engine.json", caption="../report/bench.rst",
                    category="Benchmarks"),
    params:
        python=sys.executable,  # the interpreter running Snakemake (its env has plugsim installed)
        args=" ".join(str(a) for a in config.get("benchmarks", {}).get("args", [])),
    log:
        "logs/bench/bench.log",
    benchmark:
        "results/benchmarks/jobs/bench/bench.tsv"
    threads: 1
    resources:
        runtime=15,
        mem_mb=2000,
    shell:
        "NUMBA_NUM_THREADS={threads} {params.python} -m engine.bench --json --no-compile {params.args} > {output.json} 2> {log}"


onsuccess:
    import timings  # workflow/scripts/timings.py

    timings.collect("results/benchmarks/jobs", "results/benchmarks/timings.csv")

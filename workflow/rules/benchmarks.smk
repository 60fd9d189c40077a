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


rule work_precision:
    """Error of the pressure drop, slug velocity and slug length against wall time for each
    numerical knob (config benchmarks.work_precision: sweep -> reference value)."""
    input:
        summaries=lambda wc: [summary_json(s, p) for s in WORK_PRECISION for p in POINTS[s]],
    output:
        table="results/benchmarks/work_precision.csv",
        png=report("results/benchmarks/work_precision.png", caption="../report/work_precision.rst",
                   category="Benchmarks"),
        pdf="results/benchmarks/work_precision.pdf",
    params:
        studies=lambda wc: {s: {"parameter": sweep_parameter_keys(s, tied=False)[0],
                                "reference": WORK_PRECISION[s]["reference"],
                                "default": knob_default(s),
                                "summaries": [summary_json(s, p) for p in POINTS[s]]}
                            for s in WORK_PRECISION},
    log:
        "logs/work_precision/work_precision.log",
    benchmark:
        "results/benchmarks/jobs/work_precision/work_precision.tsv"
    threads: 1
    resources:
        runtime=5,
        mem_mb=1000,
    script:
        "../scripts/work_precision.py"


onsuccess:
    import timings  # workflow/scripts/timings.py

    timings.collect("results/benchmarks/jobs", "results/benchmarks/timings.csv")

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
    """Error of the pressure drop, slug velocity and slug length against CPU time for each
    numerical knob (config benchmarks.work_precision: sweep -> reference value), one row of panels
    per flow regime."""
    input:
        summaries=lambda wc: [paths.summary_json(s, p) for s in PLAN.work_precision for p in PLAN.points[s]],
    output:
        table="results/benchmarks/work_precision.csv",
        png=report("results/benchmarks/work_precision.png", caption="../report/work_precision.rst",
                   category="Benchmarks"),
        pdf="results/benchmarks/work_precision.pdf",
    params:
        studies=lambda wc: PLAN.work_precision_studies(),
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


rule scale:
    """Cost against the number of grains (benchmarks/scale.py): dense packings of 10^3 to 10^5 grains
    in longer 7 mm and in wider (14, 28 mm) tubes, gas on and off, one core; up to 3000 grains when
    config benchmarks.scale_reduced is true."""
    output:
        csv="results/benchmarks/scale/scale.csv",
        md="results/benchmarks/scale/scale.md",
        png=report("results/benchmarks/scale/scale.png", caption="../report/scale.rst",
                   category="Benchmarks"),
    params:
        python=sys.executable,
        script=Path(workflow.basedir) / "benchmarks" / "scale.py",  # next to the Snakefile, not the cwd
        reduced="--reduced" if config.get("benchmarks", {}).get("scale_reduced", False) else "",
        engine_source=ENGINE_SOURCE,  # rerun when the engine's source changes
    log:
        "logs/scale/scale.log",
    benchmark:
        "results/benchmarks/jobs/scale/scale.tsv"
    threads: 1
    resources:
        runtime=20,
        mem_mb=3000,
    shell:
        "NUMBA_NUM_THREADS={threads} {params.python} {params.script} --out-dir $(dirname {output.csv}) "
        "{params.reduced} > {log} 2>&1"


rule stability:
    """Numerical-stability stress sweep (benchmarks/stability.py): short cases at extreme time
    steps, gas velocities, viscosities, contact laws and feeds, each classified as ran, refused up
    front or stopped with a reason; the job fails if any case blows up silently. Eight cases when
    config benchmarks.stability_reduced is true."""
    output:
        csv="results/benchmarks/stability/stability.csv",
        md="results/benchmarks/stability/stability.md",
        png=report("results/benchmarks/stability/stability.png", caption="../report/stability.rst",
                   category="Benchmarks"),
    params:
        python=sys.executable,
        script=Path(workflow.basedir) / "benchmarks" / "stability.py",  # next to the Snakefile, not the cwd
        reduced="--reduced" if config.get("benchmarks", {}).get("stability_reduced", False) else "",
        engine_source=ENGINE_SOURCE,
    log:
        "logs/stability/stability.log",
    benchmark:
        "results/benchmarks/jobs/stability/stability.tsv"
    threads: 1
    resources:
        runtime=20,
        mem_mb=2000,
    shell:
        "NUMBA_NUM_THREADS={threads} {params.python} {params.script} --out-dir $(dirname {output.csv}) "
        "{params.reduced} > {log} 2>&1"


rule restitution:
    """Head-on restitution against the time step over the contact-start phase (benchmarks/
    restitution.py): the analytic error of the time step; 2 time steps at e = 0.5 when config
    benchmarks.restitution_reduced is true."""
    output:
        csv="results/benchmarks/restitution/restitution.csv",
        md="results/benchmarks/restitution/restitution.md",
        png=report("results/benchmarks/restitution/restitution.png", caption="../report/restitution.rst",
                   category="Benchmarks"),
    params:
        python=sys.executable,
        script=Path(workflow.basedir) / "benchmarks" / "restitution.py",
        reduced="--reduced" if config.get("benchmarks", {}).get("restitution_reduced", False) else "",
        engine_source=ENGINE_SOURCE,
    log:
        "logs/restitution/restitution.log",
    benchmark:
        "results/benchmarks/jobs/restitution/restitution.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=1000,
    shell:
        "NUMBA_NUM_THREADS={threads} {params.python} {params.script} --out-dir $(dirname {output.csv}) "
        "{params.reduced} > {log} 2>&1"


onsuccess:
    import timings  # workflow/scripts/timings.py

    timings.collect("results/benchmarks/jobs", "results/benchmarks/timings.csv")

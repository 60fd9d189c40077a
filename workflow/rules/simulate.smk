# Stage 1: run each case of every sweep (one NetCDF case file per point; identical cases once).


rule simulate:
    """Run one case: base case YAML + the point's overrides -> case file; from an empty tube, or
    (sweep `warm_start`) from the grains at the end of another case."""
    input:
        unpack(simulate_inputs),
    output:
        case=paths.case_file("{sweep}", "{point}"),
    params:
        overrides=lambda wc: PLAN.overrides[wc_key(wc)],
        engine_source=ENGINE_SOURCE,  # rerun when the engine's source changes
    log:
        "logs/simulate/{sweep}/{point}.log",
    benchmark:
        "results/benchmarks/jobs/simulate/{sweep}/{point}.tsv"
    threads: 1
    priority: simulate_priority  # longest critical path first (docs/workflow.md)
    resources:
        runtime=runtime_minutes,
        mem_mb=2000,
    script:
        "../scripts/simulate.py"

# Stage 4: characteristic curves: one table per sweep (one row per case) and a quick plot of it.


rule curve:
    """Table of a sweep: its parameters and each case's steady pressure drop, regime, ..."""
    input:
        summaries=lambda wc: [paths.summary_json(wc.sweep, p) for p in PLAN.points[wc.sweep]],
    output:
        table=paths.curve_csv("{sweep}"),
    params:
        parameters=lambda wc: PLAN.sweep_parameter_keys(wc.sweep),
    log:
        "logs/curve/{sweep}.log",
    benchmark:
        "results/benchmarks/jobs/curve/{sweep}.tsv"
    threads: 1
    resources:
        runtime=5,
        mem_mb=1000,
    script:
        "../scripts/curve.py"


rule curve_plot:
    """Pressure drop against the first parameter of a sweep (one line per value of the second);
    drawn for every sweep, also the ones no paper figure uses."""
    input:
        table=paths.curve_csv("{sweep}"),
    output:
        png=report(paths.curve_png("{sweep}"), caption="../report/curve.rst",
                   category="Sweeps", labels={"sweep": "{sweep}"}),
    params:
        parameters=lambda wc: PLAN.sweep_parameter_keys(wc.sweep, tied=False),
        caption=lambda wc: captions.sweep_text(PLAN, wc.sweep),
    log:
        "logs/curve_plot/{sweep}.log",
    benchmark:
        "results/benchmarks/jobs/curve_plot/{sweep}.tsv"
    threads: 1
    resources:
        runtime=5,
        mem_mb=1000,
    script:
        "../scripts/curve_plot.py"

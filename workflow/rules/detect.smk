# Stage 2: detect and track slugs in each case, reduce it to a summary, and the slug statistics
# against position (H8-H11, V9-V12).


rule detect:
    """Slugs (porosity < threshold) per frame, tracked; the case summary (steady pressure drop,
    regime, grains in the tube, slug rate/velocity/length at the analysis position)."""
    input:
        case=case_nc_of,
    output:
        slugs=paths.slugs_csv("{sweep}", "{point}"),
        summary=paths.summary_json("{sweep}", "{point}"),
    params:
        threshold=config["analysis"]["threshold"],
        position=analysis_position,
        sweep=lambda wc: wc.sweep,
        point=lambda wc: wc.point,
        parameters=lambda wc: PLAN.points[wc.sweep][wc.point],
    log:
        "logs/detect/{sweep}/{point}.log",
    benchmark:
        "results/benchmarks/jobs/detect/{sweep}/{point}.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/detect.py"


rule statistics:
    """Slug rate and statistics of slug properties at 30 positions along the tube, over the
    steady window of the case."""
    input:
        slugs=paths.slugs_csv("{sweep}", "{point}"),
        summary=paths.summary_json("{sweep}", "{point}"),
    output:
        statistics=paths.statistics_csv("{sweep}", "{point}"),
    log:
        "logs/statistics/{sweep}/{point}.log",
    benchmark:
        "results/benchmarks/jobs/statistics/{sweep}/{point}.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/slug_statistics.py"

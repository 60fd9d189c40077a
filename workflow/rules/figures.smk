# Stage 5: every reproducible figure of both papers, named by paper and number (H01..H21,
# V03..V19): PNG + PDF + a caption text stating the case parameters. The figure list and the
# case each one draws are in config `figures`.


rule figure:
    """One paper figure (kind from config figures.<fig>)."""
    input:
        unpack(figure_inputs),
    output:
        png=report(paths.figure_files("{fig}")[0], caption="../report/figure.rst",
                   category=figure_category, labels={"figure": "{fig}"}),
        pdf=paths.figure_files("{fig}")[1],
        txt=paths.figure_files("{fig}")[2],
    params:
        spec=lambda wc: {k: v for k, v in PLAN.figures[wc.fig].items() if k not in ("case", "cases")},
        caption=figure_caption,
        analysis=config["analysis"],
    log:
        "logs/figure/{fig}.log",
    benchmark:
        "results/benchmarks/jobs/figure/{fig}.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/figure.py"

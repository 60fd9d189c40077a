# Stage 7: model identification: the discretisation readings the papers leave open, crossed on the
# most informative cases, against the papers' numbers (config/identification.yaml).


rule identification:
    """Table and figure of each reading against the papers' numbers for the identification cases."""
    input:
        statements=config["validation"]["statements"],
        tables=PLAN.identification_tables(),
    output:
        csv=report("results/identification/identification.csv", caption="../report/identification.rst",
                   category="Identification"),
        md="results/identification/identification.md",
        png=report("results/identification/identification.png", caption="../report/identification.rst",
                   category="Identification"),
    params:
        compare=PLAN.identification.get("compare") or [],
        readings=PLAN.identification.get("readings") or [],
        baselines=PLAN.identification_baselines(),
    log:
        "logs/identification/identification.log",
    benchmark:
        "results/benchmarks/jobs/identification/identification.tsv"
    threads: 1
    resources:
        runtime=5,
        mem_mb=1000,
    script:
        "../scripts/identification.py"

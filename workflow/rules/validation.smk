# Stage 6: the papers' quantitative statements (resources/paper_statements.yaml) against ours.


rule validation:
    """Table of the papers' statements: value, tolerance, ours +- standard error, ratio, verdict."""
    input:
        statements=config["validation"]["statements"],
        data=validation_inputs,
    output:
        csv=report("results/validation/validation.csv", caption="../report/validation.rst",
                   category="Validation"),
        md="results/validation/validation.md",
    params:
        statements=validation_statements(),
        position=config["analysis"]["position"],
        all_cases=config.get("all_cases") or {},
    log:
        "logs/validation/validation.log",
    benchmark:
        "results/benchmarks/jobs/validation/validation.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/validation.py"

# Stage 6: the papers' quantitative statements (resources/paper_statements.yaml) against ours.


rule validation:
    """Table of the papers' statements: value, tolerance, ours +- standard error, ratio, verdict."""
    input:
        statements=config["validation"]["statements"],
        data=lambda wc: PLAN.validation_inputs(),
    output:
        csv=report(paths.VALIDATION_CSV, caption="../report/validation.rst",
                   category="Validation"),
        md="results/validation/validation.md",
    params:
        statements=PLAN.validation_statements(),
        position=config["analysis"]["position"],
        all_cases=config.get("all_cases") or {},
        partial=PLAN.partial,
        read=PLAN.partial_fingerprint(),  # partial: rerun when a file it reads appears or changes
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


rule reference:
    """Copy what a reader needs to see the result without rerunning (figure PNGs and captions, sweep
    curves, the validation table) to docs/reference/paper/, for committing. Not part of `all`:
    `snakemake -j2 reference` after a run of the paper configuration (with config/partial.yaml:
    only what this configuration has already produced, for a run done in parts)."""
    input:
        # a partial validation copies what is current (params), never asking for a product
        unpack(lambda wc: {} if PLAN.partial else PLAN.reference_files()),
        validation=[paths.VALIDATION_CSV, "results/validation/validation.md"],
    params:
        partial_files=PLAN.reference_files() if PLAN.partial else {},
    output:
        directory("docs/reference/paper"),
    log:
        "logs/reference/reference.log",
    script:
        "../scripts/reference.py"

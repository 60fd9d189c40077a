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
    only what exists, for a run done in parts)."""
    input:
        figures=PLAN.existing_if_partial([f for fig in PLAN.figures for f in paths.figure_files(fig)
                                          if not f.endswith(".pdf")]),
        curves=PLAN.existing_if_partial([f for s in PLAN.curve_sweeps() if not s.startswith("wp_")
                                         for f in (paths.curve_csv(s), paths.curve_png(s))]),
        validation=[paths.VALIDATION_CSV, "results/validation/validation.md"],
    output:
        directory("docs/reference/paper"),
    log:
        "logs/reference/reference.log",
    script:
        "../scripts/reference.py"

# Stage 7: model identification: the discretisation readings the papers leave open, crossed on the
# most informative cases, against the papers' numbers (config/identification.yaml).

IDENTIFICATION = config.get("identification") or {}
for _item in IDENTIFICATION.get("compare") or []:
    if _item["sweep"] not in POINTS:
        raise ValueError(f"config: identification compares statement {_item['statement']} on sweep "
                         f"{_item['sweep']!r}, which is not declared")
    if not any(st["id"] == _item["statement"] for st in STATEMENTS):
        raise ValueError(f"config: identification names statement {_item['statement']!r}, which is "
                         f"not in {config['validation']['statements']}")


rule identification:
    """Table and figure of each reading against the papers' numbers for the identification cases."""
    input:
        statements=config["validation"]["statements"],
        tables=sorted({f"results/curves/{item['sweep']}.csv" for item in IDENTIFICATION.get("compare") or []}),
    output:
        csv=report("results/identification/identification.csv", caption="../report/identification.rst",
                   category="Identification"),
        md="results/identification/identification.md",
        png=report("results/identification/identification.png", caption="../report/identification.rst",
                   category="Identification"),
    params:
        compare=IDENTIFICATION.get("compare") or [],
        readings=IDENTIFICATION.get("readings") or [],
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

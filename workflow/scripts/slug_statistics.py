"""Rule statistics: slug rate and slug-property statistics at 30 positions along the tube
(H8-H11, V9-V12), over the steady window of the case (from its summary).

Standalone:
    python workflow/scripts/slug_statistics.py --input slugs=results/slugs/h_default/base.csv \
        --input summary=results/summaries/h_default/base.json --output statistics=/tmp/stats.csv
"""

from _helpers import read_json, read_table, setup_logging, snakemake_or_cli, write_table


def main(smk) -> None:
    log = setup_logging(smk)
    from analysis.statistics import slug_statistics

    slugs = read_table(smk.input.slugs)
    summary = read_json(smk.input.summary)
    stats = slug_statistics(slugs, t_start=summary["t_start"])
    stats.attrs["vertical"] = bool(summary.get("vertical", slugs.attrs.get("vertical", False)))
    write_table(stats, smk.output.statistics)
    log.info("statistics at %d positions over %.2f-%.2f s, %d slug passages", len(stats),
             stats.attrs["t_start"], stats.attrs["t_end"], int(stats["n_slugs"].sum()))


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "statistics"))

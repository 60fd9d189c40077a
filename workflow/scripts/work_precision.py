"""Rule work_precision: error against wall time for each numerical knob (table + figure).

A study over run.seed (the seed study, every knob at its default) is the noise floor: it sets the
run-to-run scatter, and the default point of every other study is the mean of its runs. Studies
carry a flow regime (its own tube and flow, e.g. "slug" and "bulk"); each regime has its own seed
study and its own row of panels.

Standalone (params as YAML):
    python workflow/scripts/work_precision.py --output table=/tmp/wp.csv --output png=/tmp/wp.png \
        --params 'studies={wp_time_step: {parameter: numerics.time_step_fraction, reference: 0.0125,
                  default: 0.05, regime: slug, summaries: [results/summaries/wp_time_step/...json, ...]}}'
"""

import pandas as pd

from _helpers import read_json, save_figure, setup_logging, snakemake_or_cli, write_table


def main(smk) -> None:
    log = setup_logging(smk)
    from analysis.plots import work_precision
    from analysis.precision import SEED, by_regime, pool_default, relative_errors, run_to_run_scatter

    studies = smk.params.studies
    rows_of = {sweep: pd.DataFrame([read_json(path) for path in study["summaries"]])
               for sweep, study in studies.items()}
    # each regime's seed study (at most one, checked by the workflow) is that regime's noise floor
    seeds_of = {study.get("regime", ""): rows_of[sweep] for sweep, study in studies.items()
                if study["parameter"] == SEED}
    tables, defaults = [], {}
    for sweep, study in studies.items():
        rows, regime = rows_of[sweep], study.get("regime", "")
        seeds = seeds_of.get(regime)
        if seeds is not None and study["parameter"] != SEED:
            # the default point: the mean of the seed study's runs (analysis.precision.pool_default)
            rows = pool_default(rows, study["parameter"], study["default"], seeds)
        table = relative_errors(rows, study["parameter"], study["reference"])
        table.insert(0, "regime", regime)
        table.insert(0, "sweep", sweep)
        table["is_default"] = table["value"].sub(float(study["default"])).abs() <= 1e-9 * abs(float(study["default"]))
        tables.append(table)
        defaults[study["parameter"]] = study["default"]
        for _, row in table.iterrows():
            log.info("%s%s = %g: cpu %.0f s, dp error %.3f (noise %.3f), velocity error %.3f, length error %.3f",
                     f"[{regime}] " if regime else "", study["parameter"], row["value"], row["cpu_time_s"],
                     row["pressure_drop_error"], row["pressure_drop_noise"], row["slug_velocity_error"],
                     row["slug_length_error"])
    table = pd.concat(tables, ignore_index=True)
    table.attrs["units"] = tables[0].attrs["units"]
    # regime -> observable -> std/mean over the regime's seed runs
    table.attrs["run_to_run_scatter"] = {regime: run_to_run_scatter(group)
                                         for regime, group in by_regime(tables).items()}
    log.info("run-to-run scatter (std/mean over each regime's seed runs): %s", table.attrs["run_to_run_scatter"])
    write_table(table, smk.output.table)
    save_figure(work_precision(tables, defaults), smk.output.png, smk.output.get("pdf"))


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "work_precision"))

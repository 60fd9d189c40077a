"""Rule detect: slugs of one case (detected, tracked) and its summary.

The summary holds the case configuration (dotted keys), the sweep point, the steady pressure drop
(Pa/m) +- its standard error (analysis.timeseries.mean_error) and window, the regime and what
decides it (travel speed, delivered over fed mass flow), grains in the tube (+- the same error), at
the analysis position the slug rate, travel speed, mean maximal granular velocity (per passage and
time-weighted) and slug length (core and with the ends), and how the run started and stopped
(analysis.curves.case_summary).

Standalone:
    python workflow/scripts/detect.py --input case=results/cases/h_default/base.nc \
        --output slugs=/tmp/slugs.csv --output summary=/tmp/summary.json
"""


from _helpers import setup_logging, snakemake_or_cli, write_json, write_table


def main(smk) -> None:
    log = setup_logging(smk)
    from analysis.casefile import open_case, run_cpu_seconds, seconds
    from analysis.curves import case_summary
    from analysis.slugs import detect

    threshold = float(smk.params.get("threshold", 0.6) or 0.6)
    ds = open_case(smk.input.case)
    slugs = detect(ds, threshold)
    log.info("%d slug-frames, %d slugs", len(slugs), slugs["slug_id"].nunique() if len(slugs) else 0)
    summary = case_summary(ds, threshold=threshold, slugs=slugs,
                           position=smk.params.get("position"))
    summary["pressure_drop_unit"] = "Pa m-1"
    summary.update({"sweep": smk.params.get("sweep"), "point": smk.params.get("point"),
                    "parameters": smk.params.get("parameters") or {},
                    "case_file": str(smk.input.case),
                    "stop_reason": ds.attrs.get("stop_reason", ""),
                    "initial_state": str(ds.attrs.get("initial_state", "")),  # warm start from
                    "wall_time_s": float(ds.attrs.get("wall_time_s", float("nan"))),
                    "cpu_time_s": run_cpu_seconds(ds.attrs),  # all the run's parts
                    "time_step": float(ds.attrs.get("time_step", float("nan"))),
                    # False: a packed bed (bulk regime) of this case is not converged in the step
                    "dashpot_resolved": bool(int(ds.attrs["dashpot_resolved"])),
                    "simulated_time": float(seconds(ds["time"].values)[-1]),
                    "n_slugs": int(slugs["slug_id"].nunique()) if len(slugs) else 0,
                    "vertical": bool(float(ds.attrs.get("inclination_deg", 0.0)) >= 45.0)})
    write_table(slugs, smk.output.slugs)
    write_json(summary, smk.output.summary)
    log.info("pressure drop %.4g +- %.2g Pa/m (%s), regime %s",
             summary["pressure_drop"], summary["pressure_drop_sem"],
             f"{summary['t_start']:.2f}-{summary['t_end']:.2f} s", summary["regime"])


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "detect"))

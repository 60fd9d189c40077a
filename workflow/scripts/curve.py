"""Rule curve: the table of one sweep, one row per case: its parameters, then the steady pressure
drop (Pa/m) +- standard error (analysis.timeseries.mean_error), regime and the other case
summaries (SI units; the first line of the CSV holds the units as JSON attributes).

Standalone:
    python workflow/scripts/curve.py --input results/summaries/h_vs/a.json \
        --input results/summaries/h_vs/b.json --output table=/tmp/h_vs.csv \
        --params 'parameters=[gas.superficial_velocity]'
"""

import pandas as pd

from _helpers import read_json, setup_logging, snakemake_or_cli, write_table

RESULTS = ["pressure_drop", "pressure_drop_sem", "pressure_drop_correlation_time", "regime",
           "t_start", "t_end", "window", "stop_reason",
           "dense_fraction", "slug_fraction", "slug_rate", "slug_velocity", "travel_speed",
           "travel_speed_sem", "max_velocity", "max_velocity_sem", "slug_length", "slug_length_total", "n_particles", "n_particles_sem",
           "mass_flow_out", "mass_flow_fed", "delivery", "n_slugs", "dashpot_resolved",
           "initial_state", "vertical", "block_piston_force", "block_gas_force", "block_weight_force",
           "block_wall_friction_force"]
UNITS = {"pressure_drop": "Pa m-1", "pressure_drop_sem": "Pa m-1",
         "pressure_drop_correlation_time": "s", "t_start": "s", "t_end": "s",
         "slug_rate": "s-1", "slug_velocity": "m s-1", "travel_speed": "m s-1",
         "travel_speed_sem": "m s-1", "max_velocity": "m s-1", "max_velocity_sem": "m s-1", "slug_length": "m", "slug_length_total": "m",
         "mass_flow_out": "kg s-1", "mass_flow_fed": "kg s-1", "delivery": "1",
         **{f"block_{name}_force": "N" for name in ("piston", "gas", "weight", "wall_friction")}}


def table(summaries, parameters) -> pd.DataFrame:
    """One row per case summary: point, parameters (case keys), results."""
    rows = pd.DataFrame(summaries)
    columns = ["point", *parameters, *[c for c in RESULTS if c in rows]]
    out = rows[columns].sort_values(list(parameters) or ["point"]).reset_index(drop=True)
    out.attrs.update(units=UNITS, parameters=list(parameters))
    return out


def main(smk) -> None:
    log = setup_logging(smk)
    summaries = [read_json(path) for path in smk.input]
    out = table(summaries, list(smk.params.parameters or []))
    write_table(out, smk.output.table)
    log.info("%d cases\n%s", len(out), out.to_string())


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "curve"))

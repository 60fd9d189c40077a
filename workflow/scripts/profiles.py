"""Rule profiles: select the slugs passing the analysis position with length and velocity near the
mean (papers' bands unless configured) and average their slice fields against dx/d
(H12-H16, V13-V17).

Standalone:
    python workflow/scripts/profiles.py --input case=results/cases/h_default/base.nc \
        --input slugs=results/slugs/h_default/base.csv --input summary=results/summaries/h_default/base.json \
        --output profile=/tmp/profile.nc --output selection=/tmp/selection.csv --params position=0.26
"""

import numpy as np

from _helpers import ensure_parent, read_json, read_table, setup_logging, snakemake_or_cli, write_table


def select(slugs, summary, params):
    """Slugs passing the position in the steady window, near the mean length and velocity."""
    from analysis.profiles import select_slugs

    if not len(slugs):
        return slugs.iloc[:0].assign(position=[])
    return select_slugs(slugs, position=float(params.get("position", 0.26)),
                        length_band=params.get("length_band"),
                        velocity_band=params.get("velocity_band"), t_start=summary["t_start"])


def main(smk) -> None:
    log = setup_logging(smk)
    from analysis.casefile import open_case
    from analysis.profiles import slug_profiles

    ds = open_case(smk.input.case)
    slugs = read_table(smk.input.slugs)
    summary = read_json(smk.input.summary)
    selection = select(slugs, summary, smk.params)
    log.info("%d of %d slugs passing x = %s m selected", len(selection),
             selection.attrs.get("n_passing", 0), smk.params.get("position"))
    profile = slug_profiles(ds, selection)
    profile.attrs["vertical"] = int(bool(slugs.attrs.get("vertical", summary.get("vertical", False))))
    profile.attrs["position"] = float(smk.params.get("position", 0.26))
    profile.attrs["mean_n_particles"] = float(selection["n_particles"].mean()) if len(selection) else np.nan
    for key, value in list(profile.attrs.items()):  # netCDF attributes: numbers, strings, arrays
        if isinstance(value, (bool, np.bool_)):
            profile.attrs[key] = int(value)
        elif value is None:
            profile.attrs[key] = ""
    write_table(selection, smk.output.selection)
    profile.to_netcdf(ensure_parent(smk.output.profile))


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "profiles"))

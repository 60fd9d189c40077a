"""Rule radial: radial porosity and axial velocity in rings (0.25 d wide, 1.5 d high) through the
selected plugs, from the grain snapshot nearest each plug's passage (V18, V19).

Standalone:
    python workflow/scripts/radial.py --input case=results/cases/v_default/base.nc \
        --input slugs=results/slugs/v_default/base.csv \
        --input selection=results/profiles/v_default/base.selection.csv --output radial=/tmp/radial.nc
"""

import numpy as np
import xarray as xr

from _helpers import ensure_parent, read_table, setup_logging, snakemake_or_cli


def empty_profile(ds, reason: str) -> xr.Dataset:
    """A profile of NaNs on the ring grid, when no selected plug has a snapshot."""
    from analysis.casefile import geometry

    geo = geometry(ds)
    width = 0.25 * geo.particle_diameter
    r = np.arange(width / 2, geo.tube_radius, width)
    nan = np.full(r.size, np.nan)
    out = xr.Dataset({name: ("r", nan) for name in ("porosity", "porosity_sem", "velocity",
                                                     "velocity_sem")}, coords={"r": r})
    out.attrs.update(particle_diameter=geo.particle_diameter, n_slugs=0, note=reason)
    return out


def main(smk) -> None:
    log = setup_logging(smk)
    from analysis.casefile import CaseFileError, open_case
    from analysis.snapshots import averaged_radial_profile

    ds = open_case(smk.input.case)
    slugs = read_table(smk.input.slugs)
    selection = read_table(smk.input.selection)
    try:
        if not len(selection):
            raise CaseFileError("no plugs were selected at the analysis position")
        profile = averaged_radial_profile(ds, selection, slugs)
        profile.attrs["n_slugs"] = len(profile.attrs["slug_ids"])
        profile.attrs["note"] = ""
    except CaseFileError as err:
        log.warning("no radial profile: %s", err)
        profile = empty_profile(ds, str(err))
    profile.to_netcdf(ensure_parent(smk.output.radial))


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "radial"))

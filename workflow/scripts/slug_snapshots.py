"""Rule slug_snapshots: cross-sections at half tube length (H17) and the axial grain velocity
against height (H18 over time, H19 averaged through the slug), from the grain snapshots in a
window of `window` seconds centred on one slug passing half the tube length.

The slug is the first of the profile selection that passes there while snapshots exist, else any
slug passing there, else (no slug) the window is centred in the snapshot span.

Standalone:
    python workflow/scripts/slug_snapshots.py --input case=results/cases/h_default/base.nc \
        --input slugs=results/slugs/h_default/base.csv \
        --input selection=results/profiles/h_default/base.selection.csv \
        --output cross_sections=/tmp/cs.nc --output velocity_height=/tmp/vh.nc --params window=0.2
"""

import numpy as np
import pandas as pd
import xarray as xr

from _helpers import ensure_parent, read_table, setup_logging, snakemake_or_cli


def main(smk) -> None:
    log = setup_logging(smk)
    from analysis.casefile import geometry, open_case
    from analysis.snapshots import (cross_section, snapshot, snapshot_times,
                                    time_average_by_height, velocity_by_height)
    from analysis.statistics import choose_slug, covering_window

    ds = open_case(smk.input.case)
    slugs = read_table(smk.input.slugs)
    selection = read_table(smk.input.selection)
    geo = geometry(ds)
    window = float(smk.params.get("window", 0.2))
    x0 = geo.tube_length / 2
    times = snapshot_times(ds)
    slug_id, t_center = choose_slug(slugs, selection, x0, times, window)
    keep = np.nonzero(np.abs(times - t_center) <= window / 2 + 1e-9)[0]
    log.info("slug %d passes x0 = %.4f m at t = %.3f s; %d snapshots", slug_id, x0, t_center, keep.size)
    sections, heights = [], []
    for k in keep:
        _, pos, vel = snapshot(ds, int(k))
        sections.append(cross_section(pos, x0, geo.tube_radius, geo.particle_diameter))
        heights.append(velocity_by_height(pos, vel, (x0 - geo.particle_diameter / 2,
                                                     x0 + geo.particle_diameter / 2),
                                          geo.tube_radius, geo.particle_diameter))
    index = pd.Index(times[keep], name="snapshot_time")
    cs = xr.concat(sections, dim=index, data_vars=["grain_volume", "volume_fraction"],
                   coords="minimal", compat="override", join="exact")
    vh = xr.concat(heights, dim=index, data_vars="all", coords="minimal", compat="override",
                   join="exact")
    through = covering_window(slugs, slug_id, x0) or (float(times[keep][0]), float(times[keep][-1]))
    mean = time_average_by_height(vh, through)
    vh["mean_velocity"] = ("height", mean["velocity"].values,
                           {"units": "m s-1", "long_name": "time-averaged axial grain velocity"})
    attrs = {"slug_id": slug_id, "t_center": t_center, "x0": x0, "window": window,
             "average_t_start": through[0], "average_t_end": through[1]}
    cs.attrs.update(attrs)
    vh.attrs.update(attrs)
    cs.to_netcdf(ensure_parent(smk.output.cross_sections))
    vh.to_netcdf(ensure_parent(smk.output.velocity_height))


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "slug_snapshots"))

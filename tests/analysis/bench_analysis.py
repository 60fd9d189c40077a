"""Time the analysis of one case file: `python -m tests.analysis.bench_analysis [CASE.nc]`.

Without an argument, writes the 22.5 s synthetic default case (2250 frames x 150 slices, 50 grain
snapshots) to a temporary NetCDF4 file first. Prints the wall time of each step and the total.
Not a test: timings belong in benchmarks, not in tests.
"""

from __future__ import annotations

import io
import sys
import tempfile
import time
from pathlib import Path

import analysis as A
from analysis import plots


def run(path: Path) -> float:
    steps = []
    clock = time.perf_counter()

    def step(name):
        nonlocal clock
        now = time.perf_counter()
        steps.append((name, now - clock))
        clock = now

    start = clock
    ds = A.open_case(path); step("read case file")
    slugs = A.detect(ds); step(f"detect + track ({len(slugs)} slug frames, "
                               f"{slugs['slug_id'].nunique()} slugs)")
    stats = A.slug_statistics(slugs); step("statistics at 30 positions")
    sel = A.select_slugs(slugs)
    prof = A.slug_profiles(ds, sel); step(f"profiles at 0.26 m ({len(sel)} slugs)")
    summary = A.case_summary(ds, slugs=slugs); step("steady pressure drop + regime")
    has_snapshots = "snapshot_count" in ds
    if has_snapshots:
        sections = A.cross_section_series(ds)
        heights = A.velocity_height_series(ds)
        try:
            radial = A.averaged_radial_profile(ds, sel, slugs)
        except A.CaseFileError:
            radial = None
        step(f"snapshots ({sections.sizes['snapshot_time']} frames)")
    figures = [plots.porosity_image(ds, t_range=(0, 4)), plots.slug_rate(stats),
               *[plots.slug_statistic(stats, q) for q in ("min_porosity", "max_velocity", "length")],
               *[plots.slug_profile(prof, f) for f in ("porosity", "velocity", "wall_stress",
                                                       "granular_temperature")],
               plots.slug_profile(prof, ["drag_force", "particle_force"])]
    if has_snapshots:
        figures += [plots.cross_section_strip(sections, t_range=(9.9, 10.1)),
                    plots.velocity_height_image(heights)]
        if radial is not None:
            figures += [plots.radial_profile(radial, "porosity"),
                        plots.radial_profile(radial, "velocity")]
    for fig in figures:
        fig.savefig(io.BytesIO(), format="png")
    step(f"{len(figures)} figures to PNG")
    total = time.perf_counter() - start
    for name, seconds in steps:
        print(f"{seconds:8.3f} s  {name}")
    print(f"{total:8.3f} s  total  (regime {summary['regime']}, "
          f"pressure drop {summary['pressure_drop'] / 100:.2f} +- {summary['pressure_drop_sem'] / 100:.2f} hPa/m)")
    return total


def main(argv: list[str]) -> None:
    if argv:
        run(Path(argv[0]))
        return
    from . import synthetic
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "default.nc"
        synthetic.write(synthetic.default_case(), path)
        print(f"synthetic 22.5 s default case: {path.stat().st_size / 1e6:.1f} MB")
        run(path)


if __name__ == "__main__":
    main(sys.argv[1:])

#!/usr/bin/env python
"""What a shorter run cap would cost and change: the paper run's case files cut at the cap.

    python benchmarks/studies/run_cap.py SRC/results/cases results/cases --cap 20 [--all]
        [--keep SWEEP ...]
    python benchmarks/studies/run_cap.py --compare BASELINE/results/curves results/curves

Copies every case file of SRC (results/cases/<sweep>/<point>.nc of a finished paper run) into
the destination folder, cutting at `--cap` seconds the runs that went on beyond it: by default the
runs until steady (`run.until_steady`, the curve cases: they would have stopped at a cap of
`--cap`), with `--all` the fixed-duration ones too (the default cases and those whose consumers
ask a series); `--keep` leaves the runs of the sweeps it names whole (`--all --keep h_default
v_default`: the curve sweeps' `run.duration` set to the cap). A run writes, up to any time, the
frames of the same run stopped later, so a cut run is the run with that cap. It keeps its frames
up to the cap and says what a run stopped there would say: stop reason `max_duration` (until
steady) or `duration`, no steady window, no block after the cap, and CPU and wall seconds pro
rata of the simulated time (rough: filling the tube costs less per second than conveying). Its
recorded configuration is left as it was, so that the workflow reads it as the planned case.
Without `--cap` the files are copied whole (the baseline, analysed by the same code).

The warm-start sources (`base.nc`) are dated before the cases started from them, so that the
workflow's analysis runs on them without running a case again. In a checkout of the repository,
with the cut files in its results/cases:

    snakemake -j2 reference --rerun-triggers mtime --allowed-rules detect statistics profiles \\
        radial slug_snapshots curve curve_plot figure validation reference
    python workflow/scripts/validation_changes.py BASELINE/results/validation/validation.csv \\
        results/validation/validation.csv

Printed: per cut case, where it ended and where it is cut, and its CPU seconds before and after;
then the sums over all cases.

--compare reads the curve tables (results/curves/<sweep>.csv) of the baseline and of the cut run
and prints, for every point whose regime or pressure drop changed, the regime of each and the
pressure drop's move in the baseline's standard errors and in the cut run's (both runs share
their first frames, so the move is smaller than two independent runs would show); then how many
points moved by more than one and two errors.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from analysis.casefile import config, run_cpu_seconds  # noqa: E402

STEADY_ATTRS = ("steady_start", "steady_end", "steady_pressure_drop", "steady_pressure_drop_sem",
                "steady_correlation_time", "steady_outflow", "steady_inflow")
TIME_ATTRS = ("cpu_time_s", "cpu_time_total_s", "wall_time_s")


def until_steady(ds: xr.Dataset) -> bool:
    """Whether the run that wrote `ds` was to stop once steady (its recorded run.until_steady)."""
    return bool(config(ds).get("run.until_steady", False))


def frames_to(ds: xr.Dataset, cap: float) -> int:
    """How many of the frames of `ds` a run stopped at `cap` (s) writes."""
    t = ds["time"].values.astype(float)
    # frames are written every output.interval; a frame within a thousandth of one of the cap is kept
    return int(np.searchsorted(t, cap + 1e-3 * float(t[1] - t[0]), side="right"))


def cut(ds: xr.Dataset, cap: float) -> xr.Dataset:
    """`ds` with its frames up to `cap` (s) and the attributes of a run stopped there."""
    t = ds["time"].values.astype(float)
    keep = frames_to(ds, cap)
    out = ds.isel(time=slice(0, keep))
    ran, now = float(t[-1]), float(t[keep - 1])
    attrs = dict(ds.attrs)
    attrs["stop_reason"] = "max_duration" if until_steady(ds) else "duration"
    for name in STEADY_ATTRS:
        attrs[name] = math.nan
    if math.isfinite(float(attrs.get("blocked_time", math.nan))) and attrs["blocked_time"] > now:
        attrs["blocked_time"] = math.nan
    for name in TIME_ATTRS:
        if name in attrs:
            attrs[name] = float(attrs[name]) * now / ran
    out.attrs = attrs
    return out


def to_cut(ds: xr.Dataset, cap: float | None, every_run: bool, kept: bool = False) -> bool:
    """Whether the run of `ds` went on beyond `cap` and the study cuts it (`kept`: its sweep is
    left whole)."""
    if cap is None or kept:
        return False
    return frames_to(ds, cap) < ds.sizes["time"] and (every_run or until_steady(ds))


def write(ds: xr.Dataset, path: Path) -> None:
    """Write `ds` as a case file (temporary name first: no partial file under the final name)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    ds.to_netcdf(tmp)
    os.replace(tmp, path)


def compare_curves(baseline: Path, cut_run: Path) -> pd.DataFrame:
    """Per curve point of both runs: regimes and pressure drops (Pa/m) with their standard
    errors, and the move of the cut run's over each run's error."""
    rows = []
    for path in sorted(baseline.glob("*.csv")):
        other = cut_run / path.name
        if not other.is_file():
            continue
        a = pd.read_csv(path, comment="#").set_index("point")
        b = pd.read_csv(other, comment="#").set_index("point")
        for point in a.index.intersection(b.index):
            dp_a, se_a = a.at[point, "pressure_drop"], a.at[point, "pressure_drop_sem"]
            dp_b, se_b = b.at[point, "pressure_drop"], b.at[point, "pressure_drop_sem"]
            rows.append({"sweep": path.stem, "point": point, "regime": a.at[point, "regime"],
                         "regime_cut": b.at[point, "regime"], "pressure_drop": dp_a,
                         "pressure_drop_sem": se_a, "pressure_drop_cut": dp_b,
                         "pressure_drop_sem_cut": se_b,
                         "moved_in_baseline_se": (dp_b - dp_a) / se_a if se_a > 0 else math.nan,
                         "moved_in_cut_se": (dp_b - dp_a) / se_b if se_b > 0 else math.nan})
    return pd.DataFrame(rows)


def print_comparison(table: pd.DataFrame) -> None:
    changed = table[(table["regime"] != table["regime_cut"])
                    | (table["pressure_drop"] != table["pressure_drop_cut"])]
    for _, r in changed.iterrows():
        print(f"{r['sweep']}/{r['point']}: {r['regime']} -> {r['regime_cut']}, "
              f"{r['pressure_drop'] / 100:.2f} ± {r['pressure_drop_sem'] / 100:.2f} -> "
              f"{r['pressure_drop_cut'] / 100:.2f} ± {r['pressure_drop_sem_cut'] / 100:.2f} hPa/m "
              f"({r['moved_in_baseline_se']:+.1f} baseline s.e., {r['moved_in_cut_se']:+.1f} cut s.e.)")
    moved = changed["moved_in_baseline_se"].abs()
    ratios = (changed["pressure_drop_sem_cut"] / changed["pressure_drop_sem"]).dropna()
    errors = f"{ratios.median():.2f}x the baseline's" if len(ratios) else "– (none to compare)"
    print(f"\n{len(table)} curve points, {len(changed)} changed; regime changed: "
          f"{int((table['regime'] != table['regime_cut']).sum())}; pressure drop moved by more "
          f"than 1 baseline s.e.: {int((moved > 1).sum())}, more than 2: {int((moved > 2).sum())}; "
          f"the cut run's errors {errors} (median of the changed points); an error that did not "
          "converge (NaN): "
          f"{int(table['pressure_drop_sem'].isna().sum())} points in the baseline, "
          f"{int(table['pressure_drop_sem_cut'].isna().sum())} in the cut run")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("source", nargs="?", help="results/cases of a finished run")
    ap.add_argument("dest", nargs="?", help="folder to write the case files to (results/cases of a checkout)")
    ap.add_argument("--compare", nargs=2, metavar=("BASELINE_CURVES", "CUT_CURVES"),
                    help="compare the curve tables of two runs instead (results/curves of each)")
    ap.add_argument("--cap", type=float, help="cut at this simulated time, s (none: copy whole)")
    ap.add_argument("--all", action="store_true", help="cut the fixed-duration runs as well")
    ap.add_argument("--keep", nargs="+", default=[], metavar="SWEEP",
                    help="sweeps whose runs are left whole")
    args = ap.parse_args(argv)
    if args.compare:
        print_comparison(compare_curves(*map(Path, args.compare)))
        return
    if args.dest is None:
        ap.error("give SOURCE and DEST (or --compare BASELINE_CURVES CUT_CURVES)")
    source, dest = Path(args.source), Path(args.dest)
    if args.cap is not None and not args.cap > 0:
        ap.error(f"--cap {args.cap}: a positive simulated time in seconds")
    files = sorted(source.glob("*/*.nc"))
    if not files:
        ap.error(f"source {source}: no case files (<sweep>/<point>.nc)")
    if unknown := sorted(set(args.keep) - {path.parent.name for path in files}):
        ap.error(f"--keep {' '.join(unknown)}: no such sweep in {source}")
    if dest.resolve() == source.resolve():
        ap.error("dest is the source folder: the case files would be overwritten")
    before = after = 0.0
    cut_cases = 0
    for path in files:
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        cpu = run_cpu_seconds(ds.attrs)
        before += cpu
        if to_cut(ds, args.cap, args.all, path.parent.name in args.keep):
            ran = float(ds["time"].values[-1])
            ds = cut(ds, args.cap)
            cut_cases += 1
            print(f"{path.parent.name}/{path.stem}: ran to {ran:.2f} s ({ds.attrs.get('stop_reason')} "
                  f"after the cut), cut at {float(ds['time'].values[-1]):.2f} s; CPU {cpu:.0f} -> "
                  f"{run_cpu_seconds(ds.attrs):.0f} s")
        after += run_cpu_seconds(ds.attrs)
        write(ds, dest / path.parent.name / path.name)
    # warm-start sources dated before the cases they start (the workflow's mtime order)
    now = time.time()
    for path in dest.glob("*/*.nc"):
        stamp = now - 60 if path.stem == "base" else now
        os.utime(path, (stamp, stamp))
    scope = "every run" if args.all else "the runs until steady"
    if args.keep:
        scope += f" but those of {', '.join(args.keep)}"
    print(f"\n{len(files)} case files, {cut_cases} cut ({scope}, cap {args.cap} s): "
          f"{before:,.0f} -> {after:,.0f} CPU s ({after / before:.2f}x)")


if __name__ == "__main__":
    main()

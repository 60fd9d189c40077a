#!/usr/bin/env python
"""When would the cases of a run have stopped at another steady-stop tolerance, and what would move?

    python benchmarks/studies/steady_tolerance.py results/cases/*/*.nc [--tolerance 0.03 0.04 0.05]
        [--every 5] [--csv OUT.csv]

Replays the steady stop of `plugsim run` (engine.run.steady_window, with the case's own
keys except run.steady_rel_error; keys this engine no longer has are left out) on the recorded
time series of every case file
that ran with run.until_steady, checking every `--every` output frames as the run does every
frame. For each tolerance: the simulated time at which the case would have stopped, the steady
pressure drop the curves would show (Pa/m, analysis.curves.steady_pressure_drop on the series up
to that time: the replayed steady window, or after the fill and MSER-5 when never steady), and its
CPU time estimated pro rata of simulated time from the run's CPU seconds (all its parts; a warm-started case
costs about the same per simulated second throughout; a case that fills or drains does not, so
the estimate is rough there). A tolerance looser than the one the case ran with can only stop
it earlier; a tighter one stops it at most at the end of its series (marked not steady).
Prints a summary per tolerance (the cases' own one always included): total estimated CPU, saving,
and the change of the curve pressure drop against the case's own tolerance (median |change|,
standard deviation, largest).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from analysis.casefile import run_cpu_seconds  # noqa: E402
from analysis.curves import steady_pressure_drop  # noqa: E402
from engine import Case  # noqa: E402
from engine.case import KEYS  # noqa: E402
from engine.run import steady_window  # noqa: E402

SERIES = ("mass_out", "pressure_drop", "n_particles", "mass_in")


class _Series:
    """What steady_window reads of a Recorder: times and series up to a frame."""

    def __init__(self, times, series):
        self.times, self.series = times, series


def replay(ds: xr.Dataset, tolerance: float, every: int = 5) -> tuple[float, float, bool]:
    """(stop time s, steady pressure drop of the series up to it Pa/m, steady?) of a recorded run
    had it used run.steady_rel_error = tolerance; the series end (not steady) if it never converges."""
    config = yaml.safe_load(ds.attrs["config_yaml"])
    keys = {f"{section}.{name}": value for section, values in config.items()
            for name, value in values.items() if f"{section}.{name}" in KEYS}
    keys["run.steady_rel_error"] = tolerance
    case = Case().with_overrides(list(keys.items()))
    t = ds["time"].values.astype(float)
    series = {name: ds[name].values for name in SERIES}
    for k in range(2, len(t) + 1):
        if k % every and k != len(t):
            continue
        window = steady_window(_Series(t[:k], {n: s[:k] for n, s in series.items()}), case)
        if window:
            ran = ds.isel(time=slice(0, k))
            ran.attrs.update(stop_reason="steady", steady_start=window.start, steady_end=window.end)
            return float(t[k - 1]), _curve_value(ran), True
    ran = ds.copy()
    ran.attrs.update(stop_reason="max_duration", steady_start=float("nan"), steady_end=float("nan"))
    return float(t[-1]), _curve_value(ran), False


def _curve_value(ds: xr.Dataset) -> float:
    return float(steady_pressure_drop(ds)["pressure_drop"])


def table(paths, tolerances, every: int = 5) -> pd.DataFrame:
    """One row per until-steady case file and tolerance (see the module docstring)."""
    rows = []
    for path in paths:
        with xr.open_dataset(path) as ds:
            ds.load()
        config = yaml.safe_load(ds.attrs["config_yaml"])
        if not config["run"]["until_steady"]:
            continue
        end, cpu = float(ds["time"].values[-1]), run_cpu_seconds(ds.attrs)
        own = float(config["run"]["steady_rel_error"])
        for tol in sorted(set(tolerances) | {own}):  # the run's own: what the changes compare with
            stop, dp, steady = replay(ds, tol, every)
            rows.append({"case": str(path), "own_tolerance": own,
                         "tolerance": tol, "simulated_s": end, "stop_s": stop, "steady": steady,
                         "pressure_drop_pa_m": dp, "cpu_s": cpu,
                         "cpu_s_estimated": cpu * stop / end if end > 0 else cpu})
    return pd.DataFrame(rows)


def summary(rows: pd.DataFrame) -> pd.DataFrame:
    """Per tolerance: estimated CPU, saving against the cases' own runs, pressure-drop change."""
    own = rows[np.isclose(rows["tolerance"], rows["own_tolerance"])].set_index("case")
    out = []
    for tol, part in rows.groupby("tolerance"):
        part = part.set_index("case")
        change = part["pressure_drop_pa_m"] / own["pressure_drop_pa_m"].reindex(part.index) - 1
        out.append({"tolerance": tol, "cases": len(part), "steady": int(part["steady"].sum()),
                    "cpu_s": part["cpu_s_estimated"].sum(), "cpu_s_recorded": part["cpu_s"].sum(),
                    "saved_cpu_s": part["cpu_s"].sum() - part["cpu_s_estimated"].sum(),
                    "dp_change_median_abs": float(change.abs().median()),
                    "dp_change_std": float(change.std()), "dp_change_max_abs": float(change.abs().max())})
    return pd.DataFrame(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="+", help="case files (NetCDF) of a run")
    parser.add_argument("--tolerance", type=float, nargs="+", default=[0.03, 0.04, 0.05],
                        help="values of run.steady_rel_error to replay (fractions)")
    parser.add_argument("--every", type=int, default=5, help="check the stop every N output frames")
    parser.add_argument("--csv", default=None, help="write the per-case table here")
    args = parser.parse_args(argv)
    bad = [t for t in args.tolerance if not 0 < t <= 1]
    if bad or args.every < 1:
        parser.error(f"--tolerance must lie in (0, 1] (got {bad}) and --every >= 1 (got {args.every})")
    rows = table(args.cases, args.tolerance, args.every)
    if rows.empty:
        parser.error("none of the case files ran with run.until_steady")
    if args.csv:
        rows.to_csv(args.csv, index=False)
    print(summary(rows).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

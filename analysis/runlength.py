"""Run lengths: the averaging window a case needs for the precision asked of each of its quantities.

A case's validated quantities are means over its steady window: the pressure drop per tube length
and the grains in the tube (evenly sampled series, analysis.timeseries.mean_error), and the
slugs' travel speed and maximal granular velocity where they pass a position (one sample per
slug, statistics.describe: the papers' standard deviation / sqrt(n)). For each quantity asked,
`required_windows` measures the standard error over the window the case ran and extrapolates the
window that brings it to the precision asked, with the same estimator:

- series: error^2 = var tau / n, so n = var tau / target^2 samples, at least the case's
  run.steady_min_correlation_times tau (timeseries.required_length); also the shortest leading
  part of the window at which the estimate first reached it (timeseries.first_reached, what a stop
  testing the growing window sees);
- passages: n = (sd / target)^2 slugs at the rate the window saw them pass.

The window starts after the start-up transient where the analysis starts averaging
(curves.averaging_window: the run's own steady window, else after the fill and MSER-5) unless a
start is given. benchmarks/studies/run_lengths.py applies it to case files and to the
precision the papers' statements ask (docs/performance.md, "Run lengths the statements need").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd
import xarray as xr

from .casefile import config, geometry, require, seconds
from .curves import averaging_window, sampling_interval
from .statistics import describe, passages
from .timeseries import MIN_CORRELATION_TIMES, first_reached, mean_error, required_length

SERIES = {"pressure_drop": "Pa m-1", "n_particles": "1"}  # evenly sampled, per frame
PASSAGES = {"slug_velocity": "m s-1", "max_velocity": "m s-1"}  # one sample per slug passing
QUANTITIES = {**SERIES, **PASSAGES}


@dataclass(frozen=True)
class Precision:
    """The standard error asked of a mean: `value` in the quantity's units, or with relative=True
    a fraction of the mean."""

    value: float
    relative: bool = False

    def __post_init__(self):
        if not self.value > 0:
            raise ValueError(f"a precision must be > 0, not {self.value!r}")

    def absolute(self, mean: float) -> float:
        """The standard error asked (the quantity's units) of a mean `mean`."""
        return self.value * abs(mean) if self.relative else self.value


def required_windows(ds: xr.Dataset, precision: Mapping[str, Precision | float],
                     position: float | None = None, t_start: float | None = None,
                     slugs: pd.DataFrame | None = None, every: int = 10) -> pd.DataFrame:
    """One row per quantity of `precision` (keys of QUANTITIES; a bare number is an absolute
    standard error in the quantity's SI unit: Pa/m, grains, m/s).

    Columns: quantity, unit, estimator ("series" or "passages"), mean, sem (over the window run;
    NaN when not converged), target (the standard error asked, absolute), t_start, window_run (s),
    window_needed (s after t_start; NaN when the window run is too short to estimate it), reached
    (s after t_start at which the estimate of the growing window, tried every `every` frames,
    first met the target; NaN when it did not within the window run, and for passages),
    correlation_time (s; series), n (samples or slugs in the window run). The slug quantities are
    taken at `position` (m; default mid-tube, as curves.case_summary) from `slugs` (default
    slugs.detect(ds)); the window is averaging_window's unless `t_start` (s) is given.
    """
    unknown = sorted(set(precision) - set(QUANTITIES))
    if unknown:
        raise ValueError(f"no run length for {', '.join(unknown)}: known are {', '.join(QUANTITIES)}")
    t = seconds(ds["time"].values)
    if t_start is None:
        first, last, _ = averaging_window(ds)
    else:
        first, last = int(np.searchsorted(t, t_start)), t.size - 1
    t0, t1 = float(t[first]), float(t[last])
    interval = sampling_interval(t)
    keys = config(ds) if "config_yaml" in ds.attrs else {}
    times = float(keys.get("run.steady_min_correlation_times", MIN_CORRELATION_TIMES))
    geo = geometry(ds)
    rows = []
    for quantity, asked in precision.items():
        asked = asked if isinstance(asked, Precision) else Precision(float(asked))
        row = {"quantity": quantity, "unit": QUANTITIES[quantity], "t_start": t0, "window_run": t1 - t0}
        if quantity in SERIES:
            require(ds, quantity)
            x = np.asarray(ds[quantity].values[first:last + 1], dtype=np.float64)
            if quantity == "pressure_drop":
                x = x / geo.tube_length
            est = mean_error(x, interval, times)
            target = asked.absolute(est.mean)
            row.update(estimator="series", mean=est.mean, sem=est.error, target=target,
                       window_needed=required_length(x, target, interval, times),
                       reached=first_reached(x, target, interval, times, every),
                       correlation_time=est.tau_s, n=est.n)
        else:
            if slugs is None:
                from .slugs import detect
                slugs = detect(ds)
            at = geo.tube_length / 2 if position is None else float(position)
            sample = passages(slugs, [at], t0, t1)[quantity].to_numpy(dtype=np.float64)
            d = describe(sample)
            target = asked.absolute(d["mean"])
            sd = d["sem"] * math.sqrt(d["n"]) if d["n"] > 1 else math.nan
            needed = (sd / target) ** 2 * (t1 - t0) / d["n"] if d["n"] > 1 else math.nan
            row.update(estimator="passages", mean=d["mean"], sem=d["sem"], target=target,
                       window_needed=needed, reached=math.nan, correlation_time=math.nan, n=d["n"])
        rows.append(row)
    out = pd.DataFrame(rows, columns=["quantity", "unit", "estimator", "mean", "sem", "target",
                                      "t_start", "window_run", "window_needed", "reached",
                                      "correlation_time", "n"])
    out.attrs["units"] = {"t_start": "s", "window_run": "s", "window_needed": "s", "reached": "s",
                          "correlation_time": "s"}
    return out

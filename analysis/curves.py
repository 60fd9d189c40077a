"""Characteristic curves and sweep reductions (H3, H5-H7, H21, V4, V7, V8).

Per case: steady-state pressure drop per tube length (Pa/m; plots show hPa/m) with its standard
error (analysis.timeseries.mean_error), and the transport regime from the slug statistics. Over a sweep: a tidy table,
one row per case, against the swept parameters.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd
import xarray as xr

from .casefile import config, geometry, open_case, require, seconds, slice_faces
from .slugs import THRESHOLD, detect
from .statistics import slug_statistics
from .timeseries import MIN_CORRELATION_TIMES, mean_error, mser_start

# Regime thresholds (see regime):
BULK_FILL = 0.9  # tube "completely filled" (H §3.1, V §4.1): slugs cover >= 90 % of its length
# slug/plug conveying: slugs pass mid-tube at least once every 5 s (the papers' default cases pass
# 1.2 and 3.9 per second, H §5 and V §5; a sliding layer fills the cross-section only locally)
MIN_SLUG_RATE = 0.2  # 1/s
# sticking plugs (V §4.1: "big plugs sticking in the tube or their motion is reduced
# considerably"): plugs in the middle of the tube slower than the grains enter (0.04 m/s, V §4.2)
STICKING_SPEED = 0.04  # m/s
BLOCKED_DELIVERY = 0.5  # blocked: the tube delivers less than half of its feed over the window
ALWAYS = ("gas.superficial_velocity", "feed.mass_flow_kg_h", "tube.inclination_deg")


FILLED_FRACTION = 0.95  # hold-up fraction of its final level at which the tube counts as filled


def filled_index(ds: xr.Dataset, fraction: float = FILLED_FRACTION) -> int:
    """First frame at which the grains in the tube reach `fraction` of their final level (the
    median over the run's second half): the end of the filling. 0 without n_particles; a warm
    start is filled at once."""
    if "n_particles" not in ds:
        return 0
    n = np.asarray(ds["n_particles"].values, dtype=np.float64)
    level = np.median(n[n.size // 2:])
    return int(np.argmax(n >= fraction * level)) if level > 0 else 0


def averaging_window(ds: xr.Dataset) -> tuple[int, int, str]:
    """(first, last) frame of the steady window and where it comes from: "run" (the window of a
    run that stopped steady, attrs steady_start/steady_end), else "fill+mser" (once the tube has
    filled, filled_index: the papers average "after filling", and MSER-5 finds the remaining
    transient over, to the end of the run)."""
    t = seconds(ds["time"].values)
    start, end = (float(ds.attrs.get(k, np.nan)) for k in ("steady_start", "steady_end"))
    if ds.attrs.get("stop_reason") == "steady" and np.isfinite(start) and np.isfinite(end):
        return int(np.searchsorted(t, start)), int(np.searchsorted(t, end, side="right")) - 1, "run"
    dp = np.asarray(ds["pressure_drop"].values, dtype=np.float64)
    filled = filled_index(ds)
    return filled + mser_start(dp[filled:]), t.size - 1, "fill+mser"


def steady_pressure_drop(ds: xr.Dataset, t_start: float | None = None) -> dict:
    """Steady-state pressure drop per tube length (Pa/m) and its standard error (mean_error).

    The window runs from t_start (s) to the end of the run, or by default is averaging_window's: the
    same window as the run's steady stop gives the same number. Returns pressure_drop,
    pressure_drop_sem (Pa/m; NaN when the window covers fewer than the case's
    run.steady_min_correlation_times), pressure_drop_sem_estimate (Pa/m: the same estimator's error
    over such a short window too, MeanError.estimate), pressure_drop_correlation_time (s),
    pressure_drop_converged, t_start, t_end (s) and window ("given", "run" or "fill+mser").
    """
    require(ds, "pressure_drop")
    geo = geometry(ds)
    t = seconds(ds["time"].values)
    if t_start is None:
        first, last, source = averaging_window(ds)
    else:
        first, last, source = int(np.searchsorted(t, t_start)), t.size - 1, "given"
    keys = config(ds) if "config_yaml" in ds.attrs else {}
    times = float(keys.get("run.steady_min_correlation_times", MIN_CORRELATION_TIMES))
    dp = np.asarray(ds["pressure_drop"].values[first:last + 1], dtype=np.float64) / geo.tube_length
    est = mean_error(dp, sampling_interval(t), times)
    return {"pressure_drop": est.mean, "pressure_drop_sem": est.error, "pressure_drop_sem_estimate": est.estimate,
            "pressure_drop_correlation_time": est.tau_s, "pressure_drop_converged": est.converged,
            "t_start": float(t[first]), "t_end": float(t[last]), "window": source}


def sampling_interval(t) -> float:
    """Interval (s) of evenly sampled times; 1 for fewer than two."""
    return float(np.median(np.diff(t))) if len(t) > 1 else 1.0


def slug_fractions(ds: xr.Dataset, slugs: pd.DataFrame, t_start: float | None = None) -> dict:
    """Time means over frames at t >= t_start of the tube length covered by slugs (dense_fraction)
    and of the grain volume inside slugs (slug_fraction), both from the detected slugs."""
    geo = geometry(ds)
    t = seconds(ds["time"].values)
    t0 = t[0] if t_start is None else t_start
    frames = t >= t0
    phi = ds["porosity"].transpose("time", "x").values[frames]
    width = np.diff(slice_faces(np.asarray(ds["x"].values, dtype=np.float64)))
    total = np.nansum((1.0 - phi) * width, axis=1) * geo.cross_section / geo.particle_volume
    in_window = slugs[slugs["time"] >= t0]
    covered = in_window["length"].sum() / (frames.sum() * geo.tube_length)
    grains = total.sum()
    slug_fraction = in_window["n_particles"].sum() / grains if grains > 0 else 0.0
    return {"dense_fraction": float(covered), "slug_fraction": float(slug_fraction)}


def regime(dense_fraction: float, slug_rate: float, travel_speed: float = float("nan"),
           delivery: float = float("nan"), vertical: bool = False, stop_reason: str = "",
           bulk_fill: float = BULK_FILL, min_slug_rate: float = MIN_SLUG_RATE,
           sticking_speed: float = STICKING_SPEED,
           blocked_delivery: float = BLOCKED_DELIVERY) -> str:
    """Transport regime as the papers define it (H §3.1, §4, §5; V §4.1), from measured quantities.

    dense_fraction: time mean of the tube length covered by slug cores; slug_rate (1/s): slugs
    passing mid-tube; travel_speed (m/s): median travel speed of the slugs in the middle half of
    the tube; delivery: delivered over fed mass flow; stop_reason: the case file's. In this order:
    "blocked" (the run stopped blocked, or it delivers less than blocked_delivery of its feed);
    "bulk" (slugs fill the tube: the transport comes through the enforced feed); "sticking plugs"
    (vertical: plugs there but slower than sticking_speed); "slug" / "plug" (slugs pass mid-tube
    at least min_slug_rate per second, whatever share of the grains rests between them); else
    "sliding layer" (horizontal: grains slide or roll along the bottom) or "dilute" (vertical).
    NaN quantities never satisfy a condition.
    """
    if stop_reason == "blocked" or delivery < blocked_delivery:
        return "blocked"
    if dense_fraction >= bulk_fill:
        return "bulk"
    if vertical and travel_speed < sticking_speed:
        return "sticking plugs"
    if slug_rate >= min_slug_rate:
        return "plug" if vertical else "slug"
    return "dilute" if vertical else "sliding layer"


def _mid_tube(slugs: pd.DataFrame, tube_length: float, t_start: float | None) -> pd.Series:
    """Rows at t >= t_start (all without) whose slug centre lies in the middle half of the tube."""
    t0 = -np.inf if t_start is None else t_start
    return (slugs["time"] >= t0) & (np.abs(slugs["x_center"] - tube_length / 2) <= tube_length / 4)


def travel_speed(slugs: pd.DataFrame, tube_length: float, t_start: float | None = None) -> float:
    """Median travel speed (m/s, slug_velocity) over the frames at t >= t_start in which a slug's
    centre lies in the middle half of the tube, away from the inlet's and outlet's boundary
    regions (H §5: 0.05 m); NaN without such frames."""
    v = slugs.loc[_mid_tube(slugs, tube_length, t_start), "slug_velocity"].to_numpy(dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else float("nan")


def travel_speed_sem(slugs: pd.DataFrame, tube_length: float, t_start: float | None = None) -> float:
    """Standard error (m/s) of travel_speed: the slugs are the independent samples (the frames of
    one slug are not), so each slug seen mid-tube gives its median speed, and the error of the
    median is sqrt(pi/2) times that of a mean over those slugs; NaN with fewer than two slugs."""
    seen = slugs.loc[_mid_tube(slugs, tube_length, t_start) & np.isfinite(slugs["slug_velocity"])]
    per_slug = seen.groupby("slug_id")["slug_velocity"].median().to_numpy(dtype=np.float64)
    if per_slug.size < 2:
        return float("nan")
    return float(math.sqrt(math.pi / 2) * per_slug.std(ddof=1) / math.sqrt(per_slug.size))


def _slope(t, values) -> float:
    """Least-squares slope of values against t (units per s); NaN for fewer than two points."""
    return float(np.polyfit(t, values, 1)[0]) if len(t) > 1 else float("nan")


def force_balance(ds: xr.Dataset, window: float = 1.0) -> dict:
    """Axial forces on the grains in the tube (N), means over the last `window` seconds of the case:
    piston_force (the feed piston's push), gas_force (the drag of every slice: its drag per grain
    times its grains, (1 - porosity) A dx / V_p), weight_force (the grains' weight along the tube
    axis) and wall_friction_force (wall.friction times their weight across the axis: the sliding
    friction of a column resting on the wall)."""
    require(ds, "piston_force", "drag_force", "porosity", "n_particles")
    geo = geometry(ds)
    t = seconds(ds["time"].values)
    last = t >= t[-1] - window
    width = np.diff(slice_faces(ds["x"].values))
    grains = (1.0 - ds["porosity"].values[last]) * geo.cross_section * width / geo.particle_volume
    mass = geo.particle_density * geo.particle_volume
    weight = float(np.mean(ds["n_particles"].values[last])) * mass * geo.gravity
    incline = math.radians(geo.inclination_deg)
    mu_wall = float(config(ds).get("wall.friction", float("nan"))) if "config_yaml" in ds.attrs else float("nan")
    return {"piston_force": float(np.mean(ds["piston_force"].values[last])),
            "gas_force": float(np.mean(np.nansum(ds["drag_force"].values[last] * grains, axis=1))),
            "weight_force": weight * math.sin(incline),
            "wall_friction_force": mu_wall * weight * math.cos(incline)}


def case_summary(ds: xr.Dataset, threshold: float = THRESHOLD, t_start: float | None = None,
                 position: float | None = None,
                 slugs: pd.DataFrame | None = None) -> dict:
    """One case reduced to scalars: configuration (dotted keys) and results.

    Results: steady_pressure_drop's (pressure drop and error, its correlation time and whether it
    converged, window t_start, t_end), dense_fraction, slug_fraction, regime (and what decides it:
    travel_speed and its error travel_speed_sem, m/s; delivery), at `position` (default mid-tube): slug_rate (1/s), slug_velocity
    (m/s, travel speed of the tracked centres), max_velocity (m/s, the papers' mean maximal
    granular velocity, per passage) and max_velocity_time (time-weighted), slug_length (core) and
    slug_length_total (with the ends, the papers' reading; m), each with its standard error (_sem);
    n_particles (time mean in the window) and n_particles_sem (mean_error), mass_flow_out and
    mass_flow_in (kg/s, slopes of mass_out and mass_in over the window), mass_flow_fed (kg/s, the
    configured feed) and stop_reason; a blocked case adds the force balance of its last second
    (force_balance, N) as block_piston_force, block_gas_force, block_weight_force and
    block_wall_friction_force.
    """
    geo = geometry(ds)
    row = dict(config(ds)) if "config_yaml" in ds.attrs else {}
    steady = steady_pressure_drop(ds, t_start)
    t0 = steady["t_start"]
    slugs = detect(ds, threshold) if slugs is None else slugs
    fractions = slug_fractions(ds, slugs, t0)
    position = geo.tube_length / 2 if position is None else position
    stats = slug_statistics(slugs, [position], t_start=t0).iloc[0] if len(slugs) else None
    t = seconds(ds["time"].values)
    window = (t >= t0) & (t <= steady["t_end"])
    row.update(steady)
    row.update(fractions)
    nan = float("nan")
    for key, column in (("slug_rate", "rate"), ("slug_velocity", "slug_velocity_mean"),
                        ("slug_velocity_sem", "slug_velocity_sem"),
                        ("max_velocity", "max_velocity_mean"), ("max_velocity_sem", "max_velocity_sem"),
                        ("max_velocity_time", "max_velocity_time_mean"),
                        ("max_velocity_time_sem", "max_velocity_time_sem"),
                        ("slug_length", "length_mean"), ("slug_length_sem", "length_sem"),
                        ("slug_length_total", "length_total_mean"),
                        ("slug_length_total_sem", "length_total_sem")):
        row[key] = float(stats[column]) if stats is not None else (0.0 if key == "slug_rate" else nan)
    if "n_particles" in ds:
        grains = mean_error(ds["n_particles"].values[window], sampling_interval(t),
                            row.get("run.steady_min_correlation_times", MIN_CORRELATION_TIMES))
        row["n_particles"], row["n_particles_sem"] = grains.mean, grains.error
    for name in ("mass_out", "mass_in"):
        if name in ds:
            row[f"mass_flow_{name[5:]}"] = _slope(t[window], np.asarray(ds[name].values)[window])
    fed = row.get("feed.mass_flow_kg_h")
    row["mass_flow_fed"] = float(fed) / 3600 if fed is not None else nan
    row["delivery"] = row.get("mass_flow_out", nan) / row["mass_flow_fed"] if row["mass_flow_fed"] else nan
    row["stop_reason"] = str(ds.attrs.get("stop_reason", ""))
    row["travel_speed"] = travel_speed(slugs, geo.tube_length, t0) if len(slugs) else nan
    row["travel_speed_sem"] = travel_speed_sem(slugs, geo.tube_length, t0) if len(slugs) else nan
    row["regime"] = regime(fractions["dense_fraction"], row["slug_rate"], row["travel_speed"],
                           row["delivery"], geo.vertical, row["stop_reason"])
    if row["regime"] == "blocked" and "piston_force" in ds:
        row.update({f"block_{name}": value for name, value in force_balance(ds).items()})
    return row


def sweep_table(cases: Iterable, parameters: Iterable[str] | None = None, **kwargs) -> pd.DataFrame:
    """Tidy table of case_summary rows over a sweep: one row per case (paths or Datasets).

    Columns: case (file name or index), the parameters (default: every configuration key that
    differs between cases, plus superficial velocity, mass flow and inclination), then the results.
    kwargs go to case_summary.
    """
    rows = []
    for k, case in enumerate(cases):
        ds = open_case(case) if isinstance(case, (str, Path)) else case
        row = case_summary(ds, **kwargs)
        row["case"] = Path(case).name if isinstance(case, (str, Path)) else k
        rows.append(row)
    table = pd.DataFrame(rows)
    config_keys = [c for c in table.columns if "." in c]
    if parameters is None:
        varying = [c for c in config_keys if table[c].astype(str).nunique() > 1]
        parameters = list(dict.fromkeys([*varying, *[c for c in ALWAYS if c in table]]))
    results = ["pressure_drop", "pressure_drop_sem", "pressure_drop_correlation_time",
               "pressure_drop_converged", "regime", "t_start", "t_end", "window",
               "dense_fraction", "slug_fraction", "slug_rate", "slug_velocity", "travel_speed",
               "travel_speed_sem", "max_velocity", "max_velocity_sem", "slug_length", "slug_length_total", "n_particles", "n_particles_sem",
               "mass_flow_out", "mass_flow_fed", "delivery", "stop_reason"]
    columns = ["case", *parameters, *[c for c in results if c in table]]
    out = table[columns].sort_values(list(parameters) or ["case"]).reset_index(drop=True)
    out.attrs["units"] = {"pressure_drop": "Pa m-1", "pressure_drop_sem": "Pa m-1", "t_start": "s",
                          "t_end": "s", "pressure_drop_correlation_time": "s", "slug_rate": "s-1",
                          "slug_velocity": "m s-1", "travel_speed": "m s-1",
                          "travel_speed_sem": "m s-1", "max_velocity": "m s-1",
                          "max_velocity_sem": "m s-1", "slug_length": "m", "slug_length_total": "m", "mass_flow_out": "kg s-1",
                          "mass_flow_fed": "kg s-1", "delivery": "1"}
    return out


def unresolved_bulk(table: pd.DataFrame) -> pd.Series:
    """Rows that are bulk points whose case did not resolve the tangential dashpot (column
    `dashpot_resolved` False, or "False"/0 as a CSV reads it back; unknown counts as not flagged):
    a packed bed there carries a time-step error (docs/performance.md)."""
    if "regime" not in table or "dashpot_resolved" not in table:
        return pd.Series(False, index=table.index)
    unresolved = table["dashpot_resolved"].map(lambda v: str(v).strip().lower() in ("false", "0", "0.0"))
    return (table["regime"] == "bulk") & unresolved


# ---- shape of a characteristic curve (validation of the papers' trend statements) ---------------

def _weights(err, y):
    """1/err weights; points without an error get the median relative error of the others."""
    err = np.asarray(err, dtype=float)
    y = np.asarray(y, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(err / y)
    known = rel[np.isfinite(rel) & (rel > 0)]
    fallback = float(np.median(known)) if len(known) else 0.05  # 5 %: about the run-to-run scatter
    return np.where(np.isfinite(err) & (err > 0), err, fallback * np.abs(y))


def linear_slope(x, y, err) -> tuple[float, float]:
    """Weighted least-squares slope dy/dx and its standard error (units of y per unit of x).

    The error is scaled by the fit's reduced chi-square when that exceeds 1, so scatter beyond
    the points' own standard errors widens it (never narrows it).
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if len(x) < 2:
        raise ValueError("a slope needs at least two points")
    sigma = _weights(err, y)
    if len(x) == 2:
        return float((y[1] - y[0]) / (x[1] - x[0])), float(np.hypot(*sigma) / abs(x[1] - x[0]))
    coef, cov = np.polyfit(x, y, 1, w=1 / sigma, cov="unscaled")
    chi2 = float(np.sum(((y - np.polyval(coef, x)) / sigma) ** 2)) / (len(x) - 2)
    return float(coef[0]), float(np.sqrt(cov[0, 0] * max(chi2, 1.0)))


def trend(x, y, err, z: float = 2.0) -> str:
    """'increasing' / 'decreasing' when the weighted slope is more than z standard errors from 0,
    else 'flat'."""
    slope, sem = linear_slope(x, y, err)
    if slope > z * sem:
        return "increasing"
    if slope < -z * sem:
        return "decreasing"
    return "flat"


def is_monotonic_increasing(x, y, err, z: float = 2.0) -> bool:
    """True when no step between neighbouring points (sorted by x) falls by more than z combined
    standard errors, and the curve rises overall (last point above the first by more than that)."""
    order = np.argsort(np.asarray(x, dtype=float))
    y = np.asarray(y, dtype=float)[order]
    sigma = _weights(np.asarray(err, dtype=float)[order], y)
    steps = np.diff(y)
    tol = z * np.hypot(sigma[1:], sigma[:-1])
    return bool(np.all(steps >= -tol) and y[-1] - y[0] > z * np.hypot(sigma[0], sigma[-1]))


def hyperbola(x, a, x0, b):
    """a / (x - x0) + b: diverges at x0, tends to b for large x (V §4.1, Fig. 7); fit_deviation
    keeps x0 in [0, min x) and b >= 0."""
    return a / (x - x0) + b


def fit_deviation(x, y, err, model: str) -> tuple[float, dict]:
    """Largest relative deviation |y - fit| / fit of the points from a weighted fit of `model`
    ('linear' or 'hyperbola'), with the fitted parameters. Dimensionless."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    sigma = _weights(err, y)
    if model == "linear":
        if len(x) < 3:
            raise ValueError("a linear fit needs at least three points to be tested")
        coef = np.polyfit(x, y, 1, w=1 / sigma)
        fit, params = np.polyval(coef, x), {"slope": float(coef[0]), "intercept": float(coef[1])}
    elif model == "hyperbola":
        from scipy.optimize import curve_fit

        if len(x) < 4:
            raise ValueError("a hyperbola fit needs at least four points to be tested")
        # the papers' hyperbola (V §4.1): divergence at a positive x0 below the data, a finite
        # non-negative asymptote b; start with x0 halfway to 0 and b at the largest-x value
        lo_x0 = 0.0 if x.min() > 0 else -np.inf
        hi_x0 = x.min() - 1e-9 * max(float(np.ptp(x)), abs(float(x.min())), 1e-300)  # below the data
        x0 = 0.5 * x.min() if x.min() > 0 else x.min() - (x.max() - x.min())
        a0 = (y[np.argmin(x)] - y[np.argmax(x)]) * (x.min() - x0)
        b0 = max(float(y[np.argmax(x)]), 1e-9 * float(np.max(np.abs(y))))
        try:
            p, _ = curve_fit(hyperbola, x, y, p0=(a0, x0, b0), sigma=sigma,
                             bounds=([-np.inf, lo_x0, 0.0], [np.inf, hi_x0, np.inf]),
                             maxfev=20000)
        except RuntimeError as err_fit:
            raise ValueError(f"the hyperbola fit did not converge: {err_fit}") from None
        fit, params = hyperbola(x, *p), {"a": float(p[0]), "x0": float(p[1]), "b": float(p[2])}
    else:
        raise ValueError(f"unknown model {model!r} (known: linear, hyperbola)")
    return float(np.max(np.abs(y - fit) / np.abs(fit))), params

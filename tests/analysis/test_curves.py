"""Steady pressure drop and its error, regime rule, sweep table."""

import math

import numpy as np
import pandas as pd
import pytest
import yaml

from analysis import (case_summary, mean_error, mser_start, regime, steady_pressure_drop,
                      sweep_table)
from analysis import curves
from analysis.casefile import seconds
from analysis.curves import BLOCKED_DELIVERY, BULK_FILL, MIN_SLUG_RATE, STICKING_SPEED, travel_speed_sem

from . import synthetic as S

TIMES = np.arange(2250) * 0.01


def test_error_after_mser_covers_the_true_mean_of_correlated_noise():
    # 200 runs: a 6 s rise, then AR(1) noise (10 %, lag-one correlation 0.95, tau = 39 frames) for
    # 54 s, ~140 correlation times: the true mean lies within 2 standard errors in 95 % of runs for
    # exact errors, measured 96.5 % here; the naive std/sqrt(n) would cover ~25 %. Binomial spread
    # for 200 runs: 1.5 %.
    times = np.arange(6000) * 0.01
    z, starts = [], []
    for seed in range(200):
        p = S.pressure_signal(times, 1000.0, seed=seed)
        k = mser_start(p)
        est = mean_error(p[k:], 0.01)
        z.append((est.mean - 1000.0) / est.error)
        starts.append(times[k])
    z = np.array(z)
    assert 0.90 <= np.mean(np.abs(z) < 2) <= 0.99
    assert abs(np.mean(z)) < 0.25  # no bias from the transient: 3 x the spread of the mean of z
    # MSER finds the end of the rise (6 s) within the noise
    assert 3.5 <= min(starts) and max(starts) <= 12.0 and 5.0 <= np.mean(starts) <= 7.0


def test_steady_pressure_drop_in_pa_per_metre_with_an_explicit_window():
    ds = S.build([], 22.5, pressure_drop=1500.0, seed=3)
    res = steady_pressure_drop(ds, t_start=8.0)
    assert res["t_start"] == pytest.approx(8.0)
    expected = mean_error(np.asarray(ds["pressure_drop"].values)[800:] / S.L_TUBE, S.DT)
    assert res["pressure_drop"] == pytest.approx(expected.mean, rel=1e-12)
    assert res["pressure_drop_sem"] == pytest.approx(expected.error, rel=1e-12)
    assert res["pressure_drop_correlation_time"] == pytest.approx(expected.tau_s, rel=1e-12)
    assert res["window"] == "given" and res["pressure_drop_converged"]
    assert abs(res["pressure_drop"] - 1500.0) < 4 * res["pressure_drop_sem"]


def test_regime_rule_thresholds():
    nan = float("nan")
    below, at = MIN_SLUG_RATE * 0.99, MIN_SLUG_RATE
    assert regime(BULK_FILL, 0.0) == "bulk"
    assert regime(BULK_FILL - 0.01, at) == "slug"
    assert regime(BULK_FILL - 0.01, below) == "sliding layer"
    assert regime(0.1, below, vertical=True) == "dilute"
    assert regime(0.3, 1.0, 0.2, vertical=True) == "plug"
    # slug conveying whatever share of the grains rests between the slugs (no share is an input)
    assert regime(0.05, 1.2, 0.42) == "slug"
    # sticking: vertical plugs slower than the grains enter; horizontal slow slugs stay slugs
    assert regime(0.5, 0.0, STICKING_SPEED * 0.99, vertical=True) == "sticking plugs"
    assert regime(0.5, 1.0, STICKING_SPEED, vertical=True) == "plug"
    assert regime(0.5, 1.0, STICKING_SPEED * 0.99) == "slug"
    # blocked: the run says so, or under BLOCKED_DELIVERY of the feed leaves; before bulk
    assert regime(1.0, 0.0, nan, BLOCKED_DELIVERY * 0.99) == "blocked"
    assert regime(1.0, 0.0, nan, BLOCKED_DELIVERY) == "bulk"
    assert regime(0.3, 1.0, 0.3, 1.0, stop_reason="blocked") == "blocked"
    assert regime(0.3, 1.0, nan, nan) == "slug"  # unknown delivery and speed decide nothing


def _blocked(ds):
    """The same case, but nothing leaves the tube."""
    return ds.assign(mass_out=ds["mass_out"] * 0.0)


@pytest.mark.parametrize("make, inclination, expected", [
    (lambda: S.build([S.moving(1.0, 0.04, 2.0)], 10.0), 0.0, "bulk"),  # a dense column fills it
    (lambda: S.build(S.periodic(0.75, 0.3, 0.05, 10.0), 10.0), 0.0, "slug"),
    (lambda: S.build(S.periodic(0.75, 0.3, 0.05, 10.0), 10.0, inclination_deg=90.0), 90.0, "plug"),
    # 6 mm slugs hold ~10 % of the grains, yet they form and travel: slug conveying
    (lambda: S.build(S.periodic(0.75, 0.3, 0.006, 10.0), 10.0), 0.0, "slug"),
    (lambda: S.build([], 10.0), 0.0, "sliding layer"),  # no slugs at all
    (lambda: S.build([], 10.0, inclination_deg=90.0), 90.0, "dilute"),
    (lambda: S.build([S.moving(0.3, 0.0, 0.05)], 10.0, inclination_deg=90.0), 90.0,
     "sticking plugs"),
    (lambda: _blocked(S.build(S.periodic(0.75, 0.3, 0.05, 10.0), 10.0)), 0.0, "blocked"),
])
def test_regime_of_synthetic_cases(make, inclination, expected):
    summary = case_summary(make())
    assert summary["regime"] == expected


def test_case_summary_reports_the_known_slug_numbers():
    summary = case_summary(S.build(S.periodic(0.75, 0.3, 0.05, 22.5), 22.5))
    # rate: one per 0.75 s +- one slug over the steady window (>= 10 s here)
    assert summary["slug_rate"] == pytest.approx(1 / 0.75, abs=1 / 10.0)
    assert summary["slug_velocity"] == pytest.approx(0.3, rel=5e-4)  # see test_slugs
    assert summary["slug_length"] == pytest.approx(0.05, abs=1e-9)
    ends = 2 * S.RAMP * (S.PHI_GAP - S.THRESHOLD) / (S.PHI_GAP - S.PHI_SLUG)  # see test_slugs
    assert 0.05 + ends <= summary["slug_length_total"] <= 0.05 + ends + 3 * S.DX
    assert summary["max_velocity"] == pytest.approx(0.3, abs=1e-12)
    assert summary["max_velocity_time"] == pytest.approx(0.3, abs=1e-12)
    assert summary["travel_speed"] == pytest.approx(0.3, rel=5e-3)
    assert summary["travel_speed_sem"] < 5e-3 * 0.3  # every slug travels at 0.3 m/s
    assert summary["delivery"] == pytest.approx(1.0, rel=1e-9)  # mass_out rises at the feed rate
    # slugs cover length/spacing = 0.05 / 0.225 of the tube, +- one slug's part at the ends
    assert summary["dense_fraction"] == pytest.approx(0.05 / 0.225, abs=0.05 / S.L_TUBE)
    assert summary["gas.superficial_velocity"] == 1.0


def test_sweep_table_against_the_swept_parameters(tmp_path):
    levels = {(0.5, 2.49): 3000.0, (1.0, 2.49): 1000.0, (0.5, 9.95): 6000.0, (1.0, 9.95): 2500.0}
    cases = []
    for k, ((vs, mdot), level) in enumerate(levels.items()):
        ds = S.build(S.periodic(0.75, 0.3, 0.05, 12.0), 12.0, pressure_drop=level, seed=k,
                     **{"gas.superficial_velocity": vs, "feed.mass_flow_kg_h": mdot})
        path = tmp_path / f"case{k}.nc"
        S.write(ds, path)
        cases.append(path)
    table = sweep_table(cases)
    # the two swept keys (and the inclination, always listed) follow the case name
    assert set(table.columns[1:4]) == {"gas.superficial_velocity", "feed.mass_flow_kg_h",
                                       "tube.inclination_deg"}
    assert len(table) == 4 and set(table["regime"]) == {"slug"}
    for _, row in table.iterrows():
        level = levels[(row["gas.superficial_velocity"], row["feed.mass_flow_kg_h"])]
        assert abs(row["pressure_drop"] - level) < 4 * row["pressure_drop_sem"]  # 4 std errors
    assert table.attrs["units"]["pressure_drop"] == "Pa m-1"


# ---- curve shapes for the papers' trend statements ----------------------------------------------

def test_linear_slope_recovers_a_known_line_and_its_error():
    # y = 3 x + 1 with Gaussian noise of sigma 0.1: the weighted fit must find the slope within
    # a few of its own standard errors, and that error must be near the analytic
    # sigma / sqrt(sum (x - mean x)^2) = 0.1 / sqrt(82.5) = 0.011 (chi2 scaling only widens it).
    rng = np.random.default_rng(1)
    x = np.arange(10.0)
    y = 3 * x + 1 + rng.normal(0, 0.1, x.size)
    slope, sem = curves.linear_slope(x, y, np.full(x.size, 0.1))
    assert abs(slope - 3) < 3 * sem
    assert 0.011 <= sem < 0.02


def test_trend_names_rises_falls_and_noise():
    x = np.linspace(0.5, 5, 9)
    err = np.full(x.size, 0.5)
    assert curves.trend(x, 10 + 2 * x, err) == "increasing"
    assert curves.trend(x, 10 - 2 * x, err) == "decreasing"
    # alternating +-0.5 around a constant: slope within its error
    assert curves.trend(x, 10 + 0.5 * (-1) ** np.arange(x.size), err) == "flat"


def test_monotonic_increase_tolerates_noise_but_not_a_real_drop():
    x = np.arange(6.0)
    err = np.full(6, 0.1)
    assert curves.is_monotonic_increasing(x, [1.0, 1.9, 1.85, 3.0, 4.1, 5.0], err)  # dip 0.05 < 2*0.14
    assert not curves.is_monotonic_increasing(x, [1.0, 2.0, 1.2, 3.0, 4.0, 5.0], err)  # drop 0.8
    assert not curves.is_monotonic_increasing(x, np.full(6, 2.0), err)  # no rise at all


def test_fit_deviation_accepts_its_model_and_rejects_the_other():
    eta = np.array([4.5, 5.5, 6.73, 7.5, 8.5])
    y = curves.hyperbola(eta, 60.0, 3.5, 20.0)  # diverges at 3.5, tends to 20
    err = 0.01 * y
    dev, p = curves.fit_deviation(eta, y, err, "hyperbola")
    assert dev < 1e-4 and p["x0"] == pytest.approx(3.5, rel=1e-3)
    # the same points are far from a straight line (the first one most)
    assert curves.fit_deviation(eta, y, err, "linear")[0] > 0.05
    mdot = np.array([1.0, 2.49, 5.0, 7.5, 9.95])
    dev, p = curves.fit_deviation(mdot, 2.0 * mdot + 1.0, np.full(5, 0.1), "linear")
    assert dev < 1e-9 and p["slope"] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="unknown model"):
        curves.fit_deviation(mdot, mdot, mdot, "cubic")


def test_the_window_of_a_run_that_stopped_steady_gives_its_number():
    # the run's steady window [10 s, end] wins over the fill + MSER rule (which would start at ~6 s)
    ds = S.build([], 22.5, pressure_drop=1500.0, seed=4)
    t = seconds(ds["time"].values)
    dp = np.asarray(ds["pressure_drop"].values)
    ds.attrs.update(stop_reason="steady", steady_start=10.0, steady_end=float(t[-1]))
    res = steady_pressure_drop(ds)
    run = mean_error(dp[t >= 10.0], S.DT)  # what engine.run.steady_window computes (Pa)
    assert res["window"] == "run" and res["t_start"] == 10.0 and res["t_end"] == t[-1]
    assert res["pressure_drop"] * S.L_TUBE == pytest.approx(run.mean, rel=1e-12)
    assert res["pressure_drop_sem"] * S.L_TUBE == pytest.approx(run.error, rel=1e-12)
    # and the case summary (curves, validation, captions) carries the same numbers
    summary = case_summary(ds)
    assert summary["pressure_drop"] == res["pressure_drop"]
    assert summary["pressure_drop_sem"] == res["pressure_drop_sem"]
    # a run that did not stop steady: fill + MSER
    ds.attrs.update(stop_reason="max_duration", steady_start=float("nan"), steady_end=float("nan"))
    res = steady_pressure_drop(ds)
    assert res["window"] == "fill+mser" and 3.5 <= res["t_start"] <= 9.0


def test_steady_window_starts_after_the_tube_has_filled():
    # a flat, noisy pressure drop (MSER alone would keep it whole) while the hold-up still rises
    # to its level until t = 4 s: the papers average "after filling", so the window must start
    # where the hold-up reaches 95 % of its final level (t = 3.8 s)
    ds = S.build([], duration=10.0, pressure_drop=1000.0)
    t = seconds(ds["time"].values)
    ds["pressure_drop"] = ("time", 1000.0 + 10 * np.sin(7 * t))
    ds["n_particles"] = ("time", 3000.0 * np.minimum(t / 4.0, 1.0))
    assert t[curves.filled_index(ds)] == pytest.approx(3.8, abs=0.011)
    assert steady_pressure_drop(ds)["t_start"] >= 3.8
    ds["n_particles"] = ("time", np.full(t.size, 3000.0))  # a warm start: filled from the start
    assert curves.filled_index(ds) == 0


def test_travel_speed_error_counts_slugs_not_frames():
    # four slugs at 0.2-0.5 m/s, seen in 3 to 30 frames each mid-tube (x = 0.5 m of a 1 m tube),
    # plus frames near the inlet that must not count: the error is that of the median over the
    # four slugs, sqrt(pi/2) s / sqrt(4) with s the standard deviation of their speeds
    rows = [{"time": 1.0 + 0.01 * k, "slug_id": i, "x_center": 0.5, "slug_velocity": v}
            for i, (v, frames) in enumerate([(0.2, 3), (0.3, 30), (0.4, 10), (0.5, 5)])
            for k in range(frames)]
    rows += [{"time": 1.0, "slug_id": 9, "x_center": 0.05, "slug_velocity": 3.0}]
    slugs = pd.DataFrame(rows)
    expected = math.sqrt(math.pi / 2) * np.std([0.2, 0.3, 0.4, 0.5], ddof=1) / 2
    assert travel_speed_sem(slugs, 1.0) == pytest.approx(expected, rel=1e-12)
    assert math.isnan(travel_speed_sem(slugs[slugs["slug_id"] == 1], 1.0))  # one slug: no spread


@pytest.mark.parametrize("inclination", [0.0, 90.0])
def test_force_balance_of_a_packed_column(inclination):
    # a tube half full of grains (porosity 0.5 everywhere) with a drag of 1 uN per grain and a
    # piston pushing 2 N over the last second (1 N before): the gas force is the drag times the
    # grains, (1 - 0.5) A L / V_p; the weight acts along the axis when vertical, and wall.friction
    # times it across the axis when horizontal
    ds = S.build([], duration=3.0, inclination_deg=inclination)
    ds["porosity"][:] = 0.5
    ds["drag_force"][:] = 1e-6
    t = ds["time"].values
    ds["piston_force"][:] = np.where(t >= t[-1] - 1.0, 2.0, 1.0)
    ds["n_particles"][:] = 1000
    cfg = yaml.safe_load(ds.attrs["config_yaml"])
    cfg["wall"] = {"friction": 0.3}
    ds.attrs["config_yaml"] = yaml.safe_dump(cfg)
    balance = curves.force_balance(ds)
    grains = 0.5 * S.A_TUBE * S.L_TUBE / S.V_GRAIN
    weight = 1000 * S.RHO * S.V_GRAIN * 9.81
    assert balance["piston_force"] == pytest.approx(2.0)
    assert balance["gas_force"] == pytest.approx(1e-6 * grains, rel=1e-6)  # float32 fields
    vertical = inclination == 90.0
    assert balance["weight_force"] == pytest.approx(weight if vertical else 0.0, abs=1e-12)
    assert balance["wall_friction_force"] == pytest.approx(0.0 if vertical else 0.3 * weight, abs=1e-12)

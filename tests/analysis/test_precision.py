"""Work-precision errors on summaries whose answer is known."""

import numpy as np
import pandas as pd
import pytest

from analysis.plots import work_precision
from analysis.precision import relative_errors


def summaries():
    # knob 0.1 is the reference; 0.2 is 10 % off in pressure drop with 1 % standard errors (resolved),
    # 0.4 is 1 % off with the same errors (within sqrt(2) standard errors: not resolved)
    return pd.DataFrame({
        "numerics.time_step_fraction": [0.4, 0.1, 0.2],
        "pressure_drop": [1010.0, 1000.0, 1100.0], "pressure_drop_sem": [10.0, 10.0, 10.0],
        "slug_velocity": [0.30, 0.30, 0.36], "slug_velocity_sem": [0.003, 0.003, 0.003],
        "slug_length": [0.05, 0.05, 0.05], "slug_length_sem": [np.nan, 0.001, 0.001],
        "wall_time_s": [10.0, 40.0, 20.0], "cpu_time_s": [9.0, 38.0, 19.0]})


def test_relative_errors_against_the_reference():
    table = relative_errors(summaries(), "numerics.time_step_fraction", 0.1)
    assert list(table["value"]) == [0.1, 0.2, 0.4]  # sorted by the knob
    ref, half, quarter = table.iloc[0], table.iloc[1], table.iloc[2]
    assert ref["is_reference"] and ref["pressure_drop_error"] == 0 and not ref["pressure_drop_resolved"]
    assert half["pressure_drop_error"] == pytest.approx(0.10)
    assert half["pressure_drop_noise"] == pytest.approx(np.sqrt(2) * 0.01)
    assert half["pressure_drop_resolved"] and half["slug_velocity_resolved"]
    assert quarter["pressure_drop_error"] == pytest.approx(0.01) and not quarter["pressure_drop_resolved"]
    assert np.isnan(quarter["slug_length_noise"])  # an unknown error stays unknown
    assert quarter["cpu_time_s"] == 9.0


def test_missing_reference_is_refused():
    with pytest.raises(ValueError, match="reference value 0.3"):
        relative_errors(summaries(), "numerics.time_step_fraction", 0.3)


def test_work_precision_figure_has_units_and_log_axes():
    table = relative_errors(summaries(), "numerics.time_step_fraction", 0.1)
    fig = work_precision([table], {"numerics.time_step_fraction": 0.2})
    axes = fig.axes
    assert len(axes) == 3
    assert all(ax.get_xscale() == "log" and ax.get_yscale() == "log" for ax in axes)
    assert "CPU time" in axes[0].get_xlabel() and "(s" in axes[0].get_xlabel()


def test_run_to_run_scatter_counts_shared_cases_once():
    from analysis.precision import run_to_run_scatter

    a = relative_errors(summaries(), "numerics.time_step_fraction", 0.1)
    b = a.copy()  # the same cases seen by a second knob sweep
    scatter = run_to_run_scatter([a, b])
    x = np.array([1010.0, 1000.0, 1100.0])
    assert scatter["pressure_drop"] == pytest.approx(np.std(x, ddof=1) / x.mean())
    assert scatter["slug_length"] == pytest.approx(0.0, abs=1e-12)


def test_run_to_run_scatter_comes_from_the_seed_study_when_there_is_one():
    from analysis.precision import run_to_run_scatter

    knob = relative_errors(summaries(), "numerics.time_step_fraction", 0.1)  # a 10 % knob effect
    seeds = pd.DataFrame({"run.seed": [0, 1, 2], "pressure_drop": [1000.0, 1020.0, 990.0],
                          "pressure_drop_sem": [10.0] * 3, "slug_velocity": [0.30, 0.31, 0.29],
                          "slug_velocity_sem": [0.003] * 3, "slug_length": [0.05, 0.05, 0.06],
                          "slug_length_sem": [0.001] * 3, "cpu_time_s": [19.0, 20.0, 21.0]})
    seed_table = relative_errors(seeds, "run.seed", 0)
    scatter = run_to_run_scatter([knob, seed_table])
    x = np.array([1000.0, 1020.0, 990.0])
    # the knob's 10 % effect must not widen the noise floor it is judged against
    assert scatter["pressure_drop"] == pytest.approx(np.std(x, ddof=1) / x.mean())
    assert scatter["pressure_drop"] < run_to_run_scatter([knob])["pressure_drop"]
    fig = work_precision([knob, seed_table], {"run.seed": 0})
    # the legend stands right of the row's last panel, clear of the points
    assert "seed only (noise floor)" in [t.get_text() for t in fig.axes[2].get_legend().get_texts()]


def test_default_point_is_the_mean_of_the_seed_runs():
    from analysis.precision import pool_default

    seeds = pd.DataFrame({"run.seed": [0, 1, 2, 3], "pressure_drop": [1100.0, 1000.0, 1020.0, 980.0],
                          "pressure_drop_sem": [30.0] * 4, "slug_velocity": [0.30] * 4,
                          "slug_velocity_sem": [0.003] * 4, "slug_length": [0.05] * 4,
                          "slug_length_sem": [0.001] * 4, "wall_time_s": [20.0] * 4,
                          "cpu_time_s": [18.0, 20.0, 22.0, 20.0]})
    rows = summaries()  # knob 0.2 is the default here, a single run at 1100 Pa/m
    pooled = pool_default(rows, "numerics.time_step_fraction", 0.2, seeds)
    default = pooled.loc[pooled["numerics.time_step_fraction"] == 0.2].iloc[0]
    x = np.array([1100.0, 1000.0, 1020.0, 980.0])
    assert default["pressure_drop"] == pytest.approx(x.mean())
    assert default["pressure_drop_sem"] == pytest.approx(x.std(ddof=1) / 2.0)
    assert default["cpu_time_s"] == pytest.approx(20.0)
    others = pooled.loc[pooled["numerics.time_step_fraction"] != 0.2]
    pd.testing.assert_frame_equal(others, rows.loc[rows["numerics.time_step_fraction"] != 0.2])
    # one chance-high default run is no longer a 10 % error against the reference
    table = relative_errors(pooled, "numerics.time_step_fraction", 0.1)
    assert table.loc[table["value"] == 0.2, "pressure_drop_error"].iloc[0] == pytest.approx(0.025)


def seed_runs(pressure_drops):
    n = len(pressure_drops)
    return pd.DataFrame({"run.seed": list(range(n)), "pressure_drop": pressure_drops,
                         "pressure_drop_sem": [10.0] * n, "slug_velocity": [0.30] * n,
                         "slug_velocity_sem": [0.003] * n, "slug_length": [0.05] * n,
                         "slug_length_sem": [0.001] * n, "cpu_time_s": [20.0] * n})


def test_each_regime_is_drawn_against_its_own_seed_scatter():
    from analysis.precision import by_regime, run_to_run_scatter

    tables = []
    for regime, seeds in (("slug", [1000.0, 1010.0, 990.0]), ("bulk", [1000.0, 1200.0, 800.0])):
        for table in (relative_errors(summaries(), "numerics.time_step_fraction", 0.1),
                      relative_errors(seed_runs(seeds), "run.seed", 0)):
            table.insert(0, "regime", regime)
            tables.append(table)
    groups = by_regime(tables)
    assert list(groups) == ["slug", "bulk"] and all(len(g) == 2 for g in groups.values())
    fig = work_precision(tables, {"numerics.time_step_fraction": 0.2})
    assert len(fig.axes) == 6  # a row of three panels per regime
    for row, regime in enumerate(groups):
        expected = 2 * run_to_run_scatter(groups[regime])["pressure_drop"]
        dashed = [line.get_ydata()[0] for line in fig.axes[3 * row].get_lines() if line.get_linestyle() == "--"]
        assert dashed == [pytest.approx(expected)], regime
        assert fig.axes[3 * row].get_ylabel().startswith(regime)


def test_a_reference_without_slugs_is_named_instead_of_drawn():
    rows = summaries()
    rows.loc[rows["numerics.time_step_fraction"] == 0.1, "slug_velocity"] = np.nan  # a bed: no slug
    fig = work_precision([relative_errors(rows, "numerics.time_step_fraction", 0.1)], {})
    notes = [[t.get_text() for t in ax.texts] for ax in fig.axes]
    assert any("no value in the reference run" in n and "time step" in n for n in notes[1])
    assert not any("no value" in n for n in notes[0] + notes[2])

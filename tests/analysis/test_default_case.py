"""The whole analysis on the 22.5 s default-like synthetic case, read back from NetCDF."""

import numpy as np
import pytest

from analysis import case_summary, slug_statistics, tracks


def test_rates_along_the_tube(default_slugs):
    stats = slug_statistics(default_slugs)
    duration = stats.attrs["duration"]
    inlet = stats[(stats["x"] > 0.02) & (stats["x"] < 0.09)]
    beyond = stats[stats["x"] > 0.13]
    # 5 cm slugs every 0.75 s everywhere, plus 15 mm slugs between them that dissolve before
    # 0.11 m: twice the rate near the inlet; +- one slug over the run at each position
    assert np.all(np.abs(inlet["rate"] - 2 / 0.75) <= 2 / duration)
    assert np.all(np.abs(beyond["rate"] - 1 / 0.75) <= 1 / duration)
    assert np.allclose(beyond[beyond["x"] < 0.45]["length_mean"], 0.05, atol=1e-9)


def test_small_slugs_dissolve_and_big_ones_leave(default_slugs):
    table = tracks(default_slugs)
    # lengths away from the inlet and outlet (a slug touching them shows its visible part only)
    inside = default_slugs[~default_slugs["truncated"]].groupby("slug_id")["length"].max()
    dissolved = table[table["fate"] == "dissolved"].index
    left = table[table["fate"] == "left"].index
    assert len(dissolved) == 30 and (table.loc[dissolved, "x_last"] < 0.12).all()
    assert (inside[dissolved] <= 0.015 + 1e-9).all()
    assert len(left) == 30 and np.allclose(inside[left], 0.05, atol=1e-9)


def test_summary_of_the_default_case(default_case, default_slugs):
    summary = case_summary(default_case, slugs=default_slugs)
    assert summary["regime"] == "slug"
    assert abs(summary["pressure_drop"] - 1000.0) < 4 * summary["pressure_drop_sem"]
    assert summary["mass_flow_out"] == pytest.approx(2.49 / 3600, rel=1e-9)

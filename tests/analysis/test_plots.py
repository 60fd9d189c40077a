"""Plot functions: they draw the data given, with units on every axis, and save as PNG."""

import io

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from analysis import (cross_section_series, select_slugs, slug_profiles,
                      slug_statistics, velocity_height_series, plots)
from analysis.snapshots import time_average_by_height

from . import synthetic as S


def saved(fig):
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()[:8] == b"\x89PNG\r\n\x1a\n"


def test_porosity_image_shows_the_porosity_in_the_papers_grey_scale(default_case):
    fig = plots.porosity_image(default_case, t_range=(10.0, 14.0))
    ax = fig.axes[0]
    image = ax.get_images()[0]
    expected = default_case["porosity"].sel(time=slice(10.0, 14.0)).values.T
    assert np.array_equal(image.get_array(), expected)
    assert image.get_cmap().name == "gray"  # dark = low porosity
    assert ax.get_xlabel() == "time (s)" and ax.get_ylabel() == "x (m)"
    assert saved(fig)


def test_statistics_plots_have_error_bars_and_dotted_quartiles(default_slugs):
    stats = slug_statistics(default_slugs)
    fig = plots.slug_statistic(stats, "length")
    ax = fig.axes[0]
    dotted = [line for line in ax.get_lines() if line.get_linestyle() == ":"]
    assert len(dotted) == 2
    assert np.allclose(dotted[0].get_ydata(), stats["length_q25"])
    assert ax.get_ylabel() == "slug core length, porosity < 0.6 (m)" and ax.get_xlabel() == "x (m)"
    ax = plots.slug_statistic(stats, "length_total").axes[0]
    assert ax.get_ylabel() == "slug length with its ends (m)"
    fig = plots.slug_rate(stats)
    assert fig.axes[0].get_ylabel() == "Slug rate (1/s)"
    assert saved(fig)


def test_vertical_statistics_speak_of_plugs_and_height():
    ds = S.build(S.periodic(0.75, 0.16, 0.024, 4.0), 4.0, inclination_deg=90.0)
    from analysis import detect
    stats = slug_statistics(detect(ds))
    ax = plots.slug_statistic(stats, "min_porosity").axes[0]
    assert ax.get_xlabel() == "z (m)" and "plug" in ax.get_ylabel()


def test_profile_plots(default_case, default_slugs):
    prof = slug_profiles(default_case, select_slugs(default_slugs))
    fig = plots.slug_profile(prof, ["drag_force", "particle_force"])
    ax = fig.axes[0]
    assert ax.get_ylabel() == "force per grain (µN)" and ax.get_xlabel() == r"$\Delta x/d$"
    assert len(ax.get_lines()) == 2
    assert np.allclose(ax.get_lines()[0].get_ydata(), prof["drag_force"].values * 1e6, equal_nan=True)
    ax = plots.slug_profile(prof, "granular_temperature").axes[0]
    assert ax.get_ylabel() == "granular temperature per grain (nJ)"
    assert np.nanmax(ax.get_lines()[0].get_ydata()) == pytest.approx(S.TEMPERATURE_PEAK * 1e9)
    ax.figure.canvas.draw()  # no offset exponent: the tick labels carry the numbers themselves
    assert ax.yaxis.get_offset_text().get_text() == ""
    ax = plots.slug_profile(prof, "wall_stress").axes[0]
    dotted = [line for line in ax.get_lines() if line.get_linestyle() == ":"]
    assert len(dotted) == 1  # the weight of the resting layer (H15)
    assert np.allclose(dotted[0].get_ydata(), prof["resting_layer_stress"].values, equal_nan=True)
    assert saved(ax.figure)


def test_snapshot_plots(default_case):
    series = cross_section_series(default_case)
    fig = plots.cross_section(series.isel(snapshot_time=0))
    assert fig.axes[0].get_xlabel() == "y (mm)"
    assert saved(plots.cross_section_strip(series, t_range=(9.9, 10.1)))
    heights = velocity_height_series(default_case)
    ax = plots.velocity_height(time_average_by_height(heights)).axes[0]
    assert ax.get_xlabel() == "granular velocity (m/s)" and ax.get_ylabel() == "height z (mm)"
    assert saved(plots.velocity_height_image(heights))


def test_radial_plot_uses_r_over_d():
    profile = pytest.importorskip("xarray").Dataset(
        {"porosity": ("r", [0.5, 0.6]), "porosity_sem": ("r", [0.01, 0.02])},
        coords={"r": ("r", [0.000175, 0.000525])}, attrs={"particle_diameter": S.D_GRAIN})
    ax = plots.radial_profile(profile).axes[0]
    assert ax.get_xlabel() == "r/d"
    assert np.allclose(ax.get_lines()[0].get_xdata(), [0.125, 0.375])


def test_characteristic_curves_in_hpa_per_metre():
    table = pd.DataFrame({
        "gas.superficial_velocity": [0.5, 1.0, 0.5, 1.0], "feed.mass_flow_kg_h": [2.49, 2.49, 9.95, 9.95],
        "pressure_drop": [3000.0, 1000.0, 6000.0, 2500.0], "pressure_drop_sem": [50.0] * 4,
        "regime": ["bulk", "slug", "bulk", "slug"]})
    fig = plots.characteristic_curves(table)
    ax = fig.axes[0]
    assert ax.get_ylabel() == "pressure drop (hPa/m)"
    assert ax.get_xlabel() == "superficial gas velocity $v_s$ (m/s)"
    texts = legend_texts(ax)
    assert texts[0] == ["2.49 kg/h", "9.95 kg/h"]  # the groups, titled in words
    assert texts[1] == ["bulk (tube filled)", "slug conveying"]  # every marker explained
    assert np.allclose(ax.get_lines()[0].get_ydata(), [30.0, 10.0])  # Pa/m -> hPa/m
    viscosity = pd.DataFrame({"gas.viscosity": [4.5e-5, 8.5e-5], "pressure_drop": [1200.0, 900.0],
                              "pressure_drop_sem": [10.0, 10.0]})
    ax = plots.characteristic_curves(viscosity, x="gas.viscosity", group=None).axes[0]
    assert ax.get_xlabel() == r"gas viscosity $\eta$ (cP)"
    assert np.allclose(ax.get_lines()[0].get_xdata(), [0.045, 0.085])  # Pa s -> cP
    assert isinstance(fig, Figure) and saved(fig)


def test_bulk_points_with_an_unresolved_dashpot_are_crossed():
    table = pd.DataFrame({
        "gas.superficial_velocity": [0.15, 0.25, 1.0, 2.0], "pressure_drop": [9000.0, 7000.0, 1000.0, 800.0],
        "pressure_drop_sem": [50.0] * 4, "regime": ["bulk", "bulk", "slug", "slug"],
        # as read back from a curve CSV; the slug point at 2 m/s is unresolved too but not a packed bed,
        # the bulk point at 0.25 m/s is resolved
        "dashpot_resolved": ["False", "True", "False", "False"]})
    ax = plots.characteristic_curves(table, group=None).axes[0]
    crosses = [line for line in ax.get_lines() if line.get_marker() == "x" and len(line.get_xdata())]
    assert len(crosses) == 1 and np.allclose(crosses[0].get_xydata(), [[0.15, 90.0]])
    assert plots.UNRESOLVED_BULK in legend_texts(ax)[-1]
    table["dashpot_resolved"] = [True, True, None, None]  # resolved, or unknown: no cross, no entry
    ax = plots.characteristic_curves(table, group=None).axes[0]
    assert not [line for line in ax.get_lines() if line.get_marker() == "x" and len(line.get_xdata())]
    assert plots.UNRESOLVED_BULK not in legend_texts(ax)[-1]


def legend_texts(ax):
    """Texts of every legend of the axes, in the order drawn."""
    from matplotlib.legend import Legend
    return [[t.get_text() for t in c.get_texts()] for c in ax.get_children() if isinstance(c, Legend)]


def test_blocked_points_are_drawn_apart_and_explained():
    table = pd.DataFrame({
        "gas.superficial_velocity": [0.3, 0.5, 1.0, 2.0], "pressure_drop": [9000.0, 7000.0, 1000.0, 800.0],
        "pressure_drop_sem": [50.0] * 4, "regime": ["blocked", "sticking plugs", "plug", "dilute"]})
    ax = plots.characteristic_curves(table, group=None, title="Vertical tube").axes[0]
    curve = ax.get_lines()[0]  # the joined curve leaves the blocked point out
    assert np.allclose(curve.get_xdata(), [0.5, 1.0, 2.0])
    crosses = [line for line in ax.get_lines() if line.get_marker() == "X" and len(line.get_xdata())]
    assert len(crosses) == 1 and np.allclose(crosses[0].get_xydata(), [[0.3, 90.0]])
    texts = legend_texts(ax)[-1]
    assert texts[:3] == ["plug conveying", "sticking plugs", "dilute (no plugs)"]
    assert texts[3].startswith("blocked") and ax.get_title() == "Vertical tube"


def test_undrawn_axes_names_empty_panels():
    fig = Figure()
    full, empty = fig.subplots(1, 2)
    full.plot([0, 1], [1, 2])
    empty.plot([], [], "o", label="proxy")  # a legend proxy is no data
    empty.set_title("nothing here")
    assert plots.undrawn_axes(fig) == ["nothing here"]
    nan = Figure().add_subplot()
    nan.plot([0, 1], [np.nan, np.nan])
    assert plots.undrawn_axes(nan.figure) == ["panel 1"]
    scatter = Figure().add_subplot(projection="3d")
    scatter.scatter([], [], [])
    assert plots.undrawn_axes(scatter.figure) == ["panel 1"]
    scatter.scatter([0.0], [0.0], [0.0])
    assert plots.undrawn_axes(scatter.figure) == []


def test_plots_draw_into_a_given_axes(default_slugs):
    fig = Figure()
    ax = fig.add_subplot()
    assert plots.slug_rate(slug_statistics(default_slugs), ax=ax) is fig


def test_calibration_figures_in_the_papers_units():
    keys = ("gas.viscosity", "particles.friction")
    first, second = np.linspace(4.5e-5, 8.5e-5, 11), np.linspace(0.2, 0.8, 11)
    a, b = np.meshgrid((first - 6e-5) / 2e-5, (second - 0.4) / 0.3)
    chi2 = a ** 2 + b ** 2
    design = pd.DataFrame({keys[0]: [4.5e-5, 6.5e-5, 8.5e-5], keys[1]: [0.2, 0.5, 0.8]})
    fig = plots.calibration_misfit(first, second, chi2, keys, design, np.array([6e-5, 0.4]), np.array([1e-5, 0.1]))
    ax = fig.axes[0]
    assert ax.get_xlabel() == r"gas viscosity $\eta$ (cP)" and "Coulomb" in ax.get_ylabel()
    assert ax.get_xlim() == pytest.approx((0.045, 0.085))  # cP, not Pa s: the bounds
    assert plots.undrawn_axes(fig) == []
    table = pd.DataFrame({"label": ["B", "B"], "quantity": ["pressure_drop", "plug_length"],
                          "value": [4500.0, 0.05], "error": [200.0, 0.02],
                          "fitted": [4400.0, 0.04], "fitted_std": [100.0, 0.01]})
    fig = plots.measured_against_fitted(table)
    assert [ax.get_ylabel() for ax in fig.axes] == ["pressure drop (hPa/m)", "plug length (cm)"]
    assert fig.axes[0].get_lines()[0].get_ydata()[0] == pytest.approx(45.0)  # hPa/m
    assert plots.undrawn_axes(fig) == []


def test_a_predicted_point_without_its_own_error_is_drawn_open_and_named_in_the_legend():
    table = pd.DataFrame({"label": ["A", "C"], "quantity": ["pressure_drop", "pressure_drop"],
                          "value": [4200.0, 4450.0], "error": [200.0, 200.0], "predicted": [4010.0, 4270.0],
                          "predicted_std": [430.0, 200.0], "own_error_known": [False, True]})
    ax = plots.measured_against_fitted(table, what="predicted").axes[0]
    markers = {bars.get_label(): bars.lines[0] for bars in ax.containers}
    closed, open_ = markers["predicted model ± 1 s.d."], markers["predicted model ± the fit's part only"]
    assert closed.get_ydata() == pytest.approx([42.7]) and open_.get_ydata() == pytest.approx([40.1])
    assert open_.get_markerfacecolor() == "none" and closed.get_markerfacecolor() != "none"
    labels = [t.get_text() for t in ax.figure.legends[0].get_texts()]
    assert labels == ["measured ± 1 s.d.", "predicted model ± 1 s.d.", "predicted model ± the fit's part only"]

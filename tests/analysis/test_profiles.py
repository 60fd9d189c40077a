"""Averaged slug profiles at mid-tube: selection band, alignment on the centre of mass, averages."""

import math

import numpy as np
import pytest
import xarray as xr

from analysis import detect, resting_layer_stress, select_slugs, slug_profiles
from analysis.profiles import FAR_OUTSIDE, PAPER_BANDS, temperature_check

from . import synthetic as S


@pytest.fixture(scope="module")
def two_lengths():
    """Slugs of 0.03 m and 0.07 m alternating, at 0.3 m/s: mean length 0.05 m at mid-tube."""
    slugs = [S.moving(0.0, 0.3, 0.03 if k % 2 else 0.07, t_ref=k * 0.75 - 2.0) for k in range(16)]
    ds = S.build(slugs, 10.0)
    return ds, detect(ds)


def test_selection_band_around_the_mean(two_lengths):
    _, slugs = two_lengths
    # papers' horizontal band: 0.05 +- 0.03 m, u +- 0.1 m/s; here on the core length
    everything = select_slugs(slugs, length_column="length")
    assert everything.attrs["length_center"] == pytest.approx(0.05, abs=0.003)
    assert len(everything) == everything.attrs["n_passing"] > 10
    assert len(select_slugs(slugs, length_band=0.015, length_column="length")) == 0  # both 0.02 off
    short = select_slugs(slugs, length_center=0.03, length_band=0.005, length_column="length")
    assert len(short) > 0 and np.allclose(short["length"], 0.03, atol=1e-9)
    assert len(select_slugs(slugs, velocity_center=0.5, velocity_band=0.1)) == 0


def test_selection_uses_the_length_with_the_ends_by_default(two_lengths):
    _, slugs = two_lengths
    sel = select_slugs(slugs)
    assert sel.attrs["length_column"] == "length_total"
    # each end adds the ramp from porosity 0.6 to 0.9 (14 mm) and at most 1.5 slices (see test_slugs)
    ends = 2 * S.RAMP * (S.PHI_GAP - S.THRESHOLD) / (S.PHI_GAP - S.PHI_SLUG)
    assert 0.05 + ends <= sel.attrs["length_center"] <= 0.05 + ends + 3 * S.DX


def test_temperature_check_flags_a_peak_far_above_the_papers_axis():
    prof = xr.Dataset({"granular_temperature": ("dx_d", np.array([0.0, 3e-9, 1e-9]))})
    ok = temperature_check(prof, vertical=True)
    assert ok["peak"] == 3e-9 and ok["axis_top"] == 3.5e-9 and not ok["far_outside"]
    hot = temperature_check(prof * (FAR_OUTSIDE * 3.5e-9 / 3e-9 * 1.01), vertical=True)
    assert hot["far_outside"] and hot["ratio"] == pytest.approx(FAR_OUTSIDE * 1.01)
    assert not temperature_check(prof * 1e3, vertical=False)["far_outside"]  # no axis known


def test_vertical_tubes_use_the_vertical_paper_band():
    ds = S.build(S.periodic(0.75, 0.16, 0.024, 6.0), 6.0, inclination_deg=90.0)
    sel = select_slugs(detect(ds))
    assert sel.attrs["length_band"] == PAPER_BANDS["vertical"]["length"] == 0.01
    assert sel.attrs["velocity_band"] == 0.02


def test_profile_of_identical_slugs_is_their_shape(default_case, default_slugs):
    sel = select_slugs(default_slugs)
    prof = slug_profiles(default_case, sel)
    d = S.D_GRAIN
    assert prof.attrs["n_selected"] == len(sel) > 20
    centre = prof.sel(dx_d=0.0, method="nearest")
    # The 5 cm slugs have a flat core 0.036 m wide around the centre, where interpolation is exact.
    assert centre["porosity"].item() == pytest.approx(S.PHI_SLUG, abs=1e-9)
    assert centre["drag_force"].item() == pytest.approx(S.DRAG_PEAK, rel=1e-9)
    assert centre["particle_force"].item() == pytest.approx(-S.DRAG_PEAK, rel=1e-9)
    assert centre["wall_stress"].item() == pytest.approx(S.WALL_PEAK, rel=1e-9)
    assert centre["porosity_sem"].item() == pytest.approx(0.0, abs=1e-9)  # identical slugs
    far = prof.sel(dx_d=-40.0, method="nearest")
    assert far["porosity"].item() == pytest.approx(S.PHI_GAP, abs=1e-9)
    # The mean profile crosses 0.6 at +-L/2 from the centre of mass: the crossings are on the
    # linear ramps, and the centres of mass err by < 1e-5 m (0.007 d); allow 0.02 d.
    x, phi = prof["dx_d"].values, prof["porosity"].values
    front = np.interp(0.6, phi[(x > 0) & (x < 30)], x[(x > 0) & (x < 30)])
    back = np.interp(0.6, phi[(x < 0) & (x > -30)][::-1], x[(x < 0) & (x > -30)][::-1])
    assert front == pytest.approx(0.025 / d, abs=0.02)
    assert back == pytest.approx(-0.025 / d, abs=0.02)


def test_profile_mean_and_standard_error_match_numpy(default_case, default_slugs):
    sel = select_slugs(default_slugs).iloc[:3]
    ds = default_case.copy(deep=True)
    frames = sel["frame"].to_numpy()
    offsets = np.array([0.0, 1e-6, 4e-6])  # N, added to the drag force of each slug's frame
    ds["drag_force"].values[frames, :] += offsets[:, None]
    prof = slug_profiles(ds, sel, fields=["drag_force"])
    centre = prof.sel(dx_d=0.0, method="nearest")
    values = S.DRAG_PEAK + offsets
    assert centre["drag_force"].item() == pytest.approx(np.mean(values), rel=1e-12)
    assert centre["drag_force_sem"].item() == pytest.approx(np.std(values, ddof=1) / math.sqrt(3),
                                                            rel=1e-9)
    assert centre["n_slugs"].item() == 3


def test_resting_layer_stress_is_the_weight_per_wall_area():
    ds = S.build([], 0.02)
    # weight of a slice over its wall area: rho_s (1 - phi) A dx g / (pi D dx)
    expected = S.RHO * (1 - 0.9) * S.A_TUBE * 9.81 / (math.pi * S.D_TUBE)
    assert resting_layer_stress(0.9, ds) == pytest.approx(expected, rel=1e-12)
    vertical = S.build([], 0.02, inclination_deg=90.0)
    assert resting_layer_stress(0.9, vertical) == pytest.approx(0.0, abs=1e-12)

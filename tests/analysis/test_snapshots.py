"""Cross-section and radial binning of grain snapshots: grain volume is conserved."""

import math

import numpy as np
import pandas as pd
import pytest

from analysis import (averaged_radial_profile, cross_section, cross_section_series, detect,
                      radial_profile, select_slugs, snapshot, velocity_by_height,
                      velocity_height_series)
from analysis.snapshots import (ball_points, slug_in_snapshots, snapshot, snapshot_times,
                                time_average_by_height)

from . import synthetic as S

R = S.D_TUBE / 2
D = S.D_GRAIN
V = S.V_GRAIN


def test_ball_points_are_symmetric():
    p = ball_points()
    assert np.allclose(p.mean(axis=0), 0.0, atol=1e-15)  # pieces keep each grain's centre
    assert np.all(np.linalg.norm(p, axis=1) <= 1.0)


def test_cross_section_conserves_grain_volume():
    rng = np.random.default_rng(3)
    pos, _ = S.packed_grains(rng, 200, (0.26 - D / 2, 0.26 + D / 2))
    section = cross_section(pos, 0.26, R, D, thickness=3 * D)  # every grain fully in the slab
    # each grain is split into pieces of equal volume: only summation rounding remains
    assert section["grain_volume"].sum().item() == pytest.approx(200 * V, rel=1e-12)


def test_cross_section_cuts_grains_at_the_slab_faces():
    # a grain centred on a slab face has exactly half its pieces inside (symmetric lattice)
    pos = np.array([[0.26 + D / 2, 0.0, 0.0]])
    section = cross_section(pos, 0.26, R, D, thickness=D)
    assert section["grain_volume"].sum().item() == pytest.approx(V / 2, rel=1e-12)


def test_cross_section_of_a_resting_layer_is_empty_above_it():
    rng = np.random.default_rng(4)
    pos, _ = S.packed_grains(rng, 400, (0.255, 0.265))
    pos = pos[pos[:, 2] <= -D / 2]  # grains wholly below the axis
    section = cross_section(pos, 0.26, R, D, pixels=40)
    upper = section["volume_fraction"].where(section["z"] > 0)
    assert np.nanmax(upper.values) == 0.0
    assert np.nanmax(section["volume_fraction"].values) > 0.0
    # the pixels' volume inside the tube adds up to the slab volume (16 x 16 sub-samples per
    # boundary pixel: the measured error is 1e-5; allow 1e-3)
    assert section["pixel_volume"].sum().item() == pytest.approx(math.pi * R**2 * D, rel=1e-3)


def test_radial_profile_conserves_volume_and_finds_the_layers():
    # a string of grains on the axis moving at 0.3 m/s, a ring touching the wall at 0.1 m/s
    angles = np.arange(8) * 2 * np.pi / 8
    wall = np.column_stack([np.full(8, 0.26), 2 * D * np.cos(angles), 2 * D * np.sin(angles)])
    axis = np.array([[0.26, 0.0, 0.0]])
    pos = np.vstack([axis, wall])
    vel = np.zeros_like(pos)
    vel[0, 0], vel[1:, 0] = 0.3, 0.1
    prof = radial_profile(pos, vel, 0.26, R, D)  # rings 0.25 d wide, 1.5 d high
    assert prof["grain_volume"].sum().item() == pytest.approx(9 * V, rel=1e-12)
    assert prof["ring_volume"].sum().item() == pytest.approx(math.pi * R**2 * 1.5 * D, rel=1e-12)
    r = prof["r"].values / D
    assert len(r) == 10  # R = 2.5 d
    assert np.allclose(prof["velocity"].values[r < 0.5], 0.3)
    assert np.allclose(prof["velocity"].values[r > 1.5], 0.1)
    gap = (r > 0.5) & (r < 1.5)
    assert np.all(np.isnan(prof["velocity"].values[gap]))
    assert np.allclose(prof["porosity"].values[gap], 1.0)


def test_grains_pressed_into_the_wall_count_in_the_outer_ring():
    pos = np.array([[0.26, R - D / 2 + 0.05 * D, 0.0]])  # 5 % overlap with the wall
    prof = radial_profile(pos, np.zeros((1, 3)), 0.26, R, D)
    assert prof["grain_volume"].sum().item() == pytest.approx(V, rel=1e-12)


def test_velocity_by_height_separates_layers():
    # bottom layer resting at z = -2 d, a layer at z = 0 moving at 0.5 m/s
    y = np.linspace(-1.0, 1.0, 3) * D
    bottom = np.column_stack([np.full(3, 0.26), y, np.full(3, -2 * D)])
    middle = np.column_stack([np.full(3, 0.26), y, np.zeros(3)])
    pos = np.vstack([bottom, middle])
    vel = np.zeros_like(pos)
    vel[3:, 0] = 0.5
    prof = velocity_by_height(pos, vel, (0.25, 0.27), R, D)
    z = prof["height"].values / D
    assert prof["grain_volume"].sum().item() == pytest.approx(6 * V, rel=1e-12)
    assert np.allclose(prof["velocity"].values[(z > -2.5) & (z < -1.5)], 0.0)
    assert np.allclose(prof["velocity"].values[(z > -0.5) & (z < 0.5)], 0.5)
    assert np.all(np.isnan(prof["velocity"].values[(z > -1.5) & (z < -0.5)]))


def test_snapshot_series_read_the_ragged_array(default_case):
    t, pos, vel = snapshot(default_case, 3)
    assert t == pytest.approx(9.93) and pos.shape == (600, 3) and np.allclose(vel[:, 0], 0.3)
    series = cross_section_series(default_case)
    assert series.sizes["snapshot_time"] == 50
    heights = velocity_height_series(default_case)
    mean = time_average_by_height(heights)
    assert np.nanmax(np.abs(mean["velocity"].values - 0.3)) < 1e-12


def test_averaged_radial_profile_is_centred_on_each_slug():
    ds = S.build(S.periodic(0.75, 0.3, 0.05, 4.0), 4.0)
    slugs = detect(ds)
    sel = select_slugs(slugs)
    shots = []
    for row in sel.itertuples():  # one grain on the axis at the slug's centre of mass, one far off
        pos = np.array([[row.x_center, 0.0, 0.0], [row.x_center + 0.03, 0.0, 0.0]])
        vel = np.array([[0.3, 0, 0], [9.9, 0, 0]])
        shots.append((row.time, pos, vel))
    shots.append((0.005, np.array([[0.26, 0.0, 0.0]]), np.zeros((1, 3))))  # not near a passage
    ds = S.add_snapshots(ds, shots)
    prof = averaged_radial_profile(ds, sel, slugs)
    assert list(prof.attrs["slug_ids"]) == sel["slug_id"].tolist()
    # The 1.5 d window centred on the centre of mass holds the whole centred grain (it would lose
    # volume if the window were off by more than 0.25 d) and not the one 0.03 m away.
    assert prof["grain_volume"].sum().item() == pytest.approx(len(sel) * V, rel=1e-12)
    r = prof["r"].values / D
    assert np.allclose(prof["velocity"].values[r < 0.5], 0.3)
    assert np.allclose(prof["porosity"].values[r > 0.5], 1.0)
    assert np.allclose(prof["porosity_sem"].values, 0.0, atol=1e-12)  # identical slugs


def test_the_slug_to_picture_lies_in_a_snapshot(default_case, default_slugs):
    # H2 must show a slug: the synthetic snapshots (9.9-10.4 s, grains over 0.2425-0.2825 m) see
    # one 5 cm slug pass mid-tube at 9.95 s; slugs elsewhere in the tube hold none of their grains
    k, row = slug_in_snapshots(default_case, default_slugs)
    t = snapshot_times(default_case)[k]
    assert 9.9 <= t <= 10.4 and abs(row["time"] - t) < 0.006
    assert row["x_start_total"] < 0.2825 and row["x_end_total"] > 0.2425
    _, pos, _ = snapshot(default_case, k)
    inside = (pos[:, 0] >= row["x_start_total"]) & (pos[:, 0] <= row["x_end_total"])
    assert inside.sum() > 300  # most of the 600 grains
    # a preferred slug that never meets a snapshot does not win over one that does
    elsewhere = default_slugs[default_slugs["time"] < 5.0]["slug_id"].unique()
    assert slug_in_snapshots(default_case, default_slugs, prefer=elsewhere)[1]["slug_id"] == row["slug_id"]
    # and no slug in any snapshot: nothing to picture
    early = default_slugs[default_slugs["time"] < 5.0]
    early.attrs.update(default_slugs.attrs)
    assert slug_in_snapshots(default_case, early) is None


def test_a_single_snapshot_pictures_the_slug_in_it():
    # one snapshot used to be matched to index -1, whose grains are the empty range [n:0]
    rng = np.random.default_rng(0)
    pos, vel = S.packed_grains(rng, 50, (0.04, 0.06))
    ds = S.build([], duration=1.0, snapshots=[(0.5, pos, vel)])
    slugs = pd.DataFrame([{"slug_id": 7, "time": 0.5, "x_center": 0.05, "x_start_total": 0.03,
                           "x_end_total": 0.07, "n_particles": 50}])
    k, row = slug_in_snapshots(ds, slugs)
    assert k == 0 and row["slug_id"] == 7

"""Slug statistics against position: the numbers must match numpy on the same samples."""

import numpy as np
import pytest

from analysis import describe, detect, passages, slug_statistics
from analysis.statistics import crossings, default_positions, time_weighted

from . import synthetic as S

RNG = np.random.default_rng(7)
LENGTHS = RNG.uniform(0.02, 0.08, size=40)  # m, one per slug


@pytest.fixture(scope="module")
def random_lengths():
    """Slugs of random length at 0.3 m/s, one every 0.75 s (0.225 m apart: they never touch)."""
    slugs = [S.moving(0.0, 0.3, length, t_ref=k * 0.75 - 2.0) for k, length in enumerate(LENGTHS)]
    return detect(S.build(slugs, 22.5))


def test_describe_matches_numpy():
    v = RNG.normal(size=37)
    v[3] = np.nan  # NaNs are dropped
    d = describe(v)
    f = v[np.isfinite(v)]
    assert d["n"] == 36
    assert d["mean"] == np.mean(f)
    assert d["sem"] == np.std(f, ddof=1) / np.sqrt(36)
    assert (d["q25"], d["median"], d["q75"]) == tuple(np.percentile(f, [25, 50, 75]))


def test_statistics_match_numpy_on_the_passing_slugs(random_lengths):
    positions = [0.2, 0.3]
    stats = slug_statistics(random_lengths, positions).set_index("x")
    sample = passages(random_lengths, positions)
    for p in positions:
        lengths = sample[sample["position"] == p]["length"].to_numpy()
        row = stats.loc[p]
        assert row["n_slugs"] == len(lengths)
        assert row["length_mean"] == pytest.approx(np.mean(lengths), rel=1e-12)
        assert row["length_sem"] == pytest.approx(np.std(lengths, ddof=1) / np.sqrt(len(lengths)),
                                                  rel=1e-12)
        q25, q75 = np.percentile(lengths, [25, 75])
        assert (row["length_q25"], row["length_q75"]) == pytest.approx((q25, q75), rel=1e-12)


def test_each_slug_passing_is_sampled_once_with_its_own_length(random_lengths):
    sample = passages(random_lengths, [0.3])
    assert sample["slug_id"].is_unique
    # The slugs passing 0.3 m within the run: centre (front - L/2) reaches 0.3 m at
    # t = k 0.75 - 2 + (0.3 + L/2) / 0.3, for 0 < t <= 22.49 s.
    t_pass = np.arange(len(LENGTHS)) * 0.75 - 2.0 + (0.3 + LENGTHS / 2) / 0.3
    expected = np.sort(LENGTHS[(t_pass > 0) & (t_pass <= 22.49)])
    assert np.allclose(np.sort(sample["length"]), expected, atol=1e-9)  # exact lengths, see test_slugs


def test_rate_counts_net_passages_per_second(random_lengths):
    stats = slug_statistics(random_lengths, [0.3])
    n_forward = len(passages(random_lengths, [0.3]))
    assert stats["rate"].item() == pytest.approx(n_forward / 22.49, rel=1e-12)
    assert stats.attrs["duration"] == pytest.approx(22.49)


def test_a_slug_rocking_across_a_position_counts_once():
    # centre of mass 0.26 - 0.01 cos(5 pi t) m: starts below 0.26 m, ends above it, and crosses
    # it upward at t = 0.1, 0.5, 0.9 s and downward at 0.3, 0.7 s: one net passage
    rocking = S.Slug(front=lambda t: 0.285 - 0.01 * np.cos(2 * np.pi * 2.5 * t),
                     length=lambda t: 0.05 + 0 * t, speed=lambda t: 0 * t)
    slugs = detect(S.build([rocking], 1.0))
    cross = crossings(slugs, [0.26])
    assert cross["direction"].tolist() == [1, -1, 1, -1, 1]
    assert np.allclose(cross["time"], [0.1, 0.3, 0.5, 0.7, 0.9], atol=0.0101)
    stats = slug_statistics(slugs, [0.26])
    assert stats["rate"].item() == pytest.approx(1 / 0.99)
    assert stats["n_slugs"].item() == 1


def test_window_restricts_the_rate_and_the_samples(random_lengths):
    late = slug_statistics(random_lengths, [0.3], t_start=10.0)
    assert late.attrs["duration"] == pytest.approx(12.49)
    sample = passages(random_lengths, [0.3], t_start=10.0)
    assert (sample["time"] > 10.0).all()
    assert late["n_slugs"].item() == len(sample)


def test_default_positions_are_bin_centres():
    p = default_positions(0.525)
    assert len(p) == 30 and p[0] == pytest.approx(0.00875) and p[-1] == pytest.approx(0.51625)


def test_per_passage_and_time_weighted_means_of_slow_and_fast_slugs():
    # one slug at a time, alternately at 0.2 and 0.4 m/s: each passage counts once in the papers'
    # mean (0.3 m/s), while a slow slug spends twice the frames near x in the time-weighted one:
    # (2 x 0.2 + 0.4) / 3 = 0.267 m/s
    slugs = [S.moving(0.0, 0.2 if k % 2 == 0 else 0.4, 0.05, t0=3.5 * k, t1=3.5 * (k + 1))
             for k in range(6)]
    table = detect(S.build(slugs, 21.0))
    x = S.L_TUBE / 2
    row = slug_statistics(table, [x]).iloc[0]
    assert row["n_slugs"] == 6
    assert row["max_velocity_mean"] == pytest.approx(0.3, abs=1e-12)
    # frames within half a bin (8.75 mm) of x: 8.75 per slow and 4.375 per fast slug, each count
    # rounded to a whole frame (+- 1): the mean moves by at most ~0.2 / 13 = 0.015 m/s
    assert row["max_velocity_time_mean"] == pytest.approx(0.8 / 3, abs=0.015)
    w = time_weighted(table, x, "max_velocity", S.L_TUBE / 60)
    assert w["n_slugs"] == 6 and w["mean"] == row["max_velocity_time_mean"]
    assert w["sem"] > 0


def test_the_slug_shown_passes_mid_tube_within_the_snapshots(random_lengths):
    from analysis.statistics import choose_slug, covering_window
    slugs = random_lengths
    x0, window = S.L_TUBE / 2, 0.2
    times = np.arange(10.0, 14.0, 0.01)  # snapshots over 10-14 s
    passing = passages(slugs, [x0])
    inside = passing[(passing["time"] >= 10.1) & (passing["time"] <= 13.9)]
    # with no selection: the passing slug with the most grains
    slug_id, t = choose_slug(slugs, slugs[:0], x0, times, window)
    biggest = inside.sort_values("n_particles", ascending=False).iloc[0]
    assert (slug_id, t) == (int(biggest["slug_id"]), float(biggest["time"]))
    # a selected slug passing there wins, even a smaller one
    smallest = inside.sort_values("n_particles").iloc[0]
    chosen = choose_slug(slugs, smallest.to_frame().T[["slug_id"]], x0, times, window)
    assert chosen == (int(smallest["slug_id"]), float(smallest["time"]))
    # it covers x0 for about (length + ramps) / 0.3 m/s around its passage
    lo, hi = covering_window(slugs, chosen[0], x0)
    assert lo <= chosen[1] <= hi and 0.0 < hi - lo < (0.08 + 2 * S.RAMP) / 0.3
    # no slug passes: the middle of the snapshots, no covering window
    slug_id, t = choose_slug(slugs[:0], slugs[:0], x0, times, window)
    assert slug_id == -1 and t == pytest.approx((times[0] + times[-1]) / 2, abs=1e-12)
    assert covering_window(slugs, -1, x0) is None

"""Run lengths: the window a quantity needs for a requested standard error (analysis.runlength,
timeseries.required_length and first_reached)."""

import math

import numpy as np
import pytest

from analysis.runlength import Precision, required_windows
from analysis.timeseries import first_reached, mean_error, required_length

from . import synthetic
from .test_timeseries import ar1, exact_variance_of_mean


def test_the_length_asked_of_an_ar1_series_gives_its_mean_the_error_asked():
    # AR(1), a = 0.9: var = 1 / (1 - a^2), tau = 19 samples; an error 0.2 needs
    # var tau / 0.2^2 = 2500 samples. Each estimate comes from a 4000-sample series (210 tau)
    # and scatters by 24 % (twice the error's); the mean over 200 replicas is known to 2 %,
    # and Geyer's +0 to +2 % in the error is +0 to +4 % here: 0.08 leaves room for both.
    # Without tau in the estimate it would come out 19 times short, with the error instead of
    # its square 12 times.
    a, target = 0.9, 0.2
    exact = 1 / (1 - a * a) * (1 + a) / (1 - a) / target**2
    estimates = np.array([required_length(row, target) for row in ar1(a, 4000, 200, seed=3)])
    assert not np.isnan(estimates).any()
    assert estimates.mean() == pytest.approx(exact, rel=0.08)
    # run that long, the means of fresh replicas scatter by the error asked: analytically (finite
    # n) and measured over 500 replicas (their SD known to 3.2 %, three of those)
    n = int(round(estimates.mean()))
    assert math.sqrt(exact_variance_of_mean(a, n)) == pytest.approx(target, rel=0.05)
    assert ar1(a, n, 500, seed=4).mean(axis=1).std(ddof=1) == pytest.approx(target, rel=0.12)


def test_the_length_is_in_seconds_and_never_below_the_correlation_times_the_estimator_needs():
    x = ar1(0.5, 2000, 1, seed=5)[0]  # tau = 3 samples
    est = mean_error(x, 0.01)
    # an error far above the series' own needs no more samples than 50 tau to be known at all
    assert required_length(x, 10.0, interval=0.01) == pytest.approx(50 * est.tau * 0.01)
    assert required_length(x, 10.0, interval=0.01, min_correlation_times=20) == pytest.approx(20 * est.tau * 0.01)
    # a tighter error: var tau / target^2 samples, each 0.01 s
    assert required_length(x, 0.01, interval=0.01) == pytest.approx(est.error**2 * est.n / 0.01**2 * 0.01)


def test_a_series_too_short_to_know_its_correlation_time_gives_no_length():
    short = ar1(0.99, 300, 1, seed=6)[0]  # 1.5 tau
    assert math.isnan(required_length(short, 0.1))
    with pytest.raises(ValueError, match="must be > 0"):
        required_length(short, 0.0)
    with pytest.raises(ValueError, match="must be > 0"):
        Precision(0.0)


def test_the_growing_window_first_meets_the_error_near_the_length_asked():
    # white noise of SD 1: an error of 0.1 needs 100 samples; the first time the growing window's
    # estimate meets it scatters around that (measured over 200 replicas: median 100, 50 to 212),
    # never before the 50 correlation times; it is NaN when the series is too short
    reached = np.array([first_reached(row, 0.1) for row in ar1(0.0, 400, 200, seed=5)])
    assert not np.isnan(reached).any()
    assert 85 <= np.median(reached) <= 115
    assert reached.min() >= 50
    assert math.isnan(first_reached(ar1(0.0, 60, 1, seed=6)[0], 0.1))
    # tried every 10 samples, it reports a multiple of 10 (or the whole series)
    assert first_reached(ar1(0.0, 400, 1, seed=7)[0], 0.1, every=10) % 10 == 0


def slugs_of_three_speeds(duration):
    """5 cm slugs entering every 0.75 s at 0.28, 0.30, 0.32 m/s in turn (none catches the one ahead
    within the tube): one velocity per slug passing mid-tube, SD sqrt(2/3) 0.02 m/s."""
    speeds = (0.28, 0.30, 0.32)
    return [synthetic.moving(0.0, speeds[k % 3], 0.05, t_ref=k * 0.75)
            for k in range(-4, int(duration / 0.75) + 2)]


@pytest.fixture(scope="module")
def varied_case():
    # pressure drop 1000 Pa/m after 6 s, AR(1) noise of 10 %, lag-one correlation 0.8 (tau = 9
    # frames); 40 s: a window of 34 s after the transient (380 tau)
    return synthetic.build(slugs_of_three_speeds(40.0), duration=40.0)


def test_windows_of_a_case_per_quantity(varied_case):
    table = required_windows(varied_case, {"pressure_drop": 5.0, "slug_velocity": 0.002,
                                           "max_velocity": Precision(0.01, relative=True)},
                             t_start=6.0).set_index("quantity")
    assert list(table.index) == ["pressure_drop", "slug_velocity", "max_velocity"]
    dp = table.loc["pressure_drop"]
    # per metre: var tau / target^2 = 100^2 x 9 / 5^2 = 3600 frames, 36 s (per tube length
    # instead: 0.525^-2 = 3.6 times more); one 380-tau series estimates it to about 20 %
    assert dp["mean"] == pytest.approx(1000.0, rel=0.03)
    assert dp["window_needed"] == pytest.approx(36.0, rel=0.25)
    assert dp["window_run"] == pytest.approx(34.0, abs=0.02) and dp["t_start"] == pytest.approx(6.0)
    assert dp["estimator"] == "series" and dp["target"] == 5.0
    # reached within the window when the window is long enough for it
    assert math.isnan(dp["reached"]) == (dp["sem"] > 5.0)
    # one slug every 0.75 s, velocities of SD sqrt(2/3) 0.02 m/s: (0.0163 / 0.002)^2 slugs
    velocity = table.loc["slug_velocity"]
    assert velocity["estimator"] == "passages" and velocity["n"] == pytest.approx(34 / 0.75, abs=1.5)
    assert velocity["window_needed"] == pytest.approx((math.sqrt(2 / 3) * 0.02 / 0.002) ** 2 * 0.75, rel=0.1)
    assert math.isnan(velocity["reached"])
    # the synthetic grains move with their slug: the same spread; relative: 1 % of the mean 0.3 m/s
    peak = table.loc["max_velocity"]
    assert peak["target"] == pytest.approx(0.01 * peak["mean"])
    assert peak["mean"] == pytest.approx(0.30, abs=0.005)


def test_unknown_quantities_are_refused(varied_case):
    with pytest.raises(ValueError, match="no run length for slug_length"):
        required_windows(varied_case, {"slug_length": 0.001})

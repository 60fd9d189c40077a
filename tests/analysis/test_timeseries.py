"""The one estimator of means and errors of correlated series (analysis.timeseries)."""

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from analysis.timeseries import MIN_CORRELATION_TIMES, mean_error, mser_start

REPLICAS = 500


def ar1(a: float, n: int, replicas: int, seed: int) -> np.ndarray:
    """Stationary AR(1) series x_t = a x_{t-1} + e_t, e ~ N(0, 1): one row per replica."""
    e = np.random.default_rng(seed).normal(size=(replicas, n))
    e[:, 0] /= math.sqrt(1 - a * a)  # start in the stationary distribution
    return lfilter([1.0], [1.0, -a], e, axis=1)


def exact_variance_of_mean(a: float, n: int) -> float:
    """var(mean of n samples) of the stationary AR(1) above, finite n."""
    return (1 / (1 - a * a) / n) * ((1 + a) / (1 - a) - 2 * a * (1 - a**n) / (n * (1 - a) ** 2))


@pytest.mark.parametrize("a", [0.0, 0.9, 0.99])
def test_error_matches_the_spread_of_replica_means_of_ar1(a):
    tau = (1 + a) / (1 - a)
    n = max(int(200 * tau), 2000)  # 200 correlation times (white noise: 2000 samples)
    x = ar1(a, n, REPLICAS, seed=7)
    results = [mean_error(row) for row in x]
    assert all(r.converged for r in results)  # at 100 tau 0.2-0.6 % come out past 2 tau (not converged)
    errors = np.array([r.error for r in results])
    means = x.mean(axis=1)
    exact = math.sqrt(exact_variance_of_mean(a, n))
    # The generator: the SD of 500 replica means has a relative error 1/sqrt(2 x 499) = 3.2 %;
    # 4 of those.
    assert means.std(ddof=1) == pytest.approx(exact, rel=0.13)
    # The estimator: each error comes from n / tau = 200 independent samples with a measured
    # scatter of 10 % (4 % for white noise), so the RMS over 500 replicas is known to 0.5 %;
    # Geyer's sequence adds a measured bias of 0 to +2 % in the error (seeds 7, 8). 0.05 leaves
    # 3 SD of the replica average beside the bias.
    rms = math.sqrt(np.mean(errors**2))
    assert rms == pytest.approx(exact, rel=0.05)
    # against the spread of the replica means: add 3 x the 3.2 % of the replica SD
    assert rms == pytest.approx(means.std(ddof=1), rel=0.12)
    # tau itself: measured 0 to +3.5 % in the mean over replicas
    assert np.mean([r.tau for r in results]) == pytest.approx(tau, rel=0.08)
    # coverage of mean +- 2 SE: 95.4 % for exact errors; measured 94.6-96.4 %, binomial SD over
    # 500 replicas 1 %
    coverage = np.mean(np.abs(means) <= 2 * errors)
    assert 0.92 <= coverage <= 0.98


@pytest.mark.parametrize("a", [0.9, 0.99])
def test_a_series_of_a_few_correlation_times_is_not_converged(a):
    tau = (1 + a) / (1 - a)
    x = ar1(a, int(3 * tau), REPLICAS, seed=11)
    results = [mean_error(row) for row in x]
    # the naive std / sqrt(n) would claim about 3 x too small an error; here almost every replica
    # is flagged (measured 0.4 % / 1.6 % not flagged), and a flagged one has no error at all
    flagged = [not r.converged for r in results]
    assert np.mean(flagged) >= 0.95
    assert all(math.isnan(r.error) for r, f in zip(results, flagged) if f)
    # and the estimated tau stays below the truth: a short series cannot show its own correlation
    assert np.median([r.tau for r in results]) < tau


def test_the_estimate_of_a_window_short_of_the_correlation_times_asked_is_finite_and_low():
    # 30 tau of AR(1) at a = 0.9, short of the 50 asked: measured 89-91 % of 500 replicas flagged,
    # and 92-97 % have an estimate (the others' own tau puts them below 20 tau); against the exact
    # error of the mean the estimates are low, RMS 0.93-0.94 of it (seeds 5-7: a short window
    # shows a low tau), an RMS known to about 1 %
    a, tau = 0.9, 19.0
    n = int(30 * tau)
    results = [mean_error(row) for row in ar1(a, n, REPLICAS, seed=5)]
    assert np.mean([not r.converged for r in results]) >= 0.85
    estimates = np.array([r.estimate for r in results])
    assert np.mean(np.isfinite(estimates)) >= 0.9
    ratio = math.sqrt(np.nanmean(estimates ** 2)) / math.sqrt(exact_variance_of_mean(a, n))
    assert 0.85 <= ratio <= 1.0
    # converged, the estimate is the error; below 20 correlation times there is none (at 5 tau,
    # measured 96-98 % of replicas without one: the rest show a tau four times too low)
    long = mean_error(ar1(a, int(200 * tau), 1, seed=5)[0])
    assert long.converged and long.estimate == long.error
    short = [mean_error(row) for row in ar1(a, int(5 * tau), REPLICAS, seed=5)]
    assert np.mean([math.isnan(r.estimate) for r in short]) >= 0.9


def test_units_of_tau_and_independent_samples():
    x = ar1(0.9, 20000, 1, seed=3)[0]
    r = mean_error(x, interval=0.01)
    assert r.converged and r.n == 20000
    assert r.tau_s == pytest.approx(r.tau * 0.01, rel=1e-12)
    assert r.n_independent == pytest.approx(20000 / r.tau, rel=1e-12)
    assert r.tau == pytest.approx(19.0, rel=0.25)  # one series of 1000 tau: ~10 % scatter measured
    assert r.error == pytest.approx(math.sqrt(np.var(x) * r.tau / x.size), rel=1e-12)


def test_white_noise_gives_the_naive_error():
    x = np.random.default_rng(5).normal(size=10000)
    r = mean_error(x)
    assert r.tau == pytest.approx(1.0, abs=0.1)  # scatter of 1 + 2 sum rho over a few lags: ~0.03
    assert r.error == pytest.approx(x.std() / 100, rel=0.05)


def test_degenerate_series():
    assert mean_error(np.full(50, 3.0)) == mean_error(np.full(50, 3.0))
    flat = mean_error(np.full(50, 3.0))
    assert flat.mean == 3.0 and flat.error == 0.0 and flat.converged
    assert not mean_error([]).converged and math.isnan(mean_error([]).mean)
    assert math.isnan(mean_error([1.0]).error)
    # fewer than MIN_CORRELATION_TIMES samples never converge, even if they look anticorrelated
    few = mean_error([1.0, -1.0] * int(MIN_CORRELATION_TIMES // 2 - 1))
    assert not few.converged and math.isnan(few.error)


def test_mser_keeps_a_stationary_series_whole():
    v = np.random.default_rng(1).normal(size=2000)
    assert mser_start(v) < 200  # measured 0-10 % on white noise; a rise would push it to > 25 %


def test_mser_finds_the_end_of_a_rise():
    t = np.arange(3000) * 0.01
    v = np.minimum(t / 6.0, 1.0) + ar1(0.95, t.size, 1, seed=2)[0] * 0.1 * math.sqrt(1 - 0.95**2)
    assert 4.0 <= t[mser_start(v)] <= 12.0  # the rise ends at 6 s (the 200-seed test in test_curves)

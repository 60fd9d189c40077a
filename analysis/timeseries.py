"""Mean and standard error of a correlated, evenly sampled time series; warm-up truncation.

The one estimator of the project: the steady stop of a run (engine.run.steady_window), the curves,
the validation and the captions all call `mean_error`. Numpy only, so that the engine can import
it (analysis never imports the engine).

The window is Geyer's initial monotone sequence (Geyer 1992, as in ArviZ's ess and Stan), in
numpy rather than a dependency: on AR(1) series of 100 tau (1000 replicas) it gave the variance
of the mean within 1 % with a 14-19 % scatter of the error, where Sokal's window c = 5 (emcee's
autocorr.integrated_time, which also raises instead of flagging a short series) came out 2-5 %
low with 20-23 % scatter; pymbar's statistical_inefficiency would add a dependency for a sum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MIN_CORRELATION_TIMES = 50.0  # fewer tau: no error (not converged); at 20 the flagged errors were 18 % low
# fewer tau: no estimate either; at 20 tau the estimates of AR(1) replicas are 12 % low in the median
# and 5 % in RMS, at 5 tau 32 % and 22 % (tests/analysis/test_timeseries.py)
ESTIMATE_MIN_CORRELATION_TIMES = 20.0
# Why mean_error gives no error (NaN): said the same way wherever a caption reports it.
NOT_CONVERGED = "the window covers too few correlation times"


@dataclass(frozen=True)
class MeanError:
    """Mean of a series and its standard error; tau = statistical inefficiency g in samples."""

    mean: float
    error: float  # standard error of the mean; NaN when not converged
    tau: float  # integrated autocorrelation time 1 + 2 sum rho_k (samples); NaN if unknown
    interval: float  # sampling interval (s)
    n: int  # samples
    converged: bool  # Geyer's sequence ended inside the series and n >= min_correlation_times * tau
    # the same formula's error, converged or not, over at least ESTIMATE_MIN_CORRELATION_TIMES
    # (low below min_correlation_times); NaN for a shorter series or when Geyer's sequence did not end
    estimate: float = math.nan

    @property
    def tau_s(self) -> float:
        """Integrated autocorrelation time (s)."""
        return self.tau * self.interval

    @property
    def n_independent(self) -> float:
        """Number of independent samples n / tau."""
        return self.n / self.tau if self.tau > 0 else math.nan

    @property
    def covered_correlation_times(self) -> float:
        """Length of the series in correlation times (n / tau); 0 for an empty series."""
        return self.n / self.tau if self.n and self.tau > 0 else 0.0


def autocorrelation(values) -> np.ndarray:
    """Normalised autocorrelation rho_k (k = 0 .. n-1) of a series, by FFT; rho_0 = 1.

    Lag sums are divided by n (not n - k): the estimate stays positive definite. A constant series
    gives rho = (1, 0, 0, ...).
    """
    x = np.asarray(values, dtype=np.float64)
    n = x.size
    x = x - x.mean()
    size = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(x, size)
    acf = np.fft.irfft(f * np.conj(f), size)[:n]
    if acf[0] <= 0:
        out = np.zeros(n)
        out[0] = 1.0
        return out
    return acf / acf[0]


def mean_error(values, interval: float = 1.0,
               min_correlation_times: float = MIN_CORRELATION_TIMES) -> MeanError:
    """Mean of an evenly sampled series (every `interval` s) and its standard error
    sqrt(var * tau / n), tau = 1 + 2 sum_k rho_k the statistical inefficiency g (samples).

    The sum is cut by Geyer's initial monotone sequence: the pair sums rho_2k + rho_2k+1 are
    added while positive, each capped at the one before. Not converged (error NaN) when the
    pair sums stay positive to the end of the series or n < min_correlation_times * max(tau, 1):
    a series shorter than a few tau shows too little of its own fluctuation and tau comes out
    small (below 1 on few white-noise samples).
    """
    x = np.asarray(values, dtype=np.float64)
    n = x.size
    if n == 0:
        return MeanError(math.nan, math.nan, math.nan, interval, 0, False)
    mean = float(x.mean())
    var = float(np.mean((x - mean) ** 2))
    if n < 2 or var == 0.0:
        # a constant series is known exactly; one sample says nothing about its error
        error = 0.0 if n >= 2 else math.nan
        return MeanError(mean, error, 1.0, interval, n, n >= 2, error)
    tau, ended = statistical_inefficiency(autocorrelation(x))
    converged = ended and n >= min_correlation_times * max(tau, 1.0)
    long_enough = n >= min(ESTIMATE_MIN_CORRELATION_TIMES, min_correlation_times) * max(tau, 1.0)
    estimate = math.sqrt(var * tau / n) if ended and long_enough else math.nan
    return MeanError(mean, estimate if converged else math.nan, tau, interval, n, converged, estimate)


def statistical_inefficiency(rho: np.ndarray) -> tuple[float, bool]:
    """(tau, ended): tau = -1 + 2 sum of Geyer's initial monotone sequence of pair sums
    rho_2k + rho_2k+1 (samples), floored at 1/n; ended is False when no pair sum turned
    non-positive inside the series (the window then is the whole series)."""
    pairs = len(rho) // 2
    gamma = rho[0:2 * pairs:2] + rho[1:2 * pairs:2]
    stop = np.flatnonzero(gamma <= 0.0)
    ended = stop.size > 0
    gamma = np.minimum.accumulate(gamma[:stop[0] if ended else pairs])
    return max(-1.0 + 2.0 * float(gamma.sum()), 1.0 / len(rho)), ended


def mser_start(values, batch: int = 5) -> int:
    """Index where the statistically steady part starts (MSER-5 truncation, White 1997).

    Over batches of `batch` samples, choose the truncation k (at most half the series) minimising
    the squared standard error estimate var(rest) / len(rest) of the remaining batch means.
    """
    v = np.asarray(values, dtype=np.float64)
    n = v.size // batch
    if n < 4:
        return 0
    means = v[: n * batch].reshape(n, batch).mean(axis=1)
    rest = np.arange(n, 0, -1)  # batches kept for truncation k = 0 .. n-1
    s1 = np.cumsum(means[::-1])[::-1]
    s2 = np.cumsum((means**2)[::-1])[::-1]
    var = s2 / rest - (s1 / rest) ** 2
    score = var / rest
    k = int(np.argmin(score[: n // 2 + 1]))
    return k * batch


def required_length(values, target: float, interval: float = 1.0,
                    min_correlation_times: float = MIN_CORRELATION_TIMES) -> float:
    """Length (s) of a window of this series whose mean has standard error `target` (the series'
    units), by mean_error's own estimate: its error sqrt(var tau / n) falls as 1/sqrt(n) with var
    and tau those of the series given, so n = var tau / target^2 samples, and at least
    min_correlation_times tau (the estimator gives no error before). NaN when the series' own
    estimate is not converged (too short to know its tau); 0 for a constant series."""
    if not target > 0:
        raise ValueError(f"target standard error {target!r} must be > 0")
    est = mean_error(values, interval, min_correlation_times)
    if not est.converged:
        return math.nan
    if est.error == 0.0:
        return 0.0
    samples = est.error**2 * est.n / target**2  # var tau / target^2
    return max(samples, min_correlation_times * max(est.tau, 1.0)) * interval


def first_reached(values, target: float, interval: float = 1.0,
                  min_correlation_times: float = MIN_CORRELATION_TIMES, every: int = 1) -> float:
    """Length (s) of the shortest leading part of the series, tried every `every` samples, whose
    mean_error is converged with an error at most `target`: what a stop testing the growing window
    would see. NaN when no part reaches it. It comes early on average: the first time a noisy
    estimate dips below a bound (docs/decisions/0014-steady-tolerance-3-percent.md); required_length
    is the estimate to plan on."""
    if not target > 0:
        raise ValueError(f"target standard error {target!r} must be > 0")
    x = np.asarray(values, dtype=np.float64)
    ends = list(range(max(every, 2), x.size + 1, every))
    if x.size >= 2 and (not ends or ends[-1] != x.size):
        ends.append(x.size)  # the whole series is always tried
    for n in ends:
        est = mean_error(x[:n], interval, min_correlation_times)
        if est.converged and est.error <= target:
            return n * interval
    return math.nan

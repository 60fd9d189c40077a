"""Fitting effective model parameters (e.g. gas.viscosity, particles.friction) to measured operating
points: a design over the parameters' bounds, one quadratic response surface per measured quantity
and operating point fitted to the simulated values with their standard errors, the misfit weighted
by the measurement errors and the surfaces' own uncertainty, its minimum, and the uncertainty of
the fitted values from draws of both (docs/rig-calibration.md).

Parameters are handled in coded units: -1 at the lower bound, +1 at the upper one.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd
from scipy.optimize import minimize


@dataclass(frozen=True)
class Bounds:
    """The parameters fitted and their bounds, in their own units."""

    keys: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def of(cls, bounds: Mapping[str, tuple[float, float]]) -> "Bounds":
        keys = tuple(bounds)
        low, high = (np.array([float(bounds[k][i]) for k in keys]) for i in (0, 1))
        if not keys or np.any(~(high > low)):
            raise ValueError(f"bounds need at least one parameter, each with low < high, got {dict(bounds)}")
        return cls(keys, low, high)

    def coded(self, values: np.ndarray) -> np.ndarray:
        return 2.0 * (np.asarray(values, dtype=float) - self.low) / (self.high - self.low) - 1.0

    def decoded(self, x: np.ndarray) -> np.ndarray:
        return self.low + (np.asarray(x, dtype=float) + 1.0) * 0.5 * (self.high - self.low)


def first_design(bounds: Bounds) -> pd.DataFrame:
    """Face-centred central composite design: the 2^k corners, the 2k face centres and the centre
    (3 x 3 for two parameters), enough for a quadratic surface in each; one column per key."""
    k = len(bounds.keys)
    coded = [np.array(c, dtype=float) for c in itertools.product((-1.0, 1.0), repeat=k)]
    for i, sign in itertools.product(range(k), (-1.0, 1.0)):
        face = np.zeros(k)
        face[i] = sign
        coded.append(face)
    coded.append(np.zeros(k))
    return pd.DataFrame(bounds.decoded(np.array(coded)), columns=list(bounds.keys))


def confirmation_design(bounds: Bounds, values: np.ndarray, std: np.ndarray) -> pd.DataFrame:
    """Around a fitted optimum: the optimum and one standard deviation either side along each
    parameter (2k + 1 points), kept inside the bounds; a quarter of the bounds' width where the
    standard deviation is not known (not finite)."""
    values, std = np.asarray(values, dtype=float), np.asarray(std, dtype=float)
    std = np.where(np.isfinite(std), std, 0.25 * (bounds.high - bounds.low))
    points = [values]
    for i, sign in itertools.product(range(len(values)), (-1.0, 1.0)):
        p = values.copy()
        p[i] += sign * std[i]
        points.append(p)
    return pd.DataFrame(np.clip(np.array(points), bounds.low, bounds.high), columns=list(bounds.keys))


def quadratic_terms(x: np.ndarray, degree: int = 2) -> np.ndarray:
    """Regressors of a polynomial surface in coded x (n, k): 1, x_i and, for degree 2, x_i x_j
    (i <= j)."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    columns = [np.ones(len(x))] + [x[:, i] for i in range(x.shape[1])]
    if degree == 2:
        columns += [x[:, i] * x[:, j] for i, j in itertools.combinations_with_replacement(range(x.shape[1]), 2)]
    return np.column_stack(columns)


@dataclass(frozen=True)
class Surface:
    """A response surface in coded parameters: coefficients and their covariance."""

    degree: int
    coefficients: np.ndarray
    covariance: np.ndarray
    reduced_chi2: float  # of the surface against the simulated values (lack of fit when >> 1)

    def predict(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and variance of the surface at coded x (n, k)."""
        a = quadratic_terms(x, self.degree)
        return a @ self.coefficients, np.einsum("ni,ij,nj->n", a, self.covariance, a)


def fit_surface(x: np.ndarray, y: np.ndarray, sem: np.ndarray) -> Surface:
    """Weighted least-squares surface through simulated values y +- sem at coded x: quadratic when
    the points allow (at least one more than its terms), else linear. The coefficients' covariance
    is scaled up by the reduced chi-square when the surface does not follow the points within
    their errors."""
    x, y, sem = np.atleast_2d(x), np.asarray(y, dtype=float), np.asarray(sem, dtype=float)
    keep = np.isfinite(y) & np.isfinite(sem) & (sem > 0)
    x, y, sem = x[keep], y[keep], sem[keep]
    k = x.shape[1]
    degree = 2 if len(y) > quadratic_terms(np.zeros((1, k))).shape[1] else 1
    a = quadratic_terms(x, degree)
    if len(y) < a.shape[1]:
        raise ValueError(f"{len(y)} simulated values with an error, a surface in {k} parameters needs "
                         f"at least {a.shape[1]}")
    w = 1.0 / sem
    coefficients, *_ = np.linalg.lstsq(a * w[:, None], y * w, rcond=None)
    dof = len(y) - a.shape[1]
    chi2 = float(np.sum(((a @ coefficients - y) * w) ** 2))
    reduced = chi2 / dof if dof > 0 else float("nan")
    covariance = np.linalg.pinv((a * w[:, None]).T @ (a * w[:, None]))
    if dof > 0 and reduced > 1.0:
        covariance = covariance * reduced
    return Surface(degree, coefficients, covariance, reduced)


@dataclass(frozen=True)
class Fit:
    """The fitted parameters (own units) with their standard deviations and covariance, the
    misfit at the optimum and its degrees of freedom, and the draws behind the uncertainty."""

    keys: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    chi2: float
    dof: int
    at_bound: tuple[str, ...]
    draws: np.ndarray  # (n, k) optima of the perturbed misfits, own units
    surfaces: tuple[Surface, ...]  # one per target, in the targets' order

    def as_dict(self) -> dict:
        return {"parameters": {k: {"value": float(v), "std": float(s)}
                               for k, v, s in zip(self.keys, self.values, self.std)},
                "chi2": self.chi2, "dof": self.dof, "at_bound": list(self.at_bound)}


def surfaces(design: pd.DataFrame, targets: pd.DataFrame, bounds: Bounds) -> list[Surface]:
    """One surface per target row (label, summary_key): the design rows of that label, the summary
    value and its `<summary_key>_sem`."""
    out = []
    for _, t in targets.iterrows():
        rows = design[design["label"] == t["label"]]
        key = t["summary_key"]
        if key not in rows or f"{key}_sem" not in rows:
            raise KeyError(f"the design has no column {key} or {key}_sem for {t['label']} {t['quantity']}")
        try:
            out.append(fit_surface(bounds.coded(rows[list(bounds.keys)].to_numpy()), rows[key], rows[f"{key}_sem"]))
        except ValueError as err:
            raise ValueError(f"operating point {t['label']}, {t['quantity']}: {err}") from None
    return out


def misfit(x: np.ndarray, fitted: list[Surface], value: np.ndarray, error: np.ndarray,
           coefficients: list[np.ndarray] | None = None) -> np.ndarray:
    """Chi-square at coded points x (n, k): sum over targets of (surface - measured)^2 over the
    measurement variance plus the surface's variance there. `coefficients` replaces the surfaces'
    own (a draw)."""
    x = np.atleast_2d(x)
    total = np.zeros(len(x))
    for i, s in enumerate(fitted):
        a = quadratic_terms(x, s.degree)
        mean = a @ (s.coefficients if coefficients is None else coefficients[i])
        variance = np.einsum("ni,ij,nj->n", a, s.covariance, a)
        total += (mean - value[i]) ** 2 / (error[i] ** 2 + variance)
    return total


def _minimum(k: int, chi2, start: np.ndarray | None = None) -> np.ndarray:
    """Coded point of least chi2 in the box, polished by L-BFGS-B from `start` or else from the
    best point of a grid over the box."""
    if start is None:
        axes = np.linspace(-1.0, 1.0, max(5, int(round(4000 ** (1.0 / k)))))
        grid = np.array(list(itertools.product(axes, repeat=k)))
        start = grid[int(np.argmin(chi2(grid)))]
    result = minimize(lambda p: float(chi2(p[None, :])[0]), start, method="L-BFGS-B", bounds=[(-1.0, 1.0)] * k)
    return result.x if result.fun <= float(chi2(start[None, :])[0]) else start


def fit(design: pd.DataFrame, targets: pd.DataFrame, bounds: Bounds, draws: int = 200,
        seed: int = 0) -> Fit:
    """Fit the parameters to the targets (analysis.measurements.targets) through surfaces of the
    design's simulated summaries (columns: the parameter keys, `label`, each summary key and its
    `_sem`). The uncertainty comes from `draws` optima, each of the misfit with the measured values
    drawn from their errors and every surface's coefficients from their covariance."""
    fitted = surfaces(design, targets, bounds)
    value, error = targets["value"].to_numpy(dtype=float), targets["error"].to_numpy(dtype=float)
    k = len(bounds.keys)
    best = _minimum(k, lambda x: misfit(x, fitted, value, error))
    rng = np.random.default_rng(seed)
    sample = []
    for _ in range(draws):
        drawn_value = value + rng.normal(0.0, error)
        drawn = [rng.multivariate_normal(s.coefficients, s.covariance) for s in fitted]
        sample.append(_minimum(k, lambda x: misfit(x, fitted, drawn_value, error, drawn), start=best))
    sample = bounds.decoded(np.array(sample))
    covariance = np.atleast_2d(np.cov(sample, rowvar=False))
    at_bound = tuple(key for key, c in zip(bounds.keys, best) if abs(c) > 1.0 - 1e-6)
    return Fit(bounds.keys, bounds.decoded(best), np.sqrt(np.diag(covariance)), covariance,
               float(misfit(best, fitted, value, error)[0]), len(value) - k, at_bound, sample, tuple(fitted))


def fitted_table(targets: pd.DataFrame, bounds: Bounds, result: Fit) -> pd.DataFrame:
    """The targets with what the fitted model gives: `fitted` (the surface at the fitted values)
    and `fitted_std` (its spread over the fit's draws and the surface's own error), and `pull`,
    (fitted - measured) over both errors combined."""
    at_best = bounds.coded(result.values)[None, :]
    drawn = bounds.coded(result.draws)
    table = targets.copy()
    means, stds = [], []
    for s in result.surfaces:
        mean, variance = s.predict(at_best)
        spread = np.std(s.predict(drawn)[0]) if len(drawn) > 1 else 0.0
        means.append(float(mean[0]))
        stds.append(float(np.sqrt(variance[0] + spread ** 2)))
    table["fitted"], table["fitted_std"] = means, stds
    table["pull"] = pull(table, "fitted")
    return table


def pull(table: pd.DataFrame, model: str) -> pd.Series:
    """(model - measured) over the measured error and the model's (`<model>_std`) combined."""
    return (table[model] - table["value"]) / np.sqrt(table["error"] ** 2 + table[f"{model}_std"] ** 2)


def misfit_grid(targets: pd.DataFrame, bounds: Bounds, result: Fit,
                n: int = 61) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chi-square over the first two fitted parameters (own units; the others at their fitted
    values): the axes (n,) and (n,) and chi2 (n, n), indexed [second, first]; for one parameter
    its axis, [0.] and chi2 (1, n)."""
    fitted = list(result.surfaces)
    value, error = targets["value"].to_numpy(dtype=float), targets["error"].to_numpy(dtype=float)
    axis = np.linspace(-1.0, 1.0, n)
    centre = bounds.coded(result.values)
    if len(bounds.keys) == 1:
        x = np.repeat(centre[None, :], n, axis=0)
        x[:, 0] = axis
        return bounds.decoded(x)[:, 0], np.zeros(1), misfit(x, fitted, value, error)[None, :]
    a, b = np.meshgrid(axis, axis)
    x = np.repeat(centre[None, :], n * n, axis=0)
    x[:, 0], x[:, 1] = a.ravel(), b.ravel()
    chi2 = misfit(x, fitted, value, error).reshape(n, n)
    corners = bounds.decoded(np.array([[-1.0] * len(centre), [1.0] * len(centre)]))
    return (np.linspace(corners[0, 0], corners[1, 0], n), np.linspace(corners[0, 1], corners[1, 1], n), chi2)


def propagated_std(gradient: np.ndarray, covariance: np.ndarray, own_sem: float) -> float:
    """Standard deviation of a prediction: the fit's covariance carried through the gradient of the
    predicted quantity with respect to the fitted parameters (own units), and the prediction
    case's own standard error."""
    gradient = np.asarray(gradient, dtype=float)
    return float(np.sqrt(gradient @ np.asarray(covariance, dtype=float) @ gradient + own_sem ** 2))


def central_gradient(plus: np.ndarray, minus: np.ndarray, plus_at: np.ndarray, minus_at: np.ndarray) -> np.ndarray:
    """Gradient of a quantity from its values at one step up and one down along each parameter
    (the steps may be unequal where a bound clips them); 0 along a parameter without a step."""
    step = np.asarray(plus_at, dtype=float) - np.asarray(minus_at, dtype=float)
    change = np.asarray(plus, dtype=float) - np.asarray(minus, dtype=float)
    return np.divide(change, step, out=np.zeros_like(change), where=step > 0)

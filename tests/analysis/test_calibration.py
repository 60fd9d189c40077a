"""Fitting effective parameters to measured points: design, response surfaces, the fit and its
uncertainty, on synthetic responses whose exact optimum and error propagation are known."""

import math

import numpy as np
import pandas as pd
import pytest

from analysis.calibration import (Bounds, central_gradient, confirmation_design, first_design, fit,
                                  fit_surface, misfit, propagated_std, quadratic_terms, surfaces)

BOUNDS = Bounds.of({"gas.viscosity": (4.5e-5, 8.5e-5), "particles.friction": (0.2, 0.8)})
TRUE = np.array([6.73e-5, 0.5])


def responses(p: np.ndarray) -> dict:
    """A synthetic model, quadratic in the parameters (so a quadratic surface is exact): the
    pressure drop (Pa/m) grows with viscosity and friction, plugs slow with friction and lengthen."""
    eta, mu = p[..., 0] / 6.73e-5, p[..., 1]
    return {"pressure_drop": 4000.0 * eta * (1.0 + 0.5 * mu),
            "slug_velocity": 0.3 - 0.2 * mu + 0.1 * (eta - 1.0),
            "slug_length_total": 0.03 + 0.04 * mu ** 2}


def jacobian(p: np.ndarray) -> np.ndarray:
    """d responses / d parameters (rows: pressure drop, velocity, length), analytic."""
    eta, mu = p[0] / 6.73e-5, p[1]
    return np.array([[4000.0 * (1.0 + 0.5 * mu) / 6.73e-5, 2000.0 * eta],
                     [0.1 / 6.73e-5, -0.2],
                     [0.0, 0.08 * mu]])


ERRORS = {"pressure_drop": 200.0, "slug_velocity": 0.02, "slug_length_total": 0.005}
SEMS = {"pressure_drop": 20.0, "slug_velocity": 0.002, "slug_length_total": 0.0005}  # per design case


def design_table(rng=None) -> pd.DataFrame:
    design = first_design(BOUNDS)
    truth = responses(design.to_numpy())
    for key, values in truth.items():
        noise = 0.0 if rng is None else rng.normal(0.0, SEMS[key], len(values))
        design[key], design[f"{key}_sem"] = values + noise, SEMS[key]
    design["label"] = "B"
    return design


def target_table(rng=None) -> pd.DataFrame:
    truth = responses(TRUE)
    rows = [{"label": "B", "quantity": key, "summary_key": key,
             "value": float(truth[key]) + (0.0 if rng is None else rng.normal(0.0, ERRORS[key])),
             "error": ERRORS[key]} for key in truth]
    return pd.DataFrame(rows)


def test_first_design_is_the_face_centred_composite_inside_the_bounds():
    design = first_design(BOUNDS)
    coded = BOUNDS.coded(design.to_numpy())
    assert len(design) == 9 and len({tuple(r) for r in coded.round(12)}) == 9  # the 3 x 3 grid
    assert set(np.unique(coded.round(12))) == {-1.0, 0.0, 1.0}
    three = first_design(Bounds.of({"a": (0, 1), "b": (0, 1), "c": (0, 1)}))
    assert len(three) == 8 + 6 + 1  # corners, face centres, centre: still a full quadratic in 3


def test_confirmation_design_brackets_the_optimum_inside_the_bounds():
    design = confirmation_design(BOUNDS, np.array([8.4e-5, 0.5]), np.array([0.5e-5, 0.1]))
    assert len(design) == 5
    assert design["gas.viscosity"].max() == 8.5e-5  # clipped at the upper bound
    assert sorted(design["particles.friction"].round(12)) == [0.4, 0.5, 0.5, 0.5, 0.6]
    unknown = confirmation_design(BOUNDS, np.array([6.5e-5, 0.5]), np.array([np.nan, 0.1]))
    assert sorted(unknown["gas.viscosity"].round(12)) == pytest.approx([5.5e-5, 6.5e-5, 6.5e-5, 6.5e-5, 7.5e-5])


def test_bounds_need_low_below_high():
    with pytest.raises(ValueError, match="low < high"):
        Bounds.of({"gas.viscosity": (8.5e-5, 4.5e-5)})


def test_quadratic_surface_reproduces_a_quadratic_exactly():
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, (12, 2))
    truth = lambda x: 1.0 + 2.0 * x[:, 0] - x[:, 1] + 0.5 * x[:, 0] * x[:, 1] + 3.0 * x[:, 1] ** 2
    surface = fit_surface(x, truth(x), np.full(12, 1e-6))
    assert surface.degree == 2
    probe = rng.uniform(-1, 1, (5, 2))
    # rounding only: the coefficients are O(1) and the solve is well conditioned
    np.testing.assert_allclose(surface.predict(probe)[0], truth(probe), atol=1e-8)


def test_too_few_points_fall_back_to_a_plane_then_refuse():
    x = np.array([[-1.0, -1.0], [1.0, -1.0], [0.0, 1.0], [0.5, 0.5]])
    assert fit_surface(x, x.sum(axis=1), np.ones(4)).degree == 1
    with pytest.raises(ValueError, match="needs at least 3"):
        fit_surface(x[:2], x[:2].sum(axis=1), np.ones(2))


def test_lack_of_fit_widens_the_surface_errors():
    x = np.array(list(np.ndindex(4, 4)), dtype=float) / 1.5 - 1.0
    smooth = fit_surface(x, (x ** 2).sum(axis=1), np.full(16, 0.01))
    rough = fit_surface(x, np.exp(3 * x[:, 0]), np.full(16, 0.01))  # not a quadratic
    assert smooth.reduced_chi2 < 1e-6 and rough.reduced_chi2 > 10
    assert np.all(np.diag(rough.covariance) > 10 * np.diag(smooth.covariance))


def test_noise_free_fit_returns_the_true_parameters():
    result = fit(design_table(), target_table(), BOUNDS, draws=20)
    # exact surfaces and targets: only the optimiser's tolerance (~1e-6 in coded units) remains
    np.testing.assert_allclose(BOUNDS.coded(result.values), BOUNDS.coded(TRUE), atol=1e-4)
    assert result.chi2 < 1e-6 and result.dof == 1 and result.at_bound == ()


def test_optimum_outside_the_bounds_is_flagged():
    targets = target_table()
    targets["value"] = responses(np.array([9.5e-5, 0.5]))["pressure_drop"], 0.2, 0.04  # higher viscosity
    result = fit(design_table(), targets, BOUNDS, draws=5)
    assert "gas.viscosity" in result.at_bound


def test_uncertainty_matches_linear_error_propagation_and_covers_the_truth():
    # Noisy design cases and noisy measurements, repeated: the reported standard deviation should be
    # the linearised propagation (J^T W J)^-1 of the measurement errors (the design noise is 10x
    # smaller and averages over 9 cases), and the truth should lie within 2 of them about 95 % of the
    # time. 20 repeats with 40 draws each: a reported std carries ~11 % sampling error, a coverage
    # of 0.95 a binomial s.d. of 0.05, so >= 0.8 fails only for a real under-estimate.
    j = jacobian(TRUE)
    weights = np.diag([1.0 / ERRORS[k] ** 2 for k in ERRORS])
    expected = np.sqrt(np.diag(np.linalg.inv(j.T @ weights @ j)))
    rng = np.random.default_rng(7)
    inside, ratios = [], []
    for _ in range(20):
        result = fit(design_table(rng), target_table(rng), BOUNDS, draws=40, seed=int(rng.integers(1 << 30)))
        inside.append(np.abs(result.values - TRUE) <= 2.0 * result.std)
        ratios.append(result.std / expected)
    assert np.mean(inside, axis=0).min() >= 0.8
    assert np.all((np.median(ratios, axis=0) > 0.7) & (np.median(ratios, axis=0) < 1.5))


def test_misfit_weights_by_measurement_and_surface_variance():
    design = design_table()
    targets = target_table()
    result_best = BOUNDS.coded(TRUE)[None, :]
    fitted = surfaces(design, targets, BOUNDS)
    value, error = targets["value"].to_numpy(), targets["error"].to_numpy()
    off = result_best + np.array([[0.2, 0.0]])
    shifted = responses(BOUNDS.decoded(off)[0])
    by_hand = sum((shifted[k] - value[i]) ** 2 / (error[i] ** 2 + fitted[i].predict(off)[1][0])
                  for i, k in enumerate(ERRORS))
    assert misfit(off, fitted, value, error)[0] == pytest.approx(by_hand, rel=1e-6)
    assert quadratic_terms(off).shape == (1, 6)


def test_prediction_error_carries_the_fit_covariance_through_the_gradient():
    # a linear quantity y = 3 eta' + 2 mu': its variance is g^T C g exactly, plus the case's own
    covariance = np.array([[0.04, 0.01], [0.01, 0.09]])
    g = central_gradient(np.array([3.0 * 1.2, 2.0 * 0.5]), np.array([3.0 * 0.8, 2.0 * 0.2]),
                         np.array([1.2, 0.5]), np.array([0.8, 0.2]))  # unequal (clipped) steps
    np.testing.assert_allclose(g, [3.0, 2.0])
    expected = math.sqrt(9 * 0.04 + 4 * 0.09 + 2 * 6 * 0.01 + 0.5 ** 2)
    assert propagated_std(g, covariance, 0.5) == pytest.approx(expected)


def test_fitted_table_and_misfit_map_of_an_exact_fit():
    from analysis.calibration import fitted_table, misfit_grid

    targets = target_table()
    result = fit(design_table(), targets, BOUNDS, draws=20)
    table = fitted_table(targets, BOUNDS, result)
    # exact surfaces, exact targets: the fitted model reproduces each measured value
    np.testing.assert_allclose(table["fitted"], targets["value"], rtol=1e-5)
    assert np.all(np.abs(table["pull"]) < 1e-3) and np.all(table["fitted_std"] > 0)
    first, second, chi2 = misfit_grid(targets, BOUNDS, result, n=41)
    assert (first[0], first[-1], second[0], second[-1]) == pytest.approx((4.5e-5, 8.5e-5, 0.2, 0.8))
    row, column = np.unravel_index(np.argmin(chi2), chi2.shape)
    # the map's least cell is the one holding the truth (grid spacing 1e-6 Pa s and 0.015)
    assert abs(first[column] - TRUE[0]) <= 1e-6 and abs(second[row] - TRUE[1]) <= 0.015


def test_gradient_is_zero_along_a_parameter_without_a_step():
    # both steps clipped onto the same bound: no information, no division by zero
    g = central_gradient(np.array([5.0, 2.0]), np.array([1.0, 2.0]), np.array([1.2, 0.8]), np.array([0.8, 0.8]))
    np.testing.assert_allclose(g, [10.0, 0.0], rtol=1e-12)  # 4 / 0.4: rounding only

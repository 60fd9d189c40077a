"""benchmarks/studies/branch_learning.py: its loop sums what it says, and it reports every fraction."""

import numpy as np
import pytest

from .. import load_benchmark


@pytest.fixture(scope="module")
def study():
    return load_benchmark("studies/branch_learning")


def test_the_branchy_loop_is_the_sum_it_describes(study):
    x = np.random.default_rng(3).random(1000)
    below = x < study.THRESHOLD
    expected = np.sum(x[below] * 1.0001 + 0.5) - np.sum(x[~below] * 0.9999)
    # the two sums in another order: rounding of a 1000-term sum of O(1) terms, ~1e-13
    assert study.branchy_sum(x, study.THRESHOLD) == pytest.approx(expected, rel=1e-12)


def test_every_fraction_and_the_sorted_data_are_timed(study):
    result = study.measure(elements=200, calls=2, rounds=1)
    assert set(result) == {*study.FRACTIONS, "sorted"}
    assert all(ns > 0 for ns in result.values())

"""benchmarks/scale.py: the smallest packing is a valid dense state and the timing is sane (~10 s)."""

import math

import numpy as np
import pytest

from . import load_benchmark


@pytest.fixture(scope="module")
def scale():
    return load_benchmark("scale")


@pytest.fixture(scope="module")
def state(scale):
    return scale.settled_state(1000, 0.007)


def test_standard_tube_gives_the_bench_packing(scale):
    from engine.bench import standard_case, standard_packing

    assert np.array_equal(scale.dense_packing(scale.case_for(0.525, 0.007, gas=False)),
                          standard_packing(standard_case()))
    assert scale.tube_length(3066, 0.007) == pytest.approx(0.525, rel=0.01)


def test_smallest_packing_is_dense_and_inside(scale, state):
    pos, d, R = state["positions"], 0.0014, 0.0035
    assert 950 <= len(pos) <= 1050
    assert np.all(np.isfinite(pos))
    assert np.all(np.hypot(pos[:, 1], pos[:, 2]) <= R - d / 2 + 0.01 * d)
    assert np.all((pos[:, 0] >= d / 2 - 0.01 * d) & (pos[:, 0] <= state["length"]))
    stats = scale.contact_stats(pos, d, 2 * R)
    assert stats["max_overlap_d"] < 0.01
    assert 2 <= stats["contacts_per_grain"] <= 6


def test_contact_stats_counts_pairs_and_walls(scale):
    d = 0.0014
    pos = np.array([[0.01, 0, 0], [0.01 + 0.99 * d, 0, 0], [0.0005, 0, 0.0035 - d / 2 + 1e-5]])
    stats = scale.contact_stats(pos, d, 0.007)
    assert stats["contacts_per_grain"] == pytest.approx((2 + 2) / 3)  # one pair, wall and inlet of grain 3
    assert stats["max_overlap_d"] == pytest.approx(0.2 / 1.4)          # inlet: r - x = 0.2 mm


@pytest.mark.parametrize("gas", [False, True])
def test_timing_is_positive_and_finite(scale, state, gas):
    sim = scale.simulation_from(state, gas)
    sim.advance(10 * sim.dt)
    wall, cpu = scale.time_steps(sim, 50)
    assert math.isfinite(wall) and wall > 0
    assert math.isfinite(cpu) and cpu > 0
    assert sim.n_particles == len(state["positions"])

"""benchmarks/studies/neighbor_build.py: the engine's list is the grain-by-grain form's, entry for
entry (each with its grain) and in the same order (which the contact sums follow)."""

import numpy as np
import pytest

from engine.kernels.neighbors import build_neighbor_list

from .. import load_benchmark
from . import small_conveying_simulation


@pytest.fixture(scope="module")
def study():
    return load_benchmark("studies/neighbor_build")


def test_the_engine_builds_the_grain_by_grain_list(study):
    sim = small_conveying_simulation()
    sim._rebuild()
    n = int(sim._n[0])
    assert (sim._in_feed[:n] == 1).sum() > 1  # pairs of two feed grains are left out of both
    engine, before = study.lists_of(build_neighbor_list, sim), study.lists_of(study.grain_by_grain, sim)
    assert engine[1].size > n
    assert len(engine) == len(before) == 3  # nbr_start, nbr, nbr_i
    for a, b in zip(engine, before):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(engine[2], np.repeat(np.arange(n), np.diff(engine[0])))  # entry k's grain


def test_timing_and_step_share_report_positive_figures(study):
    sim = small_conveying_simulation()
    sim._rebuild()
    timing = study.time_builds(sim, calls=2, rounds=1)
    assert timing["engine_us"] > 0 and timing["grain_by_grain_us"] > 0
    share = study.step_share(sim, pieces=1, piece=0.001)
    assert share["step_us"] > 0 and share["steps_per_rebuild"] >= 1


def test_a_case_needs_its_initial_state(study, capsys):
    with pytest.raises(SystemExit):
        study.main(["config/cases/vertical.yaml"])
    assert "go together" in capsys.readouterr().err

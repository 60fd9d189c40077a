"""benchmarks/stability.py: a refused time step names the key and the limit, a normal case runs with
every check passed, and bad states (fabricated, or slipped into a real run) are caught as SILENT."""

import math

import numpy as np
import pytest

from . import load_benchmark


@pytest.fixture(scope="module")
def stability():
    return load_benchmark("stability")


def dense_case(stability, duration=0.15, **extra):
    """A 3.5 cm horizontal tube fed at 9.95 kg/h: ~250 grains in contact after 0.15 s (~1 s wall)."""
    return stability.StressCase("test", "dense", "horizontal",
                                {"feed.mass_flow_kg_h": 9.95, "feed.entry_velocity": 0.16, **extra},
                                duration=duration)


@pytest.fixture(scope="module")
def final_state(stability):
    """The state of the dense case after 0.15 s."""
    from engine import Simulation

    sim = Simulation(stability.build_case(dense_case(stability)))
    sim.advance(0.15)
    return stability.state_of(sim)


def test_time_step_above_the_limit_is_refused_naming_key_and_limit(stability):
    row = stability.run_stress_case(stability.StressCase(
        "time step, horizontal", "0.5", "horizontal", {"numerics.time_step_fraction": 0.5}))
    assert row["outcome"] == "refused" and row["steps"] == 0
    assert "numerics.time_step_fraction = 0.5" in row["reason"]
    assert "stable limit" in row["reason"] and "numerics.time_step_fraction <= 0.287" in row["reason"]  # 0.6 x the damped pair limit 0.478 at e = 0.5
    assert "\n" not in row["reason"]


def test_normal_case_runs_with_every_check_passed(stability):
    row = stability.run_stress_case(dense_case(stability))
    assert row["outcome"] == "ran", row["reason"]
    assert row["checks"] == "finite ok, inside ok, overlap ok, mass ok"
    assert row["n_particles"] > 100 and row["steps"] > 0
    assert 0 < row["max_overlap_over_d"] <= row["max_overlap_sampled_over_d"] < stability.MAX_OVERLAP
    assert math.isfinite(row["pressure_drop_Pa"]) and row["pressure_drop_Pa"] > 0


def test_real_state_passes_and_fabricated_bad_states_fail(stability, final_state):
    checks, measures = stability.check_state(final_state)
    assert all(checks.values()), checks
    assert measures["mass_books_over_m"] == pytest.approx(0, abs=1e-9)
    d, R = 2 * final_state["radius"], final_state["tube_radius"]

    def broken(**changes):
        state = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in final_state.items()}
        for name, change in changes.items():
            change(state) if callable(change) else state.__setitem__(name, change)
        return stability.check_state(state)[0]

    def nan_velocity(state):
        state["velocities"][3, 1] = np.nan

    def outside(state):
        state["positions"][5, 1:] = [0.0, R + 0.1 * d]

    def overlapping(state):
        # grain 7 onto a grain far enough from the outlet that 0.6 d further is still in the tube
        j = int(np.argmin(state["positions"][:, 0]))
        state["positions"][7 if j != 7 else 8] = state["positions"][j] + [0.6 * d, 0.0, 0.0]

    assert stability.failed(broken(v=nan_velocity)) == ["finite"]
    assert "inside" in stability.failed(broken(p=outside))
    assert stability.failed(broken(p=overlapping)) == ["overlap"]
    assert stability.failed(broken(mass_out=final_state["mass_out"] + final_state["grain_mass"])) == ["mass"]
    assert stability.failed(broken(pressure_drop=math.inf)) == ["finite"]
    # A finished run whose final state fails a check is SILENT, never `ran`.
    outcome, reason = stability.classify("ran", "", [], broken(v=nan_velocity), 0.15)
    assert outcome == "SILENT" and "finite" in reason
    assert stability.classify("stopped", "a grain left the tube", [], broken(v=nan_velocity), 0.1) == \
        ("stopped", "a grain left the tube")


def test_bad_state_slipped_into_a_run_is_reported_silent(stability, monkeypatch):
    """The whole path: a grain moved out of the tube behind the engine's back (after 0.05 s) makes
    the finished run SILENT."""
    real = stability.state_of

    def corrupted(sim):
        state = real(sim)
        if sim.time > 0.05 and len(state["positions"]):
            state["positions"][0, 1:] = [0.0, 2 * state["tube_radius"]]
        return state

    monkeypatch.setattr(stability, "state_of", corrupted)
    row = stability.run_stress_case(dense_case(stability, duration=0.1))
    assert row["outcome"] == "SILENT"
    assert "inside failed" in row["reason"] and "finished without a failure" in row["reason"]
    assert stability.headline([row]).endswith("1 silent")

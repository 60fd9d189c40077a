"""benchmarks/studies/step_split.py: the parts it times leave the simulation as it is, and its split
of the step adds up to the whole step."""

import math

import numpy as np
import pytest

from .. import load_benchmark
from . import small_conveying_simulation


@pytest.fixture(scope="module")
def study():
    return load_benchmark("studies/step_split")


def test_the_parts_are_timed_on_copies_with_the_grains_held(study):
    sim = small_conveying_simulation()
    calls = study.part_calls(sim)  # rebuilds the simulation's list first
    assert list(calls) == ["kick_drift", "sort", "build", *study.GAS_PARTS, "contacts"]
    before = [a.copy() for a in sim._grains()] + [sim._nbr_start.copy(), sim._nbr.copy(), sim._nbr_i.copy(),
                                                   sim.gas.pressure.copy()]
    held = calls["kick_drift"][1][0]
    positions, velocities = held.pos.copy(), held.vel.copy()
    for kernel, args in calls.values():  # called as the study calls them, twice
        kernel(*args)
        kernel(*args)
    study.loop_step(sim, 0, 2)  # the step moving and held, on copies as well
    study.loop_step(sim, 5, 2)
    after = [*sim._grains(), sim._nbr_start, sim._nbr, sim._nbr_i, sim.gas.pressure]
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(held.pos, positions)  # the kick and drift by 0 move nothing
    np.testing.assert_array_equal(held.vel, velocities)
    assert np.abs(held.force[:sim.n_particles]).max() > 0  # the contacts part did compute forces


def test_the_split_adds_up_to_the_whole_step(study):
    us = {"kick_drift": 10.0, "sort": 80.0, "build": 240.0, "deposit": 50.0, "fields": 5.0, "sources": 5.0,
          "solve": 40.0, "gradient": 5.0, "drag": 45.0, "contacts": 100.0}
    parts = study.split(us, step_us=200.0, held_us=150.0, steps_per_rebuild=40.0, gas_interval=10)
    assert parts["sort"]["us_per_step"] == 2.0 and parts["build"]["us_per_step"] == 6.0
    assert parts["deposit"]["us_per_step"] == 5.0 and parts["contacts"]["us_per_step"] == 100.0
    # parts 133 us per step; the held step 150: together 17; the step 200: motion 50
    assert math.isclose(parts["together"]["us_per_step"], 17.0)
    assert math.isclose(parts["motion"]["us_per_step"], 50.0)
    assert math.isclose(sum(row["us_per_step"] for row in parts.values()), 200.0)
    assert math.isclose(parts["contacts"]["speedup_if_free"], 2.0)


def test_half_the_step_asks_what_the_contacts_can_give(study):
    def parts(share):
        return {"contacts": {"share": share}}
    # 80 % of the step: the step at half leaves the contacts 30 %, 8/3 as fast
    assert math.isclose(study.contacts_speedup_for_half(parts(0.8)), 0.8 / 0.3)
    assert study.contacts_speedup_for_half(parts(0.5)) == math.inf
    assert study.contacts_speedup_for_half(parts(0.4)) == math.inf


def test_the_rounds_are_split_one_by_one_then_their_medians_taken(study):
    def row(step, held, contacts):
        return {"steps_per_rebuild": 20.0, "step": step, "held": held, "kick_drift": 10.0, "sort": 40.0,
                "build": 160.0, "contacts": contacts}
    # a slow round (everything 1.5x) between two at the same speed: the medians are the fast rounds'
    measured = [row(200.0, 160.0, 120.0), row(300.0, 240.0, 180.0), row(210.0, 160.0, 120.0)]
    parts = study.median_split(measured, 10)
    assert math.isclose(parts["contacts"]["us_per_step"], 120.0)
    assert math.isclose(parts["motion"]["us_per_step"], 50.0)  # 40, 60, 50
    assert math.isclose(parts["contacts"]["share"], 0.6)  # 0.60, 0.60, 0.571
    assert math.isclose(parts["contacts"]["speedup_if_free"], 2.5)


def test_a_case_needs_its_initial_state(study, capsys):
    with pytest.raises(SystemExit):
        study.main(["config/cases/vertical.yaml"])
    assert "go together" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        study.main(["--rounds", "0"])

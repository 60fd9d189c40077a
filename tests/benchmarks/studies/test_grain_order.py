"""benchmarks/studies/grain_order.py: a permutation of the grain rows keeps the physics (a few seconds)."""

import numpy as np
import pytest

from .. import load_benchmark
from . import small_conveying_simulation

# the per-grain arrays that the physics reads (wall_normal and the rebuild's scratch rows are
# rewritten before they are read; test_permute_moves_every_per_grain_row covers them)
PHYSICAL = ["_pos", "_vel", "_omg", "_force", "_torque", "_drag", "_viscous_damping", "_gid", "_in_feed", "_pos_ref"]


@pytest.fixture(scope="module")
def grain_order():
    return load_benchmark("studies/grain_order")


@pytest.fixture(scope="module")
def sim(grain_order):
    sim = small_conveying_simulation()
    grain_order.ready(sim, 10)
    sim._prepare()  # a fresh list: the next step does not rebuild it
    n = int(sim._n[0])
    # the state exercises every array: feed grains, drag held from the last gas update, viscous sums
    assert sim.n_particles > 50 and (sim._in_feed[:n] == 1).any()
    assert np.abs(sim._drag[:n]).max() > 0 and sim._viscous_damping[:n].max() > 0
    assert np.abs(sim._omg[:n]).max() > 0
    return sim


def shuffled(sim, seed=1):
    return np.random.default_rng(seed).permutation(int(sim._n[0]))


def pairs_of(grain_order, sim):
    i, j = grain_order.list_pairs(sim)
    return set(zip(i.tolist(), j.tolist()))


def test_permute_moves_every_per_grain_row(grain_order, sim):
    perm = shuffled(sim)
    out = grain_order.permute(sim, perm)
    n, cap = int(sim._n[0]), len(sim._pos)
    # every array of one row per grain, found here independently of the study's own list
    per_grain = [name for name, value in vars(sim).items() if isinstance(value, np.ndarray) and value.ndim
                 and len(value) == cap]
    assert set(grain_order.PER_GRAIN) <= set(per_grain)
    for name in per_grain:
        assert np.array_equal(getattr(out, name)[:n], getattr(sim, name)[:n][perm]), name
    # the same pairs in the new rows, each under its lower row, partners ascending
    inverse = np.argsort(perm)
    moved = {tuple(sorted((int(inverse[i]), int(inverse[j])))) for i, j in pairs_of(grain_order, sim)}
    assert pairs_of(grain_order, out) == moved
    i, j = grain_order.list_pairs(out)
    assert np.all(j > i) and np.all(np.diff(i * (n + 1) + j) > 0)


def test_the_list_format_is_the_engines(grain_order, sim):
    # the engine's own list (fresh from its rebuild) rewritten by set_list is the same list
    out = grain_order.permute(sim, np.arange(int(sim._n[0])))
    n = int(sim._n[0])
    assert np.array_equal(out._nbr_start[:n + 1], sim._nbr_start[:n + 1])
    assert np.array_equal(out._nbr[:sim._nbr_start[n]], sim._nbr[:sim._nbr_start[n]])


def test_permute_and_back_is_the_identity(grain_order, sim):
    perm = shuffled(sim, 2)
    back = grain_order.permute(grain_order.permute(sim, perm), np.argsort(perm))
    n = int(sim._n[0])
    for name in grain_order.PER_GRAIN:
        assert np.array_equal(getattr(back, name)[:n], getattr(sim, name)[:n]), name
    assert pairs_of(grain_order, back) == pairs_of(grain_order, sim)


@pytest.mark.parametrize("order", ["id", "random", "cell", "morton", "x"])
def test_every_order_keeps_the_physics(grain_order, sim, order):
    perm = grain_order.order_of(sim, order)
    out = grain_order.permute(sim, perm)
    deviations = grain_order.check_physics(sim, out)
    assert grain_order.physics_agrees(deviations), deviations


def test_a_shuffle_keeps_the_physics_to_rounding(grain_order, sim):
    deviations = grain_order.check_physics(sim, grain_order.permute(sim, shuffled(sim)))
    assert max(deviations.values()) < 1e-13, deviations


@pytest.mark.parametrize("name", PHYSICAL)
def test_an_array_left_unpermuted_breaks_the_physics(grain_order, sim, name):
    # a permutation that forgot one array: the check must see it
    n = int(sim._n[0])
    out = grain_order.permute(sim, shuffled(sim))
    getattr(out, name)[:n] = getattr(sim, name)[:n]
    deviations = grain_order.check_physics(sim, out)
    assert not grain_order.physics_agrees(deviations), deviations


def test_permute_refuses_an_unknown_per_grain_array(grain_order, sim):
    import copy

    other = copy.deepcopy(sim)
    other._new_per_grain = np.zeros(len(other._pos))
    with pytest.raises(ValueError, match="_new_per_grain"):
        grain_order.permute(other, shuffled(other))
    with pytest.raises(ValueError, match="permutation"):
        grain_order.permute(sim, np.zeros(int(sim._n[0]), dtype=int))


def test_orders(grain_order, sim):
    n = int(sim._n[0])
    for order in grain_order.ORDERS:
        assert sorted(grain_order.order_of(sim, order).tolist()) == list(range(n)), order
    assert np.array_equal(grain_order.order_of(sim, "cell"), np.arange(n))  # fresh from the engine's rebuild
    assert grain_order.morton_code(np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 0, 0], [3, 3, 3]])).tolist() == \
        [1, 2, 4, 8, 63]
    random = grain_order.permute(sim, grain_order.order_of(sim, "random"))
    assert grain_order.partner_distance(random)["mean"] > 5 * grain_order.partner_distance(sim)["mean"]


def test_study_reports_every_order(grain_order, sim):
    import copy

    res = grain_order.study(copy.deepcopy(sim), repeats=1)
    assert list(res["orders"]) == list(grain_order.ORDERS)
    engine = res["orders"]["engine"]
    assert engine["forces_ratio"] == engine["step_ratio"] == 1.0
    assert res["windows_with_rebuild"] == 0 and res["steps_per_timed_window"] > 0
    for row in res["orders"].values():
        assert row["forces_ns_per_contact"] > 0 and row["step_us"] > 0 and row["physics_max_deviation"] < 1e-9

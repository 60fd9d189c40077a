"""benchmarks/studies/contact_ablation.py: its variants still apply to the engine's loop, and the
ones said to keep the bits do (six loops compiled, about 40 s)."""

import numpy as np
import pytest

from engine.kernels import contacts

from .. import load_benchmark
from . import small_conveying_simulation


@pytest.fixture(scope="module")
def ablation():
    return load_benchmark("studies/contact_ablation")


@pytest.fixture(scope="module")
def loop_arguments():
    sim = small_conveying_simulation()
    n, grains = sim.n_particles, sim._grains()
    assert (grains.in_feed[:n] == 1).any() and np.abs(grains.omg[:n]).max() > 0
    return (0, n, grains, sim._nbr_start, sim._nbr, sim._p, grains.force, grains.torque, grains.viscous_damping,
            sim._nbr_start[:0])


def test_every_variant_finds_its_anchors_in_the_engine_source(ablation):
    for name in ["engine", *ablation.VARIANTS]:
        law_source, loop_source = ablation.sources(name)
        assert "def _contacts_range_with(optional):" in loop_source
        assert (law_source, loop_source) != ablation.sources("engine") or name == "engine"


def test_the_variants_said_to_keep_the_bits_keep_them_and_the_rewritten_law_is_the_same_law(ablation, loop_arguments):
    engine = ablation.forces_of(contacts._contacts_range_plain, loop_arguments)
    assert np.abs(engine[1]).max() > 0
    for name in ("compacted", "signed_index", "branchless", "compacted_branchless"):
        assert ablation.VARIANTS[name][2]
        assert ablation.compare(ablation.forces_of(ablation.build(name), loop_arguments), engine)["bit_identical"], name
    # the same law with its branch chosen on |v_t| instead of on squares: only the rounding of
    # s = -gt |v_t| / |v_t| differs, a few ulp of each tangential force (1e-16 relative); a wrong branch
    # would move a force by mu F_n - gt |v_t|
    other = ablation.forces_of(ablation.build("root_both_branches"), loop_arguments)
    np.testing.assert_allclose(other[1], engine[1], rtol=0, atol=1e-12 * np.abs(engine[1]).max())
    np.testing.assert_array_equal(other[3], engine[3])  # the same contacts in the viscous branch
    assert not ablation.compare(other, engine)["bit_identical"]


def test_the_single_precision_law_is_the_law_to_float32_rounding(ablation, loop_arguments):
    engine = ablation.forces_of(contacts._contacts_range_plain, loop_arguments)
    single = ablation.build("single_law")
    result, force, torque, _ = ablation.forces_of(single, loop_arguments)
    # float32 rounds each of a law's ~20 operations by up to 6e-8 relative, so a grain's summed force
    # is off by ~1e-6 of the largest force; an overlap taken as the float32 difference dia - dist
    # instead of from dia^2 - dist^2 in double would be off by 2e-3 of it
    scale = np.abs(engine[1]).max()
    np.testing.assert_allclose(force, engine[1], rtol=0, atol=1e-5 * scale)
    np.testing.assert_allclose(torque, engine[2], rtol=0, atol=1e-5 * np.abs(engine[2]).max())
    np.testing.assert_allclose(result[:2], engine[0][:2], rtol=1e-5)  # the largest overlaps
    assert force.dtype == np.float64 and not np.array_equal(force, engine[1])


def test_a_missing_initial_state_is_refused_before_any_work(ablation, tmp_path, capsys):
    with pytest.raises(SystemExit):
        ablation.main(["--initial-state", str(tmp_path / "none.nc")])
    assert "none.nc: no such file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        ablation.main(["--repeats", "0"])
    with pytest.raises(SystemExit):
        ablation.main(["--variants", "compacted", "no_such_variant"])
    assert "unknown variants no_such_variant" in capsys.readouterr().err


def test_the_moving_timing_moves_copies_and_leaves_the_state(ablation):
    sim = small_conveying_simulation()
    n, grains = sim.n_particles, sim._grains()
    before = [a.copy() for a in grains]
    times = ablation.time_moving({"engine": contacts._contacts_range_plain}, grains, n, sim._nbr_start, sim._nbr,
                                 sim._p, sim._counters, steps=2, repeats=1)
    assert set(times) == {"engine", "kick_drift"}
    assert all(len(t) == 1 and t[0] > 0 for t in times.values())
    for a, b in zip(before, grains):
        np.testing.assert_array_equal(a, b)
    copy = type(grains)(*[a.copy() for a in grains])
    run = ablation._moving_caller(contacts._contacts_range_plain)
    taken = run(2, copy, n, sim._nbr_start, sim._nbr, sim._p, copy.force, copy.torque, copy.viscous_damping,
                sim._nbr_start[:0], sim._counters.copy())
    assert taken == 2 and not np.array_equal(copy.pos[:n], grains.pos[:n])  # the timed grains move

"""Contact forces on threads: the chunked sum equals the serial one up to rounding, runs stay
reproducible, bad thread counts are refused (momentum across chunk borders: test_grains.py).
The one-thread contact passes (the default) equal the single loop up to rounding."""

import numba
import numpy as np
import pytest

from engine import Case, Simulation
from engine.bench import settled_simulation
from engine.cli import main as cli_main
from engine.kernels.contacts import contact_forces, contact_forces_chunked
from engine.kernels.passes import contact_passes, pair_buffers
from engine.kernels.state import Chunks

TWO_THREADS = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 numba threads")


@pytest.fixture(scope="module")
def packing():
    """The benchmark's settled dense packing (3066 grains, ~3.5 contacts per grain)."""
    return settled_simulation()


def _forces(sim, nchunks, passes=False):
    n, cap = int(sim._n[0]), len(sim._pos)  # the feed's grains included
    force, torque, wall, diag = np.zeros((cap, 3)), np.zeros((cap, 3)), np.zeros(cap), np.zeros(3)
    damping = np.zeros(cap)  # the sum of gamma_t of each grain's viscous contacts (numerics.implicit_spin)
    p = sim._p._replace(implicit_spin=1.0)  # so that the viscous damping is summed
    grains = sim._grains()._replace(force=force, torque=torque, viscous_damping=damping, wall_normal=wall)
    args = (grains, n, sim._nbr_start, sim._nbr, p, diag)
    if nchunks == 1:
        if passes:
            contact_passes(grains, n, sim._nbr_start, sim._nbr, sim._nbr_i, p, diag, pair_buffers())
        else:
            contact_forces(*args)
        return force[:n], torque[:n], damping[:n], wall[:n], diag, None
    spill_f, spill_t = np.zeros((nchunks, cap, 3)), np.zeros((nchunks, cap, 3))
    spill_d = np.zeros((nchunks, cap))
    bounds, chunk_diag, count = np.zeros(nchunks + 1, np.int64), np.zeros((nchunks, 3)), np.zeros(cap, np.int64)
    contact_forces_chunked(*args, Chunks(spill_f, spill_t, spill_d, bounds, chunk_diag, count))
    assert not spill_f.any() and not spill_t.any() and not spill_d.any(), \
        "spill rows must be zero again after the call"
    spilled = (chunk_diag[:, 2] > bounds[1:]).sum()
    return force[:n], torque[:n], damping[:n], wall[:n], diag, spilled


@pytest.mark.parametrize("nchunks", [2, 3, 7])
def test_chunked_contact_forces_equal_the_serial_sum(packing, nchunks):
    f1, t1, g1, w1, d1, _ = _forces(packing, 1)
    f2, t2, g2, w2, d2, spilled = _forces(packing, nchunks)
    assert spilled == nchunks - 1, "every chunk but the last has pairs reaching into the next one"
    # Only the order of summation of a grain's pair forces differs: a few ulp of the largest
    # terms (|F| ~ k_n * overlap ~ 1e-4 N), far below 1e-12 of the largest force.
    scale = np.abs(f1).max()
    np.testing.assert_allclose(f2, f1, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(t2, t1, rtol=0, atol=1e-12 * np.abs(t1).max())
    # the viscous gamma_t sums cross chunk borders too (sums of equal gamma_t: exact up to rounding)
    assert g1.max() > 0
    np.testing.assert_allclose(g2, g1, rtol=1e-14)
    np.testing.assert_array_equal(w2, w1)  # walls are summed per grain, in one chunk: identical
    np.testing.assert_array_equal(d2[:2], d1[:2])


def _assert_passes_equal_the_single_loop(sim, single, passes):
    """Force, torque, gamma_t sums and wall normal of the two kernels (_forces) equal up to rounding."""
    (f1, t1, g1, w1), (f2, t2, g2, w2) = single[:4], passes[:4]
    # The same terms, summed in another order (the passes add each pair to both grains in list order,
    # then the walls), and the vectorised law fused into other multiply-adds by LLVM: a few ulp of the
    # largest terms (|F| ~ k_n * overlap ~ 1e-4 N), far below 1e-12 of the largest force. A cylinder
    # contact's overlap rho - (R - r) is the difference of two nearly equal lengths: one rounding of
    # rho = |(y, z)| (fused or not) moves it by ulp(R) and the normal force by k_n ulp(R) ~ 9e-16 N
    # (measured: 1 ulp), its friction torque by r times that; 4 such roundings are allowed.
    wall = 4 * sim._p.stiffness * np.spacing(sim._p.tube_radius)
    np.testing.assert_allclose(f2, f1, rtol=0, atol=1e-12 * np.abs(f1).max() + wall)
    np.testing.assert_allclose(t2, t1, rtol=0, atol=1e-12 * np.abs(t1).max() + sim._p.radius * wall)
    np.testing.assert_allclose(g2, g1, rtol=1e-14)  # sums of equal gamma_t: exact up to rounding
    np.testing.assert_allclose(w2, w1, rtol=0, atol=wall)


def test_contact_passes_equal_the_single_loop(packing):
    single, passes = _forces(packing, 1), _forces(packing, 1, passes=True)
    _assert_passes_equal_the_single_loop(packing, single, passes)
    assert single[2].max() > 0 and single[3].max() > 0, "viscous contacts and cylinder contacts are compared"
    d1, d2 = single[4], passes[4]
    np.testing.assert_allclose(d2[:2], d1[:2], rtol=1e-12)  # the overlap guard sees the same overlaps
    assert d1[0] > 0


def test_run_with_contact_passes_follows_the_single_loop():
    passes, single = settled_simulation(), settled_simulation()
    single.set_contact_passes(False)
    # both settled with the passes, the default; they part by the rounding of the force sums
    for sim in (passes, single):
        sim.advance(400 * sim.dt)
    assert np.abs(passes.positions - single.positions).max() < 1e-13
    assert not np.array_equal(passes.positions, single.positions)  # the two kernels did run


@TWO_THREADS
def test_threaded_run_is_reproducible_and_follows_the_serial_run():
    a, b, serial = (settled_simulation(threads=t) for t in (2, 2, 1))  # same packing, settled on one thread
    for sim in (a, b, serial):
        sim.advance(400 * sim.dt)
    np.testing.assert_array_equal(a.positions, b.positions)
    # The two engines differ by the rounding of the force sums (1e-16 relative); in the packing this
    # grows to ~1e-15 m in 400 steps (and ~1e-12 m in 1200: chaotic, not a different model).
    assert np.abs(a.positions - serial.positions).max() < 1e-13


def test_thread_counts_outside_the_range_are_refused(tmp_path, capsys):
    limit = numba.config.NUMBA_NUM_THREADS
    with pytest.raises(ValueError, match=f"allowed 1 to {limit}"):
        Simulation(Case(), threads=0)
    out = tmp_path / "x.nc"
    assert cli_main(["run", "config/cases/horizontal.yaml", "--out", str(out), "--threads", str(limit + 1)]) == 2
    assert f"--threads: threads = {limit + 1}: allowed 1 to {limit}" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("rolling", [0.0, 0.1])
def test_contact_passes_equal_the_single_loop_at_the_feed(rolling):
    """The feed's grains (kinematic, their pairs counted apart in diag[1]), the inlet wall, and the
    optional contact terms (rolling resistance), which the standard packing has none of."""
    sim = Simulation(Case().with_overrides(["gas.enabled=false", f"particles.rolling_resistance={rolling}"]))
    sim.advance(0.1)
    n, d, r = int(sim._n[0]), 2 * sim.model.radius, sim.model.radius
    feed = sim._pos[:n][sim._in_feed[:n] == 1]
    front = feed[np.argmax(feed[:, 0])]
    # a tube grain pressed on the feed's front grain, one against the inlet wall
    sim.add_particles([front + [0.98 * d, 0.0, 0.0], [0.8 * r, 0.0, 0.0]], angular_velocities=[[0, 50, 0], [30, 0, 0]])
    sim._prepare()
    single, passes = _forces(sim, 1), _forces(sim, 1, passes=True)
    _assert_passes_equal_the_single_loop(sim, single, passes)
    assert single[4][1] > 0, "a feed grain touches a tube grain"
    assert single[4][0] >= 0.2 * r, "the inlet's overlap"
    np.testing.assert_allclose(passes[4][:2], single[4][:2], rtol=1e-12)

"""Contact forces on threads: the chunked sum equals the serial one up to rounding, runs stay
reproducible, bad thread counts are refused (momentum across chunk borders: test_grains.py).
The one-thread contact passes equal the single loop up to rounding."""

import numba
import numpy as np
import pytest

from engine import Case, Simulation
from engine.bench import settled_simulation
from engine.cli import main as cli_main
from engine.kernels.contacts import contact_forces, contact_forces_chunked, pair_buffers
from engine.kernels.state import Chunks

TWO_THREADS = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 numba threads")


@pytest.fixture(scope="module")
def packing():
    """The benchmark's settled dense packing (3066 grains, ~3.5 contacts per grain)."""
    return settled_simulation()


def _forces(sim, nchunks, pairs=None):
    n, cap = sim.n_particles, len(sim._pos)
    force, torque, wall, diag = np.zeros((cap, 3)), np.zeros((cap, 3)), np.zeros(cap), np.zeros(3)
    damping = np.zeros(cap)  # the sum of gamma_t of each grain's viscous contacts (numerics.implicit_spin)
    p = sim._p._replace(implicit_spin=1.0)  # so that the viscous damping is summed
    grains = sim._grains()._replace(force=force, torque=torque, viscous_damping=damping, wall_normal=wall)
    args = (grains, n, sim._nbr_start, sim._nbr, p, diag)
    if nchunks == 1:
        contact_forces(*args, pair_buffers(0) if pairs is None else pairs)
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


@pytest.mark.parametrize("block", [64, 512])
def test_contact_passes_equal_the_single_loop(packing, block):
    f1, t1, g1, w1, d1, _ = _forces(packing, 1)
    f2, t2, g2, w2, d2, _ = _forces(packing, 1, pair_buffers(block))
    # the same sums in the same order; only LLVM's fused multiply-adds in the vectorised law differ
    np.testing.assert_allclose(f2, f1, rtol=0, atol=1e-12 * np.abs(f1).max())
    np.testing.assert_allclose(t2, t1, rtol=0, atol=1e-12 * np.abs(t1).max())
    np.testing.assert_allclose(g2, g1, rtol=1e-14)
    np.testing.assert_allclose(w2, w1, rtol=1e-12, atol=1e-12 * np.abs(w1).max())
    np.testing.assert_array_equal(d2[:2], d1[:2])  # the overlap guard sees the same overlaps


def test_run_with_contact_passes_follows_the_single_loop():
    passes, single = settled_simulation(), settled_simulation()
    passes.set_contact_passes(True)
    for sim in (passes, single):
        sim.advance(400 * sim.dt)
    assert np.abs(passes.positions - single.positions).max() < 1e-13


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

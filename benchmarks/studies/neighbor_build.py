#!/usr/bin/env python
"""The neighbour-list build against its grain-by-grain form, interleaved in one process.

    python benchmarks/studies/neighbor_build.py [CASE.yaml --initial-state CASE_FILE.nc] \\
        [--calls 100] [--rounds 11] [--json OUT.json]

The engine builds the half list cell by cell: a cell's grains share the at most five contiguous
grain ranges of its half stencil, and every candidate is written with the next slot taken only if
it is kept (engine/kernels/neighbors.py). `grain_by_grain` below is the form before: each grain
finds its cell and walks the 14 cells of its stencil one by one, branching on each test. Both are
called on the same sorted grains (the standard dense packing of `plugsim bench`, or CASE.yaml
started from the grains at the end of CASE_FILE.nc and advanced 5 ms, then re-sorted), --calls
times per round in turn. Reported: whether the two lists are identical (entries, each entry's
grain and their order), µs per build of each (medians over the rounds) and their per-round ratio,
then the case advanced 2 ms seven times: µs per step, steps per rebuild, and the share of a step
the build takes.

    python benchmarks/studies/neighbor_build.py config/cases/vertical.yaml \\
        --initial-state results/cases/v_default/base.nc
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numba as nb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from engine import Case, Simulation  # noqa: E402
from engine.bench import settled_simulation  # noqa: E402
from engine.kernels import indices  # noqa: E402
from engine.kernels.neighbors import _cell_index, build_neighbor_list  # noqa: E402
from engine.run import read_initial_state  # noqa: E402

SETTLE = 0.005  # s advanced from the initial state before timing


@nb.njit  # not cached: the tests import this file under another module name than a run does
def grain_by_grain(pos, in_feed, n, p, shape, cell_start, nbr_start, nbr, nbr_i):
    """The build before: per grain its cell, the 14 cells of its half stencil, a branch per test
    (each entry's grain written to nbr_i as well, as the engine's build does)."""
    cut = 2.0 * p.radius + p.skin
    cut2 = cut * cut
    ncx = shape[indices.NCX]
    ncy = shape[indices.NCY]
    ncz = shape[indices.NCZ]
    cap = nbr.shape[0]
    k = 0
    for i in range(n):
        nbr_start[i] = k
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        cx, cy, cz = _cell_index(xi, yi, zi, p, shape)
        for ax in range(cx, min(cx + 2, ncx)):
            for ay in range(cy if ax == cx else max(cy - 1, 0), min(cy + 2, ncy)):
                for az in range(cz if ax == cx and ay == cy else max(cz - 1, 0), min(cz + 2, ncz)):
                    c = (ax * ncy + ay) * ncz + az
                    for j in range(max(cell_start[c], i + 1), cell_start[c + 1]):
                        if in_feed[i] and in_feed[j]:
                            continue
                        dx = pos[j, 0] - xi
                        dy = pos[j, 1] - yi
                        dz = pos[j, 2] - zi
                        if dx * dx + dy * dy + dz * dz < cut2:
                            if k >= cap:
                                return -1
                            nbr[k] = j
                            nbr_i[k] = i
                            k += 1
    nbr_start[n] = k
    return k


def prepare(case_file: str | None, initial_state: str | None) -> Simulation:
    """The simulation to time, its grains freshly sorted (the state a build starts from)."""
    if case_file is None:
        sim = settled_simulation()
    else:
        case = Case.from_yaml(case_file)
        sim = Simulation(case)
        sim.add_particles(*read_initial_state(initial_state, case))
        sim.advance(SETTLE)
    sim._rebuild()
    return sim


def lists_of(build, sim: Simulation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(nbr_start, nbr, nbr_i) that `build` makes of the simulation's sorted grains."""
    n = int(sim._n[0])  # the feed's grains included
    start, nbr, nbr_i = np.zeros_like(sim._nbr_start), np.zeros_like(sim._nbr), np.zeros_like(sim._nbr_i)
    k = build(sim._pos, sim._in_feed, n, sim._p, sim._shape, sim._cell_start, start, nbr, nbr_i)
    assert k >= 0, "the list buffer is too small"
    return start[:n + 1], nbr[:k], nbr_i[:k]


def time_builds(sim: Simulation, calls: int, rounds: int) -> dict:
    """µs per build of the engine's and the grain-by-grain form, interleaved rounds."""
    start, nbr, nbr_i = np.zeros_like(sim._nbr_start), np.zeros_like(sim._nbr), np.zeros_like(sim._nbr_i)
    args = (sim._pos, sim._in_feed, int(sim._n[0]), sim._p, sim._shape, sim._cell_start, start, nbr, nbr_i)
    times = {"engine": [], "grain_by_grain": []}
    for _ in range(rounds):
        for name, build in (("engine", build_neighbor_list), ("grain_by_grain", grain_by_grain)):
            begin = time.perf_counter()
            for _ in range(calls):
                build(*args)
            times[name].append(1e6 * (time.perf_counter() - begin) / calls)
    return {"engine_us": float(np.median(times["engine"])),
            "grain_by_grain_us": float(np.median(times["grain_by_grain"])),
            "speedup": float(np.median(np.divide(times["grain_by_grain"], times["engine"])))}


def step_share(sim: Simulation, pieces: int = 7, piece: float = 0.002) -> dict:
    """µs per step of the case itself and its mean steps between rebuilds."""
    per_step, interval = [], []
    for _ in range(pieces):
        before = sim._counters.copy()
        begin = time.perf_counter()
        sim.advance(piece)
        done = sim._counters - before
        per_step.append(1e6 * (time.perf_counter() - begin) / done[indices.STEPS])
        interval.append(done[indices.STEPS] / max(done[indices.REBUILDS], 1))
    return {"step_us": float(np.median(per_step)), "steps_per_rebuild": float(np.mean(interval))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("case", nargs="?", help="case YAML (default: the standard dense packing)")
    parser.add_argument("--initial-state", help="case file whose final grains start the case (with CASE)")
    parser.add_argument("--calls", type=int, default=100, help="builds per round (100)")
    parser.add_argument("--rounds", type=int, default=11, help="interleaved rounds (11); medians reported")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args(argv)
    if (args.case is None) != (args.initial_state is None):
        parser.error("CASE and --initial-state go together")
    if args.calls < 1 or args.rounds < 1:
        parser.error("--calls and --rounds must be >= 1")
    sim = prepare(args.case, args.initial_state)
    engine, before = lists_of(build_neighbor_list, sim), lists_of(grain_by_grain, sim)
    identical = all(np.array_equal(a, b) for a, b in zip(engine, before))
    row = {"grains": int(sim._n[0]), "list_entries": int(engine[1].size), "identical": identical,
           **time_builds(sim, args.calls, args.rounds)}
    row.update(step_share(sim))
    row["build_share_of_step"] = row["engine_us"] / row["steps_per_rebuild"] / row["step_us"]
    print(f"{row['grains']} grains, {row['list_entries']} list entries; lists identical: {identical}")
    print(f"build: engine {row['engine_us']:.0f} us, grain by grain {row['grain_by_grain_us']:.0f} us, "
          f"{row['speedup']:.2f}x (median of per-round ratios)")
    print(f"step {row['step_us']:.1f} us, a rebuild every {row['steps_per_rebuild']:.1f} steps: the build "
          f"{row['engine_us'] / row['steps_per_rebuild']:.1f} us per step ({100 * row['build_share_of_step']:.1f} %), "
          f"grain by grain {row['grain_by_grain_us'] / row['steps_per_rebuild']:.1f} us")
    if args.json:
        Path(args.json).write_text(json.dumps(row, indent=1))
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python
"""Cost of a real case in steady flow, for variants of its numerical settings, measured interleaved.

    python benchmarks/studies/case_cost.py CASE.yaml --initial-state CASE_FILE.nc \\
        [--variant "numerics.neighbor_skin=0.15" --variant "numerics.neighbor_skin=0.3" ...] \\
        [--chunk 0.01] [--rounds 8] [--json OUT.json]

Each variant is the case with its `--variant` overrides (space-separated key=value; none: the case
as it is), started from the grains at the end of the case file CASE_FILE.nc (a warm start, so the
tube is in steady flow rather than filling) and advanced 5 ms to settle. The variants are then
advanced by `--chunk` simulated seconds in turn, `--rounds` times (interleaved in one process, so
that a load change hits every variant alike). A variant may set `threads=N` (not a case key: the
contact forces on N threads; time threaded variants one per process: interleaved with a one-thread
variant they lose most of their gain, docs/performance.md "Threads") and `passes=0` (not a case key
either: the one-thread contact forces in the single loop instead of in passes, the default, which
`passes=1` keeps; Simulation.set_contact_passes). Reported per variant: the
median CPU seconds of the process per simulated second (all threads; one thread: what an idle core
takes as wall time) and the median wall seconds, each with its median per-round ratio to the first
variant, the mean number of steps between neighbour-list rebuilds and the list entries per grain.
The gas, the feed and the outlet are on, as in the case itself.

The default cases from their own 30 s states (docs/performance.md):

    python benchmarks/studies/case_cost.py config/cases/vertical.yaml \\
        --initial-state results/cases/v_default/base.nc
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from engine import Case, Simulation  # noqa: E402
from engine.kernels import indices  # noqa: E402
from engine.run import read_initial_state  # noqa: E402

SETTLE = 0.005  # s advanced before timing: compiles the kernels and lets the warm start settle


def prepare(case_file: str, initial_state: str, variant: str) -> Simulation:
    """The case with the variant's overrides (`threads=N`: N threads for the contact forces,
    `passes=0`: the one-thread contact forces in the single loop, `passes=1`: in passes, the
    default), started from the grains of `initial_state`."""
    tokens = variant.split()
    engine = {name: [int(t.split("=", 1)[1]) for t in tokens if t.startswith(f"{name}=")]
              for name in ("threads", "passes")}
    case = Case.from_yaml(case_file, [t for t in tokens if t.split("=", 1)[0] not in engine])
    sim = Simulation(case, engine["threads"][-1] if engine["threads"] else 1)
    if engine["passes"]:  # else the engine's default (the passes)
        sim.set_contact_passes(bool(engine["passes"][-1]))
    sim.add_particles(*read_initial_state(initial_state, case))
    sim.advance(SETTLE)
    return sim


def measure(sims: list[Simulation], chunk: float, rounds: int) -> list[dict]:
    """Interleaved timing: per simulation the CPU s per simulated s and rebuild interval of each round."""
    cost = [[] for _ in sims]
    wall = [[] for _ in sims]
    interval = [[] for _ in sims]
    for _ in range(rounds):
        for k, sim in enumerate(sims):
            before = sim._counters.copy()
            start, cpu = time.perf_counter(), time.process_time()
            sim.advance(chunk)
            cost[k].append((time.process_time() - cpu) / chunk)
            wall[k].append((time.perf_counter() - start) / chunk)
            done = sim._counters - before
            interval[k].append(done[indices.STEPS] / max(done[indices.REBUILDS], 1))
    rows = []
    for k, sim in enumerate(sims):
        n = sim.n_particles
        rows.append({"cpu_s_per_simulated_s": float(np.median(cost[k])),
                     "wall_s_per_simulated_s": float(np.median(wall[k])),
                     "cost_ratio_to_first": float(np.median(np.divide(cost[k], cost[0]))),
                     "wall_ratio_to_first": float(np.median(np.divide(wall[k], wall[0]))),
                     "steps_per_rebuild": float(np.mean(interval[k])),
                     "list_entries_per_grain": float(sim._nbr_start[int(sim._n[0])]) / max(n, 1),
                     "grains": n, "cpu_s_all": cost[k], "wall_s_all": wall[k]})
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("case", help="case YAML (e.g. config/cases/vertical.yaml)")
    parser.add_argument("--initial-state", required=True, help="case file whose final grains start the runs")
    parser.add_argument("--variant", action="append", default=None,
                        help='overrides "key=value key=value" of one variant (repeatable; default: the case)')
    parser.add_argument("--chunk", type=float, default=0.01, help="simulated seconds per timed piece (0.01)")
    parser.add_argument("--rounds", type=int, default=8, help="timed pieces per variant (8); the median is reported")
    parser.add_argument("--json", help="also write the rows to this JSON file")
    args = parser.parse_args(argv)
    if args.chunk <= 0 or args.rounds < 1:
        parser.error("--chunk must be > 0 s and --rounds >= 1")
    variants = args.variant or [""]
    sims = [prepare(args.case, args.initial_state, v) for v in variants]
    rows = measure(sims, args.chunk, args.rounds)
    print(f"{Path(args.case).name} from {args.initial_state}: {args.rounds} interleaved pieces of "
          f"{args.chunk} s per variant; CPU time of the process (all threads) and wall time")
    print(f"{'variant':40s} {'CPU s/sim s':>11s} {'ratio':>6s} {'wall s/sim s':>12s} {'ratio':>6s} "
          f"{'steps/rebuild':>13s} {'entries/grain':>13s} {'grains':>6s}")
    for variant, row in zip(variants, rows):
        row["variant"] = variant
        print(f"{variant or '(case as is)':40s} {row['cpu_s_per_simulated_s']:11.1f} {row['cost_ratio_to_first']:6.3f} "
              f"{row['wall_s_per_simulated_s']:12.1f} {row['wall_ratio_to_first']:6.3f} "
              f"{row['steps_per_rebuild']:13.1f} {row['list_entries_per_grain']:13.2f} {row['grains']:6d}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

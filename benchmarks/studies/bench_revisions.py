#!/usr/bin/env python
"""`plugsim bench` of git revisions against each other, in alternating processes (one noisy machine).

    python benchmarks/studies/bench_revisions.py REV [REV ...] [--rounds 5] [--steps 2000] [--json OUT]

Each revision (a branch, tag or commit; `WORKTREE` for the files of this checkout as they are,
uncommitted changes included) is exported into a temporary directory with its own numba cache and
warmed up once (compiling its kernels, up to two minutes each). Then every round runs one process
per revision in turn, each settling the standard dense case (engine.bench) and reporting:
particle-steps per second over --steps steps, ns per touching contact of a whole step (grain pairs
plus wall contacts), and the contact forces alone (evaluate_contacts, --steps // 4 calls on the
settled state, in the revision's default one-thread kernel: the single loop before the contact
passes became the default, the passes since), µs per call and ns per contact. The probe reads the
revision's signature of evaluate_contacts off its Simulation (each list entry's grain `_nbr_i`
and the one-thread work arrays `_pairs` are passed only where the revision has them). Printed:
medians over the rounds, and the median of the per-round ratios to the first revision (the figure
that carries over between machines).
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

# Runs inside each exported revision (whatever its kernels' signatures): the whole-step rate as
# `plugsim bench` measures it, then the contact forces alone.
PROBE = r"""
import json, sys, time
import numpy as np
from engine.bench import settled_simulation, measure_rate
from engine.kernels.contacts import evaluate_contacts
steps = int(sys.argv[1])
sim = settled_simulation()
rate = measure_rate(sim, steps, 1)[0]
n, d, r = sim.n_particles, 2 * sim.model.radius, sim.model.radius
pos, start, dynamic = sim._pos[:n], sim._nbr_start[:n + 1], sim._in_feed[:n] == 0
off = pos[sim._nbr[:start[n]]] - pos[np.repeat(np.arange(n), np.diff(start))]
pairs = int(np.count_nonzero(np.einsum("ij,ij->i", off, off) < d * d))
inner = sim.case["tube.diameter"] / 2 - r
walls = int(np.count_nonzero(dynamic & (pos[:, 1] ** 2 + pos[:, 2] ** 2 > inner * inner)))
walls += int(np.count_nonzero(dynamic & (pos[:, 0] < r)))
# evaluate_contacts(grains, n, nbr_start, nbr, [nbr_i,] p, diag, chunks[, pairs]): each list entry's
# grain (nbr_i) and the one-thread work arrays (pairs) only in the revisions that have them
args = (sim._grains(), n, sim._nbr_start, sim._nbr)
if hasattr(sim, "_nbr_i"):
    args += (sim._nbr_i,)
args += (sim._p, sim._diag.copy(), sim._chunks)
if hasattr(sim, "_pairs"):
    args += (sim._pairs,)
evaluate_contacts(*args)
calls = max(1, steps // 4)
times = []
for _ in range(5):
    t = time.perf_counter()
    for _ in range(calls):
        evaluate_contacts(*args)
    times.append((time.perf_counter() - t) / calls)
kernel = sorted(times)[2]
contacts = pairs + walls
print(json.dumps({"grains": n, "pairs": pairs, "walls": walls, "rate": rate,
                  "ns_per_contact": 1e9 * n / rate / contacts, "kernel_us": kernel * 1e6,
                  "kernel_ns_per_contact": kernel * 1e9 / contacts}))
"""


def export(revision: str, into: Path) -> None:
    into.mkdir(parents=True)
    if revision == "WORKTREE":
        files = subprocess.run(["git", "-C", str(REPO), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                               capture_output=True, check=True).stdout.split(b"\0")
        for name in filter(None, files):
            source = REPO / name.decode()
            if source.is_file():
                (into / name.decode()).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(source, into / name.decode())
        return
    archive = subprocess.run(["git", "-C", str(REPO), "archive", revision], capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)


def probe(tree: Path, steps: int) -> dict:
    env = {"PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    import os
    env = dict(os.environ, **env)
    out = subprocess.run([sys.executable, "-c", PROBE, str(steps)], cwd=tree, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"bench_revisions: {tree.name} failed: {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("revisions", nargs="+", help="git revisions, or WORKTREE")
    parser.add_argument("--rounds", type=int, default=5, help="processes per revision (5); medians reported")
    parser.add_argument("--steps", type=int, default=2000, help="timed steps per process (2000)")
    parser.add_argument("--json", help="also write every round's numbers to this JSON file")
    args = parser.parse_args(argv)
    if args.rounds < 1 or args.steps < 1:
        parser.error("--rounds and --steps must be >= 1")
    with tempfile.TemporaryDirectory(prefix="plugsim-revisions-") as tmp:
        trees = []
        for k, revision in enumerate(args.revisions):
            tree = Path(tmp) / f"{k}"
            export(revision, tree)
            probe(tree, 10)  # compiles into the tree's own numba cache
            trees.append(tree)
        rows = [[] for _ in trees]
        for _ in range(args.rounds):
            for k, tree in enumerate(trees):
                rows[k].append(probe(tree, args.steps))
    first = rows[0]
    print(f"standard dense case, {args.rounds} alternating processes per revision, {args.steps} steps each; "
          f"medians (ratio: median of the per-round ratios to {args.revisions[0]})")
    print(f"{'revision':24s} {'particle-steps/s':>16s} {'ratio':>6s} {'ns/contact':>10s} {'forces us':>9s} "
          f"{'ns/contact':>10s} {'ratio':>6s} {'pairs+walls':>11s}")
    summary = []
    for revision, row in zip(args.revisions, rows):
        med = {key: statistics.median(r[key] for r in row) for key in ("rate", "ns_per_contact", "kernel_us",
                                                                      "kernel_ns_per_contact")}
        ratio = statistics.median(r["rate"] / f["rate"] for r, f in zip(row, first))
        kratio = statistics.median(f["kernel_us"] / r["kernel_us"] for r, f in zip(row, first))
        print(f"{revision:24s} {med['rate']:16.3e} {ratio:6.3f} {med['ns_per_contact']:10.1f} {med['kernel_us']:9.1f} "
              f"{med['kernel_ns_per_contact']:10.1f} {kratio:6.3f} {row[-1]['pairs']:>5d}+{row[-1]['walls']:<5d}")
        summary.append({"revision": revision, "medians": med, "speed_ratio": ratio, "forces_speed_ratio": kratio,
                        "rounds": row})
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

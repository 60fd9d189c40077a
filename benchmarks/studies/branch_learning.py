#!/usr/bin/env python
"""Whether this machine's core learns a repeated sequence of branch outcomes: a loop over random
numbers with one data-dependent branch, called again and again on the same data and on data of
which a fraction is redrawn before each call.

    python benchmarks/studies/branch_learning.py [--elements 9000] [--calls 30] [--rounds 9]

The loop takes one of two short arithmetic branches per element (below or above 0.45, so about
half each, at random). Each round calls it --calls times per fraction redrawn (0, 0.1, 1, 5, 20 and
100 % of the elements drawn anew before every call), the fractions in turn; reported are ns per
element (medians over the rounds), and the same loop over sorted data (one switch of branch: every
outcome predictable) for reference.

A kernel timed by calling it repeatedly on one state sees its branch outcomes repeat exactly; in a
run they change a little from step to step. This study measures what that difference can be worth
on the machine (docs/decisions/0040-step-budget-on-moving-grains.md).
"""

from __future__ import annotations

import argparse
import sys
import time

import numba as nb
import numpy as np

FRACTIONS = (0.0, 0.001, 0.01, 0.05, 0.2, 1.0)
THRESHOLD = 0.45


@nb.njit  # not cached: the tests import this file under another module name than a run does
def branchy_sum(x, threshold):
    """Sum over x of 1.0001 x + 0.5 where x < threshold and of -0.9999 x elsewhere, one branch per
    element."""
    s = 0.0
    for i in range(x.shape[0]):
        if x[i] < threshold:
            s += x[i] * 1.0001 + 0.5
        else:
            s -= x[i] * 0.9999
    return s


def measure(elements: int, calls: int, rounds: int, seed: int = 0) -> dict:
    """ns per element of branchy_sum for each fraction redrawn before each call, and on sorted data
    ("sorted"): medians over the rounds."""
    rng = np.random.default_rng(seed)
    base = rng.random(elements)
    data = {fraction: base.copy() for fraction in FRACTIONS}
    data["sorted"] = np.sort(base)
    branchy_sum(base, THRESHOLD)  # compiles
    times = {name: [] for name in data}
    for _ in range(rounds):
        for name, x in data.items():
            total = 0.0
            for _ in range(calls):
                if name != "sorted" and name > 0.0:
                    redraw = rng.integers(0, elements, int(round(name * elements)))
                    x[redraw] = rng.random(redraw.size)
                begin = time.perf_counter()
                branchy_sum(x, THRESHOLD)
                total += time.perf_counter() - begin
            times[name].append(1e9 * total / calls / elements)
    return {name: float(np.median(t)) for name, t in times.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--elements", type=int, default=9000, help="elements per call (9000)")
    parser.add_argument("--calls", type=int, default=30, help="calls per fraction and round (30)")
    parser.add_argument("--rounds", type=int, default=9, help="interleaved rounds (9); medians reported")
    args = parser.parse_args(argv)
    if args.elements < 1 or args.calls < 1 or args.rounds < 1:
        parser.error("--elements, --calls and --rounds must be >= 1")
    result = measure(args.elements, args.calls, args.rounds)
    print(f"{args.elements} random elements, one data-dependent branch each; ns per element")
    for name, ns in result.items():
        label = "sorted data" if name == "sorted" else f"{100 * name:g} % redrawn before each call"
        print(f"  {label:34s} {ns:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

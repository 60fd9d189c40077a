#!/usr/bin/env python
"""Instructions per contact of the single contact loop and of its ablation variants, counted by
valgrind, and the instructions per cycle they run at.

    python benchmarks/studies/contact_instructions.py [--variants engine normal_only ...] \
        [--calls 300] [--json OUT.json]

The loop is contacts._contacts_range_with without the optional terms (the loop of each chunk on
threads, and on one thread with Simulation.set_contact_passes(False); not the one-thread default,
the contact passes of engine/kernels/passes.py), with its laws (laws.pair_normal,
laws.surface_forces, laws.cylinder_contact, laws.wall_contact) from a copy of laws.py.
On the settled standard packing of `plugsim bench` (as contact_ablation.py), each variant of
contact_ablation.py is written to a module in a temporary directory, compiled once natively (numba
caches it there), then its process runs under `valgrind --tool=cachegrind` twice, with 1 and with
1 + --calls calls of the loop: the difference of the two instruction counts is the loop's, free of
the start-up (Python, numpy, numba, the cache load), with PYTHONHASHSEED=0 and one OpenBLAS
thread (its idle threads spin, and valgrind counts the spinning: 60 instructions per contact).
valgrind's virtual CPU reports other features (and another name) than the host's, and numba keys
its cache by them: every run here compiles for the host's CPU name with the features valgrind
reports (NUMBA_CPU_NAME, NUMBA_CPU_FEATURES), so that the runs under valgrind load the code timed
natively instead of compiling their own (the features valgrind lacks, such as adx, sha or vaes, are
not ones this loop's code uses). The same variant timed natively (median of 7 rounds of 300
calls, CPU time) and the core's clock (a dependent chain of an integer multiply and an add, 4
cycles on AMD Zen and Intel cores since Skylake) give its cycles per call and so its instructions
per cycle. Needs valgrind on PATH.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

REFS = re.compile(r"I\s+refs:\s+([\d,]+)")
HEADER = ("import math\nimport numba as nb\nimport numpy as np\nimport ablation_laws as laws\n"
          "from engine.kernels.laws import FASTMATH\n\n")

# the calls from compiled code (no dispatch per call), cached like the loop
CALLER = """
loop = _contacts_range_with(False)


@nb.njit(cache=True)
def run(calls, grains, n, nbr_start, nbr, p, force, torque, damping, counts):
    for _ in range(calls):
        loop(0, n, grains, nbr_start, nbr, p, force, torque, damping, counts)
"""


def write_variant(directory: Path, name: str) -> Path:
    """contact_ablation's variant `name` as the modules ablation_laws.py and ablation_loop.py
    (cached compilation) in directory/name; returns that directory."""
    import contact_ablation

    law_source, loop_source = contact_ablation.sources(name)
    where = directory / name
    where.mkdir(parents=True, exist_ok=True)
    (where / "ablation_laws.py").write_text(law_source)
    (where / "ablation_loop.py").write_text(HEADER + loop_source + CALLER)
    return where


def save_state(path: Path) -> dict:
    """The settled standard packing's loop arguments, pickled to `path`; returns its contact counts."""
    from engine.bench import contact_count, settled_simulation

    sim = settled_simulation()
    state = {"grains": tuple(a.copy() for a in sim._grains()), "n": sim.n_particles,
             "nbr_start": sim._nbr_start.copy(), "nbr": sim._nbr.copy(), "p": tuple(sim._p),
             "counted": contact_count(sim)}
    path.write_bytes(pickle.dumps(state))
    return state["counted"]


def worker(variant: Path, state_path: Path, calls: int, rounds: int) -> None:
    """Call the variant's loop once, then `rounds` times `calls` calls; prints the CPU seconds per
    call of each round (one line of JSON)."""
    sys.path.insert(0, str(variant))
    from ablation_loop import run

    from engine.kernels.state import Grains
    from engine.parameters import GrainParameters

    state = pickle.loads(state_path.read_bytes())
    grains = Grains(*state["grains"])
    arguments = (grains, state["n"], state["nbr_start"], state["nbr"], GrainParameters(*state["p"]),
                 grains.force, grains.torque, grains.viscous_damping, state["nbr_start"][:0])
    run(1, *arguments)
    times = []
    for _ in range(rounds):
        start = time.process_time()
        run(calls, *arguments)
        times.append((time.process_time() - start) / max(calls, 1))
    print(json.dumps(times))


def _run(command: list[str], env: dict) -> subprocess.CompletedProcess:
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command[:4])}...: failed\n{done.stderr[-2000:]}")
    return done


def instructions(variant: Path, state_path: Path, calls: int, env: dict) -> float:
    """Instructions of one call of the variant's loop (valgrind; two runs differing by `calls`)."""
    counts = []
    for n in (0, calls):
        command = ["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
                   sys.executable, __file__, "--worker", str(variant), str(state_path), str(n), "1"]
        counts.append(int(REFS.search(_run(command, env).stderr).group(1).replace(",", "")))
    if counts[1] <= counts[0]:  # the first run compiled: its cache key was not the native run's
        raise SystemExit(f"{variant.name}: the run under valgrind did not load the natively compiled loop")
    return (counts[1] - counts[0]) / calls


def cpu_target(env: dict) -> dict:
    """NUMBA_CPU_NAME (the host's) and NUMBA_CPU_FEATURES (those valgrind's CPU reports)."""
    probe = ("import llvmlite.binding as ll; ll.initialize_native_target(); "
             "print(ll.get_host_cpu_name()); print(ll.get_host_cpu_features().flatten())")
    name = _run([sys.executable, "-c", probe], env).stdout.split()[0]
    features = _run(["valgrind", "-q", sys.executable, "-c", probe], env).stdout.split()[1]
    return {"NUMBA_CPU_NAME": name, "NUMBA_CPU_FEATURES": features}


def clock_hz(chain: int = 200_000_000) -> float:
    """The core's clock (Hz) from a dependent multiply-add chain of 4 cycles per link (median of 5)."""
    import numba as nb
    import numpy as np

    @nb.njit
    def links(n, x):
        for _ in range(n):
            x = x * x + np.uint64(1442695040888963407)  # squares: no jump-ahead folds the chain
        return x

    links(10, np.uint64(3))
    seconds = []
    for _ in range(5):
        start = time.perf_counter()
        links(chain, np.uint64(3))
        seconds.append(time.perf_counter() - start)
    return 4 * chain / statistics.median(seconds)


def main(argv=None) -> int:
    import contact_ablation

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variants", nargs="+", default=["engine", "distance_only", "no_walls", "normal_only",
                                                          "root_both_branches", "single_law"],
                        help="contact_ablation.py variants (default: the engine and five variants)")
    parser.add_argument("--calls", type=int, default=300, help="calls counted under valgrind (default 300)")
    parser.add_argument("--json", type=Path, help="write the figures here")
    parser.add_argument("--worker", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        variant, state_path, calls, rounds = args.worker
        worker(Path(variant), Path(state_path), int(calls), int(rounds))
        return 0
    unknown = [v for v in args.variants if v != "engine" and v not in contact_ablation.VARIANTS]
    if unknown:
        parser.error(f"--variants: unknown {', '.join(unknown)}; known: engine, {', '.join(contact_ablation.VARIANTS)}")
    if args.calls < 1:
        parser.error("--calls must be at least 1")
    if shutil.which("valgrind") is None:
        raise SystemExit("valgrind is not on PATH: install it (Debian: apt-get install valgrind)")

    # one thread everywhere: OpenBLAS's idle worker threads spin, and valgrind counts their spinning
    env = {**os.environ, "PYTHONHASHSEED": "0", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1", "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    env.update(cpu_target(env))
    hz = clock_hz()
    out = {"clock_GHz": hz / 1e9, "variants": {}}
    with tempfile.TemporaryDirectory() as tmp:
        state_path = Path(tmp) / "state.pkl"
        counted = save_state(state_path)
        touching = counted["pairs"] + counted["walls"]
        out["contacts"] = counted
        print(f"standard packing: {counted['pairs']} touching pairs, {counted['walls']} wall contacts, "
              f"{counted['list_entries']} list entries; clock {hz / 1e9:.2f} GHz")
        for name in args.variants:
            variant = write_variant(Path(tmp), name)
            seconds = statistics.median(json.loads(_run([sys.executable, __file__, "--worker", str(variant),
                                                         str(state_path), "300", "7"], env).stdout))
            count = instructions(variant, state_path, args.calls, env)
            cycles = seconds * hz
            row = {"instructions_per_call": count, "instructions_per_contact": count / touching,
                   "us_per_call": 1e6 * seconds, "cycles_per_contact": cycles / touching,
                   "instructions_per_cycle": count / cycles}
            out["variants"][name] = row
            print(f"  {name:15s} {count / touching:6.0f} instructions/contact  {row['cycles_per_contact']:5.0f} "
                  f"cycles/contact  {row['instructions_per_cycle']:.2f} per cycle  ({row['us_per_call']:.0f} us/call)")
    if args.json:
        args.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

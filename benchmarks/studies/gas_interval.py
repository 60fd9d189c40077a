"""Gas update policy: error of the pressure drop against wall time for gas updates every k grain steps.

The standard dense packing (engine.bench: 6 cm plug + bed, ~3070 grains) in the default horizontal
tube with the gas on (v_s = 1 m/s, feed off) is pushed for 0.15 s from the same start for each k;
the pressure drop is sampled every millisecond. Reported: mean pressure drop over the last 0.1 s,
its largest deviation from k = 1 over the whole record, and the wall time relative to k = 1. The row
"1*" repeats k = 1 from positions perturbed by 1 nm: grain packings are chaotic, so this is the
noise floor below which a difference between policies means nothing.

    python benchmarks/studies/gas_interval.py [--intervals 1 2 5 10 20] [--seconds 0.15]
"""

import argparse
import time

import numpy as np

from engine import Simulation
from engine.bench import standard_case, standard_packing


def record(interval: int, seconds: float, perturb: float = 0.0) -> tuple[np.ndarray, float]:
    sim = Simulation(standard_case("gas.enabled=true", f"numerics.gas_interval={interval}"))
    packing = standard_packing(sim.case)
    packing[:, 0] += perturb * np.random.default_rng(1).uniform(-1, 1, len(packing))
    sim.add_particles(packing)
    sim.advance(0.001)  # compile outside the timing
    start = time.perf_counter()
    drops = []
    for _ in range(int(round(seconds / 0.001))):
        sim.advance(0.001)
        drops.append(sim.pressure_drop)
    return np.array(drops), time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intervals", type=int, nargs="+", default=[1, 2, 5, 10, 20])
    parser.add_argument("--seconds", type=float, default=0.15)
    args = parser.parse_args()
    results = {str(k): record(k, args.seconds) for k in args.intervals}
    results["1*"] = record(1, args.seconds, perturb=1e-9)
    ref, ref_wall = results[str(args.intervals[0])]
    tail = slice(len(ref) // 3, None)
    print(f"{'k':>4} {'mean dp (Pa)':>13} {'mean err':>9} {'max |err| (Pa)':>15} {'max rel':>8} {'wall (s)':>9} {'speed-up':>9}")
    for k, (drops, wall) in results.items():
        err = drops - ref
        print(f"{k:>4} {drops[tail].mean():13.2f} {drops[tail].mean() / ref[tail].mean() - 1:9.2%} "
              f"{np.abs(err).max():15.3f} {np.abs(err).max() / np.abs(ref).max():8.2%} {wall:9.1f} {ref_wall / wall:9.2f}")


if __name__ == "__main__":
    main()

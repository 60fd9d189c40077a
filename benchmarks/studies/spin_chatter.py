#!/usr/bin/env python
"""Step-to-step chatter of the grain spins in a packed bed, for variants of the time step and gamma_t.

    python benchmarks/studies/spin_chatter.py CASE.yaml --initial-state CASE_FILE.nc \\
        [--variant "numerics.time_step_fraction=0.05" ...] [--steps 120] [--settle 0.003] [--json OUT.json]

The explicit tangential dashpot F_t = -gamma_t v_t relaxes a contact's slip in the time m_slip/gamma_t
(m_slip = m/7 between two spheres: 9.6 us for the default grains). A grain in a packed bed has
several contacts coupled through its spin, so the explicit update can overshoot although one
contact alone would not: the spin increments then reverse from one step to the next (period-2
chatter), bounded only by the Coulomb limit. Each variant is the case with its overrides, started
from the grains at the end of CASE_FILE.nc, advanced `--settle` s, then `--steps` single steps.
Reported per variant: gamma_t dt / m_slip (the dashpot's step ratio between grains) and, for the
spins and the velocities, the fraction of reversed increments (successive increments of one grain
with a negative dot product; a smooth signal sampled s steps per oscillation reverses at most 2/s
of them) and the rms value.

The work-precision study's bulk bed (docs/decisions/0005-packed-bed-dashpot-condition.md):

    python benchmarks/studies/spin_chatter.py config/cases/horizontal.yaml \\
        --initial-state results/cases/wp_bulk_fill/base.nc \\
        --set tube.length=0.2 --set gas.nodes_x=57 --set gas.superficial_velocity=0.15 \\
        --variant "numerics.time_step_fraction=0.15" --variant "numerics.time_step_fraction=0.05"
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from engine import Case, Simulation  # noqa: E402
from engine.run import read_initial_state  # noqa: E402


def reversed_fraction(series: np.ndarray) -> float:
    """Fraction of successive increments (per grain, steps n and n+1) with a negative dot product.

    series: (steps, grains, 3). 0 for a smooth signal resolved by many steps, 1 for a period-2 one.
    """
    inc = np.diff(series, axis=0)
    dots = (inc[1:] * inc[:-1]).sum(-1)
    return float((dots < 0).mean())


def record(sim: Simulation, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Spins (rad/s) and velocities (m/s), (steps, grains, 3), of the grains present at every one of
    `steps` single steps."""
    ids, spins, vels = [], [], []
    for _ in range(steps):
        sim.advance(sim.dt)
        ids.append(sim.ids.copy())
        spins.append(sim.angular_velocities.copy())
        vels.append(sim.velocities.copy())
    common = ids[0]
    for i in ids[1:]:
        common = np.intersect1d(common, i)
    pick = [np.searchsorted(i, common) for i in ids]
    return (np.array([w[k] for w, k in zip(spins, pick)]), np.array([v[k] for v, k in zip(vels, pick)]))


def chatter(case: Case, initial_state: str, settle: float, steps: int) -> dict:
    """The measured row of one variant."""
    sim = Simulation(case)
    sim.add_particles(*read_initial_state(initial_state, case))
    sim.advance(settle)
    spins, vels = record(sim, steps)
    return {"time_step_s": sim.dt, "time_step_fraction": case["numerics.time_step_fraction"],
            "tangential_damping": case["particles.tangential_damping"],
            "dashpot_step_ratio": sim.model.dashpot_step_ratio,
            "grains": int(spins.shape[1]),
            "spin_reversed_fraction": reversed_fraction(spins),
            "spin_rms_rad_s": float(np.sqrt((spins**2).sum(-1).mean())),
            "velocity_reversed_fraction": reversed_fraction(vels),
            "velocity_rms_m_s": float(np.sqrt((vels**2).sum(-1).mean()))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", help="case YAML, e.g. config/cases/horizontal.yaml")
    parser.add_argument("--initial-state", required=True, help="case file whose final grains start each variant")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override for every variant (repeatable)")
    parser.add_argument("--variant", action="append", default=[],
                        help="space-separated KEY=VALUE overrides of one variant (repeatable; none: the case)")
    parser.add_argument("--steps", type=int, default=120, help="single steps recorded (default 120)")
    parser.add_argument("--settle", type=float, default=0.003, help="s advanced before recording (default 0.003)")
    parser.add_argument("--json", help="write the rows to this file")
    args = parser.parse_args(argv)
    if args.steps < 3:
        parser.error(f"--steps = {args.steps}: at least 3 steps are needed for two increments")
    if args.settle < 0:
        parser.error(f"--settle = {args.settle}: must be >= 0 s")
    rows = []
    for variant in args.variant or [""]:
        case = Case.from_yaml(args.case, [*args.set, *variant.split()])
        row = {"variant": variant, **chatter(case, args.initial_state, args.settle, args.steps)}
        rows.append(row)
        print(f"{variant or '(case)':45s} gamma_t dt/m_slip {row['dashpot_step_ratio']:.2f}  spins reversed "
              f"{row['spin_reversed_fraction']:.2f} (rms {row['spin_rms_rad_s']:.0f} rad/s)  velocities reversed "
              f"{row['velocity_reversed_fraction']:.2f}  [{row['grains']} grains]", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

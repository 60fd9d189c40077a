#!/usr/bin/env python
"""Head-on restitution against the time step, over the phase at which a contact starts.

A contact starts and ends between steps, so the restitution of one collision depends on where in a
step the grains first touch (the phase). Two grains (or a grain and the cylinder wall) approach
head-on at 0.1 m/s with gravity, gas and feed off; the initial gap is shifted by
phase x v_rel x dt for evenly spaced phases in [0, 1). Reported per contact, time step (fraction of
the contact time t_c) and configured e: the smallest and largest error of the measured e and the
error averaged over the phases (what a flow of many collisions at random phases sees). A time step
above the stable limit of an e is refused by the engine and kept as a row without numbers.

    python benchmarks/restitution.py [--out-dir results/benchmarks/restitution] [--reduced]
        [--fractions 0.0125 0.025 0.05 0.1 0.15] [--restitutions 0.3 0.5 0.9] [--phases 20]

Prints the table; with --out-dir writes restitution.csv (one row per contact, time step and e),
restitution.md and restitution.png (error against the time step at e = 0.5: mean and range).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from engine import Case, CaseError, Simulation

SPEED = 0.1  # m/s, relative approach speed
DURATION = 0.03  # s: the approach (2.8 ms) plus many contact times (t_c ~ 60 us)
FULL = {"fractions": [0.0125, 0.025, 0.05, 0.1, 0.15], "restitutions": [0.3, 0.5, 0.9], "phases": 20}
REDUCED = {"fractions": [0.05, 0.1], "restitutions": [0.5], "phases": 10}


def case(fraction: float, restitution: float, wall: bool) -> Case:
    """Gravity, gas and feed off; the restitution of the pair (or of the wall) set."""
    key = "wall.restitution" if wall else "particles.restitution"
    return Case().with_overrides(["gas.enabled=false", "feed.mass_flow_kg_h=0", "physics.gravity=0",
                                  f"{key}={restitution}", f"numerics.time_step_fraction={fraction}"])


def measured_restitution(c: Case, phase: float, wall: bool = False) -> float:
    """Restitution of one head-on collision of case `c` whose contact starts at `phase` (0..1) of a
    step (raises CaseError when the engine refuses the case's time step)."""
    sim = Simulation(c)
    d = c["particles.diameter"]
    gap = 0.2 * d + phase * SPEED * sim.dt
    if wall:  # towards the cylinder wall along +z
        sim.add_particles([[0.1, 0.0, c["tube.diameter"] / 2 - d / 2 - gap]], [[0.0, 0.0, SPEED]])
        sim.advance(DURATION)
        return -sim.velocities[0, 2] / SPEED
    half = SPEED / 2
    sim.add_particles([[0.1, 0.0, 0.0], [0.1 + d + gap, 0.0, 0.0]], [[half, 0.0, 0.0], [-half, 0.0, 0.0]])
    sim.advance(DURATION)
    v = sim.velocities
    return (v[1, 0] - v[0, 0]) / SPEED


def table(fractions, restitutions, phases: int, wall: bool = False) -> pd.DataFrame:
    """One row per (time-step fraction, e): error min, max and mean over the phases; a time step the
    engine refuses for this e gives NaN and the reason."""
    rows = []
    for fraction in fractions:
        for e in restitutions:
            row = {"contact": "grain-wall" if wall else "grain-grain", "time_step_fraction": fraction,
                   "restitution": e, "error_min": np.nan, "error_max": np.nan, "error_mean": np.nan,
                   "refused": ""}
            try:
                c = case(fraction, e, wall)
                errors = np.array([measured_restitution(c, ph, wall) - e for ph in np.arange(phases) / phases])
                row.update(error_min=errors.min(), error_max=errors.max(), error_mean=errors.mean())
            except CaseError as err:
                row["refused"] = str(err)
            rows.append(row)
    return pd.DataFrame(rows)


def markdown(result: pd.DataFrame, phases: int) -> str:
    """The table as markdown: error range over the phases and (in brackets) their mean."""
    lines = [f"# Head-on restitution against the time step ({phases} contact-start phases)", "",
             "Measured e minus configured e: range over the phases (mean over them).", "",
             "| contact | Δt/t_c | e | error range | mean error |", "|---|---|---|---|---|"]
    for r in result.itertuples():
        if r.refused:
            lines.append(f"| {r.contact} | {r.time_step_fraction:g} | {r.restitution:g} | refused | |")
        else:
            lines.append(f"| {r.contact} | {r.time_step_fraction:g} | {r.restitution:g} | "
                         f"{r.error_min:+.3f}…{r.error_max:+.3f} | {r.error_mean:+.4f} |")
    return "\n".join(lines) + "\n"


def plot(result: pd.DataFrame, path: Path, restitution: float = 0.5) -> None:
    """Error of e against Δt/t_c at one configured e: phase mean (line) and range (band)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.5))
    for contact, rows in result[(result.restitution == restitution) & (result.refused == "")].groupby("contact"):
        line, = ax.plot(rows.time_step_fraction, rows.error_mean, "o-", label=f"{contact}, mean over phases")
        ax.fill_between(rows.time_step_fraction, rows.error_min, rows.error_max, color=line.get_color(),
                        alpha=0.2, label=f"{contact}, range")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("time step Δt / t_c (1)")
    ax.set_ylabel(f"measured − configured e (1), e = {restitution:g}")
    if ax.get_legend_handles_labels()[0]:  # nothing to draw when every point was refused
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, help="write restitution.{csv,md,png} here")
    parser.add_argument("--reduced", action="store_true", help="the CI subset: 2 time steps, e = 0.5, 10 phases")
    parser.add_argument("--fractions", type=float, nargs="+", help="time steps, fractions of t_c")
    parser.add_argument("--restitutions", type=float, nargs="+", help="configured e")
    parser.add_argument("--phases", type=int, help="contact-start phases per point")
    args = parser.parse_args(argv)
    settings = dict(REDUCED if args.reduced else FULL)
    settings.update({k: v for k, v in (("fractions", args.fractions), ("restitutions", args.restitutions),
                                       ("phases", args.phases)) if v is not None})
    result = pd.concat([table(settings["fractions"], settings["restitutions"], settings["phases"], wall)
                        for wall in (False, True)], ignore_index=True)
    text = markdown(result, settings["phases"])
    print(text)
    if args.out_dir:
        args.out_dir.mkdir(parents=True, exist_ok=True)
        result.to_csv(args.out_dir / "restitution.csv", index=False)
        (args.out_dir / "restitution.md").write_text(text)
        plot(result, args.out_dir / "restitution.png")


if __name__ == "__main__":
    main()

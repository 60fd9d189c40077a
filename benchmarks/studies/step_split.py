#!/usr/bin/env python
"""Where one step of a case goes: each part of the step timed alone, and the step on moving and on
held grains, interleaved.

    python benchmarks/studies/step_split.py [CASE.yaml --initial-state CASE_FILE.nc] \\
        [--calls 50] [--rounds 11] [--json OUT.json]

The case (default: the standard dense packing of `plugsim bench`, gas off) starts from the grains at
the end of CASE_FILE.nc and is advanced 5 ms. Each round advances it 2 ms more (Simulation.advance:
the steps per neighbour rebuild, and a new state for the round), then measures on copies of its
arrays, in µs per step:

- the step: the engine's loop (kick and drift, a rebuild when a grain has moved half the skin,
  the gas on its steps, the contact forces; `stepper` functions, 300 steps), the grains moving;
- the held step: the same loop with the kick and drift by 0 (the same arithmetic, the grains
  stay put) and a rebuild every measured rebuild interval;
- each part alone, called --calls times from compiled code on held copies:
  - kick_drift: the merged kick and drift with the rebuild test (`_kick_drift` by 0), every step;
  - sort and build: the two halves of a rebuild, once per rebuild interval;
  - deposit, fields, sources, solve, gradient, drag: the gas coupling (`gas.couple`'s kernels), once
    per `numerics.gas_interval` steps;
  - contacts: the contact forces (`evaluate_contacts`: the simulation's kernel, on one thread the
    contact passes by default), every step;
- `together`: the held step less the parts' sum (the loop's own work, the parts one after another
  instead of each repeated on warm caches);
- `motion`: the step less the held step: what grains that move cost beyond the same arithmetic on
  a state repeated call after call, which the parts' own timings do not see.

Each round's split adds up to its step; reported are the medians over the rounds (a shared machine
changes speed from one second to the next: the quantities of one round are measured within about
a second), per part with its share of the step and how much faster the step would run if that part
cost nothing (1 / (1 - share)); then how much faster the contact forces would have to run for the
step to cost half, with the rest unchanged.

    python benchmarks/studies/step_split.py config/cases/horizontal.yaml \\
        --initial-state results/cases/h_default/base.nc
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numba as nb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from engine import Case, Simulation  # noqa: E402
from engine.bench import settled_simulation  # noqa: E402
from engine.kernels import gas as gas_kernels, indices, stepper  # noqa: E402
from engine.kernels.contacts import evaluate_contacts  # noqa: E402
from engine.kernels.neighbors import build_neighbor_list, sort_and_compact  # noqa: E402
from engine.kernels.state import Grains, Neighbors  # noqa: E402
from engine.run import read_initial_state  # noqa: E402

SETTLE = 0.005  # s advanced from the initial state before timing
GAS_PARTS = ("deposit", "fields", "sources", "solve", "gradient", "drag")


def prepare(case_file: str | None, initial_state: str | None) -> Simulation:
    """The simulation to split: the standard packing, or the case from the end of initial_state."""
    if case_file is None:
        return settled_simulation()
    case = Case.from_yaml(case_file)
    sim = Simulation(case)
    sim.add_particles(*read_initial_state(initial_state, case))
    sim.advance(SETTLE)
    return sim


def steps_per_rebuild(sim: Simulation, piece: float = 0.002) -> float:
    """Advance the simulation by `piece` s; the steps per neighbour rebuild in it."""
    before = sim._counters.copy()
    sim.advance(piece)
    done = sim._counters - before
    return done[indices.STEPS] / max(done[indices.REBUILDS], 1)


@nb.njit  # not cached: the tests import this file under another module name than a run does
def _loop(steps, grains, n_held, p, kick_p, kick_dt, neighbors, counters, diag, gas, chunks, pairs, every):
    """`steps` steps of the engine's loop (stepper.advance without its opening and closing half kicks),
    the kick and drift by kick_dt with kick_p; a rebuild when the drift asks for one or, with
    every > 0, on every every-th step."""
    n = n_held[0]
    for step in range(steps):
        need = stepper._kick_drift(grains, n, kick_p, kick_dt, counters)
        if need or (every > 0 and step % every == 0):
            n = stepper.rebuild(grains, n, p, neighbors, counters)
        stepper._step_forces(grains, n, p, neighbors, counters, diag, gas, chunks, pairs)


def loop_step(sim: Simulation, held_every: int = 0, steps: int = 300) -> float:
    """µs per step of _loop on copies of the simulation's state: the grains moving (held_every 0)
    or held (kick and drift by 0) with a rebuild every held_every steps."""
    grains = Grains(*[a.copy() for a in sim._grains()])
    neighbors = Neighbors(*[a.copy() for a in sim._neighbors()])
    p = sim._p
    kick_p, kick_dt = (p, p.dt) if held_every == 0 else (p._replace(dt=0.0), 0.0)
    args = (grains, sim._n.copy(), p, kick_p, kick_dt, neighbors, sim._counters.copy(), sim._diag.copy(),
            _gas_copy(sim), sim._chunks, sim._pairs, held_every)
    begin = time.perf_counter()
    _loop(steps, *args)
    return 1e6 * (time.perf_counter() - begin) / steps


def _gas_copy(sim: Simulation):
    """A copy of the simulation's gas arrays (gas.GasArrays)."""
    gas = sim.gas.arrays()
    return type(gas)(*[a.copy() if isinstance(a, np.ndarray) else a for a in gas])


def part_calls(sim: Simulation) -> dict:
    """Each part of a step as (kernel, its arguments), on copies of the simulation's arrays (gas parts
    only with the gas on)."""
    sim._rebuild()  # freshly sorted: the state a rebuild starts from
    n = int(sim._n[0])  # the feed's grains included
    p = sim._p
    grains = Grains(*[a.copy() for a in sim._grains()])
    frozen = p._replace(dt=0.0)  # kick and drift by 0: the same arithmetic, the grains stay put
    shape, cell_start, cell_of, order, tmp3, tmpi, nbr_start, nbr, nbr_i = sim._neighbors()
    sorted_grains = tuple(a.copy() for a in (grains.pos, grains.vel, grains.omg, grains.drag, grains.gid,
                                             grains.in_feed))
    counters, diag = sim._counters.copy(), sim._diag.copy()
    calls = {  # in a step's order
        "kick_drift": (stepper._kick_drift, (grains, n, frozen, 0.0, counters)),
        "sort": (sort_and_compact, sorted_grains + (n, p, shape, cell_start.copy(), cell_of, order, tmp3, tmpi,
                                                    counters)),
        "build": (build_neighbor_list, (grains.pos, grains.in_feed, n, p, shape, cell_start, nbr_start.copy(),
                                        nbr.copy(), nbr_i.copy())),
    }
    if p.gas_on > 0.0:
        calls.update(_gas_calls(p, _gas_copy(sim), grains, n, np.zeros_like(grains.drag)))
    calls["contacts"] = (evaluate_contacts, (grains, n, nbr_start, nbr, nbr_i, p, diag, sim._chunks, sim._pairs))
    return calls


def _gas_calls(p, gas, grains: Grains, n: int, drag: np.ndarray) -> dict:
    """The kernels of gas.couple with their arguments (p: the grain parameters, gas: a copy of the
    gas arrays)."""
    g = gas.g
    nx, ny, nz = gas.pressure.shape
    longest = max(nx, ny, nz)
    dt = p.dt * p.gas_interval
    rate = p.feed_volume_rate
    fields = (gas.pressure, gas.phi, gas.kappa, gas.src, gas.area, gas.ay, gas.az, g, dt, p.gas_theta)
    if g.split > 0.5:
        solve = (gas_kernels.gas_step_split,
                 fields + (gas.wvec.reshape(gas.wvec.size)[:10 * longest].reshape((10, longest)),))
    else:
        solve = (gas_kernels.gas_step, fields + (gas.wmat, gas.wvec))
    return {
        "deposit": (gas_kernels.deposit, (grains.pos, grains.vel, n, g, gas.dep)),
        "fields": (gas_kernels.update_fields, (gas.dep, gas.area, g, gas.phi, gas.kappa, gas.u)),
        "sources": (gas_kernels.volume_sources, (gas.u, gas.area, gas.ay, gas.az, g, rate, gas.src)),
        "solve": solve,
        "gradient": (gas_kernels.pressure_gradient, (gas.pressure, gas.phi, gas.kappa, gas.u, g, rate, gas.nodal)),
        "drag": (gas_kernels.drag_forces, (grains.pos, n, gas.nodal, g, drag, False)),
    }


@nb.njit  # not cached: the tests import this file under another module name than a run does
def _repeat(calls, kernel, args):
    """kernel(*args) `calls` times from compiled code, as the time loop calls it (no call from
    Python, whose argument unboxing costs ~5 µs for the grain arrays)."""
    for _ in range(calls):
        kernel(*args)


def measure(sim: Simulation, calls: int, rounds: int) -> list[dict]:
    """Per round, in turn: 2 ms of the simulation (its steps per rebuild), the step moving and held,
    and each part `calls` times on held copies of the round's state; µs of each, per round."""
    loop_step(sim, 0, 1)  # compiles the loop
    for kernel, args in part_calls(sim).values():
        _repeat(1, kernel, args)  # compiles each part's loop
    measured = []
    for _ in range(rounds):
        every = steps_per_rebuild(sim)
        row = {"steps_per_rebuild": every, "step": loop_step(sim), "held": loop_step(sim, max(1, round(every)))}
        for name, (kernel, args) in part_calls(sim).items():
            begin = time.perf_counter()
            _repeat(calls, kernel, args)
            row[name] = 1e6 * (time.perf_counter() - begin) / calls
        measured.append(row)
    return measured


def median_split(measured: list[dict], gas_interval: int) -> dict:
    """Each round's split (`split`), then per quantity its median over the rounds; the step's
    speed-up if a part cost nothing from its median share."""
    splits = []
    for row in measured:
        us = {k: v for k, v in row.items() if k not in ("step", "held", "steps_per_rebuild")}
        splits.append(split(us, row["step"], row["held"], row["steps_per_rebuild"], gas_interval))
    parts = {}
    for name in splits[0]:
        share = float(np.median([x[name]["share"] for x in splits]))
        parts[name] = {key: float(np.median([x[name][key] for x in splits])) for key in ("us_per_call", "us_per_step")}
        parts[name].update(share=share, speedup_if_free=1.0 / (1.0 - share))
    return parts


def intervals(steps_per_rebuild: float, gas_interval: int) -> dict:
    """Steps between calls of the parts that do not run every step."""
    return {"sort": steps_per_rebuild, "build": steps_per_rebuild, **{k: gas_interval for k in GAS_PARTS}}


def split(us_per_call: dict, step_us: float, held_us: float, steps_per_rebuild: float, gas_interval: int) -> dict:
    """µs per step of each part (a rebuild's parts over its interval, the gas's over its own) and of
    what the parts alone do not show: `together`, the held step less the parts' sum, and `motion`,
    the step less the held step. Per part also its share of the step and the step's speed-up if it
    cost nothing."""
    every = intervals(steps_per_rebuild, gas_interval)
    per_step = {name: us / every.get(name, 1.0) for name, us in us_per_call.items()}
    per_step["together"] = held_us - sum(per_step.values())
    per_step["motion"] = step_us - held_us
    return {name: {"us_per_call": us_per_call.get(name, float("nan")), "us_per_step": us,
                   "share": us / step_us, "speedup_if_free": step_us / (step_us - us)}
            for name, us in per_step.items()}


def contacts_speedup_for_half(parts: dict) -> float:
    """How many times faster the contact forces must run for the step to cost half, the rest
    unchanged (inf when the rest alone costs half the step or more)."""
    share = parts["contacts"]["share"]
    left = share - 0.5  # what the contacts may still cost, as a share of the step today
    return share / left if left > 0.0 else float("inf")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("case", nargs="?", help="case YAML (default: the standard dense packing)")
    parser.add_argument("--initial-state", help="case file whose final grains start the case (with CASE)")
    parser.add_argument("--calls", type=int, default=50, help="calls of each part per round (50)")
    parser.add_argument("--rounds", type=int, default=11, help="interleaved rounds (11); medians reported")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args(argv)
    if (args.case is None) != (args.initial_state is None):
        parser.error("CASE and --initial-state go together")
    if args.calls < 1 or args.rounds < 1:
        parser.error("--calls and --rounds must be >= 1")
    sim = prepare(args.case, args.initial_state)
    measured = measure(sim, args.calls, args.rounds)
    parts = median_split(measured, int(sim._p.gas_interval))
    step, held = (float(np.median([row[k] for row in measured])) for k in ("step", "held"))
    every = float(np.mean([row["steps_per_rebuild"] for row in measured]))
    motion = float(np.median([row["step"] / row["held"] for row in measured]))
    need = contacts_speedup_for_half(parts)
    print(f"{sim.n_particles} grains; the step {step:.1f} us, with the grains held {held:.1f} us (per round "
          f"{motion:.2f}x, median); a rebuild every {every:.1f} steps, a gas update every "
          f"{int(sim._p.gas_interval)} steps; medians of {args.rounds} rounds")
    print(f"{'part':12s} {'us/call':>9s} {'us/step':>8s} {'share':>6s} {'step x if free':>14s}")
    for name, row in parts.items():
        print(f"{name:12s} {row['us_per_call']:9.1f} {row['us_per_step']:8.1f} {100 * row['share']:5.1f}% "
              f"{row['speedup_if_free']:14.2f}")
    if math.isfinite(need):
        print(f"half the step's cost with the rest unchanged: contact forces {need:.2f}x faster")
    else:
        print("half the step's cost is out of reach of the contact forces alone: the rest costs half or more")
    if args.json:
        Path(args.json).write_text(json.dumps({"grains": sim.n_particles, "step_us": step, "held_step_us": held,
                                               "step_over_held": motion, "steps_per_rebuild": every,
                                               "parts": parts, "contacts_speedup_for_half": need,
                                               "rounds": measured}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

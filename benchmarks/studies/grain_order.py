#!/usr/bin/env python
"""Cost of the contact forces and of a step against the order of the grains in memory.

    python benchmarks/studies/grain_order.py [--initial-state results/cases/h_default/base.nc] \\
        [--case config/cases/horizontal.yaml] [--scale-grains N] [--repeats 7] [--no-standard] [--json OUT.json]

The engine stores the grains sorted by cell at every neighbour-list rebuild (a stable counting sort
over the cell grid, x-major: engine/kernels/neighbors.py). This study times the same physical state
with the grains stored in other orders, to say what that sort buys and whether another order would
buy more. States:

  standard   the settled standard packing of `plugsim bench` (engine.bench.settled_simulation);
  run        (with --initial-state) a case's final grains (a warm start of --case, as --initial-state
             does, engine.run.read_initial_state), advanced SETTLE s with the gas and the feed on;
  scale      (--scale-grains N > 0) the dense packing of about N grains in a longer 7 mm tube of
             benchmarks/scale.py (its arrays outgrow the core's L2 cache).

Orders (each a permutation of the grain rows; ratios are to `engine`):

  engine  the rows as the engine holds them: cell order of its last rebuild;
  id      by grain id, the order of insertion: the rows' order if the rebuild did not sort (grains
          appended at the inlet, those past the outlet compacted out); of `run`, the order of the
          case file, so the storage order a 30 s run would have drifted to;
  random  a random permutation (seed 0): the limit of that drift;
  cell    re-sorted by cell now (the engine's rebuild: stable by cell index);
  morton  by the Morton (Z-order) code of the cell (cx, cy, cz), stable within a cell;
  x       by the grain's axial coordinate.

`permute` reorders every per-grain array of the Simulation (state, forces and scratch; it refuses a
Simulation holding a per-grain array it does not know) and rewrites the neighbour list for the new
rows: the same pairs, each under its lower row, partners ascending (the engine's own format). The
engine's rebuild is not called after permuting: it would sort the rows back into cell order.
Every order is checked against `engine` (check_physics): after one force evaluation the forces,
torques, viscous-damping sums and cylinder normal forces of each grain (by id) and the total
overlap energy agree to rounding, and so do the positions, velocities and spins after one step
taken from the permuted stored forces.

Timed in one loop of `--repeats` rounds, each round every (measurement, order) once in a shuffled
order, so that a change of the machine's load hits all alike (CPU time of the process; the wall
time is in the JSON): the contact forces alone, in the single loop (`forces`) and in passes
(`forces_passes`, the engine's one-thread default), both through `plugsim bench --kernels`'s
compiled loop; steps through Simulation.advance (the entry point of `plugsim bench`, with the
engine's default contact kernel), in windows that start from a copy of the order's state and end
before its first neighbour rebuild (which would sort the rows); the engine's rebuild (sort and
list) started from each order; sort_and_compact alone on the `engine` rows (the sort's own cost
per rebuild). Reported: medians over the rounds, and per order the median of each round's ratio
to `engine`; `engine` and `cell` hold the same or nearly the same rows, so their ratio shows the
noise. Per order also how far apart contact partners are stored: the mean and 90th percentile of
|i - j| over the touching pairs; and the steps between rebuilds, over INTERVAL_TIME from the state.

All three states (1.5 to 2.5 minutes on the loaded 2-core machine; docs/performance.md, "Grain order
in memory"):

    python benchmarks/studies/grain_order.py --initial-state results/cases/h_default/base.nc \\
        --scale-grains 30000 --repeats 9
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from engine import Case, Simulation  # noqa: E402
from engine.simulation import SimulationError  # noqa: E402
from engine.bench import _run_forces, settled_simulation  # noqa: E402
from engine.kernels import contacts, indices  # noqa: E402
from engine.kernels import passes as contact_passes  # noqa: E402
from engine.kernels.neighbors import sort_and_compact  # noqa: E402
from engine.kernels.stepper import rebuild  # noqa: E402
from engine.run import read_initial_state  # noqa: E402

ORDERS = ("engine", "id", "random", "cell", "morton", "x")
# per-grain rows of a Simulation: the state and forces (state.Grains) and the rebuild's scratch rows
PER_GRAIN = ("_pos", "_vel", "_omg", "_force", "_drag", "_torque", "_viscous_damping", "_wall_normal", "_gid",
             "_in_feed", "_pos_ref", "_tmp3", "_tmpi", "_cell_of", "_order")
# arrays of a Simulation that are not one row per grain (the list is rewritten by `permute`)
NOT_PER_GRAIN = ("_p", "_shape", "_n", "_counters", "_diag", "_cell_start", "_nbr", "_nbr_i", "_nbr_start")
SETTLE = 0.005        # s a warm start is advanced before the study (as case_cost.py)
WINDOW_STEPS = 400    # longest timed window of steps
STEP_BUDGET = 1.2e6   # grain-steps per timing of the steps (windows summed)
FORCE_SECONDS = 0.04  # aimed CPU seconds per timing of the contact forces
INTERVAL_TIME = 0.01  # s advanced (on a copy) to count the steps between rebuilds
TOLERANCE = 1e-9      # relative agreement asked of the orders' physics


# ---- orders -----------------------------------------------------------------------------------
def cell_index(sim: Simulation, pos: np.ndarray) -> np.ndarray:
    """(cx, cy, cz) of each centre, as the engine's neighbour grid (neighbors._cell_index)."""
    p, shape = sim._p, sim._shape
    cx = ((pos[:, 0] - p.cell_x0) / p.cell_dx).astype(np.int64)
    cy = ((pos[:, 1] + p.tube_radius) / p.cell_dyz).astype(np.int64)
    cz = ((pos[:, 2] + p.tube_radius) / p.cell_dyz).astype(np.int64)
    return np.column_stack([np.clip(cx, 0, shape[0] - 1), np.clip(cy, 0, shape[1] - 1),
                            np.clip(cz, 0, shape[2] - 1)])


def morton_code(cells: np.ndarray) -> np.ndarray:
    """Z-order code of cells (k, 3): the bits of cx, cy, cz interleaved (cx the lowest of each triple)."""
    code = np.zeros(len(cells), dtype=np.int64)
    for bit in range(20):
        for axis in range(3):
            code |= ((cells[:, axis] >> bit) & 1) << (3 * bit + axis)
    return code


def order_of(sim: Simulation, name: str, seed: int = 0) -> np.ndarray:
    """The permutation (new row -> present row) of the grain rows 0..n-1 that gives order `name`."""
    n = int(sim._n[0])
    pos = sim._pos[:n]
    if name == "engine":
        return np.arange(n)
    if name == "id":
        return np.argsort(sim._gid[:n], kind="stable")
    if name == "random":
        return np.random.default_rng(seed).permutation(n)
    cells = cell_index(sim, pos)
    if name == "cell":
        ncx, ncy, ncz = sim._shape
        return np.argsort((cells[:, 0] * ncy + cells[:, 1]) * ncz + cells[:, 2], kind="stable")
    if name == "morton":
        return np.argsort(morton_code(cells), kind="stable")
    if name == "x":
        return np.argsort(pos[:, 0], kind="stable")
    raise ValueError(f"order {name!r}: one of {', '.join(ORDERS)}")


# ---- permuting a Simulation ---------------------------------------------------------------------
def per_grain_arrays(sim: Simulation) -> list[str]:
    """Names of the Simulation's per-grain arrays (PER_GRAIN); ValueError if it holds an array of one
    row per grain that PER_GRAIN does not name (a new one: this study must learn it)."""
    cap = len(sim._pos)
    found = {name for name, value in vars(sim).items()
             if isinstance(value, np.ndarray) and name not in NOT_PER_GRAIN and value.ndim and len(value) == cap}
    unknown = sorted(found - set(PER_GRAIN))
    if unknown:
        raise ValueError(f"Simulation holds per-grain arrays {unknown} that grain_order.PER_GRAIN does not name")
    missing = sorted(set(PER_GRAIN) - found)
    if missing:
        raise ValueError(f"Simulation lacks the per-grain arrays {missing} of grain_order.PER_GRAIN")
    return list(PER_GRAIN)


def list_pairs(sim: Simulation) -> tuple[np.ndarray, np.ndarray]:
    """The half neighbour list as (row i, row j) arrays (int64), in list order."""
    n = int(sim._n[0])
    start = sim._nbr_start[:n + 1]
    return np.repeat(np.arange(n), np.diff(start)), sim._nbr[:start[n]].astype(np.int64)


def set_list(sim: Simulation, i: np.ndarray, j: np.ndarray) -> None:
    """Write the pairs (i, j) as the half list: each under its lower row, partners ascending, and
    each entry's grain (the lower row, _nbr_i; the contact passes read it)."""
    n = int(sim._n[0])
    lo, hi = np.minimum(i, j), np.maximum(i, j)
    key = np.lexsort((hi, lo))
    sim._nbr[:len(key)] = hi[key]
    sim._nbr_i[:len(key)] = lo[key]
    sim._nbr_start[0] = 0
    sim._nbr_start[1:n + 1] = np.cumsum(np.bincount(lo, minlength=n))


def permute(sim: Simulation, perm: np.ndarray) -> Simulation:
    """A copy of `sim` whose grain rows are reordered: row k of the copy is row perm[k] of `sim`,
    in every per-grain array, with the same neighbour pairs in the new rows. Forces stay valid."""
    n = int(sim._n[0])
    perm = np.asarray(perm, dtype=np.int64)
    if sorted(perm.tolist()) != list(range(n)):
        raise ValueError(f"not a permutation of the {n} grain rows")
    out = copy.deepcopy(sim)
    for name in per_grain_arrays(sim):
        getattr(out, name)[:n] = getattr(sim, name)[:n][perm]
    if sim.threads > 1:  # the chunk balance's contact counts per grain
        out._chunks.contact_count[:n] = sim._chunks.contact_count[:n][perm]
    inverse = np.empty(n, dtype=np.int64)
    inverse[perm] = np.arange(n)
    i, j = list_pairs(sim)
    set_list(out, inverse[i], inverse[j])
    return out


def ready(sim: Simulation, steps: int) -> None:
    """Create the feed layers the next `steps` steps need (so that no layer is appended inside them,
    which would rebuild and sort); if any was, rebuild the list and evaluate the forces."""
    speed = sim._p.feed_speed
    sim._refill_feed(2 * speed * steps * sim.dt + 4 * sim.model.radius)
    if sim._dirty:
        sim._prepare()


def evaluate(sim: Simulation) -> None:
    """One evaluation of the contact forces (the engine's, on its present list)."""
    contacts.evaluate_contacts(sim._grains(), int(sim._n[0]), sim._nbr_start, sim._nbr, sim._nbr_i, sim._p,
                               sim._diag, sim._chunks, sim._pairs)


def overlap_energy(sim: Simulation) -> float:
    """Elastic energy sum k delta^2 / 2 of the touching pairs of the list, J (no walls)."""
    i, j = list_pairs(sim)
    pos = sim._pos
    delta = 2 * sim.model.radius - np.linalg.norm(pos[j] - pos[i], axis=1)
    return float(0.5 * sim.model.stiffness * np.sum(np.sort(delta[delta > 0] ** 2)))


def by_id(sim: Simulation, name: str) -> np.ndarray:
    """Rows 0..n-1 of the per-grain array `name`, ordered by grain id."""
    n = int(sim._n[0])
    return getattr(sim, name)[:n][np.argsort(sim._gid[:n], kind="stable")]


def _deviation(a: np.ndarray, b: np.ndarray) -> float:
    scale = max(float(np.abs(a).max(initial=0.0)), 1e-300)
    return float(np.abs(a - b).max(initial=0.0)) / scale


def check_physics(base: Simulation, other: Simulation) -> dict:
    """Largest relative deviations between two storage orders of one state (both as they are, their
    forces valid): per grain (by id) after one force evaluation (force, torque, viscous_damping,
    wall_normal), the overlap energy, and per grain after one step taken from the stored forces
    (pos, vel, omg), plus whether that step rebuilt the list in one and not the other (step_failed
    and step_error if the step raised SimulationError)."""
    out = {}
    if not np.array_equal(np.sort(base._gid[:int(base._n[0])]), np.sort(other._gid[:int(other._n[0])])):
        return {"ids": math.inf}
    a, b = copy.deepcopy(base), copy.deepcopy(other)
    evaluate(a)
    evaluate(b)
    for name in ("_force", "_torque", "_viscous_damping", "_wall_normal"):
        out[name.lstrip("_")] = _deviation(by_id(a, name), by_id(b, name))
    out["overlap_energy"] = abs(overlap_energy(a) - overlap_energy(b)) / max(overlap_energy(a), 1e-300)
    a, b = copy.deepcopy(base), copy.deepcopy(other)
    before = a._counters[indices.REBUILDS], b._counters[indices.REBUILDS]
    try:
        a.advance(a.dt)
        b.advance(b.dt)
    except SimulationError as err:  # a state broken by its order (a grain outside the tube)
        out["step_failed"] = math.inf
        out["step_error"] = str(err)
        return out
    for name in ("_pos", "_vel", "_omg"):
        out["step_" + name.lstrip("_")] = _deviation(by_id(a, name), by_id(b, name))
    out["step_rebuild_differs"] = float((a._counters[indices.REBUILDS] - before[0])
                                        != (b._counters[indices.REBUILDS] - before[1]))
    return out


def physics_agrees(deviations: dict, tolerance: float = TOLERANCE) -> bool:
    """Whether every deviation of check_physics is within `tolerance` (and the step ran)."""
    return "step_error" not in deviations and all(v <= tolerance for v in deviations.values())


# ---- scramble ----------------------------------------------------------------------------------
def partner_distance(sim: Simulation) -> dict:
    """How far apart the rows of touching pairs lie: mean, median and 90th percentile of |i - j|."""
    i, j = list_pairs(sim)
    pos = sim._pos
    touching = np.einsum("ij,ij->i", pos[j] - pos[i], pos[j] - pos[i]) < (2 * sim.model.radius) ** 2
    gap = np.abs(i[touching] - j[touching])
    return {"mean": float(gap.mean()), "median": float(np.median(gap)), "p90": float(np.percentile(gap, 90))}


def contact_count(sim: Simulation) -> dict:
    """Touching contacts as the contact kernel sees them (engine.bench.contact_count over every row,
    feed grains included): list pairs closer than d, cylinder and inlet contacts of dynamic grains."""
    n, r = int(sim._n[0]), sim.model.radius
    i, j = list_pairs(sim)
    pos, dynamic = sim._pos[:n], sim._in_feed[:n] == 0
    offset = pos[j] - pos[i]
    pairs = int(np.count_nonzero(np.einsum("ij,ij->i", offset, offset) < 4 * r * r))
    inner = sim.case["tube.diameter"] / 2 - r
    walls = int(np.count_nonzero(dynamic & (pos[:, 1] ** 2 + pos[:, 2] ** 2 > inner * inner)))
    walls += int(np.count_nonzero(dynamic & (pos[:, 0] < r)))
    return {"pairs": pairs, "walls": walls, "list_entries": len(j)}


# ---- timing ------------------------------------------------------------------------------------
def _clock() -> tuple[float, float]:
    return time.process_time(), time.perf_counter()


def interleaved(runs: dict, repeats: int, seed: int = 1) -> dict:
    """CPU and wall seconds of each run (callable returning the (CPU, wall) seconds it timed itself,
    or None to time the whole call), `repeats` rounds, each round the runs once in a shuffled order;
    one untimed call of each first."""
    for run in runs.values():
        run()
    cpu = {name: [] for name in runs}
    wall = {name: [] for name in runs}
    rng = np.random.default_rng(seed)
    names = list(runs)
    for _ in range(repeats):
        for k in rng.permutation(len(names)):
            name = names[k]
            run = runs[name]
            c0, w0 = _clock()
            inner = run()
            c1, w1 = _clock()
            c, w = inner if inner is not None else (c1 - c0, w1 - w0)
            cpu[name].append(c)
            wall[name].append(w)
    return {"cpu": cpu, "wall": wall}


def steps_before_rebuild(sim: Simulation, limit: int) -> int:
    """Steps the state takes before its first neighbour rebuild (at most `limit`), on a copy."""
    probe = copy.deepcopy(sim)
    start = probe._counters[indices.REBUILDS]
    for k in range(limit):
        probe.advance(probe.dt)
        if probe._counters[indices.REBUILDS] != start:
            return k
    return limit


def rebuild_interval(sim: Simulation, seconds: float) -> float:
    """Mean steps between neighbour rebuilds over `seconds` of simulated time, on a copy."""
    probe = copy.deepcopy(sim)
    before = probe._counters.copy()
    probe.advance(seconds)
    done = probe._counters - before
    return float(done[indices.STEPS] / max(1, done[indices.REBUILDS]))


def forces_runs(sims: dict, passes: bool) -> tuple[dict, int]:
    """Runs timing `calls` one-thread contact-force evaluations (single loop, or in passes) per order,
    called from compiled code (engine.bench's loop), each on a fresh copy of the order's state (the
    copy uncounted: arrays at new addresses each time, so that no one placement in memory decides
    an order's time); and `calls`."""
    count = contact_count(next(iter(sims.values())))
    calls = max(3, math.ceil(FORCE_SECONDS / (35e-9 * (count["pairs"] + count["walls"]))))

    def run(sim):
        work = copy.deepcopy(sim)
        pairs = contact_passes.pair_buffers() if passes else contacts.single_loop_buffers()
        grains, n, diag = work._grains(), int(work._n[0]), work._diag.copy()
        c0, w0 = _clock()
        _run_forces(calls, grains, n, work._nbr_start, work._nbr, work._nbr_i, work._p, diag, work._chunks, pairs)
        c1, w1 = _clock()
        return c1 - c0, w1 - w0

    return {name: (lambda sim=sim: run(sim)) for name, sim in sims.items()}, calls


def step_runs(sims: dict, window: int) -> tuple[dict, int, int, list]:
    """Runs timing steps through Simulation.advance per order: `windows` windows of `window` steps,
    each from a fresh copy of the order's state (uncounted), about STEP_BUDGET grain-steps in all;
    and window, windows and a counter of the windows in which the list was rebuilt (the rows sorted)
    all the same."""
    grains = next(iter(sims.values())).n_particles
    window = max(1, min(window, round(STEP_BUDGET / grains)))
    windows = max(1, round(STEP_BUDGET / grains / window))
    rebuilt = [0]

    def run(sim):
        cpu = wall = 0.0
        for _ in range(windows):
            work = copy.deepcopy(sim)
            before = work._counters[indices.REBUILDS]
            c0, w0 = _clock()
            work.advance(window * work.dt)
            c1, w1 = _clock()
            cpu, wall = cpu + c1 - c0, wall + w1 - w0
            rebuilt[0] += int(work._counters[indices.REBUILDS] != before)
        return cpu, wall

    return {name: (lambda sim=sim: run(sim)) for name, sim in sims.items()}, window, windows, rebuilt


REBUILD_ROUNDS = 10  # rebuilds per timing, each on a fresh copy


def rebuild_runs(sims: dict) -> dict:
    """Runs timing REBUILD_ROUNDS of the engine's rebuild (sort and list) started from each order, each
    on a fresh copy (uncounted); and "sort_only": sort_and_compact alone on the `engine` order."""

    def rounds(sim, call):
        cpu = wall = 0.0
        for _ in range(REBUILD_ROUNDS):
            work = copy.deepcopy(sim)
            c0, w0 = _clock()
            call(work)
            c1, w1 = _clock()
            cpu, wall = cpu + c1 - c0, wall + w1 - w0
        return cpu, wall

    def full(work):
        rebuild(work._grains(), int(work._n[0]), work._p, work._neighbors(), work._counters)

    def sort_only(work):
        nbrs = work._neighbors()
        sort_and_compact(work._pos, work._vel, work._omg, work._drag, work._gid, work._in_feed, int(work._n[0]),
                         work._p, nbrs.shape, nbrs.cell_start, nbrs.cell_of, nbrs.order, nbrs.tmp3, nbrs.tmpi,
                         work._counters)

    runs = {name: (lambda sim=sim: rounds(sim, full)) for name, sim in sims.items()}
    runs["sort_only"] = lambda: rounds(sims["engine"], sort_only)
    return runs


def time_orders(sims: dict, window: int, repeats: int) -> dict:
    """Every timing of the orders in one interleaved loop (so that the columns are comparable):
    per kind (forces, forces_passes, step, rebuild) and order the CPU and wall seconds per call,
    step or rebuild of each round."""
    single, calls = forces_runs(sims, passes=False)
    passes, _ = forces_runs(sims, passes=True)
    steps, window, windows, rebuilt = step_runs(sims, window)
    kinds = {"forces": (single, calls), "forces_passes": (passes, calls), "step": (steps, window * windows),
             "rebuild": (rebuild_runs(sims), REBUILD_ROUNDS)}
    runs = {(kind, name): run for kind, (per, _) in kinds.items() for name, run in per.items()}
    times = interleaved(runs, repeats)
    out = {kind: {clock: {name: [t / kinds[kind][1] for t in times[clock][(kind, name)]] for name in per}
                  for clock in ("cpu", "wall")} for kind, (per, _) in kinds.items()}
    out["window"], out["windows"], out["rebuilt"] = window, windows, rebuilt[0]
    return out


# ---- a state, its orders and their costs ---------------------------------------------------------
def standard_state() -> Simulation:
    return settled_simulation()


def run_state(case_file: str, initial_state: str) -> Simulation:
    case = Case.from_yaml(case_file)
    sim = Simulation(case)
    sim.add_particles(*read_initial_state(initial_state, case))
    sim.advance(SETTLE)
    return sim


def scale_state(grains: int) -> Simulation:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import scale  # benchmarks/scale.py

    state = scale.settled_state(grains, 0.007)
    sim = Simulation(scale.case_for(state["length"], state["diameter"], gas=False))
    sim.add_particles(state["positions"], state["velocities"], state["angular_velocities"])
    sim.advance(0.001)
    return sim


def study(sim: Simulation, repeats: int) -> dict:
    """Orders of `sim`'s state: physics check, partner distances and timings (see the module doc)."""
    ready(sim, WINDOW_STEPS)
    base = sim
    sims = {name: (base if name == "engine" else permute(base, order_of(base, name))) for name in ORDERS}
    checks = {name: check_physics(base, other) for name, other in sims.items() if name != "engine"}
    bad = {name: dev for name, dev in checks.items() if not physics_agrees(dev)}
    if bad:
        raise AssertionError(f"orders disagree with the engine's physics: {bad}")
    count = contact_count(base)
    n_contacts = count["pairs"] + count["walls"]
    every = rebuild_interval(base, INTERVAL_TIME)
    t = time_orders(sims, steps_before_rebuild(base, WINDOW_STEPS), repeats)
    rows = {}
    for name in ORDERS:
        row = {"partners": partner_distance(sims[name]),
               "physics_max_deviation": max(checks[name].values()) if name in checks else 0.0}
        for kind in ("forces", "forces_passes", "step", "rebuild"):
            cpu, wall = t[kind]["cpu"], t[kind]["wall"]
            row[kind + "_s"] = statistics.median(cpu[name])
            row[kind + "_wall_s"] = statistics.median(wall[name])
            row[kind + "_ratio"] = statistics.median(a / b for a, b in zip(cpu[name], cpu["engine"]))
            row[kind + "_ratios"] = [a / b for a, b in zip(cpu[name], cpu["engine"])]
        row["forces_ns_per_contact"] = 1e9 * row["forces_s"] / n_contacts
        row["forces_passes_ns_per_contact"] = 1e9 * row["forces_passes_s"] / n_contacts
        row["step_us"] = 1e6 * row["step_s"]
        row["step_ns_per_contact"] = 1e9 * row["step_s"] / n_contacts
        rows[name] = row
    sort_only = statistics.median(t["rebuild"]["cpu"]["sort_only"])
    return {"grains": base.n_particles, "rows_stored": int(base._n[0]), "contacts": count,
            "steps_per_timed_window": t["window"], "timed_windows": t["windows"],
            "windows_with_rebuild": t["rebuilt"], "repeats": repeats, "steps_per_rebuild": every,
            "sort_only_s": sort_only, "sort_only_us_per_step": 1e6 * sort_only / every, "orders": rows}


def print_state(label: str, res: dict) -> None:
    c = res["contacts"]
    print(f"\n{label}: {res['grains']} grains in the tube ({res['rows_stored']} rows), {c['pairs']} touching pairs + "
          f"{c['walls']} wall contacts, {c['list_entries']} list entries; steps timed in windows of "
          f"{res['steps_per_timed_window']}; CPU time, medians of {res['repeats']} interleaved")
    print(f"{'order':8s} {'|i-j| mean':>10s} {'p90':>6s} {'forces ns/c':>11s} {'ratio':>6s} {'passes ns/c':>11s} "
          f"{'ratio':>6s} {'step us':>8s} {'ns/c':>6s} {'ratio':>6s} {'rebuild us':>10s} {'ratio':>6s} {'physics':>8s}")
    for name, r in res["orders"].items():
        print(f"{name:8s} {r['partners']['mean']:10.1f} {r['partners']['p90']:6.0f} {r['forces_ns_per_contact']:11.1f} "
              f"{r['forces_ratio']:6.3f} {r['forces_passes_ns_per_contact']:11.1f} {r['forces_passes_ratio']:6.3f} "
              f"{r['step_us']:8.1f} {r['step_ns_per_contact']:6.1f} {r['step_ratio']:6.3f} "
              f"{1e6 * r['rebuild_s']:10.1f} {r['rebuild_ratio']:6.3f} {r['physics_max_deviation']:8.1e}")
    print(f"sort_and_compact alone on the engine order: {1e6 * res['sort_only_s']:.1f} us per rebuild; a rebuild "
          f"every {res['steps_per_rebuild']:.0f} steps (over {INTERVAL_TIME:g} s from the state): "
          f"{res['sort_only_us_per_step']:.2f} us per step; timed windows with a rebuild all the same: "
          f"{res['windows_with_rebuild']}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--initial-state", help="case file whose final grains are the `run` state (else skipped)")
    parser.add_argument("--case", default=str(ROOT / "config/cases/horizontal.yaml"),
                        help="case YAML of the `run` state (default config/cases/horizontal.yaml)")
    parser.add_argument("--scale-grains", type=int, default=0,
                        help="grains of the `scale` state (benchmarks/scale.py's 7 mm family; 0: skipped)")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved repeats; medians reported (7)")
    parser.add_argument("--no-standard", action="store_true", help="skip the standard packing")
    parser.add_argument("--json", help="also write the results to this JSON file")
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.scale_grains < 0:
        parser.error("--repeats must be >= 1 and --scale-grains >= 0")
    if args.initial_state and not Path(args.initial_state).is_file():
        parser.error(f"--initial-state {args.initial_state}: no such file")
    results = {}
    if not args.no_standard:
        results["standard"] = study(standard_state(), args.repeats)
        print_state("standard packing (plugsim bench)", results["standard"])
    if args.initial_state:
        sim = run_state(args.case, args.initial_state)
        results["run"] = study(sim, args.repeats)
        print_state(f"{Path(args.case).name} from the final grains of {args.initial_state} "
                    "(`id`: the case file's order)", results["run"])
    if args.scale_grains:
        results["scale"] = study(scale_state(args.scale_grains), args.repeats)
        print_state(f"dense packing of ~{args.scale_grains} grains in a 7 mm tube (benchmarks/scale.py)",
                    results["scale"])
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python
"""Scale: how the cost of a step grows with the number of grains, in longer and in wider tubes.

    python benchmarks/scale.py --out-dir results/benchmarks/scale [--reduced]

Families of dense packings of N = 10^3 ... 10^5 grains (d = 1.4 mm):

  long    the default 7 mm tube, made longer;
  wide14  a 14 mm tube, and
  wide28  a 28 mm tube, each as long as N needs.

Every packing is engine.bench's standard dense case generalised (`dense_packing`): stacked ring
layers (engine.feed.layer_template of the tube's cross-section, 1.02 d apart, each turned by a random
angle), full layers over a plug from 38 % to 50 % of the length and, elsewhere, the lowest 7/19 of
each layer (a bed), settled under gravity with the gas off for SETTLE_TIME = 0.02 s (2.6-2.9
contacts per grain, walls included; the standard case settled for 0.05 s has 3.2). The tube length is the
one that gives N grains, so a 7 mm tube of ~3070 grains is the standard case itself (0.525 m), and
each family keeps the standard case's hold-up per layer. Tubes shorter than 2 cm are skipped.

Each packing is timed through Simulation.advance for a fixed number of steps (median of 5 (3 reduced)
repeats, which are interleaved across all packings so a load change hits every N alike, after a
warm-up so that no compile time is counted), with the gas off and with the gas on (defaults:
v_s = 1 m/s, updated every 10 steps) on a grid of ~3.5 mm cells: gas.nodes_x = round(L / 3.5 mm),
nodes_y = nodes_z = max(2, round(D / 3.5 mm)). Feed off. One thread (the engine's
default). Both the wall time and the CPU time of the timing thread are recorded: on a loaded machine the
wall time includes the time the thread waited for a core; the CPU time is what an idle core would
take. Memory: peak resident set size (VmHWM) of a fresh process that builds the gas-on case and
runs 20 steps, and the engine's own arrays (sum of their nbytes).

Writes OUT/scale.csv (one row per packing and gas setting), OUT/scale.md (table, conditions and
the headline: the largest N, and 7 mm tube length, for which 10 simulated seconds cost at most one
hour on one core) and OUT/scale.png (log-log cost against N). About 6 min on a loaded 2-core
machine; `--reduced` (CI, ~15 s): N up to 3000 in the 7 and 14 mm tubes. `--replot CSV` rewrites
the .md and .png from an existing table.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from engine import Case, Simulation
from engine.bench import PLUG_LENGTH, PLUG_START, TARGET_GRAINS, stack_layers
from engine.feed import layer_template

STANDARD_LENGTH = 0.525                      # m, the standard case's tube (engine.bench)
PLUG_FROM = PLUG_START / STANDARD_LENGTH     # plug from 38.1 % ...
PLUG_TO = (PLUG_START + PLUG_LENGTH) / STANDARD_LENGTH  # ... to 49.5 % of the length
BED_FRACTION = 7 / 19                        # the standard bed: the lowest 7 of 19 grains per layer
LAYER_SPACING = 1.02                         # layer pitch, in d (as engine.bench)
SETTLE_TIME = 0.02                           # s of settling under gravity, gas off
GAS_CELL = 0.0035                            # m, gas cell size kept along and across
MIN_LENGTH = 0.02                            # m: shorter tubes are skipped
HOLDUP_7MM = TARGET_GRAINS / STANDARD_LENGTH  # grains per metre of a 7 mm tube in the papers' runs
BUDGET_SIMULATED = 10.0                      # s of simulated time (fill + steady window) ...
BUDGET_WALL = 3600.0                         # ... per hour of wall time on one core

FAMILIES = {"long": 0.007, "wide14": 0.014, "wide28": 0.028}  # tube diameter, m
FULL = {"families": ("long", "wide14", "wide28"), "grains": (1000, 3000, 10000, 30000, 100000),
        "repeats": 5, "particle_steps": 4e6}
REDUCED = {"families": ("long", "wide14"), "grains": (1000, 3000), "repeats": 3, "particle_steps": 1e6}


# ---- packings -------------------------------------------------------------------------------------
def _layers(diameter: float, d: float) -> tuple[np.ndarray, int]:
    template = layer_template(diameter / 2, d)
    return template, max(1, round(BED_FRACTION * len(template)))


def tube_length(grains: int, diameter: float, d: float = 0.0014) -> float:
    """Tube length (m) whose dense packing (`dense_packing`) holds about `grains` grains."""
    template, bed = _layers(diameter, d)
    plug = PLUG_TO - PLUG_FROM
    per_layer = plug * len(template) + (1 - plug) * bed
    layers = grains / per_layer
    return round(layers * LAYER_SPACING * d + 2 * d, 4)


def case_for(length: float, diameter: float, gas: bool, *overrides: str) -> Case:
    """Defaults, feed off, this tube, gas on or off on a ~3.5 mm grid."""
    across = max(2, round(diameter / GAS_CELL))
    return Case().with_overrides([
        "feed.mass_flow_kg_h=0", f"tube.length={length}", f"tube.diameter={diameter}",
        f"gas.enabled={'true' if gas else 'false'}", f"gas.nodes_x={max(3, round(length / GAS_CELL))}",
        f"gas.nodes_y={across}", f"gas.nodes_z={across}", *overrides])


def dense_packing(case: Case, seed: int = 0) -> np.ndarray:
    """Grain centres (n, 3) before settling: engine.bench.standard_packing for any tube.

    Full ring layers between PLUG_FROM and PLUG_TO of the length, the lowest BED_FRACTION of each
    layer elsewhere. For the standard 7 mm x 0.525 m tube this is exactly standard_packing.
    """
    d, length = case["particles.diameter"], case["tube.length"]
    template, per_layer = _layers(case["tube.diameter"], d)
    xs = np.arange(d, length - d, LAYER_SPACING * d)
    plug = (xs >= PLUG_FROM * length) & (xs < PLUG_TO * length)
    return stack_layers(xs, plug, template, per_layer, d, np.random.default_rng(seed))


def settled_state(grains: int, diameter: float, settle_time: float = SETTLE_TIME) -> dict:
    """Build and settle (gas off) the packing of about `grains` grains; returns length and arrays."""
    length = tube_length(grains, diameter)
    sim = Simulation(case_for(length, diameter, gas=False))
    sim.add_particles(dense_packing(sim.case))
    sim.advance(settle_time)
    return {"length": length, "diameter": diameter, "positions": sim.positions.copy(),
            "velocities": sim.velocities.copy(), "angular_velocities": sim.angular_velocities.copy()}


def simulation_from(state: dict, gas: bool) -> Simulation:
    """A Simulation of the settled state, gas on or off."""
    sim = Simulation(case_for(state["length"], state["diameter"], gas))
    sim.add_particles(state["positions"], state["velocities"], state["angular_velocities"])
    return sim


def contact_stats(positions: np.ndarray, d: float, tube_diameter: float) -> dict:
    """Contacts per grain (grain pairs counted for both grains, cylinder and inlet walls included)
    and the largest overlap, as a fraction of d (k-d tree, independent of the engine)."""
    r, R = d / 2, tube_diameter / 2
    pairs = cKDTree(positions).query_pairs(d, output_type="ndarray")
    dist = np.linalg.norm(positions[pairs[:, 0]] - positions[pairs[:, 1]], axis=1)
    wall = np.hypot(positions[:, 1], positions[:, 2]) + r - R
    inlet = r - positions[:, 0]
    overlaps = np.concatenate([d - dist, wall[wall > 0], inlet[inlet > 0], [0.0]])
    contacts = 2 * len(pairs) + np.count_nonzero(wall > 0) + np.count_nonzero(inlet > 0)
    return {"contacts_per_grain": contacts / len(positions), "max_overlap_d": float(overlaps.max() / d)}


# ---- timing -------------------------------------------------------------------------------------
def steps_for(grains: int, particle_steps: float, multiple: int = 10) -> int:
    """Steps per repeat: about `particle_steps` particle-steps, 100 to 2000, a multiple of 10."""
    steps = min(2000, max(100, particle_steps / grains))
    return int(multiple * round(steps / multiple))


def time_steps(sim: Simulation, steps: int) -> tuple[float, float]:
    """(wall, CPU) seconds per step of `steps` steps of sim.advance (the calling thread's CPU)."""
    wall0, cpu0 = time.perf_counter(), time.thread_time()
    sim.advance(steps * sim.dt)
    return (time.perf_counter() - wall0) / steps, (time.thread_time() - cpu0) / steps


def engine_bytes(sim: Simulation) -> int:
    """Bytes of the numpy arrays the Simulation and its gas field hold."""
    total = 0
    for obj in (sim, sim.gas):
        total += sum(v.nbytes for v in vars(obj).values() if isinstance(v, np.ndarray))
    return total


def _probe(path: str) -> None:
    """Subprocess: build the gas-on case of a saved state, run 20 steps, print peak RSS (MB)."""
    with np.load(path) as f:
        state = {k: f[k] for k in f.files}
    state["length"], state["diameter"] = float(state["length"]), float(state["diameter"])
    sim = simulation_from(state, gas=True)
    sim.advance(20 * sim.dt)
    print(json.dumps({"peak_rss_mb": peak_rss_mb(), "engine_mb": engine_bytes(sim) / 2**20}))


def peak_rss_mb() -> float:
    """Peak resident set size of this process since its exec, MB.

    /proc/self/status VmHWM: getrusage's ru_maxrss would carry over the high-water mark of the
    parent that forked this process (Linux keeps it across exec), i.e. of the study itself.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def peak_memory(state: dict) -> dict:
    """Peak RSS (MB) of a fresh process holding this state with the gas on, and the engine arrays."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "state.npz"
        np.savez(path, **state)
        out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--probe", str(path)], capture_output=True,
                             text=True, check=True, env=dict(os.environ, NUMBA_NUM_THREADS="1"))
    return json.loads(out.stdout.strip().splitlines()[-1])


# ---- the study ----------------------------------------------------------------------------------
def points(families, grains) -> list[tuple[str, int]]:
    """(family, N) pairs whose tube is at least MIN_LENGTH long."""
    return [(f, n) for f in families for n in grains if tube_length(n, FAMILIES[f]) >= MIN_LENGTH]


def study(families, grains, repeats: int, particle_steps: float, log=print) -> list[dict]:
    """Build, settle and time every packing; one row per packing and gas setting."""
    entries = []
    for family, n in points(families, grains):
        start = time.perf_counter()
        state = settled_state(n, FAMILIES[family])
        grains_in = len(state["positions"])
        entry = {"family": family, "diameter_mm": FAMILIES[family] * 1e3, "length_m": state["length"],
                 "grains": grains_in,
                 **contact_stats(state["positions"], 0.0014, FAMILIES[family]),
                 **peak_memory(state), "steps": steps_for(grains_in, particle_steps), "sims": {}}
        for gas in (False, True):
            sim = simulation_from(state, gas)
            sim.advance(20 * sim.dt)  # warm-up: compile (or load) the kernels, first neighbour list
            entry["sims"][gas] = sim
        entry["gas_grid"] = "x".join(str(entry["sims"][True].case[f"gas.nodes_{a}"]) for a in "xyz")
        entry["dt"] = entry["sims"][False].dt
        log(f"built {family:7s} D = {entry['diameter_mm']:g} mm, L = {state['length']:.3f} m, "
            f"{grains_in} grains, {entry['contacts_per_grain']:.2f} contacts per grain, "
            f"max overlap {entry['max_overlap_d']:.2%} d, peak RSS {entry['peak_rss_mb']:.0f} MB "
            f"({time.perf_counter() - start:.1f} s)")
        entries.append(entry)
    load = [os.getloadavg()]
    timings = {(i, gas): [] for i in range(len(entries)) for gas in (False, True)}
    for r in range(repeats):  # interleaved: every packing once per round
        for i, entry in enumerate(entries):
            for gas in (False, True):
                timings[i, gas].append(time_steps(entry["sims"][gas], entry["steps"]))
        log(f"timing round {r + 1}/{repeats} done, load average {os.getloadavg()[0]:.2f}")
    load.append(os.getloadavg())
    rows = []
    for i, entry in enumerate(entries):
        for gas in (False, True):
            wall = statistics.median(t[0] for t in timings[i, gas])
            cpu = statistics.median(t[1] for t in timings[i, gas])
            sim = entry["sims"][gas]
            rows.append({
                "family": entry["family"], "diameter_mm": entry["diameter_mm"], "length_m": entry["length_m"],
                "grains": entry["grains"], "contacts_per_grain": round(entry["contacts_per_grain"], 3),
                "max_overlap_d": round(entry["max_overlap_d"], 5), "gas": "on" if gas else "off",
                "gas_grid": entry["gas_grid"] if gas else "", "time_step_s": entry["dt"],
                "steps": entry["steps"], "repeats": repeats,
                "us_per_step": wall * 1e6, "cpu_us_per_step": cpu * 1e6,
                "particle_steps_per_s": entry["grains"] / wall,
                "wall_s_per_simulated_s": wall / entry["dt"], "cpu_s_per_simulated_s": cpu / entry["dt"],
                "grains_after": sim.n_particles,
                "peak_rss_mb": round(entry["peak_rss_mb"], 1), "engine_mb": round(entry["engine_mb"], 2),
                "load_before": round(load[0][0], 2), "load_after": round(load[1][0], 2)})
    return rows


def budget_grains(rows: list[dict], family: str, gas: str, column: str) -> tuple[float, bool]:
    """N at which `column` (s per simulated s) reaches BUDGET_WALL / BUDGET_SIMULATED, by log-log
    interpolation between the measured points (extrapolation from the nearest two: flag True)."""
    pts = sorted((r["grains"], r[column]) for r in rows if r["family"] == family and r["gas"] == gas)
    if len(pts) < 2:
        return math.nan, True
    target = BUDGET_WALL / BUDGET_SIMULATED
    n, c = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    above = np.flatnonzero(c >= math.log(target))
    k = len(pts) - 2 if not len(above) else max(0, above[0] - 1)
    k = min(k, len(pts) - 2)
    slope = (c[k + 1] - c[k]) / (n[k + 1] - n[k])
    star = n[k] + (math.log(target) - c[k]) / slope
    return float(math.exp(star)), not (n[0] <= star <= n[-1])


def exponents(rows: list[dict], family: str, gas: str, column: str = "us_per_step") -> list[float]:
    """Local log-log slopes of cost against N between consecutive points."""
    pts = sorted((r["grains"], r[column]) for r in rows if r["family"] == family and r["gas"] == gas)
    return [math.log(b[1] / a[1]) / math.log(b[0] / a[0]) for a, b in zip(pts, pts[1:])]


# ---- outputs ------------------------------------------------------------------------------------
COLUMNS = ["family", "diameter_mm", "length_m", "grains", "contacts_per_grain", "max_overlap_d", "gas",
           "gas_grid", "time_step_s", "steps", "repeats", "us_per_step", "cpu_us_per_step",
           "particle_steps_per_s", "wall_s_per_simulated_s", "cpu_s_per_simulated_s", "grains_after",
           "peak_rss_mb", "engine_mb", "load_before", "load_after"]


def write_csv(rows: list[dict], path: Path) -> None:
    import csv
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})


def headline(rows: list[dict]) -> list[str]:
    """The budget statements: largest N for 10 simulated s per hour, per family, gas on."""
    lines = []
    per_hour = f"{BUDGET_SIMULATED:g} simulated seconds per hour"
    for family in dict.fromkeys(r["family"] for r in rows):
        wall, wall_x = budget_grains(rows, family, "on", "wall_s_per_simulated_s")
        cpu, cpu_x = budget_grains(rows, family, "on", "cpu_s_per_simulated_s")
        diameter = next(r["diameter_mm"] for r in rows if r["family"] == family)
        note = lambda x: " (extrapolated)" if x else ""  # noqa: E731
        if family == "long":
            lines.append(
                f"**Largest 7 mm tube at {per_hour} on one core (gas on): about {cpu:,.0f} grains"
                f"{note(cpu_x)}, i.e. a {cpu / HOLDUP_7MM:.1f} m tube at the papers' hold-up of "
                f"{HOLDUP_7MM:,.0f} grains per metre** (from the CPU time of the timed thread, what an "
                f"idle core takes); from the wall time measured under this run's load: {wall:,.0f} "
                f"grains{note(wall_x)}, {wall / HOLDUP_7MM:.1f} m.")
        else:
            length = tube_length(int(cpu), diameter / 1e3) if math.isfinite(cpu) else math.nan
            lines.append(f"- {diameter:g} mm tube ({family}), gas on: about {cpu:,.0f} grains{note(cpu_x)} "
                         f"({length:.2f} m of this study's packing) by CPU time, {wall:,.0f}{note(wall_x)} "
                         f"by wall time.")
    return lines


def _spaced(lines: list[str]) -> list[str]:
    """The headline paragraph, a blank line, then the list of the other families."""
    return lines[:1] + [""] + lines[1:] if lines and not lines[0].startswith("-") else lines


def write_markdown(rows: list[dict], path: Path, meta: dict) -> None:
    head = ("| tube | D (mm) | L (m) | N | contacts/grain | gas | gas grid | steps × repeats | µs/step wall "
            "| µs/step CPU | particle-steps/s | wall s / sim s | CPU s / sim s | peak RSS (MB) | engine (MB) |")
    lines = ["# Scale: cost against the number of grains", "",
             f"{meta['date']}, {meta['machine']}, one thread, {meta['mode']} run; load average (1 min) "
             f"{meta['load_before']:.2f} before and {meta['load_after']:.2f} after the timing on "
             f"{os.cpu_count()} cores.", "", *_spaced(headline(rows)), "",
             f"Assumption: a typical case needs {BUDGET_SIMULATED:g} s of simulated time (fill + steady "
             f"window), so the budget is {BUDGET_WALL / BUDGET_SIMULATED:g} s of wall time per simulated "
             f"second on one core; the number of grains N at that cost is interpolated log-log between "
             f"the measured points of the gas-on runs. The papers' runs hold about "
             f"{HOLDUP_7MM:,.0f} grains per metre of 7 mm tube ({TARGET_GRAINS} in 0.525 m). The packings "
             f"are static (a settled bed and a plug, gas off for the settling): a conveying run moves "
             f"more and rebuilds its neighbour list more often.", "",
             head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        lines.append(
            f"| {r['family']} | {r['diameter_mm']:g} | {r['length_m']:.3f} | {r['grains']} | "
            f"{r['contacts_per_grain']:.2f} | {r['gas']} | {r['gas_grid'] or '-'} | {r['steps']} × {r['repeats']} | "
            f"{r['us_per_step']:.0f} | {r['cpu_us_per_step']:.0f} | {r['particle_steps_per_s']:.3g} | "
            f"{r['wall_s_per_simulated_s']:.1f} | {r['cpu_s_per_simulated_s']:.1f} | {r['peak_rss_mb']:.0f} | "
            f"{r['engine_mb']:.1f} |")
    lines += ["", "Growth exponents (local log-log slope of µs per step against N between consecutive "
              "points; 1 = cost proportional to N), CPU time (wall time):", ""]
    for family in dict.fromkeys(r["family"] for r in rows):
        for gas in ("off", "on"):
            slopes = ", ".join(f"{c:.2f} ({w:.2f})" for c, w in zip(exponents(rows, family, gas, "cpu_us_per_step"),
                                                                exponents(rows, family, gas)))
            lines.append(f"- {family}, gas {gas}: {slopes or '-'}")
    lines += ["", "Gas cost (wall time per step with the gas on over gas off; the gas grid has ~3.5 mm "
              "cells, its solve dense (ny nz)² blocks per axial node):", ""]
    for family in dict.fromkeys(r["family"] for r in rows):
        ratios = [on["us_per_step"] / off["us_per_step"] for on in rows for off in rows
                  if on["family"] == off["family"] == family and on["grains"] == off["grains"]
                  and on["gas"] == "on" and off["gas"] == "off"]
        grid = next(r["gas_grid"] for r in rows if r["family"] == family and r["gas"] == "on")
        lines.append(f"- {family} ({grid.split('x', 1)[1]} across): +{statistics.median(ratios) - 1:.0%} "
                     f"(median over N; {min(ratios) - 1:+.0%} to {max(ratios) - 1:+.0%})")
    lines += ["", "Columns: µs/step wall and CPU are medians over the repeats (interleaved across all "
              "packings); particle-steps/s = N / wall time per step; wall (CPU) s / sim s = time per step "
              "/ time step; peak RSS of a fresh process holding the gas-on case (Python, numba and the "
              "kernels included, ~190 MB of it); engine = the numpy arrays the Simulation and its gas field "
              "allocate (grain arrays sized for a full tube: pages never touched are not resident).", ""]
    path.write_text("\n".join(lines))


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4))
    colours = {"long": "C0", "wide14": "C1", "wide28": "C2"}
    for family in dict.fromkeys(r["family"] for r in rows):
        diameter = next(r["diameter_mm"] for r in rows if r["family"] == family)
        for gas, style in (("on", "-o"), ("off", "--s")):
            sel = sorted((r for r in rows if r["family"] == family and r["gas"] == gas), key=lambda r: r["grains"])
            n = [r["grains"] for r in sel]
            label = f"D = {diameter:g} mm, gas {gas}"
            ax1.plot(n, [r["us_per_step"] for r in sel], style, color=colours.get(family), label=label,
                     mfc="none" if gas == "off" else None)
            ax2.plot(n, [r["particle_steps_per_s"] for r in sel], style, color=colours.get(family), label=label,
                     mfc="none" if gas == "off" else None)
    ref = min(rows, key=lambda r: (r["family"] != "long", r["gas"] != "off", r["grains"]))
    n_all = np.array([min(r["grains"] for r in rows), max(r["grains"] for r in rows)], float)
    ax1.plot(n_all, ref["us_per_step"] * n_all / ref["grains"], ":", color="k", lw=1, label="slope 1 (cost ∝ N)")
    dt = ref["time_step_s"]
    budget = BUDGET_WALL / BUDGET_SIMULATED * dt * 1e6
    ax1.axhline(budget, color="grey", lw=0.8)
    ax1.text(n_all[0], budget * 0.8, f"{BUDGET_SIMULATED:g} simulated s per wall hour", fontsize=8, color="grey")
    ax1.set(xscale="log", yscale="log", xlabel="grains N", ylabel="wall time per step (µs)",
            title="cost of one time step")
    ax2.set(xscale="log", yscale="log", xlabel="grains N", ylabel="particle-steps per second (1/s)",
            title="throughput (one thread)")
    ax1.legend(fontsize=7)
    ax2.legend(fontsize=7)
    for ax in (ax1, ax2):
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
    fig.text(0.01, 0.01, f"wall time on one thread, load average {rows[0]['load_before']:.1f}-"
             f"{rows[0]['load_after']:.1f} on {os.cpu_count()} cores; CPU times and the table: scale.md",
             fontsize=7, color="grey")
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def read_csv(path: Path) -> list[dict]:
    """Rows of a scale.csv, typed as `study` returns them."""
    import csv
    ints = {"grains", "steps", "repeats", "grains_after"}
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        for k, v in row.items():
            if k in ints:
                row[k] = int(v)
            elif k not in {"family", "gas", "gas_grid"}:
                row[k] = float(v)
    return rows


def _meta(rows: list[dict], date: datetime.datetime, mode: str) -> dict:
    return {"date": date.isoformat(timespec="minutes"), "machine": _cpu_model(), "mode": mode,
            "load_before": rows[0]["load_before"], "load_after": rows[0]["load_after"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/scale"))
    parser.add_argument("--reduced", action="store_true", help="N up to 3000 in 7 and 14 mm tubes (CI)")
    parser.add_argument("--replot", metavar="CSV", type=Path,
                        help="only rewrite scale.md and scale.png from an existing scale.csv")
    parser.add_argument("--probe", help=argparse.SUPPRESS)  # internal: memory of one saved state
    args = parser.parse_args(argv)
    if args.probe:
        _probe(args.probe)
        return 0
    if args.replot:
        rows = read_csv(args.replot)
        date = datetime.datetime.fromtimestamp(args.replot.stat().st_mtime)
        meta = _meta(rows, date, "full" if max(r["grains"] for r in rows) > 5000 else "reduced")
        write_markdown(rows, args.out_dir / "scale.md", meta)
        plot(rows, args.out_dir / "scale.png")
        return 0
    settings = REDUCED if args.reduced else FULL
    start = time.perf_counter()
    rows = study(settings["families"], settings["grains"], settings["repeats"], settings["particle_steps"],
                 log=lambda m: print(m, flush=True))
    args.out_dir.mkdir(parents=True, exist_ok=True)
    meta = _meta(rows, datetime.datetime.now(), "reduced" if args.reduced else "full")
    write_csv(rows, args.out_dir / "scale.csv")
    write_markdown(rows, args.out_dir / "scale.md", meta)
    plot(rows, args.out_dir / "scale.png")
    print("\n".join(headline(rows)))
    print(f"wrote {args.out_dir}/scale.{{csv,md,png}} in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())

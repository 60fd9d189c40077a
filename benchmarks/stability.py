#!/usr/bin/env python
"""Numerical-stability stress sweep: which cases run, which are refused up front, which stop with a
reason, and proof that none blows up silently.

    python benchmarks/stability.py --out-dir results/benchmarks/stability [--reduced]

Every stress case is a case YAML (config/cases/horizontal.yaml or vertical.yaml) in a short tube
(3.5 cm, 10 gas nodes: 3.5 mm cells) plus overrides, varied one factor at a time from the default
(time step as a fraction of the contact time, superficial velocity, viscosity, friction and
restitution, dense feeds, an empty tube, gas off) and in a few combinations of the worst ones. Each
case is classified as exactly one of

  refused  engine.CaseError before any step (the case or the Simulation refuses it; message kept);
  stopped  the engine detected a numerical failure during the run (SimulationError from a step, or
           engine.run's per-frame health check: RunError); the one-line reason is kept;
  ran      finished, and no independent check below ever failed;
  SILENT   finished although an independent check failed at some point: a silent blow-up, an
           engine problem. The script reports it loudly and exits 1. So does `crashed` (any other
           exception).

The run loop is run_case's (advance one output interval, then engine.run._check_health), with the
state inspected here as well, independently of the engine's own checks, against what the engine
promises (docs/engine.md, "Failure detection" and "Runs and case files"): 50 times per frame the
engine's own largest overlap of the last force evaluation (at most engine.run.MAX_OVERLAP = 0.2 d);
10 times per frame finite positions, centres inside the cylinder, the mass books, and the largest
overlap computed here from the positions with a k-d tree (feed grains included); at every frame end
and at the end all of that plus finite velocities and pressure field and every centre within
R - r + 0.2 d of the axis and 0 <= x <= L. A failed check is an event: if the engine stops the run
later the case is `stopped` (run_case writes no file then; the first event is noted as the detection
latency), if the run finishes it is SILENT.

Chaos caveat: advancing in pieces is not bit-identical to run_case's one advance per frame once the
feed appends layers between pieces (the engine then re-sorts and re-evaluates the forces), so a
borderline case (a column heating up at the edge of the accepted time step) can fall on either side
of a check in the two loops; its outcome here is one sample, the heating itself is systematic.

Writes OUT/stability.csv (one row per case), OUT/stability.md (the table and a headline) and
OUT/stability.png (the map: one row per axis, one marker per case coloured by outcome). Every case runs
on one thread (the engine's default). Exit status: 0 no silent failure, 1 otherwise.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from engine import Case, CaseError, Simulation, SimulationError
from engine.contact import ContactModel
from engine.run import MAX_OVERLAP, RunError, _check_health

REPO = Path(__file__).resolve().parents[1]
BASES = {"horizontal": REPO / "config/cases/horizontal.yaml", "vertical": REPO / "config/cases/vertical.yaml"}
# Short and cheap: a 3.5 cm tube keeps the 3.5 mm gas cells of the 52.5 cm default with 10 nodes.
COMMON = {"tube.length": 0.035, "gas.nodes_x": 10, "run.checkpoint_interval": 0.0}
MONITORS_PER_FRAME = 50     # reads of the engine's own overlap per output interval (0.2 ms)
CHECKS_EVERY = 5            # independent checks every 5th read: 10 per output interval
HEATING_FACTOR = 10.0       # kinetic energy per grain above this multiple of the smallest-dt run: heating
MASS_TOLERANCE = 1e-9       # of one grain's mass: the books are integer counts times the grain mass
OUTCOMES = ("ran", "refused", "stopped", "SILENT", "crashed")
BAD = ("SILENT", "crashed")
TRAVEL_NOTE = 0.1           # v_max dt / d above this: one step can carry a pair past the overlap bound
PRESSURE_NOTE = 0.1         # max |P'| / P0 above this: the linearised gas equation (P' << P0) is strained


# ---- the cases --------------------------------------------------------------------------------
@dataclass(frozen=True)
class StressCase:
    """One stress case: a base YAML, overrides on top of COMMON, a simulated duration."""

    axis: str
    label: str                  # short name on the map and in the table
    base: str                   # "horizontal" or "vertical"
    overrides: dict = field(default_factory=dict)
    duration: float = 1.0       # simulated s
    x: float | None = None      # the varied time step (places the stable-limit line on the map)
    reduced: bool = False       # part of the --reduced subset (CI)

    def override_list(self) -> list[tuple[str, Any]]:
        merged = {**COMMON, "run.duration": self.duration, **self.overrides}
        return list(merged.items())

    def overrides_text(self) -> str:
        return "; ".join(f"{k}={v}" for k, v in self.overrides.items()) or "(none)"


# Rows of the map, in order: axis name -> what varies along it, with units.
TIME_STEP = "time step Δt / t_c (numerics.time_step_fraction, contact times)"
AXES: dict[str, str] = {
    "time step, horizontal": TIME_STEP,
    "time step, packed column": TIME_STEP,
    "time step, packed column, μ = μ_w = 1": TIME_STEP,
    "time step, undamped e = 1, γ_t = 0": TIME_STEP,
    "superficial velocity": "gas.superficial_velocity v_s (m/s)",
    "viscosity": "gas.viscosity η (Pa s; 1e-3 Pa s = 1 cP)",
    "contact law": "friction μ = μ_w (1), restitution e = e_w (1)",
    "dense feed": "feed.mass_flow_kg_h ṁ (kg/h) @ feed.entry_velocity u_in (m/s)",
    "empty tube, gas off": "feed ṁ (kg/h), gas v_s (m/s)",
    "combinations": "worst factors combined (v_s in m/s, η in cP, ṁ in kg/h, Δt in t_c; H/V: horizontal/vertical)",
}

PACKED = {"gas.enabled": False, "feed.mass_flow_kg_h": 9.95, "feed.entry_velocity": 0.16}
UNDAMPED = {"particles.restitution": 1.0, "wall.restitution": 1.0, "particles.tangential_damping": 0.0}
FRICTION_1 = {"particles.friction": 1.0, "wall.friction": 1.0}
HUGE_DRAG = {"gas.superficial_velocity": 20.0, "gas.viscosity": 1e-3}
FEED_50 = {"feed.mass_flow_kg_h": 50.0, "feed.entry_velocity": 0.8}


def stress_cases() -> list[StressCase]:
    """The full list (StressCase.reduced marks the CI subset)."""
    cases: list[StressCase] = []
    add = cases.append
    # Time step, one factor at a time. The single-pair limit at the defaults is the damped pair
    # spring's, 0.478 t_c at e = 0.5 (the tangential dashpot is capped, engine/contact.py), and the
    # engine accepts numerics.time_step_safety = 0.6 of it (0.287 t_c); undamped and frictionless,
    # 2/ω = 0.637 t_c, accepted up to 0.382 t_c. Rows with the margin off (time_step_safety = 1)
    # show what it protects against.
    for f in (0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.28, 0.3, 0.5, 1.0, 2.0):
        add(StressCase("time step, horizontal", f"{f:g}", "horizontal",
                       {"numerics.time_step_fraction": f}, x=f, reduced=f in (0.05, 0.5)))
    # A column pushed up by a dense feed with the gas off: every grain in contact, the stiffest modes.
    for f in (0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.28, 0.3):
        add(StressCase("time step, packed column", f"{f:g}", "vertical",
                       {**PACKED, "numerics.time_step_fraction": f}, x=f, reduced=f == 0.28))
    for f in (0.3, 0.35, 0.4, 0.45):
        add(StressCase("time step, packed column, margin off", f"{f:g}", "vertical",
                       {**PACKED, "numerics.time_step_fraction": f, "numerics.time_step_safety": 1.0}, x=f))
    # The same column with the friction of the papers' vertical friction sweep at its top (μ = 1).
    for f in (0.05, 0.1, 0.15, 0.2, 0.25, 0.28):
        add(StressCase("time step, packed column, μ = μ_w = 1", f"{f:g}", "vertical",
                       {**PACKED, **FRICTION_1, "numerics.time_step_fraction": f}, x=f))
    for f in (0.3, 0.35, 0.4, 0.45):
        add(StressCase("time step, packed column, μ = μ_w = 1, margin off", f"{f:g}", "vertical",
                       {**PACKED, **FRICTION_1, "numerics.time_step_fraction": f,
                        "numerics.time_step_safety": 1.0}, x=f))
    for f in (0.1, 0.3, 0.38, 0.4, 0.5):
        add(StressCase("time step, undamped e = 1, γ_t = 0", f"{f:g}", "vertical",
                       {**UNDAMPED, "numerics.time_step_fraction": f}, x=f))
    for f in (0.45, 0.5, 0.55, 0.6, 0.63, 0.65):
        add(StressCase("time step, undamped, margin off", f"{f:g}", "vertical",
                       {**UNDAMPED, "numerics.time_step_fraction": f, "numerics.time_step_safety": 1.0},
                       x=f, reduced=f == 0.6))
    for v in (0.0, 0.1, 1.0, 5.0, 10.0, 20.0):
        add(StressCase("superficial velocity", f"{v:g}", "horizontal", {"gas.superficial_velocity": v},
                       x=v, reduced=v == 20.0))
    for eta in (1e-5, 6.73e-5, 1e-3):
        add(StressCase("viscosity", f"{eta:g}", "horizontal", {"gas.viscosity": eta}, x=eta))
    for label, ov in [("μ = 0", {"particles.friction": 0.0, "wall.friction": 0.0}),
                      ("μ = 1", FRICTION_1),
                      ("e = 0.99", {"particles.restitution": 0.99, "wall.restitution": 0.99}),
                      ("e = 1", {"particles.restitution": 1.0, "wall.restitution": 1.0}),
                      ("μ = 0, e = 1", {"particles.friction": 0.0, "wall.friction": 0.0,
                                        "particles.restitution": 1.0, "wall.restitution": 1.0}),
                      ("e = 0.15 (lowest)", {"particles.restitution": 0.15, "wall.restitution": 0.15}),
                      ("e = 0.1 (below range)", {"particles.restitution": 0.1, "wall.restitution": 0.1})]:
        add(StressCase("contact law", label, "horizontal", ov))
    for label, flow, speed, reduced in [("2.49 @ 0.04", 2.49, 0.04, False), ("9.95 @ 0.16", 9.95, 0.16, False),
                                        ("20 @ 0.35", 20.0, 0.35, False), ("50 @ 0.8", 50.0, 0.8, False),
                                        ("9.95 @ 0.04", 9.95, 0.04, False), ("50 @ 0.16", 50.0, 0.16, True)]:
        add(StressCase("dense feed", label, "horizontal",
                       {"feed.mass_flow_kg_h": flow, "feed.entry_velocity": speed}, duration=0.5,
                       reduced=reduced))
    for label, base, ov, reduced in [
            ("empty, v_s = 1", "horizontal", {"feed.mass_flow_kg_h": 0.0}, True),
            ("empty, v_s = 20", "horizontal", {"feed.mass_flow_kg_h": 0.0, "gas.superficial_velocity": 20.0}, False),
            ("empty, gas off", "horizontal", {"feed.mass_flow_kg_h": 0.0, "gas.enabled": False}, False),
            ("2.49, gas off (H)", "horizontal", {"gas.enabled": False}, False),
            ("2.49, gas off (V)", "vertical", {"gas.enabled": False}, False)]:
        add(StressCase("empty tube, gas off", label, base, ov, reduced=reduced))
    for label, base, ov, duration, reduced in [
            ("v_s 20, η 1 (H)", "horizontal", HUGE_DRAG, 1.0, False),
            ("v_s 20, η 1, ṁ 50 (H)", "horizontal", {**HUGE_DRAG, **FEED_50}, 0.5, True),
            ("v_s 20, η 1, ṁ 9.95 (V)", "vertical",
             {**HUGE_DRAG, "feed.mass_flow_kg_h": 9.95, "feed.entry_velocity": 0.16}, 0.5, False),
            ("v_s 20, η 0.01, Δt 0.19 (H)", "horizontal",
             {"gas.superficial_velocity": 20.0, "gas.viscosity": 1e-5, "numerics.time_step_fraction": 0.19}, 1.0, False),
            ("v_s 20, μ 0, e 0.99, Δt 0.29 (H)", "horizontal",
             {"gas.superficial_velocity": 20.0, "particles.friction": 0.0, "wall.friction": 0.0,
              "particles.restitution": 0.99, "wall.restitution": 0.99, "numerics.time_step_fraction": 0.29}, 1.0, False),
            ("ṁ 50, Δt 0.19 (V)", "vertical", {**FEED_50, "numerics.time_step_fraction": 0.19}, 0.5, False),
            ("ṁ 50, gas off, Δt 0.19 (V)", "vertical",
             {**FEED_50, "gas.enabled": False, "numerics.time_step_fraction": 0.19}, 0.5, False),
            # without the tangential dashpot the limit is the damped pair's, 0.478 t_c at e = 0.5,
            # accepted up to 0.6 of it (0.287)
            ("γ_t 0, packed, Δt 0.28 (V)", "vertical",
             {**PACKED, "particles.tangential_damping": 0.0, "numerics.time_step_fraction": 0.28}, 1.0, False),
            # frictionless: no tangential-dashpot limit, the normal one (0.6 x 0.50 t_c) applies
            ("μ 0, Δt 0.29 (H)", "horizontal",
             {"particles.friction": 0.0, "wall.friction": 0.0, "numerics.time_step_fraction": 0.29}, 1.0, False),
            ("μ 0, Δt 0.4 (H)", "horizontal",
             {"particles.friction": 0.0, "wall.friction": 0.0, "numerics.time_step_fraction": 0.4}, 1.0, False),
            ("e 1, γ_t 0, μ 0, ṁ 50, gas off, Δt 0.6 (V)", "vertical",
             {**UNDAMPED, **FEED_50, "particles.friction": 0.0, "wall.friction": 0.0, "gas.enabled": False,
              "numerics.time_step_fraction": 0.6, "numerics.time_step_safety": 1.0}, 0.5, False),
            # tests/engine/test_run.py::test_numerical_failure_exits_1_with_one_line_and_no_file
            ("e 1, γ_t 0, Δt 0.6, 3 cm (V; engine test)", "vertical",
             {**UNDAMPED, "numerics.time_step_fraction": 0.6, "numerics.time_step_safety": 1.0,
              "tube.length": 0.03, "gas.nodes_x": 8}, 1.0, False)]:
        add(StressCase("combinations", label, base, ov, duration=duration, reduced=reduced))
    return cases


def build_case(spec: StressCase) -> Case:
    """The engine Case of a stress case (raises CaseError when the case is refused)."""
    return Case.from_yaml(BASES[spec.base], spec.override_list())


def stable_fraction(spec: StressCase) -> float:
    """The stable time-step limit of the case's contact law, in contact times (nan if refused otherwise)."""
    try:
        model = ContactModel.from_case(build_case(spec).with_overrides([("numerics.time_step_fraction", 1e-3)]))
    except CaseError:
        return math.nan
    return model.stable_time_step / model.contact_time


# ---- the independent checks -------------------------------------------------------------------
def state_of(sim: Simulation) -> dict[str, Any]:
    """Everything the checks need, read from a Simulation (copies; the feed grains included)."""
    n_all = int(sim._n[0])
    in_feed = sim._in_feed[:n_all] == 1  # grains of the feed layers, held in place until released
    gas_on = bool(sim.case["gas.enabled"])
    return {
        "positions": np.array(sim.positions), "velocities": np.array(sim.velocities),
        "angular_velocities": np.array(sim.angular_velocities),
        "feed_positions": np.array(sim._pos[:n_all][in_feed]),
        "n_particles": sim.n_particles, "mass_in": sim.mass_in, "mass_out": sim.mass_out,
        "grain_mass": sim.model.mass, "radius": sim.model.radius,
        "tube_radius": sim.case["tube.diameter"] / 2, "tube_length": sim.case["tube.length"],
        "time": sim.time, "dt": sim.dt,
        "feed_limit": (sim.feed.mass_flow * sim.time + sim.feed.layer_mass) if sim.feed.enabled else 0.0,
        "pressure_drop": sim.pressure_drop if gas_on else 0.0,
        "gas_pressure": np.array(sim.gas.pressure) if gas_on else np.zeros(1),
        "gas_reference": sim.case["gas.pressure"],
    }


def max_overlap(state: dict[str, Any]) -> float:
    """Largest overlap (m): grain-grain (feed grains included), grain-cylinder, grain-inlet plane."""
    pos, r = state["positions"], state["radius"]
    d = 2 * r
    if not np.all(np.isfinite(pos)):
        return math.nan
    worst = 0.0
    if len(pos):
        rho = np.hypot(pos[:, 1], pos[:, 2])
        worst = max(worst, float(np.max(rho + r - state["tube_radius"])), float(np.max(r - pos[:, 0])))
        feed = state.get("feed_positions", np.zeros((0, 3)))
        everything = np.vstack([pos, feed]) if len(feed) else pos
        tree = cKDTree(everything)
        pairs = tree.query_pairs(d, output_type="ndarray")
        if len(pairs):
            pairs = pairs[pairs[:, 0] < len(pos)]  # at least one dynamic grain (feed-feed pairs are fixed)
        if len(pairs):
            dist = np.linalg.norm(everything[pairs[:, 0]] - everything[pairs[:, 1]], axis=1)
            worst = max(worst, float(np.max(d - dist)))
    return max(worst, 0.0)


def check_state(state: dict[str, Any], full: bool = True) -> tuple[dict[str, bool], dict[str, float]]:
    """Independent checks of a state (see state_of): ({check: passed}, {measure: value}).

    full=True (what the engine guarantees at the end of every output frame, and so at the end):
      finite   positions, velocities, angular velocities, pressure drop and pressure field finite;
      inside   every centre in the tube: sqrt(y^2+z^2) <= R - r + MAX_OVERLAP d and 0 <= x <= L;
      overlap  the largest overlap (max_overlap) at most MAX_OVERLAP d;
      mass     mass_in - mass_out = n m to MASS_TOLERANCE m, and 0 <= mass_in <= m_dot t + one layer.
    full=False (what the engine's drift guard guarantees after every step): finite positions,
      centres inside the cylinder (sqrt(y^2+z^2) <= R) with -r <= x <= L, and the mass books.
    """
    pos, vel, omg = state["positions"], state["velocities"], state["angular_velocities"]
    r, R, L = state["radius"], state["tube_radius"], state["tube_length"]
    d, m = 2 * r, state["grain_mass"]
    finite = bool(np.all(np.isfinite(pos)))
    if full:
        finite = finite and bool(np.all(np.isfinite(vel)) and np.all(np.isfinite(omg))
                                 and math.isfinite(state["pressure_drop"])
                                 and np.all(np.isfinite(state["gas_pressure"])))
    with np.errstate(invalid="ignore"):
        rho = np.hypot(pos[:, 1], pos[:, 2])
        limit, x_min = (R - r + MAX_OVERLAP * d, 0.0) if full else (R, -r)
        inside = bool(np.all(rho <= limit) and np.all(pos[:, 0] >= x_min) and np.all(pos[:, 0] <= L * (1 + 1e-12)))
    books = state["mass_in"] - state["mass_out"] - state["n_particles"] * m
    mass = bool(len(pos) == state["n_particles"] and abs(books) <= MASS_TOLERANCE * m
                and 0.0 <= state["mass_in"] <= state["feed_limit"] * (1 + 1e-9) + MASS_TOLERANCE * m
                and state["mass_out"] >= 0.0)
    checks = {"finite": finite, "inside": inside}
    worst = max_overlap(state)
    measures = {"mass_books_over_m": books / m, "max_overlap_over_d": worst / d,
                "max_speed": float(np.max(np.linalg.norm(vel, axis=1))) if len(vel) else 0.0,
                "max_pressure_over_P0": float(np.max(np.abs(state["gas_pressure"]))) / state["gas_reference"]}
    if full:
        checks["overlap"] = bool(math.isfinite(worst) and worst <= MAX_OVERLAP * d)
    checks["mass"] = mass
    return checks, measures


def failed(checks: dict[str, bool]) -> list[str]:
    return [name for name, ok in checks.items() if not ok]


# ---- one case ---------------------------------------------------------------------------------
def first_line(err: BaseException) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__


def run_stress_case(spec: StressCase, monitors_per_frame: int = MONITORS_PER_FRAME,
                    checks_every: int = CHECKS_EVERY) -> dict[str, Any]:
    """Run one stress case and classify it; returns its table row (a dict).

    Each output frame is advanced in `monitors_per_frame` pieces; after each piece the engine's own
    overlap of the last force evaluation is read (cheap), and after every `checks_every`-th piece
    the independent checks run. After the last piece of a frame comes run_case's frame check
    (engine.run._check_health), then the full independent checks. An overlap past the bound or a
    failed independent check is an event; the run goes on. If the engine stops the run later, the
    case is `stopped` (run_case then writes no file, so nothing wrong gets out; the first event is
    noted as the detection latency); if the run finishes, the case is SILENT (the first event is the
    reason).
    """
    row: dict[str, Any] = {"axis": spec.axis, "case": spec.label, "base": spec.base,
                           "overrides": spec.overrides_text(), "duration_s": spec.duration,
                           "outcome": "", "reason": "", "checks": "", "wall_s": 0.0, "steps": 0,
                           "time_step_s": math.nan, "time_step_over_tc": math.nan, "stable_over_tc": math.nan,
                           "n_particles": math.nan, "pressure_drop_Pa": math.nan,
                           "max_overlap_over_d": math.nan, "max_overlap_sampled_over_d": math.nan,
                           "max_speed_m_s": math.nan, "max_kinetic_energy_per_grain_J": math.nan, "notes": ""}
    start = time.perf_counter()
    try:
        case = build_case(spec)
        sim = Simulation(case)
    except CaseError as err:
        row.update(outcome="refused", reason=first_line(err), wall_s=time.perf_counter() - start)
        return row
    except Exception as err:  # noqa: BLE001 - anything else is a crash, reported loudly
        row.update(outcome="crashed", reason=f"{type(err).__name__}: {first_line(err)}",
                   wall_s=time.perf_counter() - start)
        return row
    model = sim.model
    d = 2 * model.radius
    row.update(time_step_s=sim.dt, time_step_over_tc=sim.dt / model.contact_time,
               stable_over_tc=model.stable_time_step / model.contact_time)
    interval = case["output.interval"]
    per_frame = int(round(interval / sim.dt))
    bounds = np.linspace(0, per_frame, min(monitors_per_frame, per_frame) + 1).round().astype(int)
    pieces = [int(b) for b in np.diff(bounds) if b > 0]
    frames = int(round(spec.duration / interval))
    sampled = max_pressure = max_kinetic = 0.0
    events: list[str] = []   # the first event the engine did not stop on (later ones are not needed)
    outcome, reason = "ran", ""

    def note_event(what: str) -> None:
        if not events:
            events.append(f"{what} at t = {sim.time:.4f} s")

    try:
        for _ in range(frames):
            for k, steps in enumerate(pieces):
                sim.advance(steps * sim.dt)
                max_kinetic = max(max_kinetic, sim.kinetic_energy / max(sim.n_particles, 1))
                if k == len(pieces) - 1:
                    break  # the frame end: the engine's own frame check comes first
                engine_overlap = sim.max_overlap / d
                sampled = max(sampled, engine_overlap)
                if engine_overlap > MAX_OVERLAP:
                    note_event(f"overlap {engine_overlap:.3f} d > {MAX_OVERLAP} d (engine's own value, "
                                f"between output frames)")
                if (k + 1) % checks_every == 0:
                    quick, measures = check_state(state_of(sim), full=False)
                    sampled = max(sampled, measures["max_overlap_over_d"])
                    max_pressure = max(max_pressure, measures["max_pressure_over_P0"])
                    if failed(quick):
                        note_event(f"check {', '.join(failed(quick))} failed (between output frames)")
                    if measures["max_overlap_over_d"] > MAX_OVERLAP:
                        note_event(f"overlap {measures['max_overlap_over_d']:.3f} d > {MAX_OVERLAP} d "
                                   f"(between output frames)")
            _check_health(sim)  # exactly what run_case does after every frame ...
            sim.reset_max_overlap()  # ... and the next frame's overlap window
            checks, measures = check_state(state_of(sim))
            sampled = max(sampled, measures["max_overlap_over_d"])
            max_pressure = max(max_pressure, measures["max_pressure_over_P0"])
            if failed(checks):
                note_event(f"check {', '.join(failed(checks))} failed at a frame end")
    except (SimulationError, RunError) as err:
        outcome, reason = "stopped", first_line(err)
    except Exception as err:  # noqa: BLE001
        outcome, reason = "crashed", f"{type(err).__name__}: {first_line(err)}"
    row["wall_s"] = time.perf_counter() - start
    final, measures = check_state(state_of(sim))
    sampled = max(sampled, measures["max_overlap_over_d"])
    outcome, reason = classify(outcome, reason, events, final, sim.time)
    row.update(outcome=outcome, reason=reason, steps=sim._steps, n_particles=sim.n_particles,
               pressure_drop_Pa=sim.pressure_drop if case["gas.enabled"] else 0.0,
               max_overlap_over_d=measures["max_overlap_over_d"], max_overlap_sampled_over_d=sampled,
               max_speed_m_s=measures["max_speed"], max_kinetic_energy_per_grain_J=max_kinetic,
               checks=", ".join(f"{k} {'ok' if v else 'FAILED'}" for k, v in final.items()))
    # Notes on finished runs: what a reader should know although no check failed.
    notes = []
    if outcome == "stopped" and events:
        notes.append(f"first sign before the stop: {events[0]}")
    if outcome in ("ran", "SILENT"):
        travel = measures["max_speed"] * sim.dt / d
        if travel > TRAVEL_NOTE:
            notes.append(f"v_max dt = {travel:.2f} d: one step can carry a pair past the overlap bound")
        if max_pressure > PRESSURE_NOTE:
            notes.append(f"max |P'| = {max_pressure:.2f} P0: the linearised gas equation (P' << P0) is strained")
        if case["gas.enabled"] and not sim.feed.enabled and sim.n_particles == 0:
            notes.append(f"empty tube: dp = {sim.pressure_drop:.4g} Pa (no wall shear on the gas: "
                         f"eta v_s L / kappa(phi_max) {empty_tube_drop(case):.4g} Pa)")
    row["notes"] = "; ".join(notes)
    return row


def empty_tube_drop(case) -> float:
    """Darcy drop of the empty tube, Pa: every node reads kappa at the porosity ceiling."""
    phi, d = case["gas.porosity_max"], case["particles.diameter"]
    kappa = d**2 * phi**3 / (180 * (1 - phi) ** 2)
    return case["gas.viscosity"] * case["gas.superficial_velocity"] * case["tube.length"] / kappa


def classify(engine_outcome: str, engine_reason: str, events: list[str], final: dict[str, bool],
             end_time: float) -> tuple[str, str]:
    """(outcome, reason) of a case that started: `engine_outcome` is "ran" (no exception), "stopped"
    or "crashed"; `events` the failed checks seen during the run; `final` the checks of the final
    state. A run that finished with any failed check is SILENT."""
    if engine_outcome != "ran":
        return engine_outcome, engine_reason
    if failed(final):
        events = [*events, f"check {', '.join(failed(final))} failed in the final state (t = {end_time:.4f} s)"]
    if events:
        return "SILENT", f"{events[0]} and the run finished without a failure"
    return "ran", f"finished t = {end_time:.3f} s"


def note_heating(rows: list[dict], factor: float = HEATING_FACTOR) -> None:
    """On the time-step axes, note runs whose largest kinetic energy per grain exceeds `factor` times
    that of the axis's smallest time step that finished (the same case otherwise): numerical heating."""
    for axis in {r["axis"] for r in rows if r["axis"].startswith("time step")}:
        done = [r for r in rows if r["axis"] == axis and r["outcome"] in ("ran", "SILENT")]
        if len(done) < 2:
            continue
        ref = min(done, key=lambda r: r["time_step_over_tc"])
        if not ref["max_kinetic_energy_per_grain_J"] > 0:
            continue
        for r in done:
            ratio = r["max_kinetic_energy_per_grain_J"] / ref["max_kinetic_energy_per_grain_J"]
            if r is not ref and ratio > factor:
                text = (f"numerical heating: kinetic energy per grain up to {ratio:.0f}x that at "
                        f"Δt = {ref['time_step_over_tc']:.2f} t_c")
                r["notes"] = f"{text}; {r['notes']}" if r["notes"] else text


def warm_up() -> float:
    """Load the compiled kernels once (numba cache) so that per-case wall times exclude it."""
    start = time.perf_counter()
    for gas in (True, False):
        sim = Simulation(Case.from_yaml(BASES["horizontal"], [*COMMON.items(), ("gas.enabled", gas)]))
        sim.advance(0.002)
        check_state(state_of(sim))
    return time.perf_counter() - start


# ---- outputs ----------------------------------------------------------------------------------
COLUMNS = ["axis", "case", "base", "overrides", "outcome", "reason", "checks", "wall_s", "steps",
           "duration_s", "time_step_s", "time_step_over_tc", "stable_over_tc", "n_particles",
           "pressure_drop_Pa", "max_overlap_over_d", "max_overlap_sampled_over_d", "max_speed_m_s",
           "max_kinetic_energy_per_grain_J", "notes"]


def headline(rows: list[dict]) -> str:
    count = {o: sum(r["outcome"] == o for r in rows) for o in OUTCOMES}
    text = (f"{len(rows)} cases: {count['ran']} ran, {count['refused']} refused up front, "
            f"{count['stopped']} stopped with a reason, {count['SILENT']} silent")
    if count["crashed"]:
        text += f", {count['crashed']} CRASHED"
    return text


def write_csv(rows: list[dict], path: Path, attrs: dict) -> None:
    import pandas as pd

    table = pd.DataFrame(rows, columns=COLUMNS)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as handle:
        handle.write("# attrs: " + json.dumps(attrs) + "\n")
        table.to_csv(handle, index=False, float_format="%.6g")
    os.replace(tmp, path)


def _fmt(value: Any, spec: str) -> str:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return "–" if not math.isfinite(value) else format(value, spec)
    return str(value)


def write_markdown(rows: list[dict], path: Path, attrs: dict) -> None:
    lines = ["# Numerical-stability stress sweep", "",
             f"**{headline(rows)}.** Total wall time {attrs['total_wall_s']:.0f} s on one thread "
             f"({attrs['machine']}; the run's date is in the CSV's attributes).", "",
             f"Each case: `{attrs['bases']}` with {attrs['common']} plus the overrides listed, run "
             f"for `duration` simulated seconds (1 s; 0.5 s for the dense feeds) from an empty tube, the "
             f"loop of engine.run.run_case. `refused`: engine.CaseError before any step. `stopped`: the "
             f"engine stopped the run with a one-line reason (SimulationError from a step, or "
             f"run_case's per-frame health check); run_case writes no file then. `ran`: finished, "
             f"and no independent check ever failed: the engine's own largest overlap read 50 times "
             f"per 0.01 s frame; 10 times per frame finite positions, centres inside the cylinder, "
             f"mass_in − mass_out = n m and the largest overlap computed here from the positions "
             f"(feed grains included); at every frame end and at the end also finite velocities and "
             f"pressure, centres within R − r + {MAX_OVERLAP} d and 0 ≤ x ≤ L; overlaps at most "
             f"{MAX_OVERLAP} d throughout. `SILENT`: finished although a check failed. `max overlap` is "
             f"the final state's, `sampled` the largest seen at any check; `notes` flag numerical "
             f"heating (largest kinetic energy per grain over {HEATING_FACTOR:g} times that of the "
             f"axis's smallest time step), a first failed check before a stop (detection latency), "
             f"steps longer than {TRAVEL_NOTE} d at v_max, |P'| above {PRESSURE_NOTE} P0. Produced by "
             f"`python benchmarks/stability.py`{' --reduced' if attrs['reduced'] else ''}.", "",
             *_problems(rows),
             "| axis | case | base | overrides | outcome | reason | checks | wall (s) | steps | Δt/t_c | "
             "grains | Δp (Pa) | max overlap / d | sampled / d | v_max (m/s) | notes |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        outcome = f"**{r['outcome']}**" if r["outcome"] in BAD else r["outcome"]
        lines.append("| " + " | ".join([
            r["axis"], r["case"], r["base"][0].upper(), f"`{r['overrides']}`", outcome,
            r["reason"].replace("|", "\\|"), r["checks"], _fmt(r["wall_s"], ".1f"), _fmt(r["steps"], "d"),
            _fmt(r["time_step_over_tc"], ".3f"), _fmt(r["n_particles"], ".0f"), _fmt(r["pressure_drop_Pa"], ".4g"),
            _fmt(r["max_overlap_over_d"], ".3f"), _fmt(r["max_overlap_sampled_over_d"], ".3f"),
            _fmt(r["max_speed_m_s"], ".3g"), r["notes"].replace("|", "\\|")]) + " |")
    path.write_text("\n".join(lines) + "\n")


def _problems(rows: list[dict]) -> list[str]:
    """Markdown lines listing the silent cases and the finished runs with a warning note."""
    lines = []
    bad = [r for r in rows if r["outcome"] in BAD]
    if bad:
        lines += [f"**{len(bad)} case(s) {'/'.join(sorted({r['outcome'] for r in bad}))}** (an engine "
                  f"problem: the run did not stop although the state was wrong):", ""]
        lines += [f"- {r['axis']} / {r['case']}: {r['reason']}" for r in bad] + [""]
    warned = [r for r in rows if r["outcome"] == "ran" and r["notes"] and r["wall_s"] > 0
              and "empty tube" not in r["notes"]]
    if warned:
        lines += ["Finished runs with a warning (no check failed):", ""]
        lines += [f"- {r['axis']} / {r['case']}: {r['notes']}" for r in warned] + [""]
    return lines


COLOURS = {"ran": "tab:green", "refused": "tab:blue", "stopped": "tab:orange", "SILENT": "tab:red",
           "crashed": "black"}
MARKERS = {"horizontal": "o", "vertical": "^"}


def _limit_position(xs: list[float], limit: float) -> float:
    """Where `limit` falls on a categorical row whose values xs ascend (linear between neighbours)."""
    for i in range(len(xs) - 1):
        if xs[i] <= limit < xs[i + 1]:
            return i + (limit - xs[i]) / (xs[i + 1] - xs[i])
    return len(xs) - 0.5 if limit >= xs[-1] else -0.5


def write_map(rows: list[dict], specs: list[StressCase], path: Path, title: str) -> None:
    """One row per axis, one marker per case (colour: outcome, shape: tube), equally spaced and
    labelled with the varied value; on the time-step rows a dashed line marks the stable limit the
    engine accepts."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    axes = [a for a in AXES if any(s.axis == a for s in specs)]
    fig = Figure(figsize=(10, 1.15 * len(axes) + 1.2), layout="constrained")
    grid = fig.subplots(len(axes), 1, squeeze=False)[:, 0]
    by_label = {(r["axis"], r["case"]): r for r in rows}
    for ax, axis in zip(grid, axes):
        members = [s for s in specs if s.axis == axis]
        for i, s in enumerate(members):
            r = by_label[(s.axis, s.label)]
            ax.scatter([i], [0], s=70, c=COLOURS[r["outcome"]], marker=MARKERS[s.base], edgecolors="k",
                       linewidths=0.5, zorder=3)
        rotate = axis == "combinations"
        ax.set_xticks(range(len(members)), [s.label for s in members], fontsize=7,
                      rotation=20 if rotate else 0, ha="right" if rotate else "center",
                      rotation_mode="anchor")
        ax.set_xlim(-0.6, len(members) - 0.4)
        if axis.startswith("time step"):
            limit = stable_fraction(members[0])
            xs = [s.x for s in members]
            if math.isfinite(limit) and all(x is not None for x in xs):
                at = _limit_position(xs, limit)
                ax.axvline(at, color="0.3", ls="--", lw=1)
                right = at > (len(members) - 1) / 2
                ax.text(at, 0.55, f" stable limit {limit:.3f} t_c: refused above " if right else
                        f" stable limit {limit:.3f} t_c: refused above", fontsize=7, va="center",
                        ha="right" if right else "left")
        ax.set_yticks([])
        ax.set_ylim(-1, 1)
        ax.set_xlabel(AXES[axis], fontsize=8, labelpad=1)
        ax.set_title(axis, fontsize=9, loc="left", pad=2)
    handles = [Line2D([], [], ls="", marker="s", color=COLOURS[o], label=o) for o in OUTCOMES
               if o in ("ran", "refused", "stopped", "SILENT") or any(r["outcome"] == o for r in rows)]
    handles += [Line2D([], [], ls="", marker=MARKERS[b], mfc="white", mec="k", label=f"{b} tube") for b in MARKERS]
    fig.suptitle(title, fontsize=10)
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=8, frameon=False)
    fig.savefig(path, dpi=130)


# ---- main -------------------------------------------------------------------------------------
def select(reduced: bool) -> list[StressCase]:
    cases = stress_cases()
    return [c for c in cases if c.reduced] if reduced else cases


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", default="results/benchmarks/stability", type=Path)
    parser.add_argument("--reduced", action="store_true", help="the CI subset (about 8 cases, under a minute)")
    args = parser.parse_args(argv)
    import numba

    numba.set_num_threads(1)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    specs = select(args.reduced)
    started = time.perf_counter()
    warm = warm_up()
    print(f"warm-up (numba cache) {warm:.1f} s; {len(specs)} cases", file=sys.stderr, flush=True)
    rows, done = [], {}
    for spec in specs:
        try:
            key = (build_case(spec).to_yaml(), spec.duration)
        except CaseError:
            key = None  # refused: cheap, never shared
        if key in done:  # the default point of several axes: run once, listed on each row
            first = done[key]
            same = f"the run of {first['axis']} / {first['case']} (identical case, run once)"
            row = {**first, "axis": spec.axis, "case": spec.label, "overrides": spec.overrides_text(),
                   "wall_s": 0.0, "notes": "; ".join(filter(None, [same, first["notes"]]))}
        else:
            row = run_stress_case(spec)
            if key is not None:
                done[key] = row
        rows.append(row)
        print(f"{row['outcome']:>8}  {row['wall_s']:6.1f} s  {spec.axis} / {spec.label}: {row['reason']}"
              + (f"  [{row['notes']}]" if row["notes"] else ""), file=sys.stderr, flush=True)
    note_heating(rows)
    total = time.perf_counter() - started
    attrs = {"headline": headline(rows), "total_wall_s": round(total, 1), "warm_up_s": round(warm, 1),
             "reduced": args.reduced, "overlap_bound_over_d": MAX_OVERLAP,
             "bases": ", ".join(str(p.relative_to(REPO)) for p in BASES.values()),
             "common": ", ".join(f"{k} = {v}" for k, v in COMMON.items()),
             "threads": 1, "machine": f"{platform.machine()} {os.cpu_count()} CPUs",
             "date": datetime.datetime.now().isoformat(timespec="seconds"),
             "units": {"wall_s": "s", "duration_s": "s (simulated)", "time_step_s": "s",
                       "pressure_drop_Pa": "Pa", "max_speed_m_s": "m/s",
                       "time_step_over_tc": "1 (contact times)", "max_overlap_over_d": "1 (grain diameters)"}}
    write_csv(rows, args.out_dir / "stability.csv", attrs)
    write_markdown(rows, args.out_dir / "stability.md", attrs)
    write_map(rows, specs, args.out_dir / "stability.png", f"Stability stress sweep: {headline(rows)}")
    print(headline(rows) + f" ({total:.0f} s wall)", flush=True)
    bad = [r for r in rows if r["outcome"] in BAD]
    for r in bad:
        what = ("the run finished although the state went wrong" if r["outcome"] == "SILENT"
                else "an unexpected exception")
        print(f"{r['outcome']}: {r['axis']} / {r['case']} ({r['base']}, {r['overrides']}): {r['reason']} "
              f"-- an engine problem: {what}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

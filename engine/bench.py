"""Grain-engine benchmark on the standard dense case (python -m engine.bench, or `plugsim bench`).

The standard case: the default 7 mm x 0.525 m horizontal tube with a 6 cm plug that fills the
cross-section and a settled bed in the rest of the tube, about 3200 grains, gas and feed off. It is
the problem LAMMPS runs in benchmarks/lammps/ (same grains, same contact law, one core).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba as nb
import numpy as np

from .case import Case
from .feed import layer_template
from .kernels import contacts, passes
from .parser import OneLineParser
from .simulation import Simulation

PLUG_LENGTH = 0.06  # m
PLUG_START = 0.2    # m
TARGET_GRAINS = 3200


def standard_case(*overrides: str) -> Case:
    """The benchmark case: defaults with gas and feed off, the explicit tangential dashpot."""
    # the papers' explicit tangential law, as LAMMPS gran/hooke integrates it (benchmarks/lammps)
    return Case().with_overrides(["gas.enabled=false", "feed.mass_flow_kg_h=0", "numerics.implicit_spin=false",
                                  *overrides])


def standard_packing(case: Case) -> np.ndarray:
    """Grain centres (n, 3) of a plug plus a bed, on stacked ring layers (before settling)."""
    d, length = case["particles.diameter"], case["tube.length"]
    template = layer_template(case["tube.diameter"] / 2, d)
    spacing = 1.02 * d
    xs = np.arange(d, length - d, spacing)
    plug = (xs >= PLUG_START) & (xs < PLUG_START + PLUG_LENGTH)
    n_plug = plug.sum() * len(template)
    # bed: the lowest grains of each layer, as many as give about TARGET_GRAINS in all
    per_layer = max(1, round((TARGET_GRAINS - n_plug) / (~plug).sum()))
    return stack_layers(xs, plug, template, per_layer, d, np.random.default_rng(0))


def stack_layers(xs, full, template, per_layer: int, d: float, rng) -> np.ndarray:
    """Grain centres (n, 3): a randomly rotated ring layer `template` (k, 2) at each x (m); full
    layers where `full`, else only its lowest `per_layer` grains (a bed); small axial jitter."""
    layers = []
    for x, whole in zip(xs, full):
        angle = rng.uniform(0, 2 * np.pi)  # random layer rotations break the lattice symmetry
        c, s = np.cos(angle), np.sin(angle)
        yz = template @ np.array([[c, s], [-s, c]])
        if not whole:
            yz = yz[np.argsort(yz[:, 1])[:per_layer]]
        jitter = rng.uniform(-0.004, 0.004, len(yz)) * d
        layers.append(np.column_stack([x + jitter, yz]))
    return np.vstack(layers)


def settled_simulation(*overrides: str, settle_time: float = 0.05, threads: int = 1) -> Simulation:
    """The standard case after letting the bed settle under gravity (on one thread, so that the
    packing is the same for any `threads`, which then applies to the timed steps)."""
    sim = Simulation(standard_case(*overrides))
    sim.add_particles(standard_packing(sim.case))
    sim.advance(settle_time)
    sim.set_threads(threads)
    return sim


def contacts_per_grain(sim: Simulation) -> float:
    """Mean number of touching neighbours per grain, the cylinder and inlet walls included."""
    pos, d = sim.positions, 2 * sim.model.radius
    order = np.argsort(pos[:, 0])
    pos = pos[order]
    pairs = 0
    for shift in range(1, 64):  # grains sorted by x: partners lie within a few dozen places
        dist = np.linalg.norm(pos[shift:] - pos[:-shift], axis=1)
        pairs += np.count_nonzero(dist < d)
    wall = np.count_nonzero(np.hypot(pos[:, 1], pos[:, 2]) + d / 2 > sim.case["tube.diameter"] / 2)
    wall += np.count_nonzero(pos[:, 0] < d / 2)
    return (2 * pairs + wall) / len(pos)


def contact_count(sim: Simulation) -> dict:
    """Touching contacts of the present state, as the contact kernel sees them: grain pairs of the
    neighbour list closer than d, cylinder and inlet contacts of the dynamic grains."""
    n, d, r = sim.n_particles, 2 * sim.model.radius, sim.model.radius
    pos, start, dynamic = sim._pos[:n], sim._nbr_start[:n + 1], sim._in_feed[:n] == 0
    first = np.repeat(np.arange(n), np.diff(start))
    offset = sim._pos[sim._nbr[:start[n]]] - pos[first]  # a neighbour may be a row beyond n (feed)
    pairs = int(np.count_nonzero(np.einsum("ij,ij->i", offset, offset) < d * d))
    inner = sim.case["tube.diameter"] / 2 - r
    walls = int(np.count_nonzero(dynamic & (pos[:, 1] ** 2 + pos[:, 2] ** 2 > inner * inner)))
    walls += int(np.count_nonzero(dynamic & (pos[:, 0] < r)))
    return {"pairs": pairs, "walls": walls, "list_entries": int(start[n])}


PASSES = ("compact", "gather", "pair_law", "scatter", "walls")


@nb.njit(cache=True)
def _run_passes(upto, calls, grains, n, nbr_start, nbr, nbr_i, p, pairs):
    """`calls` times the passes of passes.contact_passes (without the optional terms) over every block
    of list entries up to PASSES[upto] (0: compact; 3: compact, gather, pair law and scatter), or
    (upto 4) the walls alone."""
    pos, vel, omg = passes.flat_rows(grains.pos), passes.flat_rows(grains.vel), passes.flat_rows(grains.omg)
    force, torque = passes.flat_rows(grains.force), passes.flat_rows(grains.torque)
    implicit = p.implicit_spin > 0.0
    dia = 2.0 * p.radius
    entries = nbr_start[n]
    for _ in range(calls):
        if upto == 4:
            passes._walls_plain(grains, n, p, pos, vel, omg, force, torque, implicit)
            continue
        for lo in range(0, entries, passes.BLOCK):
            m = passes._compact(lo, min(entries, lo + passes.BLOCK), pos, nbr_i, nbr, dia * dia, pairs.pair_i,
                                pairs.pair_j)
            if upto >= 1:
                passes._gather_plain(m, pos, vel, omg, grains.in_feed, True, pairs.pair_i, pairs.pair_j, pairs.rows)
            if upto >= 2:
                passes._pair_law_plain(m, p, pairs.rows)
            if upto >= 3:
                passes._scatter_plain(m, force, torque, grains.viscous_damping, implicit, pairs.pair_i, pairs.pair_j,
                                      pairs.rows)


@nb.njit(cache=True)
def _run_forces(calls, grains, n, nbr_start, nbr, nbr_i, p, diag, chunks, pairs):
    """`calls` times evaluate_contacts (the single loop with empty work arrays, else the passes)."""
    for _ in range(calls):
        contacts.evaluate_contacts(grains, n, nbr_start, nbr, nbr_i, p, diag, chunks, pairs)


def time_contact_kernels(sim: Simulation, calls: int, repeats: int) -> dict:
    """Seconds per call of the one-thread contact forces alone, as the single loop and in passes,
    and of each pass over all blocks (PASSES: compact, gather, pair law and scatter as the
    differences of the passes run up to each, the walls alone), on the present state: medians of
    `repeats` interleaved runs of `calls` calls each (called from compiled code), and the median
    per-run ratio single loop / passes (passes_speedup)."""
    n, p, grains = sim.n_particles, sim._p, sim._grains()
    nbr_start, nbr, nbr_i, diag, chunks = sim._nbr_start, sim._nbr, sim._nbr_i, sim._diag.copy(), sim._chunks
    pairs, single = passes.pair_buffers(), contacts.single_loop_buffers()
    runs = {"single_loop": lambda: _run_forces(calls, grains, n, nbr_start, nbr, nbr_i, p, diag, chunks, single),
            "passes": lambda: _run_forces(calls, grains, n, nbr_start, nbr, nbr_i, p, diag, chunks, pairs)}
    for k, name in enumerate(PASSES):
        runs["upto_" + name] = lambda k=k: _run_passes(k, calls, grains, n, nbr_start, nbr, nbr_i, p, pairs)
    times = {name: [] for name in runs}
    for name, run in runs.items():
        run()  # compiled, caches warm
    for _ in range(repeats):  # interleaved, so that a change of the machine's load hits all alike
        for name, run in runs.items():
            times[name].append(_timed(run) / calls)
    median = {name: statistics.median(t) for name, t in times.items()}
    out = {"single_loop": median["single_loop"], "passes": median["passes"], "walls": median["upto_walls"]}
    before = 0.0
    for name in PASSES[:-1]:
        out[name] = median["upto_" + name] - before
        before = median["upto_" + name]
    out["passes_speedup"] = statistics.median(a / b for a, b in zip(times["single_loop"], times["passes"]))
    _run_forces(1, grains, n, nbr_start, nbr, nbr_i, p, diag, chunks, sim._pairs)  # the state's forces as they were
    out["blocks"] = -(-int(nbr_start[n]) // passes.BLOCK)
    return out


def measure_rate(sim: Simulation, steps: int, repeats: int) -> list[float]:
    """Particle-steps per second of `repeats` runs of `steps` steps each."""
    rates = []
    for _ in range(repeats):
        n = sim.n_particles
        start = time.perf_counter()
        sim.advance(steps * sim.dt)
        rates.append(n * steps / (time.perf_counter() - start))
    return rates


def compile_time() -> dict:
    """Seconds to import and run the first step in a fresh process: cold (empty cache) and warm."""
    code = ("import time; t=time.perf_counter(); from engine.bench import standard_case;"
            "from engine import Simulation; s=Simulation(standard_case());"
            "s.add_particles([[0.1,0,0]]); s.advance(s.dt); print(time.perf_counter()-t)")
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        for label in ("cold", "warm"):
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                 check=True)
            out[label] = float(res.stdout.strip().splitlines()[-1])
    return out


def write_lammps_data(sim: Simulation, path: str | Path) -> None:
    """Write the grains as a LAMMPS atom_style sphere data file (SI units).

    LAMMPS's granular cylinder wall is along z, so the tube axis x maps to LAMMPS z:
    (x, y, z) -> (y, z, x); gravity along our -z is LAMMPS -y.
    """
    pos, vel = sim.positions, sim.velocities
    R, L = sim.case["tube.diameter"] / 2, sim.case["tube.length"]
    d, rho = sim.case["particles.diameter"], sim.case["particles.density"]
    lines = ["plugsim standard dense case (tube axis along z)", "", f"{len(pos)} atoms", "1 atom types",
             "", f"{-R:.6g} {R:.6g} xlo xhi", f"{-R:.6g} {R:.6g} ylo yhi", f"{-0.01:.6g} {L + 0.01:.6g} zlo zhi",
             "", "Atoms # sphere", ""]
    for i, (x, y, z) in enumerate(pos, start=1):
        lines.append(f"{i} 1 {d:.10g} {rho:.10g} {y:.10g} {z:.10g} {x:.10g}")
    lines += ["", "Velocities", ""]
    for i, (vx, vy, vz) in enumerate(vel, start=1):
        lines.append(f"{i} {vy:.10g} {vz:.10g} {vx:.10g} 0 0 0")
    Path(path).write_text("\n".join(lines) + "\n")


def lammps_parameters(sim: Simulation) -> dict:
    """The contact law in LAMMPS gran/hooke units (damping per unit reduced mass, 1/s)."""
    m = sim.model
    m_pair = m.mass / 2
    return {"kn": m.stiffness, "gamma_n": m.damping_pair / m_pair, "gamma_t": m.tangential_damping_pair / m_pair,
            "xmu": m.friction_pair, "dt": sim.dt, "radius_tube": sim.case["tube.diameter"] / 2,
            "gravity": sim.case["physics.gravity"], "n_grains": sim.n_particles}


def gas_cost_split(steps: int, repeats: int) -> dict:
    """Cost per step of grains, coupling (deposit, fields, gradient, drag) and the gas solve, s.

    The standard packing with the gas on (v_s = 1 m/s, gas updated every step): the whole step is
    timed through Simulation.advance, the coupling and the solve by calling their kernels alone.
    """
    from .kernels import gas as gas_kernels

    sim = Simulation(standard_case("gas.enabled=true", "numerics.gas_interval=1"))
    sim.add_particles(standard_packing(sim.case))
    sim.advance(0.001)
    total = statistics.median(
        _timed(lambda: sim.advance(steps * sim.dt)) / steps for _ in range(repeats))
    gas, dt = sim.gas, sim.dt
    # writable copies: the kernel is compiled for writable arrays (a read-only view would compile
    # another specialisation inside the timing)
    positions, velocities = np.array(sim.positions), np.array(sim.velocities)
    grains = len(positions)
    arrays = gas.arrays()
    drag = np.zeros_like(positions)

    def couple_steps():
        for _ in range(steps):
            gas_kernels.couple(positions, velocities, grains, arrays, dt, 1, gas.theta, 0.0, drag, False)

    def solve_steps():  # the scheme and theta couple runs (gas.scheme, gas.theta)
        gas.step(steps * dt, steps)

    couple = statistics.median(_timed(couple_steps) / steps for _ in range(repeats))
    solve = statistics.median(_timed(solve_steps) / steps for _ in range(repeats))
    return {"grains_s_per_step": total - couple, "coupling_s_per_step": couple - solve,
            "gas_solve_s_per_step": solve, "total_s_per_step": total, "grains": grains,
            "wall_s_per_simulated_s": total / dt}


def _timed(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def run(steps: int = 2000, repeats: int = 5, with_compile: bool = True, threads: int = 1,
        kernels: bool = False, single_loop: bool = False) -> dict:
    """Build, settle and time the standard case; returns the numbers it prints.

    ns_per_contact: a whole step's time over the touching contacts (grain pairs plus cylinder and
    inlet contacts, counted at the end of the timed steps). With `kernels` also the contact forces
    alone and each of their passes, per call and per contact (kernels_s, kernels_ns_per_contact).
    """
    sim = settled_simulation(threads=threads)
    sim.set_contact_passes(not single_loop)
    rates = measure_rate(sim, steps, repeats)
    rate = statistics.median(rates)
    count = contact_count(sim)
    contacts = count["pairs"] + count["walls"]
    result = {"threads": threads, "contact_passes": not single_loop, "grains": sim.n_particles,
              "contacts_per_grain": round(contacts_per_grain(sim), 3),
              "time_step_s": sim.dt, "steps_per_repeat": steps, "repeats": repeats,
              "particle_steps_per_s_median": rate,
              "particle_steps_per_s_all": [round(r) for r in rates],
              "wall_s_per_simulated_s": sim.n_particles / rate / sim.dt,
              "contacts": count, "ns_per_contact": 1e9 * sim.n_particles / rate / contacts}
    if kernels:
        seconds = time_contact_kernels(sim, max(1, steps // 4), repeats)
        result["kernels_s"] = seconds
        result["kernels_ns_per_contact"] = {k: 1e9 * v / contacts for k, v in seconds.items()
                                            if k not in ("blocks", "passes_speedup")}
    if with_compile:
        result["compile_s"] = compile_time()
    return result


def _check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse bad options before any work (parser.error: exit 2, one line naming the option)."""
    from .simulation import check_threads

    for name in ("steps", "repeats"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} = {getattr(args, name)}: allowed 1 or more")
    try:
        check_threads(args.threads)
    except ValueError as err:
        parser.error(f"--threads: {err}")
    if args.write_lammps:
        out = Path(args.write_lammps)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            parser.error(f"--write-lammps {out}: cannot create the directory ({err.strerror})")


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="plugsim bench", description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps per repeat (default 2000)")
    parser.add_argument("--repeats", type=int, default=5, help="repeats; the median is reported")
    parser.add_argument("--no-compile", action="store_true", help="skip the compile-time measurement")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--threads", type=int, default=1,
                        help="threads for the contact forces of the timed steps (default 1)")
    parser.add_argument("--kernels", action="store_true",
                        help="also time the one-thread contact forces alone, single loop against passes, "
                             "and each pass")
    parser.add_argument("--single-loop", action="store_true",
                        help="time the steps with the one-thread contact forces in the single loop instead of "
                             "in passes (Simulation.set_contact_passes(False))")
    parser.add_argument("--gas", action="store_true",
                        help="also time the same packing with the gas on and split the cost per step")
    parser.add_argument("--write-lammps", metavar="DIR",
                        help="also write the settled packing (grains.data) and params.json for LAMMPS")
    args = parser.parse_args(argv)
    _check_arguments(parser, args)
    result = run(args.steps, args.repeats, not args.no_compile, args.threads, args.kernels, args.single_loop)
    if args.gas:
        result["gas"] = gas_cost_split(args.steps, args.repeats)
    if args.write_lammps:
        sim = settled_simulation()
        out = Path(args.write_lammps)
        out.mkdir(parents=True, exist_ok=True)
        write_lammps_data(sim, out / "grains.data")
        (out / "params.json").write_text(json.dumps(lammps_parameters(sim), indent=1))
    if args.json:
        print(json.dumps(result))
    else:
        print(f"grains                 {result['grains']}")
        print(f"contacts per grain     {result['contacts_per_grain']:.2f} (walls included)")
        print(f"particle-steps per s   {result['particle_steps_per_s_median']:.3e} "
              f"(median of {args.repeats} x {args.steps} steps, "
              f"{args.threads} thread{'s' if args.threads > 1 else ''})")
        print(f"wall s per simulated s {result['wall_s_per_simulated_s']:.1f} (dt = {result['time_step_s']:.3g} s)")
        c = result["contacts"]
        print(f"ns per contact         {result['ns_per_contact']:.1f} (a whole step over its {c['pairs']} touching "
              f"pairs + {c['walls']} wall contacts; {c['list_entries']} list entries)")
        if "kernels_s" in result:
            k, ns = result["kernels_s"], result["kernels_ns_per_contact"]
            print(f"contact forces alone   single loop {k['single_loop'] * 1e6:.1f} us per call, "
                  f"{ns['single_loop']:.1f} ns per contact; in passes {k['passes'] * 1e6:.1f} us, "
                  f"{ns['passes']:.1f} ns per contact ({k['blocks']} blocks of list entries): passes "
                  f"{k['passes_speedup']:.3f}x")
            print("  passes, ns/contact   " + ", ".join(f"{name} {ns[name]:.1f}" for name in PASSES))
        if "gas" in result:
            g = result["gas"]
            print(f"with gas, per step     grains {g['grains_s_per_step'] * 1e6:.0f} us, coupling "
                  f"{g['coupling_s_per_step'] * 1e6:.0f} us, gas solve {g['gas_solve_s_per_step'] * 1e6:.0f} us "
                  f"-> {g['wall_s_per_simulated_s']:.0f} wall s per simulated s")
        if "compile_s" in result:
            print(f"compile + first step   {result['compile_s']['cold']:.1f} s cold cache, "
                  f"{result['compile_s']['warm']:.1f} s warm cache")
    return 0


if __name__ == "__main__":
    sys.exit(main())

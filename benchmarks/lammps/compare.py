#!/usr/bin/env python
"""plugsim against LAMMPS (pair gran/hooke) on the standard dense case, one core each, interleaved.

    python benchmarks/lammps/compare.py [--repeats 5] [--steps 5000] [--json] [--check-law]

1. `python -m engine.bench --write-lammps DIR` settles the standard case (about 3070 grains in the
   horizontal 7 mm tube) and writes DIR/grains.data and DIR/params.json.
2. For each repeat: one plugsim bench process (`--repeats 1 --steps N`), then one LAMMPS run of
   in.tube for N steps on the same packing; both pinned to one core (taskset), OMP_NUM_THREADS =
   NUMBA_NUM_THREADS = 1. The vCPUs are shared and noisy, so the two codes alternate in one run.
3. Particle-steps per second: plugsim from its JSON; LAMMPS from "Loop time of T on 1 procs for N
   steps with A atoms" as N A / T. Both time only the time loop (no set-up, no I/O). ns per contact:
   a step's time over the touching contacts (grain pairs + cylinder and inlet contacts) that
   plugsim counts at the end of its run, for both codes (the same packing, the same steps).
4. Every LAMMPS run is checked: no lost atoms, same grain count and steps as plugsim, wall overlaps
   below 1 % of d, speeds bounded, finite energies. Problems make the exit status 1.

--check-law additionally starts both codes from one identical state (angular velocities included,
full precision) and compares the grains after a few steps: with the grain-wall dashpot off
(wall.restitution = 1) the two must agree to round-off (same law); with the default case the
difference shows what LAMMPS's unclamped wall dashpot changes (see README.md).

Exit status: 0 ok, 1 a check failed, 2 LAMMPS not found.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
INPUT = HERE / "in.tube"
REPO = HERE.parents[1]
LAMMPS_NAMES = ("lmp", "lmp_serial", "lmp_mpi", "lammps")
LOOP_RE = re.compile(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms")
MAX_OVERLAP = 0.01   # of d: a wall overlap above this is reported as a problem
MAX_SPEED = 1.0      # m/s: far above anything a settled bed in a 7 mm tube can reach (sqrt(2 g D) = 0.37)


class CompareError(RuntimeError):
    """A failed step; the message is one line."""


# ---- environment ------------------------------------------------------------------------------
def find_lammps(explicit: str | None) -> str | None:
    if explicit:
        return shutil.which(explicit) or (explicit if Path(explicit).is_file() else None)
    if os.environ.get("LAMMPS"):
        return shutil.which(os.environ["LAMMPS"])
    for name in LAMMPS_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def single_core_env() -> dict:
    env = dict(os.environ)
    for key in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[key] = "1"
    return env


def pinned(cmd: list[str], cpu: int | None) -> list[str]:
    if cpu is not None and shutil.which("taskset"):
        return ["taskset", "-c", str(cpu), *cmd]
    return cmd


def run_checked(cmd: list[str], env: dict, cwd: Path, what: str) -> str:
    res = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    if res.returncode != 0:
        tail = (res.stdout + res.stderr).strip().splitlines()[-5:]
        errors = [line for line in tail if "ERROR" in line] or tail
        raise CompareError(f"{what} failed (exit {res.returncode}): {' | '.join(errors)}")
    return res.stdout


# ---- parameters -------------------------------------------------------------------------------
def lammps_variables(model, case, dt: float) -> dict:
    """in.tube's -var values for a plugsim contact model (see README.md for the mapping)."""
    m = model.mass
    theta = math.radians(case["tube.inclination_deg"])
    # ours (x along the tube, gravity -x sin(theta) - z cos(theta)) -> LAMMPS (y, z, x)
    return {"kn": model.stiffness, "kt": model.stiffness * 2.0 / 7.0,   # kt: unused by gran/hooke
            "gn": model.damping_pair / (m / 2), "gt": model.tangential_damping_pair / (m / 2),
            "mu": model.friction_pair,
            "gnw": model.damping_wall / m, "gtw": model.tangential_damping_wall / m, "muw": model.friction_wall,
            "dt": dt, "R": case["tube.diameter"] / 2, "g": case["physics.gravity"],
            "gx": 0.0, "gy": -math.cos(theta), "gz": -math.sin(theta),
            "skin": case["numerics.neighbor_skin"] * case["particles.diameter"]}


def benchmark_variables(params: dict) -> dict:
    """Variables for the benchmark: params.json for what it holds, the engine's model for the rest."""
    from engine.bench import standard_case
    from engine.contact import ContactModel
    case = standard_case()
    model = ContactModel.from_case(case)
    var = lammps_variables(model, case, params["dt"])
    theirs = {"kn": params["kn"], "gn": params["gamma_n"], "gt": params["gamma_t"], "mu": params["xmu"],
              "R": params["radius_tube"], "g": params["gravity"]}
    for key, value in theirs.items():
        if not math.isclose(value, var[key], rel_tol=1e-9):
            raise CompareError(f"params.json {key} = {value!r} but the engine's standard case gives "
                               f"{var[key]!r}: the engine changed while this ran; run again")
        var[key] = value
    for key, name in (("gnw", "gamma_n_wall"), ("gtw", "gamma_t_wall"), ("muw", "xmu_wall")):
        if name in params:  # a newer params.json may carry the wall values itself
            var[key] = params[name]
    return var


def var_args(var: dict) -> list[str]:
    out = []
    for key, value in var.items():
        out += ["-var", key, repr(float(value)) if isinstance(value, float) else str(value)]
    return out


# ---- the two codes ------------------------------------------------------------------------------
def run_ours(steps: int, env: dict, cpu: int | None, write: Path | None = None) -> dict:
    cmd = [sys.executable, "-m", "engine.bench", "--json", "--no-compile", "--repeats", "1",
           "--steps", str(steps)]
    if write is not None:
        cmd += ["--write-lammps", str(write)]
    out = run_checked(pinned(cmd, cpu), env, REPO, "plugsim bench")
    return json.loads(out.strip().splitlines()[-1])


def thermo_block(text: str, header_start: str) -> list[dict]:
    """Rows of the thermo table whose header starts with header_start."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.startswith(header_start):
            keys = line.split()
            rows = []
            for row in lines[i + 1:]:
                parts = row.split()
                if len(parts) != len(keys) or not parts[0].isdigit():
                    break
                rows.append({k: float(v) for k, v in zip(keys, parts)})
            return rows
    return []


def run_lammps(lmp: str, data: Path, var: dict, steps: int, env: dict, cpu: int | None, cwd: Path,
               dump: Path | None = None) -> dict:
    cmd = [lmp, "-in", str(INPUT), "-log", "none", "-nocite", "-var", "data", str(data), *var_args(var),
           "-var", "nsteps", str(steps)]
    if dump is not None:
        cmd += ["-var", "dump", "1", "-var", "dumpfile", str(dump)]
    out = run_checked(pinned(cmd, cpu), env, cwd, "LAMMPS")
    loops = [m for m in LOOP_RE.finditer(out) if int(m.group(3)) == steps]
    if not loops:
        raise CompareError(f"LAMMPS printed no 'Loop time ... for {steps} steps' line")
    seconds, procs, nsteps, atoms = (float(loops[0].group(1)), int(loops[0].group(2)),
                                     int(loops[0].group(3)), int(loops[0].group(4)))
    thermo = thermo_block(out, "Step Atoms c_ke")
    contacts = thermo_block(out, "Step Atoms c_cntsum")
    version = re.search(r"LAMMPS \(([^)]*)\)", out)
    dangerous = re.search(r"Dangerous builds = (\d+)", out)
    builds = re.search(r"Neighbor list builds = (\d+)", out)
    warnings = [line.strip() for line in out.splitlines()
                if line.startswith("WARNING") and "New thermo_style command" not in line]
    return {"version": version.group(1) if version else "?", "seconds": seconds, "procs": procs,
            "steps": nsteps, "atoms": atoms, "rate": nsteps * atoms / seconds,
            "thermo": thermo, "contacts": contacts[-1] if contacts else {},
            "neighbor_builds": int(builds.group(1)) if builds else None,
            "dangerous_builds": int(dangerous.group(1)) if dangerous else None, "warnings": warnings}


def stability(run: dict, n_grains: int, d: float, mgd: float) -> tuple[dict, list[str]]:
    """Summary of one LAMMPS run and the problems found in it."""
    problems = []
    start, end = (run["thermo"][0], run["thermo"][-1]) if len(run["thermo"]) >= 2 else ({}, {})
    if not end:
        return {}, ["LAMMPS thermo output missing"]
    values = [v for row in run["thermo"] for v in row.values()]
    if not all(math.isfinite(v) for v in values):
        problems.append("non-finite LAMMPS thermo values")
    if int(end["Atoms"]) != n_grains or run["atoms"] != n_grains:
        problems.append(f"LAMMPS has {int(end['Atoms'])} atoms at the end, plugsim {n_grains}")
    wall = max(row["c_rout"] for row in run["thermo"]) / d
    inlet = max(row["c_zlow"] for row in run["thermo"]) / d
    if wall > MAX_OVERLAP or inlet > MAX_OVERLAP:
        problems.append(f"LAMMPS wall overlap {max(wall, inlet):.3g} d above {MAX_OVERLAP} d")
    vmax = max(row["c_vmax"] for row in run["thermo"])
    if vmax > MAX_SPEED:
        problems.append(f"LAMMPS grain speed {vmax:.3g} m/s above {MAX_SPEED} m/s")
    if run["dangerous_builds"]:
        problems.append(f"LAMMPS reports {run['dangerous_builds']} dangerous neighbour builds")
    problems += [f"LAMMPS {w}" for w in run["warnings"]]
    ke = lambda row: row["c_ke"] + row["c_erot"]  # noqa: E731
    summary = {"atoms_start": int(start["Atoms"]), "atoms_end": int(end["Atoms"]),
               "max_wall_overlap_d": max(wall, 0.0), "max_inlet_overlap_d": max(inlet, 0.0),
               "max_speed_m_s": vmax, "kinetic_energy_start_J": ke(start), "kinetic_energy_end_J": ke(end),
               "kinetic_energy_end_per_grain_mgd": ke(end) / (n_grains * mgd),
               "neighbor_builds": run["neighbor_builds"]}
    return summary, problems


# ---- the optional law check -----------------------------------------------------------------------
def write_state(sim, path: Path) -> None:
    """Full-precision LAMMPS data file of a simulation, angular velocities included (axes as bench)."""
    pos, vel, omg = sim.positions, sim.velocities, sim.angular_velocities
    R, L = sim.case["tube.diameter"] / 2, sim.case["tube.length"]
    d, rho = sim.case["particles.diameter"], sim.case["particles.density"]
    f = lambda v: f"{float(v):.17g}"  # noqa: E731
    lines = ["plugsim state for the law check (tube axis along z)", "", f"{len(pos)} atoms", "1 atom types", "",
             f"{f(-R)} {f(R)} xlo xhi", f"{f(-R)} {f(R)} ylo yhi", f"-0.01 {f(L + 0.01)} zlo zhi", "",
             "Atoms # sphere", ""]
    lines += [f"{i} 1 {f(d)} {f(rho)} {f(p[1])} {f(p[2])} {f(p[0])}" for i, p in enumerate(pos, 1)]
    lines += ["", "Velocities", ""]
    lines += [f"{i} {f(v[1])} {f(v[2])} {f(v[0])} {f(w[1])} {f(w[2])} {f(w[0])}"
              for i, (v, w) in enumerate(zip(vel, omg), 1)]
    path.write_text("\n".join(lines) + "\n")


def check_law(lmp: str, steps: int, env: dict, cpu: int | None, workdir: Path) -> list[dict]:
    """Both codes from one state for `steps` steps; largest differences per grain."""
    import numpy as np

    from engine import Simulation
    from engine.bench import settled_simulation, standard_case
    out = []
    for label, overrides in (("wall dashpot off (wall.restitution=1)", ("wall.restitution=1",)),
                             ("default case", ())):
        base = settled_simulation(*overrides)
        data, dump = workdir / "law.data", workdir / "law.dump"
        write_state(base, data)
        ours = Simulation(standard_case(*overrides))   # fresh: forces from the full-step state, as LAMMPS
        ours.add_particles(base.positions, base.velocities, base.angular_velocities)
        ours.advance(steps * ours.dt)
        var = lammps_variables(ours.model, ours.case, ours.dt)
        run_lammps(lmp, data, var, steps, env, cpu, workdir, dump=dump)
        state = np.loadtxt(dump, skiprows=9)
        if not np.array_equal(state[:, 0], np.arange(1, len(state) + 1)):
            raise CompareError("law check: LAMMPS dump is not the grains in id order")
        d = ours.case["particles.diameter"]
        dx = np.abs(state[:, [3, 1, 2]] - ours.positions).max()
        dv = np.abs(state[:, [6, 4, 5]] - ours.velocities).max()
        dw = np.abs(state[:, [9, 7, 8]] - ours.angular_velocities).max()
        out.append({"case": label, "steps": steps, "max_dx_over_d": dx / d,
                    "max_dv_over_vmax": dv / np.abs(ours.velocities).max(),
                    "max_dw_over_wmax": dw / np.abs(ours.angular_velocities).max()})
    return out


# ---- main -----------------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="interleaved runs of each code (default 5)")
    parser.add_argument("--steps", type=int, default=5000, help="time steps per run (default 5000)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    parser.add_argument("--lammps", metavar="BINARY", help=f"LAMMPS executable (default: $LAMMPS or the "
                        f"first of {', '.join(LAMMPS_NAMES)} on PATH)")
    parser.add_argument("--cpu", type=int, default=0, help="core to pin both codes to (default 0; -1: no pinning)")
    parser.add_argument("--workdir", type=Path, help="keep grains.data, params.json here (default: a temp dir)")
    parser.add_argument("--check-law", action="store_true",
                        help="also compare both codes' grains after --check-steps steps from one state")
    parser.add_argument("--check-steps", type=int, default=100, help="steps of the law check (default 100)")
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.steps < 1:
        parser.error("--repeats and --steps must be >= 1")

    lmp = find_lammps(args.lammps)
    if lmp is None:
        print("compare.py: LAMMPS not found (tried " + (args.lammps or ", ".join(LAMMPS_NAMES)) +
              "); install it with `apt-get install lammps` or pass --lammps BINARY", file=sys.stderr)
        return 2
    cpu = None if args.cpu < 0 or not shutil.which("taskset") else args.cpu
    env = single_core_env()
    os.environ.update({k: env[k] for k in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS")})  # for --check-law

    tmp = None
    if args.workdir is None:
        tmp = tempfile.TemporaryDirectory(prefix="plugsim-lammps-")
        workdir = Path(tmp.name)
    else:
        workdir = args.workdir.resolve()
        workdir.mkdir(parents=True, exist_ok=True)
    try:
        return compare(args, lmp, cpu, env, workdir)
    except CompareError as exc:
        print(f"compare.py: {exc}", file=sys.stderr)
        return 1
    finally:
        if tmp is not None:
            tmp.cleanup()


def compare(args, lmp: str, cpu: int | None, env: dict, workdir: Path) -> int:
    load_start = os.getloadavg()
    # the data, once (this bench run also warms numba's cache; its timing is not used)
    run_ours(100, env, cpu, write=workdir)
    params = json.loads((workdir / "params.json").read_text())
    data = workdir / "grains.data"
    var = benchmark_variables(params)
    n_grains = int(params["n_grains"])

    ours_runs, lammps_runs, problems = [], [], []
    for _ in range(args.repeats):
        ours_runs.append(run_ours(args.steps, env, cpu))
        lammps_runs.append(run_lammps(lmp, data, var, args.steps, env, cpu, workdir))
    load_end = os.getloadavg()

    from engine.bench import standard_case
    case = standard_case()
    d = case["particles.diameter"]
    mgd = case["particles.density"] * math.pi * d**3 / 6 * case["physics.gravity"] * d
    summaries = []
    for o, run in zip(ours_runs, lammps_runs):
        if o["grains"] != n_grains or run["atoms"] != n_grains:
            problems.append(f"grain counts differ: plugsim {o['grains']}, LAMMPS {run['atoms']}, "
                            f"data {n_grains}")
        if o["steps_per_repeat"] != args.steps or run["steps"] != args.steps or run["procs"] != 1:
            problems.append(f"steps differ: plugsim {o['steps_per_repeat']}, LAMMPS {run['steps']} "
                            f"on {run['procs']} procs")
        summary, found = stability(run, n_grains, d, mgd)
        summaries.append(summary)
        problems += found
    problems = list(dict.fromkeys(problems))

    ours_rates = [o["particle_steps_per_s_median"] for o in ours_runs]
    lammps_rates = [r["rate"] for r in lammps_runs]
    ours_med, lammps_med = statistics.median(ours_rates), statistics.median(lammps_rates)
    law = check_law(lmp, args.check_steps, env, cpu, workdir) if args.check_law else None
    if law and law[0]["max_dx_over_d"] > 1e-9:
        problems.append(f"law check: with the wall dashpot off the codes differ by "
                        f"{law[0]['max_dx_over_d']:.3g} d after {args.check_steps} steps (expected round-off)")
    try:
        deb = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "lammps"], capture_output=True,
                             text=True).stdout.strip() or None
    except OSError:
        deb = None

    result = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "machine": {"host": platform.node(), "cpus": os.cpu_count(), "processor": platform.processor(),
                    "pinned_cpu": cpu, "loadavg_start": load_start, "loadavg_end": load_end},
        "grains": n_grains, "steps": args.steps, "repeats": args.repeats, "time_step_s": params["dt"],
        "plugsim": {"particle_steps_per_s_median": ours_med, "particle_steps_per_s_all": ours_rates,
                    "contacts_per_grain": [o["contacts_per_grain"] for o in ours_runs],
                    "contacts": [o.get("contacts") for o in ours_runs]},
        "lammps": {"binary": lmp, "version": lammps_runs[0]["version"], "debian_package": deb,
                   "particle_steps_per_s_median": lammps_med, "particle_steps_per_s_all": lammps_rates,
                   "loop_seconds_all": [r["seconds"] for r in lammps_runs],
                   "contacts_per_grain": [r["contacts"].get("v_cpg") for r in lammps_runs],
                   "stability": summaries[-1], "variables": var},
        "ratio_plugsim_over_lammps": ours_med / lammps_med,
        # a step's time over its touching contacts (grain pairs + cylinder and inlet contacts), both
        # codes over plugsim's count at the end of each of its runs (the same packing and steps)
        "ns_per_contact": ns_per_contact(ours_runs, lammps_rates),
        "ratio_per_pair": [o / l for o, l in zip(ours_rates, lammps_rates)],
        "law_check": law, "problems": problems,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)
    return 1 if problems else 0


def ns_per_contact(ours_runs: list[dict], lammps_rates: list[float]) -> dict | None:
    """Median ns per touching contact of a step, plugsim and LAMMPS (None with a bench that does not
    count its contacts)."""
    counts = [o.get("contacts") for o in ours_runs]
    if not all(counts):
        return None
    per = lambda rate, o, c: 1e9 * o["grains"] / rate / (c["pairs"] + c["walls"])  # noqa: E731
    return {"plugsim": statistics.median(per(o["particle_steps_per_s_median"], o, c)
                                         for o, c in zip(ours_runs, counts)),
            "lammps": statistics.median(per(rate, o, c) for rate, o, c in zip(lammps_rates, ours_runs, counts)),
            "contacts": counts[-1]}


def print_table(r: dict) -> None:
    o, lm, st = r["plugsim"], r["lammps"], r["lammps"]["stability"]
    pin = f"taskset -c {r['machine']['pinned_cpu']}" if r["machine"]["pinned_cpu"] is not None else "not pinned"
    print(f"standard dense case: {r['grains']} grains, {r['steps']} steps per run, {r['repeats']} interleaved "
          f"runs each, one core ({pin}), dt = {r['time_step_s']:.4g} s")
    print(f"LAMMPS {lm['version']} ({lm['binary']}" + (f", Debian {lm['debian_package']}" if lm["debian_package"]
                                                      else "") + ")")
    fmt = lambda xs: " ".join(f"{x / 1e6:.2f}" for x in xs)  # noqa: E731
    print(f"{'':24}{'median':>12}   per run (1e6 particle-steps/s)")
    print(f"{'plugsim (numba)':24}{o['particle_steps_per_s_median']:12.3e}   {fmt(o['particle_steps_per_s_all'])}")
    print(f"{'LAMMPS (gran/hooke)':24}{lm['particle_steps_per_s_median']:12.3e}   "
          f"{fmt(lm['particle_steps_per_s_all'])}")
    print(f"{'ratio plugsim/LAMMPS':24}{r['ratio_plugsim_over_lammps']:12.2f}   per pair: "
          + " ".join(f"{x:.2f}" for x in r["ratio_per_pair"]))
    if r.get("ns_per_contact"):
        ns = r["ns_per_contact"]
        print(f"{'ns per contact':24}{ns['plugsim']:12.1f}   LAMMPS {ns['lammps']:.1f} (a step over the "
              f"{ns['contacts']['pairs']} touching pairs + {ns['contacts']['walls']} wall contacts)")
    cp_o = statistics.median(o["contacts_per_grain"])
    cp_l = statistics.median([c for c in lm["contacts_per_grain"] if c is not None] or [float("nan")])
    print(f"{'contacts per grain':24}{cp_o:12.2f}   LAMMPS {cp_l:.2f} (walls included, after the run)")
    if st:
        print(f"LAMMPS run: atoms {st['atoms_start']} -> {st['atoms_end']}, max wall overlap "
              f"{st['max_wall_overlap_d']:.2g} d, max speed {st['max_speed_m_s']:.3g} m/s, kinetic energy "
              f"{st['kinetic_energy_end_J']:.3g} J ({st['kinetic_energy_end_per_grain_mgd']:.2g} m g d per grain), "
              f"{st['neighbor_builds']} neighbour builds")
    if r["law_check"]:
        for c in r["law_check"]:
            print(f"law check, {c['case']}: after {c['steps']} steps max |dx| = {c['max_dx_over_d']:.2g} d, "
                  f"max |dv| = {c['max_dv_over_vmax']:.2g} v_max, max |dw| = {c['max_dw_over_wmax']:.2g} w_max")
    la = r["machine"]
    print(f"load average {la['loadavg_start'][0]:.2f} at the start, {la['loadavg_end'][0]:.2f} at the end "
          f"({la['cpus']} vCPUs)")
    for p in r["problems"]:
        print(f"PROBLEM: {p}")


if __name__ == "__main__":
    sys.exit(main())

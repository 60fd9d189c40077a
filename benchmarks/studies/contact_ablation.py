#!/usr/bin/env python
"""Where the single contact loop's time goes: the loop timed against copies of itself with parts
cut out or rewritten.

    python benchmarks/studies/contact_ablation.py [--calls 300] [--repeats 7] [--json OUT.json] \
        [--initial-state results/cases/h_default/base.nc --case config/cases/horizontal.yaml] \
        [--moving STEPS] [--variants NAME ...]

Each variant is the engine's single loop (`_contacts_range_with` in engine/kernels/contacts.py,
without the optional terms: the loop of each chunk on threads, and on one thread with
Simulation.set_contact_passes(False); the one-thread default, the contact passes of
engine/kernels/passes.py, is not edited here) compiled from its source (and that of laws.py) with
one edit, so that it measures the loop as it is; an edit whose anchor is no longer in the source
stops the study with its name. The loop's pair law is laws.pair_normal (the normal force, from the
centre offset as it is: one square root and one division) then laws.surface_forces (the
tangential law, laws.slip_force, and the torques); its cylinder contact is laws.cylinder_contact.

On the settled standard packing of `plugsim bench` (engine.bench.settled_simulation), or with
--initial-state on a conveying state (the final grains of a case file as a warm start of --case,
advanced 5 ms with the gas and the feed on), called from compiled code, interleaved (each round
every variant once; CPU time of the process), ns per touching contact (grain pairs and wall
contacts):

  engine          the loop as it is;
  distance_only   the list entries' distance tests alone (no law, no walls): the loop's skeleton;
  no_walls        the pairs in full, the cylinder and inlet contacts cut out;
  normal_only     up to the normal force of each pair (laws.pair_normal: its square root and
                  division), no tangential law (laws.surface_forces), no scatter; walls in full;
  no_scatter      the pairs' law in full, the reactions on the partner j not stored;
  compacted       per grain, the touching entries compacted first (their offsets to small work
                  arrays, branch-free), then the law over them, |D|^2 recomputed from the stored
                  offsets (bits unchanged; the compaction loop's |D|^2, stored, differs from the
                  one the engine's law sees in the last bits: LLVM contracts it differently);
  signed_index    the partner index as a signed integer (int64; the list holds uint32), as numba
                  indexes it by default (the wrap-around of negative indices at every load and
                  store; bits unchanged);
  root_both_branches  the tangential law's branch (laws.slip_force, the walls' too) chosen on
                  |v_t| = sqrt(|v_t|^2) instead of on squares, so that a viscous contact too takes
                  a square root and a division (the same law as the engine's; the forces differ in
                  the last bits);
  branchless      the pair's law (laws.surface_forces) in the laws' `branchless` form
                  (selects instead of its branches; bits unchanged);
  compacted_index  per grain, only the touching partners' indices compacted first, their offsets
                  recomputed in the law's loop (bits unchanged);
  compacted_branchless  both: no branch left between a grain's touching pairs, so that the core
                  could overlap one pair's chain with the next's (bits unchanged);
  single_law      a pair's law in single precision (float32) from the double offsets, velocities
                  and spin sums (laws.pair_normal's arithmetic, but the overlap from the double
                  d^2 - |D|^2, then laws.surface_forces), its forces and torques summed in
                  double; the walls in double.

A state called repeatedly is cheaper than one that changes every step (a step on moving grains costs
1.05-1.19x the same loop on held ones, benchmarks/studies/step_split.py). With --moving
STEPS each variant instead advances its own copy of the state by STEPS steps (the merged kick and
drift between its calls, the forces of each step its own), from the same state every round; the
kick and drift alone are subtracted. The variants that cut a part out of the law are left out
there, since their grains would move otherwise.

The variants that keep the bits are checked to give the engine's forces, torques and damping sums
bit for bit; the others report their largest force difference. The cost splits are differences
of these times; docs/performance.md, "The contact kernel", quotes them.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
import types
from pathlib import Path

import numba as nb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from engine import Case, Simulation  # noqa: E402
from engine.bench import contact_count, settled_simulation  # noqa: E402
from engine.kernels import contacts, laws, stepper  # noqa: E402
from engine.run import read_initial_state  # noqa: E402

SOURCE = Path(contacts.__file__)
LAWS = Path(laws.__file__)

DISTANCE = """                touching += 1
                vrx = vel[i, 0] - vel[j, 0]"""
WALLS = "            if not in_feed[i]:\n                if yi * yi + zi * zi > inner * inner:"
NO_WALLS = "            if in_feed[i] > 1:\n                if yi * yi + zi * zi > inner * inner:"  # in_feed: 0 or 1
NORMAL = """                if fn <= 0.0:
                    continue
                fx, fy, fz"""
SCATTER_J = "                if j < end:\n                    force[j, 0] -= fx"
SCATTER_SPILL = "                else:\n                    spill_force[j, 0] -= fx"
LIST_LOOP = """            for k in range(nbr_start[i], nbr_start[i + 1]):
                j = nb.uint64(nbr[k])
                dx = pos[j, 0] - xi
                dy = pos[j, 1] - yi
                dz = pos[j, 2] - zi
                dist2 = dx * dx + dy * dy + dz * dz
                if dist2 >= dia * dia:
                    continue
                touching += 1
"""
COMPACTED = """            m = 0
            for k in range(nbr_start[i], nbr_start[i + 1]):
                j = nb.uint64(nbr[k])
                dx = pos[j, 0] - xi
                dy = pos[j, 1] - yi
                dz = pos[j, 2] - zi
                dist2 = dx * dx + dy * dy + dz * dz
                bj[m] = j
                bx[m] = dx
                by[m] = dy
                bz[m] = dz
                m += not (dist2 >= dia * dia)
            touching += m
            for t in range(m):
                j = bj[t]
                dx = bx[t]
                dy = by[t]
                dz = bz[t]
                dist2 = dx * dx + dy * dy + dz * dz  # as the engine's law sees it (a stored one rounds differently)
"""
COMPACTED_INDEX = """            m = 0
            for k in range(nbr_start[i], nbr_start[i + 1]):
                j = nb.uint64(nbr[k])
                dx = pos[j, 0] - xi
                dy = pos[j, 1] - yi
                dz = pos[j, 2] - zi
                dist2 = dx * dx + dy * dy + dz * dz
                bj[m] = j
                m += not (dist2 >= dia * dia)
            touching += m
            for t in range(m):
                j = bj[t]
                dx = pos[j, 0] - xi
                dy = pos[j, 1] - yi
                dz = pos[j, 2] - zi
                dist2 = dx * dx + dy * dy + dz * dz
"""
WORK_ARRAYS_AT = "        implicit = p.implicit_spin > 0.0  # viscous_damping is only read (and summed) then\n"
WORK_ARRAYS = WORK_ARRAYS_AT + """        longest = 1
        for i in range(lo, hi):
            longest = max(longest, nbr_start[i + 1] - nbr_start[i])
        bj = np.empty(longest, dtype=np.uint64)
        bx = np.empty(longest)
        by = np.empty(longest)
        bz = np.empty(longest)
"""
TANGENTIAL_TAIL = """    if viscous:
        return -gt * vtx, -gt * vty, -gt * vtz, gt
    s = -fc / math.sqrt(vt2)
    return s * vtx, s * vty, s * vtz, 0.0"""
ROOT_BOTH_BRANCHES = """    vt = math.sqrt(vt2)
    if vt <= 0.0:
        return 0.0, 0.0, 0.0, gt
    fv = gt * vt
    ft = min(fc, fv)
    s = -ft / vt
    return s * vtx, s * vty, s * vtz, gt if fv < fc else 0.0"""
PAIR_LAW = """                vrx = vel[i, 0] - vel[j, 0]
                vry = vel[i, 1] - vel[j, 1]
                vrz = vel[i, 2] - vel[j, 2]
                fn, inv, a, vd, delta = laws.pair_normal(dx, dy, dz, dist2, vrx, vry, vrz, pair)
                if in_feed[i] or in_feed[j]:
                    max_feed = max(max_feed, delta)
                else:
                    max_overlap = max(max_overlap, delta)
                if fn <= 0.0:
                    continue
                fx, fy, fz, tx, ty, tz, tjx, tjy, tjz, g = laws.surface_forces(
                    fn, inv, a, vd, dx, dy, dz, vrx, vry, vrz, omg[i, 0] + omg[j, 0], omg[i, 1] + omg[j, 1],
                    omg[i, 2] + omg[j, 2], omg[i, 0] - omg[j, 0], omg[i, 1] - omg[j, 1], omg[i, 2] - omg[j, 2],
                    pair, optional)"""
# The pair's law in float32 from the double offsets, velocities and spin sums, under new names:
# numba gives a name one type, so a name shared with the double wall code would be promoted back.
# laws.pair_normal's arithmetic is written out, since its overlap 2r - |D| would be a float32
# difference; the relative spin is passed as zeros: the variant is compiled without the optional terms.
PAIR_LAW_SINGLE = """                f32 = nb.float32
                dxs = f32(dx)
                dys = f32(dy)
                dzs = f32(dz)
                vrx = f32(vel[i, 0] - vel[j, 0])
                vry = f32(vel[i, 1] - vel[j, 1])
                vrz = f32(vel[i, 2] - vel[j, 2])
                d2s = f32(dist2)
                dist = math.sqrt(d2s)
                a = f32(1.0) / d2s
                inv = dist * a
                vd = vrx * dxs + vry * dys + vrz * dzs
                # dia - dist from the double dia^2 - dist^2 (series to second order, relative error
                # (overlap/d)^2/2); a float32 difference dia - dist loses 0.2 % of the largest force
                q = f32(dia * dia - dist2)
                overlap = q * half_inverse_dia * (f32(1.0) + q * quarter_inverse_dia2)
                if in_feed[i] or in_feed[j]:
                    max_feed = max(max_feed, f32(overlap))
                else:
                    max_overlap = max(max_overlap, f32(overlap))
                fnp = laws.normal_force(overlap, vd * inv, pair_single)
                if fnp <= f32(0.0):
                    continue
                fx, fy, fz, tx, ty, tz, tjx, tjy, tjz, g = laws.surface_forces(
                    fnp, inv, a, vd, dxs, dys, dzs, vrx, vry, vrz, f32(omg[i, 0] + omg[j, 0]),
                    f32(omg[i, 1] + omg[j, 1]), f32(omg[i, 2] + omg[j, 2]), f32(0.0), f32(0.0), f32(0.0),
                    pair_single, optional)"""
PAIR_CONSTANTS = "        pair = laws.pair_constants(p)\n"
PAIR_CONSTANTS_SINGLE = PAIR_CONSTANTS + """        f32 = nb.float32
        pair_single = laws.Contact(f32(pair.radius), f32(pair.stiffness), f32(pair.damping), f32(pair.friction),
                                   f32(pair.tangential_damping), f32(pair.rolling_resistance), f32(pair.rolling_cap))
        half_inverse_dia = f32(0.25 / p.radius)
        quarter_inverse_dia2 = f32(0.0625 / (p.radius * p.radius))
"""
# the slipping branch's zero gamma_t typed as its inputs, so that a float32 law stays float32 (the
# branch-free form is not compiled here)
TANGENTIAL_ZEROS = [("    s = -fc / math.sqrt(vt2)\n    return s * vtx, s * vty, s * vtz, 0.0",
                     "    s = -fc / math.sqrt(vt2)\n    return s * vtx, s * vty, s * vtz, gt - gt")]

# the variants that cut a part of the law out: the grains would move otherwise, so --moving leaves them out
CUTS = ("distance_only", "no_walls", "normal_only", "no_scatter")
# name: (edits of contacts.py's loop, edits of laws.py, same bits as the engine)
VARIANTS = {
    "distance_only": ([(DISTANCE, "                touching += 1\n                fxi += dist2\n                continue\n"
                                  "                vrx = vel[i, 0] - vel[j, 0]"),
                       (WALLS, NO_WALLS)], [], False),
    "no_walls": ([(WALLS, NO_WALLS)], [], False),
    "normal_only": ([(NORMAL, "                if fn <= 0.0:\n                    continue\n"
                              "                fxi += fn * inv * dx\n                fyi += fn * inv * dy\n"
                              "                fzi += fn * inv * dz\n                continue\n"
                              "                fx, fy, fz")], [], False),
    "no_scatter": ([(SCATTER_J, "                if j < 0:\n                    force[j, 0] -= fx"),
                    (SCATTER_SPILL, "                elif j < -1:\n                    spill_force[j, 0] -= fx")], [], False),
    "compacted": ([(LIST_LOOP, COMPACTED), (WORK_ARRAYS_AT, WORK_ARRAYS)], [], True),
    "signed_index": ([("                j = nb.uint64(nbr[k])\n", "                j = nb.int64(nbr[k])\n"),
                      ("                if j < end:\n", "                if j < hi:\n"),
                      ("                    top = max(top, nb.int64(j) + 1)\n", "                    top = max(top, j + 1)\n")],
                     [], True),
    "root_both_branches": ([], [(TANGENTIAL_TAIL, ROOT_BOTH_BRANCHES)], False),
    "branchless": ([("                    pair, optional)\n", "                    pair, optional, True)\n")], [], True),
    "compacted_index": ([(LIST_LOOP, COMPACTED_INDEX), (WORK_ARRAYS_AT, WORK_ARRAYS)], [], True),
    "compacted_branchless": ([(LIST_LOOP, COMPACTED), (WORK_ARRAYS_AT, WORK_ARRAYS),
                              ("                    pair, optional)\n", "                    pair, optional, True)\n")], [], True),
    "single_law": ([(PAIR_CONSTANTS, PAIR_CONSTANTS_SINGLE), (PAIR_LAW, PAIR_LAW_SINGLE)], TANGENTIAL_ZEROS, False),
}


def _edited(text: str, edits, name: str, where: Path) -> str:
    for old, new in edits:
        if old not in text:
            raise SystemExit(f"variant {name}: its anchor is no longer in {where}:\n{old}")
        text = text.replace(old, new, 1)
    return text


def sources(name: str) -> tuple[str, str]:
    """The sources of laws.py and of the single loop's factory with variant `name`'s edits
    ("engine": none); SystemExit naming the variant when an anchor is missing."""
    loop_edits, law_edits, _ = VARIANTS.get(name, ([], [], True))
    law_source = _edited(LAWS.read_text(), law_edits, name, LAWS)
    source = SOURCE.read_text()
    start = source.index("def _contacts_range_with(optional):")
    end = source.index("_contacts_range_plain = _contacts_range_with(False)")
    return law_source, _edited(source[start:end], loop_edits, name, SOURCE)


def build(name: str):
    """The single loop without optional terms, compiled from sources(name) (uncached)."""
    law_source, loop_source = sources(name)
    law_module = types.ModuleType(f"ablation_laws_{name}")
    exec(compile(law_source.replace("cache=True", "cache=False"), f"<laws {name}>", "exec"), law_module.__dict__)
    namespace = {"math": math, "nb": nb, "np": np, "laws": law_module, "FASTMATH": laws.FASTMATH}
    exec(compile(loop_source.replace("cache=True", "cache=False"), f"<contacts {name}>", "exec"), namespace)
    return namespace["_contacts_range_with"](False)


def forces_of(loop, loop_arguments) -> tuple:
    """What `loop` returns and the forces, torques and viscous-damping sums it leaves in the grains."""
    result = loop(*loop_arguments)
    hi, grains = loop_arguments[1], loop_arguments[2]
    return result, grains.force[:hi].copy(), grains.torque[:hi].copy(), grains.viscous_damping[:hi].copy()


def compare(state: tuple, reference: tuple) -> dict:
    """Whether forces_of states agree bit for bit, and their largest force difference (N)."""
    identical = state[0] == reference[0] and all(np.array_equal(a, b) for a, b in zip(state[1:], reference[1:]))
    return {"bit_identical": bool(identical), "max_force_difference_N": float(np.abs(state[1] - reference[1]).max())}


def _caller(loop):
    @nb.njit
    def run(calls, grains, n, nbr_start, nbr, p, force, torque, damping, counts):
        for _ in range(calls):
            loop(0, n, grains, nbr_start, nbr, p, force, torque, damping, counts)
    return run


def _moving_caller(loop):
    """steps of the merged kick and drift followed by `loop`, on grains that move as in a run (the
    forces of each step from the last); stops before a step whose drift asks for a rebuild."""
    @nb.njit
    def run(steps, grains, n, nbr_start, nbr, p, force, torque, damping, counts, counters):
        taken = 0
        for _ in range(steps):
            if stepper._kick_drift(grains, n, p, p.dt, counters):
                break
            loop(0, n, grains, nbr_start, nbr, p, force, torque, damping, counts)
            taken += 1
        return taken
    return run


def time_moving(loops: dict, grains, n, nbr_start, nbr, p, counters, steps: int, repeats: int) -> dict:
    """Per loop, the CPU seconds per step of `steps` moving steps (kick, drift and the loop; one call
    of the loop per step) from copies of the same grains, one entry per round, the loops interleaved;
    "kick_drift" is the kick and drift alone (the forces held)."""
    runs = {name: _moving_caller(loop) for name, loop in loops.items()}
    runs["kick_drift"] = _moving_caller(_no_forces)
    times = {name: [] for name in runs}
    for round_ in range(repeats + 1):  # the first round compiles
        for name, run in runs.items():
            copy = type(grains)(*[a.copy() for a in grains])
            start = time.process_time()
            taken = run(steps, copy, n, nbr_start, nbr, p, copy.force, copy.torque, copy.viscous_damping,
                        nbr_start[:0], counters.copy())
            if round_:
                times[name].append((time.process_time() - start) / max(taken, 1))
    return times


@nb.njit
def _no_forces(lo, hi, grains, nbr_start, nbr, p, force, torque, damping, counts):
    """The forces left as they are (time_moving's kick and drift alone)."""
    return 0.0, 0.0, hi


def conveying_state(case_file: Path, initial_state: Path, settle: float = 0.005) -> Simulation:
    """The final grains of `initial_state` as a warm start of `case_file`, advanced `settle` s."""
    case = Case.from_yaml(case_file)
    sim = Simulation(case)
    sim.add_particles(*read_initial_state(initial_state, case))
    sim.advance(settle)
    return sim


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=300, help="calls per timed run (default 300)")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved rounds (default 7)")
    parser.add_argument("--json", type=Path, help="write the figures here")
    parser.add_argument("--initial-state", type=Path, help="a case file whose final grains are the state")
    parser.add_argument("--moving", type=int, default=0, metavar="STEPS",
                        help="time each variant over STEPS steps of grains that move (the merged kick and drift "
                             "between calls, from copies of the state; 0: the same state called repeatedly, the "
                             "default); the figures are then per step, less the kick and drift alone")
    parser.add_argument("--variants", nargs="+", metavar="NAME", help="only these variants (default: all)")
    parser.add_argument("--case", type=Path, default=Path("config/cases/horizontal.yaml"),
                        help="case YAML the --initial-state is a warm start of (default: the horizontal default)")
    args = parser.parse_args(argv)
    if args.calls < 1 or args.repeats < 1 or args.moving < 0:
        parser.error("--calls and --repeats must be at least 1, --moving at least 0")
    unknown = sorted(set(args.variants or []) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variants {', '.join(unknown)}; the variants: {', '.join(VARIANTS)}")
    for given in ([args.initial_state, args.case] if args.initial_state else []):
        if not given.is_file():
            parser.error(f"{given}: no such file")

    sim = conveying_state(args.case, args.initial_state) if args.initial_state else settled_simulation()
    n, p, grains = sim.n_particles, sim._p, sim._grains()
    nbr_start, nbr = sim._nbr_start, sim._nbr
    arguments = (grains, n, nbr_start, nbr, p, grains.force, grains.torque, grains.viscous_damping, nbr_start[:0])
    loop_arguments = (0, n, grains, nbr_start, nbr, p, *arguments[5:])  # lo, hi, then as the caller's
    counted = contact_count(sim)
    touching = counted["pairs"] + counted["walls"]
    names = ["engine", *(name for name in (args.variants or VARIANTS) if not (args.moving and name in CUTS))]
    loops = {name: build(name) for name in names}

    reference = forces_of(loops["engine"], loop_arguments)
    if not compare(forces_of(contacts._contacts_range_plain, loop_arguments), reference)["bit_identical"]:
        raise SystemExit("the loop compiled from the source does not give the engine's bits")
    same = {}
    for name in names[1:]:
        same[name] = compare(forces_of(loops[name], loop_arguments), reference)
        if VARIANTS[name][2] and not same[name]["bit_identical"]:
            raise SystemExit(f"variant {name} should keep the engine's bits and does not")
    loops["engine"](*loop_arguments)  # the state's forces as the engine computes them

    if args.moving:
        times = time_moving(loops, grains, n, nbr_start, nbr, p, sim._counters, args.moving, args.repeats)
        kick = statistics.median(times.pop("kick_drift"))
        times = {name: [t - kick for t in ts] for name, ts in times.items()}
        how = (f"medians of {args.repeats} rounds of {args.moving} moving steps, less the kick and drift alone "
               f"({1e6 * kick:.1f} us per step)")
    else:
        runs = {name: _caller(loop) for name, loop in loops.items()}
        for run in runs.values():
            run(1, *arguments)
        times = {name: [] for name in runs}
        for _ in range(args.repeats):
            for name, run in runs.items():
                start = time.process_time()
                run(args.calls, *arguments)
                times[name].append((time.process_time() - start) / args.calls)
        how = f"medians of {args.repeats} rounds of {args.calls} calls"
    print(f"{args.initial_state or 'standard packing'}: {n} grains, {counted['pairs']} touching pairs, {counted['walls']} wall contacts, "
          f"{counted['list_entries']} list entries; {how}")
    out = {"contacts": counted, "variants": {}}
    for name, t in times.items():
        ratios = [a / b for a, b in zip(times["engine"], t)]
        row = {"us_per_call": 1e6 * statistics.median(t), "ns_per_contact": 1e9 * statistics.median(t) / touching,
               "speedup": statistics.median(ratios), "speedup_range": [min(ratios), max(ratios)], **same.get(name, {})}
        out["variants"][name] = row
        bits = "" if name == "engine" else (" same bits" if row["bit_identical"] else
                                            f" forces differ by up to {row['max_force_difference_N']:.1e} N")
        print(f"  {name:15s} {row['us_per_call']:7.1f} us/call  {row['ns_per_contact']:5.1f} ns/contact  "
              f"engine/variant {row['speedup']:.3f} ({min(ratios):.3f}-{max(ratios):.3f}){bits}")
    if args.json:
        args.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

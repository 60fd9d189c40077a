#!/usr/bin/env python
"""How long must each case run for the precision its statements ask?

    python benchmarks/studies/run_lengths.py results/cases/*/*.nc [--fraction 0.5]
        [--statements resources/paper_statements.yaml] [--identification config/identification.yaml]
        [--position 0.26] [--csv OUT.csv] [--replay [KEY=VALUE ...]]
    python benchmarks/studies/run_lengths.py results/cases/*/*.nc --every-case --replay KEY=VALUE ...

For every case file, the statements of resources/paper_statements.yaml measured on it (by its
sweep, the folder it is in, and the statement's point; for identification sweeps by the `compare`
list of config/identification.yaml) that ask a mean of one of its quantities: the pressure drop per
tube length and the grains in the tube (the steady means), the slugs' travel speed and maximal
granular velocity at a position (per passage, `slug_stat`), and the pressure drops of a `ratio`.
Each asks a standard error of `--fraction` (0.5) times its tolerance (half the width of a range).
Why one half: the papers' tolerance is half a unit of the digit they quote, and a number rounded
to that digit carries an error uniform over +- tolerance, of standard deviation tolerance / sqrt(3)
= 0.58 tolerance; a standard error of half the tolerance makes ours as precise as the paper's
quote and its +- 2 errors (the validation's reach) as wide as the paper's interval. Tighter buys
nothing the quote can resolve; looser lets our noise, not the model, decide a statement at the
edge. A ratio asks its relative error of both its pressure drops, 1/sqrt(2) of it each.

analysis.runlength.required_windows then measures each quantity over the case's averaging window
(after the start-up transient) and extrapolates the window that reaches the error asked (see its
docstring). Printed per case and quantity, for its strictest statement: ours +- its standard error
now, the error asked, the window run and the window needed (s after the window's start), when
the growing window first met it, the run length that needs (start + window) and its CPU time pro
rata of the run's CPU seconds (all its parts; rough: a run from an empty tube costs less per second while it
fills), and how far ours lies outside the statement's interval in standard errors (more precision
does not change a verdict many errors away). Then the case keys that would stop each case there
(run.steady_pressure_drop_error, run.steady_n_particles_error; the engine has no slug velocities).
--csv writes every statement's row.

--replay replays the engine's steady stop (engine.run.steady_window, the case's own keys) on each
file's recorded series with those keys, or with the KEY=VALUE given (e.g. run.steady_rel_error=1
run.steady_n_particles_error=25: a case whose statements ask only its grain count), checked every
5 frames: where it would have stopped (or that it would not within the series), and the mean
pressure drop and grains over its window against the file's own (analysis.curves.case_summary's
window), in the file's standard errors.

--every-case replays the given keys on every case file, judged by a statement or not, and sums
what the workflow would have cost with them (replay_cost): each run stopped by steadiness or the
30 s cap ends at its replayed stop, its CPU seconds pro rata; the others keep theirs.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from analysis.casefile import config, run_cpu_seconds  # noqa: E402
from analysis.runlength import PASSAGES, Precision, required_windows  # noqa: E402
from analysis.slugs import detect  # noqa: E402
from engine.case import parse_override  # noqa: E402

SI = {"hPa/m": 100.0, "Pa/m": 1.0, "m/s": 1.0, "1": 1.0}  # statement unit -> SI factor
KEEP = ("pressure_drop", "n_particles", "mass_in", "mass_out", "porosity", "velocity")  # what is read
EVERY = 5  # frames between the replayed stop's checks
MEASURES = {"pressure_drop": "pressure_drop", "n_particles": "n_particles"}  # measure -> quantity


def half_width(st: dict) -> float:
    """Half the width of a statement's interval (its unit): the tolerance, or half the range."""
    if "range" in st:
        lo, hi = st["range"]
        return (float(hi) - float(lo)) / 2
    return float(st["tolerance"])


def interval(st: dict) -> tuple[float, float]:
    """The statement's interval in SI."""
    scale = SI[st.get("unit", "1")]
    if "range" in st:
        return float(st["range"][0]) * scale, float(st["range"][1]) * scale
    return ((float(st["value"]) - float(st["tolerance"])) * scale,
            (float(st["value"]) + float(st["tolerance"])) * scale)


def matches(point: dict | None, keys: dict) -> bool:
    """Whether a case configuration has every key of `point` at its value."""
    for key, value in (point or {}).items():
        here = keys.get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if here is None or not np.isclose(float(here), float(value), rtol=1e-9, atol=0.0):
                return False
        elif here != value:
            return False
    return True


def targets(statements: list[dict], compare: list[dict], sweep: str, keys: dict, fraction: float,
            position: float) -> list[dict]:
    """What the statements measured on this case ask: statement, quantity, precision, position,
    interval (SI; None for a ratio) and unit."""
    where = {c["statement"]: c.get("where") for c in compare if c["sweep"] == sweep}
    out = []
    for st in statements:
        if "tolerance" not in st and "range" not in st:
            continue  # regimes, factors, trends: no standard error to ask
        case = st.get("case") or {}
        on_case = (case.get("sweep") == sweep and matches(case.get("point"), keys)) or (
            st["id"] in where and matches(where[st["id"]], keys))
        if st["measure"] == "ratio":
            if any(c.get("sweep") == sweep and matches(c.get("point"), keys) for c in st["cases"]):
                relative = fraction * half_width(st) / abs(float(st["value"])) / math.sqrt(2)
                out.append({"statement": st["id"], "quantity": "pressure_drop", "position": None,
                            "precision": Precision(relative, relative=True), "interval": None,
                            "unit": "hPa/m"})
            continue
        if not on_case:
            continue
        if st["measure"] in MEASURES:
            quantity, at = MEASURES[st["measure"]], None
        elif st["measure"] == "slug_stat" and st.get("quantity") in PASSAGES:
            pos = st.get("position", "analysis")
            if pos == "inlet":
                continue
            quantity, at = st["quantity"], position if pos == "analysis" else float(pos)
        else:
            continue
        scale = SI[st.get("unit", "1")]
        out.append({"statement": st["id"], "quantity": quantity, "position": at,
                    "precision": Precision(fraction * half_width(st) * scale),
                    "interval": interval(st), "unit": st.get("unit", "1")})
    return out


def labels(paths: list[Path], configs: list[dict]) -> list[str]:
    """sweep, with the keys whose values tell the cases of one sweep apart."""
    out = []
    for path, keys in zip(paths, configs):
        sweep = path.parent.name
        others = [c for p, c in zip(paths, configs) if p.parent.name == sweep]
        differ = sorted(k for k in keys if any(c.get(k) != keys[k] for c in others))
        named = ", ".join(f"{k.split('.')[-1]} {keys[k]}" for k in differ)
        out.append(f"{sweep} ({named})" if differ else sweep)
    return out


def case_rows(path: Path, label: str, asked: list[dict]) -> list[dict]:
    """One row per statement asked of the case file at `path`."""
    with xr.open_dataset(path) as ds:
        ds = ds[[v for v in KEEP if v in ds.variables and v not in ("time", "x")]].load()
    slugs = detect(ds) if any(a["quantity"] in PASSAGES for a in asked) else None
    t_end = float(ds["time"].values[-1])
    cpu = run_cpu_seconds(ds.attrs)
    rows = []
    for a in asked:
        r = required_windows(ds, {a["quantity"]: a["precision"]}, position=a["position"],
                             slugs=slugs).iloc[0].to_dict()
        outside = math.nan
        if a["interval"]:
            lo, hi = a["interval"]
            distance = max(lo - r["mean"], r["mean"] - hi, 0.0)
            outside = distance / r["sem"] if r["sem"] > 0 else (0.0 if distance == 0 else math.inf)
        rows.append({"case": label, "file": str(path), "statement": a["statement"], **r,
                     "unit_shown": "hPa/m" if r["quantity"] == "pressure_drop" else a["unit"],
                     "stop_reason": ds.attrs.get("stop_reason", ""), "run_end": t_end,
                     "run_needed": r["t_start"] + r["window_needed"],
                     "cpu_h_needed": cpu / t_end * (r["t_start"] + r["window_needed"]) / 3600,
                     "outside_sem": outside})
    return rows


def table(paths, statements, compare, fraction=0.5, position=0.26) -> pd.DataFrame:
    """Every statement's row for every case file (see the module docstring)."""
    paths = [Path(p) for p in paths]
    configs = []
    for path in paths:
        with xr.open_dataset(path) as ds:
            configs.append(config(ds))
    rows = []
    for path, keys, label in zip(paths, configs, labels(paths, configs)):
        asked = targets(statements, compare, path.parent.name, keys, fraction, position)
        if asked:
            rows += case_rows(path, label, asked)
    return pd.DataFrame(rows)


def strictest(rows: pd.DataFrame) -> pd.DataFrame:
    """Per case and quantity the statement that needs the longest window (the others named)."""
    if rows.empty:
        return rows
    out = []
    for _, group in rows.groupby(["case", "quantity"], sort=False):
        group = group.sort_values("window_needed", ascending=False, na_position="first")
        row = group.iloc[0].copy()
        row["also"] = ", ".join(group["statement"].iloc[1:])
        out.append(row)
    return pd.DataFrame(out)


def shown(value: float, quantity: str) -> float:
    return value / 100 if quantity == "pressure_drop" else value  # Pa/m -> hPa/m


def markdown(rows: pd.DataFrame) -> str:
    head = ("| case | quantity | statement | ours ± s.e. | s.e. asked | window run (s) | needed (s) | "
            "first met (s) | run to (s) | CPU h | outside (s.e.) |\n|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for _, r in rows.iterrows():
        q = r["quantity"]
        digits = 4 if q in PASSAGES else (2 if q == "pressure_drop" else 0)
        statement = r["statement"] + (f" (also {r['also']})" if r.get("also") else "")
        met = "–" if math.isnan(r["reached"]) else f"{r['reached']:.1f}"
        outside = "–" if math.isnan(r["outside_sem"]) else f"{r['outside_sem']:.1f}"
        cpu = "–" if math.isnan(r["cpu_h_needed"]) else f"{r['cpu_h_needed']:.2f}"
        lines.append(
            f"| {r['case']} | {q} ({r['unit_shown']}) | {statement} | "
            f"{shown(r['mean'], q):.{digits}f} ± {shown(r['sem'], q):.{digits}f} | "
            f"{shown(r['target'], q):.{digits + 1}f} | {r['window_run']:.1f} | {r['window_needed']:.1f} | "
            f"{met} | {r['run_needed']:.0f} (ran {r['run_end']:.0f}, {r['stop_reason']}) | {cpu} | {outside} |")
    return "\n".join(lines)


def statement_keys(group: pd.DataFrame) -> dict:
    """The case keys that stop a case at the precision its series statements ask (rows of one
    case): the smallest error asked of its pressure drop (absolute, Pa/m) and of its grains."""
    keys = {}
    for quantity, key in (("pressure_drop", "run.steady_pressure_drop_error"),
                          ("n_particles", "run.steady_n_particles_error")):
        pick = group[group["quantity"] == quantity]
        if len(pick):
            keys[key] = float(f"{pick['target'].min():.3g}")
    if "run.steady_pressure_drop_error" not in keys:
        keys = {"run.steady_rel_error": 1.0, **keys}  # nothing asked of the pressure drop
    return keys


def replay(ds: xr.Dataset, overrides: dict, every: int = EVERY):
    """The engine's steady window on the recorded series of `ds` with its own keys and
    `overrides`, checked every `every` frames; None when it is not steady within the series."""
    from engine import Case
    from engine.case import KEYS
    from engine.run import steady_window

    keys = {k: v for k, v in config(ds).items() if k in KEYS}  # keys this engine no longer has: left out
    case = Case().with_overrides(list({**keys, **overrides}.items()))
    t = ds["time"].values.astype(float)
    series = {name: ds[name].values for name in ("pressure_drop", "n_particles", "mass_in", "mass_out")}

    class Recorded:  # what steady_window reads of a Recorder: times and series up to a frame
        def __init__(self, k):
            self.times, self.series = t[:k], {name: values[:k] for name, values in series.items()}

    for k in range(2, t.size + 1):
        if k % every == 0 or k == t.size:
            window = steady_window(Recorded(k), case)
            if window:
                return window
    return None


def replay_rows(paths, labels_, overrides_of) -> pd.DataFrame:
    """One row per case file: the replayed stop with the keys overrides_of(label) and the means
    over its window against the file's own."""
    from analysis.curves import case_summary
    from analysis.timeseries import mean_error

    rows = []
    for path, label in zip(paths, labels_):
        overrides = overrides_of(label)
        if overrides is None:
            continue
        with xr.open_dataset(path) as ds:
            cpu_s = run_cpu_seconds(ds.attrs)
            ds = ds[[v for v in KEEP if v in ds.variables]].load()
        own = case_summary(ds)
        length = float(ds.attrs["tube_length"])
        window = replay(ds, overrides)
        row = {"case": label, "keys": " ".join(f"{k}={v:g}" for k, v in overrides.items()),
               "ran_to": float(ds["time"].values[-1]), "stop_reason": ds.attrs.get("stop_reason", ""), "cpu_s": cpu_s,
               "own_pressure_drop": own["pressure_drop"], "own_pressure_drop_sem": own["pressure_drop_sem"],
               "own_n_particles": own["n_particles"], "own_n_particles_sem": own["n_particles_sem"],
               "stop": math.nan, "start": math.nan, "pressure_drop": math.nan, "pressure_drop_sem": math.nan,
               "n_particles": math.nan, "n_particles_sem": math.nan}
        if window:
            t = ds["time"].values
            k0, k1 = int(np.searchsorted(t, window.start)), int(np.searchsorted(t, window.end))
            grains = mean_error(ds["n_particles"].values[k0:k1 + 1].astype(float), float(t[1] - t[0]))
            row.update(stop=window.end, start=window.start,
                       pressure_drop=window.pressure_drop.mean / length,
                       pressure_drop_sem=window.pressure_drop.error / length,
                       n_particles=grains.mean, n_particles_sem=grains.error)
        rows.append(row)
    return pd.DataFrame(rows)


def replay_cost(rows: pd.DataFrame) -> dict:
    """What the replayed stop would cost against the recorded runs (CPU s, pro rata of each run's
    CPU seconds by simulated time; rough, since filling costs less per second) and how many means
    move: a run stopped by steadiness or its cap (`steady`, `max_duration`) ends at the replayed
    stop when there is one; a fixed-duration or blocked run keeps its length."""
    steady_run = rows["stop_reason"].isin(["steady", "max_duration"]) & rows["stop"].notna()
    end = rows["stop"].where(steady_run, rows["ran_to"]).clip(upper=rows["ran_to"])
    moved = rows.apply(lambda r: abs(_in_errors(r["pressure_drop"], r["own_pressure_drop"],
                                                r["own_pressure_drop_sem"])), axis=1)
    return {"cases": len(rows), "stopped_earlier": int((steady_run & (end < rows["ran_to"])).sum()),
            "cpu_s": float(rows["cpu_s"].sum()), "cpu_s_replayed": float((rows["cpu_s"] * end / rows["ran_to"]).sum()),
            "moved_over_1_se": int((steady_run & (moved > 1)).sum()),
            "moved_over_2_se": int((steady_run & (moved > 2)).sum())}


def _in_errors(value: float, own: float, error: float) -> float:
    """(value - own) / error; NaN for a series without scatter (error 0)."""
    return (value - own) / error if error > 0 else math.nan


def replay_markdown(rows: pd.DataFrame) -> str:
    lines = ["| case | keys | stop (s) | pressure drop (hPa/m) | against the file's (s.e.) | grains | "
             "against the file's (s.e.) |", "|---|---|---|---|---|---|---|"]
    for _, r in rows.iterrows():
        if math.isnan(r["stop"]):
            lines.append(f"| {r['case']} | {r['keys']} | not steady by {r['ran_to']:.1f} ({r['stop_reason']}) "
                         "| – | – | – | – |")
            continue
        dp = _in_errors(r["pressure_drop"], r["own_pressure_drop"], r["own_pressure_drop_sem"])
        n = _in_errors(r["n_particles"], r["own_n_particles"], r["own_n_particles_sem"])
        lines.append(f"| {r['case']} | {r['keys']} | {r['stop']:.2f} (window from {r['start']:.2f}; ran "
                     f"{r['ran_to']:.1f}, {r['stop_reason']}) | {r['pressure_drop'] / 100:.2f} ± "
                     f"{r['pressure_drop_sem'] / 100:.2f} | {dp:+.1f} | {r['n_particles']:.0f} ± "
                     f"{r['n_particles_sem']:.0f} | {n:+.1f} |")
    return "\n".join(lines)


def every_case(paths, overrides: dict) -> None:
    """Print the replayed stop with `overrides` on every case file and its cost (replay_cost)."""
    paths = [Path(p) for p in paths]
    rows = replay_rows(paths, [f"{p.parent.name}/{p.stem}" for p in paths], lambda case: overrides)
    print(f"the engine's steady stop replayed on the recorded series (checked every {EVERY} frames):\n")
    print(replay_markdown(rows))
    c = replay_cost(rows)
    print(f"\n{c['cases']} cases, {c['stopped_earlier']} stopped earlier: {c['cpu_s']:.0f} CPU s recorded, "
          f"{c['cpu_s_replayed']:.0f} replayed ({c['cpu_s_replayed'] / c['cpu_s']:.2f}x); of the runs stopped by "
          f"steadiness or the cap, {c['moved_over_1_se']} pressure drops move by more than 1 standard error, "
          f"{c['moved_over_2_se']} by more than 2")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="+", help="case files, in results/cases/<sweep>/")
    parser.add_argument("--statements", default="resources/paper_statements.yaml")
    parser.add_argument("--identification", default="config/identification.yaml",
                        help="configuration whose identification.compare maps statements to its sweeps")
    parser.add_argument("--fraction", type=float, default=0.5,
                        help="standard error asked, as a fraction of the tolerance (default 0.5)")
    parser.add_argument("--position", type=float, default=0.26,
                        help="m, the statements' `analysis` position (config analysis.position)")
    parser.add_argument("--csv", help="write every statement's row here")
    parser.add_argument("--replay", nargs="*", metavar="KEY=VALUE",
                        help="replay the engine's steady stop with these keys (none: each case's "
                             "statement keys)")
    parser.add_argument("--every-case", action="store_true",
                        help="with --replay KEY=VALUE: replay on every case file given, judged by a "
                             "statement or not, and print the cost against the recorded runs")
    args = parser.parse_args(argv)
    if args.every_case:
        if not args.replay:
            parser.error("--every-case needs the keys to replay: --replay KEY=VALUE ...")
        every_case(args.cases, dict(parse_override(text) for text in args.replay))
        return
    statements = yaml.safe_load(Path(args.statements).read_text())
    compare = []
    if args.identification and Path(args.identification).is_file():
        compare = (yaml.safe_load(Path(args.identification).read_text()).get("identification") or {}
                   ).get("compare") or []
    rows = table(args.cases, statements, compare, args.fraction, args.position)
    if rows.empty:
        print("no statement asks a mean of these cases")
        return
    if args.csv:
        rows.to_csv(args.csv, index=False)
    print(f"standard error asked: {args.fraction:g} x the statement's tolerance; windows after the "
          "start-up transient (analysis.curves.averaging_window)\n")
    print(markdown(strictest(rows)))
    keys = {case: statement_keys(group) for case, group in rows.groupby("case", sort=False)}
    print("\ncase keys that stop each case at its statements' precision (pressure drop, grains):")
    for case, values in keys.items():
        print(f"{case}: " + " ".join(f"--set {k}={v:g}" for k, v in values.items()))
    if args.replay is not None:
        given = dict(parse_override(text) for text in args.replay)
        files = rows.drop_duplicates("case")
        replayed = replay_rows(files["file"], files["case"],
                               lambda case: given or keys.get(case))
        print(f"\nthe engine's steady stop replayed on the recorded series (checked every {EVERY} frames):\n")
        print(replay_markdown(replayed))


if __name__ == "__main__":
    main()

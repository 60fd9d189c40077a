#!/usr/bin/env python
"""Where the paper run's CPU time goes, and how long it takes on a few cores.

    python benchmarks/studies/paper_run_cost.py [TIMINGS.csv] [--summaries results/summaries]
        [--cores 2] [--top 5]

TIMINGS.csv is a job timing table of the workflow (workflow/scripts/timings.py; default
docs/reference/benchmarks/paper_run_timings.csv). Each simulate job costs its case's CPU seconds
over every part of a run resumed from checkpoints (`case_cpu_s`; `cpu_s` where that is empty).
With the case summaries of the same run (results/summaries/<sweep>/<point>.json, written by rule
`detect`) the cases are grouped as docs/performance.md tabulates them: the default cases, the
curve cases that convey, by orientation, and the blocked points; and by how each run ended (steady,
the 30 s cap, blocked, its duration).

Then the run's wall time on `--cores` idle cores if each case took its CPU seconds: list
scheduling, longest critical path first (a case waits for the case it is warm-started from, the
summary's `initial_state`), as the workflow's priorities order it (workflow/scripts/plan.py), against
the lower bound max(total / cores, longest chain of warm starts).
"""

from __future__ import annotations

import argparse
import heapq
import json
import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_TIMINGS = ROOT / "docs/reference/benchmarks/paper_run_timings.csv"


def case_costs(timings: pd.DataFrame) -> pd.Series:
    """CPU seconds of each simulate job ("<sweep>/<point>"): case_cpu_s where known, else cpu_s."""
    jobs = timings[(timings["rule"] == "simulate") & (timings["job"] != "(total)")]
    cost = jobs["cpu_s"].astype(float)
    if "case_cpu_s" in jobs:
        cost = jobs["case_cpu_s"].astype(float).fillna(cost)
    return pd.Series(cost.to_numpy(), index=jobs["job"].to_numpy(), name="cpu_s")


def read_summaries(folder: Path, jobs) -> dict[str, dict]:
    """The summary of each job that has one (results/summaries/<sweep>/<point>.json)."""
    found = {}
    for job in jobs:
        path = folder / f"{job}.json"
        if path.is_file():
            found[job] = json.loads(path.read_text())
    return found


def initial_job(summary: dict) -> str | None:
    """The job a case was warm-started from ("<sweep>/<point>"), from its summary's initial_state
    (results/cases/<sweep>/<point>.nc); None for a case from an empty tube."""
    state = summary.get("initial_state")
    if not state:
        return None
    path = Path(state)
    return f"{path.parent.name}/{path.stem}"


def group_of(job: str, summary: dict | None) -> str:
    """The row of docs/performance.md's table a case belongs to."""
    if summary is None:
        return "no summary"
    if job.split("/")[1] == "base":
        return "default cases"
    if summary.get("regime") == "blocked":
        return "blocked points"
    return ("vertical" if summary.get("vertical") else "horizontal") + " curve cases that convey"


def groups(costs: pd.Series, summaries: dict[str, dict]) -> pd.DataFrame:
    """Cases, CPU seconds and share of the total per group and per way the run ended."""
    rows = []
    for job, cpu in costs.items():
        summary = summaries.get(job)
        rows.append({"job": job, "cpu_s": cpu, "group": group_of(job, summary),
                     "stop": (summary or {}).get("stop_reason", "–")})
    table = pd.DataFrame(rows, columns=["job", "cpu_s", "group", "stop"])
    out = []
    for by in ("group", "stop"):
        agg = table.groupby(by)["cpu_s"].agg(["count", "sum"]).reset_index()
        out.append(agg.rename(columns={by: "cases", "count": "n"}).assign(by=by))
    result = pd.concat(out, ignore_index=True)[["by", "cases", "n", "sum"]]
    result["share_%"] = 100 * result["sum"] / costs.sum()
    return result.rename(columns={"sum": "cpu_s"})


def critical_paths(costs: pd.Series, parent: dict[str, str | None]) -> dict[str, float]:
    """Each job's cost plus the longest critical path of the jobs warm-started from it."""
    children: dict[str, list[str]] = {}
    for job, source in parent.items():
        if source is not None:
            children.setdefault(source, []).append(job)
    paths: dict[str, float] = {}

    def path(job: str) -> float:
        if job not in paths:
            paths[job] = costs[job] + max((path(c) for c in children.get(job, [])), default=0.0)
        return paths[job]

    for job in costs.index:
        path(job)
    return paths


def list_schedule(costs: pd.Series, parent: dict[str, str | None], cores: int) -> float:
    """Wall seconds on `cores` cores: a free core takes the ready job of longest critical path; a
    job is ready when the job it is warm-started from has finished (a source not among the jobs
    counts as finished)."""
    if cores < 1:
        raise ValueError(f"cores: {cores}; at least 1")
    priority = critical_paths(costs, parent)
    waiting = set(costs.index)
    finished: set[str] = set()
    running: list[tuple[float, str]] = []
    now = 0.0
    while waiting or running:
        ready = sorted((j for j in waiting if parent.get(j) in finished or parent.get(j) not in costs.index),
                       key=lambda j: (-priority[j], j))
        for job in ready[:cores - len(running)]:
            waiting.discard(job)
            heapq.heappush(running, (now + costs[job], job))
        now, job = heapq.heappop(running)
        finished.add(job)
    return now


def lower_bound(costs: pd.Series, parent: dict[str, str | None], cores: int) -> float:
    """No schedule on `cores` cores ends sooner: max(total / cores, the longest chain)."""
    chain = max(critical_paths(costs, parent).values(), default=0.0)
    return max(costs.sum() / cores, chain)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("timings", nargs="?", default=str(DEFAULT_TIMINGS),
                    help="job timing table (default: the committed paper run's)")
    ap.add_argument("--summaries", default="results/summaries",
                    help="folder of the run's case summaries (<sweep>/<point>.json)")
    ap.add_argument("--cores", type=int, default=2, help="cores of the schedule (default 2)")
    ap.add_argument("--top", type=int, default=5, help="the most expensive cases to list")
    args = ap.parse_args(argv)
    if args.cores < 1:
        ap.error(f"--cores {args.cores}: at least 1")
    try:
        timings = pd.read_csv(args.timings)
    except (OSError, pd.errors.ParserError) as err:
        ap.error(f"timings {args.timings}: cannot read it ({err})")
    if missing := {"rule", "job", "cpu_s"} - set(timings.columns):
        ap.error(f"timings {args.timings}: no column {', '.join(sorted(missing))} "
                 "(a table of workflow/scripts/timings.py)")
    costs = case_costs(timings)
    if costs.isna().any():
        ap.error(f"timings {args.timings}: no CPU seconds for {', '.join(costs.index[costs.isna()])}")
    summaries = read_summaries(Path(args.summaries), costs.index)
    print(f"{len(costs)} simulate jobs, {costs.sum():,.0f} CPU s; summaries for {len(summaries)} "
          f"in {args.summaries}")
    if summaries:
        print(groups(costs, summaries).to_string(index=False, float_format=lambda v: f"{v:,.0f}"))
    print(f"\nthe {args.top} most expensive:")
    for job, cpu in costs.sort_values(ascending=False).head(args.top).items():
        print(f"  {job}: {cpu:,.0f} CPU s")
    parent = {job: initial_job(s) for job, s in summaries.items()}
    wall = list_schedule(costs, parent, args.cores)
    bound = lower_bound(costs, parent, args.cores)
    note = "" if summaries else " (no summaries: no warm-start order)"
    print(f"\non {args.cores} idle cores, longest critical path first: {wall / 3600:.2f} h; lower bound "
          f"{bound / 3600:.2f} h{note}")


if __name__ == "__main__":
    main()

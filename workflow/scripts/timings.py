"""Collect the `benchmark:` files of the jobs (results/benchmarks/jobs/<rule>/...tsv) into one
table: one row per job (rule, job, wall s, max RSS MB, CPU s) and a per-rule total at the end.
Run by the workflow's onsuccess handler, or standalone:

    python workflow/scripts/timings.py results/benchmarks/jobs results/benchmarks/timings.csv
"""

import sys
from pathlib import Path

import pandas as pd


def collect(jobs_dir, out) -> pd.DataFrame:
    rows = []
    for path in sorted(Path(jobs_dir).glob("**/*.tsv")):
        try:
            bench = pd.read_csv(path, sep="\t")
        except (pd.errors.EmptyDataError, pd.errors.ParserError):
            continue
        rel = path.relative_to(jobs_dir)
        rows.append({"rule": rel.parts[0], "job": str(rel.with_suffix(""))[len(rel.parts[0]) + 1:],
                     "wall_s": float(bench["s"].mean()),
                     "max_rss_mb": float(pd.to_numeric(bench["max_rss"], errors="coerce").max()),
                     "cpu_s": float(pd.to_numeric(bench.get("cpu_time", float("nan")),
                                                  errors="coerce").mean())})
    table = pd.DataFrame(rows, columns=["rule", "job", "wall_s", "max_rss_mb", "cpu_s"])
    totals = table.groupby("rule", as_index=False).agg(wall_s=("wall_s", "sum"),
                                                         max_rss_mb=("max_rss_mb", "max"),
                                                         cpu_s=("cpu_s", "sum"))
    totals["job"] = "(total)"
    out_table = pd.concat([table, totals[table.columns]], ignore_index=True)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    out_table.to_csv(out, index=False, float_format="%.3f")
    return out_table


if __name__ == "__main__":
    collect(sys.argv[1], sys.argv[2])

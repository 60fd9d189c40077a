"""Collect the `benchmark:` files of the jobs (results/benchmarks/jobs/<rule>/...tsv) into one
table: one row per job (rule, job, wall s, max RSS MB, CPU s of the job's last process and, for a
simulate job, `case_cpu_s`: the case file's CPU seconds over all the parts of a run resumed from
checkpoints) and a per-rule total at the end. Run by the workflow's onsuccess handler, or
standalone:

    python workflow/scripts/timings.py results/benchmarks/jobs results/benchmarks/timings.csv [results/cases]
"""

import sys
from pathlib import Path

import netCDF4
import pandas as pd

from analysis.casefile import run_cpu_seconds


def case_cpu_seconds(case_file: Path) -> float:
    """CPU seconds of all the parts of the run that wrote a case file (analysis.casefile
    .run_cpu_seconds); NaN when unknown or the file is missing."""
    if not case_file.is_file():
        return float("nan")
    with netCDF4.Dataset(case_file) as ds:
        return run_cpu_seconds({name: ds.getncattr(name) for name in ds.ncattrs()})


def _complete_sum(values: pd.Series) -> float:
    """The sum when every value is known, else NaN (a total must not leave a case out unseen)."""
    return float(values.sum()) if values.notna().all() else float("nan")


def collect(jobs_dir, out, cases_dir="results/cases") -> pd.DataFrame:
    rows = []
    for path in sorted(Path(jobs_dir).glob("**/*.tsv")):
        try:
            bench = pd.read_csv(path, sep="\t")
        except (pd.errors.EmptyDataError, pd.errors.ParserError):
            continue
        rel = path.relative_to(jobs_dir)
        job = str(rel.with_suffix(""))[len(rel.parts[0]) + 1:]
        rows.append({"rule": rel.parts[0], "job": job,
                     "wall_s": float(bench["s"].mean()),
                     "max_rss_mb": float(pd.to_numeric(bench["max_rss"], errors="coerce").max()),
                     "cpu_s": float(pd.to_numeric(bench.get("cpu_time", float("nan")),
                                                  errors="coerce").mean()),
                     "case_cpu_s": (case_cpu_seconds(Path(cases_dir) / f"{job}.nc")
                                    if rel.parts[0] == "simulate" else float("nan"))})
    table = pd.DataFrame(rows, columns=["rule", "job", "wall_s", "max_rss_mb", "cpu_s", "case_cpu_s"])
    totals = table.groupby("rule", as_index=False).agg(wall_s=("wall_s", "sum"),
                                                         max_rss_mb=("max_rss_mb", "max"),
                                                         cpu_s=("cpu_s", "sum"),
                                                         case_cpu_s=("case_cpu_s", _complete_sum))
    totals["job"] = "(total)"
    out_table = pd.concat([table, totals[table.columns]], ignore_index=True)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    out_table.to_csv(out, index=False, float_format="%.3f")
    return out_table


if __name__ == "__main__":
    collect(*sys.argv[1:4])

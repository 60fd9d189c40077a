"""workflow/scripts/timings.py: the job timing table and the case files' CPU seconds."""

import math
import sys
from pathlib import Path

import netCDF4
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "workflow" / "scripts"))
import timings  # noqa: E402

BENCH = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n{wall}\t0\t100\t0\t0\t0\t0\t0\t0\t{cpu}\n"


def _job(jobs, rule, job, wall, cpu):
    path = jobs / rule / f"{job}.tsv"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(BENCH.format(wall=wall, cpu=cpu))


def _case(cases, job, total, resumed=1, part=10.0):
    path = cases / f"{job}.nc"
    path.parent.mkdir(parents=True, exist_ok=True)
    with netCDF4.Dataset(path, "w") as ds:
        ds.resumed, ds.cpu_time_s = resumed, part
        if total is not None:
            ds.cpu_time_total_s = total


def test_a_resumed_case_counts_all_its_parts_and_a_total_never_drops_an_unknown(tmp_path):
    jobs, cases = tmp_path / "jobs", tmp_path / "cases"
    _job(jobs, "simulate", "h_default/base", wall=60.0, cpu=50.0)   # its last part only
    _case(cases, "h_default/base", 400.0)                           # all its parts
    _job(jobs, "simulate", "h_vs/gas.superficial_velocity~4", wall=30.0, cpu=25.0)
    _case(cases, "h_vs/gas.superficial_velocity~4", 24.0)
    _job(jobs, "detect", "h_default/base", wall=2.0, cpu=1.5)
    table = timings.collect(jobs, tmp_path / "timings.csv", cases).set_index(["rule", "job"])
    assert table.loc[("simulate", "h_default/base"), "case_cpu_s"] == 400.0
    assert table.loc[("simulate", "(total)"), "case_cpu_s"] == 424.0
    assert table.loc[("simulate", "(total)"), "cpu_s"] == 75.0
    assert math.isnan(table.loc[("detect", "h_default/base"), "case_cpu_s"])
    # a resumed case file without the count (an engine that did not keep it): the total is unknown
    _case(cases, "h_default/base", None)
    table = timings.collect(jobs, tmp_path / "timings.csv", cases).set_index(["rule", "job"])
    assert math.isnan(table.loc[("simulate", "h_default/base"), "case_cpu_s"])
    assert math.isnan(table.loc[("simulate", "(total)"), "case_cpu_s"])
    # ... unless it ran in one part: then its part is the whole
    _case(cases, "h_default/base", None, resumed=0, part=380.0)
    table = timings.collect(jobs, tmp_path / "timings.csv", cases).set_index(["rule", "job"])
    assert table.loc[("simulate", "(total)"), "case_cpu_s"] == 404.0
    written = pd.read_csv(tmp_path / "timings.csv")
    assert list(written.columns) == ["rule", "job", "wall_s", "max_rss_mb", "cpu_s", "case_cpu_s"]

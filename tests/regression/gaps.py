"""Measure the gaps that justify the tolerances of tests/regression/cases.py:

    python -m tests.regression.gaps measure OUT.json [--times 0.06 0.07 ...]
    python -m tests.regression.gaps compare A.json B.json

`measure` computes every regression quantity at several durations from one run per case (the
short runs' quantities from the first frames of one longer run: identical to runs of those
durations). Run it (a) twice with a warm numba cache (bit-identical), (b) with
NUMBA_CACHE_DIR=<an empty folder> (the kernels compiled in-process), (c) with a force law changed
by 1 % (a fresh NUMBA_CACHE_DIR: numba's cache does not see a change of laws.py, which other files'
kernels inline); `compare` prints the relative gap of each quantity at each duration.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from . import cases

TIMES = [0.06, 0.07, 0.08, 0.09, 0.1, 0.11, 0.12, 0.13, 0.14, 0.15]


def measure(times) -> dict:
    import xarray as xr

    res = {}
    started = time.process_time()
    res["packed_bed"] = {str(k): v for k, v in cases.packed_bed(sample_times=times).items()}
    res["cpu_s"] = {"packed_bed": time.process_time() - started}
    tmp = Path(tempfile.mkdtemp(prefix="plugsim-gaps-"))
    for orientation in ("horizontal", "vertical"):
        started = time.process_time()
        path = cases.run_short(orientation, max(times), tmp / f"{orientation}.nc")
        res["cpu_s"][orientation] = time.process_time() - started
        ds = xr.open_dataset(path).load()
        res[orientation], reduced = {}, {}
        for t in times:
            part = ds.isel(time=slice(0, int(round(t / 0.01)) + 1))
            res[orientation][str(t)] = cases.run_quantities(part)
            reduced[str(t)] = cases.reduce_case(part)
        if orientation == "horizontal":
            res["reduction_engine"] = reduced
    return res


def compare(a: dict, b: dict) -> str:
    lines = []
    for case in ("packed_bed", "horizontal", "vertical", "reduction_engine"):
        times = list(a[case])
        lines += [f"== {case}", f"{'quantity':24s}" + "".join(f"{t:>9s}" for t in times)]
        for key in a[case][times[0]]:
            row = []
            for t in times:
                x, y = a[case][t].get(key), b[case][t].get(key)
                if isinstance(x, str) or x is None or y is None:
                    row.append("same" if x == y else "DIFF")
                    continue
                scale = max(abs(x), abs(y))
                gap = abs(x - y) / scale if scale else 0.0
                row.append(f"{gap:.1e}" if gap else "0")
            lines.append(f"{key:24s}" + "".join(f"{r:>9s}" for r in row))
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m tests.regression.gaps")
    sub = parser.add_subparsers(dest="command", required=True)
    m = sub.add_parser("measure")
    m.add_argument("out")
    m.add_argument("--times", type=float, nargs="+", default=TIMES)
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    args = parser.parse_args(argv)
    if args.command == "measure":
        Path(args.out).write_text(json.dumps(measure(args.times), indent=1) + "\n")
    else:
        print(compare(json.loads(Path(args.a).read_text()), json.loads(Path(args.b).read_text())))


if __name__ == "__main__":
    main()

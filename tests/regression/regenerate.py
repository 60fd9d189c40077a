"""Regenerate the regression baselines (tests/regression/baselines/*.json):

    python -m tests.regression.regenerate            # every case
    python -m tests.regression.regenerate vertical   # some

A regeneration is a deliberate act: run it only when a result is meant to change (a physics or
numerics change, a new quantity), and name it in CHANGELOG.md with the reason; the script prints
which stored values moved and by how much, and the line to adapt.

The cases run in a child process whose numba cache is named after a hash of the engine's numba
source (tests/regression/cases.py, kernel_cache_dir), as in the test: numba's own cache does not
notice a change to an inlined function of another file (engine/kernels/laws.py), and a stale cache
would store the old physics as the new baseline.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

from . import cases

ROOT = Path(__file__).resolve().parents[2]


def software() -> dict:
    import numba
    import numpy

    import engine
    return {"plugsim": engine.__version__, "numba": numba.__version__, "numpy": numpy.__version__,
            "python": platform.python_version(), "machine": platform.machine()}


def write(name: str, values: dict) -> dict:
    """Store the quantities `values` of case `name`; returns the previous values (or {})."""
    path = cases.BASELINES / f"{name}.json"
    old = json.loads(path.read_text())["values"] if path.exists() else {}
    doc = " ".join((cases.CASES[name].__doc__ or "").split())
    record = {"case": name, "about": doc, "duration_s": cases.DURATION.get(name, cases.DURATION["horizontal"]),
              "software": software(), "values": values}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1, sort_keys=False) + "\n")
    return old


def moved(old: dict, new: dict) -> list[str]:
    lines = []
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key, "absent"), new.get(key, "absent")
        if a == b:
            continue
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
            scale = max(abs(a), abs(b))
            gap = abs(a - b) / scale if scale else 0.0
            lines.append(f"  {key}: {a!r} -> {b!r} (relative change {gap:.2e})")
        else:
            lines.append(f"  {key}: {a!r} -> {b!r}")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.regression.regenerate", description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", choices=[[], *cases.CASES], metavar="CASE",
                        help=f"cases to regenerate (default all: {', '.join(cases.CASES)})")
    args = parser.parse_args(argv)
    names = args.names or list(cases.CASES)
    if not cases.kernel_cache_dir().exists():
        print("compiling the kernels for the current source (about a minute)", flush=True)
    results = cases.run_in_child(names)
    changed = []
    for name in names:
        new_path = cases.BASELINES / f"{name}.json"
        old = write(name, results[name])
        new = json.loads(new_path.read_text())["values"]
        lines = moved(old, new)
        state = "new baseline" if not old else f"{len(lines)} value(s) moved" if lines else "unchanged"
        print(f"{new_path.relative_to(ROOT)}: {state}")
        if lines and old:
            print("\n".join(lines))
        if lines:
            changed.append(name)
    if changed:
        print(f"\nRegenerated {', '.join(changed)}. Name this regeneration and why in CHANGELOG.md, e.g.\n"
              f"  - Regression baselines regenerated ({', '.join(changed)}): <the change that moved them>.")
    else:
        print("\nNo stored value changed; nothing to name in CHANGELOG.md.")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Regression baselines: small cases whose key outputs are stored in tests/regression/baselines/
and must stay within the tolerance stated (and justified by measured gaps) per quantity in
tests/regression/cases.py. A failure means a result changed: if the change is intended,
regenerate with `python -m tests.regression.regenerate` and name it in CHANGELOG.md
(docs/engine.md, "Regression baselines")."""

import json
import math
from concurrent.futures import ThreadPoolExecutor

import pytest

from . import cases


def compare(name: str, got: dict) -> list[str]:
    """Every quantity of case `name` outside its tolerance, as readable lines (empty: all pass)."""
    stored = json.loads((cases.BASELINES / f"{name}.json").read_text())["values"]
    problems = []
    for key in sorted(set(stored) | set(got)):
        if key not in got or key not in stored:
            problems.append(f"{key}: {'missing from the result' if key not in got else 'not in the baseline'}")
            continue
        base, value = stored[key], got[key]
        rel, abs_ = cases.tolerance(name, key)
        if isinstance(base, str) or base is None or value is None or isinstance(base, bool):
            if base != value:
                problems.append(f"{key}: {value!r}, baseline {base!r}")
            continue
        gap = abs(value - base)
        allowed = abs_ + rel * abs(base)
        if not gap <= allowed:  # NaN fails
            scale = abs(base) or 1.0
            problems.append(f"{key}: {value!r}, baseline {base!r}: off by {gap:.3g} ({gap / scale:.2e} "
                            f"relative), allowed {allowed:.3g} (rel {rel:g}, abs {abs_:g})")
    return problems


@pytest.fixture(scope="module")
def results():
    """Every case's quantities, from a child process whose kernels match the current source
    (cases.run_in_child: a stale numba cache would hide a change of a force law)."""
    return cases.run_in_child(list(cases.CASES))


@pytest.mark.parametrize("name", list(cases.CASES))
def test_case_matches_its_baseline(results, name):
    got = results[name]
    problems = compare(name, got)
    assert not problems, (
        f"regression case {name!r} moved from tests/regression/baselines/{name}.json:\n  "
        + "\n  ".join(problems)
        + "\nIf intended: python -m tests.regression.regenerate " + name + " and name it in CHANGELOG.md")


def test_every_quantity_has_a_justified_tolerance():
    """Each stored quantity falls under an entry of TOLERANCES (a case's own or its default)."""
    for name in cases.CASES:
        stored = json.loads((cases.BASELINES / f"{name}.json").read_text())["values"]
        for key in stored:
            rel, abs_ = cases.tolerance(name, key)
            assert rel >= 0 and abs_ >= 0 and math.isfinite(rel + abs_)


def test_the_cases_do_not_depend_on_the_vector_width_the_kernels_are_compiled_for():
    """packed_bed (grains only) and horizontal (gas and feed too) with the kernels compiled for this
    machine's widest vectors and for half as wide ones (cases.host_cpu): bit-identical. Fastmath's
    `reassoc` lets the compiler sum in an order set by the vector width, and the settling bed
    amplifies that order to the size of a physics change (measured: compiled for a 256-bit Intel
    Xeon and for a 512-bit AMD EPYC the packed bed's largest overlap differed 3.5-fold); without it
    a case's result depends on the code, not on the machine."""
    names = ["packed_bed", "horizontal"]
    with ThreadPoolExecutor(2) as pool:  # two compiles, about a minute of CPU each
        wide, narrow = pool.map(lambda wide_vectors: cases.run_in_child(names, cases.host_cpu(wide_vectors)),
                                (True, False))
    assert wide == narrow

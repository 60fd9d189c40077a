"""The case-file contract (analysis/contract.py): consistent declarations, its generated docs
table, the synthetic case files built from it, the units the analysis refuses, and the analysis
package free of the engine. The engine's side: tests/engine/test_output_contract.py."""

import ast
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis import CaseFileError, contract, detect

from . import synthetic

ROOT = Path(__file__).resolve().parents[2]
SI = {"1", "m", "s", "kg", "N", "Pa", "J", "rad"}  # the analysis computes in SI (analysis/__init__.py)


def test_docs_table_is_generated_from_the_contract():
    assert (ROOT / "docs" / "case-file.md").read_text() == contract.markdown(), (
        "docs/case-file.md is stale: python -m analysis > docs/case-file.md")


def test_units_are_si_symbols():
    for var in contract.VARIABLES.values():
        if var.units is not None:
            tokens = {re.sub(r"(?<=[a-zA-Z])-?\d+$", "", token) for token in var.units.split()}
            assert tokens <= SI, f"{var.name}: {var.units!r}"


def test_declarations_are_consistent():
    names = [name for group in contract.GROUPS.values() for name in group]
    assert len(names) == len(set(names)) == len(contract.VARIABLES)
    assert all(v.dims == contract.TIME for v in contract.SERIES.values())
    assert all(v.dims == contract.SLICES and v.dtype == "float32" for v in contract.FIELDS.values())
    for group in (contract.SNAPSHOTS, contract.TUBE_SNAPSHOTS):
        count, *arrays = group.values()
        assert count.sample_dimension and all(v.dims[0] == count.sample_dimension for v in arrays)
        assert count.dims[0] in contract.COORDS
    for var in contract.VARIABLES.values():
        assert var.long_name and var.attrs["long_name"] == var.long_name
        assert var.profile <= bool(var.label), f"{var.name}: a profiled field needs its plot label"
    assert contract.PROFILE_FIELDS == ("porosity", "velocity", "drag_force", "particle_force",
                                       "wall_stress", "granular_temperature")  # the papers' H12-H16
    assert contract.label("drag_force") == ("force per grain (µN)", 1e6)
    assert contract.label("gas_pressure") == ("gas_pressure", 1.0)


def test_synthetic_case_files_follow_the_contract(default_case):
    groups = {**contract.SERIES, **contract.FIELDS, **contract.SNAPSHOTS}
    for name, var in {**groups, **{k: contract.COORDS[k] for k in ("time", "x", "snapshot_time")}}.items():
        assert default_case[name].dims == var.dims, name
        assert default_case[name].attrs == var.attrs, name
    assert default_case["porosity"].dtype == np.float64  # synthetic slices stay exact


def test_other_units_than_the_contract_are_refused():
    ds = synthetic.build(synthetic.periodic(0.75, 0.3, 0.05, 1.0), 1.0)
    ds["velocity"].attrs["units"] = "mm s-1"
    with pytest.raises(CaseFileError, match=r"velocity in 'mm s-1', not 'm s-1'"):
        detect(ds)


def test_the_analysis_never_imports_the_engine():
    for path in sorted((ROOT / "analysis").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            modules = ([a.name for a in node.names] if isinstance(node, ast.Import)
                       else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            assert not any(m == "engine" or m.startswith("engine.") for m in modules), path.name
    code = ("import sys, analysis, analysis.contract, analysis.plots, analysis.precision\n"
            "assert not [m for m in sys.modules if m.split('.')[0] == 'engine'], 'engine imported'")
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)

"""Tests of the scripts in benchmarks/ (loaded by path: benchmarks/ is not a package)."""

import importlib.util
import sys
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def load_benchmark(name: str):
    """The module of benchmarks/<name>.py (name may be `studies/<script>`), registered in
    sys.modules (dataclasses look it up)."""
    module_name = "benchmarks_" + name.replace("/", "_")
    spec = importlib.util.spec_from_file_location(module_name, BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module

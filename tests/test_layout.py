"""The package layout's import rules, read from the sources (ast): the analysis never imports the
engine, and no two modules of a package import each other (at module level or inside a function)."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def imported_modules(path: Path, package: str) -> set[str]:
    """Dotted names of the modules a source file imports anywhere in it (relative imports
    resolved against `package`)."""
    names = set()
    parts = path.relative_to(ROOT).with_suffix("").parts
    here = parts[:-1] if parts[-1] != "__init__" else parts
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = here[:len(here) - node.level + 1] if node.level else ()
            module = ".".join([*base, *([node.module] if node.module else [])])
            names.add(module)
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return names


def package_graph(package: str) -> dict[str, set[str]]:
    """module -> the modules of the same package it imports."""
    files = {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
             for p in (ROOT / package).rglob("*.py")}
    return {name: {m for m in imported_modules(path, package) if m in files and m != name}
            for name, path in files.items()}


def test_the_analysis_never_imports_the_engine():
    offenders = {name: sorted(m for m in imported_modules(path, "analysis")
                              if m == "engine" or m.startswith("engine."))
                 for name, path in ((p.stem, p) for p in (ROOT / "analysis").rglob("*.py"))}
    assert not {k: v for k, v in offenders.items() if v}


@pytest.mark.parametrize("package", ["engine", "analysis"])
def test_no_two_modules_import_each_other(package):
    graph = package_graph(package)
    pairs = sorted((a, b) for a, deps in graph.items() for b in deps
                   if a < b and a in graph.get(b, set()) and not b.startswith(a + "."))
    assert not pairs, f"modules importing each other: {pairs}"


def test_the_import_reader_sees_a_function_level_cycle(tmp_path, monkeypatch):
    # the rule must be able to fail: two modules importing each other, one inside a function
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import f\n")
    (pkg / "b.py").write_text("def f():\n    from .a import g\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    graph = package_graph("pkg")
    assert "pkg.b" in graph["pkg.a"] and "pkg.a" in graph["pkg.b"]

"""The registry of figure kinds (workflow/scripts/figure_kinds.py) is the one list the config
schema, the plan and the figure script agree on."""

from __future__ import annotations

import inspect
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
# appended, not prepended: workflow/scripts/statistics.py must not shadow the standard library
sys.path.append(str(ROOT / "workflow" / "scripts"))
import figure  # noqa: E402
from figure_kinds import DRAWS, KINDS, NEEDS  # noqa: E402


def test_schema_enum_of_kinds_is_the_registry():
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    enum = schema["properties"]["figures"]["additionalProperties"]["properties"]["kind"]["enum"]
    assert sorted(enum) == sorted(KINDS)


def test_every_kind_draws_with_a_function_of_the_figure_script():
    for name, kind in KINDS.items():
        draw = figure.draw_function(name)
        assert inspect.isfunction(draw) and draw.__module__ == "figure", name
        assert list(inspect.signature(draw).parameters) == ["inp", "spec", "settings"], name


def test_every_kind_says_what_it_draws_and_needs():
    for name, kind in KINDS.items():
        assert kind.draws in DRAWS, name
        assert kind.needs and kind.needs <= set(NEEDS), name


def test_every_figure_of_the_configs_has_a_registered_kind():
    for path in sorted((ROOT / "config").glob("*.yaml")):
        for fig, spec in (yaml.safe_load(path.read_text()).get("figures") or {}).items():
            assert spec["kind"] in KINDS, f"{path.name}: {fig}"
            assert KINDS[spec["kind"]].draws in spec, f"{path.name}: {fig}"

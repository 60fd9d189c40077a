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


def test_curve_caption_line_of_a_blocked_point_has_no_nan_error_and_no_repeated_regime():
    import pandas as pd
    table = pd.DataFrame([
        {"gas.superficial_velocity": 0.15, "pressure_drop": 5090.0, "pressure_drop_sem": float("nan"),
         "regime": "blocked", "stop_reason": "blocked", "delivery": 0.44, "t_start": 9.66, "t_end": 11.49},
        {"gas.superficial_velocity": 1.0, "pressure_drop": 867.0, "pressure_drop_sem": 32.0,
         "regime": "slug", "stop_reason": "steady", "delivery": 0.99, "t_start": 1.0, "t_end": 30.0}])
    blocked, slug = figure._curve_facts(table, "gas.superficial_velocity")
    assert "nan" not in blocked and "no standard error (the window covers too few correlation times)" in blocked
    assert blocked.count("blocked") == 1 and "delivers 44% of its feed" in blocked
    assert "8.67 +- 0.32 hPa/m (slug, delivers 99% of its feed, steady" in slug

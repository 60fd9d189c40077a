"""The registry of figure kinds (workflow/scripts/figure_kinds.py) is the one list the config
schema, the plan and the figure script agree on."""

from __future__ import annotations

import inspect
import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "workflow" / "scripts"))
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


def _grain_columns(fig, ax, points_mm) -> list[np.ndarray]:
    """Per 3-D point (mm), the RGB pixels of the rendered figure within 4 px of where it lands."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from mpl_toolkits.mplot3d import proj3d
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3] / 255.0
    xs, ys, _ = proj3d.proj_transform(*np.asarray(points_mm, dtype=float).T, ax.get_proj())
    near = []
    for col, row in ax.transData.transform(np.column_stack([xs, ys])):
        r, c = int(round(image.shape[0] - row)), int(round(col))
        near.append(image[max(r - 4, 0):r + 5, max(c - 4, 0):c + 5].reshape(-1, 3))
    return near


def test_grains_3d_draws_the_grains_at_both_ends_of_the_stretch(tmp_path):
    """H02 drew only the middle 1/2.2 of its stretch (perspective clipping at zoom 2.2)."""
    from types import SimpleNamespace
    import pandas as pd
    sys.path.insert(0, str(ROOT))
    from tests.analysis import synthetic as S
    center, stretch = 0.05, 0.05
    lo, hi = center - stretch / 2 + S.D_GRAIN / 2, center + stretch / 2 - S.D_GRAIN / 2
    rng = np.random.default_rng(0)
    pos, vel = S.packed_grains(rng, 100, (0.04, 0.06))
    ends = np.array([[lo, 0.0, 0.0], [hi, 0.0, 0.0]])
    pos, vel = np.vstack([pos, ends]), np.vstack([vel, [[0.3, 0, 0]] * 2])
    case = tmp_path / "case.nc"
    S.write(S.build([], duration=1.0, snapshots=[(0.5, pos, vel)]), case)
    pd.DataFrame([{"slug_id": 7, "time": 0.5, "x_center": center, "x_start_total": 0.03,
                   "x_end_total": 0.07, "length_total": 0.04, "n_particles": 100}]).to_csv(
        tmp_path / "slugs.csv", index=False)
    pd.DataFrame({"slug_id": [7]}).to_csv(tmp_path / "selection.csv", index=False)
    inp = SimpleNamespace(case=case, slugs=tmp_path / "slugs.csv", selection=tmp_path / "selection.csv")
    fig, facts = figure.grains_3d(inp, {"kind": "grains_3d"}, {"grains_stretch": stretch})
    ax = fig.axes[0]
    for where, pixels in zip(("first", "last"), _grain_columns(fig, ax, ends * 1e3)):
        coloured = pixels.max(axis=1) - pixels.min(axis=1) > 0.2  # viridis, not grey or black
        assert coloured.sum() >= 10, f"no grain drawn at the {where} end of the stretch"
    assert "102 grains in the 5.0 cm stretch drawn (x = 25-75 mm)" in facts[-1]


def test_grains_3d_titles_name_no_stretch_length():
    """The caption's facts give the stretch drawn (analysis.grains_stretch, 5 cm in CI); a length in
    the title contradicted them."""
    import re
    for path in sorted((ROOT / "config").glob("*.yaml")):
        for fig, spec in (yaml.safe_load(path.read_text()).get("figures") or {}).items():
            if spec["kind"] == "grains_3d":
                assert not re.search(r"\d\s*(cm|mm|m)\b", spec.get("title", "")), f"{path.name}: {fig}"


def test_curve_caption_of_a_blocked_point_gives_its_force_balance():
    import pandas as pd
    row = {"gas.superficial_velocity": 0.15, "pressure_drop": 5090.0, "pressure_drop_sem": 40.0,
           "regime": "blocked", "stop_reason": "blocked", "delivery": 0.44, "t_start": 9.66,
           "t_end": 11.49, "block_piston_force": 2.1, "block_gas_force": 0.12,
           "block_weight_force": 0.0, "block_wall_friction_force": 0.031}
    conveying = {**row, "regime": "slug", "stop_reason": "steady", "delivery": 1.0,
                 "block_piston_force": float("nan")}
    blocked, slug = figure._curve_facts(pd.DataFrame([row, conveying]), "gas.superficial_velocity")
    assert ("axial forces over its last second: piston 2.1 N, gas drag 0.12 N, weight along the "
            "tube 0 N, wall friction of the weight 0.031 N") in blocked
    assert "axial forces" not in slug

"""The identification table (workflow/scripts/identification.py) on synthetic curve tables: each
reading's verdict follows its own data and the papers' tolerances."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "workflow" / "scripts"))
import identification  # noqa: E402

READINGS = ["gas.face_permeability", "gas.scheme"]
STATEMENTS = [
    {"id": "DP", "statement": "dp", "measure": "pressure_drop", "value": 39, "unit": "hPa/m", "tolerance": 7.8},
    {"id": "REG", "statement": "regime", "measure": "regime", "expected": "plug"},
    {"id": "PEAK", "statement": "peak", "measure": "argmax", "value": 0.1, "unit": "1", "tolerance": 0.05,
     "x": "particles.friction", "within": [0.0, 0.3]},
]


def readings_table(dp_pa_m, regimes, friction=None):
    """Rows of a sweep over the two reading keys (harmonic/arithmetic x unsplit)."""
    rows = []
    for k, face in enumerate(["harmonic", "arithmetic"]):
        for j, mu in enumerate(friction or [0.5]):
            rows.append({"gas.face_permeability": face, "gas.scheme": "unsplit", "particles.friction": mu,
                         "pressure_drop": dp_pa_m[k][j] if friction else dp_pa_m[k],
                         "pressure_drop_sem": 50.0, "regime": regimes[k]})
    return pd.DataFrame(rows)


def test_each_reading_gets_its_own_verdict():
    tables = {"s": readings_table([3300.0, 4700.0], ["plug", "bulk"])}
    compare = [{"statement": "DP", "sweep": "s"}, {"statement": "REG", "sweep": "s"}]
    df = identification.table(STATEMENTS, tables, compare, READINGS)
    dp = df[df["id"] == "DP"].set_index("reading")
    # ours +- 2 x 0.5 hPa/m against 39 +- 7.8: 32-34 and 46-48 both overlap 31.2-46.8
    assert dp["ours"].tolist() == pytest.approx([33.0, 47.0])
    assert dp["ratio"].tolist() == pytest.approx([33 / 39, 47 / 39])
    assert dp["within"].tolist() == ["yes", "yes"]
    reg = df[df["id"] == "REG"].set_index("reading")
    assert reg["within"].tolist() == ["yes", "no"]
    assert reg.index.tolist() == ["face_permeability=harmonic, scheme=unsplit",
                                  "face_permeability=arithmetic, scheme=unsplit"]


def test_a_reading_outside_the_tolerance_is_not_within():
    tables = {"s": readings_table([2000.0, 3900.0], ["plug", "plug"])}
    df = identification.table(STATEMENTS, tables, [{"statement": "DP", "sweep": "s"}], READINGS)
    # 20 +- 2 x 0.5 hPa/m misses 31.2-46.8; 39 is the paper's value
    assert df["within"].tolist() == ["no", "yes"]


def test_grain_velocity_and_travel_speed_are_told_apart():
    # the papers' grain velocity in a slug (0.29 m/s) and its travel speed (0.42 m/s) are two
    # statements: each must read its own column of the curve table
    table = readings_table([3300.0, 4700.0], ["slug", "slug"])
    table["max_velocity"], table["travel_speed"] = [0.35, 0.30], [0.47, 0.43]
    statements = [{"id": "U", "statement": "u", "measure": "slug_stat", "value": 0.29, "unit": "m/s",
                   "tolerance": 0.03},
                  {"id": "T", "statement": "t", "measure": "slug_stat", "value": 0.42, "unit": "m/s",
                   "tolerance": 0.04}]
    compare = [{"statement": "U", "sweep": "s", "measure": "max_velocity"},
               {"statement": "T", "sweep": "s", "measure": "travel_speed"}]
    df = identification.table(statements, {"s": table}, compare, READINGS).set_index(["id", "reading"])
    assert df.loc["U", "ours"].tolist() == pytest.approx([0.35, 0.30])
    assert df.loc["U", "within"].tolist() == ["no", "yes"]
    assert df.loc["T", "ours"].tolist() == pytest.approx([0.47, 0.43])
    assert df.loc["T", "within"].tolist() == ["no", "yes"]


def test_a_blocked_reading_is_not_within():
    # 47 hPa/m would be within 39 +- 7.8, but the tube did not deliver its feed
    tables = {"s": readings_table([3300.0, 4700.0], ["plug", "blocked"])}
    df = identification.table(STATEMENTS, tables, [{"statement": "DP", "sweep": "s"}], READINGS)
    assert df["within"].tolist() == ["yes", "no (blocked)"]
    assert df["ours"].tolist() == pytest.approx([33.0, 47.0])  # the value is still shown


def test_argmax_is_taken_within_each_reading():
    friction = [0.1, 0.3]
    tables = {"f": readings_table([[900.0, 700.0], [700.0, 900.0]], ["slug", "slug"], friction)}
    df = identification.table(STATEMENTS, tables, [{"statement": "PEAK", "sweep": "f"}], READINGS)
    assert df["ours"].tolist() == [0.1, 0.3]
    assert df["within"].tolist() == ["yes", "no"]


def test_where_selects_points_and_an_empty_selection_is_an_error():
    tables = {"s": readings_table([3300.0, 4700.0], ["plug", "plug"])}
    compare = [{"statement": "DP", "sweep": "s", "where": {"particles.friction": 0.5}}]
    assert len(identification.table(STATEMENTS, tables, compare, READINGS)) == 2
    compare = [{"statement": "DP", "sweep": "s", "where": {"particles.friction": 0.7}}]
    with pytest.raises(ValueError, match="no row of sweep s"):
        identification.table(STATEMENTS, tables, compare, READINGS)


def test_markdown_counts_and_figure(tmp_path):
    tables = {"s": readings_table([2000.0, 3900.0], ["plug", "bulk"])}
    compare = [{"statement": "DP", "sweep": "s"}, {"statement": "REG", "sweep": "s"}]
    df = identification.table(STATEMENTS, tables, compare, READINGS)
    text = identification.markdown(df)
    assert "| face_permeability=harmonic, scheme=unsplit | 1 | 2 |" in text
    assert "| face_permeability=arithmetic, scheme=unsplit | 1 | 2 |" in text
    identification.figure(df, tmp_path / "id.png")
    from matplotlib.image import imread
    assert imread(tmp_path / "id.png").ndim == 3


def test_each_reading_has_its_effect_against_the_baseline_reading():
    tables = {"s": readings_table([3300.0, 4700.0], ["plug", "plug"])}
    baselines = {"s": {"gas.face_permeability": "arithmetic", "gas.scheme": "unsplit"}}
    df = identification.table(STATEMENTS, tables, [{"statement": "DP", "sweep": "s"}], READINGS, baselines)
    df = df.set_index("reading")
    # a reading is named by what differs from the baseline
    assert set(df.index) == {"baseline", "face_permeability=harmonic"}
    # harmonic 33 hPa/m against the arithmetic baseline's 47, each +- 0.5: -14 +- 0.71
    assert df.loc["face_permeability=harmonic", "effect"] == pytest.approx(-14.0)
    assert df.loc["face_permeability=harmonic", "effect_error"] == pytest.approx(0.5 * 2 ** 0.5)
    assert df.loc["baseline", "effect"] == 0.0
    assert "-14 +- 0.71" in identification.markdown(df.reset_index())


def test_summary_compares_each_reading_with_the_baseline_on_the_same_statements():
    statements = STATEMENTS + [{"id": "DP2", "statement": "dp", "measure": "pressure_drop", "value": 42,
                                "unit": "hPa/m", "tolerance": 0.5}]
    # harmonic 33 against the arithmetic baseline's 47 hPa/m on sweep s; 47.5 against 47 on sweep t
    tables = {"s": readings_table([3300.0, 4700.0], ["plug", "plug"]),
              "t": readings_table([4750.0, 4700.0], ["plug", "plug"])}
    baselines = {k: {"gas.face_permeability": "arithmetic", "gas.scheme": "unsplit"} for k in tables}
    compare = [{"statement": "DP", "sweep": "s"}, {"statement": "DP2", "sweep": "s"},
               {"statement": "DP", "sweep": "t"}, {"statement": "REG", "sweep": "s"}]
    df = identification.table(statements, tables, compare, READINGS, baselines)
    # DP (31.2-46.8 hPa/m) on s: 33 lies inside (miss 0), 47 misses by 0.2 -> closer, both within
    # (47 - 2 x 0.5 reaches 46.8); DP2 (41.5-42.5): 33 misses by 8.5, 47 by 4.5 -> farther;
    # DP on t: +0.5 +- 0.71 hPa/m is not resolved, counted neither way; REG: plug in both
    s = identification.summary(df).set_index("reading")
    assert s.loc["face_permeability=harmonic", ["within", "of", "baseline_within", "closer", "farther"]].tolist() \
        == [3, 4, 3, 1, 1]
    assert df.set_index(["id", "sweep", "reading"]).loc[("DP2", "s", "baseline"), "miss"] == pytest.approx(4.5 / 42)
    assert "| face_permeability=harmonic | 3 | 4 | 3 | 1 | 1 |" in identification.markdown(df)
    assert "| baseline | 3 | 4 | | | |" in identification.markdown(df)


def test_an_effect_without_an_error_is_resolved_only_for_an_argmax():
    friction = [0.1, 0.3]
    table = readings_table([[900.0, 700.0], [700.0, 900.0]], ["slug", "slug"], friction)
    table["pressure_drop_sem"] = float("nan")  # a mean whose error the estimator could not give
    baselines = {"f": {"gas.face_permeability": "arithmetic", "gas.scheme": "unsplit"}}
    compare = [{"statement": "PEAK", "sweep": "f"},
               {"statement": "DP", "sweep": "f", "where": {"particles.friction": 0.1}}]
    df = identification.table(STATEMENTS, {"f": table}, compare, READINGS, baselines)
    # the peak moves from 0.3 (baseline, 0.15 beyond 0.05-0.15) to 0.1 (inside): closer, resolved;
    # 9 against 7 hPa/m without errors: nearer 31.2-46.8, but the change is not resolved
    s = identification.summary(df).set_index("reading")
    assert s.loc["face_permeability=harmonic", ["closer", "farther"]].tolist() == [1, 0]

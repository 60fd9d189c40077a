"""Measures of the validation rule (workflow/scripts/validation.py) on synthetic curve tables with
known shapes: the verdicts must follow the data, not the statement."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "workflow" / "scripts"))
import validation  # noqa: E402
from _helpers import write_table  # noqa: E402

from analysis.curves import hyperbola  # noqa: E402


def curve(tmp_path, x, dp_hpa_m, key="gas.viscosity", rel_err=0.02):
    """A curve table as the curve rule writes it (pressure drop in Pa/m with its error)."""
    dp = 100.0 * np.asarray(dp_hpa_m, dtype=float)
    table = pd.DataFrame({key: x, "pressure_drop": dp, "pressure_drop_sem": rel_err * dp,
                          "regime": "plug"})
    path = tmp_path / f"curve{len(list(tmp_path.iterdir()))}.csv"
    write_table(table, path)
    return str(path)


def statement(path, measure, key="gas.viscosity", **spec):
    return {"id": "T", "paper": "V", "source": "test", "statement": "test", "measure": measure,
            "sweep": "s", "x": key, "files": {"curve": path}, "case_names": [], **spec}


ETA = np.array([4.5e-5, 5.5e-5, 6.73e-5, 7.5e-5, 8.5e-5])


def test_hyperbola_statement_within_for_a_hyperbola_and_not_for_a_parabola(tmp_path):
    spec = {"model": "hyperbola", "range": [0.0, 0.1], "unit": "1"}
    good = curve(tmp_path, ETA, hyperbola(ETA, 4e-4, 3.6e-5, 25.0))
    row = validation.compare(statement(good, "fit_deviation", **spec), {})
    assert row["within"] == "yes" and row["ours"] < 0.01
    # a parabola with its minimum inside the range: no decreasing hyperbola fits it within 10 %
    bad = curve(tmp_path, ETA, 30 + 4e10 * (ETA - 6.5e-5) ** 2)
    row = validation.compare(statement(bad, "fit_deviation", **spec), {})
    assert row["within"] == "no", row


def test_linear_statement_rejects_a_curved_mass_flow_dependence(tmp_path):
    mdot = np.array([1.0, 2.49, 5.0, 7.5, 9.95])
    spec = {"model": "linear", "range": [0.0, 0.1], "unit": "1"}
    line = curve(tmp_path, mdot, 4 + 2.4 * mdot, key="feed.mass_flow_kg_h")
    assert validation.compare(statement(line, "fit_deviation", key="feed.mass_flow_kg_h", **spec),
                              {})["within"] == "yes"
    square = curve(tmp_path, mdot, 1 + mdot ** 2, key="feed.mass_flow_kg_h")
    assert validation.compare(statement(square, "fit_deviation", key="feed.mass_flow_kg_h", **spec),
                              {})["within"] == "no"


@pytest.mark.parametrize("dp, expected, within", [
    ([50, 40, 33, 30, 28], "decreasing", "yes"),
    ([28, 30, 33, 40, 50], "decreasing", "no"),
    ([30, 30.3, 29.8, 30.1, 30], "decreasing", "no"),  # flat within 2 % errors
])
def test_trend_statement_follows_the_data(tmp_path, dp, expected, within):
    row = validation.compare(statement(curve(tmp_path, ETA, dp), "trend", expected=expected,
                                       unit="-"), {})
    assert row["within"] == within
    assert "slope" in row["note"]


def test_monotonic_statement_and_the_within_range(tmp_path):
    mu = np.array([0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0])
    spec = {"expected": "monotonic increasing", "unit": "-"}
    rising = curve(tmp_path, mu, [20, 24, 27, 30, 35, 45, 60], key="particles.friction")
    assert validation.compare(statement(rising, "monotonic", key="particles.friction", **spec),
                              {})["within"] == "yes"
    dip = curve(tmp_path, mu, [20, 24, 18, 30, 35, 45, 60], key="particles.friction")
    assert validation.compare(statement(dip, "monotonic", key="particles.friction", **spec),
                              {})["within"] == "no"
    # the dip lies outside `within`, so the remaining points are monotonic
    assert validation.compare(statement(dip, "monotonic", key="particles.friction",
                                        within=[0.3, 1.0], **spec), {})["within"] == "yes"


def test_reduced_run_warning_only_for_physical_overrides():
    table = pd.DataFrame([validation.compare({"id": "T", "paper": "H", "source": "s", "statement": "s",
                                              "measure": "trend", "value": 1, "tolerance": 1}, {})])
    assert "reduced run" not in validation.markdown(table, {"all_cases": {"output.snapshot_t_min": 7.0}})
    assert "reduced run" in validation.markdown(table, {"all_cases": {"tube.length": 0.1,
                                                                      "output.snapshots": False}})


def test_bulk_points_with_an_unresolved_dashpot_are_noted_not_judged_otherwise(tmp_path):
    v = np.array([0.15, 0.25, 0.5, 0.75, 1.0])
    table = pd.DataFrame({"gas.superficial_velocity": v, "pressure_drop": 100.0 * np.array([90, 70, 20, 12, 10.0]),
                          "pressure_drop_sem": 50.0, "regime": ["bulk", "bulk", "slug", "slug", "slug"],
                          "dashpot_resolved": [False, True, False, False, False]})
    path = tmp_path / "vs.csv"
    write_table(table, path)
    spec = {"regime": "bulk", "value": 0.3, "tolerance": 0.1, "unit": "m/s"}
    row = validation.compare(statement(str(path), "transition", key="gas.superficial_velocity", **spec), {})
    # one bulk point is unresolved (the slug points do not count: no packed bed); the verdict stands
    assert row["within"] == "yes" and row["ours"] == pytest.approx(0.375)
    assert "1 bulk point(s) in its data carry a time-step error" in row["note"]
    write_table(table.assign(dashpot_resolved=True), path)
    row = validation.compare(statement(str(path), "transition", key="gas.superficial_velocity", **spec), {})
    assert "time-step error" not in row["note"]
    summary = tmp_path / "bulk.json"
    summary.write_text('{"pressure_drop": 9000.0, "pressure_drop_sem": 90.0, "regime": "bulk", '
                       '"dashpot_resolved": false}')
    one = {"id": "T", "paper": "H", "source": "test", "statement": "test", "measure": "pressure_drop",
           "files": {"summaries": [str(summary)]}, "value": 90.0, "tolerance": 10.0, "unit": "hPa/m"}
    row = validation.compare(one, {})
    assert row["within"] == "yes" and "1 bulk point(s)" in row["note"]


def test_travel_speed_and_grain_velocity_are_separate_statements(tmp_path):
    # slugs travelling at 0.42 m/s whose grains move at 0.29 m/s (H §3 and §3.2)
    from analysis import detect
    from tests.analysis import synthetic as S

    slugs = [S.Slug(front=lambda t, k=k: 0.42 * (t - 0.75 * k), length=lambda t: np.full_like(t, 0.05),
                    speed=lambda t: np.full_like(t, 0.29)) for k in range(-2, 14)]
    table = detect(S.build(slugs, 10.0))
    write_table(table, tmp_path / "slugs.csv")
    (tmp_path / "summary.json").write_text('{"t_start": 0.0}')
    files = {"slugs": str(tmp_path / "slugs.csv"), "summary": str(tmp_path / "summary.json")}
    base = {"id": "T", "paper": "H", "source": "test", "statement": "test", "measure": "slug_stat",
            "position": "analysis", "unit": "m/s", "files": files, "case_names": []}
    ctx = {"position": 0.26}
    travel = validation.compare({**base, "quantity": "slug_velocity", "value": 0.42,
                                 "tolerance": 0.04}, ctx)
    assert travel["within"] == "yes" and travel["ours"] == pytest.approx(0.42, rel=2e-3)
    grains = validation.compare({**base, "quantity": "max_velocity", "value": 0.42,
                                 "tolerance": 0.04}, ctx)
    assert grains["within"] == "no" and grains["ours"] == pytest.approx(0.29, rel=1e-9)
    assert grains["note"].startswith("time-weighted 0.29")


def test_every_slug_statement_names_a_measured_quantity():
    import yaml

    from analysis.statistics import QUANTITIES

    statements = yaml.safe_load((ROOT / "resources" / "paper_statements.yaml").read_text())
    ids = {st["id"] for st in statements}
    assert {"H-travel-mid", "V-travel-mid", "V-temperature"} <= ids
    for st in statements:
        if st["measure"] == "slug_stat":
            assert st["quantity"] in QUANTITIES, st["id"]
        if "length" in st.get("quantity", ""):
            assert st["quantity"] == "length_total", st["id"]  # the papers' reading, with the ends


def test_blocked_points_are_left_out_of_a_curve_and_noted(tmp_path):
    v = np.array([0.15, 0.25, 0.5, 0.75, 1.0])
    table = pd.DataFrame({"gas.superficial_velocity": v,
                          "pressure_drop": 100.0 * np.array([5.0, 70, 20, 12, 10.0]),
                          "pressure_drop_sem": 50.0,
                          "regime": ["blocked", "bulk", "slug", "slug", "slug"]})
    path = tmp_path / "vs.csv"
    write_table(table, path)
    spec = {"regime": "bulk", "value": 0.3, "tolerance": 0.1, "unit": "m/s"}
    row = validation.compare(statement(str(path), "transition", key="gas.superficial_velocity", **spec), {})
    # the blocked 0.15 m/s point is not the curve's first point: the transition lies at 0.375
    assert row["ours"] == pytest.approx(0.375) and "1 blocked point(s) left out" in row["note"]
    # with it, the low blocked pressure drop would make the curve rise first; left out it falls
    row = validation.compare(statement(str(path), "trend", key="gas.superficial_velocity",
                                       expected="decreasing", unit="-"), {})
    assert row["ours"] == "decreasing" and row["within"] == "yes"


def test_verdict_changes_lists_changed_added_and_dropped_statements(tmp_path):
    import validation_changes

    old = pd.DataFrame({"id": ["A", "B", "C"], "ours": [1.0, 2.0, "plug"], "within": ["yes", "no", "no"]})
    new = pd.DataFrame({"id": ["A", "B", "D"], "ours": [1.1, 2.5, 0.4], "within": ["yes", "yes", "no"]})
    rows = validation_changes.verdict_changes(old, new).set_index("id")
    assert sorted(rows.index) == ["B", "C", "D"]  # A kept its verdict
    assert (rows.loc["B", "within_old"], rows.loc["B", "within_new"]) == ("no", "yes")
    assert rows.loc["C", "within_new"] == "—" and rows.loc["D", "within_old"] == "—"
    old.to_csv(tmp_path / "old.csv", index=False)
    new.to_csv(tmp_path / "new.csv", index=False)
    text = validation_changes.markdown(pd.read_csv(tmp_path / "old.csv"), pd.read_csv(tmp_path / "new.csv"))
    assert text.startswith("old: 1 of 3 within; new: 2 of 3 within; 3 verdicts changed")
    assert "| B | 2 | 2.5 | no | yes |" in text and "| C | plug | — | no | — |" in text


def _row(sid, role, measure, ours, err, kind="sem", **spec):
    """A validation row as _compare writes it, for the count and the re-judging."""
    st = {"id": sid, "paper": "H", "source": "s", "statement": "s", "measure": measure, **spec}
    if role == "training":
        st["role"] = role
    within = validation.judge(st, ours, err, kind)
    return st, {"id": sid, "role": validation.statement_role(st), "kind": validation.statement_kind(st),
                "paper": "H", "source": "s", "statement": "s", "paper_value": "", "unit": "1",
                "ratio": float("nan"), "ours": ours, "ours_error": err, "error_kind": kind, "within": within, "note": ""}


def test_the_headline_counts_test_statements_apart_from_training_and_by_kind():
    rows = [_row("A", "training", "pressure_drop", 10.0, 0.1, value=10, tolerance=0.5)[1],
            _row("B", "test", "pressure_drop", 12.0, 0.1, value=10, tolerance=0.5)[1],
            _row("C", "test", "n_particles", 3190.0, 10.0, value=3200, tolerance=50)[1],
            _row("D", "test", "trend", "increasing", float("nan"), "category", expected="increasing")[1],
            _row("E", "test", "regime", "slug", float("nan"), "category", expected="plug")[1]]
    text = validation.markdown(pd.DataFrame(rows), {})
    assert ("**Test statements (predictions): 2 of 4 within (quantitative 1 of 2, trend 1 of 1, "
            "regime 0 of 1).**") in text
    assert "Training statements (the identification may choose a reading on them): 1 of 1 within" in text


def test_rejudging_applies_new_tolerances_to_the_measured_values():
    old_st, old_row = _row("DP", "training", "pressure_drop", 8.3, 0.3, value=10, tolerance=2)
    assert old_row["within"] == "yes"  # 8.3 + 2 * 0.3 = 8.9 reaches 10 - 2
    new_st = {**old_st, "tolerance": 0.5}
    missing = {"id": "NEW", "paper": "V", "source": "s", "statement": "s", "measure": "pressure_drop",
               "value": 1, "tolerance": 0.1}
    table = validation.rejudge(pd.DataFrame([old_row]), [new_st, missing]).set_index("id")
    assert table.loc["DP", "within"] == "no"  # 8.9 < 9.5
    assert table.loc["DP", "role"] == "training"
    assert table.loc["NEW", "within"] == "not available"


def test_every_statement_has_a_known_role_and_kind_and_trainings_are_the_identifications():
    import yaml

    statements = yaml.safe_load((ROOT / "resources" / "paper_statements.yaml").read_text())
    assert {validation.statement_role(st) for st in statements} == {"training", "test"}
    assert {validation.statement_kind(st) for st in statements} == set(validation.KINDS)
    training = {st["id"] for st in statements if validation.statement_role(st) == "training"}
    compared = {item["statement"] for item in
                yaml.safe_load((ROOT / "config" / "identification.yaml").read_text())
                ["identification"]["compare"]}
    assert compared == training

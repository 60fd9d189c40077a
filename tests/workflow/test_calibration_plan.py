"""The calibration stage's cases (workflow/scripts/calibration_plan.py), without Snakemake: the design
named by its values, the overrides of each case, warm starts from the design's centre, the design
table, and the errors for keys, bounds and files that do not work."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "workflow" / "scripts"))
from calibration_plan import CalibrationPlan, case_file, design_table  # noqa: E402
from config_check import ConfigError  # noqa: E402

EXAMPLE = str(ROOT / "resources/measurements/vertical_series_B.csv")
V = str(ROOT / "config/cases/vertical.yaml")


def section(**extra):
    return {"name": "t", "measurements": EXAMPLE, "base": {"vertical": V}, "tube_length": 0.525,
            "fit": {"gas.viscosity": [4.5e-5, 8.5e-5], "particles.friction": [0.2, 0.8]},
            "same_as": {"wall.friction": "particles.friction"},
            "overrides": {"run.until_steady": True}, **extra}


def test_first_design_is_named_by_its_values_and_starts_from_its_centre():
    plan = CalibrationPlan(section())
    assert len(plan.first) == 9 and plan.start == "gas.viscosity~6.5e-05_particles.friction~0.5"
    assert "gas.viscosity~4.5e-05_particles.friction~0.8" in plan.first
    assert "initial_state" not in plan.simulate_inputs("B", plan.start)
    corner = "gas.viscosity~8.5e-05_particles.friction~0.2"
    assert plan.simulate_inputs("B", corner)["initial_state"] == case_file("results/calibration/t", "B", plan.start)


def test_a_case_is_the_operating_point_with_the_values_its_name_carries():
    plan = CalibrationPlan(section())
    case = plan.case("B", "gas.viscosity~5.123e-05_particles.friction~0.33")
    assert case["gas.viscosity"] == 5.123e-05
    assert case["particles.friction"] == case["wall.friction"] == 0.33  # same_as
    # the operating point: 2.2 l/min in the 7 mm tube, the measured feed, the simulated tube length
    assert case["gas.superficial_velocity"] == pytest.approx(2.2e-3 / 60 / (math.pi * 0.0035 ** 2))
    assert case["feed.mass_flow_kg_h"] == 2.49 and case["tube.length"] == 0.525
    assert case["tube.inclination_deg"] == 90.0 and case["run.until_steady"] is True
    assert plan.position("B") == pytest.approx(0.2625)  # mid-tube, where the rig's camera is


def test_a_point_at_another_mass_flow_feeds_at_the_base_cases_packing():
    # series A and C: 1.7 and 2.88 kg/h against the base case's 2.49 kg/h at 0.04 m/s; 2.88 kg/h
    # cannot be packed at 0.04 m/s (the feed's layers would be 0.91 d apart)
    from engine import Case, Simulation

    plan = CalibrationPlan(section(), {"measurements": str(ROOT / "resources/measurements/vertical_series_A_C.csv")})
    assert "feed.entry_velocity" not in CalibrationPlan(section()).operating("B")  # the base's own mass flow
    point = "gas.viscosity~6.5e-05_particles.friction~0.5"
    for label, mass_flow in (("A", 1.7), ("C", 2.88)):
        case = plan.case(label, point)
        assert case["feed.mass_flow_kg_h"] == mass_flow
        assert case["feed.entry_velocity"] == pytest.approx(0.04 * mass_flow / 2.49)
        feed = Simulation(case).feed
        assert feed.spacing == pytest.approx(Simulation(Case.from_yaml(V)).feed.spacing)
    # an overridden base entry velocity is the one scaled
    faster = CalibrationPlan(section(overrides={"feed.entry_velocity": 0.05}),
                             {"measurements": str(ROOT / "resources/measurements/vertical_series_A_C.csv")})
    assert faster.case("C", point)["feed.entry_velocity"] == pytest.approx(0.05 * 2.88 / 2.49)


def test_rig_tube_length_is_simulated_without_tube_length():
    plan = CalibrationPlan(section(tube_length=None))
    assert plan.operating("B")["tube.length"] == 1.01


def test_names_round_to_four_digits_inside_the_bounds():
    plan = CalibrationPlan(section())
    assert plan.point_name([6.123456e-5, 0.8000001]) == "gas.viscosity~6.123e-05_particles.friction~0.8"
    with pytest.raises(ValueError, match="outside"):
        plan.parameters("gas.viscosity~9e-05_particles.friction~0.5")
    with pytest.raises(ValueError, match="not key~value"):
        plan.parameters("gas.viscosity~6e-05_particles.restitution~0.5")


@pytest.mark.parametrize("change, words", [
    ({"fit": {"gas.viscosty": [4.5e-5, 8.5e-5]}}, "unknown case key 'gas.viscosty' (did you mean 'gas.viscosity'?)"),
    ({"fit": {"gas.viscosity": [8.5e-5, 4.5e-5], "particles.friction": [0.2, 0.8]}}, "calibration.fit: bounds need"),
    ({"same_as": {"wall.friction": "particles.restitution"}}, "same_as.wall.friction: 'particles.restitution' is not a fitted key"),
    ({"base": {"horizontal": V}}, "no base case for the vertical points"),
    ({"measurements": "missing.csv"}, "calibration.measurements: missing.csv: no such measurement file"),
    ({"overrides": {"gas.superficial_velocity": 1.0}}, "overrides.gas.superficial_velocity: set by each operating point"),
    ({"overrides": {"wall.friction": 0.3}}, "overrides.wall.friction: set by the fit"),
    ({"overrides": {"run.duration": -1.0}}, "run.duration"),
])
def test_bad_sections_are_refused_naming_the_entry(change, words):
    with pytest.raises(ConfigError) as err:
        CalibrationPlan(section(**change))
    assert words in str(err.value)


def test_design_table_reads_values_from_names_and_quantities_from_summaries():
    plan = CalibrationPlan(section())
    summaries = {f"results/calibration/t/summaries/B/{plan.start}.json":
                 {"pressure_drop": 3900.0, "pressure_drop_sem": 60.0, "slug_velocity": None,
                  "slug_length_total": 0.03, "slug_length_total_sem": 0.002, "regime": "plug",
                  "cpu_time_s": 412.5}}
    row = design_table(summaries, plan).iloc[0]
    assert row["label"] == "B" and row["gas.viscosity"] == 6.5e-05 and row["pressure_drop"] == 3900.0
    assert math.isnan(row["slug_velocity"]) and math.isnan(row["slug_velocity_sem"])  # no plugs passed
    assert row["cpu_time_s"] == 412.5
    assert row["pressure_drop_sem_converged"] and not row["slug_velocity_sem_converged"]


def test_a_value_whose_error_did_not_converge_keeps_the_estimate_and_says_so():
    # a case capped before its window covered the correlation times the estimator asks: the
    # summary's error is None, its estimate over the short window is there; the value must stay
    plan = CalibrationPlan(section())
    summaries = {f"results/calibration/t/summaries/B/{plan.start}.json":
                 {"pressure_drop": 4568.0, "pressure_drop_sem": None, "pressure_drop_sem_estimate": 100.4,
                  "slug_velocity": 0.198, "slug_velocity_sem": 0.0038, "regime": "plug"}}
    row = design_table(summaries, plan).iloc[0]
    assert row["pressure_drop"] == 4568.0 and row["pressure_drop_sem"] == 100.4
    assert not row["pressure_drop_sem_converged"] and row["slug_velocity_sem_converged"]


def test_cost_sums_the_known_cpu_seconds_and_counts_the_unknown():
    import calibration as script  # workflow/scripts/calibration.py

    design = pd.DataFrame({"cpu_time_s": [400.0, math.nan, 250.5]})
    c = script.cost(design)
    assert c == {"cases": 3, "cpu_time_s": 650.5, "cpu_time_unknown": 1}
    assert script.cost_line(c) == "3 cases, 650 CPU s (1 of them without a CPU time)"


def test_prediction_cases_bracket_the_fit_and_carry_its_covariance():
    import calibration as script  # workflow/scripts/calibration.py

    plan = CalibrationPlan(section(), {"measurements": EXAMPLE})
    assert plan.folder == "results/calibration/t/prediction"
    fitted = {"parameters": {"gas.viscosity": {"value": 6.0e-5, "std": 1.0e-5},
                             "particles.friction": {"value": 0.75, "std": 0.1}},
              "covariance": [[1.0e-10, 2.0e-7], [2.0e-7, 0.01]]}
    names = plan.prediction_points(fitted)
    assert names[0] == "gas.viscosity~6e-05_particles.friction~0.75"
    assert names[3] == "gas.viscosity~6e-05_particles.friction~0.8"  # +1 s.d. clipped at the bound
    assert plan.simulate_inputs("B", names[1], start=names[0])["initial_state"].endswith(f"prediction/cases/B/{names[0]}.nc")
    # summaries of a model linear in the parameters: dp = 4000 + 1e8 (eta - 6e-5) + 2000 (mu - 0.75) Pa/m
    summaries = {}
    for name in names:
        p = plan.parameters(name)
        dp = 4000 + 1e8 * (p["gas.viscosity"] - 6e-5) + 2000 * (p["particles.friction"] - 0.75)
        summaries[f"x/B/{name}.json"] = {"pressure_drop": dp, "pressure_drop_sem": 30.0, "slug_velocity": 0.2,
                                         "slug_velocity_sem": 0.01, "slug_length_total": 0.03,
                                         "slug_length_total_sem": 0.003}
    table = script.prediction_table(plan, design_table(summaries, plan), fitted).set_index("quantity")
    g = np.array([1e8, 2000.0])  # the gradient, recovered from the unequal (clipped) steps
    expected = math.sqrt(g @ np.array(fitted["covariance"]) @ g + 30.0 ** 2)
    assert table.loc["pressure_drop", "predicted"] == pytest.approx(4000.0)
    assert table.loc["pressure_drop", "predicted_std"] == pytest.approx(expected, rel=1e-6)
    # a quantity that does not change with the parameters keeps the case's own error only
    assert table.loc["plug_velocity", "predicted_std"] == pytest.approx(0.01)
    assert table["own_error_known"].all()
    # the case at the fitted values without an error of its own (too short a window, no estimate):
    # the error bar is the fit's part, and the table says so
    summaries[f"x/B/{names[0]}.json"]["pressure_drop_sem"] = None
    table = script.prediction_table(plan, design_table(summaries, plan), fitted)
    row = table.set_index("quantity").loc["pressure_drop"]
    assert not row["own_error_known"] and row["predicted_std"] == pytest.approx(math.sqrt(g @ np.array(fitted["covariance"]) @ g))
    [line] = [x for x in script.quantity_rows(table, "predicted") if "pressure_drop" in x]
    assert "the case's own error unknown" in line


def test_job_time_request_follows_the_workflow_cost_model():
    plan = CalibrationPlan(section(overrides={"run.duration": 20.0}))
    # 20 s simulated of the paper's tube at its feed: 10 + 2 x 20 min
    assert plan.runtime_minutes("B", plan.start) == 50

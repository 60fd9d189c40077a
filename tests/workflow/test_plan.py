"""The workflow's plan (workflow/scripts/plan.py) on small configs, without Snakemake: what each
case records for its consumers, identical cases run once, warm starts, file names, and the errors
for sweeps, keys and kinds that do not exist."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "workflow" / "scripts"))
import plan as paths  # noqa: E402
from plan import Plan, PlanError  # noqa: E402

H = str(ROOT / "config/cases/horizontal.yaml")
V = str(ROOT / "config/cases/vertical.yaml")


def config(sweeps, figures=None, **extra):
    return {"sweeps": sweeps, "figures": figures or {},
            "validation": {"statements": "s.yaml", "experiment": "exp.csv"}, **extra}


def single(**overrides):
    return {"base": H, "overrides": {"run.duration": 4.0, **overrides}}


def curve(values, **spec):
    return {"base": H, "parameters": {"gas.superficial_velocity": values}, **spec}


# ---- what each case records ----------------------------------------------------------------------

def test_a_curve_point_only_needs_a_steady_mean():
    plan = Plan(config({"h_vs": curve([1.5, 2.0])}))
    for key in plan.all_points():
        assert plan.needs[key] == {"steady"}
        assert plan.overrides[key]["run.until_steady"] is True
        assert plan.overrides[key]["output.snapshots"] is False


def test_a_snapshot_figure_makes_its_case_record_snapshots_for_the_whole_run():
    plan = Plan(config({"h_default": single(), "h_vs": curve([1.5, 2.0])},
                       {"H02": {"kind": "grains_3d", "case": {"sweep": "h_default"}}}))
    key = ("h_default", "base")
    assert plan.needs[key] == {"steady", "series", "snapshots"}
    assert plan.overrides[key]["output.snapshots"] is True
    assert plan.overrides[key]["run.until_steady"] is False
    assert plan.cases[key]["output.snapshots"] is True
    assert plan.overrides[("h_vs", "gas.superficial_velocity~2")]["output.snapshots"] is False


def test_a_statement_on_a_curve_point_makes_it_run_its_full_duration():
    statements = [{"id": "S1", "measure": "slug_stat", "quantity": "length",
                   "case": {"sweep": "h_vs", "point": {"gas.superficial_velocity": 2.0}}}]
    plan = Plan(config({"h_vs": curve([1.5, 2.0])}), statements)
    assert plan.overrides[("h_vs", "gas.superficial_velocity~2")]["run.until_steady"] is False
    assert plan.overrides[("h_vs", "gas.superficial_velocity~1.5")]["run.until_steady"] is True
    files = plan.validation_statements()[0]["files"]
    assert files == {"slugs": "results/slugs/h_vs/gas.superficial_velocity~2.csv",
                     "summary": "results/summaries/h_vs/gas.superficial_velocity~2.json"}


def test_a_derived_key_set_by_a_sweep_wins_over_what_the_consumers_need():
    plan = Plan(config({"h_vs": curve([1.5], overrides={"run.until_steady": False})}))
    assert plan.overrides[("h_vs", "gas.superficial_velocity~1.5")]["run.until_steady"] is False


# ---- identical cases run once --------------------------------------------------------------------

def test_a_curve_point_equal_to_a_single_case_reads_its_file_and_adds_its_needs():
    sweeps = {"h_vs": curve([1.0, 2.0], overrides={"run.duration": 4.0}), "h_default": single()}
    figures = {"H02": {"kind": "grains_3d", "case": {"sweep": "h_default"}}}
    plan = Plan(config(sweeps, figures))
    same = ("h_vs", "gas.superficial_velocity~1")  # 1.0 m/s is the base case's own value
    assert plan.canonical[same] == ("h_default", "base")  # named after the single-case sweep
    assert plan.case_nc(*same) == "results/cases/h_default/base.nc"
    assert plan.cases[same] == plan.cases[("h_default", "base")]
    assert plan.overrides[same]["output.snapshots"] is True  # the union of both consumers' needs
    other = ("h_vs", "gas.superficial_velocity~2")
    assert plan.canonical[other] == other
    assert plan.case_nc(*other) == "results/cases/h_vs/gas.superficial_velocity~2.nc"


def test_cases_that_differ_in_a_key_or_their_start_are_not_merged():
    sweeps = {"h_default": single(), "h_short": single(**{"run.duration": 3.0}),
              "h_warm": {"base": H, "warm_start": {"sweep": "h_short"},
                         "overrides": {"run.duration": 4.0}},
              "v_default": {"base": V, "overrides": {"run.duration": 4.0}}}
    plan = Plan(config(sweeps))
    assert len(set(plan.canonical.values())) == 4
    assert plan.canonical[("h_warm", "base")] == ("h_warm", "base")  # same keys as h_default, warm


def test_a_one_at_a_time_design_varies_each_parameter_alone_from_the_first_values():
    spec = {"base": H, "design": "one_at_a_time",
            "parameters": {"gas.scheme": ["unsplit", {"gas.scheme": "split", "gas.theta": 0.5}],
                           "particles.tangential_damping": [0.02, 0.005, 0.01]}}
    points = Plan(config({"id_h": spec})).points["id_h"]
    # 1 baseline + (2 - 1) + (3 - 1) points; a full factorial would have 6
    assert len(points) == 4
    assert {(p["gas.scheme"], p["particles.tangential_damping"]) for p in points.values()} == {
        ("unsplit", 0.02), ("split", 0.02), ("unsplit", 0.005), ("unsplit", 0.01)}
    split = next(p for p in points.values() if p["gas.scheme"] == "split")
    assert split["gas.theta"] == 0.5


def test_crossed_parameters_take_every_value_under_each_screened_reading():
    spec = {"base": H, "design": "one_at_a_time", "crossed": ["gas.superficial_velocity"],
            "parameters": {"gas.superficial_velocity": [0.75, 4.0],
                           "gas.face_permeability": ["arithmetic", "harmonic"],
                           "particles.stiffness": [2000.0, 8000.0]}}
    points = Plan(config({"id_v_vs": spec})).points["id_v_vs"]
    combos = {(p["gas.superficial_velocity"], p["gas.face_permeability"], p["particles.stiffness"])
              for p in points.values()}
    assert combos == {(v, face, k) for v in (0.75, 4.0) for face, k in
                      [("arithmetic", 2000.0), ("harmonic", 2000.0), ("arithmetic", 8000.0)]}


def test_an_unknown_design_is_refused_naming_the_sweep():
    spec = {**curve([1.0, 2.0]), "design": "latin"}
    with pytest.raises(Exception, match="sweep 'h_vs'.*design 'latin'"):
        Plan(config({"h_vs": spec}))


# ---- warm starts ---------------------------------------------------------------------------------

def test_warm_start_names_the_source_case_of_every_other_point():
    sweeps = {"h_default": single(),
              "h_vs": curve([1.0, 2.0], warm_start={"sweep": "h_default"})}
    plan = Plan(config(sweeps))
    assert plan.warm_source == {("h_vs", "gas.superficial_velocity~1"): ("h_default", "base"),
                                ("h_vs", "gas.superficial_velocity~2"): ("h_default", "base")}
    assert plan.simulate_inputs("h_vs", "gas.superficial_velocity~2") == {
        "base": H, "initial_state": "results/cases/h_default/base.nc"}
    assert plan.simulate_inputs("h_default", "base") == {"base": H}


def test_a_sweep_warm_started_from_its_own_point_runs_that_point_from_an_empty_tube():
    sweeps = {"h_vs": curve([1.0, 2.0], warm_start={"sweep": "h_vs",
                                                     "point": {"gas.superficial_velocity": 1.0}})}
    plan = Plan(config(sweeps))
    assert plan.warm_source == {("h_vs", "gas.superficial_velocity~2"): ("h_vs", "gas.superficial_velocity~1")}


def test_warm_start_from_next_chains_points_towards_the_last_value():
    sweeps = {"h_default": single(),
              "h_vs": curve([0.5, 1.5, 2.0], warm_start={"sweep": "h_default"},
                            warm_start_from_next={"gas.superficial_velocity": [0.5, 1.5]})}
    plan = Plan(config(sweeps))
    point = "gas.superficial_velocity~{}".format
    assert plan.warm_source[("h_vs", point("0.5"))] == ("h_vs", point("1.5"))
    assert plan.warm_source[("h_vs", point("1.5"))] == ("h_vs", point("2"))
    assert plan.warm_source[("h_vs", point("2"))] == ("h_default", "base")


def test_empty_start_runs_the_named_points_from_an_empty_tube_despite_warm_start():
    sweeps = {"h_default": single(),
              "h_vs": curve([0.5, 1.0, 2.0], warm_start={"sweep": "h_default"},
                            empty_start={"gas.superficial_velocity": [0.5, 2.0]})}
    plan = Plan(config(sweeps))
    assert plan.warm_source == {("h_vs", "gas.superficial_velocity~1"): ("h_default", "base")}
    assert plan.simulate_inputs("h_vs", "gas.superficial_velocity~0.5") == {"base": H}


@pytest.mark.parametrize("empty, message", [
    ({"gas.superficial_velocity": [3.0]}, r"empty_start: gas.superficial_velocity = 3.0 must be one of its values"),
    ({"gas.viscosity": [1e-5]}, r"empty_start: 'gas.viscosity' is not one of its parameters"),
    ({"gas.superficial_velocty": [1.0]}, r"empty_start: unknown case key 'gas.superficial_velocty'"),
])
def test_empty_start_with_an_unknown_parameter_or_value_is_refused(empty, message):
    sweeps = {"h_default": single(), "h_vs": curve([1.0, 2.0], warm_start={"sweep": "h_default"},
                                                   empty_start=empty)}
    with pytest.raises(PlanError, match=message):
        Plan(config(sweeps))


def test_a_point_chained_by_warm_start_from_next_starts_from_its_neighbour_even_if_started_empty():
    sweeps = {"h_default": single(),
              "h_vs": curve([1.5, 2.0], warm_start={"sweep": "h_default"},
                            warm_start_from_next={"gas.superficial_velocity": [1.5]},
                            empty_start={"gas.superficial_velocity": [1.5, 2.0]})}
    plan = Plan(config(sweeps))
    assert plan.warm_source == {("h_vs", "gas.superficial_velocity~1.5"): ("h_vs", "gas.superficial_velocity~2")}


def test_warm_start_from_a_warm_started_sweep_is_refused():
    sweeps = {"h_default": single(), "a": curve([2.0], warm_start={"sweep": "h_default"}),
              "b": curve([3.0], warm_start={"sweep": "a"})}
    with pytest.raises(PlanError, match="sweep 'b' warm-starts from sweep 'a', which is warm-started"):
        Plan(config(sweeps))


def test_warm_start_from_next_without_a_next_value_is_refused():
    sweeps = {"h_vs": curve([1.5, 2.0], warm_start_from_next={"gas.superficial_velocity": [2.0]})}
    with pytest.raises(PlanError, match=r"warm_start_from_next: gas.superficial_velocity = 2.0 must be"):
        Plan(config(sweeps))


# ---- scheduling: expected costs and priorities ---------------------------------------------------

def cost_file(tmp_path, rows, header="rule,job,wall_s,max_rss_mb,cpu_s"):
    path = tmp_path / "timings.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def chained_sweeps():
    """h_default; h_vs warm-started from it: 0.5 from 1.5 from 2.0 from h_default (a chain of
    three levels), and 3.0 from h_default."""
    return {"h_default": single(),
            "h_vs": curve([0.5, 1.5, 2.0, 3.0], warm_start={"sweep": "h_default"},
                          warm_start_from_next={"gas.superficial_velocity": [0.5, 1.5]})}


def test_a_case_listed_in_the_cost_file_is_expected_to_take_its_cpu_seconds(tmp_path):
    path = cost_file(tmp_path, ["simulate,h_default/base,130.0,270.0,120.5",
                                "detect,h_default/base,1.0,150.0,0.5",   # another rule: ignored
                                "simulate,(total),130.0,270.0,120.5"])
    sweeps = {"h_default": single(), "h_vs": curve([1.0, 2.0], overrides={"run.duration": 4.0})}
    plan = Plan(config(sweeps, scheduling={"job_costs": path.name}), root=tmp_path)
    assert plan.job_costs == {"h_default/base": 120.5}
    assert plan.expected_cpu_seconds("h_default", "base") == 120.5
    # the same case as h_default (1 m/s is the base case's value): its canonical case's cost
    assert plan.expected_cpu_seconds("h_vs", "gas.superficial_velocity~1") == 120.5


def test_a_resumed_case_is_expected_to_take_the_cpu_seconds_of_its_whole_run(tmp_path):
    # cpu_s is the job's last part (a run resumed from its checkpoint); case_cpu_s the whole run's
    path = cost_file(tmp_path, ["simulate,h_default/base,130.0,270.0,120.5,",
                                "simulate,h_vs/gas.superficial_velocity~2,330.0,270.0,300.0,2400.0",
                                "simulate,h_vs/gas.superficial_velocity~3,90.0,270.0,80.0,nan"],
                     header="rule,job,wall_s,max_rss_mb,cpu_s,case_cpu_s")
    sweeps = {"h_default": single(), "h_vs": curve([2.0, 3.0])}
    plan = Plan(config(sweeps, scheduling={"job_costs": str(path)}))
    assert plan.expected_cpu_seconds("h_vs", "gas.superficial_velocity~2") == 2400.0
    # unknown whole-run CPU (empty, or NaN): the job's own
    assert plan.expected_cpu_seconds("h_default", "base") == 120.5
    assert plan.expected_cpu_seconds("h_vs", "gas.superficial_velocity~3") == 80.0


def test_a_case_not_in_the_cost_file_is_expected_to_take_the_models_time(tmp_path):
    path = cost_file(tmp_path, ["simulate,h_default/base,130.0,270.0,120.5"])
    # 4 s on a tube twice the papers' (1.05 m) at twice their mass flow: 4 x 3000 grains,
    # 1 min per simulated second each -> 4 x 4 = 16 min
    sweeps = {"h_default": single(),
              "h_long": single(**{"tube.length": 1.05, "feed.mass_flow_kg_h": 4.98})}
    for scheduling in ({"job_costs": str(path)}, {"job_costs": None}, None):
        extra = {} if scheduling is None else {"scheduling": scheduling}
        plan = Plan(config(sweeps, **extra))
        assert plan.expected_cpu_seconds("h_long", "base") == pytest.approx(960.0)
        assert plan.runtime_minutes("h_long", "base") == 42            # 10 + 2 x 16: the same model
        assert plan.runtime_minutes("h_long", "base", attempt=2) == 74
    assert plan.expected_cpu_seconds("h_default", "base") == pytest.approx(240.0)  # no cost file


def test_a_warm_start_source_comes_before_the_cases_it_starts_by_its_own_cost(tmp_path):
    point = "gas.superficial_velocity~{}".format
    costs = {("h_default", "base"): 100.0, ("h_vs", point("0.5")): 40.0,
             ("h_vs", point("1.5")): 30.0, ("h_vs", point("2")): 20.0, ("h_vs", point("3")): 80.0}
    path = cost_file(tmp_path, [f"simulate,{s}/{p},1.0,1.0,{c}" for (s, p), c in costs.items()])
    plan = Plan(config(chained_sweeps(), scheduling={"job_costs": str(path)}))
    # below h_default the critical paths 2.0 -> 1.5 -> 0.5 (20 + 30 + 40) and 3.0 alone (80)
    assert plan.priority("h_vs", point("0.5")) == 40
    assert plan.priority("h_vs", point("1.5")) == 70
    assert plan.priority("h_vs", point("2")) == 90
    assert plan.priority("h_vs", point("3")) == 80
    assert plan.priority("h_default", "base") == 190
    started = [k for k, source in plan.warm_source.items() if source == ("h_default", "base")]
    assert sorted(started) == [("h_vs", point("2")), ("h_vs", point("3"))]
    assert all(plan.priority("h_default", "base") - plan.priority(*k) >= 100 for k in started)


def test_identical_points_share_the_priority_of_their_case(tmp_path):
    path = cost_file(tmp_path, ["simulate,h_default/base,1.0,1.0,50",
                                "simulate,h_vs/gas.superficial_velocity~2,1.0,1.0,70"])
    sweeps = {"h_default": single(), "h_vs": curve([1.0, 2.0], overrides={"run.duration": 4.0})}
    plan = Plan(config(sweeps, scheduling={"job_costs": str(path)}))
    assert plan.priority("h_vs", "gas.superficial_velocity~1") == 50  # h_default's case
    assert plan.priority("h_default", "base") == 50
    assert plan.priority("h_vs", "gas.superficial_velocity~2") == 70


@pytest.mark.parametrize("rows, header, message", [
    (None, None, r"scheduling.job_costs: .*nope.csv: cannot read it"),
    (["simulate,h_default/base,1.0"], "rule,job,wall_s",
     r"scheduling.job_costs: .*timings.csv: no column cpu_s"),
    (["h_default/base,1.0"], "name,cpu_s", r"scheduling.job_costs: .*timings.csv: no column rule, job"),
    (["simulate,h_default/base,slow"], "rule,job,cpu_s",
     r"scheduling.job_costs: .*timings.csv: job h_default/base: cpu_s 'slow' is not a number"),
    (["simulate,h_default/base,1.0,slow"], "rule,job,cpu_s,case_cpu_s",
     r"scheduling.job_costs: .*timings.csv: job h_default/base: case_cpu_s 'slow' is not a number"),
])
def test_a_cost_file_that_cannot_be_read_is_refused_naming_the_key_and_path(tmp_path, rows, header,
                                                                           message):
    path = tmp_path / "nope.csv" if rows is None else cost_file(tmp_path, rows, header)
    with pytest.raises(PlanError, match=message):
        Plan(config({"h_default": single()}, scheduling={"job_costs": str(path)}))


def test_the_paper_configuration_reads_the_paper_runs_costs_and_ci_the_models():
    import yaml

    paper = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    costs = paths.read_job_costs(paper["scheduling"]["job_costs"], ROOT)
    assert {"h_default/base", "v_default/base"} <= set(costs) and "(total)" not in costs
    assert all(cost > 0 for cost in costs.values())
    # the CI cases bear some of the paper's names with other parameters: the model for all
    ci = yaml.safe_load((ROOT / "config/ci.yaml").read_text())
    assert ci["scheduling"] == {"job_costs": None}


# ---- errors --------------------------------------------------------------------------------------

@pytest.mark.parametrize("figure, message", [
    ({"kind": "grains_3d", "case": {"sweep": "nope"}},
     r"figure H02 refers to sweep 'nope', which is not declared \(sweeps: \['h_vs'\]\)"),
    ({"kind": "curve", "sweep": "nope", "x": "gas.superficial_velocity"},
     "figure H02 draws sweep 'nope', which is not declared"),
    ({"kind": "grains_3d", "case": {"sweep": "h_vs"}}, "sweep 'h_vs' has 2 points"),
    ({"kind": "grains_3d", "case": {"sweep": "h_vs", "point": {"gas.superficial_velocity": 9.0}}},
     r"has 0 points matching \{'gas.superficial_velocity': 9.0\}"),
    ({"kind": "pie_chart", "case": {"sweep": "h_vs"}}, "figure H02: unknown kind 'pie_chart'"),
    ({"kind": "curve", "case": {"sweep": "h_vs"}}, "kind curve draws `sweep`"),
])
def test_a_figure_that_cannot_be_drawn_is_refused(figure, message):
    with pytest.raises(PlanError, match=message):
        Plan(config({"h_vs": curve([1.5, 2.0])}, {"H02": figure}))


def test_an_unknown_case_key_is_refused_naming_the_sweep_and_entry():
    sweeps = {"h_vs": curve([1.5], overrides={"gas.viscosty": 1e-5})}
    with pytest.raises(PlanError, match=r"sweep 'h_vs': overrides: unknown case key 'gas.viscosty' "
                                        r"\(did you mean 'gas.viscosity'\?\)"):
        Plan(config(sweeps))


def test_a_misspelt_same_as_source_gets_a_suggestion():
    sweeps = {"h_mu": {"base": H, "parameters": {"particles.friction": [0.1]},
                       "same_as": {"wall.friction": "particles.fricton"}}}
    with pytest.raises(PlanError, match=r"same_as.wall.friction: unknown case key 'particles.fricton' "
                                        r"\(did you mean 'particles.friction'\?\)"):
        Plan(config(sweeps))


def test_a_same_as_source_that_is_no_parameter_names_the_closest_parameter():
    sweeps = {"h_mu": {"base": H, "parameters": {"particles.friction": [0.1]},
                       "same_as": {"particles.restitution": "wall.friction"}}}
    with pytest.raises(PlanError, match=r"'wall.friction' is not one of its parameters"):
        Plan(config(sweeps))


def test_the_identification_may_compare_training_statements_only():
    statements = [{"id": "DP", "role": "training", "measure": "pressure_drop", "sweep": "id_h"},
                  {"id": "RATE", "measure": "slug_rate", "sweep": "id_h"}]
    sweeps = {"id_h": curve([1.0, 2.0])}
    Plan(config(sweeps, identification={"compare": [{"statement": "DP", "sweep": "id_h"}]}), statements)
    with pytest.raises(PlanError, match="'RATE', a test statement; only statements with role: training"):
        Plan(config(sweeps, identification={"compare": [{"statement": "RATE", "sweep": "id_h"}]}),
             statements)


def test_a_value_out_of_range_is_refused():
    with pytest.raises(PlanError, match="particles.friction"):
        Plan(config({"h_mu": {"base": H, "parameters": {"particles.friction": [-1.0]}}}))


def test_a_missing_base_case_is_refused():
    with pytest.raises(PlanError, match="base case /nonexistent.yaml"):
        Plan(config({"h": {"base": "/nonexistent.yaml"}}))


def test_an_unknown_measure_is_refused_naming_the_statement():
    statements = [{"id": "S9", "measure": "vibes", "case": {"sweep": "h_vs"}}]
    with pytest.raises(PlanError, match="s.yaml: statement S9: unknown measure 'vibes'"):
        Plan(config({"h_vs": curve([1.5])}), statements, "s.yaml")


def test_a_statement_on_an_undeclared_sweep_reads_nothing_and_is_not_pending():
    statements = [{"id": "S1", "measure": "pressure_drop", "case": {"sweep": "v_default"}},
                  {"id": "S2", "measure": "trend", "sweep": "v_vs"}]
    plan = Plan(config({"h_vs": curve([1.5])}), statements)
    for item in plan.validation_statements():
        assert item["files"] == {} and item["pending"] is False
    assert plan.validation_inputs() == []


def test_a_partial_validation_reads_only_what_this_configuration_produced(tmp_path, monkeypatch):
    """A case file counts when it records the planned case and what derives from it is newer;
    a case of other parameters (another configuration's results) is pending, never an input."""
    import os

    import netCDF4

    monkeypatch.chdir(tmp_path)
    statements = [{"id": "S1", "measure": "pressure_drop", "case": {"sweep": "h_default"}}]
    sweeps = {"h_default": single()}
    plan = Plan(config(sweeps, validation={"statements": "s.yaml", "partial": True}), statements)
    case, summary = Path(paths.case_file("h_default", "base")), Path(paths.summary_json("h_default", "base"))
    for path in (case, summary):
        path.parent.mkdir(parents=True)
    summary.write_text("{}")

    def write_case(recorded):
        with netCDF4.Dataset(case, "w") as ds:
            ds.setncattr("config_yaml", recorded.to_yaml())
        os.utime(summary, (case.stat().st_mtime + 1,) * 2)

    write_case(plan.cases[("h_default", "base")])
    [item] = plan.validation_statements()
    assert item["files"] == {"summaries": [str(summary)]} and item["pending"] is False
    assert plan.validation_inputs() == []  # read through params: Snakemake is never asked for them

    other = Plan(config({"h_default": single(**{"tube.length": 0.1})},
                        validation={"statements": "s.yaml", "partial": True}), statements)
    write_case(other.cases[("h_default", "base")])
    [item] = Plan(config(sweeps, validation={"statements": "s.yaml", "partial": True}),
                  statements).validation_statements()
    assert item["files"] == {} and "was run with other parameters" in item["pending"]


def test_a_partial_validation_dates_a_cases_summary_against_that_case_alone(tmp_path, monkeypatch):
    """A statement on two cases (a ratio): each summary counts when it is newer than its own case
    file, even when the other case finished after it; a summary older than its own case does not."""
    import os

    import netCDF4

    monkeypatch.chdir(tmp_path)
    statements = [{"id": "R", "measure": "ratio",
                   "cases": [{"sweep": "h_vs", "point": {"gas.superficial_velocity": 2.0}},
                             {"sweep": "h_vs", "point": {"gas.superficial_velocity": 1.0}}]}]
    sweeps = {"h_vs": curve([1.0, 2.0])}
    plan = Plan(config(sweeps, validation={"statements": "s.yaml", "partial": True}), statements)
    stamp = 1.0e9
    for v in ("2", "1"):  # case 2, its summary, then case 1 (newer than summary 2), its summary
        key = ("h_vs", f"gas.superficial_velocity~{v}")
        case, summary = Path(paths.case_file(*key)), Path(paths.summary_json(*key))
        for path in (case, summary):
            path.parent.mkdir(parents=True, exist_ok=True)
        with netCDF4.Dataset(case, "w") as ds:
            ds.setncattr("config_yaml", plan.cases[key].to_yaml())
        summary.write_text("{}")
        os.utime(case, (stamp, stamp))
        os.utime(summary, (stamp + 1, stamp + 1))
        stamp += 10

    assert plan.validation_statements()[0]["pending"] is False
    older = paths.summary_json("h_vs", "gas.superficial_velocity~2")
    os.utime(older, (1.0e9 - 1, 1.0e9 - 1))
    assert plan.validation_statements()[0]["pending"] == f"{older} is older than its case file"


def test_a_key_added_after_a_case_ran_counts_at_its_default(tmp_path, monkeypatch):
    """A case file written before a key existed records the planned case when the plan leaves
    that key at its default; set to another value, the key is a difference."""
    import netCDF4
    import yaml

    monkeypatch.chdir(tmp_path)
    plan = Plan(config({"h_default": single()}))
    key = ("h_default", "base")
    recorded = yaml.safe_load(plan.cases[key].to_yaml())
    del recorded["run"]["steady_n_particles_error"]
    case = Path(paths.case_file(*key))
    case.parent.mkdir(parents=True)
    with netCDF4.Dataset(case, "w") as ds:
        ds.setncattr("config_yaml", yaml.safe_dump(recorded))
    assert plan.case_differences(key) == []
    other = Plan(config({"h_default": single(**{"run.steady_n_particles_error": 25.0})}))
    assert other.case_differences(key) == [
        "run.steady_n_particles_error = 0.0 there, 25.0 here"]


def test_work_precision_refuses_a_reference_that_is_no_point():
    wp = {"benchmarks": {"work_precision": {"h_vs": {"reference": 3.0}}}}
    with pytest.raises(PlanError, match=r"work_precision.h_vs.reference: sweep 'h_vs' has 0 points"):
        Plan(config({"h_vs": curve([1.5, 2.0])}, **wp))


# ---- file names and figure inputs ----------------------------------------------------------------

def test_path_functions_give_the_rules_output_patterns():
    assert paths.case_file("{sweep}", "{point}") == "results/cases/{sweep}/{point}.nc"
    assert paths.snapshot_nc("{sweep}", "{point}", "radial") == "results/snapshots/{sweep}/{point}/radial.nc"
    assert paths.figure_files("{fig}") == [f"results/figures/{{fig}}.{e}" for e in ("png", "pdf", "txt")]


def test_figure_inputs_come_from_the_kind_registry():
    sweeps = {"h_default": single(), "h_vs": curve([1.5, 2.0]), "h_mu": curve([2.5])}
    figures = {"H02": {"kind": "grains_3d", "case": {"sweep": "h_default"}},
               "V04": {"kind": "curve", "sweep": "h_vs", "x": "gas.superficial_velocity",
                       "experiment": True},
               "H21": {"kind": "curve_pair", "sweeps": ["h_vs", "h_mu"], "x": "gas.superficial_velocity"},
               "H17": {"kind": "cross_sections", "case": {"sweep": "h_default"}}}
    statements = [{"id": "S1", "measure": "trend", "sweep": "h_vs", "figure": ["V04"]}]
    plan = Plan(config(sweeps, figures), statements)
    assert plan.figure_inputs("H02") == {"case": "results/cases/h_default/base.nc",
                                         "slugs": "results/slugs/h_default/base.csv",
                                         "selection": "results/profiles/h_default/base.selection.csv"}
    assert plan.figure_inputs("V04") == {"tables": ["results/curves/h_vs.csv"], "experiment": "exp.csv",
                                         "validation": "results/validation/validation.csv"}
    assert plan.figure_inputs("H21") == {"tables": ["results/curves/h_vs.csv", "results/curves/h_mu.csv"]}
    assert plan.figure_inputs("H17") == {"snapshots": "results/snapshots/h_default/base/cross_sections.nc"}


def test_source_digest_follows_every_python_file_and_nothing_else(tmp_path):
    (tmp_path / "kernels").mkdir()
    (tmp_path / "kernels" / "pair.py").write_text("K = 1\n")
    (tmp_path / "a.py").write_text("A = 1\n")
    first = paths.source_digest(tmp_path)
    (tmp_path / "notes.txt").write_text("not source")
    assert paths.source_digest(tmp_path) == first
    (tmp_path / "kernels" / "pair.py").write_text("K = 2\n")
    assert paths.source_digest(tmp_path) != first


def test_the_identification_baseline_is_each_screened_sweeps_first_values():
    statements = [{"id": "DP", "role": "training", "measure": "pressure_drop", "sweep": "id_h"}]
    spec = {"base": H, "design": "one_at_a_time",
            "parameters": {"gas.scheme": [{"gas.scheme": "unsplit", "gas.theta": 1.0},
                                          {"gas.scheme": "split", "gas.theta": 0.5}],
                           "particles.tangential_damping": [0.02, 0.005]}}
    cfg = config({"id_h": spec, "h_vs": curve([1.0, 2.0])},
                 identification={"readings": ["gas.scheme", "gas.theta", "particles.tangential_damping"],
                                 "compare": [{"statement": "DP", "sweep": "id_h"}]})
    assert Plan(cfg, statements).identification_baselines() == {
        "id_h": {"gas.scheme": "unsplit", "gas.theta": 1.0, "particles.tangential_damping": 0.02}}


def test_no_workflow_script_shadows_a_standard_library_module():
    # the rules put workflow/scripts first on sys.path (common.smk): a script named like a
    # standard-library module would replace it for every import in the workflow
    names = {path.stem for path in (ROOT / "workflow" / "scripts").glob("*.py")}
    assert not names & set(sys.stdlib_module_names)

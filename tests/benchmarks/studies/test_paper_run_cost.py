"""benchmarks/studies/paper_run_cost.py: the cost of a case is its whole run's, the groups add up,
and the schedule respects warm starts and what two cores can do."""

import json

import pandas as pd
import pytest

from .. import load_benchmark


@pytest.fixture(scope="module")
def study():
    return load_benchmark("studies/paper_run_cost")


def timings(rows):
    return pd.DataFrame(rows, columns=["rule", "job", "cpu_s", "case_cpu_s"])


def test_a_resumed_case_costs_its_whole_run_and_other_rules_are_left_out(study):
    table = timings([("simulate", "h_default/base", 100.0, float("nan")),
                     ("simulate", "h_vs/a", 30.0, 400.0),       # resumed: the last part cost 30
                     ("detect", "h_vs/a", 5.0, float("nan")),
                     ("simulate", "(total)", 130.0, 500.0)])
    costs = study.case_costs(table)
    assert costs.to_dict() == {"h_default/base": 100.0, "h_vs/a": 400.0}


def test_the_groups_add_up_to_the_run(study):
    costs = pd.Series({"h_default/base": 10.0, "h_vs/slow": 40.0, "h_vs/block": 5.0,
                       "v_vs/plug": 20.0})
    summaries = {"h_default/base": {"regime": "slug", "vertical": False, "stop_reason": "duration"},
                 "h_vs/slow": {"regime": "slug", "vertical": False, "stop_reason": "max_duration"},
                 "h_vs/block": {"regime": "blocked", "vertical": False, "stop_reason": "blocked"},
                 "v_vs/plug": {"regime": "plug", "vertical": True, "stop_reason": "steady"}}
    table = study.groups(costs, summaries)
    by_group = table[table["by"] == "group"].set_index("cases")["cpu_s"].to_dict()
    assert by_group == {"blocked points": 5.0, "default cases": 10.0,
                        "horizontal curve cases that convey": 40.0,
                        "vertical curve cases that convey": 20.0}
    for by in ("group", "stop"):
        rows = table[table["by"] == by]
        assert rows["cpu_s"].sum() == costs.sum() and rows["n"].sum() == len(costs)
        assert rows["share_%"].sum() == pytest.approx(100.0)


def test_a_warm_started_case_waits_for_its_source(study):
    # one default case of 10 s and three of 10 s started from it: on 2 cores they cannot begin
    # before 10 s, so 10 + 10 + 10 (two side by side, then the third), not the 20 of 40 / 2
    costs = pd.Series({"d/base": 10.0, "s/a": 10.0, "s/b": 10.0, "s/c": 10.0})
    parent = {"d/base": None, "s/a": "d/base", "s/b": "d/base", "s/c": "d/base"}
    assert study.list_schedule(costs, parent, 2) == 30.0
    assert study.lower_bound(costs, parent, 2) == 20.0  # the chain and total / cores
    assert study.list_schedule(costs, parent, 4) == 20.0  # the chain of two


def test_the_longest_critical_path_starts_first(study):
    # a 2 s source of a 10 s case, and two independent 6 s cases: the source first ends at
    # 12 s (source and x/1, then y beside x/1 and x/2); the two 6 s cases first would end at 18 s
    costs = pd.Series({"x/1": 6.0, "x/2": 6.0, "src/base": 2.0, "y/1": 10.0})
    parent = {"y/1": "src/base"}
    assert study.critical_paths(costs, parent) == {"x/1": 6.0, "x/2": 6.0, "src/base": 12.0,
                                                   "y/1": 10.0}
    assert study.list_schedule(costs, parent, 2) == 12.0
    assert study.lower_bound(costs, parent, 2) == 12.0


def test_the_script_reads_a_table_and_its_summaries(study, tmp_path, capsys):
    path = tmp_path / "timings.csv"
    timings([("simulate", "h_default/base", 100.0, 120.0),
             ("simulate", "h_vs/a", 30.0, 400.0)]).to_csv(path, index=False)
    folder = tmp_path / "summaries"
    for job, summary in {"h_default/base": {"stop_reason": "duration"},
                         "h_vs/a": {"regime": "slug", "stop_reason": "steady",
                                    "initial_state": "results/cases/h_default/base.nc"}}.items():
        (folder / job).parent.mkdir(parents=True, exist_ok=True)
        (folder / f"{job}.json").write_text(json.dumps(summary))
    study.main([str(path), "--summaries", str(folder), "--cores", "2"])
    out = capsys.readouterr().out
    assert "2 simulate jobs, 520 CPU s; summaries for 2" in out
    assert "0.14 h; lower bound 0.14 h" in out  # 120 + 400 s in a chain: 520 s


@pytest.mark.parametrize("argv, message", [(["--cores", "0"], "--cores 0: at least 1"),
                                           (["nope.csv"], "timings nope.csv: cannot read it")])
def test_bad_arguments_are_refused_naming_them(study, argv, message, capsys):
    with pytest.raises(SystemExit):
        study.main(argv)
    assert message in capsys.readouterr().err

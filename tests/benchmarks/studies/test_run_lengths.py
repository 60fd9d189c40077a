"""benchmarks/studies/run_lengths.py: the precision statements ask of a case, the windows it needs,
and the engine's stop replayed with the keys that ask it (synthetic cases)."""

import math

import pytest
import xarray as xr

from analysis.runlength import Precision
from tests.analysis import synthetic

from .. import load_benchmark

STATEMENTS = [
    {"id": "dp", "measure": "pressure_drop", "unit": "hPa/m", "value": 10, "tolerance": 0.5,
     "case": {"sweep": "h_default"}},
    {"id": "n", "measure": "n_particles", "unit": "1", "value": 3200, "tolerance": 50,
     "case": {"sweep": "h_default"}},
    {"id": "u", "measure": "slug_stat", "quantity": "max_velocity", "position": "analysis",
     "unit": "m/s", "range": [0.285, 0.305], "case": {"sweep": "h_default"}},
    {"id": "phi", "measure": "slug_stat", "quantity": "min_porosity", "position": "inlet", "unit": "1",
     "value": 0.57, "tolerance": 0.005, "case": {"sweep": "h_default"}},
    {"id": "n4", "measure": "n_particles", "unit": "1", "value": 1400, "tolerance": 50,
     "case": {"sweep": "h_vs", "point": {"gas.superficial_velocity": 4.0}}},
    {"id": "ratio", "measure": "ratio", "unit": "1", "value": 4, "tolerance": 1,
     "cases": [{"sweep": "v_default"}, {"sweep": "h_default"}]},
    {"id": "regime", "measure": "regime", "expected": "slug", "case": {"sweep": "h_default"}},
]


@pytest.fixture(scope="module")
def rl():
    return load_benchmark("studies/run_lengths")


def test_each_statement_asks_half_its_tolerance_of_its_quantity_in_si(rl):
    asked = {a["statement"]: a for a in rl.targets(STATEMENTS, [], "h_default", {}, 0.5, 0.26)}
    # regimes and quantities without a per-case mean (porosity at the inlet) ask nothing
    assert sorted(asked) == ["dp", "n", "ratio", "u"]
    assert asked["dp"]["precision"] == Precision(25.0)  # 0.5 hPa/m = 50 Pa/m, half of it
    assert asked["dp"]["interval"] == pytest.approx((950.0, 1050.0))
    assert asked["n"]["precision"] == Precision(25.0) and asked["n"]["quantity"] == "n_particles"
    assert asked["u"]["precision"].value == pytest.approx(0.005) and asked["u"]["position"] == 0.26
    # a ratio of two pressure drops: its relative error 0.5 x 1 / 4, 1/sqrt(2) of it from each
    ratio = asked["ratio"]["precision"]
    assert ratio.relative and ratio.value == pytest.approx(0.125 / math.sqrt(2))
    assert asked["ratio"]["quantity"] == "pressure_drop"
    assert rl.targets(STATEMENTS, [], "h_default", {}, 0.25, 0.26)[0]["precision"] == Precision(12.5)


def test_a_statement_reaches_its_point_and_an_identification_sweep_through_compare(rl):
    at = lambda sweep, keys, compare=(): [a["statement"] for a in rl.targets(
        STATEMENTS, list(compare), sweep, keys, 0.5, 0.26)]
    assert at("h_vs", {"gas.superficial_velocity": 4.0}) == ["n4"]
    assert at("h_vs", {"gas.superficial_velocity": 2.0}) == []
    compare = [{"statement": "n4", "sweep": "id_h_vs", "where": {"gas.superficial_velocity": 4.0}},
               {"statement": "dp", "sweep": "id_h_default"}]
    assert at("id_h_vs", {"gas.superficial_velocity": 4.0, "gas.scheme": "split"}, compare) == ["n4"]
    assert at("id_h_default", {}, compare) == ["dp"]


def write_case(tmp_path, sweep="h_default", duration=30.0, slugs=True, **config):
    # 5 cm slugs at 0.3 m/s every 0.75 s, pressure drop 1000 Pa/m after 6 s with AR(1) noise of
    # 10 %, tau = 9 frames: an error of 25 Pa/m needs 100^2 x 9 / 25^2 frames = 1.44 s of window
    path = tmp_path / "results" / "cases" / sweep / "base.nc"
    path.parent.mkdir(parents=True, exist_ok=True)
    slugs = synthetic.periodic(duration=duration) if slugs else []
    synthetic.write(synthetic.build(slugs, duration=duration, **config), path)
    return path


def test_the_table_gives_each_case_and_quantity_its_window(rl, tmp_path):
    path = write_case(tmp_path)
    rows = rl.table([path], STATEMENTS, [], 0.5, 0.26)
    assert sorted(rows["statement"]) == ["dp", "n", "ratio", "u"]
    dp = rows.set_index("statement").loc["dp"]
    assert dp["case"] == "h_default" and dp["target"] == 25.0
    # 1.44 s: below the 50 correlation times the estimator needs
    assert dp["window_needed"] == pytest.approx(50 * dp["correlation_time"])
    assert dp["run_needed"] == pytest.approx(dp["t_start"] + dp["window_needed"])
    # a tenth of the tolerance: 5 Pa/m, 100^2 x 9 / 5^2 frames = 36 s (one series: ~20 %)
    tight = rl.table([path], STATEMENTS[:1], [], 0.1, 0.26).iloc[0]
    assert tight["target"] == 5.0 and tight["window_needed"] == pytest.approx(36.0, rel=0.3)
    best = rl.strictest(rows).set_index("quantity")
    # the ratio asks 4.4 % of 1000 Pa/m, looser than 25 Pa/m: the pressure drop's strictest is dp
    assert best.loc["pressure_drop", "statement"] == "dp" and best.loc["pressure_drop", "also"] == "ratio"
    text = rl.markdown(rl.strictest(rows))
    [line] = [x for x in text.splitlines() if "| dp (also ratio) |" in x]
    assert line.startswith("| h_default | pressure_drop (hPa/m) |") and "| 0.250 |" in line
    assert rl.statement_keys(rows) == {"run.steady_pressure_drop_error": 25.0,
                                       "run.steady_n_particles_error": 25.0}
    assert rl.statement_keys(rows[rows["quantity"] == "n_particles"]) == {
        "run.steady_rel_error": 1.0, "run.steady_n_particles_error": 25.0}


def test_the_replayed_stop_waits_for_the_precision_asked(rl, tmp_path):
    # no slugs: the grains in the tube and the mass flows are constant, the pressure drop decides
    path = write_case(tmp_path, duration=30.0, slugs=False,
                      **{"run.steady_min_window": 2.0, "run.steady_settle": 5.0})
    import xarray as xr
    with xr.open_dataset(path) as ds:
        ds.load()
    # grains leave from 2 s, windows open at 7 s; 3 % of 1000 Pa/m needs only ~1 s of window, so
    # the 50 correlation times the estimator needs decide (4.5 s); 8 Pa/m needs
    # 100^2 x 9 / 8^2 frames = 14 s; 5 Pa/m 36 s, beyond the series
    loose = rl.replay(ds, {"run.steady_rel_error": 0.03})
    assert loose is not None and loose.start == pytest.approx(7.0, abs=0.011)
    assert loose.end - loose.start >= 50 * loose.pressure_drop.tau_s - 0.05
    assert 0.7 * 4.5 <= loose.end - loose.start <= 1.4 * 4.5
    middle = rl.replay(ds, {"run.steady_pressure_drop_error": 8.0})
    assert middle is not None and middle.pressure_drop.error / synthetic.L_TUBE <= 8.0
    assert 0.7 * 14 <= middle.end - middle.start <= 1.3 * 14
    assert rl.replay(ds, {"run.steady_pressure_drop_error": 5.0}) is None
    rows = rl.replay_rows([path], ["h_default"], lambda case: {"run.steady_pressure_drop_error": 5.0})
    assert math.isnan(rows["stop"].iloc[0]) and "not steady by 30.0" in rl.replay_markdown(rows)


def test_every_case_replays_the_stop_and_costs_it_pro_rata(rl, tmp_path, capsys):
    # two 30 s runs of the same series (no slugs): one capped by max_duration, one of fixed duration
    paths = []
    for sweep, reason in (("h_viscosity", "max_duration"), ("h_default", "duration")):
        path = write_case(tmp_path, sweep=sweep, duration=30.0, slugs=False,
                          **{"run.steady_min_window": 2.0, "run.steady_settle": 5.0})
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        ds.attrs.update(stop_reason=reason, cpu_time_total_s=600.0)
        path.unlink()
        synthetic.write(ds, path)
        paths.append(path)
    rows = rl.replay_rows(paths, ["capped", "fixed"], lambda case: {"run.steady_pressure_drop_error": 8.0})
    assert list(rows["cpu_s"]) == [600.0, 600.0]
    stop = rows["stop"].iloc[0]
    assert 7.0 + 0.7 * 14 <= stop <= 7.0 + 1.3 * 14  # as in the test above: 14 s of window from 7 s
    cost = rl.replay_cost(rows)
    # the capped run ends at its replayed stop, the fixed-duration run keeps its 30 s
    assert cost["cases"] == 2 and cost["stopped_earlier"] == 1
    ran = rows["ran_to"].iloc[0]  # the last frame's time
    assert cost["cpu_s"] == 1200.0 and cost["cpu_s_replayed"] == pytest.approx(600.0 * stop / ran + 600.0)
    assert cost["moved_over_2_se"] <= cost["moved_over_1_se"] <= 1
    # a tolerance no window reaches: nothing stops earlier, nothing is saved
    never = rl.replay_cost(rl.replay_rows(paths, ["capped", "fixed"], lambda case: {"run.steady_pressure_drop_error": 1.0}))
    assert never["stopped_earlier"] == 0 and never["cpu_s_replayed"] == 1200.0
    rl.main([str(p) for p in paths] + ["--every-case", "--replay", "run.steady_pressure_drop_error=8"])
    out = capsys.readouterr().out
    assert "h_viscosity/base" in out and "2 cases, 1 stopped earlier: 1200 CPU s recorded" in out
    with pytest.raises(SystemExit):
        rl.main([str(paths[0]), "--every-case"])

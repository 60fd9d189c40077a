"""benchmarks/studies/steady_tolerance.py: the steady stop replayed on a recorded series (synthetic case)."""

import pytest

from tests.analysis import synthetic

from .. import load_benchmark

EVERY = 10  # frames between stop checks (0.1 s); every frame would cost ~10x more here
STEADY = {"run.until_steady": True, "run.steady_settle": 1.0, "run.steady_min_window": 2.0,
          "run.steady_rel_error": 0.03}


@pytest.fixture(scope="module")
def st():
    return load_benchmark("studies/steady_tolerance")


def recorded(duration=40.0, **run):
    # pressure drop at 1000 Pa/m after a 1 s rise, with AR(1) noise of 50 % and lag-one correlation
    # 0.8 (tau 0.09 s, 50 of them in 4.5 s): the relative error of a T-second mean is about 0.5 sqrt(9 x 0.01 s / T), 3 %
    # after ~25 s and 5 % after ~9 s of window (windows open at 3 s: grains leave from 2 s, settle 1 s)
    ds = synthetic.build([], duration=duration, **{**STEADY, **run})
    times = ds["time"].values
    ds["pressure_drop"].values[:] = synthetic.pressure_signal(times, 1000.0 * synthetic.L_TUBE, transient=1.0,
                                                              noise=0.5, rho=0.8, seed=3)
    ds.attrs["cpu_time_total_s"] = 10.0 * duration  # CPU s of all the run's parts
    return ds


def test_a_looser_tolerance_stops_earlier_and_the_own_one_at_the_recorded_stop(st):
    full = recorded()
    stop3, dp3, steady3 = st.replay(full, 0.03, every=EVERY)
    stop5, dp5, steady5 = st.replay(full, 0.05, every=EVERY)
    assert steady3 and steady5 and stop5 < stop3 < 40.0
    # the steady pressure drop per metre of the series up to the stop (Pa/m, not the Pa of the
    # series): near the level, within about 2 of its errors (over seeds 0-4 of this signal the 3 %
    # stop lands 0-6 % off, the 5 % stop 2-5 %)
    assert dp3 == pytest.approx(1000.0, rel=0.12) and dp5 == pytest.approx(1000.0, rel=0.15)
    # a run that stopped at its first steady frame ends there: the replay finds that frame again
    ran = full.isel(time=slice(0, int(round(stop3 / synthetic.DT)) + 1))
    assert st.replay(ran, 0.03, every=EVERY)[0] == pytest.approx(stop3)
    # the case's own keys are kept: a longer minimum window cannot stop sooner
    assert st.replay(recorded(**{"run.steady_min_window": 30.0}), 0.03, every=EVERY)[0] >= max(stop3, 33.0)


def test_table_and_summary_count_the_saving(st, tmp_path):
    ran = recorded()
    stop3 = st.replay(ran, 0.03, every=EVERY)[0]
    ran = ran.isel(time=slice(0, int(round(stop3 / synthetic.DT)) + 1))
    ran.attrs["cpu_time_total_s"] = 100.0
    synthetic.write(ran, tmp_path / "steady.nc")
    synthetic.write(recorded(**{"run.until_steady": False}), tmp_path / "fixed.nc")
    rows = st.table([tmp_path / "steady.nc", tmp_path / "fixed.nc"], [0.03, 0.05], every=EVERY)
    assert set(rows["case"]) == {str(tmp_path / "steady.nc")}  # fixed-duration runs are not replayed
    summary = st.summary(rows).set_index("tolerance")
    stop5 = rows.loc[rows["tolerance"] == 0.05, "stop_s"].iloc[0]
    assert summary.loc[0.03, "saved_cpu_s"] == pytest.approx(0.0, abs=1e-9)
    assert summary.loc[0.05, "saved_cpu_s"] == pytest.approx(100.0 * (1 - stop5 / ran["time"].values[-1]))
    assert summary.loc[0.03, "dp_change_max_abs"] == 0.0
    # the run's own tolerance is always replayed: the changes need it
    assert set(st.table([tmp_path / "steady.nc"], [0.05], every=EVERY)["tolerance"]) == {0.03, 0.05}


def test_bad_tolerance_is_refused(st, capsys):
    with pytest.raises(SystemExit) as err:
        st.main(["x.nc", "--tolerance", "0"])
    assert err.value.code == 2 and "--tolerance must lie in (0, 1]" in capsys.readouterr().err

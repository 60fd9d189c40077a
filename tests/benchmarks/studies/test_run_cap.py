"""benchmarks/studies/run_cap.py: a run until steady that went on beyond the cap is cut there and
says so, every other file is copied as it was, and the workflow's mtime order is kept."""

import math

import numpy as np
import pytest
import xarray as xr

from analysis.curves import case_summary
from tests.analysis import synthetic

from .. import load_benchmark


@pytest.fixture(scope="module")
def study():
    return load_benchmark("studies/run_cap")


def write_case(folder, sweep, point, duration, stop_reason, until_steady, cpu_s):
    ds = synthetic.build([], duration=duration, **{"run.until_steady": until_steady})
    ds.attrs.update(stop_reason=stop_reason, cpu_time_s=cpu_s, cpu_time_total_s=cpu_s,
                    wall_time_s=cpu_s, steady_start=math.nan, blocked_time=math.nan)
    if stop_reason == "steady":
        ds.attrs.update(steady_start=6.0, steady_end=duration - synthetic.DT)
    path = folder / sweep / f"{point}.nc"
    path.parent.mkdir(parents=True, exist_ok=True)
    synthetic.write(ds, path)
    return path


@pytest.fixture
def source(tmp_path):
    folder = tmp_path / "src" / "results" / "cases"
    write_case(folder, "h_default", "base", 30.0, "duration", False, 600.0)
    write_case(folder, "h_vs", "capped", 30.0, "max_duration", True, 300.0)
    write_case(folder, "h_vs", "steady", 12.0, "steady", True, 120.0)
    return folder


def test_a_run_until_steady_beyond_the_cap_is_cut_there_with_its_cpu_pro_rata(study, source, tmp_path,
                                                                           capsys):
    dest = tmp_path / "cut" / "results" / "cases"
    study.main([str(source), str(dest), "--cap", "20"])
    with xr.open_dataset(dest / "h_vs" / "capped.nc") as cut, \
            xr.open_dataset(source / "h_vs" / "capped.nc") as whole:
        t = cut["time"].values
        assert t[-1] == pytest.approx(20.0) and t.size == 2001  # frames 0, 0.01, ..., 20 s
        np.testing.assert_array_equal(cut["pressure_drop"].values, whole["pressure_drop"].values[:2001])
        assert cut.attrs["stop_reason"] == "max_duration" and math.isnan(cut.attrs["steady_end"])
        # 300 CPU s over the 29.99 s the run recorded: 20 / 29.99 of it
        assert cut.attrs["cpu_time_total_s"] == pytest.approx(300.0 * 20.0 / 29.99)
        assert case_summary(cut)["t_end"] <= 20.0  # the analysis reads the cut run
    # the fixed-duration run and the run that stopped steady before the cap: whole
    for name in ("h_default/base", "h_vs/steady"):
        with xr.open_dataset(dest / f"{name}.nc") as copy, xr.open_dataset(source / f"{name}.nc") as orig:
            xr.testing.assert_identical(copy, orig)
    out = capsys.readouterr().out
    assert "3 case files, 1 cut (the runs until steady, cap 20.0 s): 1,020 -> 920 CPU s" in out
    # warm-start sources dated before the cases started from them
    assert (dest / "h_default/base.nc").stat().st_mtime < (dest / "h_vs/capped.nc").stat().st_mtime


def test_all_cuts_the_fixed_duration_runs_too(study, source, tmp_path):
    dest = tmp_path / "cut" / "results" / "cases"
    study.main([str(source), str(dest), "--cap", "20", "--all"])
    with xr.open_dataset(dest / "h_default" / "base.nc") as cut:
        assert cut["time"].values[-1] == pytest.approx(20.0)
        assert cut.attrs["stop_reason"] == "duration"
    with xr.open_dataset(dest / "h_vs" / "steady.nc") as copy:
        assert copy.attrs["stop_reason"] == "steady" and copy["time"].values[-1] == pytest.approx(11.99)


def test_keep_leaves_the_runs_of_a_sweep_whole(study, source, tmp_path, capsys):
    dest = tmp_path / "cut" / "results" / "cases"
    study.main([str(source), str(dest), "--cap", "20", "--all", "--keep", "h_default"])
    with xr.open_dataset(dest / "h_default" / "base.nc") as copy:
        assert copy["time"].values[-1] == pytest.approx(29.99)
    with xr.open_dataset(dest / "h_vs" / "capped.nc") as cut:
        assert cut["time"].values[-1] == pytest.approx(20.0)
    assert "(every run but those of h_default, cap 20.0 s)" in capsys.readouterr().out


def test_a_block_after_the_cap_is_not_a_block_of_the_cut_run(study, source):
    with xr.open_dataset(source / "h_vs" / "capped.nc") as ds:
        ds = ds.load()
    ds.attrs.update(stop_reason="blocked", blocked_time=25.0)
    cut = study.cut(ds, 20.0)
    assert cut.attrs["stop_reason"] == "max_duration" and math.isnan(cut.attrs["blocked_time"])


@pytest.mark.parametrize("extra, message", [(["--cap", "0"], "--cap 0.0: a positive simulated time"),
                                            (["--cap", "20", "--same"], "dest is the source folder"),
                                            (["--cap", "20", "--keep", "h_vz"],
                                             "--keep h_vz: no such sweep")])
def test_bad_arguments_are_refused_before_any_file_is_written(study, source, extra, message, capsys):
    dest = source if "--same" in extra else source.parent / "elsewhere"
    with pytest.raises(SystemExit):
        study.main([str(source), str(dest), *[e for e in extra if e != "--same"]])
    assert message in capsys.readouterr().err
    assert not (source.parent / "elsewhere").exists()


def test_compare_gives_each_points_move_in_both_runs_errors(study, tmp_path, capsys):
    base, cut = tmp_path / "base", tmp_path / "cut"
    for folder, rows in ((base, ["a,slug,1000,50", "b,slug,2000,100", "c,bulk,500,10"]),
                         (cut, ["a,slug,1000,50", "b,slug,2150,150", "c,blocked,480,20"])):
        folder.mkdir()
        (folder / "h_vs.csv").write_text("# attrs: {}\npoint,regime,pressure_drop,pressure_drop_sem\n"
                                         + "\n".join(rows) + "\n")
    table = study.compare_curves(base, cut).set_index("point")
    assert table.at["b", "moved_in_baseline_se"] == pytest.approx(1.5)
    assert table.at["b", "moved_in_cut_se"] == pytest.approx(1.0)
    assert table.at["a", "moved_in_baseline_se"] == 0.0
    study.main(["--compare", str(base), str(cut)])
    out = capsys.readouterr().out
    assert "h_vs/c: bulk -> blocked, 5.00 ± 0.10 -> 4.80 ± 0.20 hPa/m (-2.0 baseline s.e." in out
    assert ("3 curve points, 2 changed; regime changed: 1; pressure drop moved by more than 1 "
            "baseline s.e.: 2, more than 2: 0") in out
    assert "(NaN): 0 points in the baseline, 0 in the cut run" in out


def test_compare_of_a_run_with_itself_changes_nothing(study, tmp_path, capsys):
    (tmp_path / "h_vs.csv").write_text("point,regime,pressure_drop,pressure_drop_sem\na,slug,1000,50\n")
    study.main(["--compare", str(tmp_path), str(tmp_path)])
    out = capsys.readouterr().out
    assert "1 curve points, 0 changed; regime changed: 0" in out and "(none to compare)" in out


def test_without_dest_or_compare_the_usage_is_refused(study, source, capsys):
    with pytest.raises(SystemExit):
        study.main([str(source)])
    assert "give SOURCE and DEST" in capsys.readouterr().err

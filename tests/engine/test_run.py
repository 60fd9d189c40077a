"""`plugsim run` / run_case: the case file, refusal of bad input, atomic output, checkpoint + resume."""

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr

from analysis import open_case, steady_pressure_drop
from analysis.contract import FIELDS, SERIES
from analysis.timeseries import mean_error
from engine import Case, Simulation
from engine.run import RunError, _check_health, checkpoint_path, run_case, steady_window

ROOT = Path(__file__).resolve().parents[2]
CASE = ROOT / "config" / "cases" / "horizontal.yaml"
# Short, cheap grain-only runs: the feed piston pushes a 2.1 cm tube full within 0.6 s.
SHORT = ["gas.enabled=false", "tube.length=0.021", "run.duration=0.6", "output.snapshots=true",
         "output.snapshot_x_min=0.0", "output.snapshot_x_max=0.015", "output.snapshot_interval=0.05"]


def plugsim(*args, **kw):
    return subprocess.run([sys.executable, "-m", "engine.cli", *args], capture_output=True, text=True,
                          cwd=kw.pop("cwd", None), **kw)


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "case.nc"
    run_case(Case.from_yaml(CASE, SHORT), out)
    with xr.open_dataset(out) as ds:
        return ds.load()


def test_case_file_has_the_contract_variables_dims_and_units(short_run):
    ds = short_run
    assert ds.time.attrs["units"] == "s" and ds.x.attrs["units"] == "m"
    np.testing.assert_allclose(ds.time, np.arange(61) * 0.01, atol=1e-12)
    np.testing.assert_allclose(ds.x, (np.arange(6) + 0.5) * 0.0035, rtol=1e-12)
    for name, var in {**SERIES, **FIELDS}.items():
        assert ds[name].attrs["units"] == var.units and ds[name].attrs["long_name"]
    for name in SERIES:
        assert ds[name].dims == ("time",)
    for name in FIELDS:
        assert ds[name].dims == ("time", "x")
    config = Case(__import__("yaml").safe_load(ds.attrs["config_yaml"]))
    assert config == Case.from_yaml(CASE, SHORT)
    assert ds.attrs["seed"] == 0 and ds.attrs["engine_version"] and ds.attrs["stop_reason"] == "duration"
    for name in ["tube_length", "tube_diameter", "particle_diameter", "particle_density", "inclination_deg"]:
        assert name in ds.attrs


def test_case_file_keeps_the_mass_books(short_run):
    ds = short_run
    mass = math.pi / 6 * 1.4e-3**3 * 937
    np.testing.assert_allclose(ds.mass_in - ds.mass_out, ds.n_particles * mass, rtol=1e-12)
    assert ds.mass_out[-1] > 0, "the short tube should have filled and spilled"
    # slice porosity integrates to the grains in the tube (grains are whole inside 0 <= x <= L)
    solid = ((1 - ds.porosity) * 0.0035 * math.pi * 0.0035**2).sum("x")
    inside = ds.n_particles * math.pi / 6 * 1.4e-3**3
    np.testing.assert_allclose(solid, inside, rtol=2e-2)  # grains straddling x = L: < 1 grain in ~100


def test_snapshots_are_a_ragged_array_inside_the_window(short_run):
    ds = short_run
    counts = ds.snapshot_count.values
    assert ds.snapshot_count.attrs["sample_dimension"] == "grain"
    assert counts.sum() == ds.sizes["grain"] and len(counts) == 13  # every 0.05 s from t = 0
    x = ds.snapshot_position.values[:, 0]
    assert np.all((x >= 0.0) & (x <= 0.015)) and counts[-1] > 0


def test_a_shorter_run_writes_the_first_frames_of_a_longer_one(short_run, tmp_path):
    # the duration only ends a run: a finished run cut at T is the run of duration T
    # (benchmarks/studies/run_cap.py measures shorter caps on that)
    out = tmp_path / "shorter.nc"
    run_case(Case.from_yaml(CASE, SHORT + ["run.duration=0.3"]), out)
    with xr.open_dataset(out) as ds:
        assert ds.sizes["time"] == 31
        for name in {**SERIES, **FIELDS}:
            np.testing.assert_array_equal(ds[name].values, short_run[name].values[:31], err_msg=name)


def test_bad_input_is_refused_before_any_work(tmp_path):
    out = tmp_path / "bad.nc"
    res = plugsim("run", str(CASE), "--out", str(out), "--set", "particles.friction=-1")
    assert res.returncode == 2
    assert res.stderr.strip().splitlines()[-1].startswith("plugsim: error: particles.friction = -1")
    assert not out.exists() and not list(tmp_path.iterdir())


def test_killed_run_leaves_no_file_and_resumes_to_an_identical_result(tmp_path):
    args = [str(CASE), *sum((["--set", s] for s in SHORT + ["run.checkpoint_interval=1e-9"]), [])]
    reference = tmp_path / "reference.nc"
    assert plugsim("run", args[0], "--out", str(reference), *args[1:]).returncode == 0
    out = tmp_path / "killed.nc"
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, "-m", "engine.cli", "run", args[0], "--out", str(out), *args[1:]],
                            env=env, stderr=subprocess.PIPE)
    deadline = time.time() + 120
    ckpt = checkpoint_path(out)
    while not ckpt.exists() and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert ckpt.exists(), "no checkpoint was written"
    assert not out.exists(), "a killed run must not leave a file at OUT"
    res = plugsim("run", args[0], "--out", str(out), *args[1:], env=env)
    assert res.returncode == 0, res.stderr
    assert not ckpt.exists()
    with xr.open_dataset(reference) as a, xr.open_dataset(out) as b:
        assert a.attrs["resumed"] == 0 and b.attrs["resumed"] == 1 and a.attrs["wall_time_s"] > 0
        # a run in one part costs what its part did; the resumed one adds the killed part's CPU
        # seconds, saved with its checkpoint (0.05 s: the two clocks are read apart by a write)
        assert a.attrs["cpu_time_total_s"] == pytest.approx(a.attrs["cpu_time_s"], abs=0.05)
        assert b.attrs["cpu_time_total_s"] > b.attrs["cpu_time_s"] + 0.05
        for name in a.data_vars:
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


STEADY = ["run.steady_settle=1", "run.steady_min_window=2", "run.steady_rel_error=0.03"]
GRAIN = 937.0 * math.pi / 6 * 0.0014**3  # kg, the default grain
FEED = 2.49 / 3600  # kg/s, the default feed


def ar1(n, rho, sd, seed):
    """AR(1) noise of standard deviation sd and lag-one correlation rho, n frames."""
    rng = np.random.default_rng(seed)
    x = np.empty(n)
    x[0] = rng.normal() * sd
    eps = rng.normal(size=n) * sd * math.sqrt(1 - rho**2)
    for k in range(1, n):
        x[k] = rho * x[k - 1] + eps[k]
    return x


def recorded(t, dp, grains, fill=1.0, feed=FEED):
    """Recorder-like series with consistent mass books: grains fed at `feed` kg/s from t = 0, none
    leave before `fill`, then the tube holds `grains` (array) and the rest has left."""
    mass_in = feed * t
    held = np.where(t < fill, mass_in, np.minimum(grains * GRAIN, mass_in))
    return SimpleNamespace(times=t, series={"pressure_drop": dp, "mass_in": mass_in,
                                            "mass_out": mass_in - held, "n_particles": held / GRAIN})


def first_steady(case, rec, every=10):
    """The first steady window of `rec` checked every `every` frames, as a run checks every frame."""
    for k in range(every, len(rec.times) + 1, every):
        window = steady_window(SimpleNamespace(times=rec.times[:k], series={
            name: values[:k] for name, values in rec.series.items()}), case)
        if window:
            return window
    return None


def steady_hold_up(t, level=100.0, seed=0):
    """Grains in a steady tube: a level with AR(1) fluctuations of 5 grains, lag-one correlation
    0.5 (tau = 3 frames: 50 correlation times fit in the shortest window)."""
    return level + ar1(len(t), 0.5, 5.0, seed)


def test_white_noise_stops_at_the_shortest_window_after_the_fill():
    # 10 % white noise on 1000 Pa: the error of a 2 s mean (200 frames) is 0.7 %
    case = Case().with_overrides(STEADY)
    t = np.arange(0, 8, 0.01)
    dp = np.where(t < 1, 1000 * t, 1000) + np.random.default_rng(0).normal(0, 100, t.size)
    stop = first_steady(case, recorded(t, dp, steady_hold_up(t)))
    assert stop is not None
    assert stop.start == pytest.approx(2.0, abs=0.011)  # steady_settle after the first outflow
    assert stop.end - stop.start == pytest.approx(2.0, abs=0.11)
    assert stop.pressure_drop.error == pytest.approx(100 / math.sqrt(200), rel=0.2)
    assert abs(stop.outflow.mean - FEED) <= 2 * math.hypot(stop.outflow.error, stop.inflow.error)


def test_a_correlated_signal_needs_its_correlation_times_and_a_noisy_one_its_error():
    # AR(1) noise with lag-one correlation 0.97 (tau = 65 frames, 0.65 s): the 3 % error is
    # reached after ~3 s, but 50 correlation times take ~33 s; the old 10 batches passed at 2 s
    case = Case().with_overrides(STEADY)
    t = np.arange(0, 60, 0.01)
    dp = 1000 + ar1(t.size, 0.97, 100.0, seed=1)
    stop = first_steady(case, recorded(t, dp, steady_hold_up(t)))
    # the earliest candidate that passes: a later start can pass first when its own tau estimate
    # is smaller (here the one at 8 s, stopping at 34 s)
    assert stop is not None and stop.start >= 2.0 - 0.011
    length = stop.end - stop.start
    assert length >= 50 * stop.pressure_drop.tau_s - 0.1  # the estimate of tau the rule used
    assert 0.5 * 50 * 0.65 <= length <= 1.5 * 50 * 0.65  # tau estimated within its ~30 % scatter
    # white noise of 100 %: the correlation times are covered at once, the error reaches 3 % after
    # 1111 frames (11 s): the window stops then, not at a fixed length
    noisy = 1000 + np.random.default_rng(2).normal(0, 1000, t.size)
    stop = first_steady(case, recorded(t, noisy, steady_hold_up(t)))
    assert stop is not None and stop.start == pytest.approx(2.0, abs=0.011)
    assert 0.8 * 11.1 <= stop.end - stop.start <= 1.2 * 11.1  # the error's own ~10 % scatter


def test_an_absolute_pressure_drop_precision_decides_instead_of_the_relative_error():
    # white noise of 100 Pa on 1000 Pa over the 0.525 m tube: 3 % stops the shortest window (2 s,
    # above); an error of 2.5 Pa (4.76 Pa/m) needs (100 / 2.5)^2 = 1600 frames, 16 s
    t = np.arange(0, 30, 0.01)
    dp = 1000 + np.random.default_rng(0).normal(0, 100, t.size)
    case = Case().with_overrides([*STEADY, f"run.steady_pressure_drop_error={2.5 / 0.525}"])
    stop = first_steady(case, recorded(t, dp, steady_hold_up(t)))
    assert stop is not None and stop.pressure_drop.error <= 2.5
    assert 0.8 * 16 <= stop.end - stop.start <= 1.2 * 16  # the error's own ~10 % scatter, squared
    # and looser than 3 %: white noise of 1000 Pa reaches 3 % after 11 s (above), 100 Pa/m
    # (52.5 Pa) after (1000 / 52.5)^2 = 363 frames
    noisy = 1000 + np.random.default_rng(2).normal(0, 1000, t.size)
    case = Case().with_overrides([*STEADY, "run.steady_pressure_drop_error=100"])
    stop = first_steady(case, recorded(t, noisy, steady_hold_up(t)))
    assert stop is not None and stop.start == pytest.approx(2.0, abs=0.011)
    assert 0.75 * 3.63 <= stop.end - stop.start <= 1.25 * 3.63


def test_a_grain_count_precision_holds_the_stop_until_the_count_is_known():
    # the hold-up of steady_hold_up: SD 5 grains, tau = 3 frames; an error of 0.2 grains needs
    # 25 x 3 / 0.04 = 1875 frames (18.75 s), while the pressure drop meets 3 % after 2 s
    t = np.arange(0, 40, 0.01)
    dp = 1000 + np.random.default_rng(0).normal(0, 100, t.size)
    grains = steady_hold_up(t)
    case = Case().with_overrides([*STEADY, "run.steady_n_particles_error=0.2"])
    stop = first_steady(case, recorded(t, dp, grains))
    assert stop is not None
    k = int(np.searchsorted(t, stop.start - 1e-9))
    assert mean_error(grains[k:int(round(stop.end / 0.01)) + 1], 0.01).error <= 0.2 + 1e-9
    assert 0.75 * 18.75 <= stop.end - stop.start <= 1.25 * 18.75  # tau estimated within ~20 %
    # a pressure drop that never reaches 3 % in 30 s (300 % white noise: 100 s) does not hold up
    # a case whose statements ask only the grain count (run.steady_rel_error = 1: convergence)
    t = np.arange(0, 30, 0.01)
    noisy = 1000 + np.random.default_rng(3).normal(0, 3000, t.size)
    rec = recorded(t, noisy, steady_hold_up(t))
    assert first_steady(Case().with_overrides(STEADY), rec) is None
    only_count = Case().with_overrides([*STEADY, "run.steady_rel_error=1", "run.steady_n_particles_error=0.5"])
    stop = first_steady(only_count, rec)
    assert stop is not None and stop.end <= 2.0 + 2 * 3.0  # 300 frames (3 s) after the settle


def test_a_tube_still_filling_is_not_steady():
    # the hold-up climbs by 20 grains per second (4 % of the 514 grains/s fed) while the pressure
    # drop is already flat: never steady (the outflow test alone passed it after 2 s); the same
    # tube with a steady hold-up is
    case = Case().with_overrides(STEADY)
    t = np.arange(0, 30, 0.01)
    dp = 1000 + np.random.default_rng(3).normal(0, 100, t.size)
    filling = steady_hold_up(t) + 20.0 * np.maximum(t - 1.0, 0.0)
    assert first_steady(case, recorded(t, dp, filling)) is None
    assert first_steady(case, recorded(t, dp, steady_hold_up(t))) is not None


def test_a_tube_that_takes_nothing_and_delivers_nothing_is_not_steady():
    # blocked after a first spill: no grain enters or leaves from t = 1.5 s on, the pressure drop
    # is flat and converged
    case = Case().with_overrides(STEADY)
    t = np.arange(0, 20, 0.01)
    dp = 1000 + np.random.default_rng(4).normal(0, 100, t.size)
    rec = recorded(t, dp, steady_hold_up(t))
    for name in ("mass_in", "mass_out", "n_particles"):
        values = rec.series[name]
        values[t > 1.5] = values[np.searchsorted(t, 1.5)]
    assert first_steady(case, rec) is None


def test_until_steady_stops_a_short_real_case_and_records_the_window(tmp_path):
    # A 7 cm horizontal tube with the gas on fills in about a second; a loose tolerance keeps the
    # test short while exercising the whole stopping rule on real, fluctuating data.
    case = Case.from_yaml(CASE, [
        "tube.length=0.07", "gas.nodes_x=20", "numerics.gas_interval=10", "run.duration=6",
        "run.until_steady=true", "run.steady_settle=0.2", "run.steady_min_window=0.5",
        "run.steady_rel_error=0.1", "run.steady_min_correlation_times=10"])
    out = run_case(case, tmp_path / "steady.nc")
    with xr.open_dataset(out) as ds:
        assert ds.attrs["stop_reason"] == "steady"
        start, end = ds.attrs["steady_start"], ds.attrs["steady_end"]
        first_out = float(ds.time[np.argmax(ds.mass_out.values > 0)])
        # candidates open 0.2 s after the first outflow, then every half window (0.25 s)
        offset = (start - first_out - 0.2) / 0.25
        assert offset >= -1e-6 and offset == pytest.approx(round(offset), abs=1e-6)
        assert end == pytest.approx(float(ds.time[-1])) and end - start >= 0.5 - 1e-9  # frame round-off
        assert end < 6.0
        window = ds.pressure_drop.sel(time=slice(start, end)).values
        est = mean_error(window, 0.01, 10)
        assert est.error < 0.1 * est.mean
        # one case, one number: the run's attributes and the analysis agree to the digit
        assert ds.attrs["steady_pressure_drop"] == pytest.approx(est.mean, rel=1e-12)
        assert ds.attrs["steady_pressure_drop_sem"] == pytest.approx(est.error, rel=1e-12)
        res = steady_pressure_drop(open_case(out))
        assert res["window"] == "run" and res["t_start"] == start and res["t_end"] == end
        assert res["pressure_drop"] * 0.07 == pytest.approx(est.mean, rel=1e-12)
        assert res["pressure_drop_sem"] * 0.07 == pytest.approx(est.error, rel=1e-12)


def test_numerical_failure_exits_1_with_one_line_and_no_file(tmp_path):
    # Undamped, frictionless grains at 0.6 t_c: below the single-pair stability limit (0.64 t_c),
    # accepted only with the safety margin switched off (time_step_safety=1), but unstable in a
    # packed column, whose stiffest modes are higher; the guard must catch it.
    out = tmp_path / "blow.nc"
    res = plugsim("run", str(ROOT / "config/cases/vertical.yaml"), "--out", str(out), "--quiet",
                  *sum((["--set", s] for s in [
                      "numerics.time_step_fraction=0.6", "numerics.time_step_safety=1",
                      "particles.restitution=1", "wall.restitution=1",
                      "particles.tangential_damping=0", "run.duration=1", "tube.length=0.03",
                      "gas.nodes_x=8"]), []))
    assert res.returncode == 1
    lines = res.stderr.strip().splitlines()
    # which guard fires first depends on the chaotic path of the blow-up: the per-frame overlap
    # bound (test below) or the per-step check that every grain is inside the tube
    assert len(lines) == 1, lines
    assert (lines[0].startswith("plugsim: run failed: grain overlap") and "exceeds the bound 0.2 d" in lines[0]
            or lines[0].startswith("plugsim: run failed: a grain left the tube")), lines
    assert not list(tmp_path.iterdir())


def test_run_guard_stops_at_an_overlap_beyond_the_bound():
    # two grains pressed 0.3 d into each other: the largest overlap of the step is 0.3 d > 0.2 d
    sim = Simulation(Case().with_overrides(["gas.enabled=false", "feed.mass_flow_kg_h=0"]))
    d = 2 * sim.model.radius
    sim.add_particles(np.array([[0.1, 0.0, 0.0], [0.1 + 0.7 * d, 0.0, 0.0]]))
    sim.advance(sim.dt)
    # one step of their repulsion (k_n 0.3 d / m over dt) pushes them ~0.02 d apart
    assert 0.25 * d < sim.max_overlap <= 0.3 * d
    with pytest.raises(RunError, match=r"grain overlap 0\.2\d d exceeds the bound 0\.2 d"):
        _check_health(sim)


def test_bench_options_reach_the_benchmark():
    """`plugsim bench --json --steps ...`: leading options go to engine.bench, not argparse's REMAINDER."""
    res = plugsim("bench", "--help")
    assert res.returncode == 0 and "--steps" in res.stdout
    res = plugsim("bench", "--no-such-option")
    assert res.returncode == 2 and "--no-such-option" in res.stderr


# A 4 cm vertical tube at the papers' default gas and feed: plugs form and the pressure drop is
# steady (~26 hPa/m, ~250 grains) from ~0.5 s on; 3 simulated seconds cost ~7 s of CPU.
VERTICAL_SHORT = ["tube.length=0.04", "gas.nodes_x=11", "tube.inclination_deg=90"]


def _mean_after(path, t_from):
    """Mean and standard error of the pressure drop after t_from (s)."""
    with xr.open_dataset(path) as ds:
        est = mean_error(ds.pressure_drop.values[ds.time.values >= t_from], 0.01, 10)
        return est.mean, est.error


def test_warm_start_reaches_the_same_steady_state_as_a_cold_start(tmp_path):
    vertical = ROOT / "config" / "cases" / "vertical.yaml"
    cold, other, warm = tmp_path / "cold.nc", tmp_path / "other.nc", tmp_path / "warm.nc"
    run_case(Case.from_yaml(vertical, VERTICAL_SHORT + ["run.duration=4.0"]), cold)
    # the warm run starts from a different steady state: twice the gas velocity (fewer grains)
    run_case(Case.from_yaml(vertical, VERTICAL_SHORT + ["run.duration=3.0", "gas.superficial_velocity=2.0"]),
             other)
    run_case(Case.from_yaml(vertical, VERTICAL_SHORT + ["run.duration=2.0"]), warm, initial_state=other)
    with xr.open_dataset(other) as a, xr.open_dataset(warm) as b:
        assert b.n_particles.values[0] == a.n_particles.values[-1] == b.attrs["initial_particles"] > 50
        m = b.attrs["particle_density"] * math.pi * b.attrs["particle_diameter"] ** 3 / 6  # one grain, kg
        np.testing.assert_allclose(b.attrs["initial_mass"] + b.mass_in.values - b.mass_out.values,
                                   b.n_particles.values * m, rtol=1e-9)
        assert b.attrs["initial_state"] == str(other)
    cold_mean, cold_se = _mean_after(cold, 1.0)  # 3 s of steady state
    warm_mean, warm_se = _mean_after(warm, 1.0)  # 1 s, after 1 s to forget the start
    start_mean, start_se = _mean_after(other, 0.5)  # 2.5 s
    # the start is distinguishable from the cold steady state (measured ~5 standard errors apart),
    # so a warm run that remembered it would fail the comparison below
    assert abs(start_mean - cold_mean) > 3 * math.hypot(cold_se, start_se), (start_mean, cold_mean)
    # two independent time means of the same steady state: they differ by less than 3 combined
    # standard errors unless the start is remembered (false alarm ~0.3 % if the errors are right)
    assert abs(warm_mean - cold_mean) < 3 * math.hypot(cold_se, warm_se), (cold_mean, warm_mean, cold_se, warm_se)


def test_warm_start_from_a_different_tube_is_refused_before_any_step(tmp_path):
    source = tmp_path / "source.nc"
    run_case(Case.from_yaml(CASE, SHORT[:-4]), source)
    res = plugsim("run", str(CASE), "--out", str(tmp_path / "x.nc"), "--initial-state", str(source),
                  "--set", "tube.diameter=0.008", *sum((["--set", s] for s in SHORT[:-4]), []))
    assert res.returncode == 2 and "tube.diameter" in res.stderr
    assert not (tmp_path / "x.nc").exists()


def test_a_warm_start_across_orientation_or_tube_length_needs_warm_start_any(tmp_path):
    """Horizontal 2.1 cm -> vertical 1 cm: refused (exit 2, one line naming both keys, their values
    and run.warm_start_any) before any step; with run.warm_start_any=true it runs and logs one line
    with the grains kept and dropped."""
    source, out = tmp_path / "source.nc", tmp_path / "x.nc"
    run_case(Case.from_yaml(CASE, SHORT[:-4]), source)
    other = ["gas.enabled=false", "tube.length=0.01", "tube.inclination_deg=90", "run.duration=0.02"]
    args = ["run", str(CASE), "--out", str(out), "--initial-state", str(source), *sum((["--set", s] for s in other), [])]
    res = plugsim(*args)
    assert res.returncode == 2 and res.stderr.strip().splitlines() == [
        f"plugsim: error: initial state {source}: tube.inclination_deg = 0 there, 90 here (degree); "
        "tube.length = 0.021 there, 0.01 here (m); a warm start across tube length or inclination drops "
        "grains or turns gravity: --set run.warm_start_any=true accepts it"]
    assert not out.exists()
    res = plugsim(*args, "--set", "run.warm_start_any=true")
    assert res.returncode == 0, res.stderr
    with xr.open_dataset(source) as a, xr.open_dataset(out) as b:
        total = a.sizes["final_grain"]
        kept = int((a.final_position.values[:, 0] <= 0.01).sum())
        assert 0 < kept < total and b.attrs["initial_particles"] == kept
    changes = [line for line in res.stderr.splitlines() if "dropped" in line]
    assert changes == [f"plugsim: warm start from {source}: tube.inclination_deg = 0 there, 90 here (degree); "
                       f"tube.length = 0.021 there, 0.01 here (m): {kept} of {total} grains kept, "
                       f"{total - kept} beyond x = 0.01 m dropped"]
    assert "run.warm_start_any" in plugsim("keys").stdout


def test_progress_is_logged_when_there_is_no_terminal(caplog):
    """A workflow job (quiet, stderr to a file) logs progress lines at the wall-time interval."""
    from types import SimpleNamespace

    from engine.run import Progress

    sim = SimpleNamespace(n_particles=1234, pressure_drop=2500.0)
    with caplog.at_level("INFO", logger="plugsim"):
        every_update = Progress(total=1.0, quiet=True, initial=0.25, log_interval=0.0)
        every_update.update(sim, 0.25)
        every_update.update(sim, 0.25)
        rarely = Progress(total=1.0, quiet=True, log_interval=3600.0)
        rarely.update(sim, 0.5)
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2
    assert lines[0].startswith("t = 0.50 of at most 1.00 s simulated, 1234 grains, pressure drop 25.0 hPa")
    assert lines[1].startswith("t = 0.75 of at most 1.00 s")


def test_an_unresolved_tangential_dashpot_is_warned_and_recorded(tmp_path, caplog):
    """0.15 t_c at gamma_t = 0.02 N s/m: gamma_t dt/(m/7) = 0.93, above the 0.47 at which packed beds
    were measured converged; gamma_t = 0.01 (0.466) passes without a warning, and so does the implicit
    spin kick, which resolves the bulk bed at 0.93."""
    tiny = ["gas.enabled=false", "tube.length=0.021", "run.duration=0.01"]
    mass = 937.0 * math.pi * 0.0014**3 / 6
    for damping, implicit, warned in ((0.02, "false", True), (0.01, "false", False), (0.02, "true", False)):
        caplog.clear()
        out = tmp_path / f"g{damping}{implicit}.nc"
        with caplog.at_level("WARNING", logger="plugsim"):
            run_case(Case.from_yaml(CASE, [*tiny, f"particles.tangential_damping={damping}",
                                           f"numerics.implicit_spin={implicit}"]), out)
        with xr.open_dataset(out) as ds:
            ratio, dt = ds.attrs["dashpot_step_ratio"], ds.attrs["time_step"]
            assert ds.attrs["dashpot_resolved"] == (0 if warned else 1)
        assert ratio == pytest.approx(damping * dt * 7 / mass, rel=1e-12)
        messages = [r.getMessage() for r in caplog.records if "tangential dashpot" in r.getMessage()]
        assert bool(messages) == warned, messages
        if warned:
            assert f"{ratio:.2f} above 0.47" in messages[0] and "time_step_fraction" in messages[0]


def test_a_blocked_tube_is_a_result_reported_as_blocked(tmp_path):
    # the vertical column of test_enforced_feed_reports_a_blocked_tube (tests/engine/test_grains.py):
    # its piston overlap passes 0.15 % of d, so the enforced feed cannot push it
    case = Case().with_overrides(["gas.enabled=false", "tube.inclination_deg=90", "tube.length=0.02",
                                  "feed.max_overlap=0.0015", "run.duration=0.9"])
    out = run_case(case, tmp_path / "blocked.nc")
    with xr.open_dataset(out) as ds:
        assert ds.attrs["stop_reason"] == "blocked"
        assert 0 < ds.attrs["blocked_time"] < 0.9
        assert float(ds.time[-1]) <= ds.attrs["blocked_time"]
        # the piston was pushing the column up when it blocked
        assert ds.piston_force.values[-5:].mean() > 0


def test_a_column_the_feed_wedges_beyond_the_run_guard_is_blocked(tmp_path):
    # A column 100 times heavier than on Earth on soft contacts: at 0.85 s the piston lifts 418
    # grains (weight 0.56 N, piston 0.59 N) and a grain just above the inlet is pressed 0.21 d into
    # the wall by the column, while the piston's own contacts stay at 0.10 d: the feed's block test
    # (feed.max_overlap) does not see it, the run guard does, and the over-compression is the
    # feed's (pressed, still there at the frame's end, on the piston), not the step's.
    case = Case().with_overrides(["gas.enabled=false", "tube.inclination_deg=90", "tube.length=0.03",
                                  "physics.gravity=1000", "particles.stiffness=300",
                                  "particles.tangential_damping=0.005", "run.duration=1"])
    out = run_case(case, tmp_path / "wedged.nc")
    with xr.open_dataset(out) as ds:
        assert ds.attrs["stop_reason"] == "blocked"
        assert float(ds.max_overlap[-1]) > 0.2  # the run guard's bound, not the feed's
        assert float(ds.time[-1]) == ds.attrs["blocked_time"]
        weight = float(ds.n_particles[-1]) * case["particles.density"] * math.pi / 6 * 0.0014**3 * 1000
        assert float(ds.piston_force[-1]) > weight  # the piston carries the column


def test_a_collision_the_step_cannot_resolve_still_fails_beside_a_pushed_column():
    # Two grains meeting across the tube at 12 m/s beside the feed's column: at the largest step the
    # engine accepts (0.47 t_c) they move 0.24 d into each other in one step, where the resolved
    # collision (default step) peaks at 0.16 d: a time-step failure, not a blocked tube.
    peaks = {}
    for fraction in (0.47, 0.15):
        case = Case().with_overrides(["gas.enabled=false", "tube.length=0.03", "numerics.time_step_safety=1",
                                      f"numerics.time_step_fraction={fraction}"])
        sim = Simulation(case)
        d = 2 * sim.model.radius
        sim.advance(0.2)
        sim.reset_max_overlap()
        sim.add_particles([[0.02, -0.505 * d, 0], [0.02, 0.505 * d, 0]], [[0, 6, 0], [0, -6, 0]])
        sim.advance(case["output.interval"])
        peaks[fraction] = sim.max_overlap / d
        if fraction == 0.47:
            with pytest.raises(RunError, match="time step or stiffness is unsuitable"):
                _check_health(sim)
    assert peaks[0.47] > 0.2 > peaks[0.15]


def test_the_block_threshold_does_not_change_a_run_that_does_not_block(tmp_path):
    # feed.max_overlap only decides when a run ends as blocked: the piston never pauses, so a
    # run that never passes either threshold is bit-identical under both
    files = []
    for overlap in (0.05, 0.15):
        case = Case().with_overrides(["tube.inclination_deg=90", "tube.length=0.03", "gas.nodes_x=9",
                                      f"feed.max_overlap={overlap}", "run.duration=0.3"])
        files.append(run_case(case, tmp_path / f"overlap{overlap}.nc"))
    with xr.open_dataset(files[0]) as a, xr.open_dataset(files[1]) as b:
        assert a.attrs["stop_reason"] == b.attrs["stop_reason"] == "duration"
        assert float(a.n_particles[-1]) > 50  # the feed ran
        np.testing.assert_array_equal(a.final_position.values, b.final_position.values)
        np.testing.assert_array_equal(a.pressure_drop.values, b.pressure_drop.values)

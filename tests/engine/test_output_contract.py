"""A case file the engine writes holds exactly the contract's variables (analysis/contract.py), and
every analysis function reads it: a tiny run (130 grains, 0.03 s, a few seconds with the kernels
cached) of a dense plug thrown at 0.3 m/s down a 3.5 cm tube, which passes mid-tube as one slug."""

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import analysis
from analysis import contract, plots
from analysis.profiles import temperature_check
from analysis.snapshots import snapshot, slug_in_snapshots, time_average_by_height
from engine import Case
from engine.run import run_case

CASE = Path(__file__).resolve().parents[2] / "config" / "cases" / "horizontal.yaml"
D, R, L = 1.4e-3, 3.5e-3, 0.035  # grain diameter, tube radius, tube length (m)
MID = L / 2
RUN = ["tube.length=0.035", "gas.nodes_x=10", "feed.mass_flow_kg_h=0", "run.duration=0.03",
       "run.checkpoint_interval=0", "output.interval=0.005", "output.snapshots=true",
       "output.snapshot_x_min=0", "output.snapshot_x_max=0.035", "output.snapshot_interval=0.005",
       "output.tube_snapshot_interval=0.01"]


def plug(x0: float = 0.008, x1: float = 0.017) -> np.ndarray:
    """Grain centres on a face-centred cubic lattice (pitch 1.001 d) across the tube over x0..x1:
    130 grains, porosity 0.47 over the plug."""
    a = 1.001 * D * math.sqrt(2)
    g = np.arange(-4, 5)
    i, j, k = np.meshgrid(np.arange(int((x1 - x0) / a) + 2), g, g, indexing="ij")
    cells = np.stack([i.ravel(), j.ravel(), k.ravel() + 0.25], axis=1)
    basis = np.array([(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)])
    pos = (cells[:, None, :] + basis[None]).reshape(-1, 3) * a
    pos[:, 0] += x0
    return pos[(pos[:, 0] <= x1) & (np.hypot(pos[:, 1], pos[:, 2]) <= R - D / 2 - 1e-6)]


@pytest.fixture(scope="module")
def case_file(tmp_path_factory):
    """The run's case file, loaded; its warm start is a file of the contract's final state."""
    folder = tmp_path_factory.mktemp("contract")
    pos = plug()
    vel = np.zeros_like(pos)
    vel[:, 0] = 0.3
    values = dict(zip(contract.FINAL, (pos, vel, np.zeros_like(pos))))
    xr.Dataset({name: var.entry(values[name]) for name, var in contract.FINAL.items()},
               attrs={"tube_length": L, "tube_diameter": 2 * R, "particle_diameter": D,
                      "particle_density": 937.0, "inclination_deg": 0.0}).to_netcdf(folder / "plug.nc")
    out = run_case(Case.from_yaml(CASE, RUN), folder / "case.nc", initial_state=folder / "plug.nc")
    return analysis.open_case(out)


def test_the_file_holds_exactly_the_contract(case_file):
    ds = case_file
    assert set(ds.variables) == set(contract.VARIABLES)
    for name, var in contract.VARIABLES.items():
        assert ds[name].dims == var.dims, name
        assert ds[name].dtype.kind == np.dtype(var.dtype).kind, name
        if ds[name].dtype.kind != "U":
            assert ds[name].dtype == np.dtype(var.dtype), name
        attrs = {k: v for k, v in ds[name].attrs.items() if k != "digest"}  # restart_state's own
        assert attrs == var.attrs, name


EMPTY_SLICES = pytest.mark.filterwarnings("ignore:Mean of empty slice")  # one slug: NaN beyond its grains


@EMPTY_SLICES
def test_the_analysis_reads_the_run(case_file):
    ds = case_file
    geo = analysis.geometry(ds)
    assert geo.tube_length == L and analysis.config(ds)["tube.length"] == L
    slugs = analysis.detect(ds)
    assert slugs["slug_id"].nunique() == 1 and len(slugs) >= 3
    assert ((slugs["x_center"] > 0) & (slugs["x_center"] < L)).all()
    assert ((slugs["length"] > 0) & (slugs["length"] < L)).all()  # m
    assert slugs["max_velocity"].between(0.1, 1.0).all()  # m/s: the plug was thrown at 0.3 m/s
    assert slugs["min_porosity"].between(0.3, 0.6).all()
    assert len(analysis.tracks(slugs)) == 1

    stats = analysis.slug_statistics(slugs, [MID])
    assert stats["n_slugs"].tolist() == [1]
    assert stats["rate"].iloc[0] == pytest.approx(1 / stats.attrs["duration"])  # 1/s
    assert 0 < stats["length_mean"].iloc[0] < L

    summary = analysis.case_summary(ds, slugs=slugs)
    assert isinstance(summary["regime"], str) and summary["stop_reason"] == "duration"
    for key in ("pressure_drop", "dense_fraction", "slug_fraction", "slug_rate", "slug_velocity",
                "slug_length", "n_particles"):
        assert isinstance(summary[key], float) and math.isfinite(summary[key]), key
    assert summary["pressure_drop"] > 0  # Pa/m: the gas pushes through the plug
    assert summary["n_particles"] == len(plug())
    table = analysis.sweep_table([ds])
    assert len(table) == 1 and table.attrs["units"]["pressure_drop"] == "Pa m-1"
    est = analysis.mean_error(ds["pressure_drop"].values)
    assert math.isfinite(est.mean) and est.mean > 0

    selection = analysis.select_slugs(slugs, position=MID)
    assert len(selection) == 1
    profile = analysis.slug_profiles(ds, selection, extent=(-10.0, 10.0))
    for name in contract.PROFILE_FIELDS:
        assert profile[name].attrs["units"] == ds[name].attrs["units"] == contract.FIELDS[name].units
        assert profile[f"{name}_sem"].attrs["units"] == ds[name].attrs["units"]
        assert np.isfinite(profile[name].values).any(), name
    assert profile["resting_layer_stress"].attrs["units"] == ds["wall_stress"].attrs["units"]
    assert np.nanmin(profile["porosity"].values) < analysis.THRESHOLD
    assert math.isfinite(temperature_check(profile, vertical=False)["peak"])


def test_the_snapshot_analysis_reads_the_run(case_file, tmp_path):
    ds = case_file
    slugs = analysis.detect(ds)
    t, pos, vel = snapshot(ds, 0)
    assert t == 0.0 and pos.shape == vel.shape == (len(plug()), 3)
    sections = analysis.cross_section_series(ds)
    assert sections.sizes["snapshot_time"] == ds.sizes["snapshot_time"]
    # a volume fraction of the packed plug: some pixel more than half full; a pixel inside the lens
    # of two touching grains counts both (overlaps up to 0.2 d are 0.28 mm deep, pixels 0.18 mm
    # wide), so its fraction may exceed 1 but stays below the 2 of two grains
    assert 0.5 < float(sections["volume_fraction"].max()) < 2.0
    heights = analysis.velocity_height_series(ds)
    unit = ds["snapshot_velocity"].attrs["units"]
    assert heights["velocity"].attrs["units"] == unit
    assert time_average_by_height(heights)["velocity"].attrs["units"] == unit
    assert np.nanmax(heights["velocity"].values) > 0.1  # m/s
    radial = analysis.averaged_radial_profile(ds, analysis.select_slugs(slugs, position=MID), slugs)
    assert radial["velocity"].attrs["units"] == unit
    assert np.isfinite(radial["porosity"].values).any()
    assert slug_in_snapshots(ds, slugs) is not None


@EMPTY_SLICES
def test_the_plots_label_the_contract_variables(case_file):
    ds = case_file
    slugs = analysis.detect(ds)
    profile = analysis.slug_profiles(ds, analysis.select_slugs(slugs, position=MID), extent=(-10.0, 10.0))
    for name in contract.PROFILE_FIELDS:
        fig = plots.slug_profile(profile, name)
        assert fig.axes[0].get_ylabel() == contract.FIELDS[name].label
        assert not plots.undrawn_axes(fig)
    image = plots.porosity_image(ds, vmin=0.4)
    assert image.axes[1].get_ylabel() == contract.FIELDS["porosity"].label  # the colour bar
    stats = analysis.slug_statistics(slugs, [MID])
    assert not plots.undrawn_axes(plots.slug_rate(pd.DataFrame(stats)))

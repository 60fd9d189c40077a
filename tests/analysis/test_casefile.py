"""Reading the case-file contract: geometry, configuration, time axis."""

import math

import numpy as np
import pytest

from analysis import CaseFileError, config, geometry
from analysis.casefile import run_cpu_seconds, seconds, slice_faces

from . import synthetic as S


def test_geometry_from_flat_attributes_and_gravity_from_config():
    ds = S.build([], 0.05, inclination_deg=90.0, **{"physics.gravity": 3.7})
    geo = geometry(ds)
    assert (geo.tube_length, geo.tube_diameter, geo.particle_diameter) == (S.L_TUBE, S.D_TUBE, S.D_GRAIN)
    assert geo.vertical and geo.axis_name == "z"
    assert geo.gravity == 3.7
    assert geo.cross_section == pytest.approx(math.pi * 0.0035**2, rel=1e-12)
    assert geo.particle_volume == pytest.approx(math.pi / 6 * 0.0014**3, rel=1e-12)


def test_missing_geometry_attribute_is_named():
    ds = S.build([], 0.05)
    del ds.attrs["particle_diameter"]
    with pytest.raises(CaseFileError, match="particle_diameter"):
        geometry(ds)


def test_missing_variable_is_named():
    from analysis import detect
    ds = S.build([], 0.05).drop_vars("velocity")
    with pytest.raises(CaseFileError, match="velocity"):
        detect(ds)


def test_config_yaml_flattens_to_dotted_keys():
    cfg = config(S.build([], 0.05, **{"gas.superficial_velocity": 2.5}))
    assert cfg["gas.superficial_velocity"] == 2.5
    assert cfg["feed.mass_flow_kg_h"] == 2.49


def test_time_round_trips_as_float_seconds(default_case):
    t = seconds(default_case["time"].values)
    assert t.dtype == np.float64
    assert np.allclose(np.diff(t), 0.01, atol=1e-12)
    assert seconds(np.array([1500], dtype="timedelta64[ms]"))[0] == 1.5


def test_slice_faces_bound_the_tube():
    faces = slice_faces(S.slice_centres())
    assert faces[0] == pytest.approx(0.0, abs=1e-15)
    assert faces[-1] == pytest.approx(S.L_TUBE, rel=1e-12)
    assert np.allclose(np.diff(faces), S.DX, rtol=1e-12)


def test_run_cpu_seconds_counts_every_part_or_says_unknown():
    # a file of a resumed run: the total of its parts, not its last part
    assert run_cpu_seconds({"cpu_time_s": 5.0, "cpu_time_total_s": 12.0, "resumed": 1}) == 12.0
    # a file written before the total was recorded: its one part when it ran in one part
    assert run_cpu_seconds({"cpu_time_s": 5.0, "resumed": 0}) == 5.0
    # ... and unknown when it was resumed (its last part alone would undercount)
    assert math.isnan(run_cpu_seconds({"cpu_time_s": 5.0, "resumed": 1}))
    assert math.isnan(run_cpu_seconds({"cpu_time_s": 5.0}))

"""plugsim analysis: case files (NetCDF) in, the papers' numbers and pictures out.

Pure functions on xarray/pandas; no engine import. SI units throughout (plots use the papers'
units: hPa/m, cP, kg/h).
"""

from .casefile import CaseFileError, Geometry, config, geometry, open_case
from .curves import case_summary, regime, slug_fractions, steady_pressure_drop, sweep_table
from .profiles import resting_layer_stress, select_slugs, slug_profiles
from .slugs import THRESHOLD, detect, tracks
from .snapshots import (averaged_radial_profile, cross_section, cross_section_series,
                        radial_profile, snapshot, velocity_by_height, velocity_height_series)
from .statistics import crossings, describe, passages, slug_statistics
from .timeseries import MeanError, mean_error, mser_start

__all__ = [
    "CaseFileError", "Geometry", "THRESHOLD", "MeanError", "averaged_radial_profile",
    "case_summary", "config", "cross_section", "crossings", "cross_section_series", "describe", "detect",
    "geometry", "mean_error", "mser_start", "open_case", "passages", "radial_profile", "regime",
    "resting_layer_stress", "select_slugs", "slug_fractions", "slug_profiles", "slug_statistics",
    "snapshot", "steady_pressure_drop", "sweep_table", "tracks", "velocity_by_height",
    "velocity_height_series",
]

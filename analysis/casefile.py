"""Reading case files (NetCDF4, design.md "Contracts"): geometry, configuration, time axis; the
variables a function needs, with the units the contract declares (analysis/contract.py).

Everything here is SI: lengths in m, densities in kg/m3, times in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import xarray as xr
import yaml

from .contract import VARIABLES

GEOMETRY_ATTRS = ("tube_length", "tube_diameter", "particle_diameter", "particle_density",
                  "inclination_deg")
STANDARD_GRAVITY = 9.81  # m/s2, used when the configuration does not give physics.gravity


class CaseFileError(ValueError):
    """A case file that does not follow the contract (missing variable or attribute)."""


@dataclass(frozen=True)
class Geometry:
    """Tube and grain geometry of a case (SI units)."""

    tube_length: float  # m
    tube_diameter: float  # m
    particle_diameter: float  # m
    particle_density: float  # kg/m3
    inclination_deg: float  # 0 horizontal, 90 vertical
    gravity: float = STANDARD_GRAVITY  # m/s2

    @property
    def tube_radius(self) -> float:
        """Tube radius R (m)."""
        return self.tube_diameter / 2

    @property
    def cross_section(self) -> float:
        """Tube cross-section A = pi D^2 / 4 (m2)."""
        return math.pi * self.tube_diameter**2 / 4

    @property
    def particle_volume(self) -> float:
        """Grain volume V_p = pi d^3 / 6 (m3)."""
        return math.pi * self.particle_diameter**3 / 6

    @property
    def vertical(self) -> bool:
        """True when the tube is closer to vertical than to horizontal (papers' "plug" wording)."""
        return self.inclination_deg >= 45.0

    @property
    def axis_name(self) -> str:
        """Papers' name of the axial coordinate: z (height) when vertical, x when horizontal."""
        return "z" if self.vertical else "x"


def geometry(ds: xr.Dataset) -> Geometry:
    """Geometry from the flat global attributes; gravity from config_yaml (physics.gravity) if present."""
    missing = [name for name in GEOMETRY_ATTRS if name not in ds.attrs]
    if missing:
        raise CaseFileError(
            f"case file lacks global attribute(s) {', '.join(missing)} "
            f"(the contract requires {', '.join(GEOMETRY_ATTRS)})")
    values = {name: float(ds.attrs[name]) for name in GEOMETRY_ATTRS}
    cfg = config(ds) if "config_yaml" in ds.attrs else {}
    values["gravity"] = float(cfg.get("physics.gravity", STANDARD_GRAVITY))
    return Geometry(**values)


def flatten(nested: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested mapping to dotted keys: {"gas": {"viscosity": 1}} -> {"gas.viscosity": 1}."""
    flat: dict[str, Any] = {}
    for key, value in nested.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + "."))
        else:
            flat[name] = value
    return flat


def config(ds: xr.Dataset) -> dict[str, Any]:
    """The case configuration (global attribute config_yaml) as a flat dict of dotted keys."""
    if "config_yaml" not in ds.attrs:
        raise CaseFileError("case file lacks the global attribute config_yaml (the case configuration)")
    nested = yaml.safe_load(ds.attrs["config_yaml"]) or {}
    if not isinstance(nested, Mapping):
        raise CaseFileError("global attribute config_yaml is not a YAML mapping")
    return flatten(nested)


def run_cpu_seconds(attrs: Mapping[str, Any]) -> float:
    """CPU seconds of all the parts of the run that wrote a case file, from its attributes:
    `cpu_time_total_s`, or for a file without it (an older engine's) `cpu_time_s` when the run was
    not resumed; NaN when unknown (`cpu_time_s` alone counts the last part only)."""
    if "cpu_time_total_s" in attrs:
        return float(attrs["cpu_time_total_s"])
    if int(attrs.get("resumed", 1)) == 0:
        return float(attrs.get("cpu_time_s", math.nan))
    return math.nan


def require(ds: xr.Dataset, *names: str) -> None:
    """Raise CaseFileError naming every variable of `names` that the case file lacks, or that
    carries other units than the contract declares (a variable without a units attribute passes)."""
    missing = [name for name in names if name not in ds.variables]
    if missing:
        raise CaseFileError(f"case file lacks variable(s) {', '.join(missing)}")
    other = [f"{name} in {ds[name].attrs['units']!r}, not {VARIABLES[name].units!r}" for name in names
             if name in VARIABLES and "units" in ds[name].attrs
             and ds[name].attrs["units"] != VARIABLES[name].units]
    if other:
        raise CaseFileError(f"case file variable(s) in other units than the contract's: {'; '.join(other)}")


def seconds(values: Any) -> np.ndarray:
    """Times as float64 seconds (accepts floats and timedelta64, in case a reader decoded them)."""
    arr = np.asarray(values)
    if np.issubdtype(arr.dtype, np.timedelta64):
        return arr / np.timedelta64(1, "s")
    return arr.astype(np.float64)


def slice_faces(x: np.ndarray) -> np.ndarray:
    """Faces of the slices around the slice centres x (m): midpoints, ends extrapolated by half a slice."""
    x = np.asarray(x, dtype=np.float64)
    if x.size < 2:
        raise CaseFileError("need at least two slices along x")
    mid = (x[1:] + x[:-1]) / 2
    return np.concatenate([[x[0] - (x[1] - x[0]) / 2], mid, [x[-1] + (x[-1] - x[-2]) / 2]])


def open_case(path: str | Path) -> xr.Dataset:
    """Read a case file fully into memory and close it (NetCDF4 via xarray)."""
    with xr.open_dataset(path) as ds:
        return ds.load()

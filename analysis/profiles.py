"""Averaged slug profiles at a position (H12-H16, V13-V17).

Slugs passing the position with length and velocity near the mean are selected; the slice fields
of each, in the frame where it passes, are aligned on its centre of mass and averaged against
dx/d (d: grain diameter; positive dx points downstream, towards the slug front).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import xarray as xr

from .casefile import geometry, require, seconds
from .contract import PROFILE_FIELDS, VARIABLES
from .slugs import PAPER_LENGTH
from .statistics import passages

POSITION = 0.26  # m, papers: profiles at mid-tube
FIELDS = PROFILE_FIELDS  # the slice fields the papers average (analysis/contract.py)
# Half-widths of the selection bands around the mean (papers): horizontal §3.2 L = 0.05 +- 0.03 m,
# u = 0.29 +- 0.1 m/s; vertical §4.2 L = 0.024 +- 0.01 m, u = 0.16 +- 0.02 m/s. The lengths are
# the papers' slug length, with the smooth ends (slugs.PAPER_LENGTH).
PAPER_BANDS = {"horizontal": {"length": 0.03, "velocity": 0.1},
               "vertical": {"length": 0.01, "velocity": 0.02}}
# Top of the granular-temperature axis of the papers' averaged-profile figure (J per grain):
# V Fig. 17 runs 0 .. 3.5e-9 J; the text extraction of H Fig. 16 keeps no axis (no check there).
PAPER_TEMPERATURE_AXIS = {"vertical": 3.5e-9, "horizontal": None}
FAR_OUTSIDE = 10.0  # a peak more than ten times the axis top is flagged (another order of magnitude)


def select_slugs(slugs: pd.DataFrame, position: float = POSITION, length_band: float | None = None,
                 velocity_band: float | None = None, length_center: float | None = None,
                 velocity_center: float | None = None, velocity_column: str = "max_velocity",
                 t_start: float | None = None, t_end: float | None = None,
                 length_column: str = PAPER_LENGTH) -> pd.DataFrame:
    """Slugs passing `position` (m) whose length and velocity lie within a band of the mean
    (H §3.2, V §4.2).

    Bands (half-widths, m and m/s) default to the papers' for the tube orientation; centres
    default to the mean over all slugs passing the position. The velocity is `velocity_column`
    (default the maximal granular velocity, as in the papers), the length `length_column`
    (default the length with the smooth ends, the papers' reading). One row per slug (the frame
    where it passes); attrs record the centres, bands and columns used.
    """
    bands = PAPER_BANDS["vertical" if slugs.attrs.get("vertical") else "horizontal"]
    length_band = bands["length"] if length_band is None else length_band
    velocity_band = bands["velocity"] if velocity_band is None else velocity_band
    passing = passages(slugs, [position], t_start, t_end)
    if length_center is None:
        length_center = float(passing[length_column].mean())
    if velocity_center is None:
        velocity_center = float(passing[velocity_column].mean())
    keep = ((passing[length_column] - length_center).abs() <= length_band) & (
        (passing[velocity_column] - velocity_center).abs() <= velocity_band)
    out = passing[keep].reset_index(drop=True)
    out.attrs.update(position=position, length_center=length_center, length_band=length_band,
                     velocity_center=velocity_center, velocity_band=velocity_band,
                     velocity_column=velocity_column, length_column=length_column,
                     n_passing=len(passing))
    return out


def resting_layer_stress(porosity, ds: xr.Dataset):
    """Wall stress (Pa) of the grains' weight resting on the wall: rho_s (1 - phi) g cos(theta) D / 4.

    The weight of a slice, rho_s (1 - phi) A dx g cos(theta), spread over its wall area pi D dx
    (H15's dotted curve). Zero in a vertical tube.
    """
    geo = geometry(ds)
    g_normal = geo.gravity * math.cos(math.radians(geo.inclination_deg))
    return geo.particle_density * (1.0 - np.asarray(porosity)) * g_normal * geo.tube_diameter / 4


def slug_profiles(ds: xr.Dataset, selection: pd.DataFrame, fields=FIELDS,
                  extent: tuple[float, float] = (-60.0, 40.0), step: float | None = None) -> xr.Dataset:
    """Average slice fields over the selected slugs against dx/d (grain diameters from the centre).

    Each slug's fields in its frame are linearly interpolated to the grid dx/d in `extent`
    (step: one slice width in d by default) and averaged; `<field>_sem` is std/sqrt(n) over slugs
    (ddof=1), `n_slugs` the number of slugs covering each point (the tube ends cut some).
    `resting_layer_stress` (Pa) is computed from the mean porosity (see resting_layer_stress).
    """
    require(ds, *fields)
    geo = geometry(ds)
    d = geo.particle_diameter
    x = np.asarray(ds["x"].values, dtype=np.float64)
    step = float(np.mean(np.diff(x))) / d if step is None else step
    grid = np.arange(extent[0], extent[1] + step / 2, step)
    frames = selection["frame"].to_numpy(dtype=np.int64)
    centers = selection["x_center"].to_numpy(dtype=np.float64)
    out = xr.Dataset(coords={"dx_d": ("dx_d", grid, {"units": "1",
                                                     "long_name": "distance from the centre of mass / d"})})
    count = None
    for name in fields:
        data = ds[name].transpose("time", "x").values[frames]  # (slug, x)
        stack = np.full((len(frames), grid.size), np.nan)
        for k in range(len(frames)):
            ok = np.isfinite(data[k])
            stack[k] = np.interp(grid, (x[ok] - centers[k]) / d, data[k][ok], left=np.nan, right=np.nan)
        n = np.sum(np.isfinite(stack), axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.nanmean(stack, axis=0) if len(frames) else np.full(grid.size, np.nan)
            sem = np.nanstd(stack, axis=0, ddof=1) / np.sqrt(n) if len(frames) > 1 else np.full(
                grid.size, np.nan)
        sem = np.where(n > 1, sem, np.nan)
        units = VARIABLES[name].units if name in VARIABLES else ds[name].attrs.get("units", "")
        out[name] = ("dx_d", mean, {"units": units, "long_name": f"mean {name}"})
        out[f"{name}_sem"] = ("dx_d", sem, {"units": units, "long_name": f"standard error of the mean {name}"})
        count = n if count is None else np.minimum(count, n)
    out["n_slugs"] = ("dx_d", count if count is not None else np.zeros(grid.size, int))
    if "porosity" in fields:
        out["resting_layer_stress"] = ("dx_d", resting_layer_stress(out["porosity"].values, ds),
                                       {"units": "Pa",
                                        "long_name": "weight of the resting layer per wall area"})
    out.attrs.update({k: v for k, v in selection.attrs.items() if np.isscalar(v)})
    out.attrs.update(n_selected=len(frames), particle_diameter=d,
                     times=np.asarray(seconds(selection["time"].to_numpy())),
                     slug_ids=selection["slug_id"].to_numpy(dtype=np.int64))
    return out


def temperature_check(profile: xr.Dataset, vertical: bool) -> dict:
    """Peak of the averaged granular temperature (J per grain) against the top of the papers' axis.

    The engine's granular temperature is the papers' (V §4.3, H §3.3): the mean kinetic energy of
    a slice's grains minus that of their centre-of-mass motion, per grain, 0.5 m (<v^2> - <v>^2),
    in J. Returns peak (J), axis_top (J, None where the paper's axis is unknown), ratio
    peak / axis_top and far_outside (ratio above FAR_OUTSIDE).
    """
    top = PAPER_TEMPERATURE_AXIS["vertical" if vertical else "horizontal"]
    values = profile["granular_temperature"].values if "granular_temperature" in profile else []
    peak = float(np.nanmax(values)) if np.isfinite(values).any() else float("nan")
    ratio = peak / top if top else float("nan")
    return {"peak": peak, "axis_top": top, "ratio": ratio,
            "far_outside": bool(np.isfinite(ratio) and ratio > FAR_OUTSIDE)}

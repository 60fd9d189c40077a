"""Cross-section and radial profiles from grain snapshots (H17-H19, V18-V19).

Snapshots are stored as a CF contiguous ragged array: snapshot_count(snapshot_time) grains per
snapshot, then snapshot_position(grain, xyz) and snapshot_velocity(grain, xyz) (m, m/s; axial x
first, then y, z across; tube axis at y = z = 0; height is z in a horizontal tube).

Grains are split into volume pieces (a lattice of points in the sphere, each carrying an equal share
of the grain volume), so every binning below distributes exactly each grain's volume: the binned
grain volume sums to the volume of the grains (or grain parts) inside the sampled region.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import xarray as xr

from .casefile import CaseFileError, geometry, require, seconds

N_PER_DIAMETER = 12  # lattice points across a grain: 912 pieces, pieces 0.12 mm for d = 1.4 mm
N_IMAGE = 24  # finer for cross-section images (7 200 pieces), against aliasing with the pixels


def ball_points(n_per_diameter: int = N_PER_DIAMETER) -> np.ndarray:
    """Points of a cubic lattice inside the unit ball, symmetric about the centre, (m, 3)."""
    c = (np.arange(n_per_diameter) + 0.5) * 2.0 / n_per_diameter - 1.0
    p = np.stack(np.meshgrid(c, c, c, indexing="ij"), axis=-1).reshape(-1, 3)
    return p[np.einsum("ij,ij->i", p, p) <= 1.0]


def pieces(positions: np.ndarray, particle_diameter: float, velocities: np.ndarray | None = None,
           n_per_diameter: int = N_PER_DIAMETER):
    """Volume pieces of the grains: positions (m, (n*m, 3)), axial velocity (m/s), piece volume (m3)."""
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    unit = ball_points(n_per_diameter) * (particle_diameter / 2)
    pts = (pos[:, None, :] + unit[None, :, :]).reshape(-1, 3)
    weight = math.pi * particle_diameter**3 / 6 / len(unit)
    vel = None
    if velocities is not None:
        vel = np.repeat(np.asarray(velocities, dtype=np.float64).reshape(-1, 3)[:, 0], len(unit))
    return pts, vel, weight


def _near(positions: np.ndarray, lo: float, hi: float, radius: float) -> np.ndarray:
    """Mask of grains that may reach into lo <= x < hi."""
    x = positions[:, 0]
    return (x + radius >= lo) & (x - radius < hi)


def _mean_velocity(volume: np.ndarray, momentum: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(volume > 0, momentum / np.where(volume > 0, volume, 1.0), np.nan)


def cross_section(positions, x0: float, tube_radius: float, particle_diameter: float,
                  thickness: float | None = None, pixels: int = 40,
                  n_per_diameter: int = N_IMAGE) -> xr.Dataset:
    """Grain volume fraction over the cross-section (y, z) in the slab |x - x0| < thickness / 2.

    thickness defaults to one grain diameter. Variables: grain_volume (m3 per pixel),
    pixel_volume (m3 of the pixel inside the tube), volume_fraction (NaN outside the tube).
    """
    thickness = particle_diameter if thickness is None else thickness
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    lo, hi = x0 - thickness / 2, x0 + thickness / 2
    pts, _, w = pieces(pos[_near(pos, lo, hi, particle_diameter / 2)], particle_diameter,
                       n_per_diameter=n_per_diameter)
    pts = pts[(pts[:, 0] >= lo) & (pts[:, 0] < hi)]
    size = 2 * tube_radius / pixels
    iy = np.clip(((pts[:, 1] + tube_radius) / size).astype(np.int64), 0, pixels - 1)
    iz = np.clip(((pts[:, 2] + tube_radius) / size).astype(np.int64), 0, pixels - 1)
    volume = np.bincount(iz * pixels + iy, minlength=pixels * pixels).reshape(pixels, pixels) * w
    centres = -tube_radius + (np.arange(pixels) + 0.5) * size
    pixel_volume = _area_in_tube(centres, size, tube_radius) * thickness
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(pixel_volume > 0, volume / pixel_volume, np.nan)
    return xr.Dataset(
        {"grain_volume": (("z", "y"), volume, {"units": "m3"}),
         "pixel_volume": (("z", "y"), pixel_volume, {"units": "m3"}),
         "volume_fraction": (("z", "y"), fraction, {"units": "1",
                                                    "long_name": "grain volume fraction"})},
        coords={"y": ("y", centres, {"units": "m"}), "z": ("z", centres, {"units": "m"})},
        attrs={"x0": x0, "thickness": thickness})


def _area_in_tube(centres: np.ndarray, size: float, radius: float, sub: int = 16) -> np.ndarray:
    """Area (m2) of each square pixel (rows z, columns y) inside the circle of the tube."""
    offs = (np.arange(sub) + 0.5) / sub * size - size / 2
    fine = (centres[:, None] + offs[None, :]).ravel()
    inside = (fine[:, None] ** 2 + fine[None, :] ** 2) <= radius**2
    n = centres.size
    return inside.reshape(n, sub, n, sub).sum(axis=(1, 3)) * (size / sub) ** 2


def velocity_by_height(positions, velocities, x_range: tuple[float, float], tube_radius: float,
                       particle_diameter: float, bin_width: float | None = None,
                       n_per_diameter: int = N_PER_DIAMETER) -> xr.Dataset:
    """Volume-weighted mean axial grain velocity (m/s) in horizontal layers of height z (m).

    Grain volume with x in x_range is binned by height z into layers of bin_width (default d/4)
    from -R to R. Variables: grain_volume (m3), velocity (m/s, NaN in empty layers).
    """
    bin_width = particle_diameter / 4 if bin_width is None else bin_width
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    near = _near(pos, x_range[0], x_range[1], particle_diameter / 2)
    pts, vel, w = pieces(pos[near], particle_diameter, np.asarray(velocities).reshape(-1, 3)[near],
                         n_per_diameter)
    inside = (pts[:, 0] >= x_range[0]) & (pts[:, 0] < x_range[1])
    pts, vel = pts[inside], vel[inside]
    n_bins = int(math.ceil(2 * tube_radius / bin_width - 1e-9))
    k = np.clip(((pts[:, 2] + tube_radius) / bin_width).astype(np.int64), 0, n_bins - 1)
    volume = np.bincount(k, minlength=n_bins) * w
    momentum = np.bincount(k, weights=vel, minlength=n_bins) * w
    centres = -tube_radius + (np.arange(n_bins) + 0.5) * bin_width
    return xr.Dataset(
        {"grain_volume": ("height", volume, {"units": "m3"}),
         "velocity": ("height", _mean_velocity(volume, momentum),
                      {"units": "m s-1", "long_name": "mean axial grain velocity"})},
        coords={"height": ("height", centres, {"units": "m", "long_name": "height z"})},
        attrs={"x_start": x_range[0], "x_end": x_range[1], "bin_width": bin_width})


def radial_profile(positions, velocities, x_center: float, tube_radius: float,
                   particle_diameter: float, ring_width: float | None = None,
                   height: float | None = None, n_per_diameter: int = N_PER_DIAMETER) -> xr.Dataset:
    """Porosity and mean axial velocity in rings around the axis (V18/V19).

    Rings ring_width wide (default 0.25 d) in the window |x - x_center| < height / 2 (default
    1.5 d). Grain volume reaching past the wall (contact overlap) counts in the outermost ring.
    Variables: grain_volume, ring_volume (m3), porosity (1 - grain/ring volume), velocity (m/s).
    """
    d = particle_diameter
    ring_width = 0.25 * d if ring_width is None else ring_width
    height = 1.5 * d if height is None else height
    lo, hi = x_center - height / 2, x_center + height / 2
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    near = _near(pos, lo, hi, d / 2)
    pts, vel, w = pieces(pos[near], d, np.asarray(velocities).reshape(-1, 3)[near], n_per_diameter)
    inside = (pts[:, 0] >= lo) & (pts[:, 0] < hi)
    pts, vel = pts[inside], vel[inside]
    n_rings = int(math.ceil(tube_radius / ring_width - 1e-9))
    r = np.hypot(pts[:, 1], pts[:, 2])
    k = np.minimum((r / ring_width).astype(np.int64), n_rings - 1)
    volume = np.bincount(k, minlength=n_rings) * w
    momentum = np.bincount(k, weights=vel, minlength=n_rings) * w
    edges = np.minimum(np.arange(n_rings + 1) * ring_width, tube_radius)
    ring_volume = math.pi * np.diff(edges**2) * height
    return xr.Dataset(
        {"grain_volume": ("r", volume, {"units": "m3"}),
         "ring_volume": ("r", ring_volume, {"units": "m3"}),
         "porosity": ("r", 1.0 - volume / ring_volume, {"units": "1"}),
         "velocity": ("r", _mean_velocity(volume, momentum),
                      {"units": "m s-1", "long_name": "mean axial grain velocity"})},
        coords={"r": ("r", (edges[:-1] + edges[1:]) / 2, {"units": "m", "long_name": "ring centre radius"})},
        attrs={"x_center": x_center, "ring_width": ring_width, "height": height})


# --- case-file level -------------------------------------------------------------------------

def snapshot_times(ds: xr.Dataset) -> np.ndarray:
    """Times of the grain snapshots (s); CaseFileError when the file has none."""
    require_snapshots(ds)
    return seconds(ds["snapshot_time"].values)


def require_snapshots(ds: xr.Dataset) -> None:
    """Raise CaseFileError unless the file holds the snapshot ragged array."""
    try:
        require(ds, "snapshot_count", "snapshot_position", "snapshot_velocity", "snapshot_time")
    except CaseFileError as err:
        raise CaseFileError(f"no grain snapshots: {err}") from None


def snapshot(ds: xr.Dataset, k: int) -> tuple[float, np.ndarray, np.ndarray]:
    """Snapshot k: time (s), positions (n, 3) m, velocities (n, 3) m/s."""
    times = snapshot_times(ds)
    count = np.asarray(ds["snapshot_count"].values, dtype=np.int64)
    start = int(count[:k].sum())
    sl = slice(start, start + int(count[k]))
    pos = np.asarray(ds["snapshot_position"].values[sl], dtype=np.float64)
    vel = np.asarray(ds["snapshot_velocity"].values[sl], dtype=np.float64)
    return float(times[k]), pos, vel


def cross_section_series(ds: xr.Dataset, x0: float | None = None, thickness: float | None = None,
                         pixels: int = 40, n_per_diameter: int = N_IMAGE) -> xr.Dataset:
    """cross_section for every snapshot at x0 (default half the tube length), dims (snapshot_time, z, y)."""
    geo = geometry(ds)
    x0 = geo.tube_length / 2 if x0 is None else x0
    frames = []
    for k in range(len(snapshot_times(ds))):
        _, pos, _ = snapshot(ds, k)
        frames.append(cross_section(pos, x0, geo.tube_radius, geo.particle_diameter, thickness,
                                    pixels, n_per_diameter))
    return xr.concat(frames, dim=pd.Index(snapshot_times(ds), name="snapshot_time"),
                     data_vars=["grain_volume", "volume_fraction"], coords="minimal",
                     compat="override", join="exact")


def velocity_height_series(ds: xr.Dataset, x0: float | None = None, length: float | None = None,
                           bin_width: float | None = None,
                           n_per_diameter: int = N_PER_DIAMETER) -> xr.Dataset:
    """velocity_by_height for every snapshot in |x - x0| < length / 2 (defaults: L/2 and d)."""
    geo = geometry(ds)
    x0 = geo.tube_length / 2 if x0 is None else x0
    length = geo.particle_diameter if length is None else length
    frames = []
    for k in range(len(snapshot_times(ds))):
        _, pos, vel = snapshot(ds, k)
        frames.append(velocity_by_height(pos, vel, (x0 - length / 2, x0 + length / 2),
                                         geo.tube_radius, geo.particle_diameter, bin_width,
                                         n_per_diameter))
    return xr.concat(frames, dim=pd.Index(snapshot_times(ds), name="snapshot_time"),
                     data_vars="all", coords="minimal", compat="override", join="exact")


def time_average_by_height(series: xr.Dataset, t_range: tuple[float, float] | None = None) -> xr.Dataset:
    """Volume-weighted time average of a velocity_height_series over t_range (s)."""
    if t_range is not None:
        series = series.sel(snapshot_time=slice(*t_range))
    volume = series["grain_volume"].sum("snapshot_time")
    momentum = (series["grain_volume"] * series["velocity"].fillna(0.0)).sum("snapshot_time")
    out = xr.Dataset({"grain_volume": volume,
                      "velocity": ("height", _mean_velocity(volume.values, momentum.values),
                                   {"units": "m s-1"})})
    return out


def averaged_radial_profile(ds: xr.Dataset, selection: pd.DataFrame, slugs: pd.DataFrame,
                            ring_width: float | None = None, height: float | None = None,
                            n_per_diameter: int = N_PER_DIAMETER) -> xr.Dataset:
    """Radial porosity and velocity through the averaged slug (V18/V19), mean and sem over slugs.

    For each selected slug, the snapshot nearest to its passage time (within one frame interval)
    is cut in a window `height` high around the slug's centre of mass at the snapshot time
    (interpolated along its track). Slugs without such a snapshot are skipped; attrs list the
    slug ids used.
    """
    geo = geometry(ds)
    times = snapshot_times(ds)
    tol = slugs.attrs.get("dt", np.inf)
    profiles, used = [], []
    for row in selection.itertuples():
        k = int(np.argmin(np.abs(times - row.time)))
        if abs(times[k] - row.time) > tol:
            continue
        track = slugs[slugs["slug_id"] == row.slug_id].sort_values("time")
        xc = float(np.interp(times[k], track["time"], track["x_center"]))
        _, pos, vel = snapshot(ds, k)
        profiles.append(radial_profile(pos, vel, xc, geo.tube_radius, geo.particle_diameter,
                                       ring_width, height, n_per_diameter))
        used.append(row.slug_id)
    if not profiles:
        raise CaseFileError("no snapshot within one frame of the selected slugs' passage times")
    stack = xr.concat(profiles, dim="slug", coords="minimal", compat="override", join="exact")
    n = stack["velocity"].count("slug")
    out = xr.Dataset(coords={"r": stack["r"]})
    for name in ("porosity", "velocity"):
        out[name] = stack[name].mean("slug")
        out[f"{name}_sem"] = stack[name].std("slug", ddof=1) / np.sqrt(
            n if name == "velocity" else len(profiles))
    out["grain_volume"] = stack["grain_volume"].sum("slug")
    out.attrs.update(slug_ids=np.asarray(used, dtype=np.int64), particle_diameter=geo.particle_diameter,
                     ring_width=profiles[0].attrs["ring_width"], height=profiles[0].attrs["height"])
    return out


def slug_in_snapshots(ds: xr.Dataset, slugs: pd.DataFrame, prefer=()) -> tuple[int, pd.Series] | None:
    """The snapshot and slug to picture (H2): (snapshot index, the slug's row at that frame).

    Among the slugs whose frame coincides with a snapshot (within half a frame), those whose
    whole length with the ends (x_start_total .. x_end_total) holds the most snapshot grains win;
    slugs with an id in `prefer` (the profile selection) first, when any of them holds grains.
    None when no slug holds any grain of any snapshot.
    """
    times = snapshot_times(ds)
    if not len(slugs) or not times.size:
        return None
    dt = float(slugs.attrs.get("dt", np.median(np.diff(np.unique(slugs["time"])))
                               if slugs["time"].nunique() > 1 else 0.01))
    t = slugs["time"].to_numpy()
    after = np.clip(np.searchsorted(times, t), 0, times.size - 1)  # nearest snapshot: this or the one before
    before = np.clip(after - 1, 0, None)
    k = np.where(np.abs(times[before] - t) <= np.abs(times[after] - t), before, after)
    at_shot = np.abs(times[k] - t) <= dt / 2 + 1e-9
    lo_col = "x_start_total" if "x_start_total" in slugs else "x_start"
    hi_col = "x_end_total" if "x_end_total" in slugs else "x_end"
    count = np.asarray(ds["snapshot_count"].values, dtype=np.int64)
    first = np.concatenate([[0], np.cumsum(count)])
    x_all = np.asarray(ds["snapshot_position"].values[:, 0], dtype=np.float64)
    lo, hi = slugs[lo_col].to_numpy(dtype=np.float64), slugs[hi_col].to_numpy(dtype=np.float64)
    counts = np.zeros(len(slugs), dtype=np.int64)
    for row in np.nonzero(at_shot)[0]:
        x = x_all[first[k[row]]:first[k[row] + 1]]
        counts[row] = int(np.count_nonzero((x >= lo[row]) & (x <= hi[row])))
    if counts.max(initial=0) == 0:
        return None
    preferred = slugs["slug_id"].isin(list(prefer)).to_numpy() & (counts > 0)
    pool = np.nonzero(preferred)[0] if preferred.any() else np.nonzero(counts > 0)[0]
    best = int(pool[np.argmax(counts[pool])])
    return int(k[best]), slugs.iloc[best]

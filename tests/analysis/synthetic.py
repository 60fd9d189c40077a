"""Synthetic case files with a known answer, built from the case-file contract (analysis/contract.py).

A slug is a symmetric trapezoid in the solid fraction s = 1 - porosity: s rises linearly (slope
(S_SLUG - S_GAP) / RAMP) from the gap value to the slug value; the threshold 0.6 is crossed exactly
at the slug's back and front, so its length is the distance between the crossings. Slices are
volume averages (midpoint rule on SUB points, exact on the linear ramps), and the ramps are long
enough (RAMP >= 4.5 slices here) that the slices on both sides of each crossing lie on one ramp:
linear interpolation between slice centres then finds the crossing exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import xarray as xr
import yaml

from analysis import contract

L_TUBE = 0.525  # m
D_TUBE = 0.007  # m
D_GRAIN = 0.0014  # m
RHO = 937.0  # kg/m3
N_SLICES = 150
DX = L_TUBE / N_SLICES  # 3.5 mm
DT = 0.01  # s
THRESHOLD = 0.6
PHI_SLUG = 0.45  # porosity inside a slug
PHI_GAP = 0.9  # porosity between slugs
RAMP = 6 * DX  # m, width of the linear edge from PHI_GAP to PHI_SLUG
SUB = 8  # sub-points per slice for the volume average
A_TUBE = math.pi * D_TUBE**2 / 4
V_GRAIN = math.pi * D_GRAIN**3 / 6
# profiles of the other slice fields: peak value x (s - S_GAP) / (S_SLUG - S_GAP)
DRAG_PEAK = 2e-5  # N per grain
WALL_PEAK = 30.0  # Pa
TEMPERATURE_PEAK = 3e-9  # J


@dataclass
class Slug:
    """A slug: front position (m), length (m) and grain velocity (m/s) as functions of time (s)."""

    front: Callable[[np.ndarray], np.ndarray]
    length: Callable[[np.ndarray], np.ndarray]
    speed: Callable[[np.ndarray], np.ndarray]
    t0: float = -np.inf  # appears (s)
    t1: float = np.inf  # disappears (s)


def moving(front: float, velocity: float, length: float, t0: float = -np.inf, t1: float = np.inf,
           growth: float = 0.0, t_ref: float | None = None) -> Slug:
    """Slug whose front is at `front` (m) at t_ref (default t0, or 0) and moves at `velocity`;
    its length changes at `growth` (m/s; negative dissolves it)."""
    ref = (t0 if np.isfinite(t0) else 0.0) if t_ref is None else t_ref
    return Slug(front=lambda t: front + velocity * (t - ref),
                length=lambda t: length + growth * (t - ref),
                speed=lambda t: np.full_like(t, velocity, dtype=np.float64), t0=t0, t1=t1)


def solid_profile(x: np.ndarray, front: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Solid fraction of one slug at points x (m); front/length broadcast against x."""
    s_slug, s_gap, s_thr = 1 - PHI_SLUG, 1 - PHI_GAP, 1 - THRESHOLD
    slope = (s_slug - s_gap) / RAMP
    inside = np.minimum(x - (front - length), front - x)
    return np.clip(s_thr + slope * inside, s_gap, s_slug)


def slice_centres() -> np.ndarray:
    return (np.arange(N_SLICES) + 0.5) * DX


def fields(times: np.ndarray, slugs: list[Slug]):
    """Slice porosity, velocity and the shape (s - S_GAP)/(S_SLUG - S_GAP), each (time, slice)."""
    fine = ((np.arange(N_SLICES * SUB) + 0.5) * DX / SUB)[None, :]
    solid = np.full((times.size, fine.size), 1 - PHI_GAP)
    owner = np.full((times.size, fine.size), -1)
    for k, slug in enumerate(slugs):
        on = (times >= slug.t0) & (times < slug.t1)
        if not on.any():
            continue
        t = times[on][:, None]
        s = solid_profile(fine, slug.front(t), slug.length(t))
        better = s > solid[on]
        solid[on] = np.where(better, s, solid[on])
        owner[on] = np.where(better, k, owner[on])
    speeds = np.zeros((times.size, len(slugs) + 1))
    for k, slug in enumerate(slugs):
        speeds[:, k] = slug.speed(times)
    fine_vel = np.take_along_axis(speeds, np.where(owner < 0, len(slugs), owner), axis=1)
    fine_vel[owner < 0] = 0.0  # grains between slugs rest
    solid_avg = solid.reshape(times.size, N_SLICES, SUB).mean(axis=2)
    momentum = (solid * fine_vel).reshape(times.size, N_SLICES, SUB).mean(axis=2)
    velocity = momentum / solid_avg  # solid-weighted slice velocity
    shape = (solid_avg - (1 - PHI_GAP)) / (PHI_GAP - PHI_SLUG)
    return 1.0 - solid_avg, velocity, shape


def case_config(inclination_deg: float = 0.0, **overrides) -> dict:
    """Nested case configuration as in config_yaml; overrides as dotted keys."""
    cfg = {"tube": {"length": L_TUBE, "diameter": D_TUBE, "inclination_deg": inclination_deg},
           "physics": {"gravity": 9.81},
           "particles": {"diameter": D_GRAIN, "density": RHO, "friction": 0.5, "restitution": 0.5},
           "feed": {"mass_flow_kg_h": 2.49, "entry_velocity": 0.04},
           "gas": {"superficial_velocity": 1.0, "viscosity": 6.73e-5, "pressure": 101325.0},
           "run": {"seed": 0}}
    for key, value in overrides.items():
        section, name = key.split(".")
        cfg[section][name] = value
    return cfg


def pressure_signal(times: np.ndarray, level: float, transient: float = 6.0, noise: float = 0.1,
                    rho: float = 0.95, seed: int = 0) -> np.ndarray:
    """Pressure drop (Pa): linear rise to `level` over `transient` s, then AR(1) noise of relative
    standard deviation `noise` and lag-one correlation rho."""
    rng = np.random.default_rng(seed)
    eps = rng.normal(size=times.size) * noise * level * math.sqrt(1 - rho**2)
    ar = np.empty(times.size)
    ar[0] = rng.normal() * noise * level
    for k in range(1, times.size):
        ar[k] = rho * ar[k - 1] + eps[k]
    return level * np.minimum(times / transient, 1.0) + ar


def build(slugs: list[Slug], duration: float = 4.0, inclination_deg: float = 0.0,
          pressure_drop: float = 1000.0, snapshots=None, seed: int = 0, **config) -> xr.Dataset:
    """Case-file Dataset of `duration` s (frames every DT) with the given slugs.

    pressure_drop: steady level per tube length (Pa/m), reached after 6 s, with AR(1) noise of
    lag-one correlation 0.8 (tau = 9 frames: 10 s after the rise cover 100 correlation times).
    snapshots: list of (time, positions (n,3), velocities (n,3)) written as the CF ragged array.
    """
    times = np.round(np.arange(int(round(duration / DT))) * DT, 10)
    x = slice_centres()
    phi, vel, shape = fields(times, slugs)
    grains = ((1 - phi) * DX).sum(axis=1) * A_TUBE / V_GRAIN
    cfg = case_config(inclination_deg, **config)
    feed = cfg["feed"]["mass_flow_kg_h"] / 3600  # kg/s, delivered once the tube has filled (2 s)
    values = {
        "pressure_drop": pressure_signal(times, pressure_drop * L_TUBE, rho=0.8, seed=seed),
        "n_particles": np.round(grains),
        "mass_in": times * feed,
        "mass_out": np.maximum(times - 2.0, 0) * feed,
        "max_overlap": np.full(times.size, 0.01),
        "porosity": phi,
        "velocity": vel,
        "drag_force": DRAG_PEAK * shape,
        "particle_force": -DRAG_PEAK * shape,
        "wall_stress": WALL_PEAK * shape,
        "granular_temperature": TEMPERATURE_PEAK * shape,
    }
    sizes = {"time": times.size, "x": x.size}
    # every series and slice field of the contract, zero where the scenario does not model it
    data = {name: var.entry(values.get(name, np.zeros([sizes[d] for d in var.dims])), cast=False)
            for name, var in {**contract.SERIES, **contract.FIELDS}.items()}
    ds = xr.Dataset(
        data,
        coords={"time": contract.COORDS["time"].entry(times), "x": contract.COORDS["x"].entry(x)},
        attrs={"Conventions": "CF-1.13", "config_yaml": yaml.safe_dump(cfg, sort_keys=False),
               "tube_length": L_TUBE, "tube_diameter": D_TUBE, "particle_diameter": D_GRAIN,
               "particle_density": RHO, "inclination_deg": float(inclination_deg), "seed": seed},
    )
    if snapshots:
        ds = add_snapshots(ds, snapshots)
    return ds


def add_snapshots(ds: xr.Dataset, snapshots) -> xr.Dataset:
    """Attach snapshots [(time, positions, velocities), ...] as the CF contiguous ragged array
    (float64 positions and velocities; grain ids numbered through the snapshots)."""
    times = np.array([s[0] for s in snapshots], dtype=np.float64)
    pos = np.concatenate([np.asarray(s[1], dtype=np.float64).reshape(-1, 3) for s in snapshots])
    vel = np.concatenate([np.asarray(s[2], dtype=np.float64).reshape(-1, 3) for s in snapshots])
    count = np.array([len(np.asarray(s[1]).reshape(-1, 3)) for s in snapshots], dtype=np.int64)
    values = {"snapshot_count": count, "snapshot_position": pos, "snapshot_velocity": vel,
              "snapshot_grain_id": np.arange(len(pos), dtype=np.int64)}
    return ds.assign({name: var.entry(values[name], cast=False) for name, var in contract.SNAPSHOTS.items()}
                     ).assign_coords(snapshot_time=contract.COORDS["snapshot_time"].entry(times),
                                     xyz=contract.COORDS["xyz"].entry(["x", "y", "z"]))


def write(ds: xr.Dataset, path) -> None:
    """Write as NetCDF4 like the engine: float64 seconds, no fill values on coordinates."""
    encoding = {name: {"_FillValue": None} for name in ds.variables}
    ds.to_netcdf(path, format="NETCDF4", engine="netcdf4", encoding=encoding)


# --- scenarios ---------------------------------------------------------------------------------

def periodic(period: float = 0.75, velocity: float = 0.3, length: float = 0.05,
             duration: float = 22.5) -> list[Slug]:
    """Slugs of one length and velocity entering at the inlet every `period` s (steady from t=0)."""
    first = -int(math.ceil((L_TUBE + length + RAMP) / (velocity * period))) - 1
    return [moving(0.0, velocity, length, t_ref=k * period)
            for k in range(first, int(duration / period) + 2)]


def default_case(duration: float = 22.5, snapshots: bool = True) -> xr.Dataset:
    """A 22.5 s default-like case: 5 cm slugs at 0.3 m/s every 0.75 s, small slugs that dissolve
    within 0.15 m, the pressure drop rising to 1000 Pa/m over 6 s, and grain snapshots at
    100 Hz over 0.5 s (9.9-10.4 s, a 5 cm slug passes 0.26 m at 9.95 s) at half length."""
    slugs = periodic(0.75, 0.3, 0.05, duration)
    for k in range(int(duration / 0.75) + 1):  # a 15 mm slug between two big ones, gone at 0.11 m
        slugs.append(moving(0.015, 0.3, 0.015, t0=k * 0.75 + 0.375, growth=-0.04,
                            t1=k * 0.75 + 0.375 + 0.375))
    shots = None
    if snapshots:
        rng = np.random.default_rng(1)
        shots = []
        for t in np.round(np.arange(9.9, 10.4, 0.01), 10):
            pos, vel = packed_grains(rng, 600, (L_TUBE / 2 - 0.02, L_TUBE / 2 + 0.02))
            shots.append((t, pos, vel))
    return build(slugs, duration, snapshots=shots)


def packed_grains(rng, n: int, x_range: tuple[float, float], velocity: float = 0.3):
    """n grain centres uniformly in the tube (fully inside the wall) over x_range; velocity along x."""
    r_max = D_TUBE / 2 - D_GRAIN / 2
    r = r_max * np.sqrt(rng.uniform(size=n))
    a = rng.uniform(0, 2 * np.pi, size=n)
    x = rng.uniform(*x_range, size=n)
    pos = np.column_stack([x, r * np.cos(a), r * np.sin(a)])
    vel = np.zeros((n, 3))
    vel[:, 0] = velocity
    return pos, vel


if __name__ == "__main__":  # pragma: no cover
    import sys
    out = sys.argv[1] if len(sys.argv) > 1 else "synthetic_default.nc"
    write(default_case(), out)
    print(out)

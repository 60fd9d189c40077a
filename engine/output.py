"""The case file: time series, slice fields and optional grain snapshots, written as NetCDF4.

Every variable is written as the contract declares it (analysis/contract.py: name, dimensions,
type, units, long name). Series are gathered in memory (xarray cannot append along a dimension)
and written once, to a temporary name that is renamed into place only when complete.
"""

from __future__ import annotations

import errno
import os
import subprocess
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import xarray as xr

from analysis.contract import COORDS, FIELDS, FINAL, SERIES, SNAPSHOTS, TUBE_SNAPSHOTS


class Recorder:
    """Collects output frames of a running simulation."""

    def __init__(self, case):
        self.case = case
        self.width = case["output.slice_width"]
        self.series = {name: [] for name in SERIES}
        self.fields = {name: [] for name in FIELDS}
        self.times: list[float] = []
        self.snapshots: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []
        self._frames_per_snapshot = int(round(case["output.snapshot_interval"] / case["output.interval"]))
        self._last_impulse = (0.0, 0.0)  # (time, piston impulse) of the previous frame
        # whole-tube snapshots: (time, position, velocity, angular velocity, id); 0 frames = none
        self.tube_snapshots: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._frames_per_tube_snapshot = int(round(case["output.tube_snapshot_interval"]
                                                   / case["output.interval"]))

    def sample(self, sim) -> None:
        """Record one frame of `sim` (a Simulation)."""
        self.times.append(sim.time)
        d = 2 * sim.model.radius
        (t0, j0), j1 = self._last_impulse, sim.piston_impulse
        piston = (j1 - j0) / (sim.time - t0) if sim.time > t0 else 0.0
        self._last_impulse = (sim.time, j1)
        per_frame = {"max_overlap": sim.max_overlap / d, "piston_force": piston}
        for name in SERIES:  # every other series is the Simulation property of its name
            self.series[name].append(per_frame[name] if name in per_frame else getattr(sim, name))
        fields = sim.slice_fields(self.width)
        fields["gas_pressure"] = sim.gas_pressure_slices(self.width)
        for name in FIELDS:
            self.fields[name].append(fields[name].astype(np.float32))
        c = self.case
        if (c["output.snapshots"] and sim.time >= c["output.snapshot_t_min"] - 1e-12
                and (len(self.times) - 1) % self._frames_per_snapshot == 0):
            pos, vel, ids = sim.positions, sim.velocities, sim.ids
            inside = (pos[:, 0] >= c["output.snapshot_x_min"]) & (pos[:, 0] <= c["output.snapshot_x_max"])
            self.snapshots.append((sim.time, pos[inside].astype(np.float32), vel[inside].astype(np.float32),
                                   ids[inside]))
        if self._frames_per_tube_snapshot and (len(self.times) - 1) % self._frames_per_tube_snapshot == 0:
            self.tube_snapshots.append((sim.time, sim.positions.astype(np.float32),
                                        sim.velocities.astype(np.float32),
                                        sim.angular_velocities.astype(np.float32), sim.ids.copy()))

    def dataset(self, attrs: dict) -> xr.Dataset:
        """The case file as an xarray Dataset with CF units and long names."""
        nslices = len(self.fields["porosity"][0]) if self.times else int(
            round(self.case["tube.length"] / self.width))
        x = (np.arange(nslices) + 0.5) * self.width
        coords = {"time": COORDS["time"].entry(self.times), "x": COORDS["x"].entry(x)}
        data = {name: var.entry(self.series[name]) for name, var in SERIES.items()}
        for name, var in FIELDS.items():
            data[name] = var.entry(np.array(self.fields[name], dtype=np.float32).reshape(len(self.times), nslices))
        ds = xr.Dataset(data, coords=coords, attrs=attrs)
        if self.case["output.snapshots"]:
            ds = ds.merge(self._snapshot_dataset())
        if self._frames_per_tube_snapshot:
            ds = ds.merge(self._tube_snapshot_dataset())
        return ds

    @classmethod
    def from_dataset(cls, ds: xr.Dataset, case, sim) -> "Recorder":
        """The recorder that wrote the case file `ds` (loaded), holding the same frames bit for bit,
        to continue recording into; `sim` is the simulation restored with it."""
        rec = cls(case)
        rec._last_impulse = (sim.time, sim.piston_impulse)
        rec.times = [float(t) for t in ds.time.values]
        for name in SERIES:
            rec.series[name] = list(ds[name].values)
        for name in FIELDS:
            rec.fields[name] = list(ds[name].values.astype(np.float32))
        if case["output.snapshots"]:
            ends = np.cumsum(ds.snapshot_count.values)
            pos, vel, ids = (ds[name].values for name in
                             ("snapshot_position", "snapshot_velocity", "snapshot_grain_id"))
            rec.snapshots = [(float(t), pos[end - n:end], vel[end - n:end], ids[end - n:end])
                             for t, n, end in zip(ds.snapshot_time.values, ds.snapshot_count.values, ends)]
        if rec._frames_per_tube_snapshot:
            ends = np.cumsum(ds.tube_snapshot_count.values)
            arrays = [ds[name].values for name in TUBE_SNAPSHOTS if name != "tube_snapshot_count"]
            rec.tube_snapshots = [(float(t), *(a[end - n:end] for a in arrays)) for t, n, end in
                                  zip(ds.tube_snapshot_time.values, ds.tube_snapshot_count.values, ends)]
        return rec

    @staticmethod
    def final_state(sim) -> xr.Dataset:
        """Every grain in the tube at the end of the run (float64), the start of a warm run."""
        values = (sim.positions, sim.velocities, sim.angular_velocities)
        return xr.Dataset({name: var.entry(v.copy()) for (name, var), v in zip(FINAL.items(), values)},
                          coords={"xyz": COORDS["xyz"].entry(["x", "y", "z"])})

    def _snapshot_dataset(self) -> xr.Dataset:
        """Snapshots as a CF contiguous ragged array (sample dimension `grain`)."""
        return _ragged(SNAPSHOTS, "snapshot_time", self.snapshots)

    def _tube_snapshot_dataset(self) -> xr.Dataset:
        """Whole-tube snapshots as a CF contiguous ragged array (sample dimension `tube_grain`)."""
        return _ragged(TUBE_SNAPSHOTS, "tube_snapshot_time", self.tube_snapshots)


def _ragged(group: dict, time: str, snaps: list) -> xr.Dataset:
    """The contract's `group` (the count, then one variable per array of a snapshot) over the
    coordinate `time`, from snapshots [(time, array, ...), ...] (empty arrays without any)."""
    count, *arrays = group.values()
    data = {count.name: count.entry([len(s[1]) for s in snaps])}
    for k, var in enumerate(arrays, start=1):
        empty = np.zeros((0, 3)[:len(var.dims)])
        data[var.name] = var.entry(np.concatenate([s[k] for s in snaps]) if snaps else empty)
    return xr.Dataset(data, coords={time: COORDS[time].entry([s[0] for s in snaps]),
                                    "xyz": COORDS["xyz"].entry(["x", "y", "z"])})


def software_versions() -> dict:
    """Versions of the engine, Python, numpy and numba that ran a case (global attributes)."""
    import platform

    import numba

    from . import __version__
    return {"engine_version": __version__, "python_version": platform.python_version(),
            "numpy_version": np.__version__, "numba_version": numba.__version__}


def global_attributes(case, extra: dict) -> dict:
    """CF global attributes: provenance, the full configuration, flat geometry for readers."""
    from . import __version__
    attrs = {
        "Conventions": "CF-1.13",
        "title": "plugsim case: dense-phase pneumatic conveying in a tube",
        "source": f"plugsim {__version__}",
        "history": f"{datetime.now(timezone.utc).isoformat(timespec='seconds')} plugsim run",
        "references": "Strauss, McNamara, Herrmann: Plug conveying in a horizontal tube; "
                      "Strauss et al.: Plug conveying in a vertical tube",
        **software_versions(),
        "config_yaml": case.to_yaml(),
        "seed": case["run.seed"],
        "tube_length": case["tube.length"], "tube_diameter": case["tube.diameter"],
        "particle_diameter": case["particles.diameter"], "particle_density": case["particles.density"],
        "inclination_deg": case["tube.inclination_deg"],
    }
    attrs.update(extra)
    return attrs


# Below this many free bytes a failed write is taken for a full disk: netCDF4/HDF5 report one as
# "NetCDF: HDF error", without an errno, and a write fails with up to a chunk's worth still free.
LOW_SPACE = 64 * 2**20


class DiskFullError(RuntimeError):
    """Writing `path` failed because the filesystem holding it is full; the message is one line
    naming the filesystem (mount point and type) and the path."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        mount, kind = filesystem(self.path)
        super().__init__(f"no space left on {mount} ({kind}) writing {self.path}")


def free_bytes(folder: str | Path) -> int:
    """Bytes this process can still write in `folder` (root may use the blocks reserved for it)."""
    stat = os.statvfs(folder)
    return (stat.f_bfree if os.geteuid() == 0 else stat.f_bavail) * stat.f_frsize


def filesystem(path: str | Path) -> tuple[str, str]:
    """(mount point, "type device") of the filesystem that holds `path` (its folder if it does not exist)."""
    folder = Path(os.path.abspath(path))
    while not folder.exists() or not folder.is_dir():
        folder = folder.parent
    while not os.path.ismount(folder):
        folder = folder.parent
    kind = "filesystem"
    try:
        with open("/proc/mounts") as mounts:
            for line in mounts:
                device, mount, fstype = line.split()[:3]
                if mount == str(folder):
                    kind = fstype if device == fstype else f"{fstype} {device}"
    except OSError:
        pass
    return str(folder), kind


def out_of_space(err: BaseException, folder: str | Path) -> bool:
    """Whether `err`, raised while writing into `folder`, means that its filesystem is full
    (call it before removing what was partly written)."""
    if isinstance(err, OSError) and err.errno in (errno.ENOSPC, errno.EDQUOT):
        return True
    if not isinstance(err, (OSError, RuntimeError, subprocess.CalledProcessError)):
        return False
    try:
        return free_bytes(folder) < LOW_SPACE
    except OSError:
        return False


def write_atomically(ds: xr.Dataset, out: str | Path) -> None:
    """Write ds to `out` via a temporary file in the same folder, renamed only when complete;
    DiskFullError (nothing left at `out`'s temporary name) when the disk fills."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f"{out.name}.tmp-{os.getpid()}")
    encoding = {name: {"zlib": True, "complevel": 4, "shuffle": True}
                for name, var in ds.data_vars.items() if var.dtype.kind in "fiu"}
    for name, var in ds.data_vars.items():
        if var.dtype.kind == "f":
            encoding[name]["_FillValue"] = None if name in SERIES else float("nan")
    try:
        ds.to_netcdf(tmp, format="NETCDF4", engine="netcdf4", encoding=encoding)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, out)
    except (OSError, RuntimeError) as err:
        if out_of_space(err, out.parent):
            raise DiskFullError(out) from err
        raise
    finally:
        if tmp.exists():
            tmp.unlink()


"""`plugsim export`: ParaView files of a case file's whole-tube grain snapshots and slice fields.

Writes, in one folder: grains_NNNNN.vtu (one VTK unstructured-points file per snapshot: point data
radius, velocity, angular velocity, grain id) with grains.pvd, and slices_NNNNN.vtr (the slice
fields as cell data on a rectilinear grid of the slices, one cell across the tube) with slices.pvd.
Array names carry their units. The folder appears only when complete.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .output import DiskFullError, out_of_space

SNAPSHOT_KEY = "output.tube_snapshot_interval"
MARKER = "README.txt"  # every export folder has it; an existing folder without it is not replaced


class ExportError(ValueError):
    """A case file or output path that cannot be exported; the message is one line."""


@dataclass
class Export:
    """What an export wrote: folder, file counts and total size (bytes)."""

    folder: Path
    grain_files: int
    slice_files: int
    size: int


def unit_suffix(units: str) -> str:
    """'m s-1' -> '_m_per_s', 'Pa' -> '_Pa', '1' -> '' (array-name suffix)."""
    if units in ("", "1"):
        return ""
    parts = []
    for token in units.split():
        parts += ["per", token[:-2]] if token.endswith("-1") else [token]
    return "_" + "_".join(parts)


def open_case_file(path: str | Path):
    """The case file as a loaded xarray Dataset; ExportError when missing or not a case file."""
    import xarray as xr

    path = Path(path)
    if not path.is_file():
        raise ExportError(f"case file {str(path)!r} does not exist")
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            ds = ds.load()
    except (OSError, ValueError) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ExportError(f"case file {str(path)!r} cannot be read as NetCDF: {reason}") from None
    if "porosity" not in ds or "particle_diameter" not in ds.attrs:
        raise ExportError(f"case file {str(path)!r} is not a plugsim case file (no porosity slices)")
    return ds


def require_tube_snapshots(ds, path: str | Path) -> None:
    """Raise ExportError unless the case file holds whole-tube grain snapshots."""
    if "tube_snapshot_count" not in ds or ds.sizes.get("tube_snapshot_time", 0) == 0:
        raise ExportError(f"case file {str(path)!r} has no whole-tube grain snapshots: run the case with "
                          f"{SNAPSHOT_KEY} > 0 (s between snapshots, a multiple of output.interval)")


def tube_snapshots(ds):
    """Yield (time s, position m, velocity m/s, angular velocity rad/s, grain id) per snapshot."""
    start = 0
    for t, n in zip(ds["tube_snapshot_time"].values, ds["tube_snapshot_count"].values):
        sl = slice(start, start + int(n))
        start += int(n)
        yield (float(t), ds["tube_snapshot_position"].values[sl], ds["tube_snapshot_velocity"].values[sl],
               ds["tube_snapshot_angular_velocity"].values[sl], ds["tube_snapshot_grain_id"].values[sl])


def slice_field_names(ds) -> list[str]:
    """Names of the slice fields (dims time, x) of a case file."""
    return [name for name, var in ds.data_vars.items() if var.dims == ("time", "x")]


def check_out_folder(out: Path) -> None:
    """Refuse an output path that is a file or a non-empty folder that is no earlier export."""
    if out.exists() and not out.is_dir():
        raise ExportError(f"--out {str(out)!r} is a file; it must be a folder (created if missing)")
    if out.is_dir() and any(out.iterdir()) and not (out / MARKER).is_file():
        raise ExportError(f"--out {str(out)!r} is a non-empty folder that is not a plugsim export; "
                          f"choose a new or empty folder")


def _vector(values: np.ndarray) -> tuple:
    """(n, 3) -> three contiguous float32 component arrays (pyevtk's vector form)."""
    return tuple(np.ascontiguousarray(values[:, k], dtype=np.float32) for k in range(3))


def _write_no_grains(path: Path, data: dict, t: float) -> str:
    """An empty snapshot (no grain in the tube) with the same arrays; pyevtk refuses zero points."""
    def array(name, kind, components=1):
        return (f'<DataArray type="{kind}" Name="{name}" NumberOfComponents="{components}" '
                f'format="ascii"></DataArray>')
    kinds = {np.dtype(np.float32): "Float32", np.dtype(np.int64): "Int64"}
    point_data = "".join(array(name, "Float32", 3) if isinstance(value, tuple)
                         else array(name, kinds[value.dtype]) for name, value in data.items())
    path = path.with_suffix(".vtu")
    path.write_text(
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="0.1">\n<UnstructuredGrid>\n'
        f'<FieldData><DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" format="ascii">{t!r}'
        '</DataArray></FieldData>\n<Piece NumberOfPoints="0" NumberOfCells="0">\n'
        f'<Points>{array("points", "Float32", 3)}</Points>\n'
        f'<Cells>{array("connectivity", "Int32")}{array("offsets", "Int32")}{array("types", "UInt8")}'
        f'</Cells>\n<PointData>{point_data}</PointData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n')
    return str(path)


def _write_grains(ds, folder: Path) -> int:
    from pyevtk.hl import pointsToVTK
    from pyevtk.vtk import VtkGroup

    radius = 0.5 * float(ds.attrs["particle_diameter"])
    group = VtkGroup(str(folder / "grains"))
    count = 0
    for k, (t, pos, vel, omg, ids) in enumerate(tube_snapshots(ds)):
        x, y, z = _vector(pos)
        data = {"radius_m": np.full(len(pos), radius, dtype=np.float32),
                "velocity_m_per_s": _vector(vel), "angular_velocity_rad_per_s": _vector(omg),
                "grain_id": np.ascontiguousarray(ids, dtype=np.int64)}
        name = folder / f"grains_{k:05d}"
        path = (pointsToVTK(str(name), x, y, z, data=data, fieldData={"TimeValue": np.array([t])})
                if len(pos) else _write_no_grains(name, data, t))
        group.addFile(filepath=path, sim_time=t)
        count += 1
    group.save()
    return count


def _write_slices(ds, folder: Path) -> int:
    """Slice fields as cell data: x edges of the slices, one cell of the tube's width across."""
    from pyevtk.hl import gridToVTK
    from pyevtk.vtk import VtkGroup

    x = ds["x"].values
    width = 2 * float(x[0])  # slice centres are (k + 1/2) * width
    edges = np.arange(len(x) + 1) * width
    r = 0.5 * float(ds.attrs["tube_diameter"])
    across = np.array([-r, r])
    names = {name: name + unit_suffix(ds[name].attrs.get("units", "")) for name in slice_field_names(ds)}
    values = {name: ds[name].values for name in names}
    group = VtkGroup(str(folder / "slices"))
    for k, t in enumerate(ds["time"].values):
        cells = {label: np.ascontiguousarray(values[name][k].astype(np.float32).reshape(-1, 1, 1))
                 for name, label in names.items()}
        path = gridToVTK(str(folder / f"slices_{k:05d}"), edges, across, across.copy(), cellData=cells,
                         fieldData={"TimeValue": np.array([float(t)])})
        group.addFile(filepath=path, sim_time=float(t))
    group.save()
    return len(ds["time"])


def _readme(ds, case_file: Path) -> str:
    fields = ", ".join(name + unit_suffix(ds[name].attrs.get("units", "")) for name in slice_field_names(ds))
    return (f"ParaView files of {case_file.name} (plugsim export). SI units; array names carry them.\n"
            "grains.pvd: the whole-tube grain snapshots as one animation (grains_NNNNN.vtu, point data "
            "radius_m, velocity_m_per_s, angular_velocity_rad_per_s, grain_id). x runs along the tube "
            "from the inlet, y and z across, the axis at y = z = 0. To draw spheres: filter Glyph, "
            "glyph type Sphere, scale array radius_m, scale factor 2 (the glyph's own radius is 0.5).\n"
            f"slices.pvd: the slice fields per output frame (slices_NNNNN.vtr, cell data {fields}), "
            "one cell per slice along x, one across the tube.\n")


def export_case(case_file: str | Path, out: str | Path | None = None) -> Export:
    """Write the ParaView files of `case_file` into folder `out` (default: next to it, CASE_vtk);
    DiskFullError (nothing left behind) when the disk fills."""
    case_file = Path(case_file)
    out = Path(out) if out is not None else case_file.with_name(case_file.stem + "_vtk")
    check_out_folder(out)
    ds = open_case_file(case_file)
    require_tube_snapshots(ds, case_file)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f"{out.name}.tmp-{os.getpid()}")
    try:
        tmp.mkdir()
        grains = _write_grains(ds, tmp)
        slices = _write_slices(ds, tmp)
        (tmp / MARKER).write_text(_readme(ds, case_file))
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    except OSError as err:
        if out_of_space(err, out.parent):
            raise DiskFullError(out) from err
        raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    size = sum(f.stat().st_size for f in out.iterdir())
    return Export(out, grains, slices, size)

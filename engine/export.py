"""`plugsim export`: ParaView files of a case file's whole-tube grain snapshots and slice fields.

Writes, in one folder: grains_NNNNN.vtu (one VTK unstructured grid of vertex cells per snapshot
that holds grains: point data radius, velocity, angular velocity, grain id) with grains.pvd, and
slices_NNNNN.vtu (the slice fields as cell data on one hexahedron per slice, the tube's width
across) with slices.pvd. Array names carry their units. Each file carries its time as the field
array TimeValue, a child of <UnstructuredGrid> before <Piece> where the VTK XML format puts a
dataset's field data (VTK and ParaView read it there, meshio reads the files). The folder appears
only when complete.
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
    """What an export wrote: folder, file counts, snapshots left out (no grain in the tube) and
    total size (bytes)."""

    folder: Path
    grain_files: int
    slice_files: int
    size: int
    empty_snapshots: int = 0


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


VTK_VERTEX, VTK_HEXAHEDRON = 1, 12
VTK_TYPES = {np.dtype(np.float32): "Float32", np.dtype(np.float64): "Float64",
             np.dtype(np.int64): "Int64", np.dtype(np.uint8): "UInt8"}


def write_vtu(path: Path, points: np.ndarray, connectivity: np.ndarray, offsets: np.ndarray,
              types: np.ndarray, time: float, point_data: dict | None = None,
              cell_data: dict | None = None) -> str:
    """One VTK XML unstructured grid (raw appended little-endian arrays, UInt64 block sizes) with
    its time (s) as field data TimeValue."""
    blocks, tags = [], []

    def add(name: str, values: np.ndarray) -> str:
        values = np.asarray(values)
        native = values.dtype.newbyteorder("=")
        data = np.ascontiguousarray(values, dtype=native.newbyteorder("<")).tobytes()
        offset = sum(len(b) for b in blocks)
        blocks.append(np.array([len(data)], dtype="<u8").tobytes() + data)
        # scalars without NumberOfComponents (VTK's default 1): meshio reads them as (n,), not (n, 1)
        components = f'NumberOfComponents="{values.shape[1]}" ' if values.ndim == 2 else ""
        return (f'<DataArray type="{VTK_TYPES[native]}" Name="{name}" {components}'
                f'format="appended" offset="{offset}"/>')

    for label, arrays in (("PointData", point_data or {}), ("CellData", cell_data or {})):
        tags.append(f"<{label}>" + "".join(add(k, v) for k, v in arrays.items()) + f"</{label}>")
    points = np.asarray(points).reshape(-1, 3)
    if points.dtype != np.float64:
        points = points.astype(np.float32)
    tags.append(f'<Points>{add("points", points)}</Points>')
    tags.append("<Cells>" + add("connectivity", np.asarray(connectivity, dtype=np.int64))
                + add("offsets", np.asarray(offsets, dtype=np.int64))
                + add("types", np.asarray(types, dtype=np.uint8)) + "</Cells>")
    head = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
            'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
            f'<FieldData><DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" '
            f'format="ascii">{float(time)!r}</DataArray></FieldData>\n'
            f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{len(types)}">\n'
            + "\n".join(tags) + '\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding="raw">\n_')
    path = path.with_suffix(".vtu")
    path.write_bytes(head.encode() + b"".join(blocks) + b"\n</AppendedData>\n</VTKFile>\n")
    return str(path)


def _write_grains(ds, folder: Path) -> tuple[int, int]:
    """grains_NNNNN.vtu (NNNNN the snapshot's index) and grains.pvd; (files, snapshots left out).

    A snapshot without grains (an empty tube at t = 0) is left out: meshio (5.3.5) reads no
    unstructured grid without cells (meshio issue 1412), and a vertex cell needs a grain."""
    from pyevtk.vtk import VtkGroup

    radius = 0.5 * float(ds.attrs["particle_diameter"])
    group = VtkGroup(str(folder / "grains"))
    count = empty = 0
    for k, (t, pos, vel, omg, ids) in enumerate(tube_snapshots(ds)):
        n = len(pos)
        if n == 0:
            empty += 1
            continue
        data = {"radius_m": np.full(n, radius, dtype=np.float32),
                "velocity_m_per_s": np.asarray(vel, dtype=np.float32).reshape(-1, 3),
                "angular_velocity_rad_per_s": np.asarray(omg, dtype=np.float32).reshape(-1, 3),
                "grain_id": np.asarray(ids, dtype=np.int64)}
        path = write_vtu(folder / f"grains_{k:05d}", pos, np.arange(n), np.arange(1, n + 1),
                         np.full(n, VTK_VERTEX), t, point_data=data)
        group.addFile(filepath=path, sim_time=t)
        count += 1
    group.save()
    return count, empty


def slice_cells(edges: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Points (m) and hexahedron connectivity of one cell per slice between x edges, the square
    -radius..radius across the tube."""
    corners = [(-radius, -radius), (radius, -radius), (radius, radius), (-radius, radius)]
    points = np.array([(x, y, z) for x in edges for y, z in corners])
    # VTK hexahedron: the face at the lower x edge (anticlockwise seen from +x, so that its normal
    # points to the other face), then the same corners at the upper edge
    first = 4 * np.arange(len(edges) - 1)[:, None]
    return points, (first + np.arange(8)).ravel()


def _write_slices(ds, folder: Path) -> int:
    """Slice fields as cell data: one hexahedron per slice between its x edges, the tube's width across."""
    from pyevtk.vtk import VtkGroup

    x = ds["x"].values
    width = 2 * float(x[0])  # slice centres are (k + 1/2) * width
    points, connectivity = slice_cells(np.arange(len(x) + 1) * width, 0.5 * float(ds.attrs["tube_diameter"]))
    offsets, types = 8 * np.arange(1, len(x) + 1), np.full(len(x), VTK_HEXAHEDRON)
    names = {name: name + unit_suffix(ds[name].attrs.get("units", "")) for name in slice_field_names(ds)}
    values = {name: ds[name].values for name in names}
    group = VtkGroup(str(folder / "slices"))
    for k, t in enumerate(ds["time"].values):
        cells = {label: values[name][k].astype(np.float32) for name, label in names.items()}
        path = write_vtu(folder / f"slices_{k:05d}", points, connectivity, offsets, types, float(t),
                         cell_data=cells)
        group.addFile(filepath=path, sim_time=float(t))
    group.save()
    return len(ds["time"])


def _readme(ds, case_file: Path) -> str:
    fields = ", ".join(name + unit_suffix(ds[name].attrs.get("units", "")) for name in slice_field_names(ds))
    return (f"ParaView files of {case_file.name} (plugsim export). SI units; array names carry them.\n"
            "grains.pvd: the whole-tube grain snapshots as one animation (grains_NNNNN.vtu, point data "
            "radius_m, velocity_m_per_s, angular_velocity_rad_per_s, grain_id). x runs along the tube "
            "from the inlet, y and z across, the axis at y = z = 0. To draw spheres: filter Glyph, "
            "glyph type Sphere, scale array radius_m, scale factor 2 (the glyph's own radius is 0.5). "
            "A snapshot without grains (the empty tube at t = 0) has no file.\n"
            f"slices.pvd: the slice fields per output frame (slices_NNNNN.vtu, cell data {fields}), "
            "one hexahedron per slice along x, the tube's width across.\n"
            "Every file carries its time (s) as the field array TimeValue; the .pvd files list the "
            "same times.\n")


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
        grains, empty = _write_grains(ds, tmp)
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
    return Export(out, grains, slices, size, empty)

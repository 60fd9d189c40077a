"""Whole-tube grain snapshots, `plugsim export` (ParaView files read back) and `plugsim animate`."""

import platform
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numba
import numpy as np
import pytest
import xarray as xr
from PIL import Image

import engine
from engine import Case, Simulation
from engine.cli import main
from engine.output import Recorder, global_attributes
from engine.run import run_case

ROOT = Path(__file__).resolve().parents[2]
CASE = ROOT / "config" / "cases" / "horizontal.yaml"
# A grain-only 2.1 cm tube (as in test_run): the feed pushes grains in from the first step, so the
# snapshots after t = 0 hold a growing number of grains.
SHORT = ["gas.enabled=false", "tube.length=0.021", "run.duration=0.4", "output.tube_snapshot_interval=0.05"]
SNAPSHOT_VARS = ["tube_snapshot_count", "tube_snapshot_position", "tube_snapshot_velocity",
                 "tube_snapshot_angular_velocity", "tube_snapshot_grain_id", "tube_snapshot_time"]
VTK_TYPES = {"Float32": np.float32, "Float64": np.float64, "Int32": np.int32, "Int64": np.int64,
             "UInt8": np.uint8}


@pytest.fixture(scope="module")
def case_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "case.nc"
    run_case(Case.from_yaml(CASE, SHORT), out)
    return out


@pytest.fixture(scope="module")
def ds(case_file):
    with xr.open_dataset(case_file) as data:
        return data.load()


def read_vtk(path: Path) -> dict:
    """Arrays of a VTK XML file (appended raw with UInt64 headers, or ascii), by Name, with the
    Piece's NumberOfPoints; independent of the writer."""
    raw = path.read_bytes()
    start = raw.find(b"<AppendedData")
    head = raw[:start if start >= 0 else len(raw)].decode()
    binary = raw[raw.index(b"_", start) + 1:] if start >= 0 else b""
    arrays = {}
    for tag in re.findall(r"<DataArray [^>]*>", head):
        attr = dict(re.findall(r'(\w+)="([^"]*)"', tag))
        ncomp = int(attr.get("NumberOfComponents", 1))
        if attr.get("format") == "appended":
            offset = int(attr["offset"])
            size = int(np.frombuffer(binary[offset:offset + 8], dtype=np.uint64)[0])
            values = np.frombuffer(binary[offset + 8:offset + 8 + size], dtype=VTK_TYPES[attr["type"]])
        else:
            assert attr["format"] == "ascii"
            text = head[head.index(tag) + len(tag):].split("</DataArray>")[0]
            values = np.array(text.split(), dtype=VTK_TYPES[attr["type"]])
        arrays[attr["Name"]] = values.reshape(-1, ncomp) if ncomp > 1 else values
    points = re.search(r'NumberOfPoints="(\d+)"', head)
    arrays["NumberOfPoints"] = int(points.group(1)) if points else None
    return arrays


def read_pvd(path: Path) -> list[tuple[float, str]]:
    """(time, file) of each data set of a ParaView collection."""
    return [(float(d.get("timestep")), d.get("file")) for d in ET.parse(path).getroot().iter("DataSet")]


def test_whole_tube_snapshots_hold_every_grain_in_the_tube(ds):
    times = ds.tube_snapshot_time.values
    np.testing.assert_allclose(times, np.arange(9) * 0.05, atol=1e-9)  # every 0.05 s from t = 0
    counts = ds.tube_snapshot_count.values
    assert ds.tube_snapshot_count.attrs["sample_dimension"] == "tube_grain"
    np.testing.assert_array_equal(counts, ds.n_particles.sel(time=times, method="nearest").values)
    assert counts.sum() == ds.sizes["tube_grain"] and counts[-1] > 100, "the feed should have pushed grains in"
    x = ds.tube_snapshot_position.values[:, 0]
    assert x.min() >= 0.0 and x.max() <= 0.021
    assert ds.tube_snapshot_angular_velocity.attrs["units"] == "rad s-1"
    assert np.abs(ds.tube_snapshot_angular_velocity.values).max() > 0, "colliding grains spin"
    # the last snapshot is the final state (same grains, same order), stored as float32 (relative
    # rounding 6e-8, hence 1e-6)
    assert counts[-1] == ds.sizes["final_grain"]
    for name in ("position", "velocity", "angular_velocity"):
        np.testing.assert_allclose(ds[f"tube_snapshot_{name}"].values[-counts[-1]:], ds[f"final_{name}"].values,
                                   rtol=1e-6, atol=1e-9)


def test_whole_tube_snapshots_are_off_by_default_and_versions_are_recorded():
    case = Case.from_yaml(CASE, ["gas.enabled=false", "tube.length=0.021"])
    recorder = Recorder(case)
    recorder.sample(Simulation(case))
    data = recorder.dataset(global_attributes(case, {}))
    assert not [name for name in data.variables if name.startswith("tube_snapshot")]
    assert data.attrs["engine_version"] == engine.__version__
    assert data.attrs["numpy_version"] == np.__version__ and data.attrs["numba_version"] == numba.__version__
    assert data.attrs["python_version"] == platform.python_version()


def test_case_file_records_the_versions(ds):
    assert (ds.attrs["numpy_version"], ds.attrs["numba_version"]) == (np.__version__, numba.__version__)


def test_export_writes_every_snapshot_as_read_back(case_file, ds, tmp_path, capsys):
    out = tmp_path / "vtk"
    assert main(["export", str(case_file), "--out", str(out)]) == 0
    # the tube is empty at t = 0 and 0.05 s: no grain file (meshio reads no grid without cells)
    assert ("grains.pvd (7 snapshots; 2 without grains, not written), slices.pvd (41 frames)"
            in capsys.readouterr().out)
    series = read_pvd(out / "grains.pvd")
    counts = ds.tube_snapshot_count.values
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    full = counts > 0
    assert counts[:2].tolist() == [0, 0] and full[2:].all()
    assert len(series) == 7 and not (out / "grains_00000.vtu").exists()
    assert [name for _, name in series] == [f"grains_{k:05d}.vtu" for k in np.nonzero(full)[0]]
    for (t, name), t_case, n, start in zip(series, ds.tube_snapshot_time.values[full], counts[full],
                                           starts[full]):
        assert t == pytest.approx(t_case, abs=1e-12)
        grains = read_vtk(out / name)
        sl = slice(start, start + n)
        assert grains["NumberOfPoints"] == n and grains["TimeValue"] == [t]
        np.testing.assert_array_equal(grains["points"], ds.tube_snapshot_position.values[sl])
        np.testing.assert_array_equal(grains["velocity_m_per_s"], ds.tube_snapshot_velocity.values[sl])
        np.testing.assert_array_equal(grains["angular_velocity_rad_per_s"],
                                      ds.tube_snapshot_angular_velocity.values[sl])
        np.testing.assert_array_equal(grains["grain_id"], ds.tube_snapshot_grain_id.values[sl])
        np.testing.assert_allclose(grains["radius_m"], 0.7e-3, rtol=1e-7)  # float32 of d/2


def test_export_writes_the_slice_fields_on_their_grid(case_file, ds, tmp_path):
    out = tmp_path / "vtk"
    assert main(["export", str(case_file), "--out", str(out)]) == 0
    series = read_pvd(out / "slices.pvd")
    assert len(series) == ds.sizes["time"] == 41
    k = 30
    assert series[k][0] == pytest.approx(float(ds.time[k]), abs=1e-12)
    grid = read_vtk(out / series[k][1])
    points = grid["points"]
    np.testing.assert_allclose(np.unique(points[:, 0]), np.arange(7) * 0.0035, atol=1e-15)
    np.testing.assert_allclose(np.unique(points[:, 1:]), [-0.0035, 0.0035])
    assert (grid["types"] == 12).all() and len(grid["types"]) == 6  # one hexahedron per slice
    assert grid["TimeValue"] == [series[k][0]]
    np.testing.assert_array_equal(grid["porosity"], ds.porosity.values[k])
    np.testing.assert_array_equal(grid["velocity_m_per_s"], ds.velocity.values[k])
    np.testing.assert_array_equal(grid["gas_pressure_Pa"], ds.gas_pressure.values[k])
    assert "README.txt" in {p.name for p in out.iterdir()}


@pytest.fixture(scope="module")
def exported(case_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("exported") / "vtk"
    assert main(["export", str(case_file), "--out", str(out)]) == 0
    return out


def _every_file(out: Path) -> list[tuple[float, Path]]:
    """(time, path) of every file of both collections; every .vtu of the folder is in one."""
    files = [(t, out / name) for pvd in ("grains.pvd", "slices.pvd") for t, name in read_pvd(out / pvd)]
    assert sorted(p for _, p in files) == sorted(out.glob("*.vtu"))
    return files


def test_time_value_is_field_data_of_the_dataset_before_its_piece(exported):
    """Where the VTK XML format puts a dataset's field data; VTK ignores it inside <Piece>."""
    for t, path in _every_file(exported):
        raw = path.read_bytes()
        head = raw[:raw.index(b"<AppendedData")].decode() + "</VTKFile>"
        grid = ET.fromstring(head).find("UnstructuredGrid")
        assert [child.tag for child in grid] == ["FieldData", "Piece"], path.name
        (array,) = grid.find("FieldData")
        assert array.get("Name") == "TimeValue" and float(array.text) == t, path.name
        assert grid.find("Piece").find("FieldData") is None


def test_every_export_file_is_read_by_meshio_with_its_time(exported, ds):
    meshio = pytest.importorskip("meshio")
    counts = ds.tube_snapshot_count.values
    for t, path in _every_file(exported):
        mesh = meshio.read(path)
        assert mesh.field_data["TimeValue"].tolist() == [t], path.name
        if path.name.startswith("grains_"):
            k = int(path.stem.split("_")[1])
            sl = slice(int(counts[:k].sum()), int(counts[:k + 1].sum()))
            np.testing.assert_array_equal(mesh.points, ds.tube_snapshot_position.values[sl])
            np.testing.assert_array_equal(mesh.point_data["grain_id"], ds.tube_snapshot_grain_id.values[sl])
            assert [block.type for block in mesh.cells] == ["vertex"]
        else:
            k = int(path.stem.split("_")[1])
            assert [block.type for block in mesh.cells] == ["hexahedron"]
            np.testing.assert_array_equal(mesh.cell_data["porosity"][0], ds.porosity.values[k])


def test_every_export_file_is_read_by_vtk_with_its_time(exported):
    """Runs where the `vtk` package is installed (a 140 MB wheel, not in the test extra)."""
    vtk = pytest.importorskip("vtk")
    for t, path in _every_file(exported):
        reader = vtk.vtkXMLUnstructuredGridReader()
        reader.SetFileName(str(path))
        reader.Update()
        data = reader.GetOutput()
        assert reader.GetErrorCode() == 0 and data.GetNumberOfPoints() > 0, path.name
        assert data.GetFieldData().GetArray("TimeValue").GetValue(0) == t, path.name


def test_export_of_a_file_without_whole_tube_snapshots_exits_2_naming_the_key(ds, tmp_path, capsys):
    bare = tmp_path / "bare.nc"
    ds.drop_vars(SNAPSHOT_VARS).to_netcdf(bare)
    out = tmp_path / "vtk"
    for command in (["export", str(bare), "--out", str(out)], ["animate", str(bare)]):
        assert main(command) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "output.tube_snapshot_interval > 0" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bare.nc"], "nothing written"


@pytest.mark.parametrize("command, message", [
    (["export", "missing.nc"], "case file 'missing.nc' does not exist"),
    (["animate", "{file}"], "cannot be read as NetCDF"),
    (["export", "{case}", "--out", "{file}"], "is a file; it must be a folder"),
    (["export", "{case}", "--out", "{full}"], "is a non-empty folder that is not a plugsim export"),
    (["animate", "{case}", "--out", "movie.avi"], "must end in one of .gif, .mp4, .png"),
    (["animate", "{case}", "--fps", "0"], "--fps 0: allowed 0 < fps <= 100"),
])
def test_bad_export_and_animate_input_exits_2_with_one_line(case_file, tmp_path, capsys, command, message):
    (tmp_path / "a_file").write_text("not NetCDF")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("mine")
    args = [a.format(case=case_file, file=tmp_path / "a_file", full=tmp_path / "full") for a in command]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert (tmp_path / "full" / "notes.txt").read_text() == "mine"


def test_mp4_without_ffmpeg_is_refused_before_any_work(case_file, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("engine.animate.shutil.which", lambda name: None)
    assert main(["animate", str(case_file), "--out", str(tmp_path / "m.mp4")]) == 2
    assert "needs ffmpeg on the PATH" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_animation_has_one_frame_per_snapshot(case_file, ds, tmp_path):
    gif, png = tmp_path / "grains.gif", tmp_path / "last.png"
    assert main(["animate", str(case_file), "--out", str(gif), "--fps", "5"]) == 0
    with Image.open(gif) as image:
        assert image.n_frames == ds.sizes["tube_snapshot_time"] == 9
        assert image.info["duration"] == 200  # ms per frame at 5 frames per second
    assert main(["animate", str(case_file), "--out", str(png)]) == 0
    with Image.open(png) as image:
        assert image.format == "PNG" and image.size[0] > 800
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grains.gif", "last.png"], "no temporary left"


def test_a_full_disk_is_one_line_exit_1_and_leaves_nothing(case_file, tmp_path, capsys, monkeypatch):
    """The disk fills while the slice files (export) or the GIF (animate) are written: one line
    naming the filesystem and the output, exit 1, no partial folder or file left."""
    import errno

    from matplotlib.animation import PillowWriter

    import engine.export

    def no_space(*args, **kw):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(engine.export, "_write_slices", no_space)
    monkeypatch.setattr(PillowWriter, "finish", no_space)
    for command, out in ((["export", str(case_file), "--out"], tmp_path / "vtk"),
                         (["animate", str(case_file), "--out"], tmp_path / "grains.gif")):
        assert main([*command, str(out)]) == 1
        from engine.output import filesystem
        mount, kind = filesystem(tmp_path)
        assert capsys.readouterr().err.splitlines() == [f"plugsim: error: no space left on {mount} ({kind}) writing {out}"]
    assert not list(tmp_path.iterdir()), "no partial output"

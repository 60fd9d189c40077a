"""`plugsim animate`: a GIF (or MP4) of a case file: the spatio-temporal slice porosity revealed
up to each whole-tube grain snapshot, above a side view of the grains in the tube at that time."""

from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .export import ExportError, open_case_file, require_tube_snapshots, tube_snapshots
from .output import DiskFullError, out_of_space

SUFFIXES = (".gif", ".mp4", ".png")  # .png: the last frame alone, a still


@dataclass
class Animation:
    """What animate wrote: file, frames, size (bytes)."""

    path: Path
    frames: int
    size: int


def check_out_file(out: Path) -> None:
    """Refuse an output name of another kind, a folder, or .mp4 without ffmpeg (ExportError)."""
    if out.suffix.lower() not in SUFFIXES:
        raise ExportError(f"--out {str(out)!r}: the name must end in one of {', '.join(SUFFIXES)}")
    if out.is_dir():
        raise ExportError(f"--out {str(out)!r} is a folder; give a file name ending in .gif, .mp4 or .png")
    if out.suffix.lower() == ".mp4" and shutil.which("ffmpeg") is None:
        raise ExportError(f"--out {str(out)!r}: writing .mp4 needs ffmpeg on the PATH, which is not "
                          f"there; write a .gif instead")


class _Frames:
    """The figure and its update for snapshot k."""

    def __init__(self, ds, snapshots: list):
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self.snapshots = snapshots
        self.time = ds["time"].values.astype(float)
        self.porosity = ds["porosity"].values.astype(float)
        x = ds["x"].values
        length = 2 * float(x[0]) * len(x)  # slice edges run from 0 to n * width
        r_mm = 0.5e3 * float(ds.attrs["tube_diameter"])
        speeds = np.concatenate([s[2][:, 0] for s in snapshots])
        v_low, v_high = np.percentile(speeds, [1, 99]) if len(speeds) else (0.0, 1.0)
        self.fig, (self.ax_p, self.ax_g) = plt.subplots(
            2, 1, sharex=True, figsize=(10, 5.2), gridspec_kw={"height_ratios": [3, 1.3]},
            layout="constrained")
        half = 0.5 * (self.time[-1] - self.time[0]) / max(len(self.time) - 1, 1)  # a frame's row
        self.image = self.ax_p.imshow(
            np.full_like(self.porosity, np.nan), origin="lower", aspect="auto", cmap="gray",
            vmin=0.35, vmax=1.0, interpolation="nearest",
            extent=[0, length, self.time[0] - half, self.time[-1] + half])
        self.fig.colorbar(self.image, ax=self.ax_p, label="slice porosity (1)")
        self.ax_p.set_ylabel("time t (s)")
        self.grains = self.ax_g.scatter([], [], c=[], cmap="plasma", vmin=min(0.0, v_low),
                                        vmax=max(v_high, 1e-3), linewidths=0)
        self.fig.colorbar(self.grains, ax=self.ax_g, label="axial velocity (m/s)")
        for side in (-r_mm, r_mm):
            self.ax_g.axhline(side, color="0.3", lw=0.8)
        self.ax_g.set_ylim(-1.15 * r_mm, 1.15 * r_mm)
        self.ax_g.set_xlim(0, length)
        self.ax_g.set_xlabel("x along the tube from the inlet (m)")
        self.ax_g.set_ylabel("z across the tube (mm)")
        # the side view is stretched along z: grains drawn at their true width along x (at least
        # 2 pt, to stay visible) but no larger than their true height
        self.fig.canvas.draw()
        box = self.ax_g.get_window_extent()
        d = float(ds.attrs["particle_diameter"])
        along = box.width * 72 / self.fig.dpi * d / length
        across = box.height * 72 / self.fig.dpi * 1e3 * d / (2.3 * r_mm)
        self.grains.set_sizes([min(across, max(along, 2.0)) ** 2])

    def draw(self, k: int):
        t, pos, vel = self.snapshots[k][:3]
        shown = np.where((self.time <= t + 1e-9)[:, None], self.porosity, np.nan)
        self.image.set_data(shown)
        self.grains.set_offsets(np.column_stack([pos[:, 0], 1e3 * pos[:, 2]]) if len(pos) else np.zeros((0, 2)))
        self.grains.set_array(vel[:, 0])
        self.ax_p.set_title(f"t = {t:.2f} s, {len(pos)} grains in the tube")
        return self.image, self.grains


def animate_case(case_file: str | Path, out: str | Path | None = None, fps: float = 10.0) -> Animation:
    """Write the animation of `case_file` to `out` (default: next to it, CASE.gif), one frame per
    whole-tube snapshot at `fps` frames per second; a .png `out` gets the last frame only.
    DiskFullError (nothing left behind) when the disk fills."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter

    case_file = Path(case_file)
    out = Path(out) if out is not None else case_file.with_suffix(".gif")
    check_out_file(out)
    if not 0 < fps <= 100:
        raise ExportError(f"--fps {fps:g}: allowed 0 < fps <= 100 (frames per second)")
    ds = open_case_file(case_file)
    require_tube_snapshots(ds, case_file)
    snapshots = list(tube_snapshots(ds))
    frames = _Frames(ds, snapshots)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f"{out.stem}.tmp-{os.getpid()}{out.suffix}")
    try:
        if out.suffix.lower() == ".png":
            frames.draw(len(snapshots) - 1)
            frames.fig.savefig(tmp, dpi=120)
            count = 1
        else:
            writer = PillowWriter(fps=fps) if out.suffix.lower() == ".gif" else FFMpegWriter(fps=fps)
            movie = FuncAnimation(frames.fig, frames.draw, frames=len(snapshots), blit=False, repeat=False)
            movie.save(tmp, writer=writer, dpi=100)
            count = len(snapshots)
        os.replace(tmp, out)
    except (OSError, RuntimeError, subprocess.CalledProcessError) as err:  # ffmpeg fails as a process
        if out_of_space(err, out.parent):
            raise DiskFullError(out) from err
        raise
    finally:
        plt.close(frames.fig)
        if tmp.exists():
            tmp.unlink()
    return Animation(out, count, out.stat().st_size)

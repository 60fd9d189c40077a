"""Matplotlib figures for each figure family of the papers.

Every function draws into `ax` when given and returns its Figure; without `ax` it makes a new
Figure (matplotlib.figure.Figure: no pyplot state, saved with the Agg canvas). Axes carry SI units
or the papers' units (hPa/m, cP, kg/h); a case-file variable's axis label and factor are the
contract's (analysis/contract.py).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from .casefile import geometry, seconds
from .contract import label as variable_label
from .curves import unresolved_bulk

HPA = 100.0  # Pa per hPa
PARAMETERS = {  # dotted config key -> (axis label, factor from SI to the label's unit)
    "gas.superficial_velocity": ("superficial gas velocity $v_s$ (m/s)", 1.0),
    "feed.mass_flow_kg_h": ("grain mass flow (kg/h)", 1.0),
    "gas.viscosity": (r"gas viscosity $\eta$ (cP)", 1e3),
    "particles.friction": (r"Coulomb coefficient $\mu$", 1.0),
    "wall.friction": (r"wall Coulomb coefficient $\mu_w$", 1.0),
    "gas.pressure": ("pressure $P_0$ (hPa)", 1.0 / HPA),
    "tube.inclination_deg": ("inclination (degree)", 1.0),
    "feed.entry_velocity": ("grain entry velocity (m/s)", 1.0),
    "particles.restitution": ("restitution coefficient $e$", 1.0),
    "particles.stiffness": ("normal stiffness $k_n$ (N/m)", 1.0),
    "numerics.time_step_fraction": (r"time step $\Delta t/t_c$", 1.0),
    "numerics.gas_interval": ("grain steps per gas update", 1.0),
    "gas.nodes_x": ("axial gas nodes", 1.0),
    "run.seed": ("random seed", 1.0),
}
STATISTICS = {
    "rate": "{Slug} rate (1/s)",
    "min_porosity": "minimal porosity in {slug}s",
    "max_velocity": "maximal granular velocity (m/s)",
    "length": "{slug} core length, porosity < 0.6 (m)",
    "length_total": "{slug} length with its ends (m)",
    "slug_velocity": "{slug} travel speed (m/s)",
    "front_velocity": "{slug} front speed (m/s)",
    "n_particles": "grains per {slug}",
}
# Regime (analysis.curves.regime) -> marker and legend text; blocked points are not joined to the
# curve (the tube did not deliver the feed the point is labelled with).
REGIME_MARKERS = {"bulk": ("s", "bulk (tube filled)"), "slug": ("o", "slug conveying"),
                  "plug": ("o", "plug conveying"), "sticking plugs": ("D", "sticking plugs"),
                  "sliding layer": ("v", "sliding layer (no slugs)"),
                  "dilute": ("^", "dilute (no plugs)")}
BLOCKED = ("X", "blocked (delivers < half its feed;\nnot part of the curve)")


def _axes(ax=None, size=(5.0, 3.5)):
    if ax is None:
        fig = Figure(figsize=size, layout="constrained")
        return fig, fig.add_subplot()
    return ax.figure, ax


def _words(vertical) -> dict:
    return {"slug": "plug", "Slug": "Plug"} if vertical else {"slug": "slug", "Slug": "Slug"}


def porosity_image(ds: xr.Dataset, ax=None, t_range: tuple[float, float] | None = None,
                   vmin: float = 0.4, vmax: float = 1.0):
    """Spatio-temporal porosity image (H1, H4, H20, V3, V5, V6): time (s) across, position (m) up;
    the papers' grey scale, dark = low porosity, light = high porosity."""
    fig, ax = _axes(ax, (7.0, 3.0))
    por = ds["porosity"].transpose("time", "x")
    t = seconds(ds["time"].values)
    if t_range is not None:
        keep = (t >= t_range[0]) & (t <= t_range[1])
        por, t = por[keep], t[keep]
    x = np.asarray(ds["x"].values)
    dt = np.median(np.diff(t)) if t.size > 1 else 0.01
    dx = np.median(np.diff(x))
    im = ax.imshow(por.values.T, origin="lower", aspect="auto", cmap="gray", vmin=vmin, vmax=vmax,
                   extent=(t[0] - dt / 2, t[-1] + dt / 2, x[0] - dx / 2, x[-1] + dx / 2),
                   interpolation="nearest")
    axis = geometry(ds).axis_name
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{axis} (m)")
    fig.colorbar(im, ax=ax, label=variable_label("porosity")[0])
    return fig


def slug_rate(stats: pd.DataFrame, ax=None):
    """Slugs per second passing each position (H8, V9), error bars sqrt(n)/duration."""
    fig, ax = _axes(ax)
    words = _words(stats.attrs.get("vertical"))
    ax.errorbar(stats["x"], stats["rate"], yerr=stats["rate_sem"], fmt="o-", ms=3, capsize=2)
    ax.set_xlabel(f"{'z' if stats.attrs.get('vertical') else 'x'} (m)")
    ax.set_ylabel(STATISTICS["rate"].format(**words))
    ax.set_ylim(bottom=0)
    return fig


def slug_statistic(stats: pd.DataFrame, quantity: str, ax=None):
    """Mean of a slug property against position with standard-error bars and dotted quartile lines
    ("half of the slugs lie between"), as H9-H11, V10-V12."""
    fig, ax = _axes(ax)
    words = _words(stats.attrs.get("vertical"))
    ax.errorbar(stats["x"], stats[f"{quantity}_mean"], yerr=stats[f"{quantity}_sem"], fmt="o",
                ms=3, capsize=2, color="k", label="mean")
    ax.plot(stats["x"], stats[f"{quantity}_q25"], ":", color="k", label="quartiles")
    ax.plot(stats["x"], stats[f"{quantity}_q75"], ":", color="k")
    ax.set_xlabel(f"{'z' if stats.attrs.get('vertical') else 'x'} (m)")
    ax.set_ylabel(STATISTICS.get(quantity, quantity).format(**words))
    return fig


def slug_profile(profile: xr.Dataset, fields="porosity", ax=None):
    """Averaged slug profile(s) against dx/d with a standard-error band (H12-H16, V13-V17).

    fields: one name or several sharing a unit (["drag_force", "particle_force"] for H14/V15).
    The wall stress gets the dotted weight of the resting layer (H15) when it is non-zero.
    """
    fig, ax = _axes(ax)
    fields = [fields] if isinstance(fields, str) else list(fields)
    x = profile["dx_d"].values
    label, factor = variable_label(fields[0])
    for name in fields:
        mean, sem = profile[name].values * factor, profile[f"{name}_sem"].values * factor
        line, = ax.plot(x, mean, label=name.replace("_", " "))
        ax.fill_between(x, mean - sem, mean + sem, color=line.get_color(), alpha=0.25, lw=0)
    if "wall_stress" in fields and "resting_layer_stress" in profile:
        rest = profile["resting_layer_stress"].values
        if np.nanmax(np.abs(rest)) > 0:
            ax.plot(x, rest, ":", color="k", label="weight of resting layer")
    axis = "z" if profile.attrs.get("vertical") else "x"
    ax.set_xlabel(rf"$\Delta {axis}/d$")
    ax.set_ylabel(label)
    ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    if len(fields) > 1 or "wall_stress" in fields:
        ax.legend(frameon=False)
    return fig


def cross_section(section: xr.Dataset, ax=None):
    """Grain volume fraction over the cross-section (H17): black = porosity 100 %, white = 0 %."""
    fig, ax = _axes(ax, (3.5, 3.5))
    mm = 1e3
    y, z = section["y"].values * mm, section["z"].values * mm
    half = (y[1] - y[0]) / 2
    ax.imshow(section["volume_fraction"].values, origin="lower", cmap="gray", vmin=0, vmax=1,
              extent=(y[0] - half, y[-1] + half, z[0] - half, z[-1] + half), interpolation="nearest")
    ax.set_xlabel("y (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_aspect("equal")
    return fig


def cross_section_strip(series: xr.Dataset, ax=None, t_range: tuple[float, float] | None = None):
    """Consecutive cross-sections side by side, time running left to right (H17)."""
    if t_range is not None:
        series = series.sel(snapshot_time=slice(*t_range))
    frames = series["volume_fraction"].values  # (time, z, y)
    n = frames.shape[0]
    fig, ax = _axes(ax, (max(3.0, 0.6 * n), 1.2))
    strip = np.concatenate(list(frames), axis=1) if n else np.zeros((1, 1))
    ax.imshow(strip, origin="lower", cmap="gray", vmin=0, vmax=1, interpolation="nearest",
              aspect="equal")
    t = seconds(series["snapshot_time"].values)
    ax.set_yticks([])
    width = frames.shape[2] if n else 1
    ax.set_xticks((np.arange(n) + 0.5) * width, [f"{v:.2f}" for v in t], rotation=90, fontsize=6)
    ax.set_xlabel("time (s)")
    return fig


def velocity_height(profile: xr.Dataset, ax=None, label: str | None = None):
    """Mean axial grain velocity (m/s) against height z (mm) through a slug (H19)."""
    fig, ax = _axes(ax, (3.5, 3.5))
    ax.plot(profile["velocity"].values, profile["height"].values * 1e3, "o-", ms=3, label=label)
    ax.set_xlabel(variable_label("velocity")[0])
    ax.set_ylabel("height z (mm)")
    if label:
        ax.legend(frameon=False)
    return fig


def velocity_height_image(series: xr.Dataset, ax=None):
    """Axial grain velocity over time (s) and height z (mm) at one position as a slug passes (H18)."""
    fig, ax = _axes(ax, (6.0, 3.0))
    t = seconds(series["snapshot_time"].values)
    h = series["height"].values * 1e3
    dt = np.median(np.diff(t)) if t.size > 1 else 0.01
    dh = h[1] - h[0]
    im = ax.imshow(series["velocity"].transpose("height", "snapshot_time").values, origin="lower",
                   aspect="auto", cmap="viridis", interpolation="nearest",
                   extent=(t[0] - dt / 2, t[-1] + dt / 2, h[0] - dh / 2, h[-1] + dh / 2))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("height z (mm)")
    fig.colorbar(im, ax=ax, label=variable_label("velocity")[0])
    return fig


def slug_grains(positions: np.ndarray, velocities: np.ndarray, x_range: tuple[float, float],
                tube_radius: float, particle_diameter: float):
    """Grains (positions m, velocities m/s, (n, 3)) as spheres in the stretch x_range (m) of the
    tube, a 3-D scatter in mm coloured by axial velocity (H2). Every grain given is drawn."""
    mm = 1e3
    length = x_range[1] - x_range[0]
    fig = Figure(figsize=(9.0, 3.0))
    ax = fig.add_axes((0.0, 0.0, 0.9, 1.0), projection="3d")
    ax.set_proj_type("ortho")  # every grain drawn at the same scale along the stretch
    ax.set_xlim(x_range[0] * mm, x_range[1] * mm)
    ax.set_ylim(-tube_radius * mm, tube_radius * mm)
    ax.set_zlim(-tube_radius * mm, tube_radius * mm)
    ax.set_box_aspect((length, 2 * tube_radius, 2 * tube_radius), zoom=2.2)
    ax.view_init(elev=12, azim=-82)
    size = _marker_points(ax, x_range[0] * mm, particle_diameter * mm) ** 2
    # clip_on=False: a 3-D Axes' box stays square (the middle 3 in of the 9 in figure) and the
    # zoom draws the stretch beyond it; clipped to that box, only the middle third of it showed.
    sc = ax.scatter(positions[:, 0] * mm, positions[:, 1] * mm, positions[:, 2] * mm, s=size,
                    c=velocities[:, 0], cmap="viridis", depthshade=True, edgecolors="k",
                    linewidths=0.2, clip_on=False)
    ax.set_xlabel("x (mm)", labelpad=12)
    ax.set_yticks([])
    ax.set_zticks([])
    cax = fig.add_axes((0.9, 0.2, 0.015, 0.6))
    fig.colorbar(sc, cax=cax, label="axial velocity (m/s)")
    return fig


def _marker_points(ax, x0: float, diameter: float) -> float:
    """Rendered length (points) of `diameter` (data units) along x at x0 in a 3-D Axes."""
    from mpl_toolkits.mplot3d import proj3d
    ax.apply_aspect()  # the Axes' box as drawn
    xs, ys, _ = proj3d.proj_transform(np.array([x0, x0 + diameter]), np.zeros(2), np.zeros(2),
                                      ax.get_proj())
    ends = ax.transData.transform(np.column_stack([xs, ys]))
    return float(np.hypot(*(ends[1] - ends[0]))) * 72.0 / ax.figure.dpi


def radial_profile(profile: xr.Dataset, field: str = "porosity", ax=None):
    """Radial porosity (V18) or velocity (V19, m/s) through the averaged plug against r/d."""
    fig, ax = _axes(ax)
    d = profile.attrs.get("particle_diameter")
    r = profile["r"].values / d
    sem = profile[f"{field}_sem"].values if f"{field}_sem" in profile else None
    ax.errorbar(r, profile[field].values, yerr=sem, fmt="o-", ms=3, capsize=2)
    ax.set_xlabel("r/d")
    ax.set_ylabel(variable_label(field)[0])
    return fig


def characteristic_curves(table: pd.DataFrame, x: str = "gas.superficial_velocity",
                          group: str | None = "feed.mass_flow_kg_h", ax=None,
                          title: str | None = None, group_label: str | None = None):
    """Pressure drop (hPa/m, standard-error bars) against a swept parameter, one curve per group
    value (H3, V4: against v_s for each mass flow; H5-H7, H21, V7, V8).

    Markers show the regime (REGIME_MARKERS), explained in the legend. Blocked points (regime
    "blocked") are drawn as red crosses and not joined to their curve: the tube did not deliver
    the feed they are labelled with. A black cross marks a bulk point whose case did not resolve
    the tangential dashpot (column `dashpot_resolved` False): a packed bed there carries a
    time-step error (docs/performance.md, "The tangential dashpot and the time step").
    `group_label` titles the legend of the groups (default: the group key's axis label).
    """
    fig, ax = _axes(ax)
    label, factor = PARAMETERS.get(x, (x, 1.0))
    groups = [(None, table)] if group is None or group not in table else list(table.groupby(group))
    glabel, gfactor = PARAMETERS.get(group, (group, 1.0)) if group else ("", 1.0)
    unit = glabel[glabel.rfind("(") + 1:-1] if glabel.endswith(")") else ""
    flagged, regimes = False, set()
    group_handles = []
    for value, part in groups:
        part = part.sort_values(x)
        xs = part[x].to_numpy(dtype=float) * factor
        dp = part["pressure_drop"].to_numpy(dtype=float) / HPA
        err = part["pressure_drop_sem"].to_numpy(dtype=float) / HPA
        regime = part["regime"].astype(str).to_numpy() if "regime" in part else np.full(len(part), "")
        blocked = regime == "blocked"
        name = None if value is None else (f"{value * gfactor:g} {unit}".strip()
                                           if isinstance(value, (int, float, np.number)) else str(value))
        line = ax.errorbar(xs[~blocked], dp[~blocked], yerr=err[~blocked], fmt="-", capsize=2,
                           label=name)
        color = line[0].get_color()
        if name is not None:
            group_handles.append(line)
        for key, (marker, _) in REGIME_MARKERS.items():
            sel = regime == key
            if sel.any():
                ax.plot(xs[sel], dp[sel], marker, color=color, ms=5)
                regimes.add(key)
        if blocked.any():
            ax.errorbar(xs[blocked], dp[blocked], yerr=err[blocked], fmt=BLOCKED[0], color="tab:red",
                        mfc="none", ms=8, capsize=2)
            regimes.add("blocked")
        unresolved = unresolved_bulk(part).to_numpy()
        if unresolved.any():
            ax.plot(xs[unresolved], dp[unresolved], "x", color="k", ms=8, mew=1.2)
            flagged = True
    ax.set_xlabel(label)
    ax.set_ylabel("pressure drop (hPa/m)")
    ax.set_ylim(bottom=0)
    ax.ticklabel_format(axis="x", useOffset=False)
    if title:
        ax.set_title(title, fontsize=9)
    handles = [ax.plot([], [], REGIME_MARKERS[k][0], color="0.3", ms=5, label=REGIME_MARKERS[k][1])[0]
               for k in REGIME_MARKERS if k in regimes]
    if "blocked" in regimes:
        handles.append(ax.plot([], [], BLOCKED[0], color="tab:red", mfc="none", ms=8, label=BLOCKED[1])[0])
    if flagged:
        handles.append(ax.plot([], [], "x", color="k", ms=8, mew=1.2, label=UNRESOLVED_BULK)[0])
    if group_handles and len(groups) > 1:
        first = ax.legend(handles=group_handles, frameon=False, fontsize=7, loc="upper right",
                          title=group_label or glabel, title_fontsize=7)
        ax.add_artist(first)
    if handles:
        ax.legend(handles=handles, frameon=False, fontsize=7, loc="upper center", title="regime",
                  title_fontsize=7)
    return fig


def parameter_words(key: str) -> tuple[str, str, float]:
    """(name in words, unit, factor from SI to that unit) of a case key, from PARAMETERS; the key
    itself where it has no entry."""
    label, factor = PARAMETERS.get(key, (key, 1.0))
    if label.endswith(")") and " (" in label:
        name, unit = label[:-1].rsplit(" (", 1)
        return name, unit, factor
    return label, "", factor


def parameter_value(key: str, value) -> str:
    """A case key's value in the papers' unit, e.g. '2.49 kg/h' or '0.067 cP'."""
    _, unit, factor = parameter_words(key)
    try:
        return f"{float(value) * factor:g} {unit}".strip()
    except (TypeError, ValueError):
        return str(value)


def curve_title(table: pd.DataFrame, x: str) -> str:
    """Title in words of a curve figure: the tube and what is plotted against what."""
    vertical = None
    if "vertical" in table and len(table):
        vertical = str(table["vertical"].iloc[0]).strip().lower() in ("true", "1", "1.0")
    elif "tube.inclination_deg" in table and len(table):
        vertical = float(table["tube.inclination_deg"].iloc[0]) >= 45.0
    tube = {True: "Vertical tube: ", False: "Horizontal tube: ", None: ""}[vertical]
    return f"{tube}pressure drop against the {parameter_words(x)[0]}"


UNRESOLVED_BULK = "bulk, step not converged\n(tangential dashpot)"


def undrawn_axes(fig) -> list[str]:
    """Panels of `fig` that draw no data: no line, marker, collection, patch or image with a finite
    value (legend proxies with no points do not count). Named by title, else y label, else index."""
    empty = []
    for k, ax in enumerate(fig.axes):
        if not _draws_data(ax):
            empty.append(ax.get_title() or ax.get_title(loc="left") or ax.get_ylabel() or f"panel {k + 1}")
    return empty


def _draws_data(ax) -> bool:
    for line in ax.get_lines():
        xy = np.asarray(line.get_xydata(), dtype=float)
        if xy.size and np.isfinite(xy).all(axis=-1).any():
            return True
    for coll in ax.collections:
        pts = getattr(coll, "_offsets3d", None)
        if pts is not None:
            if len(pts[0]):
                return True
            continue
        offsets = np.asarray(coll.get_offsets(), dtype=float)
        if len(coll.get_paths()) and (offsets.size == 0 or np.isfinite(offsets).any()):
            if any(len(path.vertices) and np.isfinite(path.vertices).all(axis=1).any()
                   for path in coll.get_paths()):
                return True
    for image in ax.images:
        data = np.ma.filled(np.ma.asarray(image.get_array(), dtype=float), np.nan)
        if data.size and np.isfinite(data).any():
            return True
    return any(p.get_visible() for p in ax.patches)


KNOBS = {  # work-precision knobs -> legend label with unit
    "numerics.time_step_fraction": r"time step $\Delta t/t_c$",
    "particles.stiffness": r"stiffness $k_n$ (N/m)",
    "gas.nodes_x": "axial gas nodes",
    "numerics.gas_interval": "grain steps per gas update",
    "run.seed": "seed only (noise floor)",
}
OBSERVABLE_LABELS = {"pressure_drop": "pressure drop", "slug_velocity": "slug velocity",
                     "slug_length": "slug length"}


def work_precision(tables: list[pd.DataFrame], defaults: dict | None = None):
    """Relative error of pressure drop, slug velocity and slug length against the CPU time of
    each case (one core: its wall time on an otherwise idle machine), from
    analysis.precision.relative_errors tables, one per knob; one row of panels per flow regime
    (the tables' `regime` column, analysis.precision.by_regime). Filled markers: error resolved
    (> 2 combined standard errors); open markers: within that noise, whose one-standard-error level
    is the dotted line. Dashed grey: twice the run-to-run scatter of the row's regime (of its seed
    study when there is one, analysis.precision.run_to_run_scatter); the seed study's points are
    not joined. A star marks each knob's default (`defaults`: parameter -> value); squares at the
    bottom mark the references (error 0). A knob whose reference has no value of an observable (no
    slug detected in a bulk bed, say) is named in that panel instead of drawn. The legend stands
    right of each row."""
    from .precision import by_regime

    regimes = by_regime(tables)
    fig = Figure(figsize=(11.0, 3.8 * len(regimes)), layout="constrained")
    axes = np.atleast_2d(fig.subplots(len(regimes), len(OBSERVABLE_LABELS), sharex=True))
    for row, (regime, group) in zip(axes, regimes.items()):
        _work_precision_row(row, group, defaults or {})
        label = "relative error against the reference"
        row[0].set_ylabel(f"{regime}\n{label}" if regime else label)
        row[-1].legend(frameon=False, fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    for ax in axes[-1]:
        ax.set_xlabel("CPU time of the case (s, one core)")
    return fig


# Log-axis labels at 1, 2 and 5 times a power of ten only, as plain numbers (100, 200, 500, 1000).
_ONE_TWO_FIVE = FuncFormatter(lambda v, _: f"{v:g}" if v > 0 and f"{v:.0e}"[0] in "125" else "")


def _work_precision_row(axes, tables: list[pd.DataFrame], defaults: dict) -> None:
    """One regime's panels of `work_precision`, one per observable."""
    from .precision import SEED, run_to_run_scatter

    scatter = run_to_run_scatter(tables)
    floor = 3e-3  # the references (error 0) are drawn here on the log axis
    for ax, (q, name) in zip(axes, OBSERVABLE_LABELS.items()):
        missing = []
        for table in tables:
            knob = table["parameter"].iloc[0]
            ref = table["is_reference"].to_numpy(dtype=bool)
            if not np.isfinite(table.loc[ref, q].to_numpy(dtype=float)).any():
                missing.append(KNOBS.get(knob, knob))
            part = table.loc[~ref].sort_values("cpu_time_s")
            t = part["cpu_time_s"].to_numpy(dtype=float)
            err = np.maximum(part[f"{q}_error"].to_numpy(dtype=float), floor)
            resolved = part[f"{q}_resolved"].to_numpy(dtype=bool)
            noise_only = knob == SEED  # seeds are not an axis: points only
            line = ax.plot(t, err, ls="none" if noise_only else "-", marker="o" if noise_only else None,
                           mfc="white", ms=5, lw=0.8, label=KNOBS.get(knob, knob))[0]
            color = line.get_color()
            ax.plot(t[resolved], err[resolved], "o", color=color, ms=5)
            ax.plot(t[~resolved], err[~resolved], "o", mfc="white", color=color, ms=5)
            if not noise_only:  # the seeds' own noise would join them into a line
                ax.plot(t, part[f"{q}_noise"].to_numpy(dtype=float), ":", color=color, lw=0.8)
            for ti, ei, v in zip(t, err, part["value"]):
                ax.annotate(f"{v:g}", (ti, ei), textcoords="offset points", xytext=(3, 3), fontsize=6,
                            color=color)
            ax.plot(table.loc[ref, "cpu_time_s"], [floor], "s", color=color, ms=5)
            if knob in defaults:
                sel = np.isclose(part["value"].to_numpy(dtype=float), float(defaults[knob]))
                ax.plot(t[sel], err[sel], "*", color=color, ms=13, mfc="none")
        if np.isfinite(scatter[q]):
            ax.axhline(2 * scatter[q], color="0.5", ls="--", lw=0.8)
            ax.annotate("2 x run-to-run scatter", (0.02, 2 * scatter[q]), xycoords=("axes fraction", "data"),
                        xytext=(0, 2), textcoords="offset points", fontsize=6, color="0.4")
        if missing:
            ax.text(0.02, 0.02, "no value in the reference run:\n" + "\n".join(missing), transform=ax.transAxes,
                    fontsize=6, color="0.3", va="bottom")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_major_formatter(_ONE_TWO_FIVE)
        ax.xaxis.set_minor_formatter(_ONE_TWO_FIVE)  # all minor labels would overlap on a short decade
        ax.set_ylim(bottom=floor / 1.5)
        ax.set_title(name, fontsize=10)


TARGETS = {  # calibration target quantity -> (axis label, factor from SI to its unit)
    "pressure_drop": ("pressure drop (hPa/m)", 1.0 / HPA),
    "plug_velocity": ("plug velocity (m/s)", 1.0),
    "plug_length": ("plug length (cm)", 100.0),
}


def calibration_misfit(first: np.ndarray, second: np.ndarray, chi2: np.ndarray, keys: tuple[str, ...],
                       design: pd.DataFrame, values: np.ndarray, std: np.ndarray):
    """Misfit map of a calibration (analysis.calibration.misfit_grid): chi2 above its minimum over
    the first two fitted parameters, its 68 % and 95 % contours for two parameters (2.30, 6.18),
    the simulated design points and the fitted values with their standard deviations."""
    fig = Figure(figsize=(5.0, 4.0), layout="constrained")
    ax = fig.add_subplot()
    (xname, xunit, xf), (yname, yunit, yf) = parameter_words(keys[0]), parameter_words(keys[1])
    delta = chi2 - np.nanmin(chi2)
    image = ax.pcolormesh(first * xf, second * yf, np.log10(1.0 + delta), shading="gouraud", cmap="viridis_r")
    fig.colorbar(image, ax=ax, label=r"$\log_{10}(1 + \chi^2 - \chi^2_{min})$")
    ax.contour(first * xf, second * yf, delta, levels=[2.30, 6.18], colors=["w", "w"],
               linestyles=["-", "--"], linewidths=1.0)
    ax.plot(design[keys[0]] * xf, design[keys[1]] * yf, "k.", ms=6, clip_on=False, label="simulated cases")
    ax.errorbar([values[0] * xf], [values[1] * yf], xerr=[std[0] * xf], yerr=[std[1] * yf], fmt="r*",
                ms=10, capsize=3, label="fitted ± 1 s.d.")
    ax.set_xlim(first[0] * xf, first[-1] * xf)  # the bounds: cases on them sit on the frame
    ax.set_ylim(second[0] * yf, second[-1] * yf)
    ax.set_xlabel(f"{xname} ({xunit})" if xunit else xname)
    ax.set_ylabel(f"{yname} ({yunit})" if yunit else yname)
    ax.set_title("calibration misfit (contours: 68 %, 95 %)", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    return fig


def measured_against_fitted(table: pd.DataFrame, what: str = "fitted"):
    """One panel per measured quantity: each operating point's measured value +- its error and the
    model's (analysis.calibration.fitted_table columns `fitted`, `fitted_std`). A model point whose
    case has no error of its own (column `own_error_known` false) is drawn open: its bar is the
    fit's part only."""
    quantities = [q for q in TARGETS if q in set(table["quantity"])]
    fig = Figure(figsize=(3.2 * len(quantities), 3.2), layout="constrained")
    for k, quantity in enumerate(quantities):
        ax = fig.add_subplot(1, len(quantities), k + 1)
        rows = table[table["quantity"] == quantity]
        label, factor = TARGETS[quantity]
        x = np.arange(len(rows))
        known = rows["own_error_known"].to_numpy(bool) if "own_error_known" in rows else np.ones(len(rows), bool)
        ax.errorbar(x - 0.08, rows["value"] * factor, yerr=rows["error"] * factor, fmt="ks", capsize=3,
                    label="measured ± 1 s.d.")
        for drawn, style, bar in ((known, {"fmt": "ro"}, "± 1 s.d."),
                                  (~known, {"fmt": "o", "mfc": "none", "color": "r"}, "± the fit's part only")):
            if drawn.any():
                ax.errorbar(x[drawn] + 0.08, rows[what][drawn] * factor, yerr=rows[f"{what}_std"][drawn] * factor,
                            capsize=3, label=f"{what} model {bar}", **style)
        ax.set_xticks(x, [str(v) for v in rows["label"]])
        ax.set_xlim(-0.6, len(rows) - 0.4)
        ax.set_xlabel("operating point")
        ax.set_ylabel(label)
    legend = {}  # below the panels, once per kind of marker
    for ax in fig.axes:
        legend.update({bars.get_label(): bars for bars in ax.containers})
    fig.legend(list(legend.values()), list(legend), loc="outside lower center", ncols=len(legend), fontsize=7)
    return fig

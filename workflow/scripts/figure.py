"""Rule figure: one paper figure (H01..H21, V03..V19) as PNG + PDF + caption text.

The kind (config figures.<fig>.kind) picks a small function below through the registry of figure
kinds (workflow/scripts/figure_kinds.py, which also says what each kind reads); each draws with the
analysis.plots function of that figure family and returns the figure plus facts for the caption
(numbers measured on the data drawn). The caption text starts with params.caption (title and the
parameters of the cases, written when the workflow is parsed).

Standalone (the params are the figure's config entry):
    python workflow/scripts/figure.py --input statistics=results/statistics/h_default/base.csv \
        --output png=/tmp/H08.png --output pdf=/tmp/H08.pdf --output txt=/tmp/H08.txt \
        --params 'spec={kind: slug_rate}' --params 'caption=H08 test'
"""

import math

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from _helpers import (ensure_parent, note, read_table, save_figure, setup_logging,
                      snakemake_or_cli)
from analysis.timeseries import NOT_CONVERGED
from figure_kinds import KINDS as FIGURE_KINDS

HPA = 100.0


def _list(value) -> list:
    """A named input as a list (Snakemake gives a list for list inputs, the CLI a string)."""
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _open(path) -> xr.Dataset:
    with xr.open_dataset(path) as ds:
        return ds.load()


def _case(path):
    from analysis.casefile import open_case
    return open_case(path)


def _last_window(ds, seconds_shown):
    from analysis.casefile import seconds
    t = seconds(ds["time"].values)
    return (max(float(t[0]), float(t[-1]) - seconds_shown), float(t[-1]))


def _window_facts(ds, t_range) -> str:
    """Mean grains in the tube and pressure drop over the window drawn, as in the papers' captions,
    with the tables' estimator (a window drawn is not the steady window of the tables)."""
    from analysis.casefile import geometry, seconds
    from analysis.curves import sampling_interval
    from analysis.timeseries import mean_error
    t = seconds(ds["time"].values)
    sel = (t >= t_range[0]) & (t <= t_range[1])
    step = sampling_interval(t)
    grains = mean_error(ds["n_particles"].values[sel], step)
    dp = mean_error(ds["pressure_drop"].values[sel] / geometry(ds).tube_length / HPA, step)
    both = grains.converged and dp.converged
    text = (f"shown: t = {t_range[0]:.2f}-{t_range[1]:.2f} s; on average {_value(grains, '.0f', both)} "
            f"grains in the tube and a pressure drop of {_value(dp, '.3g', both)} hPa/m over this window")
    text = text if both else text + f" (no standard errors: {NOT_CONVERGED})"
    return f"{text}; {_start_text(ds)}"


def _value(est, spec: str, with_error: bool) -> str:
    """'mean +- standard error' or the mean alone."""
    return f"{est.mean:{spec}} +- {est.error:.2g}" if with_error else f"{est.mean:{spec}}"


def _start_text(ds) -> str:
    """How the case file says its run started and stopped."""
    a = ds.attrs
    start = (f"warm start from {a['initial_state']} ({int(a.get('initial_particles', 0))} grains)"
             if a.get("initial_state") else "started from an empty tube")
    return f"{start}; stopped: {a.get('stop_reason', 'unknown')}"


# ---- one function per kind: (inputs, spec, analysis settings) -> (Figure, [facts]) ------------

def porosity_image(inp, spec, settings):
    from analysis.plots import porosity_image as draw
    ds = _case(_list(inp.cases)[0])
    window = _last_window(ds, float(settings.get("image_window", 4.0)))
    return draw(ds, t_range=window), [_window_facts(ds, window)]


def porosity_image_pair(inp, spec, settings):
    from analysis.plots import porosity_image as draw
    fig = Figure(figsize=(7.0, 5.5), layout="constrained")
    cases = _list(inp.cases)
    axes = fig.subplots(len(cases), 1)
    facts = []
    for label, ax, path in zip("abcdef", np.atleast_1d(axes), cases):
        ds = _case(path)
        window = _last_window(ds, float(settings.get("image_window", 4.0)))
        draw(ds, ax=ax, t_range=window)
        ax.set_title(f"({label})", loc="left", fontsize=9)
        facts.append(f"({label}) {_window_facts(ds, window)}")
    return fig, facts


def grains_3d(inp, spec, settings):
    """H2: the grains of a slug as spheres (a 3-D scatter), coloured by axial velocity. The snapshot
    and slug are those where a slug of the profile selection (else any slug) holds the most grains
    of the snapshots (analysis.snapshots.slug_in_snapshots), so the stretch drawn shows a slug."""
    from analysis.casefile import geometry
    from analysis.plots import slug_grains
    from analysis.snapshots import slug_in_snapshots, snapshot, snapshot_times
    ds = _case(inp.case)
    geo = geometry(ds)
    selection = read_table(inp.selection)
    slugs = read_table(inp.slugs)
    times = snapshot_times(ds)
    stretch = float(settings.get("grains_stretch", 0.113))
    facts = []
    chosen = slug_in_snapshots(ds, slugs, selection["slug_id"] if len(selection) else ())
    if chosen is not None:
        k, row = chosen
        center = float(row["x_center"])
        picked = "of the profile selection" if len(selection) and row["slug_id"] in set(
            selection["slug_id"]) else "not in the profile selection (none of those is in a snapshot)"
        facts.append(f"slug {int(row['slug_id'])} ({picked}) at t = {times[k]:.2f} s, centre x = "
                     f"{center:.3f} m, length with its ends {row.get('length_total', float('nan')) * 100:.1f} cm, "
                     f"about {row['n_particles']:.0f} grains in its core")
    else:
        k = len(times) - 1
        _, pos, _ = snapshot(ds, k)
        center = float(np.mean(pos[:, 0])) if len(pos) else geo.tube_length / 2
        facts.append(f"no slug in any snapshot of this run: last snapshot (t = {times[k]:.2f} s)")
    _, pos, vel = snapshot(ds, k)
    x_range = (center - stretch / 2, center + stretch / 2)
    inside = (pos[:, 0] >= x_range[0]) & (pos[:, 0] <= x_range[1])
    fig = slug_grains(pos[inside], vel[inside], x_range, geo.tube_radius, geo.particle_diameter)
    mm = 1e3
    facts.append(f"{int(inside.sum())} grains in the {stretch * 100:.1f} cm stretch drawn "
                 f"(x = {x_range[0] * mm:.0f}-{x_range[1] * mm:.0f} mm){_snapshot_window(ds, x_range)}")
    return fig, facts


def _snapshot_window(ds, x_range) -> str:
    """'' or why part of the stretch drawn holds no grain: the snapshots record only
    output.snapshot_x_min .. x_max."""
    from analysis.casefile import config
    try:
        cfg = config(ds)
        lo, hi = float(cfg["output.snapshot_x_min"]), float(cfg["output.snapshot_x_max"])
    except (KeyError, ValueError):
        return ""
    if lo <= x_range[0] and x_range[1] <= hi:
        return ""
    return f"; the snapshots hold only the grains in x = {lo * 1e3:.0f}-{hi * 1e3:.0f} mm"


def _curve_facts(table, x, group=None) -> list[str]:
    """One line per case: parameter value(s) (papers' units), pressure drop, regime, stop reason."""
    from analysis.plots import parameter_value, parameter_words
    facts = []
    for _, row in table.iterrows():
        where = []
        for key in (x, group):
            if key and key in row:
                name = parameter_words(key)[0].replace("$", "").replace("\\", "")  # no TeX in text
                where.append(f"{name} = {parameter_value(key, row[key])}")
        start = (f"warm start from {row['initial_state']}" if isinstance(row.get("initial_state"), str)
                 and row.get("initial_state") else "from an empty tube")
        window = (f"window {row['t_start']:.2f}-{row['t_end']:.2f} s" if "t_start" in row
                  and "t_end" in row else "")
        delivered = (f"delivers {row['delivery']:.0%} of its feed" if "delivery" in row
                     and np.isfinite(float(row["delivery"])) else "")
        stop = row.get("stop_reason", "")
        detail = ", ".join(str(v) for v in (row["regime"], delivered,
                                            stop if stop != row["regime"] else "", window, start,
                                            _block_forces(row))
                           if isinstance(v, str) and v)
        sem = float(row["pressure_drop_sem"])
        error = (f" +- {sem / HPA:.2g} hPa/m" if np.isfinite(sem)
                 else f" hPa/m, no standard error ({NOT_CONVERGED})")
        facts.append(f"{', '.join(where)}: {row['pressure_drop'] / HPA:.3g}{error} ({detail})")
    return facts


def _block_forces(row) -> str:
    """The axial force balance of a blocked case's last second (analysis.curves.force_balance), or ''."""
    names = ("piston", "gas", "weight", "wall_friction")
    values = [float(row.get(f"block_{name}_force", float("nan"))) for name in names]
    if row.get("regime") != "blocked" or not np.isfinite(values[0]):
        return ""
    piston, gas, weight, friction = values
    return (f"axial forces over its last second: piston {piston:.2g} N, gas drag {gas:.2g} N, "
            f"weight along the tube {weight:.2g} N, wall friction of the weight {friction:.2g} N")


def curve(inp, spec, settings):
    from analysis.plots import characteristic_curves
    from analysis.plots import curve_title
    table = read_table(_list(inp.tables)[0])
    x, group = spec["x"], spec.get("group")
    fig = characteristic_curves(table, x=x, group=group, title=curve_title(table, x))
    facts = _curve_facts(table, x, group)
    if inp.get("experiment"):
        exp = experiment_table(inp.experiment)
        ax = fig.axes[0]
        points = ax.errorbar(exp["superficial_velocity"], exp["pressure_drop_hPa_m"],
                             yerr=exp["pressure_drop_err_hPa_m"], fmt="ks", ms=4, capsize=2)
        old = ax.get_legend()  # the regimes' legend: the experiment joins it
        handles = list(old.legend_handles) if old else []
        labels = [t.get_text() for t in old.get_texts()] if old else []
        ax.legend(handles=[*handles, points], labels=[*labels, "experiment (table 1)"],
                  frameon=False, fontsize=7, loc="upper center", title="regime", title_fontsize=7)
        facts.append("experiment (V table 1): " + "; ".join(
            f"series {r.series}: {r.air_flow_l_min} l/min = {r.superficial_velocity:.3f} m/s, "
            f"{r.pressure_drop_hPa_m} +- {r.pressure_drop_err_hPa_m} hPa/m at {r.granulate_flow_kg_h} kg/h"
            for r in exp.itertuples()))
    return fig, facts


def experiment_table(path):
    """V table 1 with the superficial velocity v_s = 4 Vdot / (pi D^2) of each air flow (m/s)."""
    import pandas as pd

    from analysis.measurements import superficial_velocity
    exp = pd.read_csv(path, comment="#")
    diameter = 0.007  # m, the experiment's tube (V §3)
    exp["superficial_velocity"] = superficial_velocity(exp["air_flow_l_min"], diameter)
    return exp


def curve_pair(inp, spec, settings):
    from analysis.plots import characteristic_curves
    fig = Figure(figsize=(8.0, 3.5), layout="constrained")
    tables = _list(inp.tables)
    axes = fig.subplots(1, len(tables))
    facts = []
    for label, ax, path in zip("abcdef", np.atleast_1d(axes), tables):
        table = read_table(path)
        from analysis.plots import curve_title
        characteristic_curves(table, x=spec["x"], group=spec.get("group"), ax=ax,
                              title=curve_title(table, spec["x"]))
        ax.set_title(f"({label})", loc="left", fontsize=9)
        facts += [f"({label}) {f}" for f in _curve_facts(table, spec["x"], spec.get("group"))]
    return fig, facts


def _stats_facts(stats) -> list[str]:
    n = int(stats["n_slugs"].sum())
    return [f"statistics over t = {stats.attrs.get('t_start', float('nan')):.2f}-"
            f"{stats.attrs.get('t_end', float('nan')):.2f} s (steady window), {n} slug passages "
            f"at {len(stats)} positions"]


def slug_rate(inp, spec, settings):
    from analysis.plots import slug_rate as draw
    stats = read_table(inp.statistics)
    fig = draw(stats)
    if not stats["n_slugs"].sum():
        note(fig, "no slugs detected in this run")
    return fig, _stats_facts(stats)


def slug_statistic(inp, spec, settings):
    from analysis.plots import slug_statistic as draw
    stats = read_table(inp.statistics)
    fig = draw(stats, spec["quantity"])
    if not stats["n_slugs"].sum():
        note(fig, "no slugs detected in this run")
    return fig, _stats_facts(stats)


def profile(inp, spec, settings):
    from analysis.plots import slug_profile
    prof = _open(inp.profile)
    fig = slug_profile(prof, spec.get("fields", ["porosity"]))
    n = int(prof.attrs.get("n_selected", 0))
    a = prof.attrs
    facts = [f"averaged over {n} of {a.get('n_passing', 0)} slugs passing x = {a.get('position', float('nan')):g} m "
             f"with length {a.get('length_center', float('nan')):.3g} +- {a.get('length_band', float('nan')):g} m "
             f"(with its ends) and maximal granular velocity {a.get('velocity_center', float('nan')):.3g} +- "
             f"{a.get('velocity_band', float('nan')):g} m/s; about {a.get('mean_n_particles', float('nan')):.0f} "
             "grains per slug; bands are +- one standard error across slugs"]
    if "granular_temperature" in spec.get("fields", []):
        from analysis.profiles import FAR_OUTSIDE, temperature_check
        check = temperature_check(prof, bool(a.get("vertical", 0)))
        if check["axis_top"]:
            facts.append(f"peak granular temperature {check['peak'] * 1e9:.3g} nJ per grain, "
                         f"{check['ratio']:.2g} times the top of the paper's axis "
                         f"({check['axis_top'] * 1e9:g} nJ)"
                         + (f": FAR OUTSIDE (more than {FAR_OUTSIDE:g} times)" if check["far_outside"] else ""))
    if n == 0:
        note(fig, "no slugs selected in this run")
    return fig, facts


def _snapshot_facts(ds) -> list[str]:
    a = ds.attrs
    who = f"slug {a.get('slug_id')}" if int(a.get("slug_id", -1)) >= 0 else "no slug (window centred in the snapshots)"
    return [f"{who} passing x0 = {a.get('x0', float('nan')):.4f} m at t = {a.get('t_center', float('nan')):.3f} s; "
            f"{ds.sizes.get('snapshot_time', 0)} snapshots over {a.get('window', float('nan')):g} s"]


def cross_sections(inp, spec, settings):
    from analysis.plots import cross_section_strip
    ds = _open(inp.snapshots)
    fig = cross_section_strip(ds)
    return fig, _snapshot_facts(ds)


def velocity_height_image(inp, spec, settings):
    from analysis.plots import velocity_height_image as draw
    ds = _open(inp.snapshots)
    fig = draw(ds)
    return fig, _snapshot_facts(ds)


def velocity_height(inp, spec, settings):
    from analysis.plots import velocity_height as draw
    ds = _open(inp.snapshots)
    mean = xr.Dataset({"velocity": ds["mean_velocity"]}, coords={"height": ds["height"]})
    fig = draw(mean)
    facts = _snapshot_facts(ds) + [f"averaged over t = {ds.attrs.get('average_t_start', float('nan')):.3f}-"
                                   f"{ds.attrs.get('average_t_end', float('nan')):.3f} s while the slug covers x0"]
    return fig, facts


def radial(inp, spec, settings):
    from analysis.plots import radial_profile
    ds = _open(inp.radial)
    fig = radial_profile(ds, spec.get("field", "porosity"))
    n = int(ds.attrs.get("n_slugs", 0))
    if n == 0:
        note(fig, "no plugs with a snapshot in this run")
    return fig, [f"averaged over {n} plugs (rings {0.25:g} d wide, 1.5 d high); "
                 f"{ds.attrs.get('note', '')}".strip("; ")]


def draw_function(kind: str):
    """The function of this module that draws a kind (its `draw` in figure_kinds.KINDS)."""
    return globals()[FIGURE_KINDS[kind].draw]


def drawn_check(fig, inp) -> str:
    """One caption line: every panel draws data, or which do not (analysis.plots.undrawn_axes),
    and for snapshot figures whether the window holds grains."""
    from analysis.plots import undrawn_axes
    problems = [f"panel without data: {name}" for name in undrawn_axes(fig)]
    if inp.get("snapshots"):
        with xr.open_dataset(inp.snapshots) as ds:
            if "grain_volume" in ds and not float(ds["grain_volume"].sum()) > 0:
                problems.append("snapshot window without grains")
    if problems:
        return "check: EMPTY: " + "; ".join(problems)
    return "check: every panel draws data"


def validation_facts(path, fig: str) -> list[str]:
    """The validation statements shown by this figure: ours against the paper's, with the verdict."""
    import pandas as pd
    table = pd.read_csv(path, keep_default_na=False)
    if "figure" not in table:
        return []
    rows = table[table["figure"].astype(str).str.split().apply(lambda figs: fig in figs)]
    facts = []
    for r in rows.itertuples():
        if r.within == "not available":
            facts.append(f"validation {r.id} ({r.statement}): not available ({r.note}); the paper's "
                         f"{r.paper_value} ({r.source})")
            continue
        ours = _number(r.ours, r.ours_error, r.unit)
        facts.append(f"validation {r.id} ({r.statement}): ours {ours} against the paper's "
                     f"{r.paper_value} ({r.source}): within tolerance: {r.within}"
                     + (f" ({r.note})" if r.note else ""))
    return facts


def _number(value, error, unit) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(v):
        return "-"
    unit = "" if unit in ("1", "-") else f" {unit}"
    try:
        e = float(error)
    except (TypeError, ValueError):
        e = float("nan")
    return f"{v:.4g}" + (f" +- {e:.2g}" if math.isfinite(e) else "") + unit


def main(smk) -> None:
    log = setup_logging(smk)
    spec = dict(smk.params.spec)
    fig, facts = draw_function(spec["kind"])(smk.input, spec, dict(smk.params.get("analysis") or {}))
    if smk.input.get("validation"):
        facts += validation_facts(smk.input.validation, str(getattr(smk.wildcards, "fig", "")))
    facts.append(drawn_check(fig, smk.input))
    save_figure(fig, smk.output.png, smk.output.pdf)
    text = [str(smk.params.get("caption") or ""), *[f"- {f}" for f in facts],
            "Inputs: " + ", ".join(str(p) for p in smk.input)]
    ensure_parent(smk.output.txt).write_text("\n".join(text) + "\n")
    log.info("\n".join(text))


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "figure"))

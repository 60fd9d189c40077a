"""Work-precision: the error of a case's observables against a converged reference, and its cost.

A study varies one numerical knob (time step, stiffness, gas grid, gas sub-stepping) over cases
that are otherwise equal; the case at the most accurate value is the reference. The observables
are statistical (time means over a fluctuating flow), so every error comes with the noise it would
show by chance: differences below about two standard errors are not resolved.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

# observable -> its standard-error column in a case summary (analysis.curves.case_summary)
OBSERVABLES = {"pressure_drop": "pressure_drop_sem", "slug_velocity": "slug_velocity_sem",
               "slug_length": "slug_length_sem"}
RESOLVED = 2.0  # an error counts as resolved above this many combined standard errors


def relative_errors(summaries: pd.DataFrame, parameter: str, reference) -> pd.DataFrame:
    """One row per case of a knob sweep, sorted by the knob's value.

    Columns: `value` (the knob), `wall_time_s`, `cpu_time_s` (the cost), `is_reference`, and for each observable q:
    q, q_sem, q_error = |q - q_ref| / |q_ref|, q_noise = sqrt(sem^2 + sem_ref^2) / |q_ref| (the
    relative difference one standard error of chance produces) and q_resolved = error > 2 noise.
    The reference row has error 0. Raises ValueError if no row has the reference value.
    """
    values = summaries[parameter].to_numpy(dtype=float)
    is_ref = np.isclose(values, float(reference), rtol=1e-9, atol=0.0)
    if is_ref.sum() != 1:
        raise ValueError(f"{parameter}: expected one case at the reference value {reference}, "
                         f"found {int(is_ref.sum())} among {sorted(values)}")
    ref = summaries.loc[is_ref].iloc[0]
    nan = pd.Series(np.nan, index=summaries.index)
    out = pd.DataFrame({"value": values, "is_reference": is_ref,
                        "wall_time_s": summaries.get("wall_time_s", nan).to_numpy(dtype=float),
                        "cpu_time_s": summaries.get("cpu_time_s", nan).to_numpy(dtype=float)})
    for q, sem in OBSERVABLES.items():
        x = summaries[q].to_numpy(dtype=float) if q in summaries else np.full(len(values), np.nan)
        s = summaries[sem].to_numpy(dtype=float) if sem in summaries else np.full(len(values), np.nan)
        scale = abs(float(ref.get(q, np.nan)))
        out[q], out[f"{q}_sem"] = x, s
        out[f"{q}_error"] = np.abs(x - float(ref.get(q, np.nan))) / scale
        out[f"{q}_noise"] = np.sqrt(s ** 2 + float(ref.get(sem, np.nan)) ** 2) / scale
        out[f"{q}_resolved"] = out[f"{q}_error"] > RESOLVED * out[f"{q}_noise"]
        out.loc[is_ref, [f"{q}_error", f"{q}_resolved"]] = [0.0, False]
    out.insert(0, "parameter", parameter)
    out.attrs["units"] = {"pressure_drop": "Pa m-1", "slug_velocity": "m s-1", "slug_length": "m",
                          "wall_time_s": "s", "cpu_time_s": "s"}
    return out.sort_values("value").reset_index(drop=True)


SEED = "run.seed"  # a study over this "knob" changes nothing numerical: its spread is pure noise


def pool_default(summaries: pd.DataFrame, parameter: str, default, seeds: pd.DataFrame) -> pd.DataFrame:
    """`summaries` with the row at the knob's default replaced by the mean over the seed study's
    cases (every knob at its default, one run per seed): each observable its mean, its standard
    error the seeds' standard deviation / sqrt(n), the cost the mean cost. One run of the default,
    shared by every knob sweep, would put its chance deviation into every sweep's error."""
    out = summaries.copy()
    at_default = np.isclose(out[parameter].to_numpy(dtype=float), float(default), rtol=1e-9, atol=0.0)
    if not at_default.any() or len(seeds) < 2:
        return out
    for q, sem in OBSERVABLES.items():
        x = seeds[q].dropna().to_numpy(dtype=float) if q in seeds else np.array([])
        mean = float(x.mean()) if len(x) else np.nan
        error = float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else np.nan
        out.loc[at_default, q] = mean
        out.loc[at_default, sem] = error
    for cost in ("wall_time_s", "cpu_time_s"):
        if cost in seeds and cost in out:
            out.loc[at_default, cost] = float(seeds[cost].mean())
    return out


def by_regime(tables: list[pd.DataFrame]) -> dict[str, list[pd.DataFrame]]:
    """The knob tables grouped by flow regime (their `regime` column; "" without one), in the
    order they first appear. Each regime has its own tube and flow, so its own seed study and
    run-to-run scatter: errors are judged only against the scatter of their own regime."""
    out: dict[str, list[pd.DataFrame]] = {}
    for table in tables:
        regime = str(table["regime"].iloc[0]) if "regime" in table and len(table) else ""
        out.setdefault(regime, []).append(table)
    return out


def run_to_run_scatter(tables: list[pd.DataFrame]) -> dict[str, float]:
    """Relative standard deviation (std/mean, ddof=1) of each observable over independent runs: the
    cases of the seed study (parameter run.seed, every knob at its default) when there is one, else
    every distinct case of the study (cases shared by several knob sweeps counted once), which is
    the same when no knob matters and larger when one does. The honest yardstick for the errors."""
    seeds = [t for t in tables if len(t) and t["parameter"].iloc[0] == SEED]
    rows = pd.concat(seeds or tables, ignore_index=True)
    rows = rows.drop_duplicates(subset=[*OBSERVABLES, "cpu_time_s"])
    out = {}
    for q in OBSERVABLES:
        x = rows[q].dropna().to_numpy(dtype=float)
        out[q] = float(np.std(x, ddof=1) / abs(np.mean(x))) if len(x) > 1 else float("nan")
    return out

"""Rules calibration_first and calibration (checkpoints) and prediction: fit the calibration's keys
to the measured operating points through the summaries of the simulated cases
(analysis.calibration), and carry the fit to other operating points.

calibration_first: the first design's cases -> design.csv, fit.json and confirmation.csv (the cases
around the first optimum that the confirmation round runs).
calibration: every case, both rounds -> fitted.json (values, standard deviations, covariance,
chi-square), fitted.yaml (overlay: `--configfile` of the workflow, `plugsim run --overlay`),
table.csv and table.md (measured against fitted), misfit.png, measured_vs_fitted.png.
prediction: the cases at the fitted values and one standard deviation either side along each key
at the prediction's operating points -> prediction/table.{csv,md} and predicted.png.

Standalone (from the repository root; `section` is the config's calibration mapping):
    python workflow/scripts/calibration.py --params stage=final --params 'section={...}' \
        --input summaries=... --output fitted=... ...
"""

import json
import math
from pathlib import Path

from _helpers import setup_logging, snakemake_or_cli, write_json, write_table


def read_summaries(paths) -> dict:
    return {str(p): json.loads(Path(p).read_text()) for p in paths}


def overlay_yaml(keys, values, std, same_as: dict, source: str) -> str:
    """The fitted values as a workflow config overlay (`all_cases`), one line per key with its
    standard deviation."""
    lines = [f"# Fitted by the calibration stage from {source} (docs/rig-calibration.md).",
             "# Use: snakemake --configfile config/config.yaml THIS_FILE, or plugsim run --overlay THIS_FILE.",
             "all_cases:"]
    fitted = dict(zip(keys, values))
    for key, value, s in zip(keys, values, std):
        lines.append(f"  {key}: {float(f'{value:.4g}')!r}  # +- {s:.2g}")
    for target, key in same_as.items():
        lines.append(f"  {target}: {float(f'{fitted[key]:.4g}')!r}  # same as {key}")
    return "\n".join(lines) + "\n"


def cost(design) -> dict:
    """The cases behind a fit or a prediction and their CPU seconds (the sum over the cases whose
    summary has them; `cpu_time_unknown`: how many have not)."""
    cpu = design["cpu_time_s"]
    return {"cases": len(design), "cpu_time_s": float(cpu.sum()), "cpu_time_unknown": int(cpu.isna().sum())}


def cost_line(c: dict) -> str:
    unknown = f" ({c['cpu_time_unknown']} of them without a CPU time)" if c["cpu_time_unknown"] else ""
    return f"{c['cases']} cases, {c['cpu_time_s']:.0f} CPU s{unknown}"


def markdown(table, result, keys, c: dict) -> str:
    lines = ["| parameter | fitted | s.d. |", "|---|---|---|"]
    lines += [f"| {k} | {v:.4g} | {s:.2g} |" for k, v, s in zip(keys, result.values, result.std)]
    lines += ["", f"chi-square {result.chi2:.2f} with {result.dof} degrees of freedom"
              + (f"; at a bound: {', '.join(result.at_bound)}" if result.at_bound else "")
              + f"; {cost_line(c)}", "", *quantity_rows(table, "fitted")]
    return "\n".join(lines) + "\n"


def quantity_rows(table, model: str) -> list[str]:
    """Markdown table of measured against the model's column `model` (fitted, predicted), in the
    papers' units, with the pull."""
    from analysis.plots import TARGETS

    lines = [f"| point | quantity | measured | {model} | pull |", "|---|---|---|---|---|"]
    for _, r in table.iterrows():
        label, factor = TARGETS[r["quantity"]]
        unit = label[label.index("(") + 1:-1]
        unknown = "" if r.get("own_error_known", True) else " (the fit's part only: the case's own error unknown)"
        lines.append(f"| {r['label']} | {r['quantity']} | {r['value'] * factor:.3g} ± {r['error'] * factor:.2g} {unit} "
                     f"| {r[model] * factor:.3g} ± {r[f'{model}_std'] * factor:.2g} {unit}{unknown} | {r['pull']:+.1f} |")
    return lines


def prediction_table(plan, design, fitted: dict):
    """Measured against predicted at each operating point of a prediction: the case at the fitted
    values, and its error from the fit's covariance through the gradient of the cases one standard
    deviation either side along each key, with the case's own standard error (`own_error_known`
    false where the case has none: its window covers too few correlation times; the error bar then
    carries the fit's part alone, and the table says so)."""
    import numpy as np

    from analysis.calibration import central_gradient, propagated_std, pull
    from analysis.measurements import targets

    names = plan.prediction_points(fitted)
    keys = list(plan.bounds.keys)
    rows = design.set_index(["label", "point"])
    table = targets(plan.points)
    predicted, spread, known = [], [], []
    for _, t in table.iterrows():
        key, at = t["summary_key"], rows.loc[t["label"]]
        centre, plus, minus = at.loc[names[0]], at.loc[names[1::2]], at.loc[names[2::2]]
        gradient = central_gradient(plus[key].to_numpy(), minus[key].to_numpy(),
                                    plus[keys].to_numpy().diagonal(), minus[keys].to_numpy().diagonal())
        own = float(centre[f"{key}_sem"])
        predicted.append(float(centre[key]))
        known.append(math.isfinite(own))
        spread.append(propagated_std(gradient, np.array(fitted["covariance"]), own if known[-1] else 0.0))
    table["predicted"], table["predicted_std"], table["own_error_known"] = predicted, spread, known
    table["pull"] = pull(table, "predicted")
    return table


def prediction_markdown(table, fitted: dict, c: dict) -> str:
    values = ", ".join(f"{k} = {p['value']:.4g} ± {p['std']:.2g}" for k, p in fitted["parameters"].items())
    lines = [f"The fitted model ({values}) at the operating points of the prediction; {cost_line(c)}.", "",
             *quantity_rows(table, "predicted")]
    return "\n".join(lines) + "\n"


def main(smk) -> None:
    log = setup_logging(smk)
    import pandas as pd

    from analysis import calibration as cal
    from analysis.measurements import targets
    from calibration_plan import CalibrationPlan, design_table

    if smk.params.stage == "prediction":
        plan = CalibrationPlan(smk.params.section, smk.params.prediction)
        design = design_table(read_summaries(smk.input.summaries), plan)
        with open(smk.input.fitted) as f:
            fitted = json.load(f)
        table = prediction_table(plan, design, fitted)
        write_table(table, smk.output.table)
        with open(smk.output.md, "w") as f:
            f.write(prediction_markdown(table, fitted, cost(design)))
        from analysis.plots import measured_against_fitted

        measured_against_fitted(table, what="predicted").savefig(smk.output.png, dpi=150)
        log.info("\n%s", table)
        return
    plan = CalibrationPlan(smk.params.section)
    design = design_table(read_summaries(smk.input.summaries), plan)
    goal = targets(plan.points)
    log.info("%d cases, %d measured quantities, fitting %s", len(design), len(goal), ", ".join(plan.bounds.keys))
    draws, seed = int(plan.section.get("draws", 200)), int(plan.section.get("seed", 0))
    result = cal.fit(design, goal, plan.bounds, draws=draws, seed=seed)
    log.info("fitted %s", result.as_dict())
    if smk.params.stage == "first":
        write_table(design, smk.output.design)
        write_json(result.as_dict(), smk.output.fit)
        confirm = cal.confirmation_design(plan.bounds, result.values, result.std)
        confirm.insert(0, "point", [plan.point_name(row) for row in confirm.to_numpy()])
        confirm.drop_duplicates("point").query("point not in @plan.first").to_csv(smk.output.confirmation, index=False)
        return
    table = cal.fitted_table(goal, plan.bounds, result)
    out = result.as_dict()
    out.update({"covariance": result.covariance.tolist(), "keys": list(result.keys),
                "measurements": plan.section["measurements"], **cost(design),
                "same_as": dict(plan.section.get("same_as") or {})})
    write_json(out, smk.output.fitted)
    with open(smk.output.overlay, "w") as f:
        f.write(overlay_yaml(result.keys, result.values, result.std, out["same_as"], plan.section["measurements"]))
    write_table(table, smk.output.table)
    with open(smk.output.md, "w") as f:
        f.write(markdown(table, result, result.keys, cost(design)))
    from analysis.plots import calibration_misfit, measured_against_fitted

    first, second, chi2 = cal.misfit_grid(goal, plan.bounds, result)
    if len(result.keys) >= 2:
        calibration_misfit(first, second, chi2, result.keys, design, result.values, result.std).savefig(
            smk.output.misfit, dpi=150)
    else:
        log.warning("one fitted key: the misfit map is a line")
        from matplotlib.figure import Figure
        fig = Figure(figsize=(5, 3.5), layout="constrained")
        ax = fig.add_subplot()
        ax.plot(first, chi2[0] - chi2.min(), "k-")
        ax.set_xlabel(result.keys[0])
        ax.set_ylabel(r"$\chi^2 - \chi^2_{min}$")
        fig.savefig(smk.output.misfit, dpi=150)
    measured_against_fitted(table).savefig(smk.output.compare, dpi=150)
    if any(not math.isfinite(v) for v in result.std):
        log.warning("a fitted standard deviation is not finite: too few cases or measured quantities")
    pd.set_option("display.width", 160)
    log.info("\n%s", table)


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "calibration"))

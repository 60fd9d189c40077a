"""Rule identification: each discretisation reading the papers leave open (the `readings` case keys
crossed in the identification sweeps) against the papers' numbers for the most informative cases.

One row per (statement, reading): the paper's value and tolerance (resources/paper_statements.yaml,
never adjusted), ours +- standard error from the sweep's curve table, ratio and verdict with the
validation rule's test (ours +- 2 standard errors overlapping the paper's interval). Measures:
pressure_drop, n_particles (steady means), regime (the case's label against `expected`),
max_velocity (the papers' mean maximal granular velocity in a slug, per passage), travel_speed
(the median speed at which slugs and plugs travel mid-tube; its error from the spread between
slugs) and
argmax (the value of the statement's `x` with the largest pressure drop within the reading's
points). A blocked case is "no (blocked)" whatever its numbers. In a one_at_a_time sweep each
reading's effect is ours less the baseline reading's ours on the same statement, with the two
standard errors combined (`baselines`: sweep -> its reading keys at their first values).
`miss` is ours' distance from the paper's interval as a fraction of the paper's value (0 inside);
the summary compares each reading with the baseline on the statements both have: how many are
within, and on how many quantitative ones the reading's effect is resolved (beyond 2 combined
standard errors) and brings ours closer to, or farther from, the paper's interval.

Standalone:
    python workflow/scripts/identification.py --input statements=resources/paper_statements.yaml \
        --input tables=results/curves/id_h_default.csv,results/curves/id_v_default.csv \
        --output csv=/tmp/id.csv \
        --output md=/tmp/id.md --output png=/tmp/id.png \
        --params 'compare=[{"statement": "H-dp-default", "sweep": "id_h_default"}]' \
        --params 'readings=["gas.face_permeability"]'
"""

import math
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from _helpers import ensure_parent, read_table, setup_logging, snakemake_or_cli, write_table
from validation import TO_UNIT, paper_interval, paper_text

NAN = float("nan")
COLUMN = {"pressure_drop": ("pressure_drop", "pressure_drop_sem"),
          "n_particles": ("n_particles", "n_particles_sem"),
          "max_velocity": ("max_velocity", "max_velocity_sem"),
          "travel_speed": ("travel_speed", "travel_speed_sem")}


def reading_label(row: pd.Series, readings: list[str], baseline: dict | None = None) -> str:
    """'face_permeability=harmonic, scheme=unsplit, ...' from the reading keys of a table row; with
    a baseline only the keys that differ from it, or 'baseline'."""
    keys = [key for key in readings if key in row]
    if baseline is not None:
        keys = [key for key in keys if key not in baseline or not _same(row[key], baseline[key])]
        if not keys:
            return "baseline"
    return ", ".join(f"{key.split('.', 1)[1]}={row[key]}" for key in keys)


def _same(a, b) -> bool:
    """Equal values of a reading key (numbers compared as floats)."""
    try:
        return math.isclose(float(a), float(b))
    except (TypeError, ValueError):
        return str(a) == str(b)


def verdict(value: float, error: float, st: dict) -> str:
    """'yes' when value +- 2 error overlaps the paper's interval (in the statement's unit)."""
    lo, hi, _ = paper_interval(st)
    reach = 2 * error if math.isfinite(error) else 0.0
    return "yes" if value + reach >= lo and value - reach <= hi else "no"


def compare_rows(st: dict, rows: pd.DataFrame, readings: list[str], measure: str,
                 baseline: dict | None = None) -> list[dict]:
    """One result per reading (group of rows sharing the reading keys)."""
    keys = [k for k in readings if k in rows]
    groups = rows.groupby(keys, sort=False, dropna=False) if keys else [((), rows)]
    out = []
    for _, group in groups:
        label = reading_label(group.iloc[0], readings, baseline)
        if measure == "regime":
            value = str(group["regime"].iloc[0])
            out.append({"reading": label, "ours": value, "ours_error": NAN, "ratio": NAN,
                        "within": "yes" if value == st["expected"] else "no"})
            continue
        if measure == "argmax":
            x = st["x"]
            lo, hi = st.get("within", [-math.inf, math.inf])
            inside = group[(group[x] >= lo) & (group[x] <= hi)]
            value = float(inside.loc[inside["pressure_drop"].idxmax(), x])
            error = NAN
        else:
            column, sem = COLUMN[measure]
            value = float(group[column].iloc[0]) * TO_UNIT.get(st.get("unit", "1"), 1.0)
            error = (float(group[sem].iloc[0]) * TO_UNIT.get(st.get("unit", "1"), 1.0)
                     if sem and sem in group else NAN)
        lo, hi, mid = paper_interval(st)
        within = verdict(value, error, st) if math.isfinite(value) else "not available"
        if measure != "argmax" and "regime" in group and group["regime"].iloc[0] == "blocked":
            within = "no (blocked)"  # a tube that did not deliver its feed meets no conveying number
        out.append({"reading": label, "ours": value, "ours_error": error,
                    "ratio": value / mid if mid else NAN, "within": within,
                    "miss": max(lo - value, value - hi, 0.0) / abs(mid) if mid else NAN})
    return out


def add_effects(rows: list[dict], baseline: str) -> None:
    """effect = ours - the baseline reading's ours (same statement, same points), error combined."""
    base = next((r for r in rows if r["reading"] == baseline), None)
    for r in rows:
        r["effect"], r["effect_error"] = NAN, NAN
        if base is None or isinstance(r["ours"], str) or not math.isfinite(base["ours"]):
            continue
        r["effect"] = r["ours"] - base["ours"]
        r["effect_error"] = math.hypot(r["ours_error"], base["ours_error"])


def table(statements: list[dict], tables: dict[str, pd.DataFrame], compare: list[dict],
          readings: list[str], baselines: dict | None = None) -> pd.DataFrame:
    """The identification table: one row per (statement, reading), with each reading's effect
    against its sweep's baseline where the sweep has one."""
    by_id = {st["id"]: st for st in statements}
    rows = []
    for item in compare:
        st = by_id[item["statement"]]
        measure = item.get("measure") or ("argmax" if st["measure"] == "argmax" else st["measure"])
        data = tables[item["sweep"]]
        for key, value in (item.get("where") or {}).items():
            data = data[np.isclose(data[key], value)] if not isinstance(value, str) else data[data[key] == value]
        if data.empty:
            raise ValueError(f"identification: no row of sweep {item['sweep']} matches {item.get('where')}")
        baseline = (baselines or {}).get(item["sweep"])
        results = compare_rows(st, data, readings, measure, baseline)
        if baseline is not None:
            add_effects(results, "baseline")
        for result in results:
            rows.append({"id": st["id"], "statement": st["statement"], "sweep": item["sweep"],
                         "measure": measure, "paper_value": paper_text(st),
                         "unit": st.get("unit", ""), **result})
    return pd.DataFrame(rows)


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """Per reading: statements within and compared; against the baseline on the same statements,
    the baseline's count within, and the quantitative statements the reading brings resolvedly
    closer to or farther from the paper's interval (|effect| > 2 combined standard errors)."""
    base = df[df["reading"] == "baseline"].set_index(["id", "sweep"])
    rows = []
    for reading, group in df.groupby("reading", sort=False):
        row = {"reading": reading, "within": int((group["within"] == "yes").sum()), "of": len(group),
               "baseline_within": NAN, "closer": NAN, "farther": NAN}
        if reading != "baseline" and not base.empty and "effect" in df:
            shared = group[group.set_index(["id", "sweep"]).index.isin(base.index)]
            b = base.loc[list(zip(shared["id"], shared["sweep"]))]
            row["baseline_within"] = int((b["within"] == "yes").sum())
            resolved = [(r.miss, m) for r, m in zip(shared.itertuples(), b["miss"])
                        if math.isfinite(r.miss) and math.isfinite(m) and _resolved(r)]
            row["closer"] = sum(1 for mine, theirs in resolved if mine < theirs)
            row["farther"] = sum(1 for mine, theirs in resolved if mine > theirs)
        rows.append(row)
    return pd.DataFrame(rows)


def _resolved(r) -> bool:
    """An effect beyond 2 combined standard errors; without an error only an argmax (a grid value,
    exact) is resolved, a mean whose error is unknown is not."""
    if not math.isfinite(r.effect) or r.effect == 0.0:
        return False
    if math.isfinite(r.effect_error):
        return abs(r.effect) > 2 * r.effect_error
    return r.measure == "argmax"


def markdown(df: pd.DataFrame) -> str:
    """The table as markdown, after the summary: each reading's count within tolerance and its
    comparison with the baseline (summary)."""
    lines = ["# Model identification: the papers' open discretisation readings", "",
             "Generated by rule `identification` (config/identification.yaml). Ours +- 2 standard "
             "errors against the papers' tolerance (resources/paper_statements.yaml).", "",
             "Against the baseline: its count within on the reading's statements, and the "
             "quantitative statements the reading's resolved effect (beyond 2 combined standard "
             "errors) brings closer to or farther from the paper's interval.", "",
             "| reading | within | of | baseline within | closer | farther |", "|---|---|---|---|---|---|"]
    for r in summary(df).itertuples():
        extra = ("| | | |" if not math.isfinite(r.baseline_within)
                 else f"| {r.baseline_within:.0f} | {r.closer:.0f} | {r.farther:.0f} |")
        lines.append(f"| {r.reading} | {r.within} | {r.of} {extra}")
    lines += ["", "| statement | reading | paper | ours | ratio | effect against the baseline | within |",
              "|---|---|---|---|---|---|---|"]
    for _, r in df.iterrows():
        unit = "" if isinstance(r["ours"], str) or r["unit"] == "1" else r["unit"]
        ours = r["ours"] if isinstance(r["ours"], str) else (
            f"{r['ours']:.4g} +- {r['ours_error']:.2g}" if math.isfinite(r["ours_error"]) else f"{r['ours']:.4g}")
        ratio = f"{r['ratio']:.2f}" if isinstance(r["ratio"], float) and math.isfinite(r["ratio"]) else ""
        lines.append(f"| {r['id']} | {r['reading']} | {r['paper_value']} | {ours} {unit} "
                     f"| {ratio} | {effect_text(r)} | {r['within']} |")
    return "\n".join(lines) + "\n"


def effect_text(r) -> str:
    """'+1.2 +- 0.3' (or '+1.2' without an error), '' without an effect."""
    effect = r.get("effect", NAN)
    if not isinstance(effect, float) or not math.isfinite(effect) or effect == 0.0:
        return ""
    error = r.get("effect_error", NAN)
    return f"{effect:+.3g}" + (f" +- {error:.2g}" if math.isfinite(error) else "")


def figure(df: pd.DataFrame, path) -> None:
    """Grid of statements (rows) against readings (columns): green within, red outside, with the
    ratio ours / paper (or our regime) written in each cell."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ids = list(dict.fromkeys(df["id"]))
    readings = list(dict.fromkeys(df["reading"]))
    grid = np.full((len(ids), len(readings)), np.nan)
    fig, ax = plt.subplots(figsize=(max(7.0, 2.2 + 1.6 * len(readings)), 1.2 + 0.45 * len(ids)))  # title fits
    for _, r in df.iterrows():
        i, j = ids.index(r["id"]), readings.index(r["reading"])
        grid[i, j] = {"yes": 1.0, "no": 0.0, "no (blocked)": 0.0}.get(r["within"], np.nan)
        text = r["ours"] if isinstance(r["ours"], str) else (
            f"{r['ratio']:.2f}" if math.isfinite(r["ratio"]) else f"{r['ours']:.3g}")
        if r["within"] == "no (blocked)":
            text += " (blocked)"
        if effect_text(r):
            text += f"\n{effect_text(r)}"
        ax.text(j, i, text, ha="center", va="center", fontsize=8)
    ax.imshow(grid, cmap="RdYlGn", vmin=-0.3, vmax=1.3, aspect="auto")
    ax.set_xticks(range(len(readings)), [r.replace(", ", "\n") for r in readings], fontsize=7)
    ax.set_yticks(range(len(ids)), ids, fontsize=8)
    ax.set_title("Each reading against the papers: ours / paper (or our regime), green = within "
                 "tolerance;\nbelow: the effect against the baseline reading, in the statement's unit",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(ensure_parent(path), dpi=120)
    plt.close(fig)


def main(smk) -> None:
    log = setup_logging(smk)
    statements = yaml.safe_load(Path(smk.input.statements).read_text())
    tables = smk.input.tables  # standalone: one string, tables=A.csv,B.csv
    paths = tables.split(",") if isinstance(tables, str) else tables
    tables = {Path(p).stem: read_table(p) for p in paths}
    df = table(statements, tables, list(smk.params.compare), list(smk.params.readings),
               dict(smk.params.get("baselines") or {}))
    write_table(df, smk.output.csv)
    ensure_parent(smk.output.md).write_text(markdown(df))
    figure(df, smk.output.png)
    log.info("%d rows\n%s", len(df), df.to_string())


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "identification"))

"""Rule validation: the papers' quantitative statements (resources/paper_statements.yaml) against
our results: paper value and tolerance, ours +- standard error, ratio ours/paper, within or not.

Ours is within when its interval (ours +- 2 standard errors, or +- the half-width of a sweep
spacing for transitions and maxima) overlaps the statement's interval (value +- tolerance, the
range, or value / factor .. value * factor). Tolerances come from the statements file with their
justification and are never adjusted here.

Each statement has a role (training: it may choose a reading; test: a prediction) and a kind
(quantitative, trend, regime); the headline counts the test statements, with the training count
beside it.

Standalone (params.statements as prepared by workflow/rules/validation.smk):
    snakemake -n validation   # shows the inputs; then run the rule, it is cheap
Re-judge a committed table's measured values with the current statements file (new tolerances,
roles and kinds; statements no longer in the file are dropped, new ones are not available):
    python workflow/scripts/validation.py --rejudge docs/reference/paper/validation.csv \
        resources/paper_statements.yaml /tmp/validation.csv      # writes .csv and .md
"""

import math

import numpy as np
import pandas as pd
import xarray as xr

from analysis import curves
from _helpers import ensure_parent, read_json, read_table, setup_logging, snakemake_or_cli

TO_UNIT = {"hPa/m": 0.01, "Pa/m": 1.0, "m/s": 1.0, "m": 1.0, "cm": 100.0, "1": 1.0, "1/s": 1.0,
           "Pa": 1.0, "r/d": 1.0, "J": 1.0}
NAN = float("nan")


class NotMeasurable(Exception):
    """The data exist but do not contain the quantity (e.g. no slugs passed the position)."""


# ---- measures: statement -> (value, error, error kind) in SI (or categorical) -----------------

def _summary(st, k=0):
    return read_json(st["files"]["summaries"][k])


def pressure_drop(st, ctx):
    s = _summary(st)
    return s["pressure_drop"], s["pressure_drop_sem"], "sem"


def n_particles(st, ctx):
    s = _summary(st)
    return s.get("n_particles", NAN), s.get("n_particles_sem", NAN), "sem"


def regime(st, ctx):
    return _summary(st)["regime"], NAN, "category"


def ratio(st, ctx):
    a, b = _summary(st, 0), _summary(st, 1)
    va, vb = a["pressure_drop"], b["pressure_drop"]
    value = va / vb
    err = abs(value) * math.hypot(a["pressure_drop_sem"] / va, b["pressure_drop_sem"] / vb)
    return value, err, "sem"


def _position(st, ctx, slugs):
    pos = st.get("position", "analysis")
    if pos == "analysis":
        return float(ctx["position"])
    if pos == "inlet":
        from analysis.statistics import default_positions
        return float(default_positions(slugs.attrs["tube_length"])[0])
    return float(pos)


def _stats_at(st, ctx):
    from analysis.statistics import slug_statistics
    slugs = read_table(st["files"]["slugs"])
    summary = read_json(st["files"]["summary"])
    if not len(slugs):
        raise NotMeasurable("no slugs detected in the case")
    pos = _position(st, ctx, slugs)
    if not 0 < pos < slugs.attrs["tube_length"]:
        raise NotMeasurable(f"position {pos:g} m is outside the tube")
    return slug_statistics(slugs, [pos], t_start=summary["t_start"]).iloc[0]


def slug_stat(st, ctx):
    """Mean over the slugs passing the position (the papers' per-passage statistics); for the
    velocities the note gives the time-weighted mean too."""
    row = _stats_at(st, ctx)
    q = st["quantity"]
    if not row["n_slugs"]:
        raise NotMeasurable("no slug passed the position")
    note = ""
    if f"{q}_time_mean" in row and math.isfinite(row[f"{q}_time_mean"]):
        note = (f"time-weighted {row[f'{q}_time_mean']:.4g} +- {row[f'{q}_time_sem']:.2g} "
                f"{st.get('unit', '')} (per passage is the papers' reading)")
    return row[f"{q}_mean"], row[f"{q}_sem"], "sem", note


def slug_rate(st, ctx):
    row = _stats_at(st, ctx)
    return row["rate"], row["rate_sem"], "sem"


def _profile(st):
    with xr.open_dataset(st["files"]["profile"]) as ds:
        prof = ds.load()
    if int(prof.attrs.get("n_selected", 0)) == 0:
        raise NotMeasurable("no slugs selected for the averaged profile")
    return prof


def _extremum(st, pick):
    prof = _profile(st)
    mean = prof[st["field"]].values
    if not np.isfinite(mean).any():
        raise NotMeasurable("profile is empty")
    i = int(pick(mean))
    return float(mean[i]), float(prof[f"{st['field']}_sem"].values[i]), "sem"


def profile_min(st, ctx):
    return _extremum(st, np.nanargmin)


def profile_max(st, ctx):
    return _extremum(st, np.nanargmax)


def selection_mean(st, ctx):
    sel = read_table(st["files"]["selection"])
    values = pd.to_numeric(sel[st["column"]], errors="coerce").dropna() if len(sel) else []
    if not len(values):
        raise NotMeasurable("no slugs selected")
    sem = float(np.std(values, ddof=1) / np.sqrt(len(values))) if len(values) > 1 else NAN
    return float(np.mean(values)), sem, "sem"


def _curve_rows(st, within=False, blocked=False):
    """The sweep's curve at `where`, sorted by `x`; with within=True only x in `within`. Blocked
    points (regime "blocked": the tube did not deliver the feed the point is labelled with) are no
    part of the curve and left out, unless blocked=True."""
    table = read_table(st["files"]["curve"])
    for key, value in (st.get("where") or {}).items():
        table = table[np.isclose(table[key].astype(float), float(value))]
    if not blocked and "regime" in table:
        table = table[table["regime"] != "blocked"]
    if within:
        lo, hi = st.get("within", [-np.inf, np.inf])
        table = table[(table[st["x"]] >= lo) & (table[st["x"]] <= hi)]
    return table.sort_values(st["x"]).reset_index(drop=True)


def transition(st, ctx):
    rows = _curve_rows(st)
    x = rows[st["x"]].to_numpy(dtype=float)
    inside = (rows["regime"] == st["regime"]).to_numpy()
    if not len(x):
        raise NotMeasurable("no points in the sweep")
    if inside.all():
        raise NotMeasurable(f"every point is {st['regime']} (transition above {x[-1]:g})")
    first = int(np.argmin(inside))  # first point that is not in the regime
    if first == 0:
        raise NotMeasurable(f"no point is {st['regime']} (transition below {x[0]:g})")
    return (x[first - 1] + x[first]) / 2, (x[first] - x[first - 1]) / 2, "half-width"


def argmax(st, ctx):
    rows = _curve_rows(st, within=True)
    if not len(rows):
        raise NotMeasurable("no points in the range")
    x = rows[st["x"]].to_numpy(dtype=float)
    i = int(np.nanargmax(rows["pressure_drop"].to_numpy(dtype=float)))
    gaps = np.diff(x)
    half = max(gaps[i - 1] if i > 0 else 0.0, gaps[i] if i < len(gaps) else 0.0) / 2 if len(x) > 1 else NAN
    return x[i], half, "half-width"


def _curve_xy(st):
    """Points of a sweep's curve within `within` (x, pressure drop and its error, Pa/m)."""
    rows = _curve_rows(st, within=True)
    rows = rows[np.isfinite(rows["pressure_drop"].astype(float))]
    if len(rows) < 2:
        raise NotMeasurable(f"{len(rows)} point(s) in the range")
    return (rows[st["x"]].to_numpy(dtype=float), rows["pressure_drop"].to_numpy(dtype=float),
            rows["pressure_drop_sem"].to_numpy(dtype=float))


def trend(st, ctx):
    x, y, err = _curve_xy(st)
    slope, sem = curves.linear_slope(x, y, err)
    note = f"slope {slope / 100:.3g} +- {sem / 100:.2g} hPa/m per unit of {st['x']}"
    return curves.trend(x, y, err), NAN, "category", note


def monotonic(st, ctx):
    x, y, err = _curve_xy(st)
    ok = curves.is_monotonic_increasing(x, y, err)
    return "monotonic increasing" if ok else "not monotonic increasing", NAN, "category", \
        "steps (hPa/m): " + ", ".join(f"{d / 100:+.3g}" for d in np.diff(y[np.argsort(x)]))


def fit_deviation(st, ctx):
    x, y, err = _curve_xy(st)
    try:
        dev, params = curves.fit_deviation(x, y, err, st["model"])
    except ValueError as why:
        raise NotMeasurable(str(why)) from None
    note = "fit " + ", ".join(f"{k} = {v:.3g}" for k, v in params.items()) + " (SI)"
    return dev, NAN, "fit", note


def radial_outer_minimum(st, ctx):
    with xr.open_dataset(st["files"]["radial"]) as ds:
        prof = ds.load()
    d = float(prof.attrs["particle_diameter"])
    phi = prof["porosity"].values
    r = prof["r"].values / d
    if not np.isfinite(phi).any():
        raise NotMeasurable("no radial profile")
    minima = [i for i in range(len(phi)) if np.isfinite(phi[i])
              and (i == 0 or phi[i] < phi[i - 1]) and (i == len(phi) - 1 or phi[i] <= phi[i + 1])
              and phi[i] < 0.7]
    if not minima:
        raise NotMeasurable("no porosity minimum below 0.7")
    return float(r[minima[-1]]), float(np.median(np.diff(r))) / 2, "half-width"


MEASURES = {f.__name__: f for f in (pressure_drop, n_particles, regime, ratio, slug_stat, slug_rate,
                                     profile_min, profile_max, selection_mean, transition, argmax,
                                     trend, monotonic, fit_deviation, radial_outer_minimum)}


# ---- comparison -------------------------------------------------------------------------------

TREND_MEASURES = {"trend", "monotonic", "fit_deviation"}
KINDS = ("quantitative", "trend", "regime")


def statement_kind(st) -> str:
    """quantitative (a number against an interval), trend (sign or shape of a curve) or regime."""
    if st["measure"] == "regime":
        return "regime"
    return "trend" if st["measure"] in TREND_MEASURES else "quantitative"


def statement_role(st) -> str:
    """training (may be looked at to choose a reading) or test (a prediction)."""
    return st.get("role", "test")


def judge(st, value, err, error_kind) -> str:
    """'yes' when ours (+- 2 standard errors, or +- its half-width) meets the statement, else 'no'."""
    if error_kind == "category":
        return "yes" if value == st["expected"] else "no"
    lo, hi, _ = paper_interval(st)
    reach = 0.0 if not math.isfinite(err) else (2 * err if error_kind == "sem" else err)
    return "yes" if (value + reach >= lo and value - reach <= hi) else "no"


def paper_interval(st):
    if "range" in st:
        lo, hi = st["range"]
        return float(lo), float(hi), (float(lo) + float(hi)) / 2
    value = float(st["value"])
    if "factor" in st:
        return value / float(st["factor"]), value * float(st["factor"]), value
    return value - float(st["tolerance"]), value + float(st["tolerance"]), value


def paper_text(st) -> str:
    unit = "" if st.get("unit", "") == "1" else st.get("unit", "")  # a count has no unit to print
    if "expected" in st:
        return str(st["expected"])
    if "range" in st:
        return f"{st['range'][0]:g}-{st['range'][1]:g} {unit}"
    if "factor" in st:
        return f"{st['value']:g} {unit} (x/ {st['factor']:g})"
    return f"{st['value']:g} +- {st['tolerance']:g} {unit}"


def _unresolved_bulk(st) -> int:
    """Bulk points among the statement's inputs (its case summaries, its curve at `where`) whose case
    did not resolve the tangential dashpot: a packed bed there carries a time-step error."""
    files = st.get("files") or {}
    count = sum(1 for path in files.get("summaries") or []
                if (s := read_json(path)).get("regime") == "bulk" and s.get("dashpot_resolved") is False)
    if files.get("curve"):
        count += int(curves.unresolved_bulk(_curve_rows(st)).sum())
    return count


def _figures(st) -> list[str]:
    """The paper figures that show the statement's quantity (its `figure`: a name or a list)."""
    figs = st.get("figure") or []
    return [figs] if isinstance(figs, str) else [str(f) for f in figs]


def compare(st, ctx) -> dict:
    """The statement's row; its note names the bulk points among the inputs that carry a time-step
    error (docs/performance.md, "The tangential dashpot and the time step")."""
    row = _compare(st, ctx)
    if st.get("files") and (n := _unresolved_bulk(st)):
        row["note"] = "; ".join(filter(None, [row["note"], f"{n} bulk point(s) in its data carry a "
                                              "time-step error (tangential dashpot not resolved)"]))
    if st.get("files") and (blocked := _blocked(st)):
        row["note"] = "; ".join(filter(None, [row["note"], blocked]))
    return row


def _blocked(st) -> str:
    """Note on blocked inputs: curve points left out, or a case that is blocked itself."""
    files = st["files"]
    if files.get("curve"):
        rows = _curve_rows(st, blocked=True)
        n = int((rows["regime"] == "blocked").sum()) if "regime" in rows else 0
        return f"{n} blocked point(s) left out of the curve" if n else ""
    names = [path for path in files.get("summaries") or [] if read_json(path).get("regime") == "blocked"]
    if files.get("summary") and read_json(files["summary"]).get("regime") == "blocked":
        names.append(files["summary"])
    return f"blocked case: it delivers less than half its feed ({', '.join(names)})" if names else ""


def _compare(st, ctx) -> dict:
    row = {"id": st["id"], "role": statement_role(st), "kind": statement_kind(st),
           "paper": st["paper"], "source": st["source"],
           "statement": st["statement"], "paper_value": paper_text(st), "unit": st.get("unit", ""),
           "justification": " ".join(str(st.get("justification", "")).split()),
           "cases": ", ".join(c for c in st.get("case_names") or [] if c) or st.get("sweep", ""),
           "ours": NAN, "ours_error": NAN, "error_kind": "", "ratio": NAN, "within": "",
           "note": "", "figure": " ".join(_figures(st))}
    if not st.get("files"):
        pending = st.get("pending")
        why = ("the case or sweep is not in this configuration" if not pending
               else f"not run yet (partial validation: {pending})" if isinstance(pending, str)
               else "not run yet (partial validation: its case or curve is not produced)")
        row.update(within="not available", note=why)
        return row
    try:
        value, err, kind, *note = MEASURES[st["measure"]](st, ctx)
    except NotMeasurable as why:
        row.update(within="not available", note=str(why))
        return row
    row["note"] = note[0] if note else ""
    if kind == "category":
        row.update(ours=value, error_kind="category", within=judge(st, value, NAN, kind))
        return row
    factor = TO_UNIT.get(st.get("unit", "1"), 1.0)
    value, err = float(value) * factor, float(err) * factor
    mid = paper_interval(st)[2]
    if not math.isfinite(value):
        row.update(within="not available", note="not measurable (NaN)")
        return row
    row.update(ours=value, ours_error=err, error_kind=kind,
               ratio=value / mid if mid and kind != "fit" else NAN,
               within=judge(st, value, err, kind))
    if not math.isfinite(err) and kind == "sem":
        row["note"] = "; ".join(filter(None, [row["note"], "no standard error (too few samples)"]))
    return row


def count_line(table: pd.DataFrame, role: str) -> str:
    """'a of n within (quantitative x of y, trend ..., regime ...)' for the statements of a role."""
    rows = table[table["role"] == role]
    within = rows["within"] == "yes"
    parts = [f"{k} {int(within[rows['kind'] == k].sum())} of {int((rows['kind'] == k).sum())}"
             for k in KINDS if (rows["kind"] == k).any()]
    missing = int((rows["within"] == "not available").sum())
    text = f"{int(within.sum())} of {len(rows)} within ({', '.join(parts)})"
    return text + (f", {missing} not available" if missing else "")


def markdown(table: pd.DataFrame, ctx) -> str:
    lines = ["# Validation against the papers", "",
             f"**Test statements (predictions): {count_line(table, 'test')}.** Training statements "
             f"(the identification may choose a reading on them): {count_line(table, 'training')}.",
             "",
             "Ours is within when ours +- 2 standard errors (+- half the sweep spacing for "
             "transitions and maxima) overlaps the paper's value +- tolerance (or range), the "
             "tolerance being the paper's own precision. Tolerances, roles and their "
             "justification: resources/paper_statements.yaml.", ""]
    if ctx.get("partial"):
        lines += ["**Partial validation** (config validation.partial): statements whose cases or "
                  "curves were not produced yet are marked not available.", ""]
    # output.* keys (what is written, when) do not change the physics; anything else does
    physical = {k: v for k, v in (ctx.get("all_cases") or {}).items() if not k.startswith("output.")}
    if physical:
        lines += [f"**Configuration overrides applied to every case:** `{physical}` "
                  "(a reduced run: the comparison is not meaningful).", ""]
    lines += ["| id | role | kind | source | statement | paper | ours | ratio | within | note |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in table.itertuples():
        if r.error_kind == "category":
            ours = str(r.ours)
        elif isinstance(r.ours, float) and math.isfinite(r.ours):
            ours = f"{r.ours:.4g}" + (f" +- {r.ours_error:.2g}" if math.isfinite(r.ours_error) else "")
            ours += f" {r.unit}" if r.unit not in ("1", "-") else ""
        else:
            ours = "-"
        ratio_text = f"{r.ratio:.2f}" if isinstance(r.ratio, float) and math.isfinite(r.ratio) else "-"
        lines.append(f"| {r.id} | {r.role} | {r.kind} | {r.paper} {r.source} | {r.statement} | "
                     f"{r.paper_value} | {ours} | "
                     f"{ratio_text} | {r.within} | {r.note} |")
    return "\n".join(lines) + "\n"


def main(smk) -> None:
    log = setup_logging(smk)
    ctx = {"position": smk.params.get("position", 0.26), "all_cases": smk.params.get("all_cases") or {},
           "partial": smk.params.get("partial", False)}
    rows = [compare(st, ctx) for st in smk.params.statements]
    table = pd.DataFrame(rows)
    table.to_csv(ensure_parent(smk.output.csv), index=False)
    ensure_parent(smk.output.md).write_text(markdown(table, ctx))
    log.info("\n%s", table[["id", "paper_value", "ours", "ours_error", "ratio", "within", "note"]])


def rejudge(old: pd.DataFrame, statements: list[dict]) -> pd.DataFrame:
    """A validation table's measured values (ours, ours_error, error_kind, note) judged again with
    `statements`: their intervals, roles and kinds. A statement the old table lacks is not
    available."""
    by_id = old.set_index("id")
    rows = []
    for st in statements:
        row = {"id": st["id"], "role": statement_role(st), "kind": statement_kind(st),
               "paper": st["paper"], "source": st["source"], "statement": st["statement"],
               "paper_value": paper_text(st), "unit": st.get("unit", ""),
               "justification": " ".join(str(st.get("justification", "")).split()), "cases": "",
               "ours": NAN, "ours_error": NAN, "error_kind": "", "ratio": NAN,
               "within": "not available", "note": "not in the re-judged table",
               "figure": " ".join(_figures(st))}
        if st["id"] in by_id.index:
            o = by_id.loc[st["id"]]
            row.update(note="" if pd.isna(o["note"]) else str(o["note"]), within=o["within"],
                       cases="" if pd.isna(o.get("cases")) else str(o.get("cases")))
            if o["within"] != "not available":
                kind = o["error_kind"]
                value = o["ours"] if kind == "category" else float(o["ours"])
                err = float(o["ours_error"])  # the table holds ours in the statement's unit
                row.update(ours=value, ours_error=err, error_kind=kind, within=judge(st, value, err, kind))
                if kind not in ("category", "fit") and (mid := paper_interval(st)[2]):
                    row["ratio"] = value / mid
        rows.append(row)
    return pd.DataFrame(rows)


def _rejudge_cli(argv: list[str]) -> None:
    """OLD.csv STATEMENTS.yaml OUT.csv: writes OUT.csv and OUT.md, prints the headline."""
    import yaml
    from pathlib import Path
    table_path, statements_path, out = argv
    table = rejudge(read_table(table_path), yaml.safe_load(open(statements_path)))
    table.to_csv(ensure_parent(out), index=False)
    text = markdown(table, {})
    Path(out).with_suffix(".md").write_text(text)
    print(text.split("\n")[2])


if __name__ == "__main__":
    import sys
    if sys.argv[1:2] == ["--rejudge"]:
        _rejudge_cli(sys.argv[2:])
    else:
        main(snakemake_or_cli(globals(), "validation"))

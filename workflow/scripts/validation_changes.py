"""The statements whose verdict differs between two validation tables (e.g. the committed reference
against a new paper run), as a Markdown table.

Standalone only (it compares runs, so it is not a rule):
    git show HEAD:docs/reference/paper/validation.csv > /tmp/old.csv
    python workflow/scripts/validation_changes.py /tmp/old.csv results/validation/validation.csv
"""

from __future__ import annotations

import argparse
import sys

import pandas as pd


def verdict_changes(old: pd.DataFrame, new: pd.DataFrame) -> pd.DataFrame:
    """One row per statement whose `within` verdict changed, or that is in only one table.

    Columns: id, ours_old, ours_new, within_old, within_new ('—' where a table lacks the statement).
    """
    both = old[["id", "ours", "within"]].merge(new[["id", "ours", "within"]], on="id", how="outer",
                                               suffixes=("_old", "_new"), sort=False)
    both[["within_old", "within_new"]] = both[["within_old", "within_new"]].fillna("—")
    changed = both[both["within_old"] != both["within_new"]]
    return changed.reset_index(drop=True)


def counts(table: pd.DataFrame) -> str:
    """'31 of 48 within' from a validation table."""
    return f"{int((table['within'] == 'yes').sum())} of {len(table)} within"


def _number(value) -> str:
    if pd.isna(value):
        return "—"
    try:
        return f"{float(value):.4g}"
    except ValueError:
        return str(value)  # a regime or a shape


def markdown(old: pd.DataFrame, new: pd.DataFrame) -> str:
    """Counts of both tables and the changed statements."""
    rows = verdict_changes(old, new)
    lines = [f"old: {counts(old)}; new: {counts(new)}; {len(rows)} verdicts changed", "",
             "| statement | ours, old | ours, new | within, old | within, new |", "|---|---|---|---|---|"]
    for r in rows.itertuples():
        lines.append(f"| {r.id} | {_number(r.ours_old)} | {_number(r.ours_new)} | {r.within_old} | {r.within_new} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", help="validation.csv of the earlier run")
    parser.add_argument("new", help="validation.csv of the later run")
    args = parser.parse_args(argv)
    sys.stdout.write(markdown(pd.read_csv(args.old), pd.read_csv(args.new)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Shared glue of the workflow scripts: standalone runs, logs, tables with attributes, JSON.

Every script in workflow/scripts runs under Snakemake (`script:`, which injects `snakemake`) and
standalone from the repository root, e.g.

    python workflow/scripts/detect.py --input case=results/cases/h_default/base.nc \
        --output slugs=/tmp/slugs.csv --log /tmp/detect.log

(`--input/--output/--params/--wildcards NAME=VALUE`, repeatable; params are read as YAML, so
`--params 'overrides={run.duration: 1.0}'` works; `--threads N`, `--log PATH`).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml


class NamedList(list):
    """A list whose items can also be reached by name (like Snakemake's input/output/params)."""

    def __init__(self, pairs=()):
        pairs = list(pairs)
        super().__init__(value for _, value in pairs)
        self._names = {}
        for name, value in pairs:
            if name:
                self._names[name] = value

    def __getattr__(self, name):
        try:
            return self.__dict__["_names"][name]
        except KeyError:
            raise AttributeError(name) from None

    def get(self, name, default=None):
        return self._names.get(name, default)

    def keys(self):
        return self._names.keys()


class Standalone:
    """What `snakemake` offers a script, built from the command line."""

    def __init__(self, rule: str, args: argparse.Namespace):
        self.rule = rule
        self.input = NamedList(_pairs(args.input))
        self.output = NamedList(_pairs(args.output))
        self.params = NamedList((k, yaml.safe_load(v)) for k, v in _pairs(args.params))
        self.wildcards = NamedList(_pairs(args.wildcards))
        self.log = NamedList([(None, args.log)] if args.log else [])
        self.threads = args.threads
        self.config = {}


def _pairs(items):
    out = []
    for item in items or []:
        name, sep, value = item.partition("=")
        out.append((name, value) if sep else (None, item))
    return out


def snakemake_or_cli(namespace: dict, rule: str):
    """The injected `snakemake` object, or one built from sys.argv for a standalone run."""
    if "snakemake" in namespace:
        return namespace["snakemake"]
    parser = argparse.ArgumentParser(description=f"workflow script of rule {rule} (standalone)")
    for flag in ("--input", "--output", "--params", "--wildcards"):
        parser.add_argument(flag, action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--log", default=None)
    parser.add_argument("--threads", type=int, default=1)
    return Standalone(rule, parser.parse_args())


def setup_logging(smk) -> logging.Logger:
    """Log to the job's log file (stdout, stderr and warnings too), or to stderr when standalone."""
    log_path = smk.log[0] if len(smk.log) else None
    if log_path:
        Path(log_path).parent.mkdir(parents=True, exist_ok=True)
        stream = open(log_path, "w", buffering=1)
        sys.stdout = sys.stderr = stream
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, force=True,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    logging.captureWarnings(True)
    return logging.getLogger(f"workflow.{smk.rule}")


def ensure_parent(path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _plain(value: Any) -> Any:
    """JSON-friendly: numpy scalars/arrays to Python, NaN/inf to None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_json(data: dict, path) -> None:
    path = ensure_parent(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(_plain(data), indent=1, sort_keys=False) + "\n")
    os.replace(tmp, path)


def read_json(path) -> dict:
    data = json.loads(Path(path).read_text())
    return {k: (math.nan if v is None else v) for k, v in data.items()}


ATTRS_PREFIX = "# attrs: "


def write_table(df, path) -> None:
    """CSV whose first line keeps the DataFrame's attrs as JSON (`# attrs: {...}`)."""
    path = ensure_parent(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as handle:
        handle.write(ATTRS_PREFIX + json.dumps(_plain(dict(df.attrs))) + "\n")
        df.to_csv(handle, index=False)
    os.replace(tmp, path)


def read_table(path):
    """A table written by write_table, attrs restored (None back to NaN)."""
    import pandas as pd

    with open(path) as handle:
        first = handle.readline()
        attrs = json.loads(first[len(ATTRS_PREFIX):]) if first.startswith(ATTRS_PREFIX) else {}
        if not first.startswith(ATTRS_PREFIX):
            handle.seek(0)
        try:
            df = pd.read_csv(handle)
        except pd.errors.EmptyDataError:
            df = pd.DataFrame()
    df.attrs.update({k: (math.nan if v is None else v) for k, v in attrs.items()})
    return df


def save_figure(fig, png, pdf=None, dpi: int = 150) -> None:
    """PNG (and PDF) of a matplotlib Figure via the Agg canvas (no pyplot state)."""
    for path in (png, pdf):
        if path:
            fig.savefig(ensure_parent(path), dpi=dpi)


def note(fig, text: str) -> None:
    """A visible note on a figure (e.g. 'no slugs detected in this run')."""
    fig.text(0.5, 0.5, text, ha="center", va="center", fontsize=9, color="tab:red",
             bbox=dict(facecolor="white", alpha=0.8, edgecolor="tab:red"))

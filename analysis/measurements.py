"""A rig's measured operating points: the measurement file (CSV, units in the header names), checked
row by row, and the targets a calibration compares the simulation with (SI units).

One row per operating point. `#` starts a comment line. Columns (docs/rig-calibration.md):

    label, orientation (horizontal | vertical), tube_length_m, tube_diameter_m,
    particle_diameter_m, particle_density_kg_m3,
    gas_flow_l_min or superficial_velocity_m_s (one of them per row), mass_flow_kg_h,
    pressure_drop_hPa_m, pressure_drop_error_hPa_m,
    optional: plug_velocity_min_m_s, plug_velocity_max_m_s, plug_length_min_m, plug_length_max_m
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

ORIENTATIONS = ("horizontal", "vertical")
# column -> what it holds (the unit is in the name); every one must be > 0 where given
REQUIRED = {
    "label": "a unique name of the operating point",
    "orientation": "horizontal or vertical",
    "tube_length_m": "the rig's tube length",
    "tube_diameter_m": "inner tube diameter",
    "particle_diameter_m": "grain diameter",
    "particle_density_kg_m3": "grain density",
    "mass_flow_kg_h": "grain mass flow",
    "pressure_drop_hPa_m": "pressure drop per metre of tube",
    "pressure_drop_error_hPa_m": "its error (one standard deviation)",
}
GAS = {"gas_flow_l_min": "gas volume flow", "superficial_velocity_m_s": "superficial gas velocity"}
# optional ranges seen at the rig: (min column, max column) -> the simulated quantity compared
RANGES = {
    "plug_velocity": ("plug_velocity_min_m_s", "plug_velocity_max_m_s"),
    "plug_length": ("plug_length_min_m", "plug_length_max_m"),
}
COLUMNS = (*REQUIRED, *GAS, *(c for pair in RANGES.values() for c in pair))
# the same for every row: one material in one tube per file
SHARED = ("tube_diameter_m", "particle_diameter_m", "particle_density_kg_m3")
# measured quantity -> (case summary key it is compared with, unit of the target in SI)
QUANTITIES = {
    "pressure_drop": ("pressure_drop", "Pa m-1"),  # per metre: a shorter simulated tube compares
    "plug_velocity": ("slug_velocity", "m s-1"),  # the plugs' travel speed at the analysis position
    "plug_length": ("slug_length_total", "m"),  # plug length with its ends
}


class MeasurementFileError(ValueError):
    """A measurement file that cannot be used; the message names the line and the column."""


@dataclass(frozen=True)
class _Where:
    path: Path
    line: int
    label: str

    def error(self, column: str, problem: str) -> MeasurementFileError:
        at = f"{self.path}: line {self.line}" + (f" (label {self.label})" if self.label else "")
        return MeasurementFileError(f"{at}, column {column}: {problem}")


def superficial_velocity(gas_flow_l_min: float, tube_diameter_m: float) -> float:
    """Superficial gas velocity (m/s) of a gas volume flow (l/min) in a tube: 4 V / (pi D^2)."""
    return gas_flow_l_min * 1e-3 / 60.0 / (math.pi * tube_diameter_m ** 2 / 4.0)


def _number(where: _Where, column: str, text: str, positive: bool = True) -> float:
    try:
        value = float(text)
    except ValueError:
        raise where.error(column, f"{text!r} is not a number") from None
    if not math.isfinite(value) or (positive and value <= 0.0):
        raise where.error(column, f"must be a finite number > 0, got {text}")
    return value


def _row(where: _Where, raw: dict[str, str]) -> dict:
    row: dict = {"line": where.line}
    for column in REQUIRED:
        text = (raw.get(column) or "").strip()
        if not text:
            raise where.error(column, f"required ({REQUIRED[column]}), empty")
        if column == "label":
            row[column] = text
        elif column == "orientation":
            if text not in ORIENTATIONS:
                raise where.error(column, f"must be one of {', '.join(ORIENTATIONS)}, got {text!r}")
            row[column] = text
        else:
            row[column] = _number(where, column, text)
    if row["particle_diameter_m"] >= row["tube_diameter_m"]:
        raise where.error("particle_diameter_m", f"must be smaller than tube_diameter_m "
                                                 f"({row['tube_diameter_m']} m), got {row['particle_diameter_m']}")
    given = {c: (raw.get(c) or "").strip() for c in GAS if (raw.get(c) or "").strip()}
    if len(given) != 1:
        raise where.error(" or ".join(GAS), f"give exactly one of them per row, got {len(given)}")
    (column, text), = given.items()
    value = _number(where, column, text)
    row[column] = value
    row["superficial_velocity_m_s"] = (value if column == "superficial_velocity_m_s"
                                       else superficial_velocity(value, row["tube_diameter_m"]))
    for low, high in RANGES.values():
        texts = [(raw.get(c) or "").strip() for c in (low, high)]
        if not any(texts):
            row[low] = row[high] = math.nan
            continue
        if not all(texts):
            raise where.error(high if texts[0] else low, f"a range needs both {low} and {high}")
        row[low], row[high] = (_number(where, c, t) for c, t in zip((low, high), texts))
        if row[high] <= row[low]:
            raise where.error(high, f"must be larger than {low} ({texts[0]}), got {texts[1]}")
    return row


def read_measurements(path: str | Path) -> pd.DataFrame:
    """The operating points of a measurement file, one row each, checked; `superficial_velocity_m_s`
    filled from the gas flow where the row gives that. Raises MeasurementFileError naming the line
    and column of the first problem."""
    path = Path(path)
    if not path.is_file():
        raise MeasurementFileError(f"{path}: no such measurement file")
    with path.open(newline="") as f:
        lines = [(n, text) for n, text in enumerate(f, start=1) if text.strip() and not text.lstrip().startswith("#")]
    if not lines:
        raise MeasurementFileError(f"{path}: empty (a header line and one row per operating point)")
    header_line, header = lines[0]
    names = [c.strip() for c in next(csv.reader([header]))]
    unknown = [c for c in names if c not in COLUMNS]
    if unknown:
        raise MeasurementFileError(f"{path}: line {header_line}: unknown column {unknown[0]!r}; "
                                   f"the columns are {', '.join(COLUMNS)}")
    missing = [c for c in REQUIRED if c not in names]
    if missing:
        raise MeasurementFileError(f"{path}: line {header_line}: missing column {missing[0]!r} ({REQUIRED[missing[0]]})")
    rows = []
    for n, text in lines[1:]:
        values = next(csv.reader([text]))
        raw = dict(zip(names, values))
        where = _Where(path, n, (raw.get("label") or "").strip())
        if len(values) != len(names):
            raise where.error(names[min(len(values), len(names)) - 1],
                              f"{len(values)} values for {len(names)} columns")
        rows.append(_row(where, raw))
    if not rows:
        raise MeasurementFileError(f"{path}: no operating points (a header line and one row per point)")
    _check_shared(path, rows)
    return pd.DataFrame(rows).set_index("label")


def _check_shared(path: Path, rows: list[dict]) -> None:
    seen: dict[str, int] = {}
    for row in rows:
        where = _Where(path, row["line"], row["label"])
        if row["label"] in seen:
            raise where.error("label", f"{row['label']!r} is already the label of line {seen[row['label']]}")
        seen[row["label"]] = row["line"]
        for column in SHARED:
            if not math.isclose(row[column], rows[0][column], rel_tol=1e-9):
                raise where.error(column, f"one material in one tube per file: line {rows[0]['line']} "
                                          f"has {rows[0][column]}, this row {row[column]}")


def targets(points: pd.DataFrame) -> pd.DataFrame:
    """What a calibration fits, one row per operating point and measured quantity, in SI units:
    `label`, `quantity` (pressure_drop, plug_velocity, plug_length), `summary_key` (the case summary
    quantity it is compared with), `value`, `error` (one standard deviation) and `unit`.

    A range seen at the rig (plug velocity, plug length) enters as its midpoint with the standard
    deviation of a uniform spread over it, half its width / sqrt(3)."""
    rows = []
    for label, p in points.iterrows():
        rows.append({"label": label, "quantity": "pressure_drop", "value": 100.0 * p["pressure_drop_hPa_m"],
                     "error": 100.0 * p["pressure_drop_error_hPa_m"]})
        for quantity, (low, high) in RANGES.items():
            if low in p and math.isfinite(p[low]):
                rows.append({"label": label, "quantity": quantity, "value": 0.5 * (p[low] + p[high]),
                             "error": 0.5 * (p[high] - p[low]) / math.sqrt(3.0)})
    table = pd.DataFrame(rows)
    table["summary_key"] = [QUANTITIES[q][0] for q in table["quantity"]]
    table["unit"] = [QUANTITIES[q][1] for q in table["quantity"]]
    return table

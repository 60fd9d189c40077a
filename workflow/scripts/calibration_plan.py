"""The cases of the calibration stage (config `calibration`, workflow/rules/calibration.smk): for each
operating point of the measurement file, the design's parameter values as cases of the base case
at that point; case names that carry their values, so that the confirmation round, chosen by the
first fit, needs no other record.

Files, under results/calibration/<name>/:
    cases/<label>/<key~value_...>.nc      summaries/<label>/<key~value_...>.json
    first/design.csv, first/fit.json, first/confirmation.csv     (checkpoint calibration_first)
    fitted.json, fitted.yaml, table.csv, table.md, misfit.png, measured_vs_fitted.png (checkpoint
    calibration)
    prediction/cases/..., prediction/summaries/..., prediction/table.{csv,md}, prediction/predicted.png
    (the cases of the prediction's operating points at the fitted values and one standard
    deviation either side along each fitted key)
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import pandas as pd

import sweeps as sw
from config_check import ConfigError

from analysis.calibration import Bounds, first_design
from analysis.measurements import QUANTITIES, MeasurementFileError, read_measurements
from engine.case import KEYS, Case, CaseError

INCLINATION = {"horizontal": 0.0, "vertical": 90.0}
# the case keys a measured operating point sets (CalibrationPlan.operating)
OPERATING = ("tube.length", "tube.diameter", "tube.inclination_deg", "particles.diameter",
             "particles.density", "gas.superficial_velocity", "feed.mass_flow_kg_h")
SUMMARY_KEYS = tuple(key for key, _ in QUANTITIES.values())  # the summary quantities measured
SIGNIFICANT = 4  # digits of a fitted value in a case name (a confirmation point is rounded to them)


def root(name: str) -> str:
    return f"results/calibration/{name}"


def case_file(folder: str, label: str, point: str) -> str:
    return f"{folder}/cases/{label}/{point}.nc"


def summary_json(folder: str, label: str, point: str) -> str:
    return f"{folder}/summaries/{label}/{point}.json"


class CalibrationPlan:
    """The calibration section of the config, checked: measured points, fitted keys and bounds,
    the base cases, and each case's overrides."""

    def __init__(self, section: Mapping[str, Any], prediction: Mapping[str, Any] | None = None):
        """The calibration (`section`, config `calibration`), or with `prediction` (config
        `prediction`) the cases at its operating points."""
        self.section = dict(section)
        self.name = str(self.section["name"])
        entry, measurements = (("prediction.measurements", prediction["measurements"]) if prediction
                               else ("calibration.measurements", self.section["measurements"]))
        self.measurements = measurements
        self.folder = root(self.name) + ("/prediction" if prediction else "")
        self._feed_bases: dict[str, Case] = {}  # feed_entry's base cases by orientation
        try:
            self.points = read_measurements(measurements)
        except MeasurementFileError as err:
            raise ConfigError(f"config: {entry}: {err}") from None
        fit = dict(self.section["fit"])
        for key in [*fit, *(self.section.get("same_as") or {}), *(self.section.get("same_as") or {}).values(),
                    *(self.section.get("overrides") or {})]:
            if key not in KEYS:
                raise ConfigError(f"config: calibration: unknown case key {key!r}"
                                  f"{sw.did_you_mean(key, KEYS)}; `plugsim keys` lists all keys")
        for target, source in (self.section.get("same_as") or {}).items():
            if source not in fit:
                raise ConfigError(f"config: calibration.same_as.{target}: {source!r} is not a fitted key "
                                  f"({', '.join(fit)})")
        for key in self.section.get("overrides") or {}:
            if key == "tube.length":
                raise ConfigError("config: calibration.overrides.tube.length: give calibration.tube_length")
            if key in OPERATING or key in fit or key in (self.section.get("same_as") or {}):
                raise ConfigError(f"config: calibration.overrides.{key}: set by "
                                  + ("each operating point of the measurement file" if key in OPERATING
                                     else "the fit") + "; leave it out here")
        try:
            self.bounds = Bounds.of({k: tuple(v) for k, v in fit.items()})
        except ValueError as err:
            raise ConfigError(f"config: calibration.fit: {err}") from None
        self.base = dict(self.section["base"])
        for orientation in set(self.points["orientation"]):
            if orientation not in self.base:
                raise ConfigError(f"config: calibration.base: no base case for the {orientation} points "
                                  f"of {measurements}; give base.{orientation}")
        self.first = [self.point_name(row) for row in first_design(self.bounds).to_numpy()]
        self.start = self.point_name(self.bounds.decoded([0.0] * len(self.bounds.keys)))
        for label in self.points.index:  # every case builds: a bad key value fails before any job
            self.case(label, self.start)

    # -- names --

    def point_name(self, values) -> str:
        """Case name of parameter values (own units), each rounded to SIGNIFICANT digits."""
        rounded = {}
        for key, low, high, value in zip(self.bounds.keys, self.bounds.low, self.bounds.high, values):
            rounded[key] = min(max(float(f"{float(value):.{SIGNIFICANT}g}"), float(low)), float(high))
        return sw.point_name(rounded)

    def parameters(self, point: str) -> dict[str, float]:
        """The fitted keys' values a case name carries; ValueError unless it names each fitted key
        once with a value inside the bounds."""
        values = {}
        for part in point.split("_"):
            key, sep, text = part.partition("~")
            if not sep or key not in self.bounds.keys or key in values:
                raise ValueError(f"calibration case {point!r}: not key~value_... of {self.bounds.keys}")
            values[key] = float(text)
        for key, low, high in zip(self.bounds.keys, self.bounds.low, self.bounds.high):
            slack = 1e-9 * (high - low)  # a name's value is rounded, never pushed outside
            if key not in values or not low - slack <= values[key] <= high + slack:
                raise ValueError(f"calibration case {point!r}: {key} missing or outside [{low}, {high}]")
        return values

    # -- cases --

    def operating(self, label: str) -> dict[str, Any]:
        """Case keys of a measured operating point; the simulated tube is `tube_length` (m) when
        the config gives it (per-metre quantities compare), else the rig's."""
        if label not in self.points.index:
            raise ValueError(f"calibration: no operating point {label!r} in {self.measurements}")
        p = self.points.loc[label]
        values = (float(self.section.get("tube_length") or p["tube_length_m"]), float(p["tube_diameter_m"]),
                  INCLINATION[p["orientation"]], float(p["particle_diameter_m"]),
                  float(p["particle_density_kg_m3"]), float(p["superficial_velocity_m_s"]),
                  float(p["mass_flow_kg_h"]))
        keys = dict(zip(OPERATING, values))
        keys.update(self.feed_entry(p["orientation"], keys["feed.mass_flow_kg_h"]))
        return keys

    def feed_entry(self, orientation: str, mass_flow_kg_h: float) -> dict[str, float]:
        """At a mass flow other than the base case's, the feed's entry velocity (m/s) scaled with
        it, so that the feed packs its layers as the base case does (the paper configuration's
        mass-flow points do the same); at the base case's own mass flow nothing."""
        if orientation not in self._feed_bases:  # read once per base case
            self._feed_bases[orientation] = Case.from_yaml(self.base[orientation]).with_overrides(
                list((self.section.get("overrides") or {}).items()))
        base = self._feed_bases[orientation]
        if mass_flow_kg_h == base["feed.mass_flow_kg_h"]:
            return {}
        return {"feed.entry_velocity": base["feed.entry_velocity"] * mass_flow_kg_h / base["feed.mass_flow_kg_h"]}

    def overrides(self, label: str, point: str) -> dict[str, Any]:
        """Every override of a case: the calibration's `overrides` < the operating point < the
        fitted values (and the keys tied to them by `same_as`)."""
        values = self.parameters(point)
        merged = {**dict(self.section.get("overrides") or {}), **self.operating(label), **values}
        for target, source in (self.section.get("same_as") or {}).items():
            merged[target] = values[source]
        return merged

    def base_case(self, label: str) -> str:
        return self.base[self.points.loc[label, "orientation"]]

    def case(self, label: str, point: str) -> Case:
        try:
            return Case.from_yaml(self.base_case(label)).with_overrides(list(self.overrides(label, point).items()))
        except CaseError as err:
            raise ConfigError(f"config: calibration, point {label}, case {point}: {err}") from None

    def simulate_inputs(self, label: str, point: str, start: str | None = None) -> dict[str, str]:
        """Base case YAML; every case but the start (the design's centre, or for a prediction the
        fitted values) begins with the start's grains at its operating point."""
        self.parameters(point)
        start = start or self.start
        inputs = {"base": self.base_case(label)}
        if point != start:
            inputs["initial_state"] = case_file(self.folder, label, start)
        return inputs

    def runtime_minutes(self, label: str, point: str) -> int:
        """Wall-time request of a case's job (SLURM --time), the workflow's cost model
        (Plan.runtime_minutes): 10 min plus twice ~1 min per simulated second for 3000 grains,
        scaled with tube length and mass flow."""
        case = self.case(label, point)
        grains = max(1.0, case["feed.mass_flow_kg_h"] / 2.49) * case["tube.length"] / 0.525
        return int(10 + 2 * case["run.duration"] * grains)

    def position(self, label: str) -> float:
        """Where slugs are measured (m): mid-tube of the simulated tube, where the papers' camera is."""
        return 0.5 * self.operating(label)["tube.length"]

    def first_summaries(self) -> list[str]:
        return [summary_json(self.folder, label, point) for label in self.points.index for point in self.first]

    def confirmation_summaries(self, confirmation_csv: str | Path) -> list[str]:
        """Summaries of the confirmation round listed by the first fit (its `point` column)."""
        names = pd.read_csv(confirmation_csv)["point"]
        return [summary_json(self.folder, label, point) for label in self.points.index for point in names]

    def prediction_points(self, fitted: Mapping[str, Any]) -> list[str]:
        """Case names of a prediction: the fitted values (fitted.json), then one standard deviation
        up and down along each fitted key, kept inside the bounds."""
        values = [fitted["parameters"][k]["value"] for k in self.bounds.keys]
        names = [self.point_name(values)]
        for i, key in enumerate(self.bounds.keys):
            for sign in (1.0, -1.0):
                moved = list(values)
                moved[i] += sign * fitted["parameters"][key]["std"]
                names.append(self.point_name(moved))
        return names

    def prediction_summaries(self, fitted: Mapping[str, Any]) -> list[str]:
        return [summary_json(self.folder, label, point) for label in self.points.index
                for point in dict.fromkeys(self.prediction_points(fitted))]


def _number(value) -> float:
    """A summary's value as a float, NaN for none."""
    return math.nan if value is None else float(value)


def design_table(summaries: Mapping[str, Mapping], plan: CalibrationPlan) -> pd.DataFrame:
    """One row per simulated case: label, point, the fitted keys' values, the summary's quantities
    with their standard errors (NaN where the summary has none) and the case's CPU seconds.

    A quantity whose error estimator did not converge (the window covers fewer correlation times
    than it asks: the error NaN) carries the same estimator's error over that window instead
    (`<key>_sem_estimate`), and `<key>_sem_converged` says which: the case's value stays on its
    surface with an error that may be low (12 % in the median at 20 correlation times; fewer
    give no estimate: analysis.timeseries.ESTIMATE_MIN_CORRELATION_TIMES), rather than dropping out.
    """
    rows = []
    for path, s in summaries.items():
        label, point = Path(path).parent.name, Path(path).stem
        row = {"label": label, "point": point, **plan.parameters(point)}
        for key in (*SUMMARY_KEYS, "n_particles"):
            value, error, estimate = (_number(s.get(name)) for name in (key, f"{key}_sem", f"{key}_sem_estimate"))
            converged = math.isfinite(error)
            row[key], row[f"{key}_sem_converged"] = value, converged
            row[f"{key}_sem"] = error if converged or not math.isfinite(value) else estimate
        row["regime"] = s.get("regime", "")
        row["cpu_time_s"] = _number(s.get("cpu_time_s"))
        rows.append(row)
    return pd.DataFrame(rows)

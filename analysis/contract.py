"""The case-file contract: every variable of a case file (NetCDF4), declared once.

Each variable has its name, dimensions, storage type, CF units and long name, and, where the plots
draw it, an axis label in the papers' words and unit with the factor from SI to that unit. The
engine writes with these declarations (engine/output.py, engine/run.py), the analysis reads and
labels with them (casefile.require checks the units, profiles, plots), and the synthetic case
files of the tests are built from them (tests/analysis/synthetic.py). docs/case-file.md is this
module's table: `python -m analysis > docs/case-file.md`.

Numpy only: the engine imports this module, and the analysis never imports the engine.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TIME = ("time",)
SLICES = ("time", "x")


@dataclass(frozen=True)
class Variable:
    """One variable of the case file."""

    name: str
    dims: tuple[str, ...]
    dtype: str  # numpy type as stored
    units: str | None  # CF units; None for a label coordinate (xyz)
    long_name: str
    label: str | None = None  # plot axis label (papers' words and unit); None: not drawn
    factor: float = 1.0  # from SI to the label's unit
    profile: bool = False  # averaged along the slug in the slug profiles (H12-H16, V13-V17)
    axis: str | None = None  # CF axis of a coordinate (T, X)
    sample_dimension: str | None = None  # the count variable of a CF contiguous ragged array

    @property
    def attrs(self) -> dict[str, str]:
        """The CF attributes as written (a ragged array's count: long_name, sample_dimension, units)."""
        if self.sample_dimension:
            return {"long_name": self.long_name, "sample_dimension": self.sample_dimension,
                    "units": self.units}
        attrs = {} if self.units is None else {"units": self.units}
        attrs["long_name"] = self.long_name
        if self.axis:
            attrs["axis"] = self.axis
        return attrs

    def entry(self, values, cast: bool = True) -> tuple:
        """(dims, array, attrs) for an xarray Dataset; `cast` stores the values as `dtype`
        (the engine), else they keep their own type (the synthetic files keep float64)."""
        return self.dims, np.asarray(values, dtype=self.dtype if cast else None), self.attrs


def _group(*variables: Variable) -> dict[str, Variable]:
    return {v.name: v for v in variables}


def _series(name, units, long_name, dtype="float64") -> Variable:
    return Variable(name, TIME, dtype, units, long_name)


def _field(name, units, long_name, label=None, factor=1.0) -> Variable:
    return Variable(name, SLICES, "float32", units, long_name, label, factor, profile=label is not None)


COORDS = _group(
    Variable("time", TIME, "float64", "s", "simulated time", axis="T"),
    Variable("x", ("x",), "float64", "m", "slice centre along the tube axis from the inlet", axis="X"),
    Variable("snapshot_time", ("snapshot_time",), "float64", "s", "snapshot time"),
    Variable("tube_snapshot_time", ("tube_snapshot_time",), "float64", "s", "whole-tube snapshot time"),
    Variable("xyz", ("xyz",), "str", None, "component"),
)

# One value per output frame. The engine records each as the Simulation property of its name
# (engine/output.py, Recorder.sample), except max_overlap (per grain diameter) and piston_force
# (the piston's impulse over the output interval).
SERIES = _group(
    _series("pressure_drop", "Pa", "gas pressure at the inlet minus at the outlet"),
    _series("n_particles", "1", "grains inside the tube", "int64"),
    _series("mass_in", "kg", "cumulative grain mass fed into the tube"),
    _series("mass_out", "kg", "cumulative grain mass that left past the outlet"),
    _series("kinetic_energy", "J", "translational plus rotational kinetic energy of the grains in the tube"),
    _series("max_overlap", "1", "largest grain-grain, grain-wall or grain-feed overlap over the steps of "
                                "the output interval, fraction of the grain diameter"),
    _series("piston_force", "N", "mean axial force of the feed piston on the grains over the output interval"),
)

# Slice averages per output frame, from Simulation.slice_fields (gas_pressure: gas_pressure_slices).
# The fields with a label are the papers' averaged slug profiles.
FIELDS = _group(
    _field("porosity", "1", "slice porosity (grains weighted by their volume in the slice)", "porosity"),
    _field("velocity", "m s-1", "mean axial grain velocity in the slice (volume-weighted)",
           "granular velocity (m/s)"),
    _field("drag_force", "N", "mean axial gas drag force per grain in the slice", "force per grain (µN)", 1e6),
    _field("particle_force", "N", "mean axial contact + wall + gravity force per grain in the slice",
           "force per grain (µN)", 1e6),
    _field("wall_stress", "Pa", "normal stress of the grains on the tube wall in the slice", "wall stress (Pa)"),
    _field("granular_temperature", "J", "mean grain kinetic energy minus that of the slice's mean motion",
           "granular temperature per grain (nJ)", 1e9),
    _field("gas_pressure", "Pa", "gas pressure relative to the background pressure, slice average"),
)

_CENTRE = "grain centre (x along the tube, y and z across)"
_ID = "grain id (order of entry into the tube)"

# Grains in the snapshot window (optional): a CF contiguous ragged array over `grain`.
SNAPSHOTS = _group(
    Variable("snapshot_count", ("snapshot_time",), "int64", "1",
             "grains in the snapshot window at each snapshot time", sample_dimension="grain"),
    Variable("snapshot_position", ("grain", "xyz"), "float32", "m", _CENTRE),
    Variable("snapshot_velocity", ("grain", "xyz"), "float32", "m s-1", "grain velocity"),
    Variable("snapshot_grain_id", ("grain",), "int64", "1", _ID),
)

# Every grain in the tube (optional), likewise over `tube_grain`.
TUBE_SNAPSHOTS = _group(
    Variable("tube_snapshot_count", ("tube_snapshot_time",), "int64", "1",
             "grains in the tube at each whole-tube snapshot time", sample_dimension="tube_grain"),
    Variable("tube_snapshot_position", ("tube_grain", "xyz"), "float32", "m", _CENTRE),
    Variable("tube_snapshot_velocity", ("tube_grain", "xyz"), "float32", "m s-1", "grain velocity"),
    Variable("tube_snapshot_angular_velocity", ("tube_grain", "xyz"), "float32", "rad s-1",
             "grain angular velocity"),
    Variable("tube_snapshot_grain_id", ("tube_grain",), "int64", "1", _ID),
)

# The grains at the end of the run, the start of a warm run.
FINAL = _group(
    Variable("final_position", ("final_grain", "xyz"), "float64", "m", "grain centre at the end of the run"),
    Variable("final_velocity", ("final_grain", "xyz"), "float64", "m s-1", "grain velocity at the end of the run"),
    Variable("final_angular_velocity", ("final_grain", "xyz"), "float64", "rad s-1",
             "grain angular velocity at the end of the run"),
)

# The pickled simulation (engine/run.py adds the attribute `digest`), read by the engine only.
RESTART = _group(
    Variable("restart_state", ("restart_byte",), "uint8", "1",
             "full engine state at the end of the run (pickled), to continue it to a longer run.duration"),
)

GROUPS = {
    "coordinates": COORDS,
    "series, one value per output frame": SERIES,
    "slice fields": FIELDS,
    "snapshots (optional)": SNAPSHOTS,
    "whole-tube snapshots (optional)": TUBE_SNAPSHOTS,
    "final state": FINAL,
    "restart state": RESTART,
}
VARIABLES = {name: v for group in GROUPS.values() for name, v in group.items()}
PROFILE_FIELDS = tuple(name for name, v in FIELDS.items() if v.profile)


def label(name: str) -> tuple[str, float]:
    """(plot axis label, factor from SI to its unit) of a variable; the name and 1 without a label."""
    v = VARIABLES.get(name)
    return (v.label, v.factor) if v is not None and v.label else (name, 1.0)


def markdown() -> str:
    """docs/case-file.md: one table of every variable, by group."""
    lines = ["# The case file's variables", "",
             "Generated from `analysis/contract.py` (`python -m analysis > docs/case-file.md`;",
             "`tests/analysis/test_contract.py` checks it is fresh). The file as a whole, its global",
             "attributes and who writes and reads it: [design.md](design.md#the-case-file-netcdf4).", "",
             "| group | variable | dimensions | stored as | units | long name | plot label |",
             "|---|---|---|---|---|---|---|"]
    for group, variables in GROUPS.items():
        for v in variables.values():
            lines.append(f"| {group} | `{v.name}` | {', '.join(v.dims)} | {v.dtype} | "
                         f"{v.units if v.units is not None else '-'} | {v.long_name} | {v.label or '-'} |")
    return "\n".join(lines) + "\n"

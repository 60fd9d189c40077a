"""The registry of figure kinds: per kind, what each case it draws must record, the files it reads
and the function of workflow/scripts/figure.py that draws it.

A figure in config `figures` names its kind. The plan (workflow/scripts/plan.py) reads `needs` and
`inputs`, the figure script reads `draw`, and a test checks the config schema's enum of kinds
against this registry. Adding a kind: one entry here, its draw function in figure.py (usually a
plot in analysis/plots.py) and the kind in the schema's enum.

What a case can be asked to record (`needs`):
  steady    - only a steady mean (the case may stop once it has converged: run.until_steady)
  series    - the slice time series over the whole run (fixed duration)
  snapshots - grain snapshots in the window output.snapshot_x_min .. x_max
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

NEEDS = ("steady", "series", "snapshots")

# what a figure entry draws: one case, several cases, one sweep's curve or several curves
DRAWS = ("case", "cases", "sweep", "sweeps")


@dataclass(frozen=True)
class FigureKind:
    """One figure family: `inputs(files, spec, cases, sweeps)` gives the named input files from
    the plan's path functions (`files`), the figure's config entry, the (sweep, point) of the cases
    drawn and the sweeps drawn."""

    needs: frozenset[str]
    draws: str
    inputs: Callable[[Any, dict, list, list], dict[str, Any]]
    draw: str


def _case_files(files, spec, cases, sweeps):
    return {"cases": [files.case_nc(*c) for c in cases]}


def _grains(files, spec, cases, sweeps):
    return {"case": files.case_nc(*cases[0]), "slugs": files.slugs_csv(*cases[0]),
            "selection": files.selection_csv(*cases[0])}


def _curve_tables(files, spec, cases, sweeps):
    inputs = {"tables": [files.curve_csv(s) for s in sweeps]}
    if spec.get("experiment"):  # V table 1 drawn over the curve
        inputs["experiment"] = files.experiment_csv
    return inputs


def _statistics(files, spec, cases, sweeps):
    return {"statistics": files.statistics_csv(*cases[0])}


def _profile(files, spec, cases, sweeps):
    return {"profile": files.profile_nc(*cases[0])}


def _snapshots(what):
    def inputs(files, spec, cases, sweeps):
        return {"snapshots": files.snapshot_nc(*cases[0], what)}
    return inputs


def _radial(files, spec, cases, sweeps):
    return {"radial": files.snapshot_nc(*cases[0], "radial")}


SERIES = frozenset({"series"})
GRAINS = frozenset({"series", "snapshots"})
STEADY = frozenset({"steady"})

KINDS: dict[str, FigureKind] = {
    "porosity_image": FigureKind(SERIES, "case", _case_files, "porosity_image"),
    "porosity_image_pair": FigureKind(SERIES, "cases", _case_files, "porosity_image_pair"),
    "grains_3d": FigureKind(GRAINS, "case", _grains, "grains_3d"),
    "curve": FigureKind(STEADY, "sweep", _curve_tables, "curve"),
    "curve_pair": FigureKind(STEADY, "sweeps", _curve_tables, "curve_pair"),
    "slug_rate": FigureKind(SERIES, "case", _statistics, "slug_rate"),
    "slug_statistic": FigureKind(SERIES, "case", _statistics, "slug_statistic"),
    "profile": FigureKind(SERIES, "case", _profile, "profile"),
    "cross_sections": FigureKind(GRAINS, "case", _snapshots("cross_sections"), "cross_sections"),
    "velocity_height_image": FigureKind(GRAINS, "case", _snapshots("velocity_height"),
                                        "velocity_height_image"),
    "velocity_height": FigureKind(GRAINS, "case", _snapshots("velocity_height"), "velocity_height"),
    "radial": FigureKind(GRAINS, "case", _radial, "radial"),
}


def kind_of(fig: str, spec: dict) -> FigureKind:
    """The registry entry of a figure's config entry; ValueError naming the figure and the known kinds."""
    kind = spec.get("kind")
    if kind not in KINDS:
        raise ValueError(f"config: figure {fig}: unknown kind {kind!r} (known: {sorted(KINDS)})")
    return KINDS[kind]

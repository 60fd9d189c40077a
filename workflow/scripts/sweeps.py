"""Sweeps declared in the config, expanded to one case per point (used by workflow/scripts/plan.py).

A sweep (config `sweeps.<name>`) names a base case YAML, fixed overrides and parameters with value
lists; every combination of the parameter values is one point (a full factorial, like Snakemake's
Paramspace), or with `design: one_at_a_time` the point of every parameter's first value plus one
point per other value with the rest at their first (a screening from a baseline), crossed in full
with the parameters listed under `crossed`. A value may also be a mapping of several keys that move together (its own key gives the
point name), and `same_as` ties a key to a parameter (wall.friction follows particles.friction).

A point is named by its parameters, `key~value` joined by `_`, e.g.
`gas.superficial_velocity~1_feed.mass_flow_kg_h~2.49`; a sweep without parameters has the single
point `base`. Points are looked up by name (never parsed), so names only need to be unique.

Precedence of the overrides of a case, later wins:
  base YAML < derived (what the consumers need) < sweep `overrides` < config `all_cases` < point.
"""

from __future__ import annotations

import difflib
import itertools
import math
from typing import Any, Iterable, Mapping

BASE_POINT = "base"


class SweepError(ValueError):
    """A sweep or a reference to a sweep point that does not make sense (message names it)."""


def format_value(value: Any) -> str:
    """A value as written in a point name: 1.0 -> '1', 6.73e-05 -> '6.73e-05', True -> 'true'."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        text = format(value, ".12g")
        return text
    return str(value).replace("/", "-").replace(" ", "-")


def did_you_mean(word: str, candidates) -> str:
    """' (did you mean 'x'?)' for the closest candidate, or ''."""
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _levels(name: str, values: Any, sweep: str) -> list[dict[str, Any]]:
    """The levels of one parameter: each a mapping of case keys to values."""
    if not isinstance(values, list) or not values:
        raise SweepError(f"sweep {sweep!r}: parameter {name!r} needs a non-empty list of values")
    levels = []
    for value in values:
        if isinstance(value, Mapping):
            if name not in value:
                raise SweepError(f"sweep {sweep!r}: every mapping value of parameter {name!r} must "
                                 f"set {name!r} itself (it names the point); got {dict(value)}")
            levels.append(dict(value))
        else:
            levels.append({name: value})
    return levels


def point_name(parameters: Mapping[str, Any]) -> str:
    """'key~value' pairs joined by '_' (the parameters in declaration order), or 'base'."""
    if not parameters:
        return BASE_POINT
    return "_".join(f"{key}~{format_value(value)}" for key, value in parameters.items())


def expand(sweep: str, spec: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Points of a sweep: name -> the overrides that define the point (parameters, linked keys, same_as).

    Raises SweepError when two points would get the same name or `same_as` names an unknown parameter.
    """
    parameters = spec.get("parameters") or {}
    same_as = spec.get("same_as") or {}
    names = list(parameters)
    for target, source in same_as.items():
        if source not in names:
            raise SweepError(f"sweep {sweep!r}: same_as {target!r}: {source!r} is not one of its "
                             f"parameters{did_you_mean(source, names)}: {names}")
    points: dict[str, dict[str, Any]] = {}
    for combo in _combinations(sweep, spec, names, [_levels(n, parameters[n], sweep) for n in names]):
        values: dict[str, Any] = {}
        for level in combo:
            values.update(level)
        label = point_name({n: level[n] for n, level in zip(names, combo)})
        for target, source in same_as.items():
            values[target] = values[source]
        if label in points:
            raise SweepError(f"sweep {sweep!r}: two points are both named {label!r}; "
                             "make the parameter values distinct")
        points[label] = values
    return points


def _combinations(sweep: str, spec: Mapping[str, Any], names: list[str],
                  levels: list[list[dict[str, Any]]]) -> list[tuple]:
    """Level combinations of the sweep's design: every one (full), or the baseline of first levels
    and each other level alone (one_at_a_time), crossed in full with the `crossed` parameters."""
    design, crossed = spec.get("design", "full"), list(spec.get("crossed") or [])
    if design not in ("full", "one_at_a_time"):
        raise SweepError(f"sweep {sweep!r}: design {design!r} is not one of full, one_at_a_time")
    unknown = [name for name in crossed if name not in names]
    if unknown or (crossed and design == "full"):
        raise SweepError(f"sweep {sweep!r}: crossed {crossed} must name parameters {names} of a "
                         "one_at_a_time design")
    if design == "full":
        return list(itertools.product(*levels))
    screened = [i for i, name in enumerate(names) if name not in crossed]
    base = [levels[i][0] for i in screened]
    screen = [tuple(base)] + [tuple(base[:k] + [other] + base[k + 1:])
                              for k, i in enumerate(screened) for other in levels[i][1:]]
    combos = []
    for fixed in itertools.product(*[levels[i] for i, name in enumerate(names) if name in crossed]):
        for row in screen:
            parts, fixed_iter, row_iter = [], iter(fixed), iter(row)
            for name in names:
                parts.append(next(fixed_iter) if name in crossed else next(row_iter))
            combos.append(tuple(parts))
    return combos


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-15)
    return a == b


def find_point(sweep: str, points: Mapping[str, Mapping[str, Any]], where: Mapping[str, Any] | None,
               required: bool = True) -> str | None:
    """Name of the one point whose values match `where` (all keys equal); the only point if None."""
    where = where or {}
    found = [name for name, values in points.items()
             if all(key in values and _equal(values[key], v) for key, v in where.items())]
    if len(found) == 1:
        return found[0]
    if not required and not found:
        return None
    what = f"matching {dict(where)}" if where else "(give `point:` to choose one)"
    raise SweepError(f"sweep {sweep!r} has {len(found)} points {what}; its points are "
                     f"{list(points)}")


def _named_levels(sweep: str, entry: str, name: str, parameters: Mapping[str, Any]) -> list[Any]:
    """The values of parameter `name` that a sweep entry (warm_start_from_next, empty_start) names;
    SweepError if it is not one of the sweep's parameters."""
    if name not in parameters:
        raise SweepError(f"sweep {sweep!r}: {entry}: {name!r} is not one of its "
                         f"parameters{did_you_mean(name, parameters)}: {list(parameters)}")
    return [level[name] for level in _levels(name, parameters[name], sweep)]


def next_point_sources(sweep: str, spec: Mapping[str, Any],
                       points: Mapping[str, Mapping[str, Any]]) -> dict[str, str]:
    """Warm-start sources of `warm_start_from_next`: point -> the point with the next value of the
    named parameter (the other parameters equal). Raises SweepError naming the key and the values."""
    parameters = spec.get("parameters") or {}
    sources: dict[str, str] = {}
    for name, values in (spec.get("warm_start_from_next") or {}).items():
        levels = _named_levels(sweep, "warm_start_from_next", name, parameters)
        for value in values:
            index = next((i for i, level in enumerate(levels) if _equal(level, value)), None)
            if index is None or index == len(levels) - 1:
                raise SweepError(f"sweep {sweep!r}: warm_start_from_next: {name} = {value!r} must be "
                                 f"one of its values except the last, {levels[:-1]}")
            for point, overrides in points.items():
                if _equal(overrides[name], value):
                    where = {key: overrides[key] for key in parameters}
                    where[name] = levels[index + 1]
                    sources[point] = find_point(sweep, points, where)
    return sources


def empty_start_points(sweep: str, spec: Mapping[str, Any],
                       points: Mapping[str, Mapping[str, Any]]) -> set[str]:
    """Points of `empty_start` ({parameter: [values]}): those with one of the values run from an
    empty tube whatever `warm_start` says. Raises SweepError naming the key and the values."""
    parameters = spec.get("parameters") or {}
    chosen: set[str] = set()
    for name, values in (spec.get("empty_start") or {}).items():
        levels = _named_levels(sweep, "empty_start", name, parameters)
        for value in values:
            if not any(_equal(level, value) for level in levels):
                raise SweepError(f"sweep {sweep!r}: empty_start: {name} = {value!r} must be one of "
                                 f"its values, {levels}")
            chosen |= {point for point, overrides in points.items() if _equal(overrides[name], value)}
    return chosen


def derived_overrides(needs: set[str]) -> dict[str, Any]:
    """Outputs a case needs from its consumers: snapshots only for snapshot figures; stop when
    steady when every consumer uses only the steady mean."""
    out: dict[str, Any] = {"output.snapshots": "snapshots" in needs}
    out["run.until_steady"] = bool(needs) and needs <= {"steady"}
    return out


def case_overrides(config: Mapping[str, Any], sweep: str, point: str,
                   needs: set[str]) -> dict[str, Any]:
    """Every override of one case, in precedence order (see the module docstring)."""
    spec = config["sweeps"][sweep]
    points = expand(sweep, spec)
    if point not in points:
        raise SweepError(f"sweep {sweep!r} has no point {point!r}; its points are {list(points)}")
    merged: dict[str, Any] = {}
    for layer in (derived_overrides(needs), spec.get("overrides") or {},
                  config.get("all_cases") or {}, points[point]):
        merged.update(layer)
    return merged


def references(ref: Mapping[str, Any] | Iterable) -> list[Mapping[str, Any]]:
    """A case reference ({sweep, point}) or a list of them, as a list."""
    return [ref] if isinstance(ref, Mapping) else list(ref)

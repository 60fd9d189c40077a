"""The plan of the workflow, built once when Snakemake parses it (workflow/rules/common.smk): the
points of every sweep, what each case must record for its consumers (figures, curves, validation
statements), warm starts, identical cases run once, and the file name of every product.

`Plan(config, statements)` raises PlanError (a ValueError whose message names the config entry)
for anything that does not make sense, so a typo fails before any job starts. The rules call its
path functions; with wildcard strings they give the rules' output patterns, e.g.
`slugs_csv("{sweep}", "{point}")`.
"""

from __future__ import annotations

import csv
import hashlib
from collections import defaultdict
from pathlib import Path
from typing import Any, Mapping

import yaml

import sweeps as sw
from figure_kinds import KINDS, kind_of

from engine.case import KEYS, Case, CaseError

Key = tuple[str, str]  # (sweep, point)

# what a validation measure (resources/paper_statements.yaml) needs from the cases it reads
MEASURE_NEEDS = {
    "pressure_drop": {"steady"}, "n_particles": {"steady"}, "regime": {"steady"},
    "ratio": {"steady"}, "transition": {"steady"}, "argmax": {"steady"}, "trend": {"steady"},
    "monotonic": {"steady"}, "fit_deviation": {"steady"},
    "slug_stat": {"series"}, "slug_rate": {"series"}, "profile_min": {"series"},
    "profile_max": {"series"}, "selection_mean": {"series"},
    "radial_outer_minimum": {"series", "snapshots"},
}

# keys the plan derives from the consumers; they tell cases apart only where a config sets them
DERIVED = ("output.snapshots", "run.until_steady")


class PlanError(ValueError):
    """A config entry the plan cannot follow (the message names it)."""


# ---- file names ---------------------------------------------------------------------------------

def case_file(sweep: str, point: str) -> str:
    return f"results/cases/{sweep}/{point}.nc"


def slugs_csv(sweep: str, point: str) -> str:
    return f"results/slugs/{sweep}/{point}.csv"


def summary_json(sweep: str, point: str) -> str:
    return f"results/summaries/{sweep}/{point}.json"


def statistics_csv(sweep: str, point: str) -> str:
    return f"results/statistics/{sweep}/{point}.csv"


def profile_nc(sweep: str, point: str) -> str:
    return f"results/profiles/{sweep}/{point}.nc"


def selection_csv(sweep: str, point: str) -> str:
    return f"results/profiles/{sweep}/{point}.selection.csv"


def snapshot_nc(sweep: str, point: str, what: str) -> str:
    return f"results/snapshots/{sweep}/{point}/{what}.nc"


def curve_csv(sweep: str) -> str:
    return f"results/curves/{sweep}.csv"


def curve_png(sweep: str) -> str:
    return f"results/curves/{sweep}.png"


def figure_files(fig: str) -> list[str]:
    return [f"results/figures/{fig}.{ext}" for ext in ("png", "pdf", "txt")]


def derives_from_one_case(path: str, sweep: str, point: str) -> bool:
    """Whether `path` is a product of the case (sweep, point) alone: its slugs, summary, statistics,
    profile, profile selection or a snapshot product."""
    own = {slugs_csv(sweep, point), summary_json(sweep, point), statistics_csv(sweep, point),
           profile_nc(sweep, point), selection_csv(sweep, point)}
    return path in own or path.startswith(f"results/snapshots/{sweep}/{point}/")


VALIDATION_CSV = "results/validation/validation.csv"


def source_digest(folder: str | Path) -> str:
    """SHA-256 of every .py file under `folder` (relative names and contents): the rerun key of
    the jobs that run the engine, so that any change to its source reruns them."""
    folder = Path(folder)
    digest = hashlib.sha256()
    for path in sorted(folder.rglob("*.py")):
        digest.update(path.relative_to(folder).as_posix().encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()


# ---- steps of the plan --------------------------------------------------------------------------

def check_case_keys(sweep: str, spec: Mapping) -> None:
    """Every case key a sweep names is an engine key (PlanError naming the entry, with a
    suggestion), checked before `same_as` or `warm_start_from_next` look a parameter up."""
    named = [("overrides", k) for k in spec.get("overrides") or {}]
    for name, values in (spec.get("parameters") or {}).items():
        named.append(("parameters", name))
        named += [(f"parameters.{name}", k) for v in values if isinstance(v, Mapping) for k in v]
    for target, source in (spec.get("same_as") or {}).items():
        named += [("same_as", target), (f"same_as.{target}", source)]
    named += [("warm_start_from_next", k) for k in spec.get("warm_start_from_next") or {}]
    named += [("empty_start", k) for k in spec.get("empty_start") or {}]
    for entry, key in named:
        if key not in KEYS:
            raise PlanError(f"config: sweep {sweep!r}: {entry}: unknown case key {key!r}"
                            f"{sw.did_you_mean(key, KEYS)}; `plugsim keys` lists all keys")


def expand_sweeps(sweeps: Mapping[str, Mapping]) -> dict[str, dict[str, dict]]:
    """sweep -> {point name -> the point's overrides}."""
    points = {}
    for name, spec in sweeps.items():
        check_case_keys(name, spec)
        try:
            points[name] = sw.expand(name, spec)
        except sw.SweepError as err:
            raise PlanError(f"config: {err}") from None
    return points


def resolve_ref(points: Mapping, ref: Mapping, what: str, required: bool = True) -> Key | None:
    """(sweep, point) of a case reference {sweep, point: {key: value}}; None if optional and absent."""
    sweep = ref.get("sweep")
    if sweep not in points:
        if not required:
            return None
        raise PlanError(f"config: {what} refers to sweep {sweep!r}, which is not declared "
                        f"(sweeps: {sorted(points)})")
    try:
        point = sw.find_point(sweep, points[sweep], ref.get("point"), required=required)
    except sw.SweepError as err:
        raise PlanError(f"config: {what}: {err}") from None
    return None if point is None else (sweep, point)


def figure_cases(points: Mapping, fig: str, spec: Mapping) -> list[Key]:
    """(sweep, point) of every single case a figure draws (not the curves)."""
    refs = []
    for name in ("case", "cases"):
        if name in spec:
            refs += sw.references(spec[name])
    return [resolve_ref(points, ref, f"figure {fig}") for ref in refs]


def figure_sweeps(points: Mapping, fig: str, spec: Mapping) -> list[str]:
    """The sweeps whose curves a figure draws."""
    names = ([spec["sweep"]] if "sweep" in spec else []) + list(spec.get("sweeps") or [])
    for name in names:
        if name not in points:
            raise PlanError(f"config: figure {fig} draws sweep {name!r}, which is not declared")
    return names


def check_figure(fig: str, spec: Mapping) -> None:
    """The figure's kind is registered and the entry names what that kind draws."""
    try:
        kind = kind_of(fig, spec)
    except ValueError as err:
        raise PlanError(str(err)) from None
    if kind.draws not in spec:
        raise PlanError(f"config: figure {fig}: kind {spec['kind']} draws `{kind.draws}`; "
                        f"the entry has {sorted(k for k in spec if k not in ('kind', 'title'))}")


def statement_cases(statements: list[dict], points: Mapping, source: str) -> list[dict]:
    """The statements, each with `_cases` (its (sweep, point), None where not declared) and
    `_missing` (its sweep is not declared); PlanError for an unknown measure."""
    out = []
    for st in statements:
        if st["measure"] not in MEASURE_NEEDS:
            raise PlanError(f"{source}: statement {st.get('id')}: unknown measure {st['measure']!r} "
                            f"(known: {sorted(MEASURE_NEEDS)})")
        refs = sw.references(st.get("case") or st.get("cases") or [])
        item = dict(st, _cases=[resolve_ref(points, r, f"statement {st['id']}", required=False)
                                for r in refs])
        if st.get("sweep") and st["sweep"] not in points:
            item["_missing"] = True
        out.append(item)
    return out


def consumer_needs(points: Mapping, figures: Mapping, statements: list[dict]) -> dict[Key, set]:
    """(sweep, point) -> what its consumers need: every point feeds its sweep's curve (steady);
    figures and statements add what their kind or measure reads."""
    needs = {(s, p): {"steady"} for s in points for p in points[s]}
    for fig, spec in figures.items():
        for key in figure_cases(points, fig, spec):
            needs[key] |= KINDS[spec["kind"]].needs
    for st in statements:
        for key in st["_cases"]:
            if key is not None:
                needs[key] |= MEASURE_NEEDS[st["measure"]]
    return needs


def warm_sources(sweeps: Mapping, points: Mapping) -> dict[Key, Key]:
    """(sweep, point) -> (sweep, point) of the case whose final grains it starts from: a sweep's
    `warm_start` case for its points (that case itself runs from an empty tube, and so do the
    points of `empty_start`), or, for the points of `warm_start_from_next` (whether or not in
    `empty_start`), their neighbour in the same sweep."""
    sources = {}
    for sweep, spec in sweeps.items():
        try:
            empty = sw.empty_start_points(sweep, spec, points[sweep])
        except sw.SweepError as err:
            raise PlanError(f"config: {err}") from None
        if spec.get("warm_start"):
            src = resolve_ref(points, spec["warm_start"], f"sweep {sweep} warm_start")
            if src[0] != sweep and sweeps[src[0]].get("warm_start"):
                raise PlanError(f"config: sweep {sweep!r} warm-starts from sweep {src[0]!r}, which is "
                                "warm-started itself; start from a case that runs from an empty tube")
            for point in points[sweep]:
                if (sweep, point) != src and point not in empty:
                    sources[(sweep, point)] = src
        try:
            chained = sw.next_point_sources(sweep, spec, points[sweep])
        except sw.SweepError as err:
            raise PlanError(f"config: {err}") from None
        for point, source in chained.items():  # chains within a sweep; the last value ends each chain
            sources[(sweep, point)] = (sweep, source)
    return sources


def read_job_costs(path: str | None, root: str | Path | None = None) -> dict[str, float]:
    """The cost file of `scheduling.job_costs` (a job timing table: columns rule, job, cpu_s, and
    optionally case_cpu_s, as docs/reference/benchmarks/paper_run_timings.csv), a relative path
    taken from `root` (the workflow's folder; None: the working directory): "<sweep>/<point>" ->
    CPU seconds of its simulate job; {} without a cost file. A row's `case_cpu_s` (the case's CPU
    over every part of a run resumed from checkpoints) is used where it is known, its `cpu_s` (the
    job's last part only) where it is empty or NaN."""
    if path is None:
        return {}
    path = Path(root or ".") / path
    entry = f"config: scheduling.job_costs: {path}"
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            columns, rows = reader.fieldnames or [], list(reader)
    except OSError as err:
        raise PlanError(f"{entry}: cannot read it ({err.strerror or err})") from None
    except (UnicodeDecodeError, csv.Error) as err:
        raise PlanError(f"{entry}: not a CSV table ({err})") from None
    if missing := [c for c in ("rule", "job", "cpu_s") if c not in columns]:
        raise PlanError(f"{entry}: no column {', '.join(missing)} (a job timing table with columns "
                        "rule, job, cpu_s, e.g. docs/reference/benchmarks/paper_run_timings.csv)")
    costs = {}
    for row in rows:
        if row["rule"] != "simulate" or row["job"] == "(total)":
            continue
        # timings.py writes an unknown case_cpu_s as an empty field (pandas: NaN)
        given = (row.get("case_cpu_s") or "").strip().lower() not in ("", "nan")
        column = "case_cpu_s" if given else "cpu_s"
        try:
            costs[row["job"]] = float(row[column])
        except (TypeError, ValueError):
            raise PlanError(f"{entry}: job {row['job']}: {column} {row[column]!r} is not a "
                            "number") from None
    return costs


def explicit_overrides(config: Mapping, sweep: str, point: str, point_values: Mapping) -> dict[str, Any]:
    """The overrides a config sets for a case, without the derived keys it leaves to the plan."""
    spec = config["sweeps"][sweep]
    overrides = sw.case_overrides(config, sweep, point, set())
    for key in DERIVED:
        if key not in (spec.get("overrides") or {}) and key not in (
                config.get("all_cases") or {}) and key not in point_values:
            overrides.pop(key, None)
    return overrides


def identical_groups(config: Mapping, points: Mapping, warm: Mapping, build) -> list[list[Key]]:
    """Points that are one case: the same base, the same start and the same resolved keys (the
    derived ones only where a config sets them). `build(sweep, point, overrides)` -> Case."""
    groups = defaultdict(list)
    for sweep, members in points.items():
        for point in members:
            explicit = explicit_overrides(config, sweep, point, members[point])
            case = build(sweep, point, explicit)
            identity = (config["sweeps"][sweep]["base"], warm.get((sweep, point)), tuple(sorted(
                (k, repr(v)) for k, v in case.items() if k not in DERIVED or k in explicit)))
            groups[identity].append((sweep, point))
    return list(groups.values())


class Plan:
    """Everything the rules need to know about the cases, figures and statements of a config."""

    def __init__(self, config: Mapping, statements: list[dict] | None = None,
                 statements_source: str = "validation.statements", root: str | Path | None = None):
        self.config = config
        self.sweeps = dict(config.get("sweeps") or {})
        self.points = expand_sweeps(self.sweeps)
        self.figures = dict(config.get("figures") or {})
        for fig, spec in self.figures.items():
            check_figure(fig, spec)
            figure_sweeps(self.points, fig, spec)
        self.experiment_csv = (config.get("validation") or {}).get("experiment")
        self.partial = bool((config.get("validation") or {}).get("partial", False))
        self.statements = statement_cases(statements or [], self.points, statements_source)
        self.needs = consumer_needs(self.points, self.figures, self.statements)
        self._bases: dict[str, Case] = {}
        self._status: dict[Key, str | None] = {}  # partial validation: case_status, once per case
        self.warm_source = warm_sources(self.sweeps, self.points)
        self.overrides: dict[Key, dict] = {}  # every override of a case, derived ones included
        self.canonical: dict[Key, Key] = {}   # the case whose file a point reads
        self.cases: dict[Key, Case] = {}
        for members in identical_groups(config, self.points, self.warm_source, self.build):
            self._merge(members)
        self.work_precision = dict((config.get("benchmarks") or {}).get("work_precision") or {})
        self._check_work_precision()
        self.identification = dict(config.get("identification") or {})
        self._check_identification(statements_source)
        self._scheduling(root)

    # -- cases --

    def base_case(self, path: str) -> Case:
        if path not in self._bases:
            try:
                self._bases[path] = Case.from_yaml(path)
            except CaseError as err:
                raise PlanError(f"config: base case {path}: {err}") from None
        return self._bases[path]

    def build(self, sweep: str, point: str, overrides: Mapping) -> Case:
        """The sweep's base case with `overrides` (PlanError naming the sweep and point)."""
        try:
            return self.base_case(self.sweeps[sweep]["base"]).with_overrides(list(overrides.items()))
        except CaseError as err:
            raise PlanError(f"config: sweep {sweep!r}, point {point!r}: {err}") from None

    def _merge(self, members: list[Key]) -> None:
        """One case for identical points, recording what any of them needs, under the name of a
        single-case sweep where one is among them."""
        needs = set().union(*(self.needs[m] for m in members))
        first = min(members, key=lambda m: len(self.points[m[0]]) > 1)
        for member in members:
            self.overrides[member] = sw.case_overrides(self.config, *member, needs)
            self.canonical[member] = first
        resolved = self.build(*first, self.overrides[first])
        for member in members:
            self.cases[member] = resolved

    def all_points(self) -> list[Key]:
        return [(s, p) for s in self.points for p in self.points[s]]

    def key(self, sweep: str, point: str) -> Key:
        """(sweep, point) of a job's wildcards; ValueError if it is no point of the config."""
        if (sweep, point) not in self.canonical:
            raise ValueError(f"no case {(sweep, point)}: not a point of the configured sweeps")
        return (sweep, point)

    def case_nc(self, sweep: str, point: str) -> str:
        """The case file a point reads (that of the identical case run once)."""
        return case_file(*self.canonical[(sweep, point)])

    def simulate_inputs(self, sweep: str, point: str) -> dict[str, str]:
        """Base case YAML, and the case file a warm-started case begins from."""
        key = self.key(sweep, point)
        inputs = {"base": self.sweeps[sweep]["base"]}
        if key in self.warm_source:
            inputs["initial_state"] = self.case_nc(*self.warm_source[key])
        return inputs

    def model_minutes(self, sweep: str, point: str) -> float:
        """The cost model of a simulate job: about 1 min of one core per simulated second for 3000
        grains, scaled with tube length and mass flow (an upper bound: a case that stops when
        steady runs shorter)."""
        case = self.cases[self.key(sweep, point)]
        grains = max(1.0, case["feed.mass_flow_kg_h"] / 2.49) * case["tube.length"] / 0.525
        return case["run.duration"] * grains

    def runtime_minutes(self, sweep: str, point: str, attempt: int = 1) -> int:
        """Rough wall-time request for a simulate job (SLURM --time): 10 min plus the cost model
        times 2 for safety, times the attempt (more on each retry)."""
        return int(10 + 2 * attempt * self.model_minutes(sweep, point))

    def expected_cpu_seconds(self, sweep: str, point: str) -> float:
        """CPU seconds a simulate job is expected to take: its `cpu_s` in the cost file
        (`scheduling.job_costs`) when that lists the case (under the name of the case run once for
        identical points), else the cost model (model_minutes)."""
        canonical = self.canonical[self.key(sweep, point)]
        cost = self.job_costs.get("{}/{}".format(*canonical))
        return cost if cost is not None else 60.0 * self.model_minutes(*canonical)

    def priority(self, sweep: str, point: str) -> int:
        """Scheduling priority of a simulate job: the length of its critical path in CPU seconds,
        its expected cost plus the largest priority of the cases warm-started from it. Snakemake
        starts the ready jobs of the highest priority first (list scheduling by level), so the
        longest chains do not end the run on one core."""
        canonical = self.canonical[self.key(sweep, point)]
        if canonical not in self._priority:
            after = max((self.priority(*case) for case in self._warm_started[canonical]), default=0)
            self._priority[canonical] = round(self.expected_cpu_seconds(*canonical)) + after
        return self._priority[canonical]

    def _scheduling(self, root: str | Path | None) -> None:
        """The cost file's simulate costs (job -> cpu_s; a relative path from `root`) and, per case
        run, the cases run once that start from its final grains."""
        self._priority: dict[Key, int] = {}
        self._warm_started: dict[Key, set[Key]] = defaultdict(set)
        for key, source in self.warm_source.items():
            if self.canonical[key] != self.canonical[source]:
                self._warm_started[self.canonical[source]].add(self.canonical[key])
        path = (self.config.get("scheduling") or {}).get("job_costs")
        self.job_costs = read_job_costs(path, root)

    def curve_sweeps(self) -> list[str]:
        """Sweeps with parameters: each has a curve table and plot."""
        return [s for s in self.points if self.sweeps[s].get("parameters")]

    def sweep_parameter_keys(self, sweep: str, tied: bool = True) -> list[str]:
        """Case keys a sweep varies: its parameters, then (tied=True) the keys moving with them."""
        spec = self.sweeps[sweep]
        keys = list(spec.get("parameters") or {})
        if tied:
            for values in (spec.get("parameters") or {}).values():
                for value in values:
                    if isinstance(value, dict):
                        keys += [k for k in value if k not in keys]
            keys += [k for k in (spec.get("same_as") or {}) if k not in keys]
        return keys

    # -- files of the paths module, so that rules and figure kinds reach them through the plan --

    slugs_csv = staticmethod(slugs_csv)
    summary_json = staticmethod(summary_json)
    statistics_csv = staticmethod(statistics_csv)
    profile_nc = staticmethod(profile_nc)
    selection_csv = staticmethod(selection_csv)
    snapshot_nc = staticmethod(snapshot_nc)
    curve_csv = staticmethod(curve_csv)
    figure_files = staticmethod(figure_files)

    # -- figures --

    def figure_cases(self, fig: str) -> list[Key]:
        return figure_cases(self.points, fig, self.figures[fig])

    def figure_sweeps(self, fig: str) -> list[str]:
        return figure_sweeps(self.points, fig, self.figures[fig])

    def figure_inputs(self, fig: str) -> dict[str, Any]:
        """Named inputs of a figure: those of its kind (figure_kinds.py), and the validation table when statements name the figure (their verdicts go
        in its caption)."""
        if fig not in self.figures:
            raise ValueError(f"figure {fig} is not in config `figures`")
        spec = self.figures[fig]
        inputs = KINDS[spec["kind"]].inputs(self, spec, self.figure_cases(fig), self.figure_sweeps(fig))
        if any(fig in figures_of(st) for st in self.statements):
            inputs["validation"] = VALIDATION_CSV
        return inputs

    # -- validation statements --

    def statement_sources(self, st: Mapping) -> list[Key]:
        """The cases a statement's files derive from: its cases, or every point of its sweep."""
        if st.get("sweep"):
            return [(st["sweep"], p) for p in self.points[st["sweep"]]]
        return [c for c in st["_cases"] if c is not None]

    def statement_files(self, st: Mapping) -> dict[str, Any]:
        """Files a statement's measure reads, by name; {} when its cases are not in this config, or
        in a partial validation when they are not produced by this configuration yet."""
        if not in_config(st):
            return {}
        files = measure_files(st["measure"], st["_cases"], st.get("sweep"))
        if self.partial and self.not_current(flat(files), self.statement_sources(st)):
            return {}
        return files

    def recorded_case(self, key: Key) -> dict | None:
        """The case the case file of `key` records ({section: {name: value}}), None when there is
        no complete case file."""
        path = self.case_nc(*key)
        if not Path(path).is_file():
            return None
        try:
            import netCDF4
            with netCDF4.Dataset(path) as ds:
                return yaml.safe_load(ds.getncattr("config_yaml"))
        except Exception:  # noqa: BLE001 - unreadable or no attribute: not a complete case file
            return None

    def case_differences(self, key: Key) -> list[str]:
        """'key = value there, value here' for each key where the case file of `key` differs from
        the planned case ([] when it is the planned case or there is no case file). A key the file
        does not record (added to the engine after it ran) counts at its default, as for `plugsim
        run` (engine.run.finished_case)."""
        recorded = self.recorded_case(key)
        if recorded is None:
            return []
        there = {name: k.default for name, k in KEYS.items()}
        there.update({f"{s}.{k}": v for s, values in recorded.items() for k, v in values.items()})
        here = {k: v for k, v in self.cases[key].items()}
        # the physical keys first: they tell a reduced run from the paper's
        order = sorted(set(there) | set(here), key=lambda k: (k.startswith(("output.", "run.")), k))
        return [f"{k} = {there.get(k, '(absent)')} there, {here.get(k, '(absent)')} here"
                for k in order if there.get(k) != here.get(k)]

    def case_status(self, key: Key) -> str | None:
        """None when the case file of `key` exists and was run with the planned case, else why not."""
        if key not in self._status:
            path = self.case_nc(*key)
            if not Path(path).is_file():
                self._status[key] = f"{path} is not produced"
            elif self.recorded_case(key) is None:
                self._status[key] = f"{path} is not a complete case file"
            elif self.case_differences(key):
                self._status[key] = f"{path} was run with other parameters"
            else:
                self._status[key] = None
        return self._status[key]

    def other_configuration(self) -> str | None:
        """One line when a case file in results/ was run with other parameters than this
        configuration plans (the results are another configuration's), else None."""
        for key in sorted(set(self.canonical.values())):
            if differences := self.case_differences(key):
                more = f" and {len(differences) - 2} more" if len(differences) > 2 else ""
                return (f"{self.case_nc(*key)} was run with other parameters than this configuration "
                        f"plans ({'; '.join(differences[:2])}{more})")
        return None

    def not_current(self, files: list[str], sources: list[Key]) -> str | None:
        """Why `files` (derived from the cases `sources`) are not this configuration's products yet:
        a file is missing, a case file is missing or from other parameters, or a file is older than
        a case file it derives from (a product of one case its own case's, any other every source's).
        None when they are current."""
        for key in sources:
            if why := self.case_status(key):
                return why
        for f in files:
            if not Path(f).is_file():
                return f"{f} is not produced"
        for f in files:
            if f.endswith(".nc") and f.startswith("results/cases/"):
                continue
            own = [k for k in sources if derives_from_one_case(f, *k)]
            newest_case = max((Path(self.case_nc(*k)).stat().st_mtime for k in own or sources), default=0.0)
            if Path(f).stat().st_mtime < newest_case:
                return f"{f} is older than its case file"
        return None

    def partial_files(self, files: list[str], sources: list[Key]) -> list[str]:
        """In a partial validation, `files` when current (not_current), else none."""
        return [] if self.not_current(files, sources) else files

    def reference_files(self) -> dict[str, list[str]]:
        """The figure PNGs and captions and the curves `rule reference` copies; in a partial
        validation only those current."""
        figures, curves = [], []
        for fig in self.figures:
            files = [f for f in figure_files(fig) if not f.endswith(".pdf")]
            sources = self.figure_cases(fig) + [(s, p) for s in self.figure_sweeps(fig)
                                                for p in self.points[s]]
            figures += self.partial_files(files, sources) if self.partial else files
        for s in self.curve_sweeps():
            if not s.startswith("wp_"):
                files = [curve_csv(s), curve_png(s)]
                sources = [(s, p) for p in self.points[s]]
                curves += self.partial_files(files, sources) if self.partial else files
        return {"figures": figures, "curves": curves}

    def validation_inputs(self) -> list[str]:
        """The files the validation reads, as job inputs: none in a partial validation (it reads
        what exists and never makes Snakemake produce or update anything)."""
        if self.partial:
            return []
        return sorted({f for st in self.statements for f in flat(self.statement_files(st))})

    def validation_statements(self) -> list[dict]:
        """Statements with the files to read (resolved here, so the script needs no path rules)."""
        out = []
        for st in self.statements:
            item = {k: v for k, v in st.items() if not k.startswith("_")}
            item["files"] = self.statement_files(st)
            # partial validation: declared here but not produced by this configuration yet
            item["pending"] = False
            if self.partial and in_config(st) and not item["files"]:
                item["pending"] = self.not_current(
                    flat(measure_files(st["measure"], st["_cases"], st.get("sweep"))),
                    self.statement_sources(st)) or True
            item["case_names"] = ["{}/{}".format(*c) if c else None for c in st["_cases"]]
            out.append(item)
        return out

    def partial_fingerprint(self) -> dict[str, int]:
        """Partial validation: every file it reads with its modification time (ns), a parameter of
        the validation job so that it reruns when a file appears or changes; {} otherwise."""
        if not self.partial:
            return {}
        files = {f for st in self.statements for f in flat(self.statement_files(st))}
        files |= {f for group in self.reference_files().values() for f in group}
        return {f: Path(f).stat().st_mtime_ns for f in sorted(files)}

    # -- model identification --

    def _check_identification(self, statements_source: str) -> None:
        """Every comparison names a declared sweep and a known training statement (a reading is
        never chosen on a test statement)."""
        roles = {st["id"]: st.get("role", "test") for st in self.statements}
        ids = set(roles)
        for item in self.identification.get("compare") or []:
            if item["sweep"] not in self.points:
                raise PlanError(f"config: identification compares statement {item['statement']} on "
                                f"sweep {item['sweep']!r}, which is not declared")
            if item["statement"] not in ids:
                raise PlanError(f"config: identification names statement {item['statement']!r}, "
                                f"which is not in {statements_source}")
            if roles[item["statement"]] != "training":
                raise PlanError(f"config: identification compares statement {item['statement']!r}, "
                                f"a test statement; only statements with role: training in "
                                f"{statements_source} may choose a reading")

    def identification_baselines(self) -> dict[str, dict]:
        """Each one_at_a_time identification sweep's baseline: its reading keys at their first
        values (the reading every other one is compared with)."""
        readings = self.identification.get("readings") or []
        out = {}
        for sweep in {item["sweep"] for item in self.identification.get("compare") or []}:
            spec = self.sweeps[sweep]
            if spec.get("design", "full") != "one_at_a_time":
                continue
            first: dict = {}
            for name, values in (spec.get("parameters") or {}).items():
                level = values[0]
                first.update(level if isinstance(level, dict) else {name: level})
            out[sweep] = {key: first[key] for key in readings if key in first}
        return out

    def identification_tables(self) -> list[str]:
        """The curve tables of the sweeps the identification compares."""
        return sorted({curve_csv(item["sweep"]) for item in self.identification.get("compare") or []})

    # -- work-precision study --

    def _check_work_precision(self) -> None:
        """Each study sweep varies one knob with its reference among the points; at most one seed
        study per regime."""
        seed_studies = defaultdict(list)
        for sweep, spec in self.work_precision.items():
            if sweep not in self.points:
                raise PlanError(f"config: benchmarks.work_precision names sweep {sweep!r}, which is "
                                "not declared")
            knobs = self.sweep_parameter_keys(sweep, tied=False)
            if len(knobs) != 1:
                raise PlanError(f"config: benchmarks.work_precision: sweep {sweep!r} must vary "
                                "exactly one parameter")
            try:
                sw.find_point(sweep, self.points[sweep], {knobs[0]: spec["reference"]})
            except sw.SweepError as err:
                raise PlanError(f"config: benchmarks.work_precision.{sweep}.reference: {err}") from None
            if knobs[0] == "run.seed":
                seed_studies[spec.get("regime", "")].append(sweep)
        for regime, studies in seed_studies.items():
            if len(studies) > 1:
                raise PlanError(f"config: benchmarks.work_precision: sweeps {', '.join(studies)} are "
                                f"all seed studies of regime {regime!r}; give each regime one (key "
                                "`regime`)")

    def knob_default(self, sweep: str) -> Any:
        """The value a sweep's knob takes without the sweep: base case + the sweep's fixed overrides."""
        key = self.sweep_parameter_keys(sweep, tied=False)[0]
        overrides = {**(self.sweeps[sweep].get("overrides") or {}), **(self.config.get("all_cases") or {})}
        return self.build(sweep, "(without the parameter)", overrides)[key]

    def work_precision_studies(self) -> dict[str, dict]:
        """Per study sweep: its knob, reference, default, regime and summaries."""
        return {s: {"parameter": self.sweep_parameter_keys(s, tied=False)[0],
                    "reference": self.work_precision[s]["reference"],
                    "default": self.knob_default(s),
                    "regime": self.work_precision[s].get("regime", ""),
                    "summaries": [summary_json(s, p) for p in self.points[s]]}
                for s in self.work_precision}


def figures_of(st: Mapping) -> list[str]:
    """Figures that show a statement's quantity (its `figure`: a name or a list)."""
    figs = st.get("figure") or []
    return [figs] if isinstance(figs, str) else list(figs)


def in_config(st: Mapping) -> bool:
    """The statement's cases and sweep are declared in this configuration."""
    return not st.get("_missing") and all(c is not None for c in st["_cases"])


def flat(files: Mapping) -> list[str]:
    """The paths of a statement_files dict (values are paths or lists of paths)."""
    return [f for v in files.values() for f in (v if isinstance(v, list) else [v])]


def measure_files(measure: str, cases: list[Key], sweep: str | None) -> dict[str, Any]:
    """Files a validation measure reads from its cases or its sweep's curve."""
    if measure in ("pressure_drop", "n_particles", "regime", "ratio"):
        return {"summaries": [summary_json(*c) for c in cases]}
    if measure in ("slug_stat", "slug_rate"):
        return {"slugs": slugs_csv(*cases[0]), "summary": summary_json(*cases[0])}
    if measure in ("profile_min", "profile_max"):
        return {"profile": profile_nc(*cases[0])}
    if measure == "selection_mean":
        return {"selection": selection_csv(*cases[0])}
    if measure == "radial_outer_minimum":
        return {"radial": snapshot_nc(*cases[0], "radial")}
    if measure in ("transition", "argmax", "trend", "monotonic", "fit_deviation"):
        return {"curve": curve_csv(sweep)}
    return {}

# Shared helpers of the rules: sweep expansion, what each case must record, file names.
# Everything here runs when the workflow is parsed (also for `snakemake -n`), so a typo in a case
# key or a sweep reference fails before any job starts.

import sys
from collections import defaultdict
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(workflow.basedir) / "workflow" / "scripts"))
import sweeps as sw  # noqa: E402  (workflow/scripts/sweeps.py)

from engine.case import Case, CaseError  # noqa: E402


wildcard_constraints:
    sweep=r"[A-Za-z0-9_-]+",
    point=r"[^/]+",
    fig=r"[A-Z]\d\d",


# ---- sweeps -> points -------------------------------------------------------------------------

SWEEPS = {name: spec for name, spec in (config.get("sweeps") or {}).items()}
POINTS = {}  # sweep -> {point name -> point overrides}
for _name, _spec in SWEEPS.items():
    try:
        POINTS[_name] = sw.expand(_name, _spec)
    except sw.SweepError as err:
        raise ValueError(f"config: {err}") from None


def resolve_ref(ref, what, required=True):
    """(sweep, point) of a case reference {sweep, point: {key: value}}; None if optional and absent."""
    sweep = ref.get("sweep")
    if sweep not in POINTS:
        if not required:
            return None
        raise ValueError(f"config: {what} refers to sweep {sweep!r}, which is not declared "
                         f"(sweeps: {sorted(POINTS)})")
    try:
        point = sw.find_point(sweep, POINTS[sweep], ref.get("point"), required=required)
    except sw.SweepError as err:
        raise ValueError(f"config: {what}: {err}") from None
    return None if point is None else (sweep, point)


# ---- consumers: what each case must record ----------------------------------------------------

FIGURES = dict(config.get("figures") or {})
NEEDS = defaultdict(set)  # (sweep, point) -> {"steady", "series", "snapshots"}
for _sweep, _points in POINTS.items():  # every point feeds its sweep's curve (or summary)
    for _point in _points:
        NEEDS[(_sweep, _point)].add("steady")


def figure_cases(fig):
    """(sweep, point) of every single case a figure draws (not the curves)."""
    spec = FIGURES[fig]
    refs = []
    if "case" in spec:
        refs += sw.references(spec["case"])
    if "cases" in spec:
        refs += sw.references(spec["cases"])
    return [resolve_ref(ref, f"figure {fig}") for ref in refs]


def figure_sweeps(fig):
    spec = FIGURES[fig]
    names = ([spec["sweep"]] if "sweep" in spec else []) + list(spec.get("sweeps") or [])
    for name in names:
        if name not in POINTS:
            raise ValueError(f"config: figure {fig} draws sweep {name!r}, which is not declared")
    return names


for _fig, _spec in FIGURES.items():
    if _spec["kind"] not in sw.KIND_NEEDS:
        raise ValueError(f"config: figure {_fig}: unknown kind {_spec['kind']!r} "
                         f"(known: {sorted(sw.KIND_NEEDS)})")
    for _key in figure_cases(_fig):
        NEEDS[_key] |= sw.KIND_NEEDS[_spec["kind"]]
    figure_sweeps(_fig)

# validation statements (resources/paper_statements.yaml): cases they measure are consumers too
MEASURE_NEEDS = {
    "pressure_drop": {"steady"}, "n_particles": {"steady"}, "regime": {"steady"},
    "ratio": {"steady"}, "transition": {"steady"}, "argmax": {"steady"}, "trend": {"steady"},
    "monotonic": {"steady"}, "fit_deviation": {"steady"},
    "slug_stat": {"series"}, "slug_rate": {"series"}, "profile_min": {"series"},
    "profile_max": {"series"}, "selection_mean": {"series"},
    "radial_outer_minimum": {"series", "snapshots"},
}
STATEMENTS = []
PARTIAL = bool(config.get("validation", {}).get("partial", False))  # config/partial.yaml
if config.get("validation", {}).get("statements"):
    STATEMENTS = yaml.safe_load(Path(config["validation"]["statements"]).read_text()) or []
for _st in STATEMENTS:
    if _st["measure"] not in MEASURE_NEEDS:
        raise ValueError(f"{config['validation']['statements']}: statement {_st.get('id')}: "
                         f"unknown measure {_st['measure']!r} (known: {sorted(MEASURE_NEEDS)})")
    _st["_cases"] = [resolve_ref(r, f"statement {_st['id']}", required=False)
                     for r in sw.references(_st.get("case") or _st.get("cases") or [])]
    if _st.get("sweep") and _st["sweep"] not in POINTS:
        _st["_missing"] = True
    for _key in _st["_cases"]:
        if _key is not None:
            NEEDS[_key] |= MEASURE_NEEDS[_st["measure"]]


# ---- one engine.Case per point; identical cases run once ----------------------------------------

_BASES = {}


def _base_case(path):
    if path not in _BASES:
        try:
            _BASES[path] = Case.from_yaml(path)
        except CaseError as err:
            raise ValueError(f"config: base case {path}: {err}") from None
    return _BASES[path]


def _build(sweep, point, overrides):
    try:
        return _base_case(SWEEPS[sweep]["base"]).with_overrides(list(overrides.items()))
    except CaseError as err:
        raise ValueError(f"config: sweep {sweep!r}, point {point!r}: {err}") from None


# warm starts: a sweep's `warm_start` names the case whose final grains start its points (the
# point that is that case itself runs from an empty tube); `warm_start_from_next` starts some points
# from their neighbour in the same sweep instead
WARM_SOURCE = {}  # (sweep, point) -> (sweep, point) of the case file it starts from
for _sweep, _spec in SWEEPS.items():
    if _spec.get("warm_start"):
        _src = resolve_ref(_spec["warm_start"], f"sweep {_sweep} warm_start")
        if SWEEPS[_src[0]].get("warm_start"):
            raise ValueError(f"config: sweep {_sweep!r} warm-starts from sweep {_src[0]!r}, which is "
                             "warm-started itself; start from a case that runs from an empty tube")
        for _point in POINTS[_sweep]:
            if (_sweep, _point) != _src:
                WARM_SOURCE[(_sweep, _point)] = _src
    try:
        _next = sw.next_point_sources(_sweep, _spec, POINTS[_sweep])
    except sw.SweepError as err:
        raise ValueError(f"config: {err}") from None
    for _point, _source in _next.items():  # chains within a sweep; the last value ends each chain
        WARM_SOURCE[(_sweep, _point)] = (_sweep, _source)

DERIVED = ("output.snapshots", "run.until_steady")
_groups = defaultdict(list)  # identity of the case (without derived keys) -> [(sweep, point)]
for _sweep, _points in POINTS.items():
    for _point in _points:
        _explicit = sw.case_overrides(config, _sweep, _point, set())
        for _k in DERIVED:  # derived keys count only when a sweep sets them explicitly
            if _k not in (SWEEPS[_sweep].get("overrides") or {}) and _k not in (
                    config.get("all_cases") or {}) and _k not in _points[_point]:
                _explicit.pop(_k, None)
        _case = _build(_sweep, _point, _explicit)
        _identity = (SWEEPS[_sweep]["base"], WARM_SOURCE.get((_sweep, _point)), tuple(sorted(
            (k, repr(v)) for k, v in _case.items() if k not in DERIVED or k in _explicit)))
        _groups[_identity].append((_sweep, _point))

OVERRIDES = {}  # (sweep, point) -> every override of its case, derived ones included
CANONICAL = {}  # (sweep, point) -> (sweep, point) of the case file it reads
CASES = {}      # (sweep, point) -> engine.Case (validated)
for _members in _groups.values():
    _needs = set().union(*(NEEDS[m] for m in _members))
    _first = min(_members, key=lambda m: len(POINTS[m[0]]) > 1)  # prefer a single-case sweep's name
    for _member in _members:
        OVERRIDES[_member] = sw.case_overrides(config, *_member, _needs)
        CANONICAL[_member] = _first
    _resolved = _build(*_first, OVERRIDES[_first])
    for _member in _members:
        CASES[_member] = _resolved


def all_points():
    return [(s, p) for s in POINTS for p in POINTS[s]]


# ---- file names -------------------------------------------------------------------------------

def case_nc(sweep, point):
    s, p = CANONICAL[(sweep, point)]
    return f"results/cases/{s}/{p}.nc"


def simulate_inputs(wildcards):
    """Base case YAML, and the case file a warm-started case begins from."""
    key = wc_key(wildcards)
    inputs = {"base": SWEEPS[key[0]]["base"]}
    if key in WARM_SOURCE:
        inputs["initial_state"] = case_nc(*WARM_SOURCE[key])
    return inputs


def slugs_csv(s, p):
    return f"results/slugs/{s}/{p}.csv"


def summary_json(s, p):
    return f"results/summaries/{s}/{p}.json"


def statistics_csv(s, p):
    return f"results/statistics/{s}/{p}.csv"


def profile_nc(s, p):
    return f"results/profiles/{s}/{p}.nc"


def selection_csv(s, p):
    return f"results/profiles/{s}/{p}.selection.csv"


def snapshot_file(s, p, what):
    return f"results/snapshots/{s}/{p}/{what}.nc"


def curve_csv(s):
    return f"results/curves/{s}.csv"


def figure_files(fig):
    return [f"results/figures/{fig}.{ext}" for ext in ("png", "pdf", "txt")]


def wc_key(wildcards):
    key = (wildcards.sweep, wildcards.point)
    if key not in CANONICAL:
        raise ValueError(f"no case {key}: not a point of the configured sweeps")
    return key


# ---- captions and run-time estimates ------------------------------------------------------------

def start_text(key):
    """How the case (sweep, point) starts: from an empty tube or from another case's final grains."""
    src = WARM_SOURCE.get(CANONICAL.get(key, key)) or WARM_SOURCE.get(key)
    return f"from the final grains of case {src[0]}/{src[1]}" if src else "from an empty tube"


def case_text(case, key=None):
    """The parameters of a case in the papers' units, for figure captions; `key` (sweep, point)
    says how it starts."""
    orient = {0.0: "horizontal", 90.0: "vertical"}.get(float(case["tube.inclination_deg"]),
                                                        f"inclined {case['tube.inclination_deg']:g} deg")
    parts = [f"{orient} tube L = {case['tube.length'] * 100:g} cm, D = {case['tube.diameter'] * 1e3:g} mm",
             f"grains d = {case['particles.diameter'] * 1e3:g} mm, rho_s = {case['particles.density']:g} kg/m3",
             f"mu = {case['particles.friction']:g} (wall {case['wall.friction']:g})",
             f"e = {case['particles.restitution']:g} (wall {case['wall.restitution']:g})",
             f"feed {case['feed.mass_flow_kg_h']:g} kg/h at {case['feed.entry_velocity']:g} m/s"]
    if case["gas.enabled"]:
        parts.append(f"v_s = {case['gas.superficial_velocity']:g} m/s, eta = {case['gas.viscosity'] * 1e3:g} cP, "
                     f"P0 = {case['gas.pressure'] / 100:g} hPa, gas grid {case['gas.nodes_x']}x"
                     f"{case['gas.nodes_y']}x{case['gas.nodes_z']}")
    else:
        parts.append("gas off")
    parts.append(("until steady, at most " if case["run.until_steady"] else "run ")
                 + f"{case['run.duration']:g} s" + (f" {start_text(key)}" if key else ""))
    return "; ".join(parts)


def sweep_text(sweep):
    """Base case, fixed overrides and swept values of a sweep, for captions."""
    spec = SWEEPS[sweep]
    first = CASES[(sweep, next(iter(POINTS[sweep])))]
    swept = "; ".join(f"{k} in {[v if not isinstance(v, dict) else v[k] for v in vals]}"
                      for k, vals in (spec.get("parameters") or {}).items())
    tied = "; ".join(f"{k} = {v}" for k, v in (spec.get("same_as") or {}).items())
    text = f"sweep {sweep} ({len(POINTS[sweep])} cases): {swept or 'single case'}"
    if tied:
        text += f" ({tied})"
    warm = [p for p in POINTS[sweep] if (sweep, p) in WARM_SOURCE]
    if not warm:
        starts = "every case starts from an empty tube"
    elif len(warm) == len(POINTS[sweep]):
        starts = "every case starts from the final grains of another case (named per point below)"
    else:
        starts = (f"{len(warm)} of {len(POINTS[sweep])} cases start from the final grains of another "
                  f"case ({', '.join(warm)}), the others from an empty tube")
    return text + f". Other parameters as in the first case: {case_text(first)}; {starts}"


def runtime_minutes(wildcards, attempt=1):
    """Rough wall-time request for a simulate job (SLURM --time): about 1 min per simulated second
    for 3000 grains on one core, scaled with tube length and mass flow, times 2 for safety."""
    case = CASES[wc_key(wildcards)]
    grains = max(1.0, case["feed.mass_flow_kg_h"] / 2.49) * case["tube.length"] / 0.525
    return int(10 + 2 * attempt * case["run.duration"] * grains)


import engine as _engine  # noqa: E402

# Case files record the engine version; it is a parameter of `simulate`, so bumping it reruns cases.
ENGINE_VERSION = _engine.__version__


def sweep_parameter_keys(sweep, tied=True):
    """Case keys a sweep varies: its parameters, then (tied=True) the keys moving with them."""
    spec = SWEEPS[sweep]
    keys = list(spec.get("parameters") or {})
    if tied:
        for values in (spec.get("parameters") or {}).values():
            for value in values:
                if isinstance(value, dict):
                    keys += [k for k in value if k not in keys]
        keys += [k for k in (spec.get("same_as") or {}) if k not in keys]
    return keys


# ---- inputs of the figure rule (figures.smk) ---------------------------------------------------

def figure_inputs(wildcards):
    """Named inputs of a figure, by its kind (config figures.<fig>.kind)."""
    fig = wildcards.fig
    if fig not in FIGURES:
        raise ValueError(f"figure {fig} is not in config `figures`")
    spec = FIGURES[fig]
    kind = spec["kind"]
    cases = figure_cases(fig)
    sweeps = figure_sweeps(fig)
    inputs = {}
    if kind in ("porosity_image", "porosity_image_pair"):
        inputs["cases"] = [case_nc(*c) for c in cases]
    elif kind == "grains_3d":
        inputs["case"] = case_nc(*cases[0])
        inputs["slugs"] = slugs_csv(*cases[0])
        inputs["selection"] = selection_csv(*cases[0])
    elif kind in ("curve", "curve_pair"):
        inputs["tables"] = [curve_csv(s) for s in sweeps]
        if spec.get("experiment"):
            inputs["experiment"] = config["validation"]["experiment"]
    elif kind in ("slug_rate", "slug_statistic"):
        inputs["statistics"] = statistics_csv(*cases[0])
    elif kind == "profile":
        inputs["profile"] = profile_nc(*cases[0])
    elif kind in ("cross_sections", "velocity_height_image", "velocity_height"):
        what = "cross_sections" if kind == "cross_sections" else "velocity_height"
        inputs["snapshots"] = snapshot_file(*cases[0], what)
    elif kind == "radial":
        inputs["radial"] = snapshot_file(*cases[0], "radial")
    if any(fig in _figures_of(st) for st in STATEMENTS):
        inputs["validation"] = "results/validation/validation.csv"  # its statements go in the caption
    return inputs


def _figures_of(st):
    """Figures that show a statement's quantity (its `figure`: a name or a list)."""
    figs = st.get("figure") or []
    return [figs] if isinstance(figs, str) else list(figs)


def figure_caption(wildcards):
    """Caption text: the figure's title, then the parameters of the case(s) or sweep(s) drawn."""
    spec = FIGURES[wildcards.fig]
    lines = [f"{wildcards.fig}: {spec.get('title', spec['kind'])}."]
    for s, p in figure_cases(wildcards.fig):
        lines.append(f"Case {s}/{p}: {case_text(CASES[(s, p)], (s, p))}.")
    for s in figure_sweeps(wildcards.fig):
        lines.append(f"Curve {sweep_text(s)}.")
    return "\n".join(lines)


def figure_category(wildcards):
    return {"H": "Horizontal tube (H)", "V": "Vertical tube (V)"}.get(wildcards.fig[0], "Other figures")


# ---- inputs of the validation rule (validation.smk) -------------------------------------------

def _in_config(st):
    """The statement's cases and sweep are declared in this configuration."""
    return not st.get("_missing") and all(c is not None for c in st["_cases"])


def _flat(files):
    """The paths of a statement_files dict (values are paths or lists of paths)."""
    return [f for v in files.values() for f in (v if isinstance(v, list) else [v])]


def statement_files(st):
    """Files a statement's measure reads, by name; {} when its cases are not in this config, or in
    a partial validation when they are not produced yet."""
    if not _in_config(st):
        return {}
    m = st["measure"]
    files = {}
    if m in ("pressure_drop", "n_particles", "regime", "ratio"):
        files["summaries"] = [summary_json(*c) for c in st["_cases"]]
    elif m in ("slug_stat", "slug_rate"):
        files["slugs"] = slugs_csv(*st["_cases"][0])
        files["summary"] = summary_json(*st["_cases"][0])
    elif m in ("profile_min", "profile_max"):
        files["profile"] = profile_nc(*st["_cases"][0])
    elif m == "selection_mean":
        files["selection"] = selection_csv(*st["_cases"][0])
    elif m == "radial_outer_minimum":
        files["radial"] = snapshot_file(*st["_cases"][0], "radial")
    elif m in ("transition", "argmax", "trend", "monotonic", "fit_deviation"):
        files["curve"] = curve_csv(st["sweep"])
    if PARTIAL and not all(Path(f).exists() for f in _flat(files)):
        return {}
    return files


def existing_if_partial(files):
    """All files, or in a partial validation only those already produced."""
    return [f for f in files if Path(f).exists()] if PARTIAL else files


def validation_inputs(wildcards):
    return sorted({f for st in STATEMENTS for f in _flat(statement_files(st))})


def validation_statements():
    """Statements with the files to read (resolved here, so the script needs no path rules)."""
    out = []
    for st in STATEMENTS:
        item = {k: v for k, v in st.items() if not k.startswith("_")}
        item["files"] = statement_files(st)
        # partial validation: declared here but not produced yet
        item["pending"] = PARTIAL and _in_config(st) and not item["files"]
        item["case_names"] = ["{}/{}".format(*c) if c else None for c in st["_cases"]]
        out.append(item)
    return out


# ---- work-precision study (benchmarks.smk) ------------------------------------------------------

WORK_PRECISION = dict((config.get("benchmarks") or {}).get("work_precision") or {})
_seed_studies = defaultdict(list)  # regime -> its seed studies (the noise floor: at most one)
for _s, _spec in WORK_PRECISION.items():
    if _s not in POINTS:
        raise ValueError(f"config: benchmarks.work_precision names sweep {_s!r}, which is not declared")
    if len(sweep_parameter_keys(_s, tied=False)) != 1:
        raise ValueError(f"config: benchmarks.work_precision: sweep {_s!r} must vary exactly one parameter")
    try:  # the reference must be one point of the sweep
        sw.find_point(_s, POINTS[_s], {sweep_parameter_keys(_s, tied=False)[0]: _spec["reference"]})
    except sw.SweepError as err:
        raise ValueError(f"config: benchmarks.work_precision.{_s}.reference: {err}") from None
    if sweep_parameter_keys(_s, tied=False)[0] == "run.seed":
        _seed_studies[_spec.get("regime", "")].append(_s)
for _regime, _studies in _seed_studies.items():
    if len(_studies) > 1:
        raise ValueError(f"config: benchmarks.work_precision: sweeps {', '.join(_studies)} are all seed "
                         f"studies of regime {_regime!r}; give each regime one (key `regime`)")


def knob_default(sweep):
    """The value a sweep's knob takes without the sweep: base case + the sweep's fixed overrides."""
    key = sweep_parameter_keys(sweep, tied=False)[0]
    overrides = {**(SWEEPS[sweep].get("overrides") or {}), **(config.get("all_cases") or {})}
    return _build(sweep, "(without the parameter)", overrides)[key]

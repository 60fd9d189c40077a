# The plan of the workflow (workflow/scripts/plan.py) and the glue between Snakemake's wildcards
# and it. The plan is built when the workflow is parsed (also for `snakemake -n`), so a typo in a
# case key or a sweep reference fails before any job starts.

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(workflow.basedir) / "workflow" / "scripts"))
import captions  # noqa: E402  (workflow/scripts/captions.py)
import plan as paths  # noqa: E402  (workflow/scripts/plan.py: the file names)
from config_check import ConfigError, load_yaml, refuse  # noqa: E402
from plan import Plan, PlanError  # noqa: E402


wildcard_constraints:
    sweep=r"[A-Za-z0-9_-]+",
    point=r"[^/]+",
    fig=r"[A-Z]\d\d",


_statements_path = (config.get("validation") or {}).get("statements")
try:
    # the cost file (scheduling.job_costs) is the repository's, next to the Snakefile, not the cwd's
    PLAN = Plan(config, load_yaml(_statements_path) if _statements_path else [], _statements_path,
                root=workflow.basedir)
except (PlanError, ConfigError) as err:
    refuse(err)  # one line, before any job

# `snakemake --report` labels and bundles what results/ holds with this configuration's banner and
# captions: refuse when the case files there are another configuration's (e.g. the CI run's
# without --configfile config/ci.yaml). Snakemake tells the Snakefile nothing of a report, hence argv.
if any(a == "--report" or a.startswith("--report=") for a in sys.argv) and "--report-after-run" not in sys.argv:
    if _other := PLAN.other_configuration():
        refuse(ConfigError(f"report: {_other}; give the --configfile(s) of the run that made them "
                           "(after a CI run: --configfile config/ci.yaml)"))

# The rerun key of the jobs that run the engine: any change to its source reruns them.
ENGINE_SOURCE = paths.source_digest(Path(workflow.basedir) / "engine")


def wc_key(wildcards):
    """(sweep, point) of a job; ValueError when it is no point of the configured sweeps."""
    return PLAN.key(wildcards.sweep, wildcards.point)


def case_nc_of(wildcards):
    return PLAN.case_nc(*wc_key(wildcards))


def simulate_inputs(wildcards):
    if PLAN.partial:  # a second guard: partial validation never asks for a case (validation.smk)
        raise ValueError("config validation.partial (config/partial.yaml) only tabulates what exists "
                         f"and runs no case; asked for results/cases/{wildcards.sweep}/"
                         f"{wildcards.point}.nc: name the targets `validation reference`")
    return PLAN.simulate_inputs(*wc_key(wildcards))


def runtime_minutes(wildcards, attempt=1):
    return PLAN.runtime_minutes(*wc_key(wildcards), attempt)


def analysis_position(wildcards):
    """Axial position (m) where a sweep's cases are analysed: the sweep's `position`, else
    analysis.position."""
    return PLAN.sweeps[wildcards.sweep].get("position", config["analysis"]["position"])


def simulate_priority(wildcards):
    """Longest critical path first (Plan.priority: CPU seconds of the case and its warm starts)."""
    return PLAN.priority(*wc_key(wildcards))


def figure_inputs(wildcards):
    return PLAN.figure_inputs(wildcards.fig)


def figure_caption(wildcards):
    return captions.figure_caption(PLAN, wildcards.fig)


def figure_category(wildcards):
    return captions.figure_category(wildcards.fig)


def calibration_summaries(wildcards):
    """Summaries of both rounds of a calibration: the first design's and the confirmation cases the
    first fit chose (checkpoint calibration_first)."""
    confirmation = checkpoints.calibration_first.get().output.confirmation
    return CAL.first_summaries() + CAL.confirmation_summaries(confirmation)


def calibration_fitted():
    """The calibration's fitted.json (checkpoint calibration), read when a prediction is planned."""
    with open(checkpoints.calibration.get().output.fitted) as f:
        return json.load(f)

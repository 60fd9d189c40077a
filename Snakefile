# plugsim workflow: reproduces every reproducible figure of Strauss, McNamara & Herrmann's horizontal
# (H) and vertical (V) plug-conveying papers, the validation table, and any sweep declared in config.
#
#   snakemake -j2                               # the papers (config/config.yaml)
#   snakemake -j2 --configfile config/ci.yaml   # the reduced CI run, laid over config.yaml
#   snakemake --report report.html              # HTML report of the figures, curves and validation
#
# Rules live in workflow/rules/ (one file per stage), thin scripts in workflow/scripts/; see
# docs/workflow.md.

import sys

from snakemake.utils import min_version, validate

min_version("9.0")
sys.path.insert(0, f"{workflow.basedir}/workflow/scripts")
from config_check import ConfigError, check_schema, load_yaml, refuse  # noqa: E402


# Snakemake's own loader names no line for a YAML syntax error: read the workflow's config first
try:
    load_yaml("config/config.yaml")
except ConfigError as err:
    refuse(err)


configfile: "config/config.yaml"


# one line naming the entry and the fix (jsonschema's own message is a dump of the schema);
# validate() then fills the schema's defaults
try:
    check_schema(config, f"{workflow.basedir}/workflow/schemas/config.schema.yaml")
except ConfigError as err:
    refuse(err)
validate(config, "workflow/schemas/config.schema.yaml")


report: "workflow/report/workflow.rst"


onstart:
    # SIGINT/SIGTERM to snakemake reach the running cases, which checkpoint and stop
    # (workflow/scripts/running.py); Snakemake alone would wait for them to finish
    import running

    running.forward_signals()


include: "workflow/rules/common.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/detect.smk"
include: "workflow/rules/profiles.smk"
include: "workflow/rules/curves.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/validation.smk"
include: "workflow/rules/benchmarks.smk"
include: "workflow/rules/identification.smk"
include: "workflow/rules/calibration.smk"


rule all:
    """Every figure, every sweep's curve, the validation table and the engine benchmark."""
    default_target: True
    input:
        [paths.figure_files(fig) for fig in PLAN.figures],
        [f for s in PLAN.curve_sweeps() for f in (paths.curve_csv(s), paths.curve_png(s))],
        [paths.summary_json(s, p) for s, p in PLAN.all_points()],
        paths.VALIDATION_CSV,
        "results/validation/validation.md",
        "results/benchmarks/engine.json",
        [f"results/benchmarks/work_precision.{e}" for e in ("csv", "png", "pdf") if PLAN.work_precision],
        [f"results/benchmarks/scale/scale.{e}" for e in ("csv", "md", "png")],
        [f"results/benchmarks/stability/stability.{e}" for e in ("csv", "md", "png")],
        [f"results/benchmarks/restitution/restitution.{e}" for e in ("csv", "md", "png")],
        [f"results/identification/identification.{e}" for e in ("csv", "md", "png")
         if PLAN.identification.get("compare")],


rule figures:
    """Only the paper figures."""
    input:
        [paths.figure_files(fig) for fig in PLAN.figures],


rule curves:
    """Only the sweep tables and their plots."""
    input:
        [f for s in PLAN.curve_sweeps() for f in (paths.curve_csv(s), paths.curve_png(s))],

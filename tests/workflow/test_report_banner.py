"""The HTML report's banner (workflow/report/workflow.rst) tells a reduced run from the paper run
by the configuration actually used, rendered as Snakemake renders it (jinja2, trim_blocks)."""

from pathlib import Path

import yaml
from jinja2 import Environment

ROOT = Path(__file__).resolve().parents[2]


def banner(config: dict) -> str:
    class Snakemake:
        pass

    Snakemake.config = config
    env = Environment(trim_blocks=True, lstrip_blocks=True)
    text = (ROOT / "workflow/report/workflow.rst").read_text()
    return env.from_string(text).render(snakemake=Snakemake, categories={}, files={})


def merged(*names: str) -> dict:
    """Config files laid over each other as Snakemake does (mappings merge key by key)."""
    def merge(a, b):
        out = dict(a)
        for k, v in b.items():
            out[k] = merge(a[k], v) if isinstance(v, dict) and isinstance(a.get(k), dict) else v
        return out
    config: dict = {}
    for name in names:
        config = merge(config, yaml.safe_load((ROOT / "config" / name).read_text()))
    return config


def test_paper_configuration_is_the_paper_run():
    text = banner(merged("config.yaml"))
    assert "Paper run" in text and "Reduced run" not in text  # output.snapshot_t_min is no physics


def test_ci_configuration_is_a_reduced_run_and_names_its_overrides():
    text = banner(merged("config.yaml", "ci.yaml"))
    assert "Reduced run" in text and "Paper run" not in text
    assert "tube.length = 0.1" in text and "output.snapshot_t_min" not in text


def test_no_all_cases_at_all_is_the_paper_run():
    config = merged("config.yaml")
    config.pop("all_cases")
    assert "Paper run" in banner(config)


def test_the_report_refuses_results_of_another_configuration(tmp_path):
    """`snakemake --report` with the paper configuration over a CI run's case files: one line naming
    the file, the differing keys and the configfile to give, before any report is made."""
    import sys

    import netCDF4

    from tests.workflow.test_workflow import scratch, snakemake

    sys.path.append(str(ROOT / "workflow" / "scripts"))
    from plan import Plan

    work = scratch(tmp_path)

    def plan(*names):
        config = merged(*names)
        path = ROOT / config["validation"]["statements"]
        return Plan(config, yaml.safe_load(path.read_text()))

    paper, ci = plan("config.yaml"), plan("config.yaml", "ci.yaml")
    # a case file both configurations write (same sweep and point name), as the CI run wrote it
    name = next(ci.case_nc(*k) for k in ci.all_points()
                if k in paper.canonical and paper.case_nc(*k) == ci.case_nc(*k))
    path = work / name
    path.parent.mkdir(parents=True)
    with netCDF4.Dataset(path, "w") as ds:
        ds.setncattr("config_yaml", ci.cases[ci.canonical[ci.key(*Path(name).with_suffix("").parts[-2:])]]
                     .to_yaml())
    run = snakemake("--report", "report.html", cwd=work)
    assert run.returncode == 2 and not (work / "report.html").exists()
    [line] = [x for x in run.stderr.splitlines() if x.startswith("Error:")]
    assert line.startswith(f"Error: report: {name} was run with other parameters than this "
                           "configuration plans (")
    assert "tube.length = 0.1 there, 0.525 here" in line and "--configfile config/ci.yaml" in line
    run = snakemake("--report", "report.html", "--configfile", "config/ci.yaml", cwd=work)
    # the right configfile passes this check (the report then needs every figure, absent here)
    assert "Error: report:" not in run.stderr

"""The Snakemake workflow: dry runs of the paper configuration, a YAML-only sweep, early refusal of
bad case keys, lint, and (marker `workflow`) the whole reduced CI workflow.

Snakemake is driven through its command line in a subprocess (its Python API is for its own
developers), from the repository root or from a scratch copy of config/ and resources/.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]
# Every reproducible figure of both papers: V1 (sketch of the set-up) and V2 (photographs of the
# experiment) are not simulation results.
FIGURES = [f"H{n:02d}" for n in range(1, 22)] + [f"V{n:02d}" for n in range(3, 20)]


def snakemake(*args: str, cwd: Path = ROOT, timeout: float = 600) -> subprocess.CompletedProcess:
    cmd = [*SNAKEMAKE, "--snakefile", str(ROOT / "Snakefile"), *args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)


def scratch(tmp_path: Path) -> Path:
    """A working directory with copies of config/ and resources/ (results go there, not the repo)."""
    for name in ("config", "resources"):
        shutil.copytree(ROOT / name, tmp_path / name)
    return tmp_path


def test_dry_run_lists_every_figure():
    run = snakemake("-n", "-F", "--cores", "2")
    assert run.returncode == 0, run.stderr + run.stdout
    out = run.stdout + run.stderr
    for fig in FIGURES:
        for ext in ("png", "pdf", "txt"):
            assert f"results/figures/{fig}.{ext}" in out, f"{fig}.{ext} missing from the dry run"
    assert "results/validation/validation.csv" in out
    assert "results/benchmarks/engine.json" in out


def test_configs_declare_every_figure():
    config = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    assert sorted(config["figures"]) == FIGURES


def test_ci_dry_run_lists_every_figure():
    run = snakemake("-n", "-F", "--cores", "2", "--configfile", "config/ci.yaml")
    assert run.returncode == 0, run.stderr + run.stdout
    out = run.stdout + run.stderr
    for fig in FIGURES:
        assert f"results/figures/{fig}.png" in out


def test_bulk_short_tube_study_plans_its_cases_only(tmp_path):
    """config/bulk_short_tube.yaml (docs/decisions/0005-packed-bed-dashpot-condition.md): its six tables plan its 15 short-tube
    cases from empty and nothing of the paper run; the defaults' seed 0 is the work-precision
    study's bulk fill (identical cases run once)."""
    work = scratch(tmp_path)
    targets = [f"results/curves/bulk_{s}.csv" for s in "RFEBAG"]
    run = snakemake("-n", "--cores", "2", "--configfile", "config/bulk_short_tube.yaml", "--", *targets,
                    cwd=work)
    assert run.returncode == 0, run.stderr + run.stdout
    out = run.stdout + run.stderr
    cases = set(re.findall(r"results/cases/(bulk_[A-Z])/run\.seed~(\d)\.nc", out))
    assert len(cases) == 14 and ("bulk_R", "0") not in cases
    assert "results/cases/wp_bulk_fill/base.nc" in out
    assert "h_default" not in out and "results/figures" not in out


def test_partial_validation_reports_what_is_not_run_yet_without_running_it(tmp_path):
    """config/partial.yaml: the table of a run in progress, no case is started for it."""
    work = scratch(tmp_path)
    run = snakemake("validation", "--cores", "1", "--configfile", "config/partial.yaml", cwd=work)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "rule simulate" not in run.stdout + run.stderr
    import pandas as pd

    table = pd.read_csv(work / "results/validation/validation.csv")
    assert (table["within"] == "not available").all()
    assert table["note"].str.startswith("not run yet").all()
    assert "Partial validation" in (work / "results/validation/validation.md").read_text()


def _job_counts(output: str) -> dict[str, int]:
    """rule -> job count from the table a dry run prints ("Job stats:")."""
    table = output.split("Job stats:", 1)[-1] if "Job stats:" in output else ""
    return {m[0]: int(m[1]) for m in re.findall(r"^(\w+)\s+(\d+)$", table, flags=re.MULTILINE)
            if m[0] != "total"}


def test_partial_validation_never_plans_a_case_over_another_configurations_results(tmp_path):
    """config/partial.yaml over a results/ of another configuration (case files of other parameters,
    older than the base YAMLs they came from, summaries, curves and figures of theirs): `validation
    reference` plans no case and no analysis, and reports those cases as not run yet."""
    import os

    work = scratch(tmp_path)
    old = time.time() - 30 * 86400
    fake = {"results/cases/h_default/base.nc": "not the paper's case",
            "results/cases/h_vs/gas.superficial_velocity~4_feed.mass_flow_kg_h~2.49.nc": "x",
            "results/summaries/h_default/base.json": json.dumps({"pressure_drop": 1.0}),
            "results/slugs/h_default/base.csv": "t,x\n",
            "results/curves/h_vs.csv": "a\n1\n", "results/curves/h_vs.png": "png",
            "results/figures/H01.png": "png", "results/figures/H01.txt": "caption"}
    for name, text in fake.items():
        path = work / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        os.utime(path, (old, old))
    run = snakemake("-n", "validation", "reference", "--cores", "1", "--configfile",
                    "config/partial.yaml", cwd=work)
    assert run.returncode == 0, run.stderr[-3000:]
    jobs = _job_counts(run.stdout + run.stderr)
    assert set(jobs) <= {"validation", "reference"}, jobs
    run = snakemake("validation", "--cores", "1", "--configfile", "config/partial.yaml", cwd=work)
    assert run.returncode == 0, run.stderr[-3000:]
    import pandas as pd

    table = pd.read_csv(work / "results/validation/validation.csv")
    assert table["note"].str.startswith("not run yet").all()


def test_new_sweep_written_as_yaml_reaches_a_curve(tmp_path):
    """A sweep over a key the papers never swept (the restitution of a horizontal tube), added as
    YAML only, expands to one case per point and reaches a curve."""
    work = scratch(tmp_path)
    (work / "config/restitution.yaml").write_text(yaml.safe_dump({"sweeps": {"h_restitution": {
        "base": "config/cases/horizontal.yaml",
        "overrides": {"run.duration": 20.0},
        "parameters": {"particles.restitution": [0.3, 0.6, 0.9]},
        "same_as": {"wall.restitution": "particles.restitution"}}},
        "figures": {"X01": {"kind": "curve", "sweep": "h_restitution", "x": "particles.restitution"}}}))
    run = snakemake("results/curves/h_restitution.png", "results/figures/X01.png", "-n", "--cores", "2",
                    "--configfile", "config/restitution.yaml", cwd=work)
    assert run.returncode == 0, run.stderr + run.stdout
    out = run.stdout + run.stderr
    for e in ("0.3", "0.6", "0.9"):
        assert f"results/cases/h_restitution/particles.restitution~{e}.nc" in out
    assert "results/curves/h_restitution.csv" in out
    assert "results/curves/h_restitution.png" in out
    assert "results/figures/X01.pdf" in out  # and as a figure of one's own


@pytest.mark.workflow
def test_new_sweep_written_as_yaml_runs_through_to_a_curve(tmp_path):
    """The same kind of YAML-only sweep, run for real in a 3 cm tube (two short cases)."""
    work = scratch(tmp_path)
    (work / "config/restitution.yaml").write_text(yaml.safe_dump({
        "sweeps": {"h_restitution": {
            "base": "config/cases/horizontal.yaml",
            "overrides": {"tube.length": 0.03, "gas.nodes_x": 9, "run.duration": 1.0},
            "position": 0.015,
            "parameters": {"particles.restitution": [0.3, 0.9]},
            "same_as": {"wall.restitution": "particles.restitution"}}}}))
    run = snakemake("results/curves/h_restitution.png", "--cores", "2",
                    "--configfile", "config/restitution.yaml", cwd=work)
    assert run.returncode == 0, run.stderr[-3000:]
    import pandas as pd

    table = pd.read_csv(work / "results/curves/h_restitution.csv", comment="#")
    assert sorted(table["particles.restitution"]) == [0.3, 0.9]
    assert list(table["wall.restitution"]) == list(table["particles.restitution"])
    assert (table["pressure_drop"] > 0).all()
    # the case files' dashpot flag reaches the curve table (0.15 t_c at gamma_t 0.02: ratio 0.93,
    # resolved by the default implicit spin kick)
    assert table["dashpot_resolved"].dtype == bool and table["dashpot_resolved"].all()
    assert (work / "results/curves/h_restitution.png").stat().st_size > 0


def test_warm_started_sweep_depends_on_its_source_case(tmp_path):
    work = scratch(tmp_path)
    (work / "config/warm.yaml").write_text(yaml.safe_dump({"sweeps": {"h_warm": {
        "base": "config/cases/horizontal.yaml",
        "overrides": {"run.duration": 20.0, "run.steady_settle": 3.0},
        "warm_start": {"sweep": "h_default"},
        "parameters": {"gas.viscosity": [4.5e-5, 8.5e-5]}}}}))
    run = snakemake("results/curves/h_warm.csv", "-n", "--cores", "2", "--configfile", "config/warm.yaml",
                    cwd=work)
    assert run.returncode == 0, run.stderr + run.stdout
    jobs = re.findall(r"rule simulate:\n\s+input: ([^\n]*)\n\s+output: ([^\n]*)", run.stdout + run.stderr)
    inputs = {out.strip(): inp for inp, out in jobs}
    for eta in ("4.5e-05", "8.5e-05"):
        assert "results/cases/h_default/base.nc" in inputs[f"results/cases/h_warm/gas.viscosity~{eta}.nc"]
    assert "results/cases/" not in inputs["results/cases/h_default/base.nc"]  # the source runs cold


def test_warm_start_from_next_chains_points_within_a_sweep(tmp_path):
    """The lowest velocity starts from the next one's final grains, at either mass flow; the others
    from the sweep's warm_start case."""
    work = scratch(tmp_path)
    (work / "config/chain.yaml").write_text(yaml.safe_dump({"sweeps": {"h_chain": {
        "base": "config/cases/horizontal.yaml",
        "overrides": {"run.duration": 20.0},
        "warm_start": {"sweep": "h_default"},
        "warm_start_from_next": {"gas.superficial_velocity": [0.15]},
        "parameters": {"gas.superficial_velocity": [0.15, 0.25, 1.0],
                       "feed.mass_flow_kg_h": [2.49, {"feed.mass_flow_kg_h": 9.95,
                                                      "feed.entry_velocity": 0.16}]}}}},
                                                     sort_keys=False))  # point names follow this order
    run = snakemake("results/curves/h_chain.csv", "-n", "--cores", "2", "--configfile",
                    "config/chain.yaml", cwd=work)
    assert run.returncode == 0, run.stderr + run.stdout
    jobs = re.findall(r"rule simulate:\n\s+input: ([^\n]*)\n\s+output: ([^\n]*)", run.stdout + run.stderr)
    inputs = {out.strip(): inp for inp, out in jobs}
    point = "results/cases/h_chain/gas.superficial_velocity~{}_feed.mass_flow_kg_h~{}.nc"
    for mdot in ("2.49", "9.95"):
        assert point.format("0.25", mdot) in inputs[point.format("0.15", mdot)]
        assert "h_default/base.nc" not in inputs[point.format("0.15", mdot)]
        for vs in ("0.25", "1"):
            assert "results/cases/h_default/base.nc" in inputs[point.format(vs, mdot)]


@pytest.mark.parametrize("chain, message", [
    ({"gas.viscosity": [0.15]}, "'gas.viscosity' is not one of its parameters"),
    ({"gas.superficial_velocity": [1.0]}, "must be one of its values except the last, [0.15, 0.25]"),
    ({"gas.superficial_velocity": [0.2]}, "gas.superficial_velocity = 0.2"),
])
def test_warm_start_from_next_refuses_a_value_without_a_next_point(tmp_path, chain, message):
    work = scratch(tmp_path)
    (work / "config/chain.yaml").write_text(yaml.safe_dump({"sweeps": {"h_chain": {
        "base": "config/cases/horizontal.yaml",
        "warm_start_from_next": chain,
        "parameters": {"gas.superficial_velocity": [0.15, 0.25, 1.0]}}}}))
    run = snakemake("-n", "--cores", "1", "--configfile", "config/chain.yaml", cwd=work)
    assert run.returncode != 0
    assert message in run.stderr + run.stdout
    assert not (work / "results").exists()


def test_typo_in_a_case_key_fails_before_any_job(tmp_path):
    work = scratch(tmp_path)
    (work / "config/typo.yaml").write_text(yaml.safe_dump({"sweeps": {"bad": {
        "base": "config/cases/horizontal.yaml",
        "parameters": {"particles.restitutoin": [0.3, 0.9]}}}}))
    run = snakemake("-n", "--cores", "1", "--configfile", "config/typo.yaml", cwd=work)
    assert run.returncode != 0
    err = run.stderr + run.stdout
    assert "particles.restitutoin" in err and "particles.restitution" in err  # names it, suggests the fix
    assert not (work / "results").exists()


def test_schema_refuses_an_unknown_config_key(tmp_path):
    work = scratch(tmp_path)
    (work / "config/bad.yaml").write_text(yaml.safe_dump({"analysis": {"positon": 0.2}}))
    run = snakemake("-n", "--cores", "1", "--configfile", "config/bad.yaml", cwd=work)
    assert run.returncode != 0
    assert "positon" in run.stderr + run.stdout


SWEEP = {"base": "config/cases/horizontal.yaml", "parameters": {"particles.restitution": [0.3, 0.9]}}


@pytest.mark.parametrize("sweep, message", [
    ({**SWEEP, "parameters": {"particles.restitution": []}},
     "sweep 'h_rest': parameters.particles.restitution: empty list; give at least 1 value"),
    ({**SWEEP, "overides": {"run.duration": 5.0}},
     "sweep 'h_rest': unknown key 'overides' (did you mean 'overrides'?); allowed keys: description, "
     "base, overrides,"),
    ({**SWEEP, "parameters": {"particles.restitutoin": [0.3]},
      "same_as": {"wall.restitution": "particles.restitution"}},
     "sweep 'h_rest': parameters: unknown case key 'particles.restitutoin' (did you mean "
     "'particles.restitution'?)"),
    ({**SWEEP, "same_as": {"wall.restitution": "particles.restitutoin"}},
     "sweep 'h_rest': same_as.wall.restitution: unknown case key 'particles.restitutoin' (did you "
     "mean 'particles.restitution'?)"),
    ({k: v for k, v in SWEEP.items() if k != "base"}, "sweep 'h_rest': missing key 'base'"),
    ({**SWEEP, "parameters": {"particles.restitution": 0.5}},
     "sweep 'h_rest': parameters.particles.restitution: 0.5 is not a list; give a list of values, "
     "e.g. [0.5]"),
    ({**SWEEP, "warm_start_from_next": {"particles.restitutoin": [0.3]}},
     "sweep 'h_rest': warm_start_from_next: unknown case key 'particles.restitutoin' (did you mean "
     "'particles.restitution'?)"),
])
def test_a_bad_sweep_is_refused_in_one_line_naming_the_fix(tmp_path, sweep, message):
    work = scratch(tmp_path)
    (work / "config/bad.yaml").write_text(yaml.safe_dump({"sweeps": {"h_rest": sweep}}))
    run = snakemake("-n", "--cores", "1", "--configfile", "config/bad.yaml", cwd=work)
    assert run.returncode == 2
    errors = [line for line in (run.stderr + run.stdout).splitlines()
              if line and not line.startswith("Config file config/config.yaml is extended")]
    assert len(errors) == 1 and errors[0].startswith("Error: config: "), errors
    assert message in errors[0]


@pytest.mark.parametrize("name, text, where", [
    ("config/config.yaml", "sweeps:\n  h_default: {base: x\n  v_default: {}\n", "config/config.yaml:3:"),
    ("resources/paper_statements.yaml", "- id: S1\n  measure: [trend\n", "resources/paper_statements.yaml:3:"),
])
def test_a_yaml_syntax_error_names_its_file_and_line(tmp_path, name, text, where):
    work = scratch(tmp_path)
    (work / name).write_text(text)
    run = snakemake("-n", "--cores", "1", cwd=work)
    assert run.returncode == 2
    assert f"Error: {where}" in run.stderr and "YAML syntax error" in run.stderr, run.stderr


def test_config_check_gives_the_line_of_a_configfile_syntax_error(tmp_path):
    """A --configfile Snakemake reads before the workflow (its message has no line):
    workflow/scripts/config_check.py names it."""
    bad = tmp_path / "my.yaml"
    bad.write_text("sweeps:\n  h_rest:\n    parameters: {particles.restitution: [0.3]\n    base: x\n")
    run = subprocess.run([sys.executable, str(ROOT / "workflow/scripts/config_check.py"),
                          "config/config.yaml", str(bad)], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stderr.strip().startswith(f"{bad}:4:5: YAML syntax error"), run.stderr


def test_bad_point_reference_is_refused(tmp_path):
    work = scratch(tmp_path)
    (work / "config/bad.yaml").write_text(yaml.safe_dump({"figures": {"H04": {
        "kind": "porosity_image",
        "case": {"sweep": "h_vs", "point": {"gas.superficial_velocity": 3.3}}}}}))
    run = snakemake("-n", "--cores", "1", "--configfile", "config/bad.yaml", cwd=work)
    assert run.returncode != 0
    assert "h_vs" in run.stderr + run.stdout


def test_two_seed_studies_in_one_regime_are_refused(tmp_path):
    work = scratch(tmp_path)
    config = yaml.safe_load((work / "config/config.yaml").read_text())
    regime = config["benchmarks"]["work_precision"]["wp_seed"]["regime"]  # wp_seed's, taken twice
    (work / "config/bad.yaml").write_text(yaml.safe_dump({
        "sweeps": {"wp_seed_more": {"base": "config/cases/horizontal.yaml", "position": 0.1,
                                    "parameters": {"run.seed": [7, 8]}}},
        "benchmarks": {"work_precision": {"wp_seed_more": {"reference": 7, "regime": regime}}}}))
    run = snakemake("-n", "--cores", "1", "--configfile", "config/bad.yaml", cwd=work)
    assert run.returncode != 0
    err = run.stderr + run.stdout
    assert "wp_seed_more" in err and "wp_seed" in err and "regime" in err


def test_work_precision_pools_each_regime_with_its_own_seeds(tmp_path):
    """workflow/scripts/work_precision.py standalone: the default point of a bulk knob is the mean
    of the bulk seeds, not of the slug seeds, and each regime keeps its own scatter."""
    import pandas as pd

    def summary(name, **values):
        row = {"pressure_drop_sem": 10.0, "slug_velocity": 0.3, "slug_velocity_sem": 0.003,
               "slug_length": 0.05, "slug_length_sem": 0.001, "wall_time_s": 10.0, "cpu_time_s": 10.0,
               **values}
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(row))
        return str(path)

    dt = "numerics.time_step_fraction"
    studies = {
        "wp_time_step": {"parameter": dt, "reference": 0.05, "default": 0.15, "regime": "slug",
                         "summaries": [summary("s1", **{dt: 0.05, "pressure_drop": 1000.0}),
                                       summary("s2", **{dt: 0.15, "pressure_drop": 5000.0})]},
        "wp_seed": {"parameter": "run.seed", "reference": 0, "default": 0, "regime": "slug",
                    "summaries": [summary(f"s3{k}", **{"run.seed": k, "pressure_drop": p})
                                  for k, p in enumerate([1000.0, 1020.0, 980.0])]},
        "wp_bulk_time_step": {"parameter": dt, "reference": 0.05, "default": 0.15, "regime": "bulk",
                              "summaries": [summary("b1", **{dt: 0.05, "pressure_drop": 2000.0}),
                                            summary("b2", **{dt: 0.15, "pressure_drop": 9000.0})]},
        "wp_bulk_seed": {"parameter": "run.seed", "reference": 0, "default": 0, "regime": "bulk",
                         "summaries": [summary(f"b3{k}", **{"run.seed": k, "pressure_drop": p})
                                       for k, p in enumerate([1500.0, 1700.0, 1600.0])]},
    }
    table_path = tmp_path / "wp.csv"
    run = subprocess.run([sys.executable, str(ROOT / "workflow/scripts/work_precision.py"),
                          "--output", f"table={table_path}", "--output", f"png={tmp_path / 'wp.png'}",
                          "--params", f"studies={json.dumps(studies)}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    table = pd.read_csv(table_path, comment="#")
    default = table.loc[(table["sweep"] == "wp_bulk_time_step") & (table["value"] == 0.15)].iloc[0]
    assert default["regime"] == "bulk"
    assert default["pressure_drop"] == pytest.approx(1600.0)  # the bulk seeds' mean (a slug mix: 1300)
    assert default["pressure_drop_error"] == pytest.approx(0.2)
    slug = table.loc[(table["sweep"] == "wp_time_step") & (table["value"] == 0.15)].iloc[0]
    assert slug["pressure_drop"] == pytest.approx(1000.0)
    attrs = json.loads(table_path.read_text().splitlines()[0].removeprefix("# attrs: "))
    assert attrs["run_to_run_scatter"]["bulk"]["pressure_drop"] == pytest.approx(100.0 / 1600.0)
    assert attrs["run_to_run_scatter"]["slug"]["pressure_drop"] == pytest.approx(20.0 / 1000.0)


def test_lint_has_no_findings_but_missing_environments():
    """--lint flags only that rules have no conda env/container (a pip-installed project)."""
    run = snakemake("--lint")
    text = run.stdout + run.stderr
    findings = set(re.findall(r"^\s+\* (.+?):$", text, flags=re.MULTILINE))
    assert "Lints for rule" in text or run.returncode == 0
    assert findings <= {"Specify a conda environment or container for each rule."}, findings


@pytest.mark.workflow
def test_ci_workflow_runs_and_writes_every_output(tmp_path):
    """The whole reduced workflow, as CI runs it: every figure, curve and the validation table."""
    work = scratch(tmp_path)
    start = time.monotonic()
    run = snakemake("--cores", "2", "--configfile", "config/ci.yaml", cwd=work, timeout=1800)
    wall = time.monotonic() - start
    print(f"CI workflow: {wall:.0f} s wall")
    assert run.returncode == 0, run.stderr[-5000:]
    import pandas as pd
    import xarray as xr
    from matplotlib.image import imread

    for fig in FIGURES:
        png = work / f"results/figures/{fig}.png"
        assert imread(png).ndim == 3, fig
        assert (work / f"results/figures/{fig}.pdf").read_bytes().startswith(b"%PDF")
        caption = (work / f"results/figures/{fig}.txt").read_text()
        assert caption.startswith(f"{fig}:") and "tube L =" in caption, fig
        # every figure draws data (figure.drawn_check: no empty panel, no snapshot window
        # without grains)
        assert "- check: every panel draws data" in caption and "EMPTY" not in caption, (fig, caption)
    h02 = (work / "results/figures/H02.txt").read_text()
    assert "no slug in any snapshot" not in h02 and " grains in the " in h02  # H02 shows a slug
    assert "validation H-u-mid" in (work / "results/figures/H10.txt").read_text()  # ours vs paper
    assert "warm start from results/cases/" in (work / "results/figures/H03.txt").read_text()
    config = yaml.safe_load((work / "config/config.yaml").read_text())
    for sweep, spec in config["sweeps"].items():
        if spec.get("parameters"):
            table = pd.read_csv(work / f"results/curves/{sweep}.csv", comment="#")
            assert len(table) >= 2 and table["pressure_drop"].notna().all(), sweep
    validation = pd.read_csv(work / "results/validation/validation.csv")
    assert set(validation["within"]) <= {"yes", "no", "not available"}
    assert len(validation) == len(yaml.safe_load((work / "resources/paper_statements.yaml").read_text()))
    with xr.open_dataset(next((work / "results/cases/h_default").glob("*.nc"))) as ds:
        assert "snapshot_position" in ds  # snapshots where profiles are drawn ...
    for case in (work / "results/cases/h_vs").glob("*.nc"):
        with xr.open_dataset(case) as ds:
            assert "snapshot_position" not in ds  # ... and nowhere else
    assert json.loads((work / "results/benchmarks/engine.json").read_text())["grains"] > 0
    assert (work / "results/benchmarks/timings.csv").exists()
    restitution = pd.read_csv(work / "results/benchmarks/restitution/restitution.csv", keep_default_na=False)
    assert set(restitution["contact"]) == {"grain-grain", "grain-wall"} and not restitution["refused"].any()
    # the model-identification stage, reduced: three readings (one at a time) on the two default cases
    ident = snakemake("identification", "--cores", "2", "--configfile", "config/ci.yaml",
                      "config/identification.yaml", "config/identification_ci.yaml", cwd=work, timeout=900)
    assert ident.returncode == 0, ident.stderr[-5000:]
    table = pd.read_csv(work / "results/identification/identification.csv", comment="#")
    assert table["reading"].nunique() == 3 and len(table) == 3 * 5
    assert "baseline" in set(table["reading"])
    assert table["reading"].str.contains("scheme=unsplit").any()  # the baseline is split
    assert set(table["within"]) <= {"yes", "no", "no (blocked)", "not available"}
    assert imread(work / "results/identification/identification.png").ndim == 3
    report = snakemake("--report", "report.html", "--configfile", "config/ci.yaml", cwd=work)
    assert report.returncode == 0, report.stderr[-3000:]
    html = (work / "report.html").read_text(errors="replace")
    assert "validation.csv" in html and "H01.png" in html
    assert "Reduced run" in html and "Paper run" not in html  # the CI config shortens every case
    assert "Missing metadata" not in report.stderr  # every file of the report's jobs was made here
    # without the run's configfile the report is refused, naming it, instead of "Paper run"
    wrong = snakemake("--report", "report.html", cwd=work)
    assert wrong.returncode == 2 and "--configfile config/ci.yaml" in wrong.stderr, wrong.stderr[-3000:]
    # the committed reference copy is regenerated from the same outputs
    # the target first: --configfile takes several values
    ref = snakemake("reference", "--cores", "1", "--configfile", "config/ci.yaml", cwd=work)
    assert ref.returncode == 0, ref.stderr[-3000:]
    copy = work / "docs/reference/paper"
    assert (copy / "validation.md").read_text() == (work / "results/validation/validation.md").read_text()
    assert sorted(p.stem for p in (copy / "figures").glob("*.png")) == FIGURES
    assert not list(copy.rglob("*.pdf"))  # PNG only: the committed copy stays small

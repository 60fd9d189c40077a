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

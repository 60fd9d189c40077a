"""Case configuration: loading, overrides, and refusal of bad input before any work."""

from pathlib import Path

import pytest

from engine import Case, CaseError, KEYS, Simulation
from engine.case import keys_markdown
from engine.cli import main as cli

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name, incline", [("horizontal", 0.0), ("vertical", 90.0)])
def test_paper_cases_load_with_paper_defaults(name, incline):
    case = Case.from_yaml(ROOT / "config" / "cases" / f"{name}.yaml")
    assert case["tube.inclination_deg"] == incline
    assert case["feed.mass_flow_kg_h"] == 2.49
    assert case["gas.viscosity"] == pytest.approx(6.73e-5)  # 0.0673 cP


def test_dotted_override_changes_only_that_key():
    base = Case()
    changed = base.with_overrides(["particles.friction=0.1"])
    assert changed["particles.friction"] == 0.1
    assert {k for k, v in changed.items() if v != base[k]} == {"particles.friction"}


@pytest.mark.parametrize("override, message", [
    ("particles.frction=0.1", r"unknown key 'particles.frction' \(did you mean 'particles.friction'\?\)"),
    ("particles.friction=-0.1", r"particles.friction = -0.1 is out of range: allowed 0 <= value <= 10"),
    ("particles.restitution=0.05", r"particles.restitution = 0.05 is out of range: allowed 0.15 <= value"),
    ("tube.length=0", r"tube.length = 0.0 is out of range: allowed 0 < value"),
    ("particles.density=abc", r"particles.density = 'abc' must be a number"),
    ("gas.nodes_x=2.5", r"gas.nodes_x = 2.5 must be an integer"),
    ("gas.enabled=3", r"gas.enabled = 3 must be true or false"),
    ("particles.diameter=0.004", r"particles.diameter = 0.004 m must be < tube.diameter / 2"),
    ("gas.viscosity=.nan", r"gas.viscosity = nan is not finite"),
    ("output.tube_snapshot_interval=-0.05", r"output.tube_snapshot_interval = -0.05 is out of range: "
                                            r"allowed 0 <= value <= 100"),
    ("output.tube_snapshot_interval=0.015", r"output.tube_snapshot_interval = 0.015 s must be 0 \(none\) "
                                            r"or a whole multiple of output.interval = 0.01 s"),
])
def test_bad_values_are_refused_naming_the_key(override, message):
    with pytest.raises(CaseError, match=message):
        Case().with_overrides([override])


def test_unknown_key_in_yaml_is_refused(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("tube:\n  lenght: 0.5\n")
    with pytest.raises(CaseError, match="unknown key 'tube.lenght'"):
        Case.from_yaml(path)


def test_time_step_above_stable_limit_is_refused_with_the_limit():
    case = Case().with_overrides(["gas.enabled=false", "numerics.time_step_fraction=0.9"])
    with pytest.raises(CaseError, match=r"above the stable limit .* s .*numerics.time_step_fraction <= 0\.\d+"):
        Simulation(case)


def test_unpackable_feed_is_refused_with_the_entry_velocity_needed():
    case = Case().with_overrides(["gas.enabled=false", "feed.mass_flow_kg_h=9.95"])
    with pytest.raises(CaseError, match=r"feed.entry_velocity >= 0\.1\d+ m/s"):
        Simulation(case)
    Simulation(case.with_overrides(["feed.entry_velocity=0.16"]))  # the documented remedy works


def test_every_key_is_documented():
    for key in KEYS.values():
        assert key.doc and key.unit is not None and key.allowed()
        Case().with_overrides([(key.name, key.default)])  # defaults are valid
    assert (ROOT / "docs" / "case-keys.md").read_text() == keys_markdown(), \
        "docs/case-keys.md is stale: regenerate with `plugsim keys --markdown > docs/case-keys.md`"


def test_cli_check_refuses_bad_override_with_exit_2(capsys):
    assert cli(["check", str(ROOT / "config/cases/horizontal.yaml"), "--set", "wall.friction=-1"]) == 2
    assert "wall.friction = -1.0 is out of range" in capsys.readouterr().err
    assert cli(["check", str(ROOT / "config/cases/horizontal.yaml")]) == 0
    # the default step under-resolves the explicit tangential dashpot of packed beds; the default
    # implicit spin kick resolves it, and check says which
    assert "0.93, above 0.47, resolved by the implicit spin kick" in capsys.readouterr().out
    assert cli(["check", str(ROOT / "config/cases/horizontal.yaml"), "--set", "numerics.implicit_spin=false"]) == 0
    assert "gamma_t dt/(m/7) = 0.93, above 0.47: packed beds" in capsys.readouterr().out
    assert cli(["check", str(ROOT / "config/cases/horizontal.yaml"), "--set",
                "numerics.time_step_fraction=0.05"]) == 0
    out = capsys.readouterr().out
    assert "gamma_t dt/(m/7) = 0.31" in out and "packed beds" not in out

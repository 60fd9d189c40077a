"""benchmarks/studies/spin_chatter.py: the reversed-increment measure and the dashpot's step ratio."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from engine import Case
from engine.run import run_case

from .. import load_benchmark

ROOT = Path(__file__).resolve().parents[3]
SMALL = ["tube.length=0.04", "gas.nodes_x=12", "run.duration=0.1", "feed.mass_flow_kg_h=9.95",
         "feed.entry_velocity=0.16"]


@pytest.fixture(scope="module")
def spin_chatter():
    return load_benchmark("studies/spin_chatter")


def test_reversed_fraction_tells_a_resolved_oscillation_from_period_two_chatter(spin_chatter):
    rng = np.random.default_rng(1)
    phases = rng.uniform(0, 2 * math.pi, (50, 1))
    steps = np.arange(400)[:, None, None]
    # 20 steps per period: the increment changes sign twice per period, so at most 2/20 reverse
    smooth = np.sin(2 * math.pi * steps / 20 + phases[None]) * np.ones((1, 1, 3))
    assert spin_chatter.reversed_fraction(smooth) == pytest.approx(0.1, abs=0.02)
    chatter = smooth + 0.5 * (-1.0) ** steps  # a period-2 part larger than the smooth increments
    assert spin_chatter.reversed_fraction(chatter) == 1.0
    drift = np.cumsum(np.ones((400, 50, 3)), axis=0)  # steady creep: no increment reverses
    assert spin_chatter.reversed_fraction(drift) == 0.0


def test_rows_give_the_dashpot_step_ratio_of_each_variant(spin_chatter, tmp_path):
    case = tmp_path / "small.yaml"
    case.write_text(Case.from_yaml(ROOT / "config/cases/vertical.yaml", SMALL).to_yaml())
    state = tmp_path / "state.nc"
    run_case(Case.from_yaml(case), state)
    out = tmp_path / "rows.json"
    assert spin_chatter.main([str(case), "--initial-state", str(state), "--steps", "5", "--settle", "0.001",
                              "--variant", "numerics.time_step_fraction=0.05",
                              "--variant", "numerics.time_step_fraction=0.15 particles.tangential_damping=0.01",
                              "--json", str(out)]) == 0
    rows = json.loads(out.read_text())
    for row in rows:
        mass = 937.0 * math.pi * 0.0014**3 / 6
        # below the cap the ratio is gamma_t dt / (m/7) exactly (dt rounded to whole output steps)
        assert row["dashpot_step_ratio"] == pytest.approx(row["tangential_damping"] * row["time_step_s"] * 7 / mass,
                                                          rel=1e-12)
        assert row["grains"] > 50
        assert 0.0 <= row["spin_reversed_fraction"] <= 1.0
    assert rows[0]["time_step_fraction"] == 0.05 and rows[1]["tangential_damping"] == 0.01
    # 0.05 t_c at 0.02 N s/m: 0.31 (the tangential relaxation time m/(7 gamma_t) is 9.6 us)
    assert rows[0]["dashpot_step_ratio"] == pytest.approx(0.31, abs=0.01)


def test_too_few_steps_are_refused(spin_chatter, tmp_path):
    with pytest.raises(SystemExit):
        spin_chatter.main(["config/cases/vertical.yaml", "--initial-state", "x.nc", "--steps", "2"])

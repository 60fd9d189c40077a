"""Tests of the one-off study scripts in benchmarks/studies/."""

from pathlib import Path

import numpy as np

from engine import Case, Simulation
from engine.bench import stack_layers
from engine.feed import layer_template

ROOT = Path(__file__).resolve().parents[3]
# a short conveying tube: feed grains, gas drag and the implicit spin kick all present
SMALL = ["tube.length=0.04", "gas.nodes_x=12", "feed.mass_flow_kg_h=9.95", "feed.entry_velocity=0.16"]


def small_conveying_simulation() -> Simulation:
    """The SMALL horizontal tube with a 1 cm packed plug mid-tube, 0.01 s after the start."""
    sim = Simulation(Case.from_yaml(ROOT / "config/cases/horizontal.yaml", SMALL))
    d = sim.case["particles.diameter"]
    xs = np.arange(d, 0.04 - d, 1.02 * d)
    template = layer_template(sim.case["tube.diameter"] / 2, d)
    sim.add_particles(stack_layers(xs, (xs > 0.015) & (xs < 0.025), template, 7, d, np.random.default_rng(0)))
    sim.advance(0.01)
    return sim

"""The kernels' parameters (engine/parameters.py): one declaration each, built from the case by name,
nothing left unfilled, and every name the kernels read declared."""

import math
import pickle
import re
from pathlib import Path

import numpy as np
import pytest

from engine import Case, Simulation
from engine.contact import ContactModel
from engine.parameters import (GAS, GRAIN, GasParameters, GrainParameters, Parameter, gas_parameters,
                               grain_parameters)

KERNELS = Path(__file__).resolve().parents[2] / "engine" / "kernels"
CASE = Case().with_overrides(["particles.friction=0.3", "wall.friction=0.4", "gas.superficial_velocity=2.5",
                              "particles.rolling_resistance=0.05", "tube.inclination_deg=30"])


def test_a_case_key_reaches_the_kernels_as_it_is():
    p, g = grain_parameters(CASE), gas_parameters(CASE)
    for declarations, built in ((GRAIN, p), (GAS, g)):
        for q in declarations:
            if isinstance(q.source, str):
                assert getattr(built, q.name) == float(CASE[q.source]), q.name
    assert p.friction_pair == 0.3 and p.friction_wall == 0.4 and g.superficial_velocity == 2.5


def test_derived_parameters_are_the_contact_models():
    p, m = grain_parameters(CASE), ContactModel.from_case(CASE)
    assert (p.dt, p.mass, p.radius, p.inertia) == (m.time_step, m.mass, m.radius, m.inertia)
    assert (p.damping_pair, p.damping_wall) == (m.damping_pair, m.damping_wall)
    assert (p.tangential_damping_pair, p.tangential_damping_wall) == (m.tangential_damping_pair,
                                                                     m.tangential_damping_wall)
    theta = math.radians(30)
    assert (p.gravity_x, p.gravity_y, p.gravity_z) == (-9.81 * math.sin(theta), 0.0, -9.81 * math.cos(theta))


def test_every_parameter_is_declared_once_and_built_as_a_finite_float():
    for declarations, kind, built in ((GRAIN, GrainParameters, grain_parameters(CASE)),
                                      (GAS, GasParameters, gas_parameters(CASE))):
        names = [q.name for q in declarations]
        assert len(names) == len(set(names)) and kind._fields == tuple(names)
        assert all(type(v) is float and math.isfinite(v) for v in built)


def test_an_unfilled_or_non_finite_parameter_is_refused_when_built():
    values = grain_parameters(CASE)._asdict()
    del values["friction_pair"]
    with pytest.raises(TypeError, match="friction_pair"):
        GrainParameters(**values)
    bad = Parameter("friction_pair", lambda case: math.nan, "1", "")
    with pytest.raises(ValueError, match="kernel parameter friction_pair = nan"):
        bad.value(CASE)
    with pytest.raises(ValueError, match="no parameter 'superficial_speed'"):
        gas_parameters(CASE, superficial_speed=1.0)


def kernel_reads(name: str) -> set[str]:
    """Attribute names the kernel modules read from the variable `name` (p or g; a comment's
    `p.cell_*` is not a name)."""
    found = set()
    for path in KERNELS.glob("*.py"):
        found |= set(re.findall(rf"\b{name}\.([a-z_][a-z0-9_]*)(?![\w*])", path.read_text()))
    return found


def test_the_kernels_read_declared_parameters_and_every_declared_one_is_read():
    # p.<name> in any kernel module is a grain parameter, g.<name> a gas one (gas.py names the gas
    # kernels' parameters g throughout)
    assert kernel_reads("p") == set(GrainParameters._fields)
    assert kernel_reads("g") == set(GasParameters._fields)


def test_a_state_pickled_with_parameter_vectors_continues_with_named_ones():
    sim = Simulation(Case().with_overrides(["feed.mass_flow_kg_h=0", "run.duration=0.01"]))
    p, g = sim._p, sim.gas.g
    sim._p, sim.gas.g = np.array(p), np.array(g)  # as the engine pickled them before
    again = pickle.loads(pickle.dumps(sim))
    assert again._p == p and again.gas.g == g

"""The time loop (engine/kernels/stepper.py) with the gas and the feed on."""

import pickle

import numpy as np

from engine import Case, Simulation


def copy(sim):
    return pickle.loads(pickle.dumps(sim))


def test_a_step_whose_list_is_outgrown_ends_as_with_a_roomy_list():
    """The step whose rebuild outgrows the list is completed outside the time loop (its gas update,
    forces, feed count and closing half kick): bit for bit the step that a large enough list takes."""
    base = Simulation(Case().with_overrides(["numerics.gas_interval=1", "tube.length=0.1"]))
    base.advance(0.15)

    def listed(sim):
        return int(sim._nbr_start[int(sim._n[0])])

    probe, steps = copy(base), 0
    while listed(probe) <= listed(base) and steps < 5000:  # the first rebuild that lengthens the list
        probe.advance(probe.dt)
        steps += 1
    roomy, tight = copy(base), copy(base)
    tight._nbr = tight._nbr[:listed(base)].copy()
    for sim in (roomy, tight):
        sim.advance(steps * sim.dt)
    assert len(tight._nbr) > listed(base)
    # every step updates the gas here, the broken one included
    np.testing.assert_array_equal(tight._drag, roomy._drag)
    np.testing.assert_array_equal(tight._vel, roomy._vel)
    np.testing.assert_array_equal(tight._pos, roomy._pos)

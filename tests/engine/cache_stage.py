"""One stage of the partial-cache reproduction in test_kernel_cache.py (run as a script in its own
process, with NUMBA_CACHE_DIR set by the test).

    chunked   compile (or load) contacts.contact_forces_chunked only, as a run stopped during its
              first compile, or a concurrent run, leaves the cache
    evaluate  call contacts.evaluate_contacts on a small packing and print its forces (hex floats)

The packing: 60 touching grains on a helix in the default horizontal tube (the first one
pressing the inlet wall), one thread (the serial branch).
"""

import sys

import numpy as np

from engine.case import Case
from engine.kernels import contacts
from engine.simulation import Simulation
from engine.kernels.stepper import rebuild

CASE = "config/cases/horizontal.yaml"


def packing() -> Simulation:
    sim = Simulation(Case.from_yaml(CASE, ["gas.enabled=false"]))
    k = np.arange(60)
    r = 0.6 * (sim._p.tube_radius - sim.model.radius)
    pos = np.stack([0.0006 + 0.0012 * k, r * np.cos(0.3 * k), r * np.sin(0.3 * k)], axis=1)  # touching
    rng = np.random.default_rng(1)
    sim.add_particles(pos, rng.normal(0.0, 0.05, (60, 3)), rng.normal(0.0, 5.0, (60, 3)))
    return sim


def main(stage: str) -> None:
    sim = packing()
    g, n = sim._grains(), int(sim._n[0])
    if stage == "chunked":
        # n = 0: compile only (one thread's Chunks have no spill rows)
        contacts.contact_forces_chunked(g, 0, sim._nbr_start, sim._nbr, sim._p, sim._diag, sim._chunks)
        return
    sim._n[0] = rebuild(g, n, sim._p, sim._neighbors(), sim._counters)
    g, n = sim._grains(), int(sim._n[0])
    contacts.evaluate_contacts(g, n, sim._nbr_start, sim._nbr, sim._nbr_i, sim._p, sim._diag, sim._chunks,
                                sim._pairs)
    print(" ".join(float(v).hex() for v in np.concatenate([g.force[:n].ravel(), g.torque[:n].ravel(),
                                                          sim._diag[:2]])))


if __name__ == "__main__":
    main(sys.argv[1])

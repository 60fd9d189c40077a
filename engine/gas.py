"""Gas pressure field: grid geometry and a thin Python wrapper around engine.kernels.gas (SI units).

`GasField` builds the cell-centred grid, the node volumes of the cut cells and every work array
for a case, then offers deposit / step / drag_forces / pressure_drop for tests and standalone use.
A numba time loop calls the kernels directly with the arrays held here (see docs/gas.md). The
grid's geometry and derived constants are in engine/gas_grid.py; the gas kernels' parameters are
declared in engine/parameters.py.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .case import Case
from .kernels import gas as K
from .gas_grid import (DUMMY_NODES, PHI_MAX, PHI_MIN, QUADRATURE_POINTS, build_geometry,  # noqa: F401
                       cross_section_areas, face_areas, grain_volume, grid_nodes, solid_min)
from .parameters import feed_volume_rate, gas_parameters


class GasField:
    """Relative gas pressure P' (Pa) on a cell-centred grid in the tube, with its coupling to grains.

    The field of a case (default: Case(), the papers' defaults): its grid (grid_nodes), theta
    (gas.theta, used by `step`), feed volume rate (m3/s, m_dot/rho_s of the feed when
    gas.inlet_displaced_volume; settable) and the gas kernels' parameters `g`
    (engine.parameters.gas_parameters), of which `replace` sets some by name over the case's
    (tests and studies: outlet_open=0.0 for the papers' prescribed outflow v_s A at the outlet).
    """

    def __init__(self, case: Case | None = None, **replace):
        case = Case() if case is None else case
        self.nodes = grid_nodes(case)
        nx, ny, nz = self.nodes
        self.theta = case["gas.theta"]
        self._feed_volume_rate = feed_volume_rate(case)
        self.g = gas_parameters(case, **replace)
        self.area, self.ay, self.az = build_geometry(case["tube.length"], self.g.tube_radius, self.nodes)
        shape = self.nodes
        self.pressure = np.zeros(shape)        # P' (Pa); P0 is g.background_pressure
        self.dep = np.zeros(shape + (4,))      # solid volume, solid volume x velocity
        self.phi = np.ones(shape)
        self.kappa = np.zeros(shape)
        self.u = np.zeros(shape + (3,))
        self.src = np.zeros(shape)
        self.nodal = np.zeros(shape + (4,))    # phi, grad P'
        blocks = ny * nz
        self.wmat = np.zeros((nx, blocks, blocks))
        # gas_step uses wvec[0:3]; couple's split scheme reuses it as a (10, max(nodes)) work array
        rows = max(3, -(-10 * max(shape) // (nx * blocks)))
        self.wvec = np.zeros((rows, nx, blocks))
        self.work = np.zeros((10, max(shape)))  # for step(split=True)
        self.update()

    # geometry -------------------------------------------------------------------------------
    @property
    def x(self):
        """Node positions along the tube (m)."""
        nx = self.nodes[0]
        return (np.arange(nx) + 0.5) * self.g.hx

    @property
    def y(self):
        """Node positions across, y (m)."""
        return -self.g.tube_radius + (np.arange(self.nodes[1]) + 0.5) * self.g.hy

    @property
    def z(self):
        """Node positions across, z (m)."""
        return -self.g.tube_radius + (np.arange(self.nodes[2]) + 0.5) * self.g.hz

    @property
    def node_volume(self):
        """Tube volume V_j = int w_j chi_tube dV of each node (m3), shape (nx, ny, nz)."""
        return np.broadcast_to(self.g.hx * self.area, self.nodes).copy()

    # coupling ---------------------------------------------------------------------------------
    @property
    def feed_volume_rate(self):
        """Volume rate m_dot / rho_s of grains entering through the inlet (m3/s)."""
        return self._feed_volume_rate

    @feed_volume_rate.setter
    def feed_volume_rate(self, value):
        self._feed_volume_rate = float(value)
        self.update()

    def arrays(self) -> K.GasArrays:
        """The field's arrays as the kernels take them (`couple`, the grain time loop)."""
        return K.GasArrays(*(getattr(self, name) for name in K.GasArrays._fields))

    def update(self):
        """Recompute phi, kappa, u and the sources from the deposit `dep`."""
        K.update_fields(self.dep, self.area, self.g, self.phi, self.kappa, self.u)
        K.volume_sources(self.u, self.area, self.ay, self.az, self.g, self.feed_volume_rate, self.src)

    def deposit(self, pos, vel=None, n=None):
        """Deposit grains (positions, velocities (n, 3), m and m/s) and refresh phi, kappa, u."""
        pos = np.ascontiguousarray(pos, dtype=float)
        n = len(pos) if n is None else n
        vel = np.zeros_like(pos) if vel is None else np.ascontiguousarray(vel, dtype=float)
        K.deposit(pos, vel, n, self.g, self.dep)
        self.update()

    def set_solid_fraction(self, solid_fraction, velocity=(0.0, 0.0, 0.0)):
        """Impose a solid-fraction field 1 - phi (scalar or (nx, ny, nz)) moving at `velocity` (m/s)."""
        solid = np.asarray(solid_fraction) * self.node_volume
        self.dep[..., 0] = solid
        self.dep[..., 1:] = solid[..., None] * np.asarray(velocity, dtype=float)
        self.update()

    def step(self, dt, substeps=1, split=None):
        """Advance P' by dt (s) in `substeps` equal theta-steps with the current phi, kappa, u.

        split=True uses the papers' dimension-split scheme, False the unsplit one; None the
        field's `scheme`.
        """
        if split is None:
            split = self.g.split > 0.5
        h = dt / substeps
        args = (self.pressure, self.phi, self.kappa, self.src, self.area, self.ay, self.az, self.g, h,
                self.theta)
        for _ in range(substeps):
            if split:
                K.gas_step_split(*args, self.work)
            else:
                K.gas_step(*args, self.wmat, self.wvec)

    def pressure_gradient(self):
        """Node pressure gradient (Pa/m), shape (nx, ny, nz, 3)."""
        K.pressure_gradient(self.pressure, self.phi, self.kappa, self.u, self.g, self.feed_volume_rate,
                            self.nodal)
        return self.nodal[..., 1:]

    def drag_forces(self, pos, n=None):
        """Drag force on each grain (N), shape (n, 3), from the current P' and phi."""
        pos = np.ascontiguousarray(pos, dtype=float)
        n = len(pos) if n is None else n
        out = np.zeros((n, 3))
        self.pressure_gradient()
        K.drag_forces(pos, n, self.nodal, self.g, out, False)
        return out

    def pressure_drop(self):
        """Inlet-face minus outlet-face pressure (Pa)."""
        return K.pressure_drop(self.pressure, self.kappa, self.u, self.area, self.g, self.feed_volume_rate)

    def gas_content(self):
        """sum_j phi_j V_j P'_j (Pa m3), conserved by a step without boundary or grain fluxes."""
        return K.gas_content(self.pressure, self.phi, self.area, self.g)

    def diffusion_number(self, dt):
        """Largest D dt / h^2 over the nodes; D = P0 kappa / (eta phi) (eq. 5), h the finest spacing."""
        h = min(self.g.hx, self.g.hy, self.g.hz)
        d = self.g.background_pressure * self.kappa / (self.g.viscosity * self.phi)
        return float(d.max() * dt / h**2)


def benchmark(repeats=2000, grains=3200, seed=0):
    """Median cost (us) of the gas kernels on the default grid, `grains` grains in the first quarter.

    Each kernel is timed in batches of `repeats` calls from inside a numba loop (no Python
    dispatch), median over 9 batches.
    """
    import numba as nb

    rng = np.random.default_rng(seed)
    f = GasField()
    r = f.g.tube_radius - 0.7e-3
    rad = r * np.sqrt(rng.random(grains))
    ang = 2.0 * math.pi * rng.random(grains)
    pos = np.column_stack([rng.random(grains) * 0.25 * f.g.tube_length, rad * np.cos(ang),
                           rad * np.sin(ang)])
    vel = rng.normal(0.0, 0.05, (grains, 3))
    force = np.zeros((grains, 3))
    f.deposit(pos, vel)

    @nb.njit
    def run(which, reps, theta, pos, vel, force, gas, work):
        g = gas.g
        for _ in range(reps):
            if which == 0:
                K.gas_step(gas.pressure, gas.phi, gas.kappa, gas.src, gas.area, gas.ay, gas.az, g, 1e-5, theta,
                           gas.wmat, gas.wvec)
            elif which == 1:
                K.gas_step_split(gas.pressure, gas.phi, gas.kappa, gas.src, gas.area, gas.ay, gas.az, g, 1e-5,
                                 theta, work)
            elif which == 2:
                K.deposit(pos, vel, len(pos), g, gas.dep)
            elif which == 3:
                K.update_fields(gas.dep, gas.area, g, gas.phi, gas.kappa, gas.u)
                K.volume_sources(gas.u, gas.area, gas.ay, gas.az, g, 0.0, gas.src)
                K.pressure_gradient(gas.pressure, gas.phi, gas.kappa, gas.u, g, 0.0, gas.nodal)
            elif which == 4:
                K.drag_forces(pos, len(pos), gas.nodal, g, force, False)
            else:
                K.couple(pos, vel, len(pos), gas, 1e-5, 1, theta, 0.0, force, False)

    names = ["gas_step", "gas_step_split", "deposit", "fields_sources_gradient", "drag_forces",
             "couple"]
    arrays = (pos, vel, force, f.arrays(), f.work)
    out = {}
    for which, name in enumerate(names):
        run(which, 1, f.theta, *arrays)
        t = []
        for _ in range(9):
            t0 = time.perf_counter()
            run(which, repeats, f.theta, *arrays)
            t.append((time.perf_counter() - t0) / repeats * 1e6)
        out[name + "_us"] = float(np.median(t))
    out["grains"] = grains
    return out


if __name__ == "__main__":
    for key, value in benchmark().items():
        print(f"{key:32s} {value:10.2f}")

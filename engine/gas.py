"""Gas pressure field: grid geometry and a thin Python wrapper around engine.kernels.gas (SI units).

`GasField` builds the cell-centred grid, the node volumes of the cut cells and every work array
for a case, then offers deposit / step / drag_forces / pressure_drop for tests and standalone use.
A numba time loop calls the kernels directly with the arrays held here (see docs/gas.md). The
grid's derived constants that the gas kernels read (grid_nodes, grain_volume, solid_min) are
declared in engine/parameters.py.
"""

from __future__ import annotations

import functools
import math
import time

import numpy as np

from .case import Case
from .kernels import gas as K

QUADRATURE_POINTS = 200_001  # angular midpoint points of the cross-section quadrature
# kappa(0.999) = 1.1e-2 m2 is 3e6 times a plug's; the block elimination then keeps the steady
# state to ~5e-7 (1e4 m2 would lose it entirely), and a grain whose node reads 1 - phi = 1e-3 sees
# a gradient of only eta v_s / kappa = 6e-3 Pa/m at v_s = 1 m/s (docs/gas.md)
PHI_MAX = 0.999
PHI_MIN = 0.2  # porosity floor of over-compressed nodes
DUMMY_NODES = (3, 1, 1)  # the grid of a case without gas: the kernels keep one signature


def _tent_antiderivative(z, m, n, lo, h):
    """Integral from lo to z (m) of the clamped tent weight of node m out of n (spacing h)."""
    if n == 1:
        return z - lo
    s = (z - (lo + (m + 0.5) * h)) / h
    rising = np.where(s <= -1.0, 0.0, 0.5 * (s + 1.0) ** 2)
    falling = 1.0 - 0.5 * (1.0 - np.minimum(s, 1.0)) ** 2
    # the end nodes carry weight 1 between themselves and the tube edge
    below = s + 0.5 if m == 0 else rising
    above = s + 0.5 if m == n - 1 else falling
    return h * np.where(s <= 0.0, below, above)


def cross_section_areas(radius, ny, nz, points=QUADRATURE_POINTS):
    """Tent-weighted tube cross-section of each node line, A_km = int w_k(y) w_m(z) chi_disk (m2).

    Exact in z; in y by the midpoint rule in the angle (y = R sin t), whose integrand is smooth but
    for kinks at the nodes.  Rescaled so that sum A_km = pi R^2 (a round-off-level correction).
    """
    return _cross_section_areas(float(radius), int(ny), int(nz), int(points)).copy()


@functools.lru_cache(maxsize=16)
def _cross_section_areas(radius, ny, nz, points):
    hy = 2.0 * radius / ny
    hz = 2.0 * radius / nz
    t = (np.arange(points) + 0.5) / points * math.pi - 0.5 * math.pi
    y = radius * np.sin(t)
    c = radius * np.cos(t)
    jac = radius * np.cos(t) * (math.pi / points)
    area = np.empty((ny, nz))
    for k in range(ny):
        wk = _tent_weight(y, k, ny, -radius, hy)
        for m in range(nz):
            span = (_tent_antiderivative(c, m, nz, -radius, hz)
                    - _tent_antiderivative(-c, m, nz, -radius, hz))
            area[k, m] = np.sum(wk * span * jac)
    area *= math.pi * radius**2 / area.sum()
    return area


def _tent_weight(y, k, n, lo, h):
    """Clamped tent weight (eq. 7) of node k out of n at coordinates y (m)."""
    if n == 1:
        return np.ones_like(y)
    s = (y - (lo + (k + 0.5) * h)) / h
    w = np.maximum(1.0 - np.abs(s), 0.0)
    if k == 0:
        w = np.where(s <= 0.0, 1.0, w)
    if k == n - 1:
        w = np.where(s >= 0.0, 1.0, w)
    return w


def _chord(face, lo_cell, hi_cell, radius):
    """Length (m) of the segment [lo_cell, hi_cell] inside the disk along the line at `face` (m)."""
    c = math.sqrt(max(radius**2 - face**2, 0.0))
    return max(0.0, min(hi_cell, c) - max(lo_cell, -c))


def face_areas(length, radius, nx, ny, nz):
    """Areas (m2) of the transverse faces inside the tube: ay (ny-1, nz) and az (ny, nz-1)."""
    hx = length / nx
    hy = 2.0 * radius / ny
    hz = 2.0 * radius / nz
    ay = np.zeros((max(ny - 1, 0), nz))
    az = np.zeros((ny, max(nz - 1, 0)))
    for k in range(ny - 1):
        for m in range(nz):
            z_lo = -radius + m * hz
            ay[k, m] = hx * _chord(-radius + (k + 1) * hy, z_lo, z_lo + hz, radius)
    for k in range(ny):
        for m in range(nz - 1):
            y_lo = -radius + k * hy
            az[k, m] = hx * _chord(-radius + (m + 1) * hz, y_lo, y_lo + hy, radius)
    return ay, az


def build_geometry(length, radius, nodes):
    """(area, ay, az): node-line cross-sections and transverse face areas of an (nx, ny, nz) grid."""
    nx, ny, nz = nodes
    return cross_section_areas(radius, ny, nz), *face_areas(length, radius, nx, ny, nz)


def grid_nodes(case: Case) -> tuple[int, int, int]:
    """Nodes (nx, ny, nz) of the case's gas grid; DUMMY_NODES when the gas is off."""
    if not case["gas.enabled"]:
        return DUMMY_NODES
    return case["gas.nodes_x"], case["gas.nodes_y"], case["gas.nodes_z"]


def grain_volume(case: Case) -> float:
    """V_p = pi d^3/6, m3."""
    return math.pi * case["particles.diameter"] ** 3 / 6.0


def solid_min(case: Case) -> float:
    """Floor of 1 - phi_i in the drag: V_p / (8 max V_j), what one deposited grain reads (V_j the
    largest node's tube volume)."""
    nx, ny, nz = grid_nodes(case)
    hx = case["tube.length"] / nx
    return grain_volume(case) / (8.0 * hx * cross_section_areas(case["tube.diameter"] / 2, ny, nz).max())


class GasField:
    """Relative gas pressure P' (Pa) on a cell-centred grid in the tube, with its coupling to grains.

    The field of a case (default: Case(), the papers' defaults): its grid (grid_nodes), theta
    (gas.theta, used by `step`), feed volume rate (m3/s, m_dot/rho_s of the feed when
    gas.inlet_displaced_volume; settable) and the gas kernels' parameters `g`
    (engine.parameters.gas_parameters), of which `replace` sets some by name over the case's
    (tests and studies: outlet_open=0.0 for the papers' prescribed outflow v_s A at the outlet).
    """

    def __init__(self, case: Case | None = None, **replace):
        from .parameters import feed_volume_rate, gas_parameters  # it imports this module's grid constants

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

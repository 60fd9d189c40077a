"""The gas grid's geometry and the constants derived from it (SI units): node-line cross-sections
and transverse face areas of the cut cells (eq. 8's volumes), the grid of a case, the grain volume
and the drag's floor of 1 - phi. engine.gas builds its field on them; engine.parameters declares
the derived ones as the gas kernels' parameters.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .case import Case

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

"""The grain feed: a piston of pre-packed layers pushed into the tube at the entry velocity u_in.

Each layer is a ring packing of the cross-section (19 grains for d = 1.4 mm in D = 7 mm), turned by
a random angle; layers follow each other at the spacing s that makes the mass flow exact:
m_dot = N_layer m u_in / s. Feed grains move kinematically and are released into the dynamics once
fully inside the tube (centre at x >= r). The piston never pauses: the mass flow is enforced, as
in the papers; its push on the grains is recorded (piston_force), and a tube that cannot take the
feed (the piston presses a grain by more than feed.max_overlap, or the column it pushes passes the
run guard's overlap, engine.run.feed_wedged) ends the run as blocked.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .case import Case, CaseError

GAP = 0.01  # clearance between template grains and to the wall, fraction of d


def _ring(radius: float, d: float, offset: float) -> np.ndarray:
    """As many points as fit at distance >= (1 + GAP) d on a circle of this radius."""
    if radius < 1e-12:
        return np.zeros((1, 2))
    ratio = (1 + GAP) * d / (2 * radius)
    if ratio > 1:
        return np.zeros((0, 2))
    count = int(math.floor(math.pi / math.asin(ratio) + 1e-9))
    angles = offset + 2 * math.pi * np.arange(count) / count
    return radius * np.column_stack([np.cos(angles), np.sin(angles)])


def _min_distance(points: np.ndarray) -> float:
    if len(points) < 2:
        return math.inf
    diff = points[:, None, :] - points[None, :, :]
    dist = np.sqrt((diff**2).sum(-1))
    return dist[np.triu_indices(len(points), 1)].min()


@functools.lru_cache(maxsize=16)
def layer_template(tube_radius: float, d: float) -> np.ndarray:
    """(y, z) centres of one densely packed cross-section layer (concentric rings), shape (k, 2).

    Searches ring spacings and relative ring rotations for the largest non-overlapping set; all
    centres lie within tube_radius - d/2 - GAP d.
    """
    outer = tube_radius - d / 2 - GAP * d
    if outer < 0:
        raise CaseError("tube.diameter must exceed particles.diameter for the feed to fit")
    best = np.zeros((1, 2))
    for spacing in np.linspace(0.85, 1.15, 31) * d:
        points = np.zeros((0, 2))
        radius = outer
        while radius > -1e-12:
            if radius < (1 + GAP) * d / 2:  # no pair fits on this ring: try a single centre grain
                radius = 0.0
            candidates = [_ring(radius, d, off) for off in np.linspace(0, math.pi, 16, endpoint=False)]
            ok = [np.vstack([points, c]) for c in candidates
                  if len(c) and _min_distance(np.vstack([points, c])) >= (1 + GAP / 2) * d]
            if ok:
                points = max(ok, key=lambda q: _min_distance(q))
            if radius == 0.0:
                break
            radius -= spacing
        if len(points) > len(best):
            best = points
    return best


class Feed:
    """Feed geometry and clock for one case (mass flow, entry velocity, layer spacing)."""

    def __init__(self, case: Case, mass: float, seed: int):
        d = case["particles.diameter"]
        self.mass_flow = case["feed.mass_flow_kg_h"] / 3600.0  # kg/s
        self.entry_velocity = case["feed.entry_velocity"]
        self.enabled = self.mass_flow > 0
        self.template = layer_template(case["tube.diameter"] / 2, d)
        self.layer_mass = len(self.template) * mass
        self.spacing = (self.layer_mass * self.entry_velocity / self.mass_flow) if self.enabled else math.inf
        self._rng = np.random.default_rng(seed)
        self.d = d
        self.tube_radius = case["tube.diameter"] / 2
        if self.enabled and self.spacing < (1 + GAP) * d:
            need = (1 + GAP) * d * self.mass_flow / self.layer_mass
            raise CaseError(
                f"feed.mass_flow_kg_h = {case['feed.mass_flow_kg_h']:g} cannot be packed at "
                f"feed.entry_velocity = {self.entry_velocity:g} m/s (layers of {len(self.template)} grains "
                f"would be {self.spacing / d:.2f} d apart, less than one diameter); use "
                f"feed.entry_velocity >= {need:.3g} m/s or a smaller mass flow")

    @property
    def solid_fraction(self) -> float:
        """Volume fraction of grains in the packed feed (1 - inlet porosity)."""
        volume = len(self.template) * math.pi * self.d**3 / 6
        return volume / (math.pi * self.tube_radius**2 * self.spacing)

    def layer(self, x: float) -> np.ndarray:
        """Positions (k, 3) of a new layer at axial position x, turned by a random angle."""
        angle = self._rng.uniform(0, 2 * math.pi)
        c, s = math.cos(angle), math.sin(angle)
        yz = self.template @ np.array([[c, s], [-s, c]])
        return np.column_stack([np.full(len(yz), x), yz])

"""What the kernels read: each parameter of the grain kernels (`GRAIN`, the named tuple `p`) and of
the gas kernels (`GAS`, the named tuple `g`), declared once, as a case key taken as it is or as a
constant derived from the case by one function.

The kernels read a parameter by the name declared here (`p.friction_pair`,
`g.superficial_velocity`); `grain_parameters(case)` and `gas_parameters(case)` build the named
tuples from these declarations, and nothing else does: a named tuple has a field for each
declaration and no other, and every value is checked to be a finite number, so a parameter
nobody fills cannot exist. Values are float64 in SI units; a switch is 1.0 (on) or 0.0 (off).
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass
from typing import Callable

from . import contact, gas_grid
from .case import KEYS, Case

BLOCK_TRAVEL = 0.02  # piston travel (fraction of d) beyond feed.max_overlap that makes a tube blocked


@dataclass(frozen=True)
class Parameter:
    """One kernel parameter: its name in the kernels, where its value comes from (a case key taken
    as it is, or the function of the case that derives it), its unit and meaning."""

    name: str
    source: str | Callable[[Case], float]
    unit: str
    doc: str

    def value(self, case: Case) -> float:
        """The value for this case, as a float (ValueError naming the parameter if it is not a finite
        number)."""
        return _number(self.name, case[self.source] if isinstance(self.source, str) else self.source(case),
                       self.origin)

    @property
    def origin(self) -> str:
        """The case key, or the deriving function's module and name."""
        if isinstance(self.source, str):
            return self.source
        return f"{self.source.__module__}.{self.source.__qualname__}"


def _number(name: str, raw, origin: str) -> float:
    if isinstance(raw, str) or not math.isfinite(raw):
        raise ValueError(f"kernel parameter {name} = {raw!r} (from {origin}) is not a finite number")
    return float(raw)


# ---- derived constants that belong to no model part (those of the contact law are in
# engine/contact.py, those of the gas grid in engine/gas_grid.py) ---------------------------------
def tube_radius(case: Case) -> float:
    """R = D/2, m."""
    return case["tube.diameter"] / 2


def gravity(case: Case) -> tuple[float, float, float]:
    """Gravity vector (m/s2) from the inclination: 0 deg -> -z, 90 deg -> -x."""
    theta = math.radians(case["tube.inclination_deg"])
    g = case["physics.gravity"]
    return -g * math.sin(theta), 0.0, -g * math.cos(theta)


def feed_speed(case: Case) -> float:
    """Speed of the feed piston u_in, m/s; 0 without a feed."""
    return case["feed.entry_velocity"] if case["feed.mass_flow_kg_h"] > 0 else 0.0


def feed_block_steps(case: Case) -> float:
    """Consecutive steps of the piston pressing a grain beyond feed.max_overlap that make the tube
    blocked. A jammed tube keeps the piston pressing while it advances; a numerical blow-up near
    the feed is a spike. Blocked means pressing for as long as the piston takes to advance
    BLOCK_TRAVEL d, long enough for a blow-up to trip the other guards first."""
    speed = feed_speed(case)
    if speed <= 0:
        return 1
    return math.ceil(BLOCK_TRAVEL * case["particles.diameter"] / (speed * contact.time_step(case)))


def feed_volume_rate(case: Case) -> float:
    """m_dot / rho_s of the feed when gas.inlet_displaced_volume, m3/s (the volume of the entering
    grains joins the inlet gas flux), else 0."""
    if case["feed.mass_flow_kg_h"] > 0 and case["gas.inlet_displaced_volume"]:
        return case["feed.mass_flow_kg_h"] / 3600.0 / case["particles.density"]
    return 0.0


def neighbor_skin(case: Case) -> float:
    """Verlet skin of the neighbour list, m."""
    return case["numerics.neighbor_skin"] * case["particles.diameter"]


def cell_x0(case: Case) -> float:
    """Lower x edge of the cell grid, m (two diameters before the inlet: the feed piston's grains)."""
    return -2 * case["particles.diameter"]


def cell_counts(case: Case) -> tuple[int, int, int]:
    """Cells of the grid along x, y and z: as many as fit cells no smaller than the list cutoff
    d + skin."""
    d, length, diameter = case["particles.diameter"], case["tube.length"], case["tube.diameter"]
    cut = d + neighbor_skin(case)
    across = max(1, int(diameter / cut))
    return max(1, int((length + 2 * d - cell_x0(case)) / cut)), across, across


def cell_dx(case: Case) -> float:
    """Cell size along x, m."""
    return (case["tube.length"] + 2 * case["particles.diameter"] - cell_x0(case)) / cell_counts(case)[0]


def cell_dyz(case: Case) -> float:
    """Cell size across (y and z), m."""
    return case["tube.diameter"] / cell_counts(case)[1]


def rotation(case: Case) -> float:
    """1.0 when the grains can spin up: rotation only matters through tangential forces, so
    frictionless grains, or grains without a tangential dashpot, are not rotated."""
    rotates = ((case["particles.friction"] > 0 or case["wall.friction"] > 0)
               and case["particles.tangential_damping"] > 0)
    return 1.0 if rotates else 0.0


# ---- the declarations ------------------------------------------------------------------------------
# The grain kernels' p (engine/kernels/: laws, contacts, neighbors, stepper)
GRAIN = (
    Parameter("dt", contact.time_step, "s", "time step"),
    Parameter("mass", contact.grain_mass, "kg", "grain mass m"),
    Parameter("radius", contact.grain_radius, "m", "grain radius r"),
    Parameter("inertia", contact.grain_inertia, "kg m2", "moment of inertia I = 2/5 m r^2"),
    Parameter("stiffness", "particles.stiffness", "N/m", "normal stiffness k_n, grain-grain and grain-wall"),
    Parameter("damping_pair", contact.damping_pair, "N s/m", "normal damping gamma_n grain-grain"),
    Parameter("damping_wall", contact.damping_wall, "N s/m", "normal damping gamma_n grain-wall"),
    Parameter("tangential_damping_pair", contact.tangential_damping_pair, "N s/m",
              "tangential damping gamma_t grain-grain, capped at (m/7)/dt"),
    Parameter("tangential_damping_wall", contact.tangential_damping_wall, "N s/m",
              "tangential damping gamma_t grain-wall, capped at (2m/7)/dt"),
    Parameter("friction_pair", "particles.friction", "1", "Coulomb coefficient mu grain-grain"),
    Parameter("friction_wall", "wall.friction", "1", "Coulomb coefficient mu grain-wall"),
    Parameter("rolling_resistance", "particles.rolling_resistance", "1",
              "rolling-resistance coefficient mu_r (0: off)"),
    Parameter("implicit_spin", "numerics.implicit_spin", "switch",
              "spin kicks scaled by 1/(1 + dt sum(gamma_t) r^2/I) of the viscous contacts"),
    Parameter("rotation", rotation, "switch", "integrate rotation (off: no tangential forces)"),
    Parameter("tube_radius", tube_radius, "m", "tube radius R"),
    Parameter("tube_length", "tube.length", "m", "tube length L: grains past it leave"),
    Parameter("gravity_x", lambda case: gravity(case)[0], "m/s2", "gravity along x"),
    Parameter("gravity_y", lambda case: gravity(case)[1], "m/s2", "gravity along y"),
    Parameter("gravity_z", lambda case: gravity(case)[2], "m/s2", "gravity along z"),
    Parameter("feed_speed", feed_speed, "m/s", "feed piston speed u_in (0: no feed)"),
    Parameter("feed_max_overlap", lambda case: case["feed.max_overlap"] * case["particles.diameter"], "m",
              "the tube is blocked when the piston presses a grain deeper than this"),
    Parameter("feed_block_steps", feed_block_steps, "1",
              "consecutive steps above feed_max_overlap that make the tube blocked"),
    Parameter("feed_volume_rate", feed_volume_rate, "m3/s", "gas displaced by the entering grains"),
    Parameter("skin", neighbor_skin, "m", "Verlet skin"),
    Parameter("cell_x0", cell_x0, "m", "lower x edge of the cell grid"),
    Parameter("cell_dx", cell_dx, "m", "cell size along x"),
    Parameter("cell_dyz", cell_dyz, "m", "cell size across"),
    Parameter("gas_on", "gas.enabled", "switch", "couple the gas every gas_interval steps"),
    Parameter("gas_interval", "numerics.gas_interval", "1", "grain steps per gas update"),
    Parameter("gas_theta", "gas.theta", "1", "theta of the gas time scheme"),
)

# The gas kernels' g (engine/kernels/gas.py)
GAS = (
    Parameter("tube_length", "tube.length", "m", "tube length L"),
    Parameter("tube_radius", tube_radius, "m", "tube radius R"),
    Parameter("tube_area", lambda case: math.pi * tube_radius(case) ** 2, "m2", "tube cross-section A = pi R^2"),
    Parameter("hx", lambda case: case["tube.length"] / gas_grid.grid_nodes(case)[0], "m", "node spacing along x"),
    Parameter("hy", lambda case: case["tube.diameter"] / gas_grid.grid_nodes(case)[1], "m", "node spacing along y"),
    Parameter("hz", lambda case: case["tube.diameter"] / gas_grid.grid_nodes(case)[2], "m", "node spacing along z"),
    Parameter("grain_volume", gas_grid.grain_volume, "m3", "grain volume V_p"),
    Parameter("grain_diameter", "particles.diameter", "m", "grain diameter d (Carman-Kozeny)"),
    Parameter("background_pressure", "gas.pressure", "Pa", "background pressure P0"),
    Parameter("viscosity", "gas.viscosity", "Pa s", "gas viscosity eta"),
    Parameter("superficial_velocity", "gas.superficial_velocity", "m/s", "superficial gas velocity v_s"),
    Parameter("porosity_max", "gas.porosity_max", "1", "porosity ceiling inside kappa only (a numerical guard)"),
    Parameter("porosity_min", lambda case: gas_grid.PHI_MIN, "1", "porosity floor of over-compressed nodes"),
    Parameter("solid_min", gas_grid.solid_min, "1", "floor of 1 - phi_i in the drag: what one deposited grain reads"),
    Parameter("outlet_open", lambda case: 1.0, "switch",
              "outlet face held at P' = 0 (off: the papers' prescribed outflow v_s A)"),
    Parameter("face_arithmetic", lambda case: float(case["gas.face_permeability"] == "arithmetic"), "switch",
              "face permeability the arithmetic mean of the two nodes' (off: harmonic)"),
    Parameter("cell_volume", lambda case: float(case["gas.deposit_volume"] == "cell"), "switch",
              "deposit normalised by the grid cell hx hy hz (off: the node's tube volume)"),
    Parameter("split", lambda case: float(case["gas.scheme"] == "split"), "switch",
              "dimension-split theta scheme in couple (off: unsplit)"),
)

GrainParameters = namedtuple("GrainParameters", [q.name for q in GRAIN])
GasParameters = namedtuple("GasParameters", [q.name for q in GAS])


def grain_parameters(case: Case) -> GrainParameters:
    """The grain kernels' parameters for this case."""
    return GrainParameters(**{q.name: q.value(case) for q in GRAIN})


def gas_parameters(case: Case, **replace: float) -> GasParameters:
    """The gas kernels' parameters for this case; `replace` sets values by name over the case's
    (tests and studies, e.g. outlet_open=0.0 for the papers' prescribed outflow)."""
    unknown = sorted(set(replace) - set(GasParameters._fields))
    if unknown:
        raise ValueError(f"the gas kernels have no parameter {unknown[0]!r} (engine/parameters.py declares them)")
    values = {q.name: q.value(case) for q in GAS}
    values.update({name: _number(name, value, "replace") for name, value in replace.items()})
    return GasParameters(**values)


def _check_declarations() -> None:
    """Every case key named here exists (a misspelt key fails on import, not in a run)."""
    for q in GRAIN + GAS:
        if isinstance(q.source, str) and q.source not in KEYS:
            raise KeyError(f"kernel parameter {q.name} reads the unknown case key {q.source!r}")


_check_declarations()

"""Case configuration: every key, its unit, default and allowed range; YAML loading and dotted overrides.

A case is a flat mapping ``"section.key" -> value``. It is validated completely on construction, so
bad input is refused before any work, with a message naming the key and the allowed range.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping

import yaml


class CaseError(ValueError):
    """A case configuration that cannot be run (unknown key, wrong type, value out of range)."""


@dataclass(frozen=True)
class Key:
    """One configuration key: meaning, unit, default and allowed range (inclusive unless noted)."""

    name: str
    default: Any
    unit: str
    doc: str
    kind: type = float
    low: float | None = None
    high: float | None = None
    low_open: bool = False  # True: value must be > low (not >=)
    choices: tuple = ()

    def allowed(self) -> str:
        """Human-readable allowed range."""
        if self.kind is bool:
            return "true or false"
        if self.choices:
            return "one of " + ", ".join(map(str, self.choices))
        lo = "" if self.low is None else f"{self.low:g} {'<' if self.low_open else '<='} "
        hi = "" if self.high is None else f" <= {self.high:g}"
        return f"{lo}value{hi}"

    def check(self, value: Any) -> Any:
        """Return the value converted to the key's type, or raise CaseError naming the key."""
        value = self._convert(value)
        if self.choices and value not in self.choices:
            raise CaseError(f"{self.name} = {value!r} is not allowed: {self.allowed()}")
        if self.kind in (int, float):
            if not math.isfinite(value):
                raise CaseError(f"{self.name} = {value!r} is not finite: allowed {self.allowed()}")
            too_low = self.low is not None and (value <= self.low if self.low_open else value < self.low)
            too_high = self.high is not None and value > self.high
            if too_low or too_high:
                raise CaseError(
                    f"{self.name} = {value!r} is out of range: allowed {self.allowed()}"
                    f" ({self.doc.split('. ')[0].rstrip('.')}, {self.unit})")
        return value

    def _convert(self, value: Any) -> Any:
        if self.kind is bool:
            if isinstance(value, bool):
                return value
            raise CaseError(f"{self.name} = {value!r} must be true or false")
        if self.kind is int:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or int(value) != value:
                raise CaseError(f"{self.name} = {value!r} must be an integer: allowed {self.allowed()}")
            return int(value)
        if self.kind is float:
            if isinstance(value, str):  # PyYAML (YAML 1.1) reads 1e-9, without a dot, as a string
                try:
                    value = float(value)
                except ValueError:
                    pass
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise CaseError(f"{self.name} = {value!r} must be a number ({self.unit}): "
                                f"allowed {self.allowed()}")
            return float(value)
        if not isinstance(value, self.kind):
            raise CaseError(f"{self.name} = {value!r} must be a {self.kind.__name__}: allowed {self.allowed()}")
        return value


# The papers' defaults (both papers, §3): L = 0.525 m, D = 7 mm, d = 1.4 mm, rho_s = 937 kg/m3,
# mu = 0.5, e = 0.5, P0 = 1013.25 hPa, eta = 0.0673 cP, v_s = 1 m/s, feed 2.49 kg/h at 0.04 m/s.
KEYS: dict[str, Key] = {k.name: k for k in [
    Key("tube.length", 0.525, "m", "Tube length L; x runs from the inlet (0) to the outlet (L).",
        low=0.0, low_open=True, high=100.0),
    Key("tube.diameter", 0.007, "m", "Inner tube diameter D.", low=0.0, low_open=True, high=1.0),
    Key("tube.inclination_deg", 0.0, "degree",
        "Tube inclination from horizontal: 0 = horizontal (gravity along -z), 90 = vertical "
        "(gravity along -x, flow upward).", low=0.0, high=90.0),
    Key("physics.gravity", 9.81, "m s-2", "Gravitational acceleration g.", low=0.0, high=1000.0),
    Key("particles.diameter", 0.0014, "m", "Grain diameter d (monodisperse spheres); must be < D/2.",
        low=0.0, low_open=True, high=1.0),
    Key("particles.density", 937.0, "kg m-3", "Grain material density rho_s.",
        low=0.0, low_open=True, high=1e5),
    Key("particles.friction", 0.5, "1", "Coulomb coefficient mu between grains.", low=0.0, high=10.0),
    Key("particles.restitution", 0.5, "1",
        "Normal restitution coefficient e of a head-on grain-grain collision (the normal damping "
        "is calibrated so that the measured e equals this value; the non-attractive spring-dashpot "
        "cannot go below 0.15).", low=0.15, high=1.0),
    Key("particles.stiffness", 2000.0, "N m-1", "Normal spring constant k_n (grain-grain and grain-wall).",
        low=0.0, low_open=True, high=1e9),
    Key("particles.tangential_damping", 0.02, "N s m-1",
        "Tangential viscous coefficient gamma_t of F_t = -min(mu|F_n|, gamma_t|v_t|); sets how fast "
        "slowly slipping contacts creep. Used as min(gamma_t, m/(7 dt)) between grains and "
        "min(gamma_t, 2m/(7 dt)) at the wall, so that the explicit dashpot cannot reverse a slip "
        "(the cap lies above gamma_t at the default step). A packed bed needs gamma_t dt/(m/7) <= "
        "0.47 or numerics.implicit_spin (docs/performance.md).",
        low=0.0, high=1e3),
    Key("particles.rolling_resistance", 0.0, "1",
        "Rolling-resistance coefficient mu_r: each contact (grain-grain and grain-wall) exerts a "
        "torque -min(mu_r r F_n, I_rel |w_rel|/dt) w_rel/|w_rel| against the relative spin w_rel "
        "(I_rel = I/2 between grains, I at the wall: one step cannot reverse the spin). Not part of "
        "the papers' model; 0 switches it off.", low=0.0, high=1.0),
    Key("wall.friction", 0.5, "1", "Coulomb coefficient mu_w between grains and the tube wall.",
        low=0.0, high=10.0),
    Key("wall.restitution", 0.5, "1", "Normal restitution coefficient of a head-on grain-wall impact.",
        low=0.15, high=1.0),
    Key("feed.mass_flow_kg_h", 2.49, "kg h-1",
        "Grain mass flow m_dot enforced at the inlet (0 switches the feed off).", low=0.0, high=1e4),
    Key("feed.entry_velocity", 0.04, "m s-1",
        "Speed u_in of the feed piston that pushes grains into the tube; the feed is refused when "
        "m_dot cannot be packed at this speed.", low=0.0, low_open=True, high=100.0),
    Key("feed.max_overlap", 0.15, "1",
        "Largest overlap (fraction of d) the feed piston may press into a grain ahead. The piston "
        "never pauses (the papers' enforced mass flow); pressing deeper means the tube cannot take "
        "the feed, and the run ends with stop_reason blocked. The default is the largest value "
        "below the run guard of 0.2 d (docs/decisions/0019-feed-block-overlap.md).",
        low=0.0, low_open=True, high=0.15),
    Key("gas.enabled", True, "", "Solve the gas pressure field and apply drag (false: pure grains).",
        kind=bool),
    Key("gas.superficial_velocity", 1.0, "m s-1", "Superficial gas velocity v_s = gas flow / A.",
        low=0.0, high=100.0),
    Key("gas.viscosity", 6.73e-5, "Pa s", "Effective dynamic gas viscosity eta (0.0673 cP).",
        low=0.0, low_open=True, high=1.0),
    Key("gas.pressure", 101325.0, "Pa", "Background (atmospheric) pressure P0.",
        low=0.0, low_open=True, high=1e8),
    Key("gas.nodes_x", 150, "1", "Gas grid nodes along the tube.", kind=int, low=3, high=100000),
    Key("gas.nodes_y", 2, "1", "Gas grid nodes across the tube (y).", kind=int, low=1, high=64),
    Key("gas.nodes_z", 2, "1", "Gas grid nodes across the tube (z).", kind=int, low=1, high=64),
    Key("gas.theta", 1.0, "1",
        "Implicitness of the gas time scheme (1 = backward Euler, 0.5 = Crank-Nicolson); below 1 the "
        "stiff dilute-cell modes flip sign every step (docs/gas.md).", low=0.5, high=1.0),
    Key("gas.face_permeability", "arithmetic", "",
        "Permeability on a face between two gas nodes in the discretised eq. (5): the arithmetic "
        "mean of the two nodes' kappa or their harmonic mean (two half cells in series); the "
        "papers do not say (choice: docs/decisions/0018-gas-discretisation-readings.md).",
        kind=str, choices=("harmonic", "arithmetic")),
    Key("gas.scheme", "split", "",
        "Gas time scheme: one theta solve per dimension in turn (split: the papers' 'each "
        "dimension is integrated separately') or the theta scheme on the whole 3-D operator "
        "(unsplit, whose fixed point is the steady state of eq. (5)); where the porosity varies "
        "across the tube the split's steady state depends on the gas step (docs/gas.md).",
        kind=str, choices=("unsplit", "split")),
    Key("gas.deposit_volume", "tube", "",
        "Volume that normalises the eq. (8) deposit into a node porosity: the node's share of the "
        "tube (tube) or the whole cubic grid cell hx hy hz (cell: the cells overhang the round "
        "tube, so a packing reads a higher porosity).", kind=str, choices=("tube", "cell")),
    Key("gas.inlet_displaced_volume", False, "",
        "Add the volume of the entering grains (m_dot / rho_s) to the inlet gas flux v_s A "
        "(false: the inlet carries the gas flux alone, the papers' source S ~ v_g P0).",
        kind=bool),
    Key("gas.porosity_max", 0.999, "1",
        "Ceiling of the porosity inside the Carman-Kozeny permeability only (a numerical guard: "
        "kappa diverges at phi = 1, and the gas solve loses accuracy beyond a contrast of ~1e10 "
        "to a plug's kappa).", low=0.9, high=0.99999),
    Key("numerics.gas_interval", 10, "1",
        "Grain steps per gas update (the drag is held in between); 1 = every step.", kind=int,
        low=1, high=10000),
    Key("numerics.time_step_fraction", 0.15, "1",
        "Time step as a fraction of the grain-grain contact time t_c (rounded down to divide "
        "output.interval); refused above the stable limit.",
        low=0.0, low_open=True, high=10.0),
    Key("numerics.implicit_spin", True, "",
        "Take the tangential dashpots' action on a grain's own spin implicitly, so that a packed bed's "
        "spins do not chatter when gamma_t dt/(m/7) > 0.47 (false: the papers' explicit law, whose "
        "packed beds then carry a time-step error); the split of a sticking impulse between spin "
        "and translation is then not exact (docs/decisions/0006-implicit-spin-kick.md).", kind=bool),
    Key("numerics.time_step_safety", 0.6, "1",
        "Fraction of the single-pair stability limit a time step may reach: packed columns have "
        "faster modes than one pair (docs/decisions/0002-time-step-safety-margin.md); 1 accepts the "
        "pair limit itself.",
        low=0.0, low_open=True, high=1.0),
    Key("numerics.neighbor_skin", 0.3, "1",
        "Verlet skin of the neighbour list, as a fraction of d (the list is rebuilt when a grain has "
        "moved half of it); results do not depend on it, only the cost (docs/performance.md).",
        low=0.0, low_open=True, high=2.0),
    Key("run.seed", 0, "1", "Seed of the random numbers (feed layer orientations).", kind=int,
        low=0, high=2**31 - 1),
    Key("run.duration", 5.0, "s",
        "Simulated time to run; with run.until_steady the largest time allowed.", low=0.0,
        low_open=True, high=1e5),
    Key("run.until_steady", False, "",
        "Stop once the tube has filled, the mean pressure drop has converged and the tube neither "
        "fills nor drains: the mass leaving equals the mass fed (see run.steady_*, docs/engine.md).",
        kind=bool),
    Key("run.steady_settle", 1.0, "s",
        "Time after the first grains leave the tube that is discarded before averaging.",
        low=0.0, high=1e4),
    Key("run.steady_min_window", 2.0, "s",
        "Shortest averaging window before a steady stop; candidate windows open every half of it.",
        low=0.0, low_open=True, high=1e4),
    Key("run.steady_rel_error", 0.03, "1",
        "Steady when the standard error of the mean pressure drop over the window (from its "
        "integrated autocorrelation time, analysis.timeseries.mean_error) is below this fraction "
        "of the mean (unless run.steady_pressure_drop_error is set; 1 asks nothing of it but "
        "convergence).", low=0.0, low_open=True, high=1.0),
    Key("run.steady_pressure_drop_error", 0.0, "Pa m-1",
        "When > 0: steady only when the standard error of the mean pressure drop per tube length "
        "is at most this, instead of run.steady_rel_error of the mean: the precision a statement "
        "asks (half its tolerance, e.g. 25 Pa/m for +-0.5 hPa/m; "
        "benchmarks/studies/run_lengths.py). 0: the relative error decides.",
        low=0.0, high=1e6),
    Key("run.steady_n_particles_error", 0.0, "1",
        "When > 0: steady only when the standard error of the mean number of grains in the tube "
        "over the window is at most this as well (e.g. 25 for a count quoted +-50). 0: no "
        "precision asked of it beyond the hold-up test.", low=0.0, high=1e9),
    Key("run.steady_min_correlation_times", 50.0, "1",
        "Steady only when the window covers at least this many integrated autocorrelation times "
        "of the pressure drop, the mass flows and the grains in the tube; the analysis gives no "
        "error for a shorter window (docs/analysis.md).",
        low=10.0, high=1e4),
    Key("run.checkpoint_interval", 120.0, "s (wall)",
        "Wall-clock seconds between checkpoints of a running case (0: none periodic; Ctrl-C and "
        "SIGTERM still write one).", low=0.0, high=1e6),
    Key("run.progress_interval", 60.0, "s (wall)",
        "Wall-clock seconds between the progress lines of a run whose output is not a terminal (a "
        "log file, a workflow job; 0: one per output frame). A terminal shows a progress bar instead.",
        low=0.0, high=1e6),
    Key("run.warm_start_any", False, "",
        "Accept a warm start (--initial-state) from a case file of another tube length or "
        "inclination: grains beyond this tube's length are dropped, gravity turns, and the run logs "
        "what changed (false: refused). Another tube diameter or grain is refused regardless.",
        kind=bool),
    Key("output.interval", 0.01, "s", "Simulated time between output frames (time series and slices).",
        low=0.0, low_open=True, high=100.0),
    Key("output.slice_width", 0.0035, "m", "Width of the slices along the tube for slice fields.",
        low=0.0, low_open=True, high=1.0),
    Key("output.snapshots", False, "", "Write grain snapshots (positions, velocities) in a window.",
        kind=bool),
    Key("output.snapshot_x_min", 0.2, "m", "Lower x of the snapshot window.", low=0.0, high=100.0),
    Key("output.snapshot_x_max", 0.32, "m", "Upper x of the snapshot window.", low=0.0, high=100.0),
    Key("output.snapshot_t_min", 0.0, "s", "Time from which snapshots are written.", low=0.0, high=1e5),
    Key("output.snapshot_interval", 0.01, "s",
        "Simulated time between snapshots (a multiple of output.interval).", low=0.0, low_open=True,
        high=100.0),
    Key("output.tube_snapshot_interval", 0.0, "s",
        "Simulated time between snapshots of every grain in the tube (positions, velocities, angular "
        "velocities) for `plugsim export` and `plugsim animate`; 0 = none. A multiple of "
        "output.interval.", low=0.0, high=100.0),
]}


def defaults() -> dict[str, Any]:
    """All keys at their default values."""
    return {name: key.default for name, key in KEYS.items()}


def flatten(nested: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested YAML mapping -> flat dotted keys (a section must be a mapping)."""
    flat: dict[str, Any] = {}
    for name, value in nested.items():
        dotted = f"{prefix}{name}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, dotted + "."))
        else:
            flat[dotted] = value
    return flat


def unflatten(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Flat dotted keys -> nested mapping (for writing YAML)."""
    nested: dict[str, Any] = {}
    for dotted, value in flat.items():
        *sections, leaf = dotted.split(".")
        node = nested
        for section in sections:
            node = node.setdefault(section, {})
        node[leaf] = value
    return nested


def parse_override(text: str) -> tuple[str, Any]:
    """'particles.friction=0.1' -> ('particles.friction', 0.1); the value is read as YAML."""
    if "=" not in text:
        raise CaseError(f"override {text!r} must look like key.path=value")
    name, raw = text.split("=", 1)
    try:
        return name.strip(), yaml.safe_load(raw)
    except yaml.YAMLError as err:
        raise CaseError(f"override {text!r}: the value is not valid YAML: {_yaml_problem(err)}") from None


def overlay_overrides(path: str | Path) -> list[tuple[str, Any]]:
    """The (key, value) pairs of a workflow config overlay's `all_cases` mapping (e.g. the fitted
    values a calibration writes), in file order."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        raise CaseError(f"overlay {str(path)!r} is not valid YAML: {_yaml_problem(err)}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise CaseError(f"overlay {str(path)!r} cannot be read: {err}") from None
    cases = data.get("all_cases") if isinstance(data, Mapping) else None
    if not isinstance(cases, Mapping) or not cases:
        raise CaseError(f"overlay {str(path)!r} must hold a mapping `all_cases` of dotted case keys "
                        "and values")
    for name in cases:
        if name not in KEYS:
            raise CaseError(f"overlay {str(path)!r}: {_unknown(name)}")
    return list(cases.items())


def _yaml_problem(err: yaml.YAMLError) -> str:
    """One line: what the YAML parser found wrong, and where (line, column from 1)."""
    mark = getattr(err, "problem_mark", None)
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
    return f"{where}{problem}"


def _unknown(name: str) -> CaseError:
    close = difflib.get_close_matches(name, KEYS, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return CaseError(f"unknown key {name!r}{hint}; `plugsim keys` lists all keys")


class Case:
    """A validated case: read values with ``case["particles.friction"]``."""

    def __init__(self, values: Mapping[str, Any] | None = None):
        merged = defaults()
        for name, value in flatten(values or {}).items():
            if name not in KEYS:
                raise _unknown(name)
            merged[name] = value
        self._values = {name: KEYS[name].check(value) for name, value in merged.items()}
        self._check_consistency()

    @classmethod
    def from_yaml(cls, path: str | Path, overrides: Iterable[str] = ()) -> "Case":
        """Load a case YAML file, then apply 'key=value' overrides."""
        path = Path(path)
        if not path.exists():
            raise CaseError(f"case file {str(path)!r} does not exist")
        if not path.is_file():
            raise CaseError(f"case file {str(path)!r} is not a file")
        try:
            nested = yaml.safe_load(path.read_text()) or {}
        except yaml.YAMLError as err:
            raise CaseError(f"case file {str(path)!r} is not valid YAML: {_yaml_problem(err)}") from None
        except (OSError, UnicodeDecodeError) as err:
            raise CaseError(f"case file {str(path)!r} cannot be read: {err}") from None
        if not isinstance(nested, Mapping):
            raise CaseError(f"case file {str(path)!r} must hold a mapping of sections")
        return cls(nested).with_overrides(overrides)

    def with_overrides(self, overrides: Iterable[str | tuple[str, Any]] = (), **kw: Any) -> "Case":
        """A new case with dotted overrides ('key=value' strings, (key, value) pairs or key__sub=value)."""
        values = dict(self._values)
        pairs = [parse_override(o) if isinstance(o, str) else o for o in overrides]
        pairs += [(k.replace("__", "."), v) for k, v in kw.items()]
        for name, value in pairs:
            if name not in KEYS:
                raise _unknown(name)
            values[name] = value
        return Case(values)

    def __getitem__(self, name: str) -> Any:
        if name not in self._values:
            raise _unknown(name)
        return self._values[name]

    def to_dict(self) -> dict[str, Any]:
        """Nested mapping of all values."""
        return unflatten(self._values)

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)

    def items(self):
        return self._values.items()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Case) and self._values == other._values

    def __repr__(self) -> str:
        changed = {k: v for k, v in self._values.items() if v != KEYS[k].default}
        return f"Case({changed})"

    def _check_consistency(self) -> None:
        """Cross-key checks (each message names the keys involved)."""
        d, D = self["particles.diameter"], self["tube.diameter"]
        if d >= D / 2:
            raise CaseError(f"particles.diameter = {d:g} m must be < tube.diameter / 2 = {D / 2:g} m")
        if self["tube.length"] < 4 * d:
            raise CaseError(f"tube.length = {self['tube.length']:g} m must be >= 4 particles.diameter")
        if self["output.snapshot_x_max"] <= self["output.snapshot_x_min"]:
            raise CaseError("output.snapshot_x_max must be > output.snapshot_x_min")
        if self["run.duration"] < self["output.interval"] * (1 - 1e-9):
            raise CaseError(f"run.duration = {self['run.duration']:g} s must be >= output.interval = "
                            f"{self['output.interval']:g} s (a run writes one frame per output.interval)")
        ratio = self["output.snapshot_interval"] / self["output.interval"]
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise CaseError(f"output.snapshot_interval = {self['output.snapshot_interval']:g} s must be a "
                            f"whole multiple of output.interval = {self['output.interval']:g} s")
        tube = self["output.tube_snapshot_interval"]
        ratio = tube / self["output.interval"]
        if tube > 0 and (abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1):
            raise CaseError(f"output.tube_snapshot_interval = {tube:g} s must be 0 (none) or a whole "
                            f"multiple of output.interval = {self['output.interval']:g} s")


def keys_markdown() -> str:
    """Reference table of every key (docs/case-keys.md is generated from this)."""
    lines = ["# Case configuration keys", "",
             "Generated by `plugsim keys --markdown`; the source of truth is `engine/case.py`.", "",
             "| key | meaning | unit | default | allowed |", "|---|---|---|---|---|"]
    for key in KEYS.values():
        lines.append(f"| `{key.name}` | {key.doc} | {key.unit or '-'} | {key.default!r} | {key.allowed()} |")
    return "\n".join(lines) + "\n"

"""The driver: owns the grain arrays, feeds the tube and calls the numba time loop in chunks."""

from __future__ import annotations

import math

import numba
import numpy as np

from .case import Case
from .contact import ContactModel
from .feed import Feed
from .gas import GasField
from .kernels import gas as gas_kernels
from .kernels import indices
from .kernels import slices as S
from .kernels.contacts import evaluate_contacts, single_loop_buffers
from .kernels.passes import pair_buffers
from .kernels.state import Chunks, Grains, Neighbors
from .kernels.stepper import advance, finish_step, rebuild
from .parameters import BLOCK_TRAVEL, cell_counts, gas_parameters, grain_parameters
from .parameters import gravity as gravity_vector

PAIRS_PER_GRAIN = 12  # initial half-list capacity; a dense packing within d + skin has about 5


def check_threads(threads: int) -> int:
    """threads, if numba can run that many (1 to NUMBA_NUM_THREADS); ValueError naming the limit."""
    limit = numba.config.NUMBA_NUM_THREADS
    if not isinstance(threads, (int, np.integer)) or not 1 <= threads <= limit:
        raise ValueError(f"threads = {threads!r}: allowed 1 to {limit} (NUMBA_NUM_THREADS, by default the "
                         "number of cores)")
    return int(threads)


class SimulationError(RuntimeError):
    """A numerical failure (non-finite state, grain outside the tube); the message is one line."""


class FeedBlocked(SimulationError):
    """The enforced feed cannot push grains into the tube (a physical outcome, not a failure)."""


class Simulation:
    """One case in a tube: grains and gas, advanced in time.

    Arrays returned by `positions`, `velocities` and `angular_velocities` are (n, 3) copies in SI
    units, ordered by grain id (the order of insertion), holding only grains inside the tube.
    `threads` > 1 computes the contact forces in that many chunks on numba threads: results are
    reproducible for a given thread count and differ from one thread's by rounding only.
    """

    def __init__(self, case: Case, threads: int = 1):
        self.threads = check_threads(threads)
        self.contact_passes = True  # set_contact_passes
        self.case = case
        self.model = ContactModel.from_case(case)
        self.feed = Feed(case, self.model.mass, case["run.seed"])
        self.dt = self.model.time_step
        self._steps = 0
        self._next_id = 0
        self._p = grain_parameters(case)  # what the grain kernels read (engine/parameters.py)
        self._shape = np.array(cell_counts(case), dtype=np.int64)
        self.gas = GasField(case)  # a 3-node dummy when the gas is off, so the kernels keep one signature
        self._allocate(self._initial_capacity())
        self._n = np.zeros(1, dtype=np.int64)
        self._counters = np.zeros(indices.NCOUNTERS, dtype=np.int64)
        self._diag = np.zeros(indices.NDIAG)  # overlaps (m) and the piston impulse (N s), indices.DIAG_*
        self._dirty = True        # arrays changed outside the time loop: rebuild + forces first
        self._feed_tail = None    # x of the last feed layer created

    # ---- set-up -------------------------------------------------------------------------------
    def _grains(self) -> Grains:
        """The per-grain arrays as the kernels take them."""
        return Grains(self._pos, self._vel, self._omg, self._force, self._drag, self._torque,
                      self._viscous_damping, self._wall_normal, self._gid, self._in_feed, self._pos_ref)

    def _neighbors(self) -> Neighbors:
        """The cell grid and neighbour list as the kernels take them."""
        return Neighbors(self._shape, self._cell_start, self._cell_of, self._order, self._tmp3, self._tmpi,
                         self._nbr_start, self._nbr, self._nbr_i)

    def _initial_capacity(self) -> int:
        c = self.case
        volume = c["tube.length"] * math.pi * c["tube.diameter"] ** 2 / 4
        grain_volume = math.pi * c["particles.diameter"] ** 3 / 6
        return int(0.6 * volume / grain_volume) + 8 * len(self.feed.template)

    def _allocate(self, cap: int) -> None:
        """(Re)allocate all per-grain arrays with capacity cap, keeping the current grains."""
        old = getattr(self, "_pos", None)
        n = int(self._n[0]) if old is not None else 0
        arrays = {}
        for name, shape, dtype in [("_pos", (cap, 3), float), ("_vel", (cap, 3), float),
                                   ("_omg", (cap, 3), float), ("_force", (cap, 3), float),
                                   ("_torque", (cap, 3), float), ("_pos_ref", (cap, 3), float),
                                   ("_viscous_damping", cap, float),
                                   ("_wall_normal", cap, float), ("_drag", (cap, 3), float),
                                   ("_tmp3", (cap, 3), float), ("_gid", cap, np.int64),
                                   ("_in_feed", cap, np.int64), ("_tmpi", cap, np.int64),
                                   ("_cell_of", cap, np.int64), ("_order", cap, np.int64),
                                   ("_nbr_start", cap + 1, np.int64)]:
            new = np.zeros(shape, dtype=dtype)
            if old is not None:
                new[:n] = getattr(self, name)[:n]
            arrays[name] = new
        self.__dict__.update(arrays)
        self._cell_start = np.zeros(int(np.prod(self._shape)) + 1, dtype=np.int64)
        # 32-bit indices: the list is read at every step, half the bytes of 64-bit ones (1.35x the compaction)
        self._nbr = np.zeros(PAIRS_PER_GRAIN * cap, dtype=np.uint32)
        self._nbr_i = np.zeros_like(self._nbr)
        self._chunks = self._chunk_arrays(cap)
        self._pairs = self._contact_buffers()
        self._dirty = True

    def __getstate__(self) -> dict:
        """The pickled state (restart_state, checkpoints) leaves out the contact passes' work arrays
        (every call rewrites them before reading) and each list entry's grain (_nbr_i, which the
        list starts give)."""
        state = dict(self.__dict__)
        state.pop("_pairs", None)
        state.pop("_nbr_i", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if not hasattr(self._p, "_fields"):  # a state pickled with the parameters as vectors
            self._p = grain_parameters(self.case)
            self.gas.g = gas_parameters(self.case)
        self.contact_passes = state.get("contact_passes", True)  # also a state pickled before them
        n = int(self._n[0])
        self._nbr = self._nbr.astype(np.uint32, copy=False)  # a state pickled with 64-bit indices
        self._nbr_i = np.zeros_like(self._nbr)
        self._nbr_i[:self._nbr_start[n]] = np.repeat(np.arange(n), np.diff(self._nbr_start[:n + 1]))
        self._pairs = self._contact_buffers()

    def set_contact_passes(self, on: bool) -> None:
        """One thread: the contact forces in passes over flat lists (True, the default) or in the
        single loop (False); docs/performance.md, "The contact kernel". The two differ in the last
        bits of the forces."""
        self.contact_passes = bool(on)
        self._pairs = self._contact_buffers()

    def _contact_buffers(self):
        """The work arrays of the one-thread contact kernel that contact_passes selects."""
        return pair_buffers() if self.contact_passes else single_loop_buffers()

    def _chunk_arrays(self, cap: int) -> Chunks:
        """Thread work arrays of evaluate_contacts (spill rows are zero between calls); dummies for one thread."""
        rows = cap if self.threads > 1 else 1
        return Chunks(np.zeros((self.threads, rows, 3)), np.zeros((self.threads, rows, 3)),
                      np.zeros((self.threads, rows)), np.zeros(self.threads + 1, dtype=np.int64),
                      np.zeros((self.threads, 3)), np.zeros(rows, dtype=np.int64))

    def set_threads(self, threads: int) -> None:
        """Compute the contact forces on `threads` numba threads from now on."""
        self.threads = check_threads(threads)
        self._chunks = self._chunk_arrays(len(self._pos))

    @property
    def gravity(self) -> np.ndarray:
        """Gravity vector (m/s2) from the inclination: 0 deg -> -z, 90 deg -> -x."""
        return np.array(gravity_vector(self.case))

    # ---- grains in and out --------------------------------------------------------------------
    def add_particles(self, positions, velocities=None, angular_velocities=None) -> np.ndarray:
        """Insert grains (k x 3 arrays, SI); returns their ids. Positions must lie inside the tube."""
        pos = np.atleast_2d(np.asarray(positions, dtype=float))
        k = len(pos)
        vel = np.zeros((k, 3)) if velocities is None else np.atleast_2d(np.asarray(velocities, float))
        omg = np.zeros((k, 3)) if angular_velocities is None else np.atleast_2d(
            np.asarray(angular_velocities, float))
        for name, arr in [("positions", pos), ("velocities", vel), ("angular_velocities", omg)]:
            if arr.shape != (k, 3) or not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} must be a finite ({k}, 3) array, got shape {arr.shape}")
        r, R, L = self.model.radius, self.case["tube.diameter"] / 2, self.case["tube.length"]
        rho = np.hypot(pos[:, 1], pos[:, 2])
        bad = np.flatnonzero((rho > R - r + 0.5 * r) | (pos[:, 0] < 0) | (pos[:, 0] > L))
        if len(bad):
            raise ValueError(f"grain {bad[0]} at {pos[bad[0]]} m is outside the tube "
                             f"(0 <= x <= {L:g} m, sqrt(y^2+z^2) <= R - r)")
        return self._append(pos, vel, omg, kinematic=False)

    def _append(self, pos, vel, omg, kinematic: bool) -> np.ndarray:
        n, k = int(self._n[0]), len(pos)
        if n + k > len(self._pos):
            self._allocate(max(2 * len(self._pos), n + k))
        sl = slice(n, n + k)
        self._pos[sl], self._vel[sl], self._omg[sl] = pos, vel, omg
        ids = np.arange(self._next_id, self._next_id + k)
        self._gid[sl], self._in_feed[sl] = ids, int(kinematic)
        self._next_id += k
        self._n[0] = n + k
        self._dirty = True
        return ids

    def _refill_feed(self, travel: float) -> None:
        """Create feed layers so that the piston holds layers for the next `travel` metres."""
        if not self.feed.enabled:
            return
        d = 2 * self.model.radius
        if self._feed_tail is None:
            self._append_layer(-d)
        while self._feed_tail > -d - travel:
            self._append_layer(self._feed_tail - self.feed.spacing)

    def _append_layer(self, x: float) -> None:
        layer = self.feed.layer(x)
        vel = np.zeros_like(layer)
        vel[:, 0] = self.feed.entry_velocity
        self._append(layer, vel, np.zeros_like(layer), kinematic=True)
        self._feed_tail = x

    # ---- time loop ----------------------------------------------------------------------------
    def _prepare(self) -> None:
        """Rebuild the neighbour list and evaluate forces after the arrays were changed."""
        self._rebuild()
        evaluate_contacts(self._grains(), int(self._n[0]), self._nbr_start, self._nbr, self._nbr_i, self._p,
                          self._diag, self._chunks, self._pairs)
        self._dirty = False

    def _rebuild(self) -> None:
        """Sort, drop outflow and rebuild the neighbour list, growing the list until it fits."""
        while True:
            self._n[0] = rebuild(self._grains(), int(self._n[0]), self._p, self._neighbors(), self._counters)
            if not self._counters[indices.OVERFLOW]:
                return
            self._grow_neighbor_list()

    def _grow_neighbor_list(self) -> None:
        """A neighbour-list buffer twice as long (at least 1024 entries: an empty one grows too)."""
        self._nbr = np.zeros(max(2 * len(self._nbr), 1024), dtype=np.uint32)
        self._nbr_i = np.zeros_like(self._nbr)

    def advance(self, seconds: float) -> None:
        """Advance by `seconds` of simulated time (rounded to whole time steps)."""
        if seconds < 0:
            raise ValueError(f"advance(seconds={seconds}) needs seconds >= 0")
        remaining = int(round(seconds / self.dt))
        # The piston may travel at most d/2 per chunk, so feed layers are always created in time.
        speed = self._p.feed_speed
        chunk = 2000 if speed == 0 else max(1, min(2000, int(self.model.radius / (speed * self.dt))))
        if self.threads > 1:
            numba.set_num_threads(self.threads)
        while remaining > 0:
            steps = min(chunk, remaining)
            feed_travel = speed * steps * self.dt
            self._refill_feed(feed_travel)
            if self._dirty:
                self._prepare()
            taken = advance(steps, self._n, self._grains(), self._p, self._neighbors(), self._counters, self._diag,
                            self.gas.arrays(), self._chunks, self._pairs)
            if self._counters[indices.OVERFLOW]:  # grow the neighbour list and finish the broken step
                self._grow_neighbor_list()
                self._rebuild()
                finish_step(self._grains(), int(self._n[0]), self._p, self._neighbors(), self._counters,
                            self._diag, self.gas.arrays(), self._chunks, self._pairs)
                taken += 1
            self._steps += taken
            remaining -= taken
            self._check_status()
            if self._feed_tail is not None:
                self._feed_tail = self._kinematic_tail()

    def _kinematic_tail(self) -> float:
        """x of the deepest feed layer (the piston moves all layers together)."""
        n = int(self._n[0])
        in_feed = self._in_feed[:n] == 1
        return float(self._pos[:n, 0][in_feed].min()) if in_feed.any() else -math.inf

    def _check_status(self) -> None:
        status = self._counters[indices.STATUS]
        if status == indices.OK:
            return
        if status == indices.BLOCKED:
            raise FeedBlocked(
                f"the tube is blocked at t = {self.time:.4f} s: the feed piston pressed a grain by more "
                f"than feed.max_overlap = {self.case['feed.max_overlap']:g} d while advancing "
                f"{BLOCK_TRAVEL:g} d")
        what = {indices.NONFINITE: "a grain position became non-finite (NaN/Inf)",
                indices.ESCAPED: "a grain left the tube through its wall or inlet"}[int(status)]
        raise SimulationError(f"{what} at t = {self.time:.6f} s; the time step or the contact "
                              f"parameters are too aggressive for this case")

    # ---- read-only state ----------------------------------------------------------------------
    def _dynamic_order(self) -> np.ndarray:
        n = int(self._n[0])
        idx = np.flatnonzero(self._in_feed[:n] == 0)
        return idx[np.argsort(self._gid[idx], kind="stable")]

    def _view(self, arr: np.ndarray) -> np.ndarray:
        out = arr[self._dynamic_order()]
        out.flags.writeable = False
        return out

    @property
    def positions(self) -> np.ndarray:
        """Grain centres (n, 3), m; x along the tube, y and z across."""
        return self._view(self._pos)

    @property
    def velocities(self) -> np.ndarray:
        """Grain velocities (n, 3), m/s."""
        return self._view(self._vel)

    @property
    def angular_velocities(self) -> np.ndarray:
        """Grain angular velocities (n, 3), rad/s."""
        return self._view(self._omg)

    @property
    def ids(self) -> np.ndarray:
        """Ids of the grains in the tube, in the order of the state arrays."""
        return self._view(self._gid)

    @property
    def time(self) -> float:
        """Simulated time, s."""
        return self._steps * self.dt

    @property
    def n_particles(self) -> int:
        """Grains inside the tube (released from the feed, not yet past the outlet)."""
        n = int(self._n[0])
        return int(np.count_nonzero(self._in_feed[:n] == 0))

    @property
    def mass_in(self) -> float:
        """Cumulative grain mass released into the tube by the feed, kg."""
        return self._counters[indices.RELEASED] * self.model.mass

    @property
    def mass_out(self) -> float:
        """Cumulative grain mass that left past the outlet, kg."""
        return self._counters[indices.REMOVED] * self.model.mass

    @property
    def max_overlap(self) -> float:
        """Largest overlap (grain-grain, grain-wall or grain-feed) over every step since the start
        or the last reset_max_overlap(), m."""
        return float(self._diag[:indices.DIAG_RUNNING_MAX + 1].max())

    @property
    def overlap(self) -> float:
        """Largest overlap (grain-grain, grain-wall or grain-feed) at the current positions (the
        last force evaluation), m."""
        return float(max(self._diag[indices.DIAG_OVERLAP], self._diag[indices.DIAG_FEED_OVERLAP]))

    def reset_max_overlap(self) -> None:
        """Start a new window for max_overlap (run_case: every output frame)."""
        self._diag[indices.DIAG_RUNNING_MAX] = 0.0

    @property
    def piston_impulse(self) -> float:
        """Cumulative axial impulse the feed piston has exerted on the tube grains, N s (its
        change over an interval, divided by the interval, is the mean piston force)."""
        return float(self._diag[indices.DIAG_PISTON_IMPULSE])

    def slice_fields(self, width: float) -> dict[str, np.ndarray]:
        """Slice averages over slices of `width` (m) from the inlet (papers §3.2).

        Each grain counts with the fraction of its volume inside the slice. Returns porosity,
        velocity (axial, m/s), drag_force and particle_force (mean axial force per grain, N; particle
        force = contacts + walls + axial gravity), wall_stress (normal cylinder-wall force per wall
        area, Pa) and granular_temperature (mean kinetic energy per grain minus that of the slice's
        mean motion, J). Means over empty slices are NaN.
        """
        nslices = int(round(self.case["tube.length"] / width))
        acc = np.zeros((nslices, S.NCOLS))
        n = int(self._n[0])
        S.accumulate_slices(self._pos, self._vel, self._force, self._drag_forces(), self._wall_normal,
                            self._in_feed, n, self.model.radius, self.model.mass, float(self.gravity[0]),
                            width, acc)
        area = math.pi * self.case["tube.diameter"] ** 2 / 4
        weight = acc[:, S.WEIGHT]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = {name: acc[:, col] / weight for name, col in
                    [("velocity", S.VEL), ("drag_force", S.DRAG), ("particle_force", S.PART),
                     ("vy", S.VY), ("vz", S.VZ), ("v2", S.KIN)]}
        temperature = 0.5 * self.model.mass * (mean["v2"] - mean["velocity"] ** 2 - mean["vy"] ** 2
                                               - mean["vz"] ** 2)
        return {"porosity": 1.0 - acc[:, S.SOLID] / (area * width),
                "velocity": mean["velocity"], "drag_force": mean["drag_force"],
                "particle_force": mean["particle_force"],
                "wall_stress": acc[:, S.WALL] / (math.pi * self.case["tube.diameter"] * width),
                "granular_temperature": np.maximum(temperature, 0.0)}

    def contacts(self) -> dict[str, np.ndarray]:
        """The touching contacts at the current positions: grain pairs (feed grains included) and
        the dynamic grains' cylinder-wall and inlet-wall contacts. Arrays over contacts: `i`, `j`
        (grain rows; j = -1 for a wall), `inlet` (an inlet-wall contact), `overlap` (m), `closing`
        (normal approach speed, m/s); `in_feed` over the grain rows. For diagnosis (a Python pass
        over a k-d tree), not the time loop."""
        from scipy.spatial import cKDTree

        n = int(self._n[0])
        pos, vel, feed = self._pos[:n], self._vel[:n], self._in_feed[:n] == 1
        r = self.model.radius
        pairs = cKDTree(pos).query_pairs(2 * r, output_type="ndarray").reshape(-1, 2)
        i, j = pairs[:, 0], pairs[:, 1]
        gap = pos[j] - pos[i]
        dist = np.linalg.norm(gap, axis=1)
        closing = np.einsum("ij,ij->i", vel[i] - vel[j], gap / dist[:, None])
        rho = np.hypot(pos[:, 1], pos[:, 2])
        wall = np.flatnonzero(~feed & (rho > self.case["tube.diameter"] / 2 - r))
        inlet = np.flatnonzero(~feed & (pos[:, 0] < r))
        radial = (vel[wall, 1] * pos[wall, 1] + vel[wall, 2] * pos[wall, 2]) / rho[wall]
        return {"i": np.concatenate([i, wall, inlet]),
                "j": np.concatenate([j, np.full(len(wall) + len(inlet), -1)]),
                "inlet": np.arange(len(i) + len(wall) + len(inlet)) >= len(i) + len(wall),
                "overlap": np.concatenate([2 * r - dist, rho[wall] + r - self.case["tube.diameter"] / 2,
                                           r - pos[inlet, 0]]),
                "closing": np.concatenate([closing, radial, -vel[inlet, 0]]),
                "in_feed": feed}

    @property
    def pressure_drop(self) -> float:
        """Gas pressure at the inlet face minus at the outlet face, Pa (0 while the gas is off)."""
        if not self.case["gas.enabled"]:
            return 0.0
        gas = self.gas
        return float(gas_kernels.pressure_drop(gas.pressure, gas.kappa, gas.u, gas.area, gas.g,
                                               self._p.feed_volume_rate))

    def gas_pressure_slices(self, width: float) -> np.ndarray:
        """Gas pressure P' (cross-section mean) at the slice centres of `width` (m), Pa."""
        nslices = int(round(self.case["tube.length"] / width))
        if not self.case["gas.enabled"]:
            return np.zeros(nslices)
        gas = self.gas
        mean = (gas.pressure * gas.area).sum(axis=(1, 2)) / gas.area.sum()
        return np.interp((np.arange(nslices) + 0.5) * width, gas.x, mean)

    @property
    def gas_force(self) -> float:
        """Axial gas drag on the grains in the tube, N (as applied in the last step)."""
        n = int(self._n[0])
        return float(self._drag[:n, 0][self._in_feed[:n] == 0].sum())

    def _drag_forces(self) -> np.ndarray:
        """Per-grain gas drag force (capacity x 3), N, as applied in the last step."""
        return self._drag

    @property
    def kinetic_energy(self) -> float:
        """Translational + rotational kinetic energy of the grains in the tube, J."""
        n = int(self._n[0])
        dyn = self._in_feed[:n] == 0
        m, inertia = self.model.mass, self.model.inertia
        return float(0.5 * m * (self._vel[:n][dyn] ** 2).sum() + 0.5 * inertia * (self._omg[:n][dyn] ** 2).sum())

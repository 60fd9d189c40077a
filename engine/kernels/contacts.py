"""Contact forces: grain-grain (half neighbour list), grain-cylinder wall and the inlet wall at x = 0.

The loops over contacts; the laws they apply are in laws.py. `grains` is a state.Grains.

One thread runs either the single loop (the default: a grain's pairs, the reactions scattered
inside, then its walls) or, given work arrays (pair_buffers; Simulation.set_contact_passes), the
contacts in passes (contact_forces), each a simple loop, over blocks of consecutive (cell-sorted)
grains: the walls, branch-free over the block's grains (vectorised); the touching pairs compacted
from the half list; their offsets, velocities and spins gathered into contiguous rows; the pair
law, branch-free over the touching pairs (vectorised); the scatter of the results into the grains.
Both add a grain's own pairs in list order, then its cylinder and its inlet contact, onto the
reactions of the grains before it. Compiled without fastmath's contract and reassoc the two give
the same bits; with them LLVM fuses and reorders the arithmetic differently in a vectorised loop,
and the forces differ in the last bit. Measured against each other: docs/performance.md, "The
contact kernel" (the passes are not faster on the project's machines).
"""

import math

import numba as nb
import numpy as np

from . import laws
from .laws import FASTMATH
from .state import Pairs

# Rows of Pairs.rows, one value per touching pair. Inputs: centre offset j - i and its square,
# relative velocity v_i - v_j, spin sum w_i + w_j and (optional terms) relative spin w_i - w_j.
# Outputs of the pair kernel: force on i, torque on i, gamma_t if viscous, (optional) torque on j.
DX, DY, DZ, D2, VX, VY, VZ, WX, WY, WZ, RWX, RWY, RWZ = range(13)
FX, FY, FZ, TX, TY, TZ, G, TJX, TJY, TJZ = range(13, 23)
PAIR_ROWS = 23
# Rows of Pairs.walls, one value per grain: the cylinder's and the inlet's force, torque, gamma_t
# if viscous and overlap (zeros without contact), and the cylinder's normal force; the grain's
# centre, velocity, spin and 1 for a dynamic grain (copied in, the inputs).
CFX, CFY, CFZ, CTX, CTY, CTZ, CG, CD, IFX, IFY, IFZ, ITX, ITY, ITZ, IG, ID, CN = range(17)
GX, GY, GZ, GVX, GVY, GVZ, GWX, GWY, GWZ, GDYN = range(17, 27)
WALL_ROWS = 27


# Capacity of a block: list entries of its grains (so touching pairs) and grains.
PAIR_BLOCK = 512


def pair_buffers(block: int = PAIR_BLOCK) -> Pairs:
    """Work arrays of contact_forces for blocks of `block` list entries and grains."""
    # unsigned indices: numba then skips the wrap-around of negative indices (and its register spills)
    return Pairs(np.zeros(block + 1, dtype=np.uint64), np.zeros(block + 1, dtype=np.uint64),
                 np.zeros((PAIR_ROWS, block + 1)), np.zeros((WALL_ROWS, block)))


@nb.njit(cache=True)
def contact_forces(grains, n, nbr_start, nbr, p, diag, pairs):
    """Zero, then accumulate the grain-grain, cylinder-wall and inlet-wall forces and torques.

    diag[0]: max overlap of dynamic grains (pairs and walls), diag[1]: max overlap with a feed
    grain, m. viscous_damping[i]: the sum of gamma_t over grain i's contacts in the viscous branch,
    N s/m (the implicit spin kick's denominator, numerics.implicit_spin; summed only when that is on).
    wall_normal[i]: normal force of the cylinder on grain i, N (0 without contact).
    Pairs with a kinematic (feed) grain act on the dynamic grain only; the feed drives the other.
    `pairs` (a state.Pairs, pair_buffers()) holds the passes' work arrays: blocks of consecutive
    grains with at most its capacity of list entries and grains are run through all passes in turn;
    with empty ones (pair_buffers(0)) the single loop runs.
    """
    cap = pairs.walls.shape[1]
    longest = 0
    if cap > 0:
        for i in range(n):
            longest = max(longest, nbr_start[i + 1] - nbr_start[i])
    # the single loop: without work arrays (pair_buffers(0), the default: Simulation.contact_passes),
    # or for a grain with more list entries than a block holds (no packing has them)
    if cap == 0 or longest > cap:
        max_overlap, max_feed, _ = _contacts_range(0, n, grains, nbr_start, nbr, p, grains.force, grains.torque,
                                                   grains.viscous_damping, nbr_start[:0])
        diag[0] = max_overlap
        diag[1] = max_feed
        return
    grains.force[:n] = 0.0
    grains.torque[:n] = 0.0
    grains.viscous_damping[:n] = 0.0
    optional = laws.optional_terms(p)
    dia = 2.0 * p.radius
    dmin = np.inf
    fmin = np.inf
    wall_overlap = 0.0
    lo = 0
    while lo < n:
        hi = lo
        while hi < n and hi - lo < cap and nbr_start[hi + 1] - nbr_start[lo] <= cap:
            hi += 1
        if optional:
            inlet = _walls_optional(grains, lo, hi, p, pairs.walls)
        else:
            inlet = _walls_plain(grains, lo, hi, p, pairs.walls)
        m = compact_touching(grains.pos, lo, hi, nbr_start, nbr, dia, pairs.pair_j, pairs.start, pairs.rows)
        if optional:
            d, f = _gather_optional(grains, lo, hi, pairs.pair_j, pairs.start, pairs.rows)
            _pair_law_optional(m, p, pairs.rows)
        else:
            d, f = _gather_plain(grains, lo, hi, pairs.pair_j, pairs.start, pairs.rows)
            _pair_law_plain(m, p, pairs.rows)
        w = scatter(grains, lo, hi, p, pairs.pair_j, pairs.start, pairs.rows, pairs.walls, optional, inlet)
        dmin = min(dmin, d)
        fmin = min(fmin, f)
        wall_overlap = max(wall_overlap, w)
        lo = hi
    # the largest overlap dia - sqrt(d2) is that of the smallest d2 (both roundings are monotone)
    diag[0] = max(max(0.0, dia - math.sqrt(dmin)), wall_overlap)
    diag[1] = max(0.0, dia - math.sqrt(fmin))


@nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def compact_touching(pos, lo, hi, nbr_start, nbr, dia, pair_j, start, rows):
    """Compact the touching pairs (centres closer than dia) of grains lo..hi-1 from the half list,
    in list order: partner j and squared distance (row D2); start[i - lo] is grain i's first.
    Branch-free: every entry is written at the next free slot, which only a touching one then
    keeps (the offsets are written by gather, for the touching pairs only). Returns their number."""
    dia2 = dia * dia
    m = 0
    for i in range(lo, hi):
        start[i - lo] = m
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        for k in range(nbr_start[i], nbr_start[i + 1]):
            j = nbr[k]
            dx = pos[j, 0] - xi
            dy = pos[j, 1] - yi
            dz = pos[j, 2] - zi
            dist2 = dx * dx + dy * dy + dz * dz
            pair_j[m] = j
            rows[D2, m] = dist2
            m += 0 if dist2 >= dia2 else 1  # a nan distance counts as touching, as it always did
    start[hi - lo] = m
    return m


def _passes_with(optional):
    """The wall pass, gather, pair kernel of contact_forces with the optional contact terms
    (laws.optional_terms) compiled in or out (a constant of the closure)."""

    @nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
    def walls_pass(grains, lo, hi, p, walls):
        """Cylinder and inlet contacts of grains lo..hi-1, branch-free (selects), into column i - lo
        of the rows of `walls`. The grains' state is first copied into rows of `walls` too, and each wall
        has its own loop: a loop whose arrays are fewer (and whose row accesses are fewer) needs
        fewer run-time overlap checks, which LLVM limits, and only then vectorises. The overlaps
        and normal forces go to rows, not into a running maximum or to wall_normal, for the same
        reason (a max reduction does not vectorise without nnan). Returns whether the inlet rows
        were written: not when no grain of the block lies within r of the inlet (the inlet loop and
        the scatter's inlet terms, zeros, are skipped then: almost every block)."""
        pos, vel, omg, in_feed = grains.pos, grains.vel, grains.omg, grains.in_feed
        wall = laws.wall_constants(p)
        r = p.radius
        inner = p.tube_radius - r  # analytic cylinder: overlap = rho + r - R
        inner2 = inner * inner
        nb_ = hi - lo
        xmin = np.inf
        for w in range(nb_):
            i = lo + w
            walls[GX, w] = pos[i, 0]
            walls[GY, w] = pos[i, 1]
            walls[GZ, w] = pos[i, 2]
            walls[GVX, w] = vel[i, 0]
            walls[GVY, w] = vel[i, 1]
            walls[GVZ, w] = vel[i, 2]
            walls[GWX, w] = omg[i, 0]
            walls[GWY, w] = omg[i, 1]
            walls[GWZ, w] = omg[i, 2]
            walls[GDYN, w] = 1.0 if in_feed[i] == 0 else 0.0
            xmin = min(xmin, pos[i, 0])
        for i in range(nb_):
            y = walls[GY, i]
            z = walls[GZ, i]
            rho2 = y * y + z * z
            rho = math.sqrt(rho2)
            delta = rho - inner
            on = walls[GDYN, i] > 0.0 and rho2 > inner2
            fn, fx, fy, fz, tx, ty, tz, g = laws.wall_contact(
                delta, 0.0, y / rho, z / rho, walls[GVX, i], walls[GVY, i], walls[GVZ, i], walls[GWX, i],
                walls[GWY, i], walls[GWZ, i], wall, optional, True)
            walls[CN, i] = fn if on else 0.0
            walls[CFX, i] = fx if on else 0.0
            walls[CFY, i] = fy if on else 0.0
            walls[CFZ, i] = fz if on else 0.0
            walls[CTX, i] = tx if on else 0.0
            walls[CTY, i] = ty if on else 0.0
            walls[CTZ, i] = tz if on else 0.0
            walls[CG, i] = g if on else 0.0
            walls[CD, i] = delta if on else 0.0
        if not (xmin < r):  # no grain of the block touches the inlet (the grains are sorted by cell in x)
            return False
        for i in range(nb_):  # the inlet wall at x = 0
            x = walls[GX, i]
            delta = r - x
            on = walls[GDYN, i] > 0.0 and x < r
            fn, fx, fy, fz, tx, ty, tz, g = laws.wall_contact(
                delta, -1.0, 0.0, 0.0, walls[GVX, i], walls[GVY, i], walls[GVZ, i], walls[GWX, i],
                walls[GWY, i], walls[GWZ, i], wall, optional, True)
            walls[IFX, i] = fx if on else 0.0
            walls[IFY, i] = fy if on else 0.0
            walls[IFZ, i] = fz if on else 0.0
            walls[ITX, i] = tx if on else 0.0
            walls[ITY, i] = ty if on else 0.0
            walls[ITZ, i] = tz if on else 0.0
            walls[IG, i] = g if on else 0.0
            walls[ID, i] = delta if on else 0.0
        return True

    @nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
    def gather(grains, lo, hi, pair_j, start, rows):
        """Centre offset j - i, relative velocity and spin sum (and relative spin) of the touching
        pairs of grains lo..hi-1 into their rows.
        Returns the smallest squared distance of a pair of dynamic grains and of a pair with a feed
        grain (inf if none)."""
        pos, vel, omg, in_feed = grains.pos, grains.vel, grains.omg, grains.in_feed
        dmin = np.inf
        fmin = np.inf
        for i in range(lo, hi):
            xi = pos[i, 0]
            yi = pos[i, 1]
            zi = pos[i, 2]
            vxi = vel[i, 0]
            vyi = vel[i, 1]
            vzi = vel[i, 2]
            wxi = omg[i, 0]
            wyi = omg[i, 1]
            wzi = omg[i, 2]
            feed_i = in_feed[i] != 0
            for c in range(start[i - lo], start[i - lo + 1]):
                j = pair_j[c]
                rows[DX, c] = pos[j, 0] - xi  # as in compact_touching
                rows[DY, c] = pos[j, 1] - yi
                rows[DZ, c] = pos[j, 2] - zi
                rows[VX, c] = vxi - vel[j, 0]
                rows[VY, c] = vyi - vel[j, 1]
                rows[VZ, c] = vzi - vel[j, 2]
                rows[WX, c] = wxi + omg[j, 0]
                rows[WY, c] = wyi + omg[j, 1]
                rows[WZ, c] = wzi + omg[j, 2]
                if optional:
                    rows[RWX, c] = wxi - omg[j, 0]
                    rows[RWY, c] = wyi - omg[j, 1]
                    rows[RWZ, c] = wzi - omg[j, 2]
                d2 = rows[D2, c]
                feed = feed_i or in_feed[j] != 0
                dmin = min(dmin, np.inf if feed else d2)
                fmin = min(fmin, d2 if feed else np.inf)
        return dmin, fmin

    @nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
    def pair_law(m, p, rows):
        """The contact law of the m touching pairs, elementwise and branch-free over contiguous rows
        (packed SIMD): force and torques on i, the torque on j (optional terms) and gamma_t if
        viscous; zeros where the normal force pulls."""
        pair = laws.pair_constants(p)
        dia = 2.0 * p.radius
        for c in range(m):
            dx = rows[DX, c]
            dy = rows[DY, c]
            dz = rows[DZ, c]
            dist = math.sqrt(rows[D2, c])
            inv = 1.0 / dist
            nx = dx * inv
            ny = dy * inv
            nz = dz * inv
            delta = dia - dist
            vrx = rows[VX, c]
            vry = rows[VY, c]
            vrz = rows[VZ, c]
            fn = laws.normal_force(delta, vrx * nx + vry * ny + vrz * nz, pair)
            if optional:
                rwx = rows[RWX, c]
                rwy = rows[RWY, c]
                rwz = rows[RWZ, c]
            else:
                rwx = rwy = rwz = 0.0
            fx, fy, fz, tx, ty, tz, tjx, tjy, tjz, g = laws.surface_forces(
                fn, nx, ny, nz, vrx, vry, vrz, rows[WX, c], rows[WY, c], rows[WZ, c], rwx, rwy, rwz, pair, optional,
                True)
            on = not (fn <= 0.0)
            rows[FX, c] = fx if on else 0.0
            rows[FY, c] = fy if on else 0.0
            rows[FZ, c] = fz if on else 0.0
            rows[TX, c] = tx if on else 0.0
            rows[TY, c] = ty if on else 0.0
            rows[TZ, c] = tz if on else 0.0
            rows[G, c] = g if on else 0.0
            if optional:
                rows[TJX, c] = tjx if on else 0.0
                rows[TJY, c] = tjy if on else 0.0
                rows[TJZ, c] = tjz if on else 0.0

    return walls_pass, gather, pair_law


_walls_plain, _gather_plain, _pair_law_plain = _passes_with(False)
_walls_optional, _gather_optional, _pair_law_optional = _passes_with(True)


@nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def scatter(grains, lo, hi, p, pair_j, start, rows, walls, optional, inlet):
    """Sum the pair results and the walls of grains lo..hi-1 into the grains: force, torque and (with
    the implicit spin kick) viscous_damping, zeroed by the caller; wall_normal. Grain i's own pairs
    are summed contiguously in registers, then its cylinder and inlet contact, and added to the
    reactions of the grains before it; the reactions go to j > i as they come (the single-loop
    kernel's order); the inlet rows only if `inlet` (walls_pass wrote them). Returns the largest wall
    overlap of a dynamic grain."""
    force, torque, viscous_damping = grains.force, grains.torque, grains.viscous_damping
    wall_normal = grains.wall_normal
    implicit = p.implicit_spin > 0.0  # viscous_damping is only read (and summed) then
    tjx_row = TJX if optional else TX
    tjy_row = TJY if optional else TY
    tjz_row = TJZ if optional else TZ
    largest = 0.0
    for i in range(lo, hi):
        w = i - lo
        fxi = 0.0
        fyi = 0.0
        fzi = 0.0
        txi = 0.0
        tyi = 0.0
        tzi = 0.0
        gsum = 0.0
        for c in range(start[w], start[w + 1]):
            j = pair_j[c]
            fx = rows[FX, c]
            fy = rows[FY, c]
            fz = rows[FZ, c]
            g = rows[G, c]
            fxi += fx
            fyi += fy
            fzi += fz
            txi += rows[TX, c]
            tyi += rows[TY, c]
            tzi += rows[TZ, c]
            gsum += g
            force[j, 0] -= fx
            force[j, 1] -= fy
            force[j, 2] -= fz
            torque[j, 0] += rows[tjx_row, c]
            torque[j, 1] += rows[tjy_row, c]
            torque[j, 2] += rows[tjz_row, c]
            if implicit:
                viscous_damping[j] += g
        fxi += walls[CFX, w]
        fyi += walls[CFY, w]
        fzi += walls[CFZ, w]
        txi += walls[CTX, w]
        tyi += walls[CTY, w]
        tzi += walls[CTZ, w]
        gsum += walls[CG, w]
        if inlet:
            fxi += walls[IFX, w]
            fyi += walls[IFY, w]
            fzi += walls[IFZ, w]
            txi += walls[ITX, w]
            tyi += walls[ITY, w]
            tzi += walls[ITZ, w]
            gsum += walls[IG, w]
            largest = max(largest, walls[ID, w])
        force[i, 0] += fxi
        force[i, 1] += fyi
        force[i, 2] += fzi
        torque[i, 0] += txi
        torque[i, 1] += tyi
        torque[i, 2] += tzi
        if implicit:
            viscous_damping[i] += gsum
        wall_normal[i] = walls[CN, w]
        largest = max(largest, walls[CD, w])
    return largest


@nb.njit(cache=True)
def evaluate_contacts(grains, n, nbr_start, nbr, p, diag, chunks, pairs):
    """contact_forces, on threads when chunks (a state.Chunks) has more than one chunk (bounds holds
    nchunks + 1 entries); see contact_forces_chunked."""
    if chunks.bounds.shape[0] > 2:
        contact_forces_chunked(grains, n, nbr_start, nbr, p, diag, chunks)
    else:
        contact_forces(grains, n, nbr_start, nbr, p, diag, pairs)


@nb.njit(cache=True, fastmath=FASTMATH, parallel=True)
def contact_forces_chunked(grains, n, nbr_start, nbr, p, diag, chunks):
    """contact_forces on threads (chunks: a state.Chunks): grains [bounds[c], bounds[c+1]) are chunk c.

    The half list gives chunk c pairs (i, j > i) whose j may lie in a later chunk: those reactions go
    to chunk c's spill arrays (all zero between calls) and are added afterwards in chunk order, so
    the result is reproducible for a given number of chunks (not bit-identical to the serial sum).
    contact_count[i] (touching pairs of i's list plus its walls) is kept from call to call to balance
    the chunks.
    """
    spill_force, spill_torque, spill_viscous_damping, bounds, chunk_diag, contact_count = chunks
    force = grains.force
    torque = grains.torque
    viscous_damping = grains.viscous_damping
    nchunks = bounds.shape[0] - 1
    _balance(nbr_start, contact_count, n, bounds)
    for c in nb.prange(nchunks):
        a, b, top = _contacts_range(bounds[c], bounds[c + 1], grains, nbr_start, nbr, p, spill_force[c],
                                    spill_torque[c], spill_viscous_damping[c], contact_count)
        chunk_diag[c, 0] = a
        chunk_diag[c, 1] = b
        chunk_diag[c, 2] = top
    max_overlap = 0.0
    max_feed = 0.0
    for c in range(nchunks):  # serial, in chunk order: reproducible sums
        max_overlap = max(max_overlap, chunk_diag[c, 0])
        max_feed = max(max_feed, chunk_diag[c, 1])
        for j in range(bounds[c + 1], int(chunk_diag[c, 2])):
            for d in range(3):
                force[j, d] += spill_force[c, j, d]
                spill_force[c, j, d] = 0.0
            for d in range(3):
                torque[j, d] += spill_torque[c, j, d]
                spill_torque[c, j, d] = 0.0
            viscous_damping[j] += spill_viscous_damping[c, j]
            spill_viscous_damping[c, j] = 0.0
    diag[0] = max_overlap
    diag[1] = max_feed


# Cost of a touching contact (force arithmetic) in units of a list entry's distance check, measured
# on the default horizontal case: 47 and 101 us for halves of 4764 / 4015 entries and 932 / 3115
# contacts fit 5 ns per entry and 25 ns per contact.
CONTACT_COST = 5


@nb.njit(cache=True)
def _balance(nbr_start, contact_count, n, bounds):
    """Chunk bounds with about equal work each, from the list entries and the touching contacts of
    each grain at the previous call (the grain order changes little between calls)."""
    nchunks = bounds.shape[0] - 1
    total = nbr_start[n] + n
    for i in range(n):
        total += CONTACT_COST * contact_count[i]
    i = 0
    done = 0
    bounds[0] = 0
    for c in range(1, nchunks):
        target = (total * c) // nchunks
        while i < n and done < target:
            done += nbr_start[i + 1] - nbr_start[i] + 1 + CONTACT_COST * contact_count[i]
            i += 1
        bounds[c] = i
    bounds[nchunks] = n


@nb.njit(cache=True, inline="always")
def _contacts_range(lo, hi, grains, nbr_start, nbr, p, spill_force, spill_torque, spill_viscous_damping,
                    contact_count):
    """The contact loop (_contacts_range_with), with the optional terms when the case switches one on."""
    if laws.optional_terms(p):
        return _contacts_range_optional(lo, hi, grains, nbr_start, nbr, p, spill_force, spill_torque,
                                        spill_viscous_damping, contact_count)
    return _contacts_range_plain(lo, hi, grains, nbr_start, nbr, p, spill_force, spill_torque,
                                 spill_viscous_damping, contact_count)


def _contacts_range_with(optional):
    """The contact loop with the optional contact terms (laws.optional_terms) compiled in or out
    (a constant of the closure)."""

    @nb.njit(cache=True, fastmath=FASTMATH)
    def contacts_range(lo, hi, grains, nbr_start, nbr, p, spill_force, spill_torque, spill_viscous_damping,
                       contact_count):
        """Forces and torques of grains lo..hi-1 and their list pairs; zeroes rows lo..hi-1 first.

        Reactions on j >= hi go to spill_force/spill_torque/spill_viscous_damping (row j).
        contact_count[i] (if not empty): touching pairs of grain i's list plus its wall contacts.
        Returns (max overlap of dynamic grains, max overlap with a feed grain, one past the largest
        spilled j or hi). The walls of grain i are handled in the same pass as its pairs, so that its
        force sums stay in registers (one pass instead of two: 1.24x faster on the standard packing,
        docs/performance.md).
        """
        pos, vel, omg, force, _, torque, viscous_damping, wall_normal, _, in_feed, _ = grains
        force[lo:hi] = 0.0
        torque[lo:hi] = 0.0
        viscous_damping[lo:hi] = 0.0
        pair = laws.pair_constants(p)
        wall = laws.wall_constants(p)
        r = p.radius
        dia = 2.0 * r
        inner = p.tube_radius - r  # analytic cylinder: overlap = rho + r - R
        max_overlap = 0.0
        max_feed = 0.0
        top = hi
        counting = contact_count.shape[0] > 0
        implicit = p.implicit_spin > 0.0  # viscous_damping is only read (and summed) then
        end = nb.uint64(hi)  # partners are unsigned: no wrap-around of negative indices (1.04-1.05x)
        for i in range(lo, hi):
            touching = 0
            xi = pos[i, 0]
            yi = pos[i, 1]
            zi = pos[i, 2]
            fxi = 0.0
            fyi = 0.0
            fzi = 0.0
            txi = 0.0
            tyi = 0.0
            tzi = 0.0
            gsum = 0.0
            for k in range(nbr_start[i], nbr_start[i + 1]):
                j = nb.uint64(nbr[k])
                dx = pos[j, 0] - xi
                dy = pos[j, 1] - yi
                dz = pos[j, 2] - zi
                dist2 = dx * dx + dy * dy + dz * dz
                if dist2 >= dia * dia:
                    continue
                touching += 1
                dist = math.sqrt(dist2)
                inv = 1.0 / dist
                nx = dx * inv
                ny = dy * inv
                nz = dz * inv
                delta = dia - dist
                if in_feed[i] or in_feed[j]:
                    max_feed = max(max_feed, delta)
                else:
                    max_overlap = max(max_overlap, delta)
                vrx = vel[i, 0] - vel[j, 0]
                vry = vel[i, 1] - vel[j, 1]
                vrz = vel[i, 2] - vel[j, 2]
                fn = laws.normal_force(delta, vrx * nx + vry * ny + vrz * nz, pair)
                if fn <= 0.0:
                    continue
                fx, fy, fz, tx, ty, tz, tjx, tjy, tjz, g = laws.surface_forces(
                    fn, nx, ny, nz, vrx, vry, vrz, omg[i, 0] + omg[j, 0], omg[i, 1] + omg[j, 1],
                    omg[i, 2] + omg[j, 2], omg[i, 0] - omg[j, 0], omg[i, 1] - omg[j, 1], omg[i, 2] - omg[j, 2],
                    pair, optional)
                gsum += g  # in a register: only its stores below are gated on `implicit`
                # force on i; j gets the opposite
                fxi += fx
                fyi += fy
                fzi += fz
                txi += tx
                tyi += ty
                tzi += tz
                # written out twice on purpose: an inlined helper measured slower on threads (docs/performance.md)
                if j < end:
                    force[j, 0] -= fx
                    force[j, 1] -= fy
                    force[j, 2] -= fz
                    torque[j, 0] += tjx
                    torque[j, 1] += tjy
                    torque[j, 2] += tjz
                    if implicit:
                        viscous_damping[j] += g
                else:
                    spill_force[j, 0] -= fx
                    spill_force[j, 1] -= fy
                    spill_force[j, 2] -= fz
                    spill_torque[j, 0] += tjx
                    spill_torque[j, 1] += tjy
                    spill_torque[j, 2] += tjz
                    if implicit:
                        spill_viscous_damping[j] += g
                    top = max(top, nb.int64(j) + 1)
            wall_normal[i] = 0.0
            if not in_feed[i]:
                rho2 = yi * yi + zi * zi
                if rho2 > inner * inner:
                    rho = math.sqrt(rho2)
                    touching += 1
                    delta = rho - inner
                    max_overlap = max(max_overlap, delta)
                    fn, fx, fy, fz, tx, ty, tz, g = laws.wall_contact(
                        delta, 0.0, yi / rho, zi / rho, vel[i, 0], vel[i, 1], vel[i, 2],
                        omg[i, 0], omg[i, 1], omg[i, 2], wall, optional)
                    wall_normal[i] = fn
                    gsum += g
                    fxi += fx
                    fyi += fy
                    fzi += fz
                    txi += tx
                    tyi += ty
                    tzi += tz
                if xi < r:  # the inlet wall at x = 0
                    delta = r - xi
                    max_overlap = max(max_overlap, delta)
                    fn, fx, fy, fz, tx, ty, tz, g = laws.wall_contact(
                        delta, -1.0, 0.0, 0.0, vel[i, 0], vel[i, 1], vel[i, 2],
                        omg[i, 0], omg[i, 1], omg[i, 2], wall, optional)
                    gsum += g
                    fxi += fx
                    fyi += fy
                    fzi += fz
                    txi += tx
                    tyi += ty
                    tzi += tz
            force[i, 0] += fxi
            force[i, 1] += fyi
            force[i, 2] += fzi
            torque[i, 0] += txi
            torque[i, 1] += tyi
            torque[i, 2] += tzi
            if implicit:
                viscous_damping[i] += gsum
            if counting:
                contact_count[i] = touching
        return max_overlap, max_feed, top

    return contacts_range


_contacts_range_plain = _contacts_range_with(False)
_contacts_range_optional = _contacts_range_with(True)

"""Contact forces of one thread in passes over flat lists (the default; contacts.evaluate_contacts).

The half neighbour list is read as flat entries k (grain nbr_i[k], partner nbr[k] > nbr_i[k]), in
blocks of BLOCK entries, so that the work rows of a block stay in the L1 cache and no loop runs
over one grain's few partners (each such loop's exit is a mispredicted branch):

1. compact: the touching pairs of the block's entries, branch-free, to pair_i, pair_j;
2. gather: their offsets, relative velocities and spin sums into rows of `rows`, one per quantity;
3. pair law: laws.pair_normal and laws.surface_forces, branch-free over the rows (packed SIMD);
4. scatter: each pair's force and torques added to both grains, in list order.

Then the walls: the cylinder's law branch-free over all grains, and the inlet's for the grains
within r of x = 0. The sums run in another order than the single loop's (contacts._contacts_range),
so the forces differ from it in the last bits. Measured against it: docs/performance.md, "The
contact kernel".
"""

import math

import numba as nb
import numpy as np

from . import laws
from .laws import FASTMATH
from .state import Pairs

BLOCK = 128  # list entries per block: its 23 work rows of 128 doubles, 23 KiB, stay in the L1 cache

# Offsets of the rows of Pairs.rows (BLOCK values each) per touching pair: inputs offset D = x_j - x_i
# and |D|^2, relative velocity v_i - v_j, spin sum w_i + w_j, relative spin w_i - w_j (optional terms);
# outputs force and torque on i, gamma_t if viscous, torque on j (optional terms).
(DX, DY, DZ, D2, VX, VY, VZ, WX, WY, WZ, RWX, RWY, RWZ,
 FX, FY, FZ, TX, TY, TZ, G, TJX, TJY, TJZ) = [row * BLOCK for row in range(23)]
ROWS = 23


def pair_buffers() -> Pairs:
    """Work arrays of contact_passes (one block)."""
    # unsigned pair indices: numba then skips the wrap-around of negative indices
    return Pairs(np.zeros(BLOCK, dtype=np.uint32), np.zeros(BLOCK, dtype=np.uint32), np.zeros(ROWS * BLOCK))


@nb.njit(cache=True)
def contact_passes(grains, n, nbr_start, nbr, nbr_i, p, diag, pairs):
    """Zero, then accumulate the grain-grain, cylinder-wall and inlet-wall forces and torques (and,
    with numerics.implicit_spin, viscous_damping; wall_normal), as contacts.contact_forces.

    diag[0]: max overlap of dynamic grains (pairs and walls), diag[1]: max overlap with a feed grain, m.
    """
    if laws.optional_terms(p):
        _contact_passes_optional(grains, n, nbr_start, nbr, nbr_i, p, diag, pairs)
    else:
        _contact_passes_plain(grains, n, nbr_start, nbr, nbr_i, p, diag, pairs)


@nb.njit(cache=True)
def _last_feed(in_feed, n):
    """The largest index of a feed grain among grains 0..n-1, or -1 (list entry k of a pair with a feed
    grain then lies below nbr_start[_last_feed + 1], since its grain nbr_i[k] < nbr[k])."""
    last = -1
    for i in range(n):
        last = i if in_feed[i] else last
    return last


@nb.njit(cache=True, inline="always")
def flat_rows(a):
    """The (n, 3) C-contiguous array a as one row: component d of grain i at 3 i + d."""
    return a.reshape(a.size)


@nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _compact(lo, hi, pos, nbr_i, nbr, dia2, pair_i, pair_j):
    """The touching pairs (centres closer than 2r) of list entries lo..hi-1, in list order, into
    pair_i, pair_j; returns their number. Branch-free: every entry is written at the next free
    slot, which only a touching one then keeps; a nan distance counts as touching."""
    m = 0
    for k in range(lo, hi):
        i = nb.uint64(nbr_i[k])
        j = nb.uint64(nbr[k])
        a = nb.uint64(3) * i
        b = nb.uint64(3) * j
        dx = pos[b] - pos[a]
        dy = pos[b + 1] - pos[a + 1]
        dz = pos[b + 2] - pos[a + 2]
        pair_i[m] = i
        pair_j[m] = j
        m += 0 if dx * dx + dy * dy + dz * dz >= dia2 else 1
    return m


def _passes_with(optional):
    """The passes and their driver with the optional contact terms (laws.optional_terms) compiled in
    or out (a constant of the closure)."""

    @nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
    def gather(m, pos, vel, omg, in_feed, feed, pair_i, pair_j, rows):
        """Offset, |offset|^2, relative velocity and spin sum (and relative spin) of the m pairs into
        their rows. Returns the smallest |offset|^2 of a pair of dynamic grains and of a pair with a
        feed grain (inf if none); without `feed` every pair counts as one of dynamic grains (the
        grains' feed flags are not read)."""
        dmin = np.inf
        fmin = np.inf
        for c in range(m):
            a = nb.uint64(3) * nb.uint64(pair_i[c])
            b = nb.uint64(3) * nb.uint64(pair_j[c])
            dx = pos[b] - pos[a]
            dy = pos[b + 1] - pos[a + 1]
            dz = pos[b + 2] - pos[a + 2]
            d2 = dx * dx + dy * dy + dz * dz
            rows[DX + c] = dx
            rows[DY + c] = dy
            rows[DZ + c] = dz
            rows[D2 + c] = d2
            rows[VX + c] = vel[a] - vel[b]
            rows[VY + c] = vel[a + 1] - vel[b + 1]
            rows[VZ + c] = vel[a + 2] - vel[b + 2]
            rows[WX + c] = omg[a] + omg[b]
            rows[WY + c] = omg[a + 1] + omg[b + 1]
            rows[WZ + c] = omg[a + 2] + omg[b + 2]
            if optional:
                rows[RWX + c] = omg[a] - omg[b]
                rows[RWY + c] = omg[a + 1] - omg[b + 1]
                rows[RWZ + c] = omg[a + 2] - omg[b + 2]
            if feed:  # the same for every pair of the call: LLVM moves the test out of the loop
                with_feed = (in_feed[pair_i[c]] != 0) | (in_feed[pair_j[c]] != 0)  # |: no branch
                dmin = min(dmin, np.inf if with_feed else d2)
                fmin = min(fmin, d2 if with_feed else np.inf)
            else:
                dmin = min(dmin, d2)
        return dmin, fmin

    @nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
    def pair_law(m, p, rows):
        """The contact law of the m pairs, elementwise and branch-free over the rows (packed SIMD):
        force and torques on i, the torque on j (optional terms) and gamma_t if viscous; zeros where
        the normal force pulls."""
        pair = laws.pair_constants(p)
        for c in range(m):
            dx = rows[DX + c]
            dy = rows[DY + c]
            dz = rows[DZ + c]
            vx = rows[VX + c]
            vy = rows[VY + c]
            vz = rows[VZ + c]
            fn, inv, a, vd, _ = laws.pair_normal(dx, dy, dz, rows[D2 + c], vx, vy, vz, pair)
            if optional:
                rwx = rows[RWX + c]
                rwy = rows[RWY + c]
                rwz = rows[RWZ + c]
            else:
                rwx = rwy = rwz = 0.0
            fx, fy, fz, tx, ty, tz, tjx, tjy, tjz, g = laws.surface_forces(
                fn, inv, a, vd, dx, dy, dz, vx, vy, vz, rows[WX + c], rows[WY + c], rows[WZ + c], rwx, rwy, rwz,
                pair, optional, True)
            on = not (fn <= 0.0)  # selects: a nan fn keeps its values
            rows[FX + c] = fx if on else 0.0
            rows[FY + c] = fy if on else 0.0
            rows[FZ + c] = fz if on else 0.0
            rows[TX + c] = tx if on else 0.0
            rows[TY + c] = ty if on else 0.0
            rows[TZ + c] = tz if on else 0.0
            rows[G + c] = g if on else 0.0
            if optional:
                rows[TJX + c] = tjx if on else 0.0
                rows[TJY + c] = tjy if on else 0.0
                rows[TJZ + c] = tjz if on else 0.0

    @nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
    def scatter(m, force, torque, viscous_damping, implicit, pair_i, pair_j, rows):
        """Add the m pairs' forces and torques to both grains (i gets F, j -F), and gamma_t to both
        viscous_damping sums if `implicit`."""
        tjx_row = TJX if optional else TX
        tjy_row = TJY if optional else TY
        tjz_row = TJZ if optional else TZ
        for c in range(m):
            a = nb.uint64(3) * nb.uint64(pair_i[c])
            b = nb.uint64(3) * nb.uint64(pair_j[c])
            fx = rows[FX + c]
            fy = rows[FY + c]
            fz = rows[FZ + c]
            force[a] += fx
            force[a + 1] += fy
            force[a + 2] += fz
            torque[a] += rows[TX + c]
            torque[a + 1] += rows[TY + c]
            torque[a + 2] += rows[TZ + c]
            force[b] -= fx
            force[b + 1] -= fy
            force[b + 2] -= fz
            torque[b] += rows[tjx_row + c]
            torque[b + 1] += rows[tjy_row + c]
            torque[b + 2] += rows[tjz_row + c]
            if implicit:
                viscous_damping[pair_i[c]] += rows[G + c]
                viscous_damping[pair_j[c]] += rows[G + c]

    @nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
    def walls(grains, n, p, pos, vel, omg, force, torque, implicit):
        """The cylinder's and the inlet's contacts of the dynamic grains added to force and torque (the
        grains' flat rows), viscous_damping if `implicit`, and wall_normal (the cylinder's normal
        force, 0 without contact). Returns the largest wall overlap.

        The cylinder's law (laws.cylinder_contact) is evaluated for every grain without a branch, so
        that the loop vectorises: a grain off the wall at a point on it (finite values), its results
        multiplied by 0. The largest overlap is taken in a loop of its own (a maximum in the law's
        loop keeps it scalar: 1.8x the time). The inlet's law only for a grain within r of x = 0.
        """
        in_feed, wall_normal, viscous_damping = grains.in_feed, grains.wall_normal, grains.viscous_damping
        wall = laws.wall_constants(p)
        r = p.radius
        inner = p.tube_radius - r  # analytic cylinder: overlap = rho + r - R
        inner2 = inner * inner
        for i in range(n):
            k = 3 * i
            y = pos[k + 1]
            z = pos[k + 2]
            on = (in_feed[i] == 0) & (y * y + z * z > inner2)  # &: no branch
            fn, fx, fy, fz, tx, ty, tz, g, _ = laws.cylinder_contact(
                y if on else inner, z if on else 0.0, vel[k], vel[k + 1], vel[k + 2], omg[k], omg[k + 1], omg[k + 2],
                inner, wall, optional, True)
            keep = 1.0 if on & (not (fn <= 0.0)) else 0.0  # a nan fn is kept: the run's guard sees it
            force[k] += keep * fx
            force[k + 1] += keep * fy
            force[k + 2] += keep * fz
            torque[k] += keep * tx
            torque[k + 1] += keep * ty
            torque[k + 2] += keep * tz
            if implicit:
                viscous_damping[i] += keep * g
            wall_normal[i] = keep * fn
        rho2 = 0.0
        for i in range(n):
            k = 3 * i
            rho2 = max(rho2, pos[k + 1] * pos[k + 1] + pos[k + 2] * pos[k + 2] if in_feed[i] == 0 else 0.0)
        largest = max(0.0, math.sqrt(rho2) - inner)
        for i in range(n):  # the inlet wall at x = 0
            k = 3 * i
            x = pos[k]
            if in_feed[i] or not (x < r):
                continue
            delta = r - x
            largest = max(largest, delta)
            fn, fx, fy, fz, tx, ty, tz, g = laws.wall_contact(
                delta, -1.0, 0.0, 0.0, vel[k], vel[k + 1], vel[k + 2], omg[k], omg[k + 1], omg[k + 2], wall,
                optional)
            force[k] += fx
            force[k + 1] += fy
            force[k + 2] += fz
            torque[k] += tx
            torque[k + 1] += ty
            torque[k + 2] += tz
            if implicit:
                viscous_damping[i] += g
        return largest

    @nb.njit(cache=True)
    def run(grains, n, nbr_start, nbr, nbr_i, p, diag, pairs):
        """contact_passes with the optional terms compiled in or out."""
        pos = flat_rows(grains.pos)
        vel = flat_rows(grains.vel)
        omg = flat_rows(grains.omg)
        force = flat_rows(grains.force)
        torque = flat_rows(grains.torque)
        force[:3 * n] = 0.0
        torque[:3 * n] = 0.0
        grains.viscous_damping[:n] = 0.0
        implicit = p.implicit_spin > 0.0  # viscous_damping is only read (and summed) then
        dia = 2.0 * p.radius
        dmin = np.inf
        fmin = np.inf
        entries = nbr_start[n]
        feed_end = nbr_start[_last_feed(grains.in_feed, n) + 1]  # every pair with a feed grain lies before
        for lo in range(0, entries, BLOCK):
            m = _compact(lo, min(entries, lo + BLOCK), pos, nbr_i, nbr, dia * dia, pairs.pair_i, pairs.pair_j)
            d, f = gather(m, pos, vel, omg, grains.in_feed, lo < feed_end, pairs.pair_i, pairs.pair_j, pairs.rows)
            pair_law(m, p, pairs.rows)
            scatter(m, force, torque, grains.viscous_damping, implicit, pairs.pair_i, pairs.pair_j, pairs.rows)
            dmin = min(dmin, d)
            fmin = min(fmin, f)
        wall_overlap = walls(grains, n, p, pos, vel, omg, force, torque, implicit)
        # the largest overlap 2r - sqrt(d2) is that of the smallest d2 (both roundings are monotone)
        diag[0] = max(max(0.0, dia - math.sqrt(dmin)), wall_overlap)
        diag[1] = max(0.0, dia - math.sqrt(fmin))

    return gather, pair_law, scatter, walls, run


_gather_plain, _pair_law_plain, _scatter_plain, _walls_plain, _contact_passes_plain = _passes_with(False)
_gather_optional, _pair_law_optional, _scatter_optional, _walls_optional, _contact_passes_optional = \
    _passes_with(True)

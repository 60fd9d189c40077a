"""Contact forces: grain-grain (half neighbour list), grain-cylinder wall and the inlet wall at x = 0.

The loops over contacts; the laws they apply are in laws.py. `grains` is a state.Grains.

evaluate_contacts runs one of three: on one thread the contacts in passes over flat lists
(passes.contact_passes, the default) or the single loop (contact_forces: a grain's pairs, the
reactions scattered inside, then its walls; Simulation.set_contact_passes(False)); on threads
the single loop over chunks of grains (contact_forces_chunked). The three add the same terms in
different orders, so their forces differ in the last bits. Measured against each other:
docs/performance.md, "The contact kernel".
"""

import math

import numba as nb
import numpy as np

from . import laws
from .laws import FASTMATH
from .passes import contact_passes
from .state import Pairs

@nb.njit(cache=True)
def contact_forces(grains, n, nbr_start, nbr, p, diag):
    """The single loop on one thread: zero, then accumulate the grain-grain, cylinder-wall and
    inlet-wall forces and torques.

    diag[0]: max overlap of dynamic grains (pairs and walls), diag[1]: max overlap with a feed
    grain, m. viscous_damping[i]: the sum of gamma_t over grain i's contacts in the viscous branch,
    N s/m (the implicit spin kick's denominator, numerics.implicit_spin; summed only when that is on).
    wall_normal[i]: normal force of the cylinder on grain i, N (0 without contact).
    Pairs with a kinematic (feed) grain act on the dynamic grain only; the feed drives the other.
    """
    max_overlap, max_feed, _ = _contacts_range(0, n, grains, nbr_start, nbr, p, grains.force, grains.torque,
                                               grains.viscous_damping, nbr_start[:0])
    diag[0] = max_overlap
    diag[1] = max_feed


@nb.njit(cache=True)
def evaluate_contacts(grains, n, nbr_start, nbr, nbr_i, p, diag, chunks, pairs):
    """The contact forces (contact_forces): on threads when chunks (a state.Chunks) has more than one
    chunk (bounds holds nchunks + 1 entries; contact_forces_chunked), else in passes when `pairs`
    (a state.Pairs) holds their work arrays (passes.pair_buffers; passes.contact_passes), else in the
    single loop (empty ones, single_loop_buffers). nbr_i[k]: the grain whose list holds entry k."""
    if chunks.bounds.shape[0] > 2:
        contact_forces_chunked(grains, n, nbr_start, nbr, p, diag, chunks)
    elif pairs.rows.shape[0] > 0:
        contact_passes(grains, n, nbr_start, nbr, nbr_i, p, diag, pairs)
    else:
        contact_forces(grains, n, nbr_start, nbr, p, diag)


def single_loop_buffers() -> Pairs:
    """Empty work arrays: evaluate_contacts then runs the single loop on one thread."""
    return Pairs(np.zeros(0, dtype=np.uint32), np.zeros(0, dtype=np.uint32), np.zeros(0))


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
                vrx = vel[i, 0] - vel[j, 0]
                vry = vel[i, 1] - vel[j, 1]
                vrz = vel[i, 2] - vel[j, 2]
                fn, inv, a, vd, delta = laws.pair_normal(dx, dy, dz, dist2, vrx, vry, vrz, pair)
                if in_feed[i] or in_feed[j]:
                    max_feed = max(max_feed, delta)
                else:
                    max_overlap = max(max_overlap, delta)
                if fn <= 0.0:
                    continue
                fx, fy, fz, tx, ty, tz, tjx, tjy, tjz, g = laws.surface_forces(
                    fn, inv, a, vd, dx, dy, dz, vrx, vry, vrz, omg[i, 0] + omg[j, 0], omg[i, 1] + omg[j, 1],
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
                if yi * yi + zi * zi > inner * inner:
                    touching += 1
                    fn, fx, fy, fz, tx, ty, tz, g, delta = laws.cylinder_contact(
                        yi, zi, vel[i, 0], vel[i, 1], vel[i, 2], omg[i, 0], omg[i, 1], omg[i, 2], inner, wall, optional)
                    max_overlap = max(max_overlap, delta)
                    if not (fn <= 0.0):  # a nan fn passes: the run's guard sees it
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

"""Cell lists and the Verlet neighbour list for a long thin tube.

Cells are boxes of at least the list cutoff d + skin: many along x, a few across (the 7 mm tube
holds 3 x 3 at the default skin). Grains are sorted by cell at every rebuild, so neighbours sit
close in memory; grains past the outlet are dropped in the same pass.
"""

import numba as nb
import numpy as np

from . import indices


@nb.njit(cache=True, inline="always")
def _cell_index(x, y, z, p, shape):
    """(cx, cy, cz) of a point, clamped to the grid (clamping only merges far cells, never splits)."""
    cx = int((x - p.cell_x0) / p.cell_dx)
    half = p.tube_radius
    cy = int((y + half) / p.cell_dyz)
    cz = int((z + half) / p.cell_dyz)
    cx = min(max(cx, 0), shape[indices.NCX] - 1)
    cy = min(max(cy, 0), shape[indices.NCY] - 1)
    cz = min(max(cz, 0), shape[indices.NCZ] - 1)
    return cx, cy, cz


@nb.njit(cache=True)
def sort_and_compact(pos, vel, omg, drag, gid, in_feed, n, p, shape, cell_start, cell_of, order, tmp3, tmpi,
                     counters):
    """Drop dynamic grains past x = L (counted in counters[REMOVED]), sort the rest by cell.

    Returns the new number of grains. cell_start (ncells + 1) holds each cell's first sorted index.
    """
    length = p.tube_length
    ncy = shape[indices.NCY]
    ncz = shape[indices.NCZ]
    ncells = shape[indices.NCX] * ncy * ncz
    cell_start[:] = 0
    n_removed = 0
    for i in range(n):
        if pos[i, 0] > length and not in_feed[i]:
            cell_of[i] = -1
            n_removed += 1
            continue
        cx, cy, cz = _cell_index(pos[i, 0], pos[i, 1], pos[i, 2], p, shape)
        c = (cx * ncy + cy) * ncz + cz
        cell_of[i] = c
        cell_start[c + 1] += 1
    for c in range(ncells):
        cell_start[c + 1] += cell_start[c]
    # counting sort: order[new] = old, with cell_start as the fill pointers (no allocation in the
    # time loop): afterwards cell_start[c] holds the end of cell c, so shift it back by one cell
    for i in range(n):
        c = cell_of[i]
        if c >= 0:
            order[cell_start[c]] = i
            cell_start[c] += 1
    for c in range(ncells, 0, -1):
        cell_start[c] = cell_start[c - 1]
    cell_start[0] = 0
    m = n - n_removed
    for arr in (pos, vel, omg, drag):  # drag is held between gas updates: it moves with its grain
        for k in range(m):
            o = order[k]
            tmp3[k, 0] = arr[o, 0]
            tmp3[k, 1] = arr[o, 1]
            tmp3[k, 2] = arr[o, 2]
        arr[:m] = tmp3[:m]
    for k in range(m):
        tmpi[k] = gid[order[k]]
    gid[:m] = tmpi[:m]
    for k in range(m):
        tmpi[k] = in_feed[order[k]]
    in_feed[:m] = tmpi[:m]
    counters[indices.REMOVED] += n_removed
    return m


@nb.njit(cache=True)
def _half_stencil_runs(cx, cy, cz, shape, cell_start, run_lo, run_hi):
    """Grain ranges of the half stencil of cell (cx, cy, cz), in ascending cell order.

    Grains are sorted by cell, so every j > i of a grain in this cell lies in this cell or in the 13
    neighbour cells of larger index (the other 13 hold only j < i). For fixed (ax, ay) the cells
    along z are consecutive, so their grains form one contiguous range: at most five ranges.
    Returns their number; range r is run_lo[r] <= j < run_hi[r].
    """
    ncx = shape[indices.NCX]
    ncy = shape[indices.NCY]
    ncz = shape[indices.NCZ]
    runs = 0
    for ax in range(cx, min(cx + 2, ncx)):
        for ay in range(cy if ax == cx else max(cy - 1, 0), min(cy + 2, ncy)):
            z_lo = cz if ax == cx and ay == cy else max(cz - 1, 0)
            z_hi = min(cz + 2, ncz)
            c = (ax * ncy + ay) * ncz
            run_lo[runs] = cell_start[c + z_lo]
            run_hi[runs] = cell_start[c + z_hi]
            runs += 1
    return runs


@nb.njit(cache=True)
def build_neighbor_list(pos, in_feed, n, p, shape, cell_start, nbr_start, nbr, nbr_i):
    """Half neighbour list (j > i, centres closer than d + skin) of cell-sorted grains: grain i's
    partners are nbr[nbr_start[i]:nbr_start[i + 1]], and nbr_i[k] is the grain whose entry k is.

    Each grain's partners are listed in ascending index (the order the contact sums take). Returns
    the number of pairs, or -1 if nbr may be too small: room is checked for every candidate of a
    range before it is tested (the caller grows nbr and calls again). Pairs of two kinematic (feed)
    grains are skipped. The loop runs over cells, so a cell's grains share its stencil's ranges.
    """
    cut = 2.0 * p.radius + p.skin
    cut2 = cut * cut
    ncx = shape[indices.NCX]
    ncy = shape[indices.NCY]
    ncz = shape[indices.NCZ]
    cap = nbr.shape[0]
    run_lo = np.empty(5, np.int64)
    run_hi = np.empty(5, np.int64)
    k = 0
    for cx in range(ncx):
        for cy in range(ncy):
            for cz in range(ncz):
                c = (cx * ncy + cy) * ncz + cz
                if cell_start[c] == cell_start[c + 1]:
                    continue
                runs = _half_stencil_runs(cx, cy, cz, shape, cell_start, run_lo, run_hi)
                for i in range(cell_start[c], cell_start[c + 1]):
                    nbr_start[i] = k
                    xi = pos[i, 0]
                    yi = pos[i, 1]
                    zi = pos[i, 2]
                    feed_i = in_feed[i]
                    for r in range(runs):
                        lo = max(run_lo[r], i + 1)
                        hi = run_hi[r]
                        if k + hi - lo > cap:
                            return -1
                        # branch-free: every candidate is written, the next slot taken only if it is kept
                        for j in range(nb.uint64(lo), nb.uint64(hi)):
                            dx = pos[j, 0] - xi
                            dy = pos[j, 1] - yi
                            dz = pos[j, 2] - zi
                            keep = dx * dx + dy * dy + dz * dz < cut2 and not (feed_i and in_feed[j])
                            nbr[k] = j
                            nbr_i[k] = i
                            k += keep
    nbr_start[n] = k
    return k

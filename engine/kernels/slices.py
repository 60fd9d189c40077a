"""Slice averages along the tube (papers §3.2): each grain weighted by the volume it has in a slice."""

import math

import numba as nb

# Columns of the slice accumulator
SOLID = 0        # solid volume in the slice, m3
WEIGHT = 1       # sum of w = (volume in slice) / V_p
VEL = 2          # sum of w v_x
DRAG = 3         # sum of w F_drag,x
PART = 4         # sum of w F_particle,x (contacts + walls + axial gravity)
WALL = 5         # sum of w |F_wall,normal|
KIN = 6          # sum of w |v|^2
VY = 7           # sum of w v_y
VZ = 8           # sum of w v_z
NCOLS = 9


@nb.njit(cache=True, inline="always")
def _volume_below(t, x, r):
    """Volume of a sphere (centre x, radius r) on the side x' < t: a spherical cap, m3."""
    h = min(max(t - (x - r), 0.0), 2.0 * r)
    return math.pi * h * h * (3.0 * r - h) / 3.0


@nb.njit(cache=True)
def accumulate_slices(pos, vel, contact_force, drag_force, wall_normal, in_feed, n, r, mass, gx, width, acc):
    """Add each dynamic grain's volume-weighted contributions to the slices of `width` (m) from x=0.

    acc has shape (nslices, NCOLS) and is zeroed here.
    """
    acc[:] = 0.0
    nslices = acc.shape[0]
    vp = 4.0 / 3.0 * math.pi * r**3
    for i in range(n):
        if in_feed[i]:
            continue
        x = pos[i, 0]
        first = max(int((x - r) / width), 0)
        last = min(int((x + r) / width), nslices - 1)
        vx = vel[i, 0]
        vy = vel[i, 1]
        vz = vel[i, 2]
        v2 = vx * vx + vy * vy + vz * vz
        fpart = contact_force[i, 0] + mass * gx
        for s in range(first, last + 1):
            vol = _volume_below((s + 1) * width, x, r) - _volume_below(s * width, x, r)
            if vol <= 0.0:
                continue
            w = vol / vp
            acc[s, SOLID] += vol
            acc[s, WEIGHT] += w
            acc[s, VEL] += w * vx
            acc[s, VY] += w * vy
            acc[s, VZ] += w * vz
            acc[s, DRAG] += w * drag_force[i, 0]
            acc[s, PART] += w * fpart
            acc[s, WALL] += w * wall_normal[i]
            acc[s, KIN] += w * v2

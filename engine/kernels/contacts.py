"""Contact forces: grain-grain (half neighbour list), grain-cylinder wall and the inlet wall at x = 0.

Normal: F_n = max(0, k_n delta + gamma_n v_n) along the line of centres (never attractive).
Tangential: F_t = -min(mu F_n, gamma_t |v_t|) v_t/|v_t| at the contact point (no history), with
v_t the tangential slip velocity of the contact point including rotation.
"""

import math

import numba as nb

from . import params as P

# fastmath without nnan/ninf so that the blow-up guards (isfinite) keep working.
FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _tangential(vcx, vcy, vcz, nx, ny, nz, fn, mu, gt):
    """Tangential force (on the first body) from the contact-point velocity vc = v1 - v2."""
    vcn = vcx * nx + vcy * ny + vcz * nz
    vtx = vcx - vcn * nx
    vty = vcy - vcn * ny
    vtz = vcz - vcn * nz
    vt = math.sqrt(vtx * vtx + vty * vty + vtz * vtz)
    if vt <= 0.0:
        return 0.0, 0.0, 0.0
    ft = min(mu * fn, gt * vt)
    s = -ft / vt
    return s * vtx, s * vty, s * vtz


@nb.njit(cache=True, fastmath=FASTMATH)
def pair_forces(pos, vel, omg, kin, n, nbr_start, nbr, p, force, torque, diag):
    """Add grain-grain contact forces and torques; diag[0] max overlap (m), diag[1] max feed overlap.

    force and torque must be zeroed by the caller. Pairs with a kinematic (feed) grain act on the
    dynamic grain only; the kinematic one is driven by the feed.
    """
    r = p[P.RADIUS]
    dia = 2.0 * r
    kn = p[P.KN]
    gn = p[P.GN_PAIR]
    gt = p[P.GT]
    mu = p[P.MU_PAIR]
    max_overlap = 0.0
    max_feed = 0.0
    for i in range(n):
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        fxi = 0.0
        fyi = 0.0
        fzi = 0.0
        txi = 0.0
        tyi = 0.0
        tzi = 0.0
        for k in range(nbr_start[i], nbr_start[i + 1]):
            j = nbr[k]
            dx = pos[j, 0] - xi
            dy = pos[j, 1] - yi
            dz = pos[j, 2] - zi
            dist2 = dx * dx + dy * dy + dz * dz
            if dist2 >= dia * dia:
                continue
            dist = math.sqrt(dist2)
            inv = 1.0 / dist
            nx = dx * inv
            ny = dy * inv
            nz = dz * inv
            delta = dia - dist
            if kin[i] or kin[j]:
                max_feed = max(max_feed, delta)
            else:
                max_overlap = max(max_overlap, delta)
            vrx = vel[i, 0] - vel[j, 0]
            vry = vel[i, 1] - vel[j, 1]
            vrz = vel[i, 2] - vel[j, 2]
            fn = kn * delta + gn * (vrx * nx + vry * ny + vrz * nz)
            if fn <= 0.0:
                continue
            wx = omg[i, 0] + omg[j, 0]
            wy = omg[i, 1] + omg[j, 1]
            wz = omg[i, 2] + omg[j, 2]
            ftx, fty, ftz = _tangential(vrx + r * (wy * nz - wz * ny), vry + r * (wz * nx - wx * nz),
                                        vrz + r * (wx * ny - wy * nx), nx, ny, nz, fn, mu, gt)
            # force on i; j gets the opposite; both get the same torque r n x F_t
            fx = -fn * nx + ftx
            fy = -fn * ny + fty
            fz = -fn * nz + ftz
            tx = r * (ny * ftz - nz * fty)
            ty = r * (nz * ftx - nx * ftz)
            tz = r * (nx * fty - ny * ftx)
            fxi += fx
            fyi += fy
            fzi += fz
            txi += tx
            tyi += ty
            tzi += tz
            force[j, 0] -= fx
            force[j, 1] -= fy
            force[j, 2] -= fz
            torque[j, 0] += tx
            torque[j, 1] += ty
            torque[j, 2] += tz
        force[i, 0] += fxi
        force[i, 1] += fyi
        force[i, 2] += fzi
        torque[i, 0] += txi
        torque[i, 1] += tyi
        torque[i, 2] += tzi
    diag[0] = max_overlap
    diag[1] = max_feed


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _wall_contact(i, delta, nx, ny, nz, vel, omg, p, force, torque):
    """Contact of grain i with a wall of outward normal n (grain -> wall), overlap delta > 0.

    Returns the normal force magnitude, N."""
    r = p[P.RADIUS]
    vx = vel[i, 0]
    vy = vel[i, 1]
    vz = vel[i, 2]
    fn = p[P.KN] * delta + p[P.GN_WALL] * (vx * nx + vy * ny + vz * nz)
    if fn <= 0.0:
        return 0.0
    wx = omg[i, 0]
    wy = omg[i, 1]
    wz = omg[i, 2]
    ftx, fty, ftz = _tangential(vx + r * (wy * nz - wz * ny), vy + r * (wz * nx - wx * nz),
                                vz + r * (wx * ny - wy * nx), nx, ny, nz, fn, p[P.MU_WALL], p[P.GT])
    force[i, 0] += -fn * nx + ftx
    force[i, 1] += -fn * ny + fty
    force[i, 2] += -fn * nz + ftz
    torque[i, 0] += r * (ny * ftz - nz * fty)
    torque[i, 1] += r * (nz * ftx - nx * ftz)
    torque[i, 2] += r * (nx * fty - ny * ftx)
    return fn


@nb.njit(cache=True, fastmath=FASTMATH)
def wall_forces(pos, vel, omg, kin, n, p, force, torque, wall_normal, diag):
    """Add cylinder-wall and inlet-wall forces on dynamic grains; raises diag[0] to the wall overlap.

    wall_normal[i] receives the normal force of the cylinder on grain i (N, 0 without contact)."""
    r = p[P.RADIUS]
    inner = p[P.TUBE_RADIUS] - r
    max_overlap = diag[0]
    for i in range(n):
        if kin[i]:
            continue
        y = pos[i, 1]
        z = pos[i, 2]
        rho2 = y * y + z * z
        wall_normal[i] = 0.0
        if rho2 > inner * inner:
            rho = math.sqrt(rho2)
            delta = rho - inner  # analytic cylinder: overlap = rho + r - R
            max_overlap = max(max_overlap, delta)
            wall_normal[i] = _wall_contact(i, delta, 0.0, y / rho, z / rho, vel, omg, p, force, torque)
        x = pos[i, 0]
        if x < r:
            delta = r - x
            max_overlap = max(max_overlap, delta)
            _wall_contact(i, delta, -1.0, 0.0, 0.0, vel, omg, p, force, torque)
    diag[0] = max_overlap

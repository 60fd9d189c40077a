"""Gas pressure kernels (McNamara-Flekkoy model, papers' eqs. 3-9), SI units throughout.

Grid: nx x ny x nz cell-centred nodes; node (i, k, m) sits at x_i = (i + 1/2) hx,
y_k = -R + (k + 1/2) hy, z_m = -R + (m + 1/2) hz with hx = L/nx, hy = 2R/ny, hz = 2R/nz.
Scalar fields are (nx, ny, nz) arrays, u is (nx, ny, nz, 3), the deposit `dep` and the
interpolation source `nodal` are (nx, ny, nz, 4); the parameters g (a named tuple: g.hx,
g.superficial_velocity, ...; declared in engine/parameters.py, GAS) and the geometry arrays (area,
ay, az) come from engine.gas.GasField.  Per grain step the caller runs,
in this order:

    deposit -> update_fields -> volume_sources -> gas_step (once or sub-cycled)
            -> pressure_gradient -> drag_forces

(`couple` does exactly this.)
Every kernel is allocation-free; work arrays are passed in.
"""

from collections import namedtuple

import numba as nb

from .laws import FASTMATH

# The arrays of one gas field, in the order the kernels take them (engine.gas.GasField.arrays)
GasArrays = namedtuple("GasArrays", "pressure dep phi kappa u src nodal wmat wvec area ay az g")



@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _axis_weights(s, n):
    """Clamped 1-D tent weights (eq. 7) at node coordinate s = x/h - 1/2 along an axis of n nodes.

    Returns (i0, i1, w1): weight 1 - w1 on node i0, w1 on i1.  Branch-free clamping puts all the
    weight on the end node between it and the tube edge, so the weights always sum to 1.
    """
    if n == 1:
        return 0, 0, 0.0
    sc = min(max(s, 0.0), n - 1.0)
    i0 = min(int(sc), n - 2)
    return i0, i0 + 1, sc - i0


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _grain_tent(pos, p, g, nx, ny, nz):
    """Tent weights (eq. 7) of grain p on its 8 surrounding nodes: (i0, i1, wx, k0, k1, wy, m0,
    m1, wz) per axis as _axis_weights gives them (corner a: _corner)."""
    r = g.tube_radius
    i0, i1, wx = _axis_weights(pos[p, 0] * (1.0 / g.hx) - 0.5, nx)
    k0, k1, wy = _axis_weights((pos[p, 1] + r) * (1.0 / g.hy) - 0.5, ny)
    m0, m1, wz = _axis_weights((pos[p, 2] + r) * (1.0 / g.hz) - 0.5, nz)
    return i0, i1, wx, k0, k1, wy, m0, m1, wz


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _corner(a, tent, scale):
    """Node (i, k, m) and scale times the tent weight of corner a (0..7: bits x, y, z) of a grain's
    cell, from its _grain_tent (scale first: the deposit's V_p w keeps its order of products)."""
    i0, i1, wx, k0, k1, wy, m0, m1, wz = tent
    i = i1 if a & 4 else i0
    k = k1 if a & 2 else k0
    m = m1 if a & 1 else m0
    w = scale * (wx if a & 4 else 1.0 - wx) * (wy if a & 2 else 1.0 - wy) * (wz if a & 1 else 1.0 - wz)
    return i, k, m, w


@nb.njit(cache=True, fastmath=FASTMATH)
def deposit(pos, vel, n, g, dep):
    """Tent-deposit grain volume and volume-weighted velocity onto the nodes (eq. 8).

    pos, vel: (capacity, 3), first n rows used (m, m/s).  dep (nx, ny, nz, 4) is overwritten:
    dep[..., 0] solid volume (m3), dep[..., 1:4] solid volume times velocity (m3 m/s).  Grains
    outside 0 <= x <= L are skipped; the weights of any other grain sum to 1, so
    sum(dep[..., 0]) = (grains inside) * V_p.
    """
    nx, ny, nz, _ = dep.shape
    dep[:] = 0.0
    vp = g.grain_volume
    length = g.tube_length
    for p in range(n):
        x = pos[p, 0]
        if not (x >= 0.0 and x <= length):
            continue
        tent = _grain_tent(pos, p, g, nx, ny, nz)
        vx = vel[p, 0]
        vy = vel[p, 1]
        vz = vel[p, 2]
        for a in range(8):
            i, k, m, w = _corner(a, tent, vp)
            dep[i, k, m, 0] += w
            dep[i, k, m, 1] += w * vx
            dep[i, k, m, 2] += w * vy
            dep[i, k, m, 3] += w * vz


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def carman_kozeny(phi, g):
    """Permeability (m2) of eq. (4), phi clamped to [phi_min, phi_max].

    No other cap: the papers' model has no wall shear on the gas, so an empty stretch of tube
    carries no pressure gradient and a lone grain feels almost no drag (V §4.3). phi_max only
    keeps the conductances within ~1e7 of a plug's, where the block elimination stays accurate.
    """
    p = min(max(phi, g.porosity_min), g.porosity_max)
    d = g.grain_diameter
    return d * d * p * p * p / (180.0 * (1.0 - p) * (1.0 - p))


@nb.njit(cache=True, fastmath=FASTMATH)
def update_fields(dep, area, g, phi, kappa, u):
    """Node porosity phi, permeability kappa (m2) and grain velocity u (m/s, eq. 8) from a deposit.

    phi_j = max(1 - dep_j0 / V_j, phi_min) with V_j = hx * area[k, m] the node's tube volume, or
    the whole grid cell hx hy hz when g.cell_volume is set (eq. 8 read on the cubic grid);
    nodes outside the tube (area 0) read phi = 1.  u_j = dep_j[1:4] / dep_j0 (0 where no grains).
    phi, kappa: (nx, ny, nz); u: (nx, ny, nz, 3).
    """
    nx, ny, nz = phi.shape
    hx = g.hx
    phi_min = g.porosity_min
    cell = g.cell_volume > 0.5
    for i in range(nx):
        for k in range(ny):
            for m in range(nz):
                vol = hx * area[k, m]
                if cell and vol > 0.0:
                    vol = hx * g.hy * g.hz
                s = dep[i, k, m, 0]
                f = 1.0 - s / vol if vol > 0.0 else 1.0
                f = max(f, phi_min)
                phi[i, k, m] = f
                kappa[i, k, m] = carman_kozeny(f, g)
                inv = 1.0 / s if s > 0.0 else 0.0
                for c in range(3):
                    u[i, k, m, c] = dep[i, k, m, c + 1] * inv


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _face(a, b, g):
    """Face permeability (m2) between nodes of permeability a and b (gas.face_permeability):
    harmonic mean (two half cells in series) or arithmetic mean."""
    if g.face_arithmetic > 0.5:
        return 0.5 * (a + b)
    return 2.0 * a * b / (a + b)


@nb.njit(cache=True, fastmath=FASTMATH)
def volume_sources(u, area, ay, az, g, feed_volume_rate, src):
    """Source term of each node (Pa m3/s): P0 times its net volume inflow, i.e. -P0 V div u (eq. 5)
    plus the boundary fluxes.

    Inlet face: v_s A + feed_volume_rate (the volume m_dot/rho_s of entering grains), shared by
    area.  Outlet face: the grain flux A u_x when open, the prescribed v_s A otherwise.  Interior
    faces carry the face-averaged grain velocity; wall faces carry nothing.
    """
    nx, ny, nz = src.shape
    p0 = g.background_pressure
    atot = g.tube_area
    q_in = g.superficial_velocity * atot + feed_volume_rate
    open_outlet = g.outlet_open > 0.5
    for k in range(ny):
        for m in range(nz):
            a = area[k, m]
            src[0, k, m] = q_in * a / atot
            for i in range(1, nx):
                src[i, k, m] = 0.0
            for i in range(nx - 1):
                f = 0.5 * a * (u[i, k, m, 0] + u[i + 1, k, m, 0])
                src[i, k, m] -= f
                src[i + 1, k, m] += f
            if open_outlet:
                src[nx - 1, k, m] -= a * u[nx - 1, k, m, 0]
            else:
                src[nx - 1, k, m] -= g.superficial_velocity * a
    for i in range(nx):
        for k in range(ny - 1):
            for m in range(nz):
                f = 0.5 * ay[k, m] * (u[i, k, m, 1] + u[i, k + 1, m, 1])
                src[i, k, m] -= f
                src[i, k + 1, m] += f
        for k in range(ny):
            for m in range(nz - 1):
                f = 0.5 * az[k, m] * (u[i, k, m, 2] + u[i, k, m + 1, 2])
                src[i, k, m] -= f
                src[i, k, m + 1] += f
    for i in range(nx):
        for k in range(ny):
            for m in range(nz):
                src[i, k, m] *= p0


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _thomas(a, b, c, d, n):
    """Solve the tridiagonal system (a sub, b diag, c super) in place; the solution ends in d."""
    for j in range(1, n):
        w = a[j] / b[j - 1]
        b[j] -= w * c[j - 1]
        d[j] -= w * d[j - 1]
    d[n - 1] /= b[n - 1]
    for j in range(n - 2, -1, -1):
        d[j] = (d[j] - c[j] * d[j + 1]) / b[j]


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _line_solve(vals, cap, t_lo, t_hi, t_end, src_dt, tdt, edt, a, b, c, d, n):
    """One theta-step of cap dP/dt = flux differences + src along a line; vals in place.

    t_lo[j] couples j-1..j (t_lo[0] = 0), t_hi[j] couples j..j+1, t_end: Dirichlet P' = 0 conductance
    of the last node; tdt = theta dt, edt = (1 - theta) dt.  Conductances in m3/(s Pa) times P0.
    """
    for j in range(n):
        lap = -t_end[j] * vals[j]
        if j > 0:
            lap += t_lo[j] * (vals[j - 1] - vals[j])
        if j < n - 1:
            lap += t_hi[j] * (vals[j + 1] - vals[j])
        a[j] = -tdt * t_lo[j]
        c[j] = -tdt * t_hi[j]
        bj = cap[j] + tdt * (t_lo[j] + t_hi[j] + t_end[j])
        dj = cap[j] * vals[j] + edt * lap + src_dt[j]
        if bj <= 0.0:  # node outside the tube: decoupled, stays at 0
            bj = 1.0
            dj = 0.0
        b[j] = bj
        d[j] = dj
    _thomas(a, b, c, d, n)
    for j in range(n):
        vals[j] = d[j]


@nb.njit(cache=True, fastmath=FASTMATH)
def apply_operator(P, kappa, area, ay, az, g, out):
    """out = L P' (Pa m3/s): the conductance sum (P0/eta) sum_f A_f kappa_f (P_nb - P_j)/h of eq. (5),
    including the open outlet (P' = 0 half a cell beyond the last node).  out: (nx, ny, nz).
    """
    nx, ny, nz = P.shape
    hx = g.hx
    c0 = g.background_pressure / g.viscosity
    out[:] = 0.0
    for k in range(ny):
        for m in range(nz):
            tx = c0 * area[k, m] / hx
            for i in range(nx - 1):
                f = tx * _face(kappa[i, k, m], kappa[i + 1, k, m], g) * (P[i + 1, k, m] - P[i, k, m])
                out[i, k, m] += f
                out[i + 1, k, m] -= f
            if g.outlet_open > 0.5:
                out[nx - 1, k, m] -= 2.0 * tx * kappa[nx - 1, k, m] * P[nx - 1, k, m]
    for i in range(nx):
        for k in range(ny - 1):
            for m in range(nz):
                f = c0 * ay[k, m] / g.hy * _face(kappa[i, k, m], kappa[i, k + 1, m], g) * (
                    P[i, k + 1, m] - P[i, k, m])
                out[i, k, m] += f
                out[i, k + 1, m] -= f
        for k in range(ny):
            for m in range(nz - 1):
                f = c0 * az[k, m] / g.hz * _face(kappa[i, k, m], kappa[i, k, m + 1], g) * (
                    P[i, k, m + 1] - P[i, k, m])
                out[i, k, m] += f
                out[i, k, m + 1] -= f


@nb.njit(cache=True, fastmath=FASTMATH)
def _assemble_blocks(kappa, phi, area, ay, az, g, tdt, tx, wmat):
    """Diagonal blocks M_i of (C - theta dt L) into wmat (nx, B, B), B = ny nz, index b = k nz + m.

    tx[i, b]: conductance between slices i and i + 1 (from gas_step).
    """
    nx, ny, nz = phi.shape
    hx = g.hx
    c0 = g.background_pressure / g.viscosity
    ty = tdt * c0 / g.hy
    tz = tdt * c0 / g.hz
    open_outlet = g.outlet_open > 0.5
    wmat[:] = 0.0
    for i in range(nx):
        for k in range(ny):
            for m in range(nz):
                b = k * nz + m
                diag = phi[i, k, m] * hx * area[k, m]
                if i > 0:
                    diag += tdt * tx[i - 1, b]
                if i < nx - 1:
                    diag += tdt * tx[i, b]
                elif open_outlet:
                    diag += tdt * 2.0 * c0 * area[k, m] / hx * kappa[i, k, m]  # face at hx/2
                wmat[i, b, b] += diag
                if k < ny - 1:
                    t = ty * ay[k, m] * _face(kappa[i, k, m], kappa[i, k + 1, m], g)
                    c = b + nz
                    wmat[i, b, b] += t
                    wmat[i, c, c] += t
                    wmat[i, b, c] -= t
                    wmat[i, c, b] -= t
                if m < nz - 1:
                    t = tz * az[k, m] * _face(kappa[i, k, m], kappa[i, k, m + 1], g)
                    c = b + 1
                    wmat[i, b, b] += t
                    wmat[i, c, c] += t
                    wmat[i, b, c] -= t
                    wmat[i, c, b] -= t
        for b in range(ny * nz):
            if wmat[i, b, b] <= 0.0:  # node outside the tube: decoupled, held at 0
                wmat[i, b, b] = 1.0


@nb.njit(cache=True, fastmath=FASTMATH)
def gas_step(P, phi, kappa, src, area, ay, az, g, dt, theta, wmat, wvec):
    """Advance the relative pressure P' (Pa, (nx, ny, nz), in place) by dt (s), eq. (5).

    Finite volumes: phi_j V_j dP_j/dt = L P' + src, L from apply_operator, src from
    volume_sources, phi/kappa/src held fixed over dt (the caller may sub-cycle).  Theta scheme
    (C - theta dt L) P'^{n+1} = (C + (1 - theta) dt L) P'^n + dt src, solved exactly (unsplit) by
    block-tridiagonal elimination along x with dense ny nz blocks.  Work arrays (float64):
    wmat (nx, B, B), wvec (3, nx, B) with B = ny nz.
    """
    nx, ny, nz = P.shape
    nb_ = ny * nz
    hx = g.hx
    c0 = g.background_pressure / g.viscosity
    tdt = theta * dt
    edt = (1.0 - theta) * dt
    y = wvec[0]
    tx = wvec[1]   # tx[i, b]: conductance between slices i and i+1
    lap = wvec[2]
    if theta < 1.0:
        apply_operator(P, kappa, area, ay, az, g, lap.reshape((nx, ny, nz)))
    for i in range(nx):
        for k in range(ny):
            for m in range(nz):
                b = k * nz + m
                rhs = phi[i, k, m] * hx * area[k, m] * P[i, k, m] + dt * src[i, k, m]
                if theta < 1.0:
                    rhs += edt * lap[i, b]
                y[i, b] = rhs
                if i < nx - 1:
                    tx[i, b] = c0 * area[k, m] / hx * _face(kappa[i, k, m], kappa[i + 1, k, m], g)
    _assemble_blocks(kappa, phi, area, ay, az, g, tdt, tx, wmat)
    # forward elimination: S_i = M_i - a S_{i-1}^-1 a (a = -theta dt tx, diagonal); wmat[i] = S_i^-1
    for i in range(nx):
        if i > 0:
            for r in range(nb_):
                ar = tdt * tx[i - 1, r]
                acc = 0.0
                for c in range(nb_):
                    wmat[i, r, c] -= ar * wmat[i - 1, r, c] * (tdt * tx[i - 1, c])
                    acc += wmat[i - 1, r, c] * y[i - 1, c]
                y[i, r] += ar * acc
        # in-place Gauss-Jordan inverse; S_i is symmetric positive definite, so no pivoting
        for p in range(nb_):
            piv = 1.0 / wmat[i, p, p]
            wmat[i, p, p] = 1.0
            for j in range(nb_):
                wmat[i, p, j] *= piv
            for r in range(nb_):
                if r != p:
                    f = wmat[i, r, p]
                    wmat[i, r, p] = 0.0
                    for j in range(nb_):
                        wmat[i, r, j] -= f * wmat[i, p, j]
    # back substitution: P_i = S_i^-1 (y_i - a P_{i+1})
    for i in range(nx - 1, -1, -1):
        if i < nx - 1:
            for b in range(nb_):
                y[i, b] += tdt * tx[i, b] * y[i + 1, b]
        for r in range(nb_):
            acc = 0.0
            for c in range(nb_):
                acc += wmat[i, r, c] * y[i, c]
            lap[i, r] = acc
        for b in range(nb_):
            y[i, b] = lap[i, b]
    for i in range(nx):
        for k in range(ny):
            for m in range(nz):
                P[i, k, m] = y[i, k * nz + m]


@nb.njit(cache=True, fastmath=FASTMATH)
def gas_step_split(P, phi, kappa, src, area, ay, az, g, dt, theta, work):
    """Dimension-split variant of gas_step: the papers' "each dimension is integrated separately"
    (gas.scheme = split).

    Lie splitting: tridiagonal theta-solves along x (with src and the outlet), then y, then z.
    Its fixed point is not the steady state of eq. (5) when the porosity varies across the tube
    (a bed in the lower half: ~100 % error at dt = 1e-5 s); see docs/gas.md.
    work: float64 (10, max(nx, ny, nz)).
    """
    nx, ny, nz = P.shape
    hx = g.hx
    c0 = g.background_pressure / g.viscosity
    tdt = theta * dt
    edt = (1.0 - theta) * dt
    open_outlet = g.outlet_open > 0.5
    a = work[0]
    b = work[1]
    c = work[2]
    d = work[3]
    vals = work[4]
    cap = work[5]
    t_lo = work[6]
    t_hi = work[7]
    t_end = work[8]
    s_dt = work[9]
    # x lines: sources and boundary conditions live here
    for k in range(ny):
        for m in range(nz):
            ar = area[k, m]
            tx = c0 * ar / hx
            for i in range(nx):
                vals[i] = P[i, k, m]
                cap[i] = phi[i, k, m] * hx * ar
                s_dt[i] = dt * src[i, k, m]
                t_end[i] = 0.0
                t_lo[i] = 0.0
                t_hi[i] = 0.0
            for i in range(nx - 1):
                t = tx * _face(kappa[i, k, m], kappa[i + 1, k, m], g)
                t_hi[i] = t
                t_lo[i + 1] = t
            if open_outlet:
                # the outlet face is half a cell from the last node
                t_end[nx - 1] = 2.0 * tx * kappa[nx - 1, k, m]
            _line_solve(vals, cap, t_lo, t_hi, t_end, s_dt, tdt, edt, a, b, c, d, nx)
            for i in range(nx):
                P[i, k, m] = vals[i]
    if ny > 1:
        hy = g.hy
        for i in range(nx):
            for m in range(nz):
                for k in range(ny):
                    vals[k] = P[i, k, m]
                    cap[k] = phi[i, k, m] * hx * area[k, m]
                    s_dt[k] = 0.0
                    t_end[k] = 0.0
                    t_lo[k] = 0.0
                    t_hi[k] = 0.0
                for k in range(ny - 1):
                    t = c0 * ay[k, m] / hy * _face(kappa[i, k, m], kappa[i, k + 1, m], g)
                    t_hi[k] = t
                    t_lo[k + 1] = t
                _line_solve(vals, cap, t_lo, t_hi, t_end, s_dt, tdt, edt, a, b, c, d, ny)
                for k in range(ny):
                    P[i, k, m] = vals[k]
    if nz > 1:
        hz = g.hz
        for i in range(nx):
            for k in range(ny):
                for m in range(nz):
                    vals[m] = P[i, k, m]
                    cap[m] = phi[i, k, m] * hx * area[k, m]
                    s_dt[m] = 0.0
                    t_end[m] = 0.0
                    t_lo[m] = 0.0
                    t_hi[m] = 0.0
                for m in range(nz - 1):
                    t = c0 * az[k, m] / hz * _face(kappa[i, k, m], kappa[i, k, m + 1], g)
                    t_hi[m] = t
                    t_lo[m + 1] = t
                _line_solve(vals, cap, t_lo, t_hi, t_end, s_dt, tdt, edt, a, b, c, d, nz)
                for m in range(nz):
                    P[i, k, m] = vals[m]


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _inlet_face_gradient(P, kappa, u, g, feed_volume_rate, k, m):
    """dP'/dx (Pa/m) on the inlet face of line (k, m).

    Darcy (eq. 3) makes the total volume flux q = u - (kappa/eta) dP/dx; q is the inlet flux.
    """
    q = g.superficial_velocity + feed_volume_rate / g.tube_area
    return -g.viscosity / kappa[0, k, m] * (q - u[0, k, m, 0])


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def _outlet_face_gradient(P, kappa, g, k, m):
    """dP'/dx (Pa/m) on the outlet face of line (k, m)."""
    nx = P.shape[0]
    if g.outlet_open > 0.5:
        return -P[nx - 1, k, m] / (0.5 * g.hx)
    return -g.viscosity / kappa[nx - 1, k, m] * g.superficial_velocity


@nb.njit(cache=True, fastmath=FASTMATH)
def pressure_gradient(P, phi, kappa, u, g, feed_volume_rate, nodal):
    """Node values the drag needs: nodal[..., 0] = phi, nodal[..., 1:4] = grad P' (Pa/m).

    nodal: (nx, ny, nz, 4).  Central differences inside; the end nodes along x average their two
    face gradients (the boundary face from the boundary condition); across, edge nodes use the
    one-sided difference.  All are exact for a pressure field linear in x, y, z that obeys the
    boundary conditions.
    """
    nx, ny, nz = P.shape
    hx = g.hx
    hy = g.hy
    hz = g.hz
    for k in range(ny):
        for m in range(nz):
            for i in range(1, nx - 1):
                nodal[i, k, m, 1] = (P[i + 1, k, m] - P[i - 1, k, m]) / (2.0 * hx)
            g_in = _inlet_face_gradient(P, kappa, u, g, feed_volume_rate, k, m)
            g_out = _outlet_face_gradient(P, kappa, g, k, m)
            nodal[0, k, m, 1] = 0.5 * (g_in + (P[1, k, m] - P[0, k, m]) / hx)
            nodal[nx - 1, k, m, 1] = 0.5 * (g_out + (P[nx - 1, k, m] - P[nx - 2, k, m]) / hx)
    for i in range(nx):
        for k in range(ny):
            for m in range(nz):
                if ny == 1:
                    gy = 0.0
                else:
                    lo = max(k - 1, 0)
                    hi = min(k + 1, ny - 1)
                    gy = (P[i, hi, m] - P[i, lo, m]) / ((hi - lo) * hy)
                if nz == 1:
                    gz = 0.0
                else:
                    lo = max(m - 1, 0)
                    hi = min(m + 1, nz - 1)
                    gz = (P[i, k, hi] - P[i, k, lo]) / ((hi - lo) * hz)
                nodal[i, k, m, 0] = phi[i, k, m]
                nodal[i, k, m, 2] = gy
                nodal[i, k, m, 3] = gz


@nb.njit(cache=True, fastmath=FASTMATH)
def drag_forces(pos, n, nodal, g, force, accumulate):
    """Drag force (N) on each grain, F = -V_p grad P_i / (1 - phi_i) (eq. 6 times the grain mass).

    phi_i and grad P_i are interpolated from nodal (see pressure_gradient) with the deposit's tent
    weights (eq. 9).  force: (capacity, 3); rows < n are overwritten (accumulate=False) or added
    to (True).  Grains outside 0 <= x <= L get no drag.
    """
    nx, ny, nz, _ = nodal.shape
    vp = g.grain_volume
    length = g.tube_length
    for p in range(n):
        x = pos[p, 0]
        fx = 0.0
        fy = 0.0
        fz = 0.0
        if x >= 0.0 and x <= length:
            tent = _grain_tent(pos, p, g, nx, ny, nz)
            ph = 0.0
            gx = 0.0
            gy = 0.0
            gz = 0.0
            for a in range(8):
                i, k, m, w = _corner(a, tent, 1.0)
                ph += w * nodal[i, k, m, 0]
                gx += w * nodal[i, k, m, 1]
                gy += w * nodal[i, k, m, 2]
                gz += w * nodal[i, k, m, 3]
            # a grain that was deposited reads 1 - phi_i >= g.solid_min; the floor only guards
            # grains added after the deposit
            s = -vp / max(1.0 - ph, g.solid_min)
            fx = s * gx
            fy = s * gy
            fz = s * gz
        if accumulate:
            force[p, 0] += fx
            force[p, 1] += fy
            force[p, 2] += fz
        else:
            force[p, 0] = fx
            force[p, 1] = fy
            force[p, 2] = fz


@nb.njit(cache=True, fastmath=FASTMATH)
def pressure_drop(P, kappa, u, area, g, feed_volume_rate):
    """Inlet-face minus outlet-face relative pressure (Pa), area-averaged over the cross-section."""
    nx, ny, nz = P.shape
    half = 0.5 * g.hx
    total = 0.0
    for k in range(ny):
        for m in range(nz):
            p_in = P[0, k, m] - half * _inlet_face_gradient(P, kappa, u, g, feed_volume_rate, k, m)
            p_out = P[nx - 1, k, m] + half * _outlet_face_gradient(P, kappa, g, k, m)
            total += area[k, m] * (p_in - p_out)
    return total / g.tube_area


@nb.njit(cache=True, fastmath=FASTMATH)
def gas_content(P, phi, area, g):
    """Sum of phi_j V_j P'_j (Pa m3): proportional to the gas mass excess, conserved by gas_step."""
    nx, ny, nz = P.shape
    hx = g.hx
    total = 0.0
    for i in range(nx):
        for k in range(ny):
            for m in range(nz):
                total += phi[i, k, m] * hx * area[k, m] * P[i, k, m]
    return total


@nb.njit(cache=True, fastmath=FASTMATH)
def couple(pos, vel, n, gas, dt, substeps, theta, feed_volume_rate, force, accumulate):
    """One grain step of the gas: deposit, fields, `substeps` gas steps of dt/substeps, drag forces.

    The five kernels above in the required order on the arrays of `gas` (a GasArrays); P'
    (gas.pressure) is advanced in place and the drag goes to force (see drag_forces).  g.split
    selects the split scheme, which uses wvec as its work array (GasField sizes wvec for both).
    """
    g = gas.g
    deposit(pos, vel, n, g, gas.dep)
    update_fields(gas.dep, gas.area, g, gas.phi, gas.kappa, gas.u)
    volume_sources(gas.u, gas.area, gas.ay, gas.az, g, feed_volume_rate, gas.src)
    h = dt / substeps
    if g.split > 0.5:
        nx, ny, nz = gas.pressure.shape
        longest = max(nx, max(ny, nz))
        work = gas.wvec.reshape(gas.wvec.size)[:10 * longest].reshape((10, longest))
        for _ in range(substeps):
            gas_step_split(gas.pressure, gas.phi, gas.kappa, gas.src, gas.area, gas.ay, gas.az, g, h, theta,
                           work)
    else:
        for _ in range(substeps):
            gas_step(gas.pressure, gas.phi, gas.kappa, gas.src, gas.area, gas.ay, gas.az, g, h, theta,
                     gas.wmat, gas.wvec)
    pressure_gradient(gas.pressure, gas.phi, gas.kappa, gas.u, g, feed_volume_rate, gas.nodal)
    drag_forces(pos, n, gas.nodal, g, force, accumulate)

"""The force laws, one place each: contact (grain-grain and grain-wall) and body forces (SI units).

Each law is a small function inlined into the kernels that loop over contacts (contacts.py) or
grains (stepper.py); its constants come from the grain parameters p (a named tuple declared in
engine/parameters.py, GRAIN) once per kernel call (`pair_constants`, `wall_constants`,
`kick_constants`), as a named tuple (`Contact`, `Kick`) that stays in registers.

Normal: F_n = max(0, k_n delta + gamma_n v_n) along the line of centres (never attractive).
Tangential: F_t = -min(mu F_n, gamma_t |v_t|) v_t/|v_t| at the contact point (no history), with
v_t the tangential slip velocity of the contact point including rotation; gamma_t arrives capped at
m_slip/dt so that the explicit dashpot cannot reverse a slip (engine/contact.py).
Rolling resistance (particles.rolling_resistance, mu_r; 0 = off): a torque
M = -min(mu_r r F_n, I_rel |w_rel|/dt) w_rel/|w_rel| against the relative spin w_rel (w_1 - w_2,
or the grain's spin at a wall), capped so that one step cannot reverse w_rel (I_rel = I/2 for a
pair, I at a wall).
"""

import math
from collections import namedtuple

import numba as nb

# The kernels' fastmath flags (engine/kernels/*). Without nnan/ninf, so that the blow-up guards
# (isfinite) keep working; without reassoc, so that the compiler sums in the order written and a
# result does not depend on the vector width it picks for the machine (decision 0043).
FASTMATH = {"nsz", "arcp", "contract", "afn"}


# The constants of one kind of contact (grain-grain or grain-wall): grain radius r (m), normal
# stiffness k_n (N/m) and damping gamma_n (N s/m), Coulomb coefficient mu, tangential damping gamma_t
# (N s/m), rolling-resistance coefficient mu_r and the rolling cap I_rel/dt (kg m2/s)
Contact = namedtuple("Contact", "radius stiffness damping friction tangential_damping rolling_resistance rolling_cap")


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def pair_constants(p):
    """The Contact between two grains (I_rel = I/2)."""
    return Contact(radius=p.radius, stiffness=p.stiffness, damping=p.damping_pair, friction=p.friction_pair,
                   tangential_damping=p.tangential_damping_pair, rolling_resistance=p.rolling_resistance,
                   rolling_cap=0.5 * p.inertia / p.dt)


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def wall_constants(p):
    """The Contact between a grain and a wall (I_rel = I)."""
    return Contact(radius=p.radius, stiffness=p.stiffness, damping=p.damping_wall, friction=p.friction_wall,
                   tangential_damping=p.tangential_damping_wall, rolling_resistance=p.rolling_resistance,
                   rolling_cap=p.inertia / p.dt)


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def optional_terms(p):
    """Whether a case switches on a contact term that is not in the papers' model (then the
    contact loop with the optional terms runs)."""
    return p.rolling_resistance > 0.0


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def slip_force(vtx, vty, vtz, fc, gt, branchless=False):
    """Tangential force -min(fc, gt |v_t|) v_t/|v_t| against the slip v_t (tangential to the
    contact), with fc = mu F_n, and gt if the contact is in its viscous (sticking) branch, else 0.

    The branch is chosen on squares, gt^2 |v_t|^2 < fc^2 (both sides non-negative), so that a
    viscous contact, -gt v_t, takes no square root and no division; a slipping one is
    -fc v_t/|v_t|. `branchless` (a compile-time constant of the caller): the same values by
    selects instead of a branch, so that a loop over contacts vectorises; the root is then taken of
    1 where the contact is viscous and its result unused; a nan slip stays a nan force."""
    vt2 = vtx * vtx + vty * vty + vtz * vtz
    viscous = gt * gt * vt2 < fc * fc or vt2 == 0.0  # no slip counts as viscous: force 0, gt kept
    if branchless:
        s = -fc / math.sqrt(1.0 if viscous else vt2)
        if viscous:
            return -gt * vtx, -gt * vty, -gt * vtz, gt
        return s * vtx, s * vty, s * vtz, 0.0
    if viscous:
        return -gt * vtx, -gt * vty, -gt * vtz, gt
    s = -fc / math.sqrt(vt2)
    return s * vtx, s * vty, s * vtz, 0.0


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def rolling_torque(fn, wx, wy, wz, r, mu_r, cap, branchless=False):
    """Rolling-resistance torque on the first body against the relative spin w, N m (`branchless`:
    see slip_force)."""
    w = math.sqrt(wx * wx + wy * wy + wz * wz)
    if branchless:
        spinning = not (w <= 0.0)
        s = -min(mu_r * r * fn, cap * w) / (w if spinning else 1.0)
        if spinning:
            return s * wx, s * wy, s * wz
        return 0.0, 0.0, 0.0
    if w <= 0.0:
        return 0.0, 0.0, 0.0
    s = -min(mu_r * r * fn, cap * w) / w
    return s * wx, s * wy, s * wz


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def normal_force(delta, vn, c):
    """Normal force magnitude k_n delta + gamma_n v_n (N; repulsive when positive) at overlap delta
    (m) and normal approach velocity vn (m/s); c = pair_ or wall_constants."""
    return c.stiffness * delta + c.damping * vn


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def pair_normal(dx, dy, dz, d2, vx, vy, vz, c):
    """Normal force of two grains at centre offset D = x2 - x1 (|D|^2 = d2), relative velocity
    v = v1 - v2; c = pair_constants.

    Returns (F_n, 1/|D|, 1/|D|^2, v.D, overlap 2r - |D|). The square root and 1/d2 do not wait
    for each other (1/|D| = |D|/d2), and the unit normal is never formed (surface_forces),
    which keeps a contact's chain of dependent operations short."""
    dist = math.sqrt(d2)
    a = 1.0 / d2
    inv = dist * a
    vd = vx * dx + vy * dy + vz * dz
    delta = 2.0 * c.radius - dist
    return normal_force(delta, vd * inv, c), inv, a, vd, delta


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def surface_forces(fn, inv, a, vd, dx, dy, dz, vx, vy, vz, wx, wy, wz, rwx, rwy, rwz, c, optional,
                   branchless=False):
    """Force and torques of a contact with normal force fn > 0 on the first body, along the normal
    n = inv D of the offset D (first -> second; inv = 1/|D|, a = 1/|D|^2, vd = v.D: pair_normal; a
    wall passes its unit normal, inv = a = 1). v is the relative velocity v1 - v2, w the spin sum
    w1 + w2 of the contact-point velocity (w1 at a wall), rw the relative spin w1 - w2 (w1 at a wall).
    The contact point's velocity is v + r w x n; its rotational part is normal to n, so the slip
    is v - (v.D) a D + r inv w x D.

    Returns (F, T1, T2, g): the force and torque on the first body, the torque on the second (the
    first's tangential torque minus its rolling torque; the second's force is -F), and gamma_t if
    the tangential force is in its viscous branch (else 0). `optional` adds the optional terms
    (optional_terms); it is a compile-time constant of the calling loop (contacts.py and passes.py
    compile one loop with them and one without), so that the loop without them keeps its arithmetic
    and speed; `branchless` likewise (slip_force).
    """
    r = c.radius
    rinv = r * inv
    vda = vd * a
    ftx, fty, ftz, g = slip_force(vx - vda * dx + rinv * (wy * dz - wz * dy),
                                  vy - vda * dy + rinv * (wz * dx - wx * dz),
                                  vz - vda * dz + rinv * (wx * dy - wy * dx),
                                  c.friction * fn, c.tangential_damping, branchless)
    sn = fn * inv
    fx = ftx - sn * dx
    fy = fty - sn * dy
    fz = ftz - sn * dz
    # both bodies get the same torque r n x F_t
    tx = rinv * (dy * ftz - dz * fty)
    ty = rinv * (dz * ftx - dx * ftz)
    tz = rinv * (dx * fty - dy * ftx)
    if optional:  # each term is zero when its key is 0
        mx, my, mz = rolling_torque(fn, rwx, rwy, rwz, r, c.rolling_resistance, c.rolling_cap, branchless)
        return fx, fy, fz, tx + mx, ty + my, tz + mz, tx - mx, ty - my, tz - mz, g
    return fx, fy, fz, tx, ty, tz, tx, ty, tz, g


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def cylinder_contact(y, z, vx, vy, vz, wx, wy, wz, inner, c, optional, branchless=False):
    """Contact of a grain centred at (x, y, z) (velocity v, spin w) with the tube's cylinder wall, whose
    surface the grain's centre meets at rho = inner (= R - r); c = wall_constants.

    The same law as wall_contact with the outward normal n = (0, y, z)/rho, taken as a pair with a
    resting partner at offset D = (0, y, z) (surface_forces): one square root and 1/rho^2 that
    do not wait for each other. Returns (F_n, F, T, g, overlap rho - inner): the normal force
    (pulling where <= 0: the caller keeps no force there), force, torque, gamma_t if viscous."""
    rho2 = y * y + z * z
    rho = math.sqrt(rho2)
    a = 1.0 / rho2
    inv = rho * a
    vd = vy * y + vz * z
    delta = rho - inner
    fn = normal_force(delta, vd * inv, c)
    fx, fy, fz, tx, ty, tz, _, _, _, g = surface_forces(fn, inv, a, vd, 0.0, y, z, vx, vy, vz, wx, wy, wz,
                                                        wx, wy, wz, c, optional, branchless)
    return fn, fx, fy, fz, tx, ty, tz, g, delta


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def wall_contact(delta, nx, ny, nz, vx, vy, vz, wx, wy, wz, c, optional, branchless=False):
    """Contact of a grain (velocity v, spin w) with a wall of outward normal n (grain -> wall) at
    overlap delta (m); c = wall_constants.

    Returns (F_n, F, T, g): the normal force magnitude (0 when separating, then all zero), force
    and torque on the grain, and gamma_t if the tangential force is in its viscous branch (else 0).
    Inlined with constant normals, the zero components fold away. `branchless`: see slip_force.
    """
    vn = vx * nx + vy * ny + vz * nz
    fn = normal_force(delta, vn, c)
    if branchless:
        fx, fy, fz, tx, ty, tz, _, _, _, g = surface_forces(fn, 1.0, 1.0, vn, nx, ny, nz, vx, vy, vz, wx, wy, wz,
                                                            wx, wy, wz, c, optional, True)
        if not (fn <= 0.0):  # selects: a nan fn keeps its values
            return fn, fx, fy, fz, tx, ty, tz, g
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if fn <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    fx, fy, fz, tx, ty, tz, _, _, _, g = surface_forces(fn, 1.0, 1.0, vn, nx, ny, nz, vx, vy, vz, wx, wy, wz,
                                                        wx, wy, wz, c, optional)
    return fn, fx, fy, fz, tx, ty, tz, g


# The constants of a kick by kick_dt: the velocity per force kick_dt/m, the spin per torque
# kick_dt/I, the implicit-spin factor kick_dt r^2/I, the velocity change by the body forces (gravity)
# and the two switches
Kick = namedtuple("Kick", "velocity_per_force spin_per_torque implicit_factor gravity_x gravity_y gravity_z "
                          "rotate implicit")


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def kick_constants(p, kick_dt):
    """The Kick of the grain parameters p by kick_dt."""
    return Kick(velocity_per_force=kick_dt / p.mass, spin_per_torque=kick_dt / p.inertia,
                implicit_factor=kick_dt * p.radius * p.radius / p.inertia, gravity_x=kick_dt * p.gravity_x,
                gravity_y=kick_dt * p.gravity_y, gravity_z=kick_dt * p.gravity_z, rotate=p.rotation > 0.0,
                implicit=p.implicit_spin > 0.0)


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def velocity_kick(vx, vy, vz, fx, fy, fz, k, drift):
    """A grain's velocity v (m/s) kicked by the force F (contacts and gas drag, N) and the body
    forces (gravity) with the Kick k. The kick before a drift sums v + a F + g left to right, the
    closing half kick v + (a F + g): both orders are kept so that the rounding of a step stays that
    of the engine's reference runs."""
    a, gx, gy, gz = k.velocity_per_force, k.gravity_x, k.gravity_y, k.gravity_z
    if drift:
        return vx + a * fx + gx, vy + a * fy + gy, vz + a * fz + gz
    return vx + (a * fx + gx), vy + (a * fy + gy), vz + (a * fz + gz)


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def spin_kick(gamma_sum, k):
    """Spin change per torque (1/(kg m2) s) of a kick with the Kick k, given the sum of gamma_t of
    the grain's viscous contacts (N s/m): divided by 1 + kick_dt r^2/I sum(gamma_t) with
    numerics.implicit_spin."""
    b = k.spin_per_torque
    return b / (1.0 + k.implicit_factor * gamma_sum) if k.implicit else b

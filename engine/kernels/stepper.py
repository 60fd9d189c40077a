"""The grain time loop: velocity Verlet (kick-drift-kick) with the feed piston and outlet removal.

Forces that depend on velocity use the half-step velocity, as LAMMPS's fix nve/sphere does.
With numerics.implicit_spin a grain's spin kick is divided by 1 + kick_dt r^2/I sum(gamma_t) over its
contacts in the viscous branch (viscous_damping): the dashpots' action on the grain's own spin taken
implicitly, so that a packed bed's spins do not chatter when gamma_t dt/(m/7) nears 1 (the fixed
points are unchanged; the split of a sticking impulse between spin and translation is not exact,
docs/performance.md, "The tangential dashpot and the time step").
"""

import math

import numba as nb

from . import laws
from . import indices
from .contacts import evaluate_contacts
from .gas import couple
from .laws import FASTMATH
from .neighbors import build_neighbor_list, sort_and_compact


@nb.njit(cache=True)
def rebuild(grains, n, p, nbrs, counters):
    """Drop grains past the outlet, sort by cell, rebuild the neighbour list. Returns the new n.

    On neighbour-list overflow sets counters[OVERFLOW] = 1 (the caller grows nbrs.nbr and retries).
    """
    pos, vel, omg, _, drag, _, _, _, gid, in_feed, pos_ref = grains
    shape, cell_start, cell_of, order, tmp3, tmpi, nbr_start, nbr, nbr_i = nbrs
    n = sort_and_compact(pos, vel, omg, drag, gid, in_feed, n, p, shape, cell_start, cell_of, order, tmp3, tmpi,
                         counters)
    pos_ref[:n] = pos[:n]
    npairs = build_neighbor_list(pos, in_feed, n, p, shape, cell_start, nbr_start, nbr, nbr_i)
    counters[indices.OVERFLOW] = 1 if npairs < 0 else 0
    counters[indices.REBUILDS] += 1
    return n


@nb.njit(cache=True, fastmath=FASTMATH)
def _kick(grains, n, p, kick_dt):
    """Velocity update of the dynamic grains by kick_dt (laws.kick)."""
    vel, omg, force, drag, torque = grains.vel, grains.omg, grains.force, grains.drag, grains.torque
    viscous_damping, in_feed = grains.viscous_damping, grains.in_feed
    k = laws.kick_constants(p, kick_dt)
    rotate = k.rotate
    for i in range(n):
        if in_feed[i]:
            continue
        vel[i, 0], vel[i, 1], vel[i, 2] = laws.velocity_kick(
            vel[i, 0], vel[i, 1], vel[i, 2], force[i, 0] + drag[i, 0], force[i, 1] + drag[i, 1],
            force[i, 2] + drag[i, 2], k, False)
        if rotate:
            bb = laws.spin_kick(viscous_damping[i], k)
            omg[i, 0] += bb * torque[i, 0]
            omg[i, 1] += bb * torque[i, 1]
            omg[i, 2] += bb * torque[i, 2]


@nb.njit(cache=True, fastmath=FASTMATH)
def _kick_drift(grains, n, p, kick_dt, counters):
    """Kick the dynamic grains by kick_dt, then move all grains one step; release feed grains fully
    inside the tube. One pass: the closing half kick of a step and the opening one of the next
    are merged into a single kick of dt.

    Returns 1 if the neighbour list must be rebuilt (a grain moved half the skin, left the tube or
    was released), and sets counters[STATUS] on a non-finite position or a grain outside the cylinder.
    """
    pos, vel, omg, force, drag, torque, viscous_damping, _, _, in_feed, pos_ref = grains
    dt = p.dt
    r = p.radius
    k = laws.kick_constants(p, kick_dt)
    rotate = k.rotate
    feed_dx = p.feed_speed * dt
    limit2 = 0.25 * p.skin * p.skin
    outlet = p.tube_length
    tube2 = p.tube_radius * p.tube_radius
    need = 0
    for i in range(n):
        if in_feed[i]:
            pos[i, 0] += feed_dx
            if pos[i, 0] >= r:
                in_feed[i] = 0
                counters[indices.RELEASED] += 1
                need = 1  # the list holds no pairs of two feed grains: add the released one's
        else:
            vx, vy, vz = laws.velocity_kick(vel[i, 0], vel[i, 1], vel[i, 2], force[i, 0] + drag[i, 0],
                                            force[i, 1] + drag[i, 1], force[i, 2] + drag[i, 2], k, True)
            vel[i, 0] = vx
            vel[i, 1] = vy
            vel[i, 2] = vz
            if rotate:
                bb = laws.spin_kick(viscous_damping[i], k)
                omg[i, 0] += bb * torque[i, 0]
                omg[i, 1] += bb * torque[i, 1]
                omg[i, 2] += bb * torque[i, 2]
            x = pos[i, 0] + dt * vx
            y = pos[i, 1] + dt * vy
            z = pos[i, 2] + dt * vz
            pos[i, 0] = x
            pos[i, 1] = y
            pos[i, 2] = z
            if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
                counters[indices.STATUS] = indices.NONFINITE
                return 1
            if y * y + z * z > tube2 or x < -r:
                counters[indices.STATUS] = indices.ESCAPED
                return 1
            if x > outlet:
                need = 1
        dx = pos[i, 0] - pos_ref[i, 0]
        dy = pos[i, 1] - pos_ref[i, 1]
        dz = pos[i, 2] - pos_ref[i, 2]
        if dx * dx + dy * dy + dz * dz > limit2:
            need = 1
    return need


@nb.njit(cache=True)
def advance(nsteps, state_n, grains, p, nbrs, counters, diag, gas, chunks, pairs):
    """Take up to nsteps steps. Returns the number taken (fewer on overflow or failure).

    state_n[0] is the number of grains (updated); forces must be valid for the current state.
    The feed piston always moves (the papers' enforced mass flow); when it has pressed a grain deeper
    than p.feed_max_overlap for p.feed_block_steps steps in a row, the step is completed and
    counters[STATUS] = BLOCKED. `grains`, `nbrs`, `chunks` and `pairs` are the bundles of state.py, `gas`
    a gas.GasArrays, `p` the grain parameters (engine/parameters.py, GRAIN).
    """
    n = state_n[0]
    dt = p.dt
    kick_dt = 0.5 * dt  # the opening half kick; afterwards closing + opening kicks merged
    taken = 0
    for _ in range(nsteps):
        need = _kick_drift(grains, n, p, kick_dt, counters)
        if counters[indices.STATUS] != indices.OK:
            break
        if need:
            n = rebuild(grains, n, p, nbrs, counters)
            if counters[indices.OVERFLOW]:
                break  # velocities are at the half step: the caller's finish_step completes it
        _step_forces(grains, n, p, nbrs, counters, diag, gas, chunks, pairs)
        taken += 1
        kick_dt = dt
        if counters[indices.STATUS] == indices.BLOCKED:
            break
    if taken > 0 and (taken == nsteps or counters[indices.STATUS] == indices.BLOCKED):
        _kick(grains, n, p, 0.5 * dt)  # closing half kick: full-step velocities
    state_n[0] = n
    return taken


@nb.njit(cache=True)
def _step_forces(grains, n, p, nbrs, counters, diag, gas, chunks, pairs):
    """The rest of a step after its drift and rebuild: the gas (on a gas step), the forces at the
    new positions, and the feed's pressed-step count (counters[STATUS] = BLOCKED when it reaches
    p.feed_block_steps)."""
    if p.gas_on > 0.0 and counters[indices.STEPS] % int(p.gas_interval) == 0:
        couple(grains.pos, grains.vel, n, gas, p.dt * p.gas_interval, 1, p.gas_theta,
               p.feed_volume_rate, grains.drag, False)
    _forces(grains, n, p, nbrs, counters, diag, chunks, pairs)
    if diag[indices.DIAG_FEED_OVERLAP] <= p.feed_max_overlap:
        counters[indices.PRESSED_STEPS] = 0
    else:
        counters[indices.PRESSED_STEPS] += 1
        if counters[indices.PRESSED_STEPS] >= p.feed_block_steps:
            counters[indices.STATUS] = indices.BLOCKED


@nb.njit(cache=True)
def _forces(grains, n, p, nbrs, counters, diag, chunks, pairs):
    """Forces at the new positions; ends a step except for its closing half kick."""
    evaluate_contacts(grains, n, nbrs.nbr_start, nbrs.nbr, nbrs.nbr_i, p, diag, chunks, pairs)
    # running maximum overlap (grain-grain, wall, feed) since the last Simulation.reset_max_overlap,
    # so that the run guard sees every step, not only a frame's last
    diag[indices.DIAG_RUNNING_MAX] = max(diag[indices.DIAG_RUNNING_MAX], diag[indices.DIAG_OVERLAP],
                                         diag[indices.DIAG_FEED_OVERLAP])
    if p.feed_speed > 0.0:
        # the feed grains carry the reactions of their contacts: minus their sum is the piston's push
        # (a separate pass, 1.6 us for 3 200 grains, ~1 % of a step, keeps the contact loop as it is)
        in_feed, force = grains.in_feed, grains.force
        push = 0.0
        for i in range(n):
            if in_feed[i]:
                push -= force[i, 0]
        diag[indices.DIAG_PISTON_IMPULSE] += push * p.dt
    counters[indices.STEPS] += 1


@nb.njit(cache=True)
def finish_step(grains, n, p, nbrs, counters, diag, gas, chunks, pairs):
    """Second half of a step broken off by advance (its list outgrown): what the step had left
    (_step_forces), then the closing half kick."""
    _step_forces(grains, n, p, nbrs, counters, diag, gas, chunks, pairs)
    _kick(grains, n, p, 0.5 * p.dt)

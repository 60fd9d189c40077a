"""Contact-law parameters derived from a case, one function each: grain mass and inertia, damping from
restitution, contact time, stable time step, the capped tangential damping; `ContactModel` holds
them for the Python side.

Normal force: F_n = max(0, k_n delta + gamma_n v_n) (linear spring + dashpot, never attractive).
Tangential force: F_t = -min(mu F_n, gamma_t |v_t|) t_hat (viscous-regularised Coulomb, no history),
with gamma_t capped at m_slip/dt so that the explicit dashpot cannot reverse a contact's slip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.optimize import brentq

from .case import Case, CaseError


def clamped_restitution(zeta: float) -> float:
    """Restitution of the non-attractive linear spring-dashpot at damping ratio zeta (0 < zeta < 1).

    The contact ends when k delta + gamma v_n first reaches zero (before delta does), so the grains
    separate faster than the textbook exp(-zeta pi / sqrt(1 - zeta^2)) predicts.
    """
    if zeta <= 0.0:
        return 1.0
    wd = math.sqrt(1.0 - zeta * zeta)
    # In units of 1/omega_0: delta = e^{-zeta t} sin(wd t)/wd; the force vanishes at wd t = theta.
    theta = math.atan2(2.0 * zeta, -(1.0 - 2.0 * zeta * zeta) / wd)
    return math.exp(-zeta * theta / wd) * abs(math.cos(theta) - zeta / wd * math.sin(theta))


def damping_ratio(restitution: float) -> float:
    """Damping ratio zeta whose clamped collision gives this restitution (inverse of the above)."""
    if restitution >= 1.0:
        return 0.0
    lowest = clamped_restitution(0.999)
    if restitution <= lowest:
        raise CaseError(f"restitution {restitution:g} is below {lowest:.3f}, the smallest the "
                        "non-attractive spring-dashpot can produce")
    return brentq(lambda z: clamped_restitution(z) - restitution, 0.0, 0.999, xtol=1e-14)


# Largest gamma_t dt / (m/7) (tangential dashpot between grains over its slip inertia) at which a
# packed bed was measured resolved: 0.466 (gamma_t = 0.01 N s/m at 0.15 t_c) gave the bed of 0.05 t_c
# within 1 % and no spin chatter, while 0.62 and 0.93 (gamma_t = 0.02 at 0.1 and 0.15 t_c) chatter and
# hold 36-40 % less pressure drop (docs/performance.md, "The tangential dashpot and the time step").
# One contact alone is stable up to 1 (the cap); a grain's several contacts couple through its spin.
DASHPOT_RESOLVED_RATIO = 0.47
# What a case above it means, for `plugsim check` and the run's warning
DASHPOT_WARNING = ("packed beds (bulk transport) carry a time-step error here, slug flow does not; "
                   "a smaller numerics.time_step_fraction or particles.tangential_damping resolves them, "
                   "as does numerics.implicit_spin: true (the default) "
                   "(docs/performance.md, \"The tangential dashpot and the time step\")")


# ---- the derived constants of the contact law, one function each (engine/parameters.py declares
# which of them the kernels read) ---------------------------------------------------------------
def grain_radius(case: Case) -> float:
    """r = d/2, m."""
    return case["particles.diameter"] / 2


def grain_mass(case: Case) -> float:
    """m = rho_s pi d^3/6, kg."""
    return case["particles.density"] * math.pi * case["particles.diameter"] ** 3 / 6


def grain_inertia(case: Case) -> float:
    """I = 2/5 m r^2, kg m2."""
    return 0.4 * grain_mass(case) * grain_radius(case) ** 2


def damping_pair(case: Case) -> float:
    """gamma_n between two grains (reduced mass m/2) that gives particles.restitution, N s/m."""
    zeta = damping_ratio(case["particles.restitution"])
    return 2 * zeta * math.sqrt(grain_mass(case) / 2 * case["particles.stiffness"])


def damping_wall(case: Case) -> float:
    """gamma_n between a grain and the wall (infinite mass) that gives wall.restitution, N s/m."""
    zeta = damping_ratio(case["wall.restitution"])
    return 2 * zeta * math.sqrt(grain_mass(case) * case["particles.stiffness"])


def _pair_frequency(case: Case) -> float:
    """omega_0 = sqrt(k_n / (m/2)) of a grain-grain contact, 1/s."""
    return math.sqrt(case["particles.stiffness"] / (grain_mass(case) / 2))


def contact_time(case: Case) -> float:
    """Duration of a head-on grain-grain contact, s."""
    zeta = damping_ratio(case["particles.restitution"])
    return math.pi / (_pair_frequency(case) * math.sqrt(1.0 - zeta**2))


def stable_time_step(case: Case) -> float:
    """The largest step allowed: numerics.time_step_safety of the single pair's limit, s."""
    zeta = damping_ratio(case["particles.restitution"])
    # Velocity Verlet on a damped oscillator is stable for omega dt < 2 (sqrt(1+zeta^2) - zeta).
    stable_normal = 2.0 / _pair_frequency(case) * (math.sqrt(1 + zeta**2) - zeta)
    # Contacts in a packed column couple into faster modes than one pair: keep a margin.
    return case["numerics.time_step_safety"] * stable_normal


def time_step(case: Case) -> float:
    """numerics.time_step_fraction of the contact time, rounded down so that output.interval is a
    whole number of steps (frames fall on t = k dt), s; CaseError above stable_time_step."""
    t_c = contact_time(case)
    dt = case["numerics.time_step_fraction"] * t_c
    dt = case["output.interval"] / math.ceil(case["output.interval"] / dt)
    stable = stable_time_step(case)
    if dt > stable:
        raise CaseError(
            f"numerics.time_step_fraction = {case['numerics.time_step_fraction']:g} gives a time step "
            f"{dt:.3g} s above the stable limit {stable:.3g} s (= {stable / t_c:.3f} of the "
            f"contact time {t_c:.3g} s, numerics.time_step_safety = "
            f"{case['numerics.time_step_safety']:g} of the single-pair limit); use "
            f"numerics.time_step_fraction <= {stable / t_c:.3f}")
    return dt


# The dashpot acts on the slip of the contact point, whose inertia is m/7 for two spheres (sliding +
# rolling of both) and 2m/7 against the wall. An explicit step with gamma_t dt / m_slip above 1
# reverses the slip, above 2 amplifies it (a sticking grain then chatters at the Coulomb bound);
# capped at m_slip/dt the slip of a sticking contact decays at any dt (tests/engine/test_grains.py).
# Below the cap (dt < (m/7)/gamma_t = 9.6 us for the default grains) the law is the papers'
# unchanged. The implicit spin kick would let a lone pair go to gamma_t dt/m = 0.184 without
# reversing, but a packed bed then chatters from 0.175 t_c
# (docs/decisions/0007-time-step-0.2-tc-rejected.md), so both kicks keep it.
def tangential_damping_pair(case: Case) -> float:
    """gamma_t between grains: min(particles.tangential_damping, (m/7)/dt), N s/m."""
    return min(case["particles.tangential_damping"], grain_mass(case) / 7.0 / time_step(case))


def tangential_damping_wall(case: Case) -> float:
    """gamma_t at the wall: min(particles.tangential_damping, (2m/7)/dt), N s/m."""
    return min(case["particles.tangential_damping"], 2.0 * grain_mass(case) / 7.0 / time_step(case))


@dataclass(frozen=True)
class ContactModel:
    """The contact law's derived constants of a case, SI units, for the Python side (reports,
    checks, the driver's bookkeeping); the kernels read theirs from engine/parameters.py, built by
    the same functions."""

    radius: float
    mass: float
    inertia: float
    stiffness: float
    damping_pair: float        # gamma_n grain-grain, N s/m
    damping_wall: float        # gamma_n grain-wall, N s/m
    tangential_damping: float  # gamma_t as configured, N s/m
    tangential_damping_pair: float  # gamma_t used grain-grain: min(gamma_t, (m/7)/dt), N s/m
    tangential_damping_wall: float  # gamma_t used grain-wall: min(gamma_t, (2m/7)/dt), N s/m
    friction_pair: float
    friction_wall: float
    contact_time: float        # duration of a head-on grain-grain contact, s
    stable_time_step: float    # explicit stability limit, s
    time_step: float           # the step used, s
    implicit_spin: bool        # numerics.implicit_spin: spin kicks of sticking contacts taken implicitly

    @property
    def dashpot_step_ratio(self) -> float:
        """gamma_t dt / (m/7) between grains: the step over the slip's relaxation time (1 at the cap)."""
        return self.tangential_damping_pair * self.time_step / (self.mass / 7.0)

    @property
    def dashpot_resolved(self) -> bool:
        """Whether packed beds are resolved at this step: dashpot_step_ratio <= DASHPOT_RESOLVED_RATIO,
        or the implicit spin kick, which took the bulk bed at 0.15 t_c to 0.05 t_c's within 1.5 %."""
        return self.implicit_spin or self.dashpot_step_ratio <= DASHPOT_RESOLVED_RATIO

    @classmethod
    def from_case(cls, case: Case) -> "ContactModel":
        return cls(
            radius=grain_radius(case), mass=grain_mass(case), inertia=grain_inertia(case),
            stiffness=case["particles.stiffness"], damping_pair=damping_pair(case),
            damping_wall=damping_wall(case), tangential_damping=case["particles.tangential_damping"],
            tangential_damping_pair=tangential_damping_pair(case),
            tangential_damping_wall=tangential_damping_wall(case),
            friction_pair=case["particles.friction"], friction_wall=case["wall.friction"],
            contact_time=contact_time(case), stable_time_step=stable_time_step(case), time_step=time_step(case),
            implicit_spin=bool(case["numerics.implicit_spin"]))

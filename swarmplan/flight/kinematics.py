"""Kinematic models, vectorized over agents: commanded velocity in, limited velocity out.

- ``multirotor``: point mass; |v| <= speed.max and |v1 - v0| <= max_accel * dt per step.
- ``fixed_wing`` (a Dubins-airplane model): speed in [speed.min, speed.max] changing by at most
  max_accel * dt; flight-path angle within ±max_climb_angle; heading and flight-path angle turn
  together, so that the direction of flight turns by at most V * dt / min_turn_radius per step
  (V the slower of the step's two speeds): the 3D curvature of the flown path, turning angle
  over distance, stays <= 1 / min_turn_radius at every speed.
Positions advance with the new velocity (semi-implicit Euler), so the recorded velocity
is exactly the step's displacement over dt.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.geometry.vec3 import norm3

if TYPE_CHECKING:
    from swarmplan.world.model import World


@dataclass(frozen=True)
class AgentParams:
    """Per-agent limits as arrays of shape (N,) (``separation`` (N, 3)), in SI units and radians."""

    ids: tuple[str, ...]
    fixed_wing: np.ndarray  # bool
    radius: np.ndarray
    speed_min: np.ndarray
    speed_max: np.ndarray
    speed_cruise: np.ndarray
    max_accel: np.ndarray
    min_turn_radius: np.ndarray
    max_climb: np.ndarray
    min_altitude: np.ndarray
    separation: np.ndarray

    @classmethod
    def from_world(cls, world: World) -> AgentParams:
        a = world.agents
        arr = lambda f: np.array([f(x) for x in a], dtype=float)  # noqa: E731
        return cls(
            ids=tuple(x.id for x in a),
            fixed_wing=np.array([x.model == "fixed_wing" for x in a]),
            radius=arr(lambda x: x.radius),
            speed_min=arr(lambda x: x.speed_min),
            speed_max=arr(lambda x: x.speed_max),
            speed_cruise=arr(lambda x: x.speed_cruise),
            max_accel=arr(lambda x: x.max_accel),
            min_turn_radius=arr(lambda x: x.min_turn_radius),
            max_climb=arr(lambda x: x.max_climb_angle),
            min_altitude=arr(lambda x: x.min_altitude),
            separation=np.array([x.separation for x in a], dtype=float).reshape(-1, 3),
        )


def initial_velocity(params: AgentParams, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Multirotors start at rest; fixed wings already fly at cruise speed, level, towards the goal."""
    v = np.zeros_like(start)
    d = goal - start
    d[:, 2] = 0.0
    n = np.linalg.norm(d, axis=1)
    heading = np.where(n[:, None] > 1e-9, d / np.maximum(n, 1e-9)[:, None], np.array([1.0, 0.0, 0.0]))
    fw = params.fixed_wing
    v[fw] = heading[fw] * params.speed_cruise[fw, None]
    return v


def limit_multirotor(
    v0: np.ndarray, v_cmd: np.ndarray, vmax: np.ndarray, amax: np.ndarray, dt: float
) -> np.ndarray:
    """New velocity: the command clipped to vmax, reached with at most amax*dt of change."""
    s = norm3(v_cmd)
    v_cmd = v_cmd * np.minimum(1.0, vmax / np.maximum(s, 1e-12))[:, None]
    dv = v_cmd - v0
    n = norm3(dv)
    return v0 + dv * np.minimum(1.0, amax * dt / np.maximum(n, 1e-12))[:, None]


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def direction_angles(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heading and flight-path angle (rad) of velocities ``v`` (n, 3)."""
    return np.arctan2(v[:, 1], v[:, 0]), np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1]))


def turn_budget(dpsi: np.ndarray, gamma0: np.ndarray, gamma1: np.ndarray, budget: np.ndarray) -> np.ndarray:
    """Fraction in [0, 1] of a heading change ``dpsi`` and a flight-path angle change
    ``gamma0 -> gamma1`` that turns the direction of flight by at most ``budget`` (rad).

    Both angles move together along the straight line in (heading, flight-path angle); the
    direction then sweeps an arc on the unit sphere of length at most
    ``sqrt(dgamma^2 + (c dpsi)^2)``, ``c`` the largest cos(gamma) on the way, which bounds the
    angle between the two directions."""
    dg = gamma1 - gamma0
    crosses = np.sign(gamma0) * np.sign(gamma1) <= 0
    c = np.where(crosses, 1.0, np.cos(np.minimum(np.abs(gamma0), np.abs(gamma1))))
    need = np.sqrt(dg**2 + (c * dpsi) ** 2)
    return np.clip(budget / np.maximum(need, 1e-15), 0.0, 1.0)


def limit_fixed_wing(
    v0: np.ndarray,
    v_cmd: np.ndarray,
    vmin: np.ndarray,
    vmax: np.ndarray,
    amax: np.ndarray,
    turn_radius: np.ndarray,
    climb: np.ndarray,
    dt: float,
) -> np.ndarray:
    """New velocity of fixed wings: speed within [vmin, vmax] by at most amax * dt a step,
    |flight-path angle| <= climb, and the direction of flight turned towards the command's
    by at most ``min(V0, V1) * dt / turn_radius`` (heading and flight-path angle together).

    A command of (near) zero keeps the direction; a vertical one keeps the heading and asks
    for the full climb or dive."""
    speed0 = norm3(v0)
    psi0, gamma0 = direction_angles(v0)
    gamma0 = np.clip(gamma0, -climb, climb)
    s_cmd = norm3(v_cmd)
    speed_cmd = np.clip(s_cmd, vmin, vmax)
    psi_cmd, gamma_cmd = direction_angles(v_cmd)
    hxy = np.hypot(v_cmd[:, 0], v_cmd[:, 1])
    vertical = hxy < 1e-9 * np.maximum(s_cmd, 1e-12)
    psi_cmd = np.where(vertical, psi0, psi_cmd)
    gamma_cmd = np.where(vertical, np.sign(v_cmd[:, 2]) * climb, gamma_cmd)
    still = s_cmd < 1e-12
    psi_cmd = np.where(still, psi0, psi_cmd)
    gamma_cmd = np.clip(np.where(still, gamma0, gamma_cmd), -climb, climb)
    speed1 = np.clip(speed0 + np.clip(speed_cmd - speed0, -amax * dt, amax * dt), vmin, vmax)
    # At the slower of the two speeds, the turn keeps the radius >= turn_radius (a hair inside,
    # so rounding never crosses it).
    budget = np.minimum(speed0, speed1) / turn_radius * dt * (1.0 - 1e-9)
    dpsi = _wrap(psi_cmd - psi0)
    f = turn_budget(dpsi, gamma0, gamma_cmd, budget)
    psi1 = psi0 + f * dpsi
    gamma1 = gamma0 + f * (gamma_cmd - gamma0)
    c = np.cos(gamma1)
    return speed1[:, None] * np.stack([c * np.cos(psi1), c * np.sin(psi1), np.sin(gamma1)], axis=1)


def limit_velocity(
    params: AgentParams, v0: np.ndarray, v_cmd: np.ndarray, dt: float, idx: np.ndarray
) -> np.ndarray:
    """New velocities of agents ``idx`` under their own model's limits."""
    out = np.empty((len(idx), 3))
    fw = params.fixed_wing[idx]
    mr = ~fw
    if mr.any():
        k = idx[mr]
        out[mr] = limit_multirotor(v0[mr], v_cmd[mr], params.speed_max[k], params.max_accel[k], dt)
    if fw.any():
        k = idx[fw]
        out[fw] = limit_fixed_wing(
            v0[fw],
            v_cmd[fw],
            params.speed_min[k],
            params.speed_max[k],
            params.max_accel[k],
            params.min_turn_radius[k],
            params.max_climb[k],
            dt,
        )
    return out

"""Turn-ahead guard for fixed wings: a command is kept only if the aircraft can still turn away.

A multirotor can brake, so the one-step safety filter of the simulation is enough for it. A
fixed wing cannot stop: by the time one step would touch a wall, no command avoids it. The
potential field does not know this either (its influence distance may be shorter than the
turn radius). So, each step, for every fixed wing that has something within reach, the
guard rolls out the kinematic model for the time of a half turn plus a second under a few
constant commands — the field's command, and sustained hard left/right turns and straight
flight, each level, climbing and diving — against the analytic distances to the obstacles
(moving ones at their predicted poses) and the terrain. If the field's command keeps the
required clearance over the whole horizon it stands; otherwise the guard flies the safe
candidate closest to it, or, when none is safe, the one that keeps the most clearance.
Because the hard turns are among the candidates at every step, the guard takes over while a
turn away still exists.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.dynamics import AgentParams, limit_velocity

ClearanceFn = Callable[[np.ndarray, np.ndarray, float], np.ndarray]
"""``clearance(points (P, 3), radii (P,), t) -> (P,)`` distance from each body to the nearest
static or moving obstacle surface or the terrain at time ``t``."""

# (turn, climb) of the sustained candidate commands: turn -1/+1 = hard right/left, 0 = hold
# heading; climb -1/0/+1 = dive/level/climb at the model's limit.
_MANOEUVRES = tuple((turn, climb) for turn in (-1, 0, 1) for climb in (0, 1, -1))


def horizon_steps(params: AgentParams, idx: np.ndarray, speed: np.ndarray, dt: float) -> int:
    """Steps needed to turn through 180 degrees at the minimum radius, plus one second."""
    v = np.maximum(speed, 1e-6)
    t = np.pi * params.min_turn_radius[idx] / v + 1.0
    return int(np.ceil(float(np.max(t)) / dt))


def _manoeuvre_commands(v: np.ndarray, climb_limit: np.ndarray) -> np.ndarray:
    """Velocity commands (n, C, 3) of the sustained manoeuvres for current velocities ``v`` (n, 3)."""
    speed = np.linalg.norm(v, axis=1)
    psi = np.arctan2(v[:, 1], v[:, 0])
    turn = np.array([m[0] for m in _MANOEUVRES], dtype=float)
    climb = np.array([m[1] for m in _MANOEUVRES], dtype=float)
    # A heading 90 degrees off makes the model turn at its limit every step.
    a = psi[:, None] + turn[None, :] * (np.pi / 2)
    g = climb[None, :] * climb_limit[:, None]
    c = np.cos(g)
    return speed[:, None, None] * np.stack([c * np.cos(a), c * np.sin(a), np.sin(g)], axis=-1)


def guard_commands(
    params: AgentParams,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    v_cmd: np.ndarray,
    t0: float,
    dt: float,
    clearance: ClearanceFn,
    required: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Guarded commands of fixed wings ``idx`` (rows of ``pos``, ``vel``, ``v_cmd``).

    ``required`` (n,) is the clearance each must keep over the horizon. Returns the commands
    (n, 3) and a mask (n,) of the agents whose field command was replaced.
    """
    n = len(idx)
    out = v_cmd.copy()
    replaced = np.zeros(n, dtype=bool)
    if n == 0:
        return out, replaced
    steps = horizon_steps(params, idx, np.linalg.norm(vel, axis=1), dt)
    c = 1 + len(_MANOEUVRES)
    agent_of = np.repeat(idx, c)
    radii = params.radius[agent_of]
    p = np.repeat(pos, c, axis=0)
    v = np.repeat(vel, c, axis=0)
    fixed = np.repeat(v_cmd, c, axis=0)  # candidate 0 of each agent: the field's command
    is_field = np.tile(np.arange(c) == 0, n)
    worst = np.full(n * c, np.inf)
    first = None
    for k in range(steps):
        man = _manoeuvre_commands(
            v.reshape(n, c, 3)[:, 1:].reshape(-1, 3), params.max_climb[agent_of[~is_field]]
        )
        cmd = fixed.copy()
        cmd[~is_field] = man[np.arange(len(man)), np.tile(np.arange(c - 1), n)]
        v = limit_velocity(params, v, cmd, dt, agent_of)
        if first is None:
            first = v.copy()
        p = p + v * dt
        worst = np.minimum(worst, clearance(p, radii, t0 + (k + 1) * dt))
    worst = worst.reshape(n, c)
    first = first.reshape(n, c, 3)
    for i in range(n):
        if worst[i, 0] >= required[i]:
            continue
        safe = np.flatnonzero(worst[i, 1:] >= required[i]) + 1
        if len(safe):
            # Of the safe manoeuvres, the one whose next velocity is nearest the field's.
            gap = np.linalg.norm(first[i, safe] - first[i, 0], axis=1)
            j = int(safe[np.argmin(gap)])
        else:
            j = int(np.argmax(worst[i]))
        if j != 0:
            out[i] = first[i, j]
            replaced[i] = True
    return out, replaced

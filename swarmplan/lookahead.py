"""Turn-ahead guard for fixed wings: a command is kept only if the aircraft can still turn away.

A multirotor can brake, so the one-step safety filter of the simulation is enough for it. A
fixed wing cannot stop: by the time one step would touch a wall, no command avoids it. The
potential field does not know this either (its influence distance may be shorter than the
turn radius). So, each step, for every fixed wing that has something within reach, the
guard predicts its flight for the time of a half turn plus a second under a few commands —
the field's command (turn towards its heading at the maximum rate, then straight), and
sustained hard left/right turns and straight flight, each level, climbing and diving — and
measures the clearance of every predicted position to the obstacles (moving ones at their
predicted poses), the terrain and the bounds. If the field's command keeps the required
clearance over the whole horizon it stands; otherwise the guard flies the safe manoeuvre
closest to it, or, when none is safe, the one that keeps the most clearance. Because the
hard turns are among the candidates at every step, the guard takes over while a turn away
still exists.

The predictions are closed-form arcs and helices of the model (constant speed, heading rate
V / R_min, flight-path angle set at once, as ``swarmplan.dynamics.limit_fixed_wing`` flies
them), so all candidates and all times are measured in one batched distance query.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.dynamics import AgentParams, limit_velocity

ClearanceFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``clearance(points (P, 3), radii (P,), times (P,)) -> (P,)`` distance from each body to the
nearest obstacle surface (moving ones where they are at that time), the terrain or the bounds."""

# (turn, climb) of the sustained candidate commands: turn -1/+1 = hard right/left, 0 = hold
# heading; climb -1/0/+1 = dive/level/climb at the model's limit.
_MANOEUVRES = tuple((turn, climb) for turn in (-1, 0, 1) for climb in (0, 1, -1))


def _wrap_angle(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


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


def predicted_positions(
    pos: np.ndarray,
    vel: np.ndarray,
    turn: np.ndarray,
    turn_time: np.ndarray,
    gamma: np.ndarray,
    radius: np.ndarray,
    times: np.ndarray,
) -> np.ndarray:
    """Positions (n, c, H, 3) at ``times`` (H,) of fixed wings at ``pos``/``vel`` (n, 3) flying
    candidate c: turn direction ``turn`` (n, c) in {-1, 0, 1} held for ``turn_time`` (n, c) s
    at the rate V / ``radius`` (n,), then straight, at flight-path angle ``gamma`` (n, c)."""
    v = np.linalg.norm(vel, axis=1)[:, None, None]  # (n, 1, 1)
    psi0 = np.arctan2(vel[:, 1], vel[:, 0])[:, None, None]
    omega = (np.linalg.norm(vel, axis=1) / radius)[:, None, None]
    t = times[None, None, :]
    g = gamma[..., None]
    vh = v * np.cos(g)
    s = turn[..., None]
    t1 = np.minimum(t, np.where(s == 0, 0.0, turn_time[..., None]))
    psi1 = psi0 + s * omega * t1
    # Arc part (s != 0): integral of vh (cos, sin)(psi0 + s w tau) over [0, t1].
    sw = np.where(s == 0, 1.0, s * omega)
    ax = np.where(s == 0, 0.0, vh / sw * (np.sin(psi1) - np.sin(psi0)))
    ay = np.where(s == 0, 0.0, -vh / sw * (np.cos(psi1) - np.cos(psi0)))
    rest = t - t1
    x = ax + vh * rest * np.cos(psi1)
    y = ay + vh * rest * np.sin(psi1)
    z = v * np.sin(g) * t + 0.0 * x
    return pos[:, None, None, :] + np.stack([x, y, z], axis=-1)


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
    speed = np.linalg.norm(vel, axis=1)
    steps = horizon_steps(params, idx, speed, dt)
    times = np.arange(1, steps + 1) * dt
    climb = params.max_climb[idx]
    radius = params.min_turn_radius[idx]
    # Candidate 0, the field's command: turn towards its heading at the maximum rate, then straight.
    psi0 = np.arctan2(vel[:, 1], vel[:, 0])
    hxy = np.linalg.norm(v_cmd[:, :2], axis=1)
    gamma_cmd = np.where(
        hxy < 1e-9, np.sign(v_cmd[:, 2]) * climb, np.arctan2(v_cmd[:, 2], np.maximum(hxy, 1e-12))
    )
    dpsi = np.where(hxy < 1e-9, 0.0, _wrap_angle(np.arctan2(v_cmd[:, 1], v_cmd[:, 0]) - psi0))
    omega = np.maximum(speed, 1e-6) / radius
    man_turn = np.array([m[0] for m in _MANOEUVRES], dtype=float)
    man_climb = np.array([m[1] for m in _MANOEUVRES], dtype=float)
    turn = np.concatenate([np.sign(dpsi)[:, None], np.broadcast_to(man_turn, (n, len(man_turn)))], axis=1)
    turn_time = np.concatenate([(np.abs(dpsi) / omega)[:, None], np.full((n, len(man_turn)), np.inf)], axis=1)
    gamma = np.concatenate(
        [np.clip(gamma_cmd, -climb, climb)[:, None], man_climb[None, :] * climb[:, None]], axis=1
    )
    c = turn.shape[1]
    points = predicted_positions(pos, vel, turn, turn_time, gamma, radius, times)  # (n, c, H, 3)
    radii = np.repeat(params.radius[idx], c * steps)
    when = t0 + np.tile(times, n * c)
    worst = clearance(points.reshape(-1, 3), radii, when).reshape(n, c, steps).min(axis=2)
    # What each candidate flies on the next step, under the model itself.
    cmds = np.concatenate([v_cmd[:, None, :], _manoeuvre_commands(vel, climb)], axis=1)
    first = limit_velocity(params, np.repeat(vel, c, axis=0), cmds.reshape(-1, 3), dt, np.repeat(idx, c))
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

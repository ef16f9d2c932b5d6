"""Turn-ahead guard for fixed wings: a command is kept only if the aircraft can still turn away.

A multirotor can brake, so the one-step safety filter of the simulation is enough for it. A
fixed wing cannot stop: by the time one step would touch a wall, no command avoids it. The
potential field does not know this either (its influence distance may be shorter than the
turn radius). So, each step, for every fixed wing that has something within reach, the
guard predicts, for the time of a full turn plus a second, the sustained manoeuvres — hard
left/right turns and straight flight, each level, climbing and diving — and measures the
clearance of every predicted position to the obstacles (moving ones at their predicted
poses), the terrain and the bounds. The field's command stands if, after one step of it, at
least one manoeuvre keeps the required clearance: a way out always remains (the invariant
of braking-distance checks, with turns in place of brakes). Otherwise the guard starts now
the safe manoeuvre closest to the field's command, or, when none is safe, the one that keeps
the most clearance. Flying the field's command until the last step that keeps a way out
leaves the field in charge everywhere but where it would corner the aircraft.

The predictions fly the model itself (``swarmplan.flight.kinematics.limit_fixed_wing``, step by
step, at constant speed: the flight-path angle ramps within the same turn budget as the
heading), all candidates at once, and all candidates and all times are measured in one batched
distance query. The manoeuvres from where the aircraft is now are only needed where the field's
command would corner it: they are flown for those aircraft alone (every row of a rollout and of
a clearance query is computed on its own, so the answers are those of flying them all).
(:func:`predicted_positions` gives the closed-form arcs and helices of a
heading rate V / R_min with the flight-path angle set at once, the level-turn limit of it.)
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.flight.kinematics import AgentParams, limit_fixed_wing, limit_velocity

ClearanceFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``clearance(points (P, 3), radii (P,), times (P,)) -> (P,)`` distance from each body to the
nearest obstacle surface (moving ones where they are at that time), the terrain or the bounds."""

# (turn, climb) of the sustained candidate commands: turn -1/+1 = hard right/left, 0 = hold
# heading; climb -1/0/+1 = dive/level/climb at the model's limit.
_MANOEUVRES = tuple((turn, climb) for turn in (-1, 0, 1) for climb in (0, 1, -1))


def horizon_steps(params: AgentParams, idx: np.ndarray, speed: np.ndarray, dt: float) -> int:
    """Steps needed to fly a full circle at the minimum radius, plus one second: a turn that
    stays clear that long is a loiter the aircraft can keep up among static obstacles (half a
    circle let moving ones close the rest of it: a 2 km-radius aircraft was cornered between
    two movers and a no-fly zone)."""
    v = np.maximum(speed, 1e-6)
    t = 2.0 * np.pi * params.min_turn_radius[idx] / v + 1.0
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
    z = np.broadcast_to(v * np.sin(g) * t, x.shape)
    return pos[:, None, None, :] + np.stack([x, y, z], axis=-1)


def rollout_manoeuvres(
    params: AgentParams, idx: np.ndarray, pos: np.ndarray, vel: np.ndarray, steps: int, dt: float
) -> np.ndarray:
    """Positions (n, C, steps, 3) of fixed wings ``idx`` at ``pos``/``vel`` flying each sustained
    manoeuvre for ``steps`` steps of the model at constant speed (the commands are re-formed
    from the current heading each step, as the guard flies them)."""
    n, c = len(idx), len(_MANOEUVRES)
    rows = np.repeat(idx, c)
    speed = np.repeat(np.linalg.norm(vel, axis=1), c)
    climb = params.max_climb[rows]
    radius = params.min_turn_radius[rows]
    amax = params.max_accel[rows]
    v = np.repeat(vel, c, axis=0)
    p = np.repeat(pos, c, axis=0)
    out = np.empty((steps, n * c, 3))
    turn = np.tile(np.array([m[0] for m in _MANOEUVRES], dtype=float), n)
    up = np.tile(np.array([m[1] for m in _MANOEUVRES], dtype=float), n) * climb
    for k in range(steps):
        cmd = _sustained_commands(v, turn, up)
        v = limit_fixed_wing(v, cmd, speed, speed, amax, radius, climb, dt)
        p = p + v * dt
        out[k] = p
    return out.transpose(1, 0, 2).reshape(n, c, steps, 3)


def _sustained_commands(v: np.ndarray, turn: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The manoeuvres' commands (n * C, 3) from the current velocities ``v`` (n * C, 3), row
    ``i * C + j`` manoeuvre j: its turn (-1, 0, 1) in ``turn`` and its flight-path angle
    (the climb limit times -1, 0 or 1) in ``g`` (n * C each)."""
    speed = np.linalg.norm(v, axis=1)
    psi = np.arctan2(v[:, 1], v[:, 0])
    a = psi + turn * (np.pi / 2)
    cg = np.cos(g)
    return speed[:, None] * np.stack([cg * np.cos(a), cg * np.sin(a), np.sin(g)], axis=-1)


def _manoeuvre_clearance(
    params: AgentParams,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    times: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted positions (n, C, H, 3) of the sustained manoeuvres from ``pos``/``vel``, and the
    matching body radii (n, C, H)."""
    n, c = len(idx), len(_MANOEUVRES)
    points = rollout_manoeuvres(params, idx, pos, vel, len(times), dt)
    radii = np.broadcast_to(params.radius[idx][:, None, None], (n, c, len(times)))
    return points, radii


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

    The field's command stands if, after one step of it, at least one sustained manoeuvre
    (hard left/right turn or straight, level/climbing/diving) keeps ``required`` (n,) clearance
    over the horizon: a way out is always kept. Otherwise the agent starts now the safe
    manoeuvre whose next velocity is nearest the field's (or, if none is safe, the one keeping
    the most clearance). Returns the commands (n, 3) and a mask (n,) of the replaced ones.
    """
    n = len(idx)
    out = v_cmd.copy()
    replaced = np.zeros(n, dtype=bool)
    if n == 0:
        return out, replaced
    steps = horizon_steps(params, idx, np.linalg.norm(vel, axis=1), dt)
    times = np.arange(1, steps + 1) * dt
    c = len(_MANOEUVRES)
    # After one step of the field's command ...
    v_next = limit_velocity(params, vel, v_cmd, dt, idx)
    p_next = pos + v_next * dt
    after, r_after = _manoeuvre_clearance(params, idx, p_next, v_next, times, dt)
    points = np.concatenate([after.reshape(-1, 3), p_next])
    radii = np.concatenate([r_after.reshape(-1), params.radius[idx]])
    when = np.concatenate([np.tile(t0 + dt + times, n * c), np.full(n, t0 + dt)])
    clear = clearance(points, radii, when)
    m = n * c * steps
    worst_after = clear[:m].reshape(n, c, steps).min(axis=2)
    step_clear = clear[m:]
    keep = (step_clear >= required) & np.any(worst_after >= required[:, None], axis=1)
    if keep.all():
        return out, replaced
    # ... and, for the agents it would corner, from where they are now (each row of a rollout
    # and of a clearance is its own: the same values as when every agent is rolled out).
    rows = np.flatnonzero(~keep)
    k = len(rows)
    now, r_now = _manoeuvre_clearance(params, idx[rows], pos[rows], vel[rows], times, dt)
    clear_now = clearance(now.reshape(-1, 3), r_now.reshape(-1), np.tile(t0 + times, k * c))
    worst_now = np.full((n, c), -np.inf)
    worst_now[rows] = clear_now.reshape(k, c, steps).min(axis=2)
    # What each manoeuvre flies on the next step, under the model itself.
    cmds = _manoeuvre_commands(vel, params.max_climb[idx])
    first = limit_velocity(params, np.repeat(vel, c, axis=0), cmds.reshape(-1, 3), dt, np.repeat(idx, c))
    first = first.reshape(n, c, 3)
    for i in np.flatnonzero(~keep):
        safe = np.flatnonzero(worst_now[i] >= required[i])
        if len(safe):
            gap = np.linalg.norm(first[i, safe] - v_next[i], axis=1)
            j = int(safe[np.argmin(gap)])
        else:
            j = int(np.argmax(worst_now[i]))
        out[i] = first[i, j]
        replaced[i] = True
    return out, replaced

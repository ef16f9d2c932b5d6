"""Turn-ahead guard for fixed wings: a command is kept only if the aircraft can still turn away.

A multirotor can brake, so the one-step safety filter of the simulation is enough for it. A
fixed wing cannot stop: by the time one step would touch a wall, no command avoids it. The
potential field does not know this either (its influence distance may be shorter than the
turn radius). So, each step, for every fixed wing that has something within reach, the
guard predicts, for the time of a full turn plus a second, the sustained manoeuvres — hard
left/right turns and straight flight, each levelling out, climbing to the ceiling of the flight
volume or diving to its floor and levelling off there — and measures the
clearance of every predicted position to the obstacles (moving ones at their predicted
poses), the terrain and the bounds. The field's command stands if, after one step of it, at
least one manoeuvre keeps the required clearance: a way out always remains (the invariant
of braking-distance checks, with turns in place of brakes). Otherwise the guard starts now
the safe manoeuvre closest to the field's command, or, when none is safe, the one that keeps
clear the longest (time for a mover to pass, for the field to find a way), the clearest of
those. Flying the field's command until the last step that keeps a way out
leaves the field in charge everywhere but where it would corner the aircraft.

The predictions fly the model itself (``swarmplan.flight._fixed_wing_kernel``, compiled: step
by step, at constant speed, rolling from the aircraft's current turn at its roll rate; the
flight-path angle ramps within the same turn budget as the heading, and comes first in it: a
diving aircraft pulls out before it tightens its turn, so a level manoeuvre does level out),
all candidates at once,
and all candidates and all times are measured in one batched distance query. The clearance
kept from obstacles, still or moving, is the aircraft's own (``clearance``, by default the
largest of its radius, half its horizontal separation and 0.05 R_min), at each predicted
position with the room the straight chord to the next one can dip by (:func:`kept_gap`); from
the terrain and the bounds one body radius. The manoeuvres from where the aircraft is now are
only needed where the field's command would corner it: they are flown for those aircraft alone
(every row of a rollout and of a clearance query is computed on its own, so the answers are
those of flying them all).
(:func:`predicted_positions` gives the closed-form arcs and helices of a
heading rate V / R_min with the flight-path angle set at once, the level-turn limit of it.)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from swarmplan.flight.kinematics import AgentParams, fixed_wing_model, fly_fixed_wing

ClearanceFn = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``clearance(points (P, 3), radii (P,), times (P,), extra (P,)) -> (P,)`` distance from each
body to the terrain or the bounds, or to the nearest obstacle surface (moving ones where they
are at that time) less ``extra``, the gap kept from obstacles beyond ``radii``."""


class CompiledGuard(NamedTuple):
    """The guard's two questions, each in one compiled pass that flies the manoeuvres of
    ``rollout`` (the rows of ``_fixed_wing_kernel.rollouts``' arguments but the steps: pos, vel,
    kappa, turn (n, C'), up (n, C'), amax, radius, climb, roll, dt) and measures their predicted
    positions with ``clearance`` as it goes: the answers of :func:`rollout_manoeuvres` and
    ``clearance``, without a position or a clearance array.

    ``first_safe(rollout, times (H + 1,), radii (n,), extra (n,), required (n,)) -> (here (n,),
    first (n,))``: the clearance of where each aircraft is at ``times[0]`` and the first of its
    manoeuvres whose positions at ``times[1:]`` all keep ``required`` (-1: none).
    ``least(rollout, times (2 H,), radii (n,), extra (n,), required (n,)) -> ((n, C'), (n, C'))``:
    the least clearance of each manoeuvre's positions at ``times`` and the steps it keeps
    ``required`` before the first that does not."""

    first_safe: Callable[..., tuple[np.ndarray, np.ndarray]]
    least: Callable[..., tuple[np.ndarray, np.ndarray]]


# (turn, climb) of the sustained candidate commands: turn -1/+1 = hard right/left, 0 = hold
# heading; climb -1/0/+1 = dive/level/climb at the model's limit.
_MANOEUVRES = tuple((turn, climb) for turn in (-1, 0, 1) for climb in (0, 1, -1))
_TURN = np.array([m[0] for m in _MANOEUVRES], dtype=float)
_UP = np.array([m[1] for m in _MANOEUVRES], dtype=float)


def horizon_steps(params: AgentParams, idx: np.ndarray, speed: np.ndarray, dt: float) -> int:
    """Steps needed to fly a full circle at the minimum radius, plus one second: a turn that
    stays clear that long is a loiter the aircraft can keep up among static obstacles (half a
    circle let moving ones close the rest of it: a 2 km-radius aircraft was cornered between
    two movers and a no-fly zone)."""
    v = np.maximum(speed, 1e-6)
    t = 2.0 * np.pi * params.min_turn_radius[idx] / v + 1.0
    return int(np.ceil(float(np.max(t)) / dt))


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
    params: AgentParams,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    steps: int,
    dt: float,
    kappa: np.ndarray | None = None,
    which: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (n, C, 2 steps, 3) of fixed wings ``idx`` at ``pos``/``vel`` (turn states
    ``kappa`` (n, 2), default straight) flying each sustained manoeuvre (or, with ``which``
    (n, C'), the manoeuvres of those indices) over a horizon of ``steps`` steps of the model at
    constant speed, and the steps each flew (n, C): the horizon and one more for each step it
    was settling (the commands are re-formed from the current state each step, as the guard
    flies them; compiled, ``swarmplan.flight._fixed_wing_kernel.rollouts``)."""
    n = len(idx)
    if which is None:
        which = np.broadcast_to(np.arange(len(_MANOEUVRES)), (n, len(_MANOEUVRES)))
    *rows, dt = _rollout_rows(params, idx, pos, vel, kappa, which, dt)
    return fixed_wing_model().rollouts(*rows, int(steps), dt)


def _rollout_rows(
    params: AgentParams,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    kappa: np.ndarray | None,
    which: np.ndarray,
    dt: float,
) -> tuple:
    """The compiled rollouts' arguments (pos, vel, kappa, turn, top, amax, radius, climb, roll,
    dt) of fixed wings ``idx`` flying the manoeuvres ``which`` (n, C'): a climb flies to the
    ceiling of ``params.levels``, a dive to its floor (none: for good), level ones nan."""
    f = np.ascontiguousarray
    kappa = np.zeros((len(idx), 2)) if kappa is None else f(kappa, dtype=float)
    up = _UP[which]
    if params.levels is None:
        floor, ceiling = np.full((len(idx), 1), -np.inf), np.full((len(idx), 1), np.inf)
    else:
        floor, ceiling = params.levels[idx, :1], params.levels[idx, 1:]
    top = np.where(up > 0, ceiling, np.where(up < 0, floor, np.nan))
    return (
        f(pos, dtype=float), f(vel, dtype=float), kappa, f(_TURN[which]), f(top, dtype=float),
        f(params.max_accel[idx]), f(params.min_turn_radius[idx]), f(params.max_climb[idx]),
        f(params.roll_rate[idx]), dt,
    )  # fmt: skip


def _manoeuvre_clearance(
    params: AgentParams,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    kappa: np.ndarray,
    times: np.ndarray,
    dt: float,
    which: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Predicted positions (n, C, 2 H, 3) of the sustained manoeuvres (``which``: those of these
    indices, (n, C')) from ``pos``/``vel``/``kappa`` at ``times`` (2 H,), the steps each flew
    (n, C), the matching body radii (n, C, 2 H) and the gaps kept from bodies beyond them."""
    n, c = len(idx), len(_MANOEUVRES) if which is None else which.shape[1]
    points, used = rollout_manoeuvres(params, idx, pos, vel, len(times) // 2, dt, kappa, which)
    radii = np.broadcast_to(params.radius[idx][:, None, None], (n, c, len(times)))
    extra = np.broadcast_to(kept_gap(params, idx, dt)[:, None, None], (n, c, len(times)))
    return points, used, radii, extra


def kept_gap(params: AgentParams, idx: np.ndarray, dt: float) -> np.ndarray:
    """The gap (n,) fixed wings ``idx`` keep from obstacles beyond their radius at each predicted
    position, so that the straight chord flown between two of them keeps their ``clearance``:
    within a distance ``D`` of a convex body the squared distance falls along a chord of length
    ``L`` by at most ``L^2 / 4`` below its ends' (``D^2 - |x|^2`` is concave), so ends at
    ``sqrt(D^2 + L^2 / 4)`` keep ``D`` = ``clearance`` + radius all along it (``L``: a step at the
    top speed)."""
    reach = params.clearance[idx] + params.radius[idx]
    half = 0.5 * params.speed_max[idx] * dt
    return np.sqrt(reach * reach + half * half) - reach + params.clearance[idx] - params.radius[idx]


def _least(clear: np.ndarray, used: np.ndarray) -> np.ndarray:
    """The least of ``clear`` (n, C, T) over the first ``used`` (n, C) steps of each row."""
    flown = np.arange(clear.shape[2]) < used[..., None]
    return np.where(flown, clear, np.inf).min(axis=2)


def _kept(clear: np.ndarray, used: np.ndarray, required: np.ndarray) -> np.ndarray:
    """The steps (n, C) each row of ``clear`` (n, C, T) keeps ``required`` (n,) before the first
    that does not, among its first ``used`` (n, C) (all of them when none)."""
    short = (clear < required[:, None, None]) & (np.arange(clear.shape[2]) < used[..., None])
    return np.where(short.any(axis=2), np.argmax(short, axis=2), used)


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
    kappa: np.ndarray | None = None,
    prefer: np.ndarray | None = None,
    compiled: CompiledGuard | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Guarded commands of fixed wings ``idx`` (rows of ``pos``, ``vel``, ``v_cmd`` and of their
    turn states ``kappa``, default straight). ``prefer`` (n,), updated in place: per agent the
    manoeuvre checked first (the answer does not depend on it; the last one found safe is
    usually safe again, and then the others are not rolled out).

    The field's command stands if, after one step of it, at least one sustained manoeuvre
    (hard left/right turn or straight, levelling/climbing/diving) keeps ``required`` (n,)
    clearance (obstacles: ``params.clearance``) over the horizon, and over as many steps more as
    it took to settle into its steady turn: a way out is always kept. Otherwise
    the agent starts now the safe manoeuvre whose next velocity is nearest the field's (or, if
    none is safe, the one that keeps the clearance the longest, the clearest of those). Returns
    the commands (n, 3) and a mask (n,) of the replaced ones. ``compiled``, when given, answers
    in one pass each (the same answers as rolling the manoeuvres out and measuring
    ``clearance``).
    """
    n = len(idx)
    out = v_cmd.copy()
    replaced = np.zeros(n, dtype=bool)
    if n == 0:
        return out, replaced
    kappa = np.zeros((n, 2)) if kappa is None else kappa
    steps = horizon_steps(params, idx, np.linalg.norm(vel, axis=1), dt)
    # The horizon and as much again for the steps a manoeuvre is still settling.
    times = np.arange(1, 2 * steps + 1) * dt
    c = len(_MANOEUVRES)
    extra_now = kept_gap(params, idx, dt)
    # After one step of the field's command ...
    k = idx
    v_next, k_next = fly_fixed_wing(
        vel, v_cmd, params.speed_min[k], params.speed_max[k], params.max_accel[k],
        params.min_turn_radius[k], params.max_climb[k], dt, kappa, params.roll_rate[k],
    )  # fmt: skip
    p_next = pos + v_next * dt
    # Is any manoeuvre safe after it? Each agent's ``prefer`` (the one safe there last time)
    # first, every other one only for the agents it leaves in doubt: the same answers.
    prefer = np.zeros(n, dtype=np.int64) if prefer is None else prefer
    if compiled is None:
        pref, used, r_pref, e_pref = _manoeuvre_clearance(
            params, idx, p_next, v_next, k_next, times, dt, prefer[:, None]
        )
        points = np.concatenate([pref.reshape(-1, 3), p_next])
        radii = np.concatenate([r_pref.reshape(-1), params.radius[idx]])
        extra = np.concatenate([e_pref.reshape(-1), extra_now])
        when = np.concatenate([np.tile(t0 + dt + times, n), np.full(n, t0 + dt)])
        clear = clearance(points, radii, when, extra)
        m = n * 2 * steps
        step_clear, least = clear[m:], _least(clear[:m].reshape(n, 1, 2 * steps), used)[:, 0]
        keep = (step_clear >= required) & (least >= required)
    else:
        when = t0 + dt + np.concatenate([[0.0], times])
        rows = _rollout_rows(params, idx, p_next, v_next, k_next, prefer[:, None], dt)
        step_clear, first = compiled.first_safe(rows, when, params.radius[idx], extra_now, required)
        keep = (step_clear >= required) & (first >= 0)
    doubt = np.flatnonzero(~keep & (step_clear >= required))
    if len(doubt) and compiled is not None:
        d = len(doubt)
        which = np.broadcast_to(np.arange(c), (d, c))
        rows = _rollout_rows(params, idx[doubt], p_next[doubt], v_next[doubt], k_next[doubt], which, dt)
        radii = params.radius[idx[doubt]]
        _, first = compiled.first_safe(rows, when, radii, extra_now[doubt], required[doubt])
        keep[doubt] = first >= 0
        prefer[doubt] = np.where(first >= 0, first, prefer[doubt])
    elif len(doubt):
        d = len(doubt)
        after, used, r_after, e_after = _manoeuvre_clearance(
            params, idx[doubt], p_next[doubt], v_next[doubt], k_next[doubt], times, dt
        )
        when = np.tile(t0 + dt + times, d * c)
        clear_after = clearance(after.reshape(-1, 3), r_after.reshape(-1), when, e_after.reshape(-1))
        safe = _least(clear_after.reshape(d, c, 2 * steps), used) >= required[doubt, None]
        keep[doubt] = safe.any(axis=1)
        prefer[doubt] = np.where(safe.any(axis=1), np.argmax(safe, axis=1), prefer[doubt])
    if keep.all():
        return out, replaced
    # ... and, for the agents it would corner, from where they are now (each row of a rollout
    # and of a clearance is its own: the same values as when every agent is rolled out).
    rows = np.flatnonzero(~keep)
    kk = len(rows)
    worst_now = np.full((n, c), -np.inf)
    kept_now = np.zeros((n, c), dtype=np.int64)
    if compiled is None:
        at = idx[rows]
        now, used, r_now, e_now = _manoeuvre_clearance(
            params, at, pos[rows], vel[rows], kappa[rows], times, dt
        )
        when_now = np.tile(t0 + times, kk * c)
        clear_now = clearance(now.reshape(-1, 3), r_now.reshape(-1), when_now, e_now.reshape(-1))
        clear_now = clear_now.reshape(kk, c, 2 * steps)
        worst_now[rows] = _least(clear_now, used)
        kept_now[rows] = _kept(clear_now, used, required[rows])
    else:
        which = np.broadcast_to(np.arange(c), (kk, c))
        flown = _rollout_rows(params, idx[rows], pos[rows], vel[rows], kappa[rows], which, dt)
        worst_now[rows], kept_now[rows] = compiled.least(
            flown, t0 + times, params.radius[idx[rows]], extra_now[rows], required[rows]
        )
    # What each manoeuvre flies on the next step, under the model itself.
    every = np.broadcast_to(np.arange(c), (n, c))
    *now_rows, _ = _rollout_rows(params, idx, pos, vel, kappa, every, dt)
    first = fixed_wing_model().first_velocities(*now_rows, dt)
    for i in np.flatnonzero(~keep):
        safe = np.flatnonzero(worst_now[i] >= required[i])
        if len(safe):
            gap = np.linalg.norm(first[i, safe] - v_next[i], axis=1)
            j = int(safe[np.argmin(gap)])
        else:  # none keeps clear: the one that keeps clear the longest, then the clearest
            j = int(np.lexsort((worst_now[i], kept_now[i]))[-1])
        out[i] = first[i, j]
        replaced[i] = True
    return out, replaced

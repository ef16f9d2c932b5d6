"""The fixed-wing kinematic model compiled: one step of one aircraft, the model's steps of many
aircraft, the turn state a step leaves, and the turn-ahead guard's rollouts of the sustained
manoeuvres (``swarmplan.flight.kinematics`` and ``swarmplan.flight.lookahead`` call these: the
one implementation of the model).

One step (:func:`fly_step`): speed towards the command's within [vmin, vmax], by at most
amax * dt; the direction of flight turned towards the command's. The turn is a vector
``w = (c dpsi, dgamma)`` of heading and flight-path angle changes (``c`` the largest
cos(gamma) between the step's two flight-path angles): its length bounds the angle the
direction turns (the direction sweeps an arc on the unit sphere no longer than it), so
``|w| <= V dt / R_min`` (V the slower of the step's two speeds) keeps the path's curvature
within 1 / R_min. The turn state ``kappa = w / (V dt)`` is the curvature of the step, its
horizontal and vertical parts; with a finite roll rate ``p`` (rad/s) the bank of the
horizontal part, ``atan(kappa_h V^2 / g)`` (a level turn's bank, V the step's faster speed),
changes by at most ``p dt`` a step, and the climb or dive takes what the turn leaves of the
budget: the turn's curvature changes continuously, the aircraft rolls into and out of turns.

Loaded at the first fixed-wing step through ``runtime.compiled.kernel_module``; every compiled
function of the model is in this file (numba's cache does not see callees in other files).
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.runtime.compiled import njit

GRAVITY = 9.80665  # swarmplan.world.airframe.GRAVITY


@njit(cache=True, nogil=True, error_model="numpy")
def _clip(x, lo, hi):  # noqa: ANN001, ANN202
    return min(max(x, lo), hi)


@njit(cache=True, nogil=True, error_model="numpy")
def _wrap(a):  # noqa: ANN001, ANN202
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, nogil=True, error_model="numpy")
def _cos_factor(g0, g1):  # noqa: ANN001, ANN202
    """The largest cos(gamma) between flight-path angles ``g0`` and ``g1``."""
    if g0 * g1 <= 0.0:
        return 1.0
    return math.cos(min(abs(g0), abs(g1)))


@njit(cache=True, nogil=True, error_model="numpy")
def fly_step(v, cmd, kappa, limits, dt):  # noqa: ANN001, ANN201
    """One step of one fixed wing at velocity ``v = (vx, vy, vz)`` with turn state ``kappa =
    (kh, kv)``, commanded ``cmd = (cx, cy, cz)``, within ``limits = (vmin, vmax, amax, radius,
    climb, roll)`` (``roll`` its roll rate, rad/s; inf: none). Returns the new velocity and turn
    state. A command of (near) zero keeps the direction; a vertical one keeps the heading and
    asks for the full climb or dive."""
    vx, vy, vz = v
    cx, cy, cz = cmd
    kh, kv = kappa
    vmin, vmax, amax, radius, climb, roll = limits
    speed0 = math.sqrt(vx * vx + vy * vy + vz * vz)
    psi0 = math.atan2(vy, vx)
    gamma0 = _clip(math.atan2(vz, math.hypot(vx, vy)), -climb, climb)
    s_cmd = math.sqrt(cx * cx + cy * cy + cz * cz)
    hxy = math.hypot(cx, cy)
    if s_cmd < 1e-12:
        psi_cmd, gamma_cmd = psi0, gamma0
    elif hxy < 1e-9 * s_cmd:
        psi_cmd, gamma_cmd = psi0, (climb if cz > 0.0 else -climb)
    else:
        psi_cmd, gamma_cmd = math.atan2(cy, cx), math.atan2(cz, hxy)
    gamma_cmd = _clip(gamma_cmd, -climb, climb)
    speed_cmd = _clip(s_cmd, vmin, vmax)
    step = amax * dt
    speed1 = _clip(speed0 + _clip(speed_cmd - speed0, -step, step), vmin, vmax)
    ds = min(speed0, speed1) * dt
    # A hair inside the radius, so rounding never crosses it.
    budget = ds / radius * (1.0 - 1e-9)
    dpsi = _wrap(psi_cmd - psi0)
    c = _cos_factor(gamma0, gamma_cmd)
    wh, wv = c * dpsi, gamma_cmd - gamma0
    n = math.hypot(wh, wv)
    if n > budget:
        f = budget / n
        wh, wv = wh * f, wv * f
    if roll < np.inf and ds > 0.0:
        # The horizontal turn as a bank (a level turn of curvature k banks atan(k V^2 / g)):
        # this step's differs from the last step's by at most roll * dt; the climb or dive
        # takes what is left of the turn budget.
        fast = max(speed0, speed1)
        q = fast * fast / GRAVITY
        b0 = math.atan(kh * q)
        db = _clip(math.atan(wh / ds * q) - b0, -roll * dt, roll * dt)
        wh = _clip(math.tan(b0 + db) / q * ds, -budget, budget)
        room = math.sqrt(max(budget * budget - wh * wh, 0.0))
        wv = _clip(wv, -room, room)
    gamma1 = _clip(gamma0 + wv, -climb, climb)
    c1 = _cos_factor(gamma0, gamma1)
    psi1 = psi0 + wh / c1
    k_h = wh / ds if ds > 0.0 else 0.0
    k_v = (gamma1 - gamma0) / ds if ds > 0.0 else 0.0
    cg = math.cos(gamma1)
    return speed1 * cg * math.cos(psi1), speed1 * cg * math.sin(psi1), speed1 * math.sin(gamma1), k_h, k_v


@njit(cache=True, nogil=True, error_model="numpy")
def fly_steps(v0, v_cmd, kappa, vmin, vmax, amax, radius, climb, roll, dt):  # noqa: ANN001, ANN201
    """:func:`fly_step` of every row: velocities (n, 3) and turn states (n, 2) after one step."""
    n = v0.shape[0]
    v1 = np.empty((n, 3))
    k1 = np.empty((n, 2))
    for i in range(n):
        v, cmd = (v0[i, 0], v0[i, 1], v0[i, 2]), (v_cmd[i, 0], v_cmd[i, 1], v_cmd[i, 2])
        limits = (vmin[i], vmax[i], amax[i], radius[i], climb[i], roll[i])
        a, b, c, d, e = fly_step(v, cmd, (kappa[i, 0], kappa[i, 1]), limits, dt)
        v1[i, 0], v1[i, 1], v1[i, 2], k1[i, 0], k1[i, 1] = a, b, c, d, e
    return v1, k1


@njit(cache=True, nogil=True, error_model="numpy")
def turn_states(v0, v1, climb, dt):  # noqa: ANN001, ANN201
    """The turn states (n, 2) of steps from velocities ``v0`` to ``v1`` (n, 3): what
    :func:`fly_step` returns for the step it flew (up to rounding), for any step."""
    n = v0.shape[0]
    out = np.zeros((n, 2))
    for i in range(n):
        s0 = math.sqrt(v0[i, 0] ** 2 + v0[i, 1] ** 2 + v0[i, 2] ** 2)
        s1 = math.sqrt(v1[i, 0] ** 2 + v1[i, 1] ** 2 + v1[i, 2] ** 2)
        ds = min(s0, s1) * dt
        if ds <= 0.0:
            continue
        g0 = _clip(math.atan2(v0[i, 2], math.hypot(v0[i, 0], v0[i, 1])), -climb[i], climb[i])
        g1 = math.atan2(v1[i, 2], math.hypot(v1[i, 0], v1[i, 1]))
        dpsi = _wrap(math.atan2(v1[i, 1], v1[i, 0]) - math.atan2(v0[i, 1], v0[i, 0]))
        out[i, 0] = _cos_factor(g0, g1) * dpsi / ds
        out[i, 1] = (g1 - g0) / ds
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def manoeuvre_step(state, speed, top, turn, amax, radius, climb, roll, dt):  # noqa: ANN001, ANN201
    """One step of a sustained manoeuvre (:func:`rollout`) from ``state = (x, y, z, vx, vy, vz,
    kh, kv)`` at ``speed``: the next state. The flight-path angle aimed at is level (``top``
    nan) or flies to the height ``top``: ``(top - z) / radius``, within the climb limit (a
    capture that never overshoots: the angle it asks for changes by less than the turn
    budget a step). The change towards it comes first in the step's turn budget ``V dt /
    R_min`` and the turn ``turn`` (-1/0/1: hard right, hold, hard left) takes the rest, as a
    pilot pulls out of a dive before tightening a turn (with a finite roll rate the bank eases
    off towards that turn at the roll rate, and the pull-out takes the room it leaves). The law
    reads the state alone, so a manoeuvre flown from a later state of its own rollout goes on
    along the same rollout."""
    x, y, z, vx, vy, vz, kh, kv = state
    gamma = _clip(math.atan2(vz, math.hypot(vx, vy)), -climb, climb)
    aim = 0.0 if math.isnan(top) else _clip((top - z) / radius, -climb, climb)
    budget = speed * dt / radius * (1.0 - 1e-9)
    dg = _clip(aim - gamma, -budget, budget)
    gc = gamma + dg
    a = math.atan2(vy, vx) + turn * math.sqrt(max(budget * budget - dg * dg, 0.0)) / _cos_factor(gamma, gc)
    cg = math.cos(gc)
    vx, vy, vz, kh, kv = fly_step(
        (vx, vy, vz), (speed * cg * math.cos(a), speed * cg * math.sin(a), speed * math.sin(gc)), (kh, kv),
        (speed, speed, amax, radius, climb, roll), dt,
    )  # fmt: skip
    return x + vx * dt, y + vy * dt, z + vz * dt, vx, vy, vz, kh, kv


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def manoeuvre_start(pos, vel, kappa):  # noqa: ANN001, ANN201
    """The state and speed of a sustained manoeuvre from ``pos``/``vel``/``kappa``
    (:func:`manoeuvre_step`)."""
    speed = math.sqrt(vel[0] ** 2 + vel[1] ** 2 + vel[2] ** 2)
    return (pos[0], pos[1], pos[2], vel[0], vel[1], vel[2], kappa[0], kappa[1]), speed


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def manoeuvre_settling(state, speed, top, radius, climb, dt):  # noqa: ANN001, ANN201
    """Whether a sustained manoeuvre at ``state`` is still on its way to its steady turn: its
    flight-path angle more than a step's turn budget from the one it aims at, or (climbing or
    diving to ``top``) more than a step's travel from that height. A rollout flies one step
    more for each such step (:func:`rollout`): the steady turn it reaches is then checked for a
    whole turn, as a level turn is from its start, and the same manoeuvre flown from a later
    state of its rollout checks no point the rollout did not."""
    z, vx, vy, vz = state[2], state[3], state[4], state[5]
    gamma = _clip(math.atan2(vz, math.hypot(vx, vy)), -climb, climb)
    budget = speed * dt / radius
    if math.isnan(top):
        return abs(gamma) > budget
    aim = _clip((top - z) / radius, -climb, climb)
    return abs(aim - gamma) > budget or abs(top - z) > speed * dt


@njit(cache=True, nogil=True, error_model="numpy")
def rollout(out, pos, vel, kappa, turn, top, amax, radius, climb, roll, dt):  # noqa: ANN001, ANN201
    """Positions ``out`` (2 H, 3), written, of one fixed wing at ``pos``/``vel`` (3,) with turn
    state ``kappa`` (2,) flying one sustained manoeuvre (``turn`` -1/0/1: hard right, hold, hard
    left; ``top``: level (nan) or climbing or diving to that height and levelling off there) at
    constant speed: each step's command levels out or climbs first and turns by what its turn
    budget leaves (:func:`manoeuvre_step`, which ``swarmplan.sim._guard_kernel.first_safe``
    flies as well). It flies the horizon H and one step more for each step it was still
    settling (:func:`manoeuvre_settling`), at most H more; the rows after the last step repeat
    its position. Returns the number of steps flown."""
    base = out.shape[0] // 2
    state, speed = manoeuvre_start(pos, vel, kappa)
    k, extra = 0, 0
    while k < base + extra:
        if extra < base and manoeuvre_settling(state, speed, top, radius, climb, dt):
            extra += 1
        state = manoeuvre_step(state, speed, top, turn, amax, radius, climb, roll, dt)
        out[k, 0], out[k, 1], out[k, 2] = state[0], state[1], state[2]
        k += 1
    for j in range(k, out.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = out[k - 1, 0], out[k - 1, 1], out[k - 1, 2]
    return k


@njit(cache=True, nogil=True, error_model="numpy")
def rollouts(pos, vel, kappa, turn, top, amax, radius, climb, roll, steps, dt):  # noqa: ANN001, ANN201
    """Positions (n, C, 2 steps, 3) of fixed wings at ``pos``/``vel`` (n, 3) with turn states
    ``kappa`` (n, 2) flying each of its sustained manoeuvres c (``turn[i, c]``, ``top[i, c]``:
    :func:`rollout` over a horizon of ``steps``) and the steps each flew (n, C)."""
    n, nc = pos.shape[0], turn.shape[1]
    out = np.empty((n, nc, 2 * steps, 3))
    used = np.empty((n, nc), dtype=np.int64)
    for i in range(n):
        for c in range(nc):
            flight = (turn[i, c], top[i, c], amax[i], radius[i], climb[i], roll[i])
            used[i, c] = rollout(out[i, c], pos[i], vel[i], kappa[i], *flight, dt)
    return out, used


@njit(cache=True, nogil=True, error_model="numpy")
def first_velocities(pos, vel, kappa, turn, top, amax, radius, climb, roll, dt):  # noqa: ANN001, ANN201
    """Velocities (n, C, 3) after the first step of each sustained manoeuvre c of the fixed
    wings of :func:`rollouts` (the step the guard commands when it starts that manoeuvre)."""
    n, nc = pos.shape[0], turn.shape[1]
    out = np.empty((n, nc, 3))
    for i in range(n):
        for c in range(nc):
            state, speed = manoeuvre_start(pos[i], vel[i], kappa[i])
            state = manoeuvre_step(
                state, speed, top[i, c], turn[i, c], amax[i], radius[i], climb[i], roll[i], dt
            )
            out[i, c, 0], out[i, c, 1], out[i, c, 2] = state[3], state[4], state[5]
    return out

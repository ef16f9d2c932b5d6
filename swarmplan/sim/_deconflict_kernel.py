"""Compiled passes of each agent's braking room (``swarmplan.sim.deconflict.braking_room``), for
swarms: the believed pairs a command closes in on, and the cuts along them in (flyer, agent)
order. Each function is its numpy counterpart's arithmetic in the same order
(tests/test_deconflict_kernel.py holds them to the same answers)."""

from __future__ import annotations

import math

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True)
def closing_pairs(pairs, radius, believed, v_cmd, agents, dt):  # noqa: ANN001, ANN201
    """``deconflict.closing_pairs_numpy``: of the believed ``pairs`` (flyer row k, agent j, table
    row, distance), those within ``radius`` that multirotor flyers' commands ``v_cmd`` close in
    on, with a state of some age: their flyer rows, unit vectors towards the other, the room
    along them and the flyer's braking (``believed`` = (flyer agents, table ages, positions,
    velocities, flyer positions); ``agents`` = (fixed wing, max_accel, checked radius))."""
    ks, js, rows, dist = pairs
    own, age_row, pos, vel, at = believed
    fixed_wing, max_accel, checked = agents
    m = ks.shape[0]
    out_k = np.empty(m, dtype=np.int64)
    out_n = np.empty((m, 3))
    out_room = np.empty(m)
    out_brake = np.empty(m)
    c = 0
    for r in range(m):
        d = dist[r]
        if not d < radius:
            continue
        k, j, row = ks[r], js[r], rows[r]
        i = own[k]
        age = age_row[row]
        if fixed_wing[i] or not d > 0.0 or not age > 0.0 or not math.isfinite(age):
            continue
        nx = (pos[row, 0] - at[k, 0]) / d
        ny = (pos[row, 1] - at[k, 1]) / d
        nz = (pos[row, 2] - at[k, 2]) / d
        if not (v_cmd[k, 0] * nx + v_cmd[k, 1] * ny) + v_cmd[k, 2] * nz > 0.0:
            continue
        aj = max_accel[j]
        gap = dist[r] - checked[i] - checked[j] - 0.5 * aj * age * age
        away = (vel[row, 0] * nx + vel[row, 1] * ny) + vel[row, 2] * nz - aj * age
        towards = max(-away, 0.0)
        bj = 0.8 * aj
        if away > 0.0:
            own_room = away * away / (2.0 * aj)
        else:
            own_room = -(towards * dt + towards * towards / (2.0 * bj))
        room = gap + own_room
        out_k[c] = k
        out_n[c, 0], out_n[c, 1], out_n[c, 2] = nx, ny, nz
        out_room[c] = room if room > 0.0 else 0.0
        out_brake[c] = 0.8 * max_accel[i]
        c += 1
    return out_k[:c].copy(), out_n[:c].copy(), out_room[:c].copy(), out_brake[:c].copy()


@njit(cache=True, nogil=True)
def cut(out, k, n, allowed):  # noqa: ANN001, ANN201
    """``deconflict.cut_numpy``: in place, each command ``out[k[r]]`` that closed in along
    ``n[r]`` faster than ``allowed[r]`` before any cut is cut to it, in order."""
    m = k.shape[0]
    over = np.empty(m, dtype=np.bool_)
    for r in range(m):
        f = k[r]
        over[r] = (out[f, 0] * n[r, 0] + out[f, 1] * n[r, 1]) + out[f, 2] * n[r, 2] > allowed[r]
    for r in range(m):
        if not over[r]:
            continue
        f = k[r]
        excess = (out[f, 0] * n[r, 0] + out[f, 1] * n[r, 1]) + out[f, 2] * n[r, 2] - allowed[r]
        if excess > 0.0:
            for e in range(3):
                out[f, e] = out[f, e] - excess * n[r, e]

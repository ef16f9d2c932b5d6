"""Compiled passes of each agent's braking room (``swarmplan.sim.deconflict.braking_room``) and
deconfliction on its beliefs (``belief_conflicts``), for swarms: the believed pairs a command
closes in on, the cuts along them in (flyer, agent) order, and the believed motions a step
meets. Each function is its numpy counterpart's arithmetic in the same order
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
    # The pairs kept, found without a branch (written at c whatever they are, kept by moving c
    # on: at tens of thousands of pairs, half of them closing, a branch is mispredicted often),
    # then worked out.
    kept = np.empty(m + 1, dtype=np.int64)
    c = 0
    for r in range(m):
        d = dist[r]
        k, row = ks[r], rows[r]
        age = age_row[row]
        e = d if d > 0.0 else 1.0  # (a pair at no distance is not kept)
        nx = (pos[row, 0] - at[k, 0]) / e
        ny = (pos[row, 1] - at[k, 1]) / e
        nz = (pos[row, 2] - at[k, 2]) / e
        closing = (v_cmd[k, 0] * nx + v_cmd[k, 1] * ny) + v_cmd[k, 2] * nz > 0.0
        kept[c] = r
        aged = age > 0.0 and math.isfinite(age)  # a state of now: the pair agrees within the step
        c += d < radius and d > 0.0 and aged and not fixed_wing[own[k]] and closing
    out_k = np.empty(c, dtype=np.int64)
    out_n = np.empty((c, 3))
    out_room = np.empty(c)
    out_brake = np.empty(c)
    for q in range(c):
        r = kept[q]
        d = dist[r]
        k, j, row = ks[r], js[r], rows[r]
        i = own[k]
        age = age_row[row]
        nx = (pos[row, 0] - at[k, 0]) / d
        ny = (pos[row, 1] - at[k, 1]) / d
        nz = (pos[row, 2] - at[k, 2]) / d
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
        out_k[q] = k
        out_n[q, 0], out_n[q, 1], out_n[q, 2] = nx, ny, nz
        out_room[q] = room if room > 0.0 else 0.0
        out_brake[q] = 0.8 * max_accel[i]
    return out_k, out_n, out_room, out_brake


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


@njit(cache=True, nogil=True)
def meetings(pairs, radius, believed, steps, agents, agreed, dt):  # noqa: ANN001, ANN201
    """``deconflict.meetings_numpy`` in one pass over the pairs: those within ``radius`` whose
    flyer decides on a belief not too old to act on and not agreed within the step, with the
    distance needed, the distance now less a rounding, the other's believed motion over the
    step, the closest approach of the flyer's step to it and whether the step meets it."""
    k, j, rows, now = pairs
    own, age, pos, vel = believed
    max_accel, cap, checked, deciding = agents
    pos0, pos1 = steps
    m = k.shape[0]
    agreeing = agreed.shape[0] > 0
    # The pairs kept, found without a branch (written at c whatever they are, kept by moving c
    # on), then worked out into arrays of their number.
    kept = np.empty(m + 1, dtype=np.int64)
    c = 0
    for p in range(m):
        kp, jp, r = k[p], j[p], rows[p]
        i = own[kp]
        a = (age[r] if math.isfinite(age[r]) else 0.0) + dt
        margin = 0.5 * max_accel[jp] * a * a  # deconflict.belief_margin
        ok = now[p] < radius and deciding[i] and margin <= cap[i] + cap[jp]
        kept[c] = p
        c += ok and not (agreeing and agreed[i, jp])
    ko = np.empty(c, dtype=np.int64)
    jo = np.empty(c, dtype=np.int64)
    need = np.empty(c)
    closing = np.empty(c)
    b0 = np.empty((c, 3))
    b1 = np.empty((c, 3))
    d = np.empty(c)
    meet = np.empty(c, dtype=np.bool_)
    for q in range(c):
        p = kept[q]
        kp, jp, r = k[p], j[p], rows[p]
        i = own[kp]
        a = (age[r] if math.isfinite(age[r]) else 0.0) + dt
        margin = 0.5 * max_accel[jp] * a * a
        ko[q], jo[q] = kp, jp
        need[q] = checked[i] + checked[jp] + margin
        # collision.segment_segment_min_distance of the flyer's step and the believed motion
        for e in range(3):
            b0[q, e] = pos[r, e]
            b1[q, e] = pos[r, e] + vel[r, e] * dt
        wx, wy, wz = pos0[i, 0] - b0[q, 0], pos0[i, 1] - b0[q, 1], pos0[i, 2] - b0[q, 2]
        ux = (pos1[i, 0] - pos0[i, 0]) - (b1[q, 0] - b0[q, 0])
        uy = (pos1[i, 1] - pos0[i, 1]) - (b1[q, 1] - b0[q, 1])
        uz = (pos1[i, 2] - pos0[i, 2]) - (b1[q, 2] - b0[q, 2])
        aa = ux * ux + uy * uy + uz * uz
        s = 0.0
        if aa > 1e-18:
            s = min(max(-(wx * ux + wy * uy + wz * uz) / max(aa, 1e-18), 0.0), 1.0)
        x, y, z = wx + s * ux, wy + s * uy, wz + s * uz
        d[q] = math.sqrt(x * x + y * y + z * z)
        closing[q] = now[p] * (1.0 - 1e-9)
        meet[q] = d[q] < need[q] and d[q] < closing[q]
    return ko, jo, need, closing, b0, b1, d, meet

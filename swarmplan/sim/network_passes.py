"""The numpy passes of the network of a world with ``comms`` (``swarmplan.sim.network``) over the
(receiver, sender) matrix of what each receiver holds: what worlds below ``COMPILED_FROM`` agents
run, and the twins that ``swarmplan.sim._network_kernel``'s compiled passes over the sparse book
of swarms are held to (tests/test_network_kernel.py): the copies' draws, their fates and
delivery, the rows each flyer holds and its pairs within a radius, and the oldest state each
flyer acts on."""

from __future__ import annotations

import numpy as np

_EPS = 1e-9


def belief_doubt(max_accel: np.ndarray, age: np.ndarray) -> np.ndarray:
    """How far an agent of ``max_accel`` may be from where it was believed to be ``age`` seconds
    after its state was true (moved on by the velocity sent): ``max_accel age^2 / 2``; 0 for a
    state of now (a flyer's own, a sensed one), and for an unknown age."""
    a = np.where(np.isfinite(age), age, 0.0)
    return 0.5 * max_accel * a * a


def held_pairs(
    view: np.ndarray, pos: np.ndarray, at: np.ndarray, own: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(flyer row k, agent j, table row, distance) for every agent j that flyer k (at ``at[k]``,
    agent ``own[k]``) holds a row of (``view[k, j]`` >= 0) within ``radius`` of it, itself left
    out, in (k, j) order."""
    k, j = np.nonzero(view >= 0)
    rows = view[k, j]
    keep = j != own[k]
    k, j, rows = k[keep], j[keep], rows[keep]
    dp = pos[rows] - at[k]
    d = np.sqrt((dp[:, 0] * dp[:, 0] + dp[:, 1] * dp[:, 1]) + dp[:, 2] * dp[:, 2])
    inside = d < radius
    return k[inside], j[inside], rows[inside], d[inside]


_SPREAD_ROW = np.uint64(0x9E3779B97F4A7C15)
_SPREAD_COPY = np.uint64(0xD1B54A32D192ED03)
_MIX1, _MIX2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)


def draws(key: np.uint64, rows: np.ndarray, receivers: np.ndarray, salt: int) -> np.ndarray:
    """The uniform draws in [0, 1) of the copies of table rows ``rows`` to ``receivers``
    (broadcast together; ``salt`` 0: their losses, 1: their jitters): a counter-based stream
    (SplitMix64's mix of the run's ``key`` and the copy), so each copy's fate is its own,
    whenever and however often it is asked."""
    with np.errstate(over="ignore"):
        z = np.asarray(rows, dtype=np.uint64) * _SPREAD_ROW
        z = key + z + (np.asarray(receivers, dtype=np.uint64) * np.uint64(2) + np.uint64(salt)) * _SPREAD_COPY
        z = (z ^ (z >> np.uint64(30))) * _MIX1
        z = (z ^ (z >> np.uint64(27))) * _MIX2
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-53


def fates_numpy(
    senders: np.ndarray, rows: np.ndarray, key: np.uint64, fate: tuple[float, float, float, float],
    at: np.ndarray, heard_by: np.ndarray,
) -> tuple[int, int]:  # fmt: skip
    """Which copies of one broadcast (``senders``, their table ``rows``) will be heard, into
    ``heard_by`` (N, k): not the sender's own, within range of it (``at``: the agents'
    positions when it was sent; empty: no range) and not lost (a draw below ``fate``'s loss;
    ``fate`` = (loss, the delay's jitter, the time the broadcast falls due, range)). Returns
    the copies lost and out of range."""
    loss, reach = fate[0], fate[3]
    n = heard_by.shape[0]
    receivers = np.arange(n)[:, None]
    listen = receivers != senders[None, :]
    far = np.zeros_like(listen)
    if at.shape[0]:
        d = at[:, None, :] - at[senders][None, :, :]
        dist = np.sqrt((d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]) + d[..., 2] * d[..., 2])
        far = listen & (dist > reach)
    near = listen & ~far
    lost = np.zeros_like(near)
    if loss > 0.0:
        lost = near & (draws(key, rows[None, :], receivers, 0) < loss)
    heard_by[:] = near & ~lost
    return int(lost.sum()), int(far.sum())


def deliver_numpy(
    heard: np.ndarray, senders: np.ndarray, rows: np.ndarray, key: np.uint64,
    fate: tuple[float, float, float, float], heard_by: np.ndarray, t: float,
) -> None:  # fmt: skip
    """The copies of one broadcast (``senders``, their table ``rows``) heard (``heard_by``,
    :func:`fates_numpy`) that have arrived by ``t`` replace older rows in ``heard`` (receiver,
    sender; a sender's rows are numbered in the order it sent them, so the newer state has the
    larger row): a copy arrives when the broadcast falls due plus the delay's jitter times a
    uniform draw in [-1, 1) (``fate`` = (loss, jitter, due time, range))."""
    jitter, due = fate[1], fate[2]
    arrives = np.full(heard_by.shape, due)
    if jitter > 0.0:
        receivers = np.arange(heard.shape[0])[:, None]
        arrives = due + jitter * (2.0 * draws(key, rows[None, :], receivers, 1) - 1.0)
    cur = heard[:, senders]
    take = heard_by & (arrives <= t + _EPS) & (cur < rows[None, :])
    heard[:, senders] = np.where(take, rows[None, :], cur)


def oldest_ages(
    k: np.ndarray, rows: np.ndarray, d: np.ndarray, age: np.ndarray, reach: float, n: int
) -> np.ndarray:
    """Per flyer row of ``n``: the largest ``age`` of the rows of the pairs (flyer row ``k``,
    table row ``rows``, distance ``d``; in flyer order) closer than ``reach``; nan for a flyer
    with none."""
    out = np.full(n, -np.inf)
    if len(k):  # the pairs run flyer by flyer: one maximum per flyer's run
        first = np.flatnonzero(np.concatenate([[True], k[1:] != k[:-1]]))
        out[k[first]] = np.maximum.reduceat(np.where(d < reach, age[rows], -np.inf), first)
    return np.where(np.isfinite(out), out, np.nan)


def compact(heard: np.ndarray, idx: np.ndarray, mark: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The table rows that flyers ``idx`` hold in ``heard`` (receiver, sender; 0: none), in the
    order first met reading ``heard[idx]`` row by row, and each flyer's view of them (n, N: the
    position among those rows, -1: none). ``mark`` has one entry per table row (the compiled
    pass's scratch; read here for its size)."""
    rows = heard[idx]
    flat = rows.ravel()
    held = flat[flat > 0]
    distinct, first = np.unique(held, return_index=True)
    live = distinct[np.argsort(first, kind="stable")]
    remap = np.full(len(mark), -1, dtype=np.int64)
    remap[live] = np.arange(len(live))
    return live, remap[rows]


def compact_near_numpy(
    heard: np.ndarray, idx: np.ndarray, mark: np.ndarray, table: tuple[np.ndarray, np.ndarray, np.ndarray],
    t: float, at: np.ndarray, radius: float, stale: tuple[np.ndarray, np.ndarray], buffers: tuple = (),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:  # fmt: skip
    """:func:`compact`, the ages at ``t`` of the rows held and their positions moved on by them
    at the velocity sent (``table`` = (time, position, velocity) per table row), and
    :func:`held_pairs` of flyers ``idx`` (at ``at``) within ``radius`` of those positions. A row
    too old to act on is left out of a flyer's view (-1): its agent may be farther from it
    (:func:`belief_doubt`) than both agents' stopping reach (``stale`` = (max_accel, stopping
    reach) per agent), as far as knowing nothing of it. ``buffers``: the compiled pass's (its
    output's room), unused here."""
    t_row, pos_row, vel_row = table
    max_accel, reach = stale
    live, view = compact(heard, idx, mark)
    age = t - t_row[live]
    moved = pos_row[live] + vel_row[live] * age[:, None]
    k, j = np.nonzero(view >= 0)
    rows = view[k, j]
    old = belief_doubt(max_accel[j], age[rows]) > reach[idx[k]] + reach[j]
    view[k[old], j[old]] = -1
    return live, view, age, moved, held_pairs(view, moved, at, idx, radius)


def belief_table_numpy(
    live: np.ndarray, age: np.ndarray, moved: np.ndarray, table: tuple[np.ndarray, ...], truth: np.ndarray,
    now: tuple[np.ndarray, ...],
) -> tuple[np.ndarray, ...]:  # fmt: skip
    """The table of believed states (``network.Beliefs``, one row each): the rows held ``live``
    (``age`` and position ``moved`` on by it, :func:`compact_near_numpy`; ``table`` = (velocity,
    acceleration, parked, distance to the goal, agent, yields) per table row), then the true
    states of agents ``truth`` (``now`` = (position, velocity, parked, distance to the goal,
    yields) per agent, age 0). Returns (position, velocity, parked, distance to the goal, age,
    agent, position and velocity moved on with the acceleration sent too, yields)."""
    vel_row, acc_row, parked_row, to_go_row, agent_row, yields_row = table
    pos, vel, parked, to_go, yields = now
    vel_held, acc_held = vel_row[live], acc_row[live]
    return (
        np.concatenate([moved, pos[truth]]),
        np.concatenate([vel_held, vel[truth]]),
        np.concatenate([parked_row[live], parked[truth]]),
        np.concatenate([to_go_row[live], to_go[truth]]),
        np.concatenate([age, np.zeros(len(truth))]),
        np.concatenate([agent_row[live], truth]),
        np.concatenate([moved + 0.5 * acc_held * (age * age)[:, None], pos[truth]]),
        np.concatenate([vel_held + acc_held * age[:, None], vel[truth]]),
        np.concatenate([yields_row[live], yields[truth]]),
    )

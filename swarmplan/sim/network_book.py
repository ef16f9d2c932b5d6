"""What every receiver holds of every sender in a swarm world with ``comms`` (from
``COMPILED_FROM`` agents; ``swarmplan.sim.network`` keeps the (receiver, sender) matrix of smaller
worlds), kept sparse: each sender's base row (its newest state delivered to every receiver that
took it) and the few receivers holding another row (a copy lost or out of range, or one arrived
ahead of its broadcast), so a delivery writes the copies missed, not one entry per receiver
(``_network_kernel.deliver``), and a flyer's view is the base rows changed at its own entries
(``_network_kernel.compact_near``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from swarmplan.runtime.compiled import kernel_module


def holdings(heard: np.ndarray, base: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The sparse lists of ``heard`` (receiver, sender: the table row held, 0: none) about each
    sender's ``base`` row: (base, start, holders, values), sender ``s``'s receivers holding
    another row ``holders[start[s]:start[s + 1]]`` (ascending) and their rows."""
    s, r = np.nonzero(heard.T != np.asarray(base)[:, None])
    start = np.concatenate([[0], np.cumsum(np.bincount(s, minlength=len(base)))]).astype(np.int64)
    return np.asarray(base, dtype=np.int64).copy(), start, r.astype(np.int64), heard[r, s].astype(np.int64)


def _kernel() -> Any:
    return kernel_module("swarmplan.sim._network_kernel")


class Book:
    """The rows every receiver holds (``heard`` (receiver, sender) at the start, about each
    sender's ``base`` row); ``lists`` the book as ``_network_kernel`` reads it."""

    def __init__(self, heard: np.ndarray, base: np.ndarray):
        self.lists = holdings(heard, base)
        self.n = len(base)
        empty = np.empty(0, dtype=np.int64)
        self._spare = (np.empty(self.n + 1, dtype=np.int64), empty, empty)

    def deliver(self, senders: np.ndarray, rows: np.ndarray, key: np.uint64, fate: tuple, misses: tuple,
                t: float, partial: bool) -> None:  # fmt: skip
        """The copies of one broadcast (``senders``, their table ``rows``; ``misses`` the receivers
        that miss each copy, ``_network_kernel.misses``; ``fate`` = (loss, jitter, due, range))
        that have arrived by ``t`` (``partial``: some are still on their way). Its new lists are
        written to the spare buffers (grown when short), which then hold the book: no buffer is
        allocated again."""
        ptr, miss = misses
        room = int(self.lists[1][-1]) + (self.n * len(senders) if partial else int(ptr[-1]))
        start, holders, values = self._spare
        if len(holders) < room:
            size = max(room, 2 * len(holders))
            holders, values = np.empty(size, dtype=np.int64), np.empty(size, dtype=np.int64)
        spare = (start, holders, values)
        if _kernel().deliver(self.lists, spare, senders, rows, key, fate, ptr, miss, t):
            self._spare, self.lists = self.lists[1:], (self.lists[0], *spare)
        else:
            self._spare = spare

    def matrix(self) -> np.ndarray:
        """(receiver, sender): the row held (0: none)."""
        base, start, holders, values = self.lists
        heard = np.repeat(base[:, None], self.n, axis=1)
        heard[np.repeat(np.arange(self.n), np.diff(start)), holders[: start[-1]]] = values[: start[-1]]
        return heard.T

    def held_by(self, i: int) -> np.ndarray:
        """(sender,): the row receiver ``i`` holds of each (0: none)."""
        base, start, holders, values = self.lists
        e = np.flatnonzero(holders[: start[-1]] == i)
        heard = base.copy()
        heard[np.searchsorted(start, e, side="right") - 1] = values[e]
        return heard

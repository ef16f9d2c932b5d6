"""Many floats written as JSON writes them (Python's ``repr``), in a few numpy operations.

The state channels hold positions and velocities rounded to 6 decimals; writing ~1500 of
them per step through ``repr`` (``%r``) was the largest cost of ``/agents/state`` at 256
agents. A float ``x`` that equals ``k / 10**6`` for an integer ``k`` (what ``round(x, 6)``
gives) with ``1e-4 <= |x| < 2**33`` (or ``x == 0``) has the shortest round-trip form
``[-]int.frac`` with the fraction's trailing zeros removed (at least one digit): no other
decimal with as few digits rounds to it, since the gap between two doubles there (at most
2**-20) is below 1e-6. Those digits come from digit tables for all values at once; any other
value (more decimals, ``|x| < 1e-4``, which ``repr`` writes with an exponent, very large
ones) goes through ``repr`` itself. :class:`Interleaved` places the numbers between fixed
text (tests/test_json_floats.py checks the bytes against ``repr`` and ``json``); with
``compiled`` set, one compiled pass writes the same bytes (:mod:`~swarmplan.io._record_kernels`).
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

from swarmplan.runtime.compiled import kernel_module

# A row per value: [sign] up to 10 integer digits (columns 1-10), "." (11), 6 fraction digits
# (12-17); repr's text from column 0 for the other values (at most 24 characters).
_WIDTH = 24
# The three digits of 0-999 as the first three bytes of a little-endian uint32 (written as one
# word; the fourth byte is overwritten by what follows).
_DIGITS3 = np.array([int.from_bytes(f"{v:03d}".encode() + b"0", "little") for v in range(1000)], "<u4")
_KEPT3 = np.array([len(f"{v:03d}".rstrip("0")) for v in range(1000)], dtype=np.intp)
_POW10 = 10 ** np.arange(10, dtype=np.int64)
_LIMIT = 2.0**33


def float_chars(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``repr`` of every value of ``x`` (1-D, finite) as ASCII: rows of characters (n, 24)
    uint8, and where each value's text starts in its row and how long it is."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    if n == 0:
        return np.zeros((0, _WIDTH), dtype=np.uint8), np.zeros(0, np.intp), np.zeros(0, np.intp)
    ax = np.abs(x)
    k = np.rint(ax * 1e6)
    fast = (k / 1e6 == ax) & (ax < _LIMIT) & ((ax >= 1e-4) | (ax == 0.0))
    k = np.where(fast, k, 0.0).astype(np.int64)
    whole, frac = np.divmod(k, 1_000_000)
    top, rest = np.divmod(whole, 1_000_000_000)
    mid, rest = np.divmod(rest, 1_000_000)
    high, low = np.divmod(rest, 1000)
    f_high, f_low = np.divmod(frac, 1000)
    chars = np.empty((n, _WIDTH), dtype=np.uint8)
    chars[:, 0] = ord("-")
    chars[:, 1] = top + ord("0")
    for at, group in ((2, mid), (5, high), (8, low), (12, f_high), (15, f_low)):  # left to right
        np.ndarray((n,), "<u4", chars, at, (_WIDTH,))[:] = _DIGITS3.take(group)
    chars[:, 11] = ord(".")
    digits = np.maximum(np.searchsorted(_POW10, whole, side="right"), 1)
    neg = np.signbit(x)
    start = 11 - digits - neg
    if neg.any():
        rows = np.flatnonzero(neg)
        chars[rows, start[rows]] = ord("-")
    decimals = np.where(f_low != 0, 3 + _KEPT3[f_low], np.maximum(_KEPT3[f_high], 1))
    length = neg + digits + 1 + decimals
    for i in np.flatnonzero(~fast).tolist():
        r = repr(float(x[i])).encode()
        chars[i, : len(r)] = np.frombuffer(r, dtype=np.uint8)
        start[i], length[i] = 0, len(r)
    return chars, start, length


def record_kernels() -> ModuleType:
    """:mod:`swarmplan.io._record_kernels`, imported (and numba with it) at first use."""
    return kernel_module("swarmplan.io._record_kernels")


class Interleaved:
    """Text ``p0 v0 p1 v1 ... v(n-1) pn``: fixed pieces ``p`` around n numbers, written each
    time as :func:`float_chars` gives them (one gather from the rows and the pieces), or with
    ``compiled`` set by one compiled pass (the same bytes; values it does not take, e.g. more
    than 6 decimals, go the numpy way)."""

    __slots__ = (
        "_n",
        "_pieces",
        "_seg_len",
        "_src",
        "_counter",
        "_piece_len",
        "_piece_start",
        "_out",
        "_list",
        "compiled",
    )

    def __init__(self, pieces: list[bytes], compiled: bool = False):
        n = self._n = len(pieces) - 1
        self._list = list(pieces)
        self._pieces = np.frombuffer(b"".join(pieces), dtype=np.uint8)
        piece_len = self._piece_len = np.fromiter(map(len, pieces), dtype=np.intp, count=n + 1)
        self._out = np.empty(len(self._pieces) + 18 * n, dtype=np.uint8)
        self.compiled = compiled
        self._piece_start = np.cumsum(piece_len) - piece_len
        self._seg_len = self._src = self._counter = None  # the numpy path's, at its first use

    def replace(self, which: list[int], pieces: list[bytes]) -> None:
        """Pieces ``which`` replaced by those of ``pieces`` (the whole new list; the others are
        the same as before): the text's layout made again from the changed lengths only."""
        if len(pieces) != self._n + 1:
            raise ValueError(f"{self._n + 1} pieces expected, got {len(pieces)}")
        for k in which:
            self._list[k] = pieces[k]
            self._piece_len[k] = len(pieces[k])
        self._pieces = np.frombuffer(b"".join(self._list), dtype=np.uint8)
        np.cumsum(self._piece_len, out=self._piece_start)
        self._piece_start -= self._piece_len
        need = len(self._pieces) + 18 * self._n
        if len(self._out) < need:
            self._out = np.empty(need + need // 4, dtype=np.uint8)  # room for longer pieces
        self._seg_len = self._src = self._counter = None  # the numpy path's, remade at its next use

    def _numpy_path(self) -> None:
        """Where each segment's text is in [rows of the numbers, pieces] (the numpy path)."""
        n, piece_len = self._n, self._piece_len
        self._seg_len = np.empty(2 * n + 1, dtype=np.intp)
        self._seg_len[0::2] = piece_len
        self._src = np.empty(2 * n + 1, dtype=np.intp)
        self._src[0::2] = n * _WIDTH + self._piece_start
        self._src[1::2] = np.arange(n) * _WIDTH
        self._counter = np.arange(len(self._pieces) + n * _WIDTH, dtype=np.intp)

    def fill_compiled(self, values: np.ndarray) -> bytes | None:
        """The text by the compiled pass; None when a value is not in its fast form (more than
        6 decimals, an exponent, not finite)."""
        values = np.ascontiguousarray(np.ravel(values), dtype=float)
        if len(values) != self._n:
            raise ValueError(f"{self._n} numbers expected, got {len(values)}")
        size = record_kernels().interleave(
            self._pieces, self._piece_start, self._piece_len, values, self._out
        )
        return self._out[:size].tobytes() if size >= 0 else None

    def fill_rows(self, first: float, a: np.ndarray, b: np.ndarray) -> bytes | None:
        """:meth:`fill_compiled` of ``first``, then per row i ``a[i]`` and ``b[i]`` (rows of 3),
        read in place by the compiled pass (no array of the values made)."""
        a = np.ascontiguousarray(a, dtype=float).reshape(-1, 3)
        b = np.ascontiguousarray(b, dtype=float).reshape(-1, 3)
        if 1 + 6 * len(a) != self._n or len(b) != len(a):
            raise ValueError(f"{self._n} numbers expected, got 1 + 3 * {len(a)} + 3 * {len(b)}")
        size = record_kernels().interleave_rows(
            self._pieces, self._piece_start, self._piece_len, first, a, b, self._out
        )
        return self._out[:size].tobytes() if size >= 0 else None

    def fill(self, values: np.ndarray) -> bytes:
        """The text with ``values`` (n numbers, any shape, row-major) in place."""
        values = np.ravel(values)
        if len(values) != self._n:
            raise ValueError(f"{self._n} numbers expected, got {len(values)}")
        if self.compiled:
            out = self.fill_compiled(values)
            if out is not None:
                return out
        chars, start, length = float_chars(values)
        if self._seg_len is None:
            self._numpy_path()
        seg_len = self._seg_len
        seg_len[1::2] = length
        src = self._src.copy()
        src[1::2] += start
        ends = np.cumsum(seg_len)
        total = int(ends[-1])
        idx = np.repeat(src - (ends - seg_len), seg_len) + self._counter[:total]
        return np.concatenate((chars.ravel(), self._pieces))[idx].tobytes()

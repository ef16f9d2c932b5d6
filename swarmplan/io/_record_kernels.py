"""Compiled (numba) pieces of the recorder's per-step messages, loaded through
:func:`swarmplan.io.json_floats.record_kernels` for swarm-sized worlds.

:func:`interleave` writes JSON text with numbers between fixed pieces, each number as
``repr`` writes it when it is a multiple of 1e-6 below 2**33 (what ``round(x, 6)`` gives:
``[-]int.frac`` without the fraction's trailing zeros, and below 1e-4 ``repr``'s exponent form,
``5e-06``, ``1.2e-05``); any other value makes it give up (-1) and the numpy path writes the
message. :func:`headings` turns horizontal
velocities into yaw quaternions with the C library's ``atan2``, ``sin`` and ``cos``, as
Python's ``math`` does (tests/test_record_kernels.py compares the bits). :func:`patch` writes
a step's timestamp and numbers into a protobuf message's bytes (``wire.Patched``).
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.runtime.compiled import njit

_LIMIT = 2.0**33
_ZERO, _DOT, _MINUS = 48, 46, 45
_EXP = np.frombuffer(b"e-0", dtype=np.uint8).copy()  # and the exponent's last digit
_PAIRS = np.frombuffer(b"".join(b"%02d" % v for v in range(100)), dtype=np.uint8).copy()  # "00".."99"
_DIGITS4 = np.frombuffer(b"".join(b"%04d" % v for v in range(10000)), dtype=np.uint8).copy()  # "0000".."9999"
_LEN4 = np.array([len(str(v)) for v in range(10000)], dtype=np.int64)  # digits of 0..9999
_KEPT4 = np.array([len((b"%04d" % v).rstrip(b"0")) for v in range(10000)], dtype=np.int64)  # without
# trailing zeros: the digits kept of a fraction's last four (and of its first two, at least one)
_KEPT2 = np.array([max(len((b"%02d" % v).rstrip(b"0")), 1) for v in range(100)], dtype=np.int64)


@njit(cache=True, nogil=True, error_model="numpy")
def _digits(out: np.ndarray, end: int, v: int) -> None:
    """The decimal digits of ``v`` (>= 0) into ``out`` just before ``end``, two at a time."""
    while v >= 100:
        q = v // 100
        r = 2 * (v - 100 * q)
        out[end - 2] = _PAIRS[r]
        out[end - 1] = _PAIRS[r + 1]
        end -= 2
        v = q
    if v >= 10:
        out[end - 2] = _PAIRS[2 * v]
        out[end - 1] = _PAIRS[2 * v + 1]
    else:
        out[end - 1] = _ZERO + v


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _number(out: np.ndarray, pos: int, x: float) -> int:
    """``x`` as ``repr`` writes it at ``pos``: the position after it, or -1 when it does not
    have the fast form. A whole part below 10**4 and the six fraction digits are written from
    the four-digit table (at most 18 bytes are written; the text that follows overwrites
    what is past the number's end)."""
    ax = abs(x)
    if not ax < _LIMIT:  # NaN too
        return -1
    k = np.rint(ax * 1e6)
    if k / 1e6 != ax:
        return -1
    ki = np.int64(k)
    out[pos] = _MINUS  # kept for a negative value (no branch on the sign)
    pos += np.int64(math.copysign(1.0, x) < 0.0)
    if 0 < ki < 100:  # below 1e-4 repr writes an exponent: d e-06, d e-05 or d.d e-05
        if ki < 10:
            out[pos] = _ZERO + ki
            pos += 1
            exp = 6
        else:
            out[pos] = _ZERO + ki // 10
            pos += 1
            if ki % 10:
                out[pos] = _DOT
                out[pos + 1] = _ZERO + ki % 10
                pos += 2
            exp = 5
        for j in range(3):
            out[pos + j] = _EXP[j]
        out[pos + 3] = _ZERO + exp
        return pos + 4
    whole = np.int64(ax)  # ax's whole part (ax is ki / 10**6 rounded): the integer division
    frac = ki - 1000000 * whole  # below, without its sign checks
    if frac < 0:
        whole -= 1
        frac += 1000000
    elif frac >= 1000000:
        whole += 1
        frac -= 1000000
    if whole < 10000:
        digits = _LEN4[whole]
        at = 4 * whole + 4 - digits
        for j in range(4):  # past the digits: overwritten by the point and the fraction
            out[pos + j] = _DIGITS4[at + j]
    else:
        digits = 5
        p = 100000
        while digits < 10 and whole >= p:
            p *= 10
            digits += 1
        _digits(out, pos + digits, whole)
    pos += digits
    out[pos] = _DOT
    high = (frac * 429497) >> 32  # frac // 10000 (exact below 10**6): its first two digits
    low = frac - 10000 * high
    out[pos + 1] = _PAIRS[2 * high]
    out[pos + 2] = _PAIRS[2 * high + 1]
    for j in range(4):
        out[pos + 3 + j] = _DIGITS4[4 * low + j]
    if low:
        return pos + 3 + _KEPT4[low]
    return pos + 1 + _KEPT2[high]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _piece(out: np.ndarray, pos: int, pieces: np.ndarray, s: int, m: int) -> int:
    # Byte by byte: slices (views) cost more than the copy itself for the pieces between the
    # numbers (tens of bytes), and a slice anywhere in the loop slows all of it (/agents/state
    # at 64 agents: 25 us a message with slices, 15 us without).
    for j in range(m):
        out[pos + j] = pieces[s + j]
    return pos + m


@njit(cache=True, nogil=True, error_model="numpy")
def interleave(
    pieces: np.ndarray, piece_start: np.ndarray, piece_len: np.ndarray, values: np.ndarray, out: np.ndarray
) -> int:
    """``p0 v0 p1 v1 ... pn`` into ``out`` (uint8, room for the pieces and 18 bytes per value):
    its length, or -1 when a value does not have the fast form."""
    n = len(values)
    pos = _piece(out, 0, pieces, piece_start[0], piece_len[0])
    for i in range(n):
        pos = _number(out, pos, values[i])
        if pos < 0:
            return -1
        pos = _piece(out, pos, pieces, piece_start[i + 1], piece_len[i + 1])
    return pos


@njit(cache=True, nogil=True, error_model="numpy")
def interleave_rows(
    pieces: np.ndarray,
    piece_start: np.ndarray,
    piece_len: np.ndarray,
    first: float,
    a: np.ndarray,
    b: np.ndarray,
    out: np.ndarray,
) -> int:
    """:func:`interleave` of the values ``first``, then per row i ``a[i, 0..2]``, ``b[i, 0..2]``
    (an ``/agents/state`` or ``/obstacles/state`` message: t, then positions and velocities)."""
    pos = _piece(out, 0, pieces, piece_start[0], piece_len[0])
    pos = _number(out, pos, first)
    if pos < 0:
        return -1
    pos = _piece(out, pos, pieces, piece_start[1], piece_len[1])
    p = 2
    for i in range(len(a)):
        for j in range(6):
            x = a[i, j] if j < 3 else b[i, j - 3]
            pos = _number(out, pos, x)
            if pos < 0:
                return -1
            pos = _piece(out, pos, pieces, piece_start[p], piece_len[p])
            p += 1
    return pos


@njit(cache=True, nogil=True, error_model="numpy")
def headings(vel: np.ndarray, slots: np.ndarray, qz: np.ndarray, qw: np.ndarray) -> None:
    """Per agent moving horizontally: the yaw along its velocity as the quaternion (0, 0, qz, qw)
    at its slot; the others keep their last heading."""
    for i in range(len(slots)):
        vx, vy = vel[i, 0], vel[i, 1]
        if vx != 0.0 or vy != 0.0:
            half = math.atan2(vy, vx) / 2.0
            qz[slots[i]] = math.sin(half)
            qw[slots[i]] = math.cos(half)


@njit(cache=True, nogil=True, error_model="numpy")
def patch(
    buf: np.ndarray, stamp_at: np.ndarray, stamp: np.ndarray, double_at: np.ndarray, values: np.ndarray
) -> None:
    """``stamp`` (bytes as uint8) at every ``stamp_at`` and each value's 8 little-endian bytes at
    its ``double_at`` in ``buf`` (what ``swarmplan.io.wire.Patched.fill`` scatters with numpy)."""
    for i in range(len(stamp_at)):
        at = stamp_at[i]
        for j in range(len(stamp)):
            buf[at + j] = stamp[j]
    raw = values.view(np.uint8)
    for i in range(len(double_at)):
        at = double_at[i]
        for j in range(8):
            buf[at + j] = raw[8 * i + j]


@njit(cache=True, nogil=True, error_model="numpy")
def patch_nonzero(
    buf: np.ndarray, stamp_at: np.ndarray, stamp: np.ndarray, double_at: np.ndarray, values: np.ndarray
) -> bool:
    """:func:`patch` with ``values`` (C-contiguous, any shape) when none is +-0.0; False and
    nothing written otherwise (proto3 would leave a +0.0 out: another layout)."""
    flat = values.reshape(-1)
    for i in range(len(flat)):
        if flat[i] == 0.0:
            return False
    patch(buf, stamp_at, stamp, double_at, flat)
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def patch_poses(
    buf: np.ndarray,
    stamp_at: np.ndarray,
    stamp: np.ndarray,
    double_at: np.ndarray,
    vel: np.ndarray,
    slots: np.ndarray,
    qz: np.ndarray,
    qw: np.ndarray,
    pos: np.ndarray,
) -> bool:
    """:func:`headings`, then :func:`patch` with x, y, z, qz, qw per agent (``pos`` and the
    headings at ``slots``) when none is +-0.0; False and nothing patched otherwise."""
    headings(vel, slots, qz, qw)
    n = len(slots)
    for i in range(n):
        k = slots[i]
        if pos[i, 0] == 0.0 or pos[i, 1] == 0.0 or pos[i, 2] == 0.0 or qz[k] == 0.0 or qw[k] == 0.0:
            return False
    values = np.empty((n, 5))
    for i in range(n):
        values[i, 0] = pos[i, 0]
        values[i, 1] = pos[i, 1]
        values[i, 2] = pos[i, 2]
        values[i, 3] = qz[slots[i]]
        values[i, 4] = qw[slots[i]]
    patch(buf, stamp_at, stamp, double_at, values.reshape(-1))
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of ``a[lo:lo + n]`` for n <= 128: eight partial sums."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r = a[lo : lo + 8].copy()
    m = n - n % 8
    for i in range(8, m, 8):
        for j in range(8):
            r[j] += a[lo + i + j]
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    for i in range(m, n):
        res += a[lo + i]
    return res


@njit(cache=True, nogil=True, error_model="numpy")
def _pairwise_sum(a: np.ndarray) -> float:
    """numpy's sum of ``a`` (its pairwise summation: blocks up to 128, halves above, each
    half's length a multiple of 8), so that a mean has numpy's bits. The halving is walked
    with a stack (a cached recursive kernel is not safe to load)."""
    if len(a) <= 128:
        return _block_sum(a, 0, len(a))
    lo = np.empty(128, dtype=np.int64)
    size = np.empty(128, dtype=np.int64)
    stage = np.empty(128, dtype=np.int64)
    sums = np.empty(128)
    lo[0], size[0], stage[0] = 0, len(a), 0
    top, done = 1, 0
    while top > 0:
        k = top - 1
        n = size[k]
        if n <= 128:
            sums[done] = _block_sum(a, lo[k], n)
            done += 1
            top -= 1
            continue
        half = n // 2
        half -= half % 8
        if stage[k] == 0:  # the first half
            stage[k] = 1
            lo[top], size[top], stage[top] = lo[k], half, 0
            top += 1
        elif stage[k] == 1:  # then the second
            stage[k] = 2
            lo[top], size[top], stage[top] = lo[k] + half, n - half, 0
            top += 1
        else:  # both: their sum
            done -= 1
            sums[done - 1] = sums[done - 1] + sums[done]
            top -= 1
    return sums[0]


@njit(cache=True, nogil=True, error_model="numpy")
def speeds(vel: np.ndarray, out: np.ndarray) -> tuple[float, float]:
    """``out[i]`` = |vel[i]| rounded to 6 decimals as ``np.round(np.sqrt((vel * vel).sum(axis=1)),
    6)`` gives it; returns their sum (numpy's) and maximum (NaN when one is NaN)."""
    top = -np.inf
    for i in range(len(out)):
        x, y, z = vel[i, 0], vel[i, 1], vel[i, 2]
        v = np.rint(math.sqrt(x * x + y * y + z * z) * 1e6) / 1e6
        out[i] = v
        if v > top or v != v:
            if top == top:
                top = v
    return _pairwise_sum(out), top


@njit(cache=True, nogil=True, error_model="numpy")
def _varint_len(n: int) -> int:
    size = 1
    while n >= 128:
        n >>= 7
        size += 1
    return size


@njit(cache=True, nogil=True, error_model="numpy")
def _put_varint(out: np.ndarray, pos: int, n: int) -> int:
    while n >= 128:
        out[pos] = (n & 0x7F) | 0x80
        n >>= 7
        pos += 1
    out[pos] = n
    return pos + 1


@njit(cache=True, nogil=True, error_model="numpy")
def _index_digits(k: int) -> int:
    digits = 1
    while k >= 10:
        k //= 10
        digits += 1
    return digits


@njit(cache=True, nogil=True, error_model="numpy")
def _point_len(pts: np.ndarray, r: int) -> int:
    """A Point3 field's length (tag and length byte, 9 bytes per coordinate not +0.0)."""
    size = 0
    for c in range(3):
        v = pts[r, c]
        if v != 0.0 or math.copysign(1.0, v) < 0.0:
            size += 9
    return 2 + size


@njit(cache=True, nogil=True, error_model="numpy")
def _put_point(out: np.ndarray, pos: int, pts: np.ndarray, raw: np.ndarray, r: int) -> int:
    """Row ``r`` of ``pts`` (its bytes: ``raw``) as a ``LinePrimitive.points`` field at ``pos``."""
    out[pos] = 0x2A
    out[pos + 1] = _point_len(pts, r) - 2
    pos += 2
    for c in range(3):
        v = pts[r, c]
        if v != 0.0 or math.copysign(1.0, v) < 0.0:
            out[pos] = 0x09 + 8 * c
            at = 24 * r + 8 * c
            for j in range(8):
                out[pos + 1 + j] = raw[at + j]
            pos += 9
    return pos


@njit(cache=True, nogil=True, error_model="numpy")
def line_entities(
    fields: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ids: tuple[np.ndarray, np.ndarray],
    entity_slot: np.ndarray,
    index: np.ndarray,
    join: np.ndarray,
    pts: np.ndarray,
    slot_start: np.ndarray,
    slot_end: np.ndarray,
    out: np.ndarray,
) -> int:
    """``SceneUpdate.entities`` records of line-strip entities into ``out``, as
    ``swarmplan.io.foxglove_paths`` joins them: per entity e (of slot s = entity_slot[e]) the
    timestamp ``stamp``, the frame id field ``fixed``, the id ``prefix[prefix_at[s]:
    prefix_at[s + 1]]`` followed by the decimal ``index[s]`` (none when negative), and one line
    primitive: ``head``, its points (a Point3 field each, +0.0 coordinates left out as proto3
    does: ``join[s]`` first when ``index[s] > 0``, then ``pts[slot_start[s]:slot_end[s]]``),
    then ``color``; ``fields = (stamp, fixed, head, color)``, ``ids = (prefix, prefix_at)``.
    Returns the bytes written (``out`` must hold them; ``pts`` and ``join`` C-contiguous)."""
    stamp, fixed, head, color = fields
    prefix, prefix_at = ids
    raw = pts.reshape(-1).view(np.uint8)
    join_raw = join.reshape(-1).view(np.uint8)
    pos = 0
    for e in range(len(entity_slot)):
        s = entity_slot[e]
        k = index[s]
        points = _point_len(join, s) if k > 0 else 0
        for r in range(slot_start[s], slot_end[s]):
            points += _point_len(pts, r)
        line = len(head) + points + len(color)
        eid = prefix_at[s + 1] - prefix_at[s] + (_index_digits(k) if k >= 0 else 0)
        size = len(stamp) + len(fixed) + 1 + _varint_len(eid) + eid + 1 + _varint_len(line) + line
        out[pos] = 0x12
        pos = _put_varint(out, pos + 1, size)
        pos = _piece(out, pos, stamp, 0, len(stamp))
        pos = _piece(out, pos, fixed, 0, len(fixed))
        out[pos] = 0x1A
        pos = _put_varint(out, pos + 1, eid)
        a, b = prefix_at[s], prefix_at[s + 1]
        pos = _piece(out, pos, prefix, a, b - a)
        if k >= 0:
            digits = _index_digits(k)
            _digits(out, pos + digits, k)
            pos += digits
        out[pos] = 0x5A
        pos = _put_varint(out, pos + 1, line)
        pos = _piece(out, pos, head, 0, len(head))
        if k > 0:
            pos = _put_point(out, pos, join, join_raw, s)
        for r in range(slot_start[s], slot_end[s]):
            pos = _put_point(out, pos, pts, raw, r)
        pos = _piece(out, pos, color, 0, len(color))
    return pos


@njit(cache=True, nogil=True, error_model="numpy")
def sample_paths(
    pos: np.ndarray,
    slots: np.ndarray,
    has: np.ndarray,
    last: np.ndarray,
    points: np.ndarray,
    count: np.ndarray,
    max_points: int,
    new: np.ndarray,
    first: np.ndarray,
) -> tuple[int, int]:
    """``PathTrails.sample`` on its arrays: each agent i not standing on its slot's last point
    appends ``pos[i]`` to its path (a full path keeps every other of its older points and its
    newest); the agents that added a point go to ``new``, those whose path starts to ``first``
    (in agent order); returns how many of each."""
    n_new = 0
    n_first = 0
    for i in range(len(slots)):
        k = slots[i]
        x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
        if has[k] and last[k, 0] == x and last[k, 1] == y and last[k, 2] == z:
            continue
        new[n_new] = i
        n_new += 1
        if not has[k]:
            first[n_first] = i
            n_first += 1
        has[k] = True
        last[k, 0], last[k, 1], last[k, 2] = x, y, z
        c = count[k]
        points[k, c, 0], points[k, c, 1], points[k, c, 2] = x, y, z
        c += 1
        if c > max_points:
            older = (max_points + 1) // 2  # points[k, 0:max_points:2], then the newest
            for j in range(1, older):
                for d in range(3):
                    points[k, j, d] = points[k, 2 * j, d]
            for d in range(3):
                points[k, older, d] = points[k, max_points, d]
            c = older + 1
        count[k] = c
    return n_new, n_first

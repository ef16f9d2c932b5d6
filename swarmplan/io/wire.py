"""Protobuf wire format, written directly for the Foxglove channels' per-agent fields.

The bytes are the ones protobuf's own serializer gives for the same messages
(tests/test_foxglove_tf_bytes.py): proto3 leaves out a double equal to +0.0 (not -0.0),
length-delimited fields carry a varint length. Building and serializing one protobuf message
per agent per step was the largest recording cost of a large swarm; here the numbers of all
agents are packed in one numpy operation (:func:`vector_fields`, :func:`pose_fields`) and a
message is one join of cached per-agent pieces (:func:`join_records`).
"""

from __future__ import annotations

import math
import struct
from types import ModuleType

import numpy as np
from google.protobuf.descriptor_pb2 import FileDescriptorSet

# FrameTransform written directly in protobuf's wire format (the bytes protobuf's own
# serializer gives, tests/test_foxglove_tf_bytes.py): building and serializing 256 messages
# per step through the protobuf API was the largest recording cost of a 256-agent step.
# Fields: 1 timestamp, 2 parent_frame_id, 3 child_frame_id, 4 translation, 5 rotation;
# proto3 leaves out a double equal to +0.0 (not -0.0); doubles are tags 0x09/0x11/0x19/0x21.
DOUBLE = struct.Struct("<d").pack
XYZ = struct.Struct("<BBBdBdBd").pack  # translation with x, y, z all non-zero: the usual case
DOUBLE_TAGS = (b"\x09", b"\x11", b"\x19", b"\x21")


def present(v: float) -> bool:
    return v != 0.0 or math.copysign(1.0, v) < 0.0  # -0.0 and NaN are written


def vector_bytes(field_tag: bytes, values: tuple[float, ...], tags: tuple[bytes, ...]) -> bytes:
    inner = b"".join(tag + DOUBLE(v) for tag, v in zip(tags, values, strict=True) if present(v))
    return field_tag + varint(len(inner)) + inner


_LAST_STAMP: tuple[float, bytes] = (math.nan, b"")  # the last time asked and its bytes


def timestamp_bytes(t: float) -> bytes:
    global _LAST_STAMP
    last = _LAST_STAMP  # (a step's channels ask for the same time in turn)
    if last[0] == t:
        return last[1]
    ns = int(round(t * 1e9))
    sec, nanos = divmod(ns, 1_000_000_000)
    inner = (b"\x08" + varint(sec) if sec else b"") + (b"\x10" + varint(nanos) if nanos else b"")
    data = b"\x0a" + varint(len(inner)) + inner
    _LAST_STAMP = (t, data)
    return data


def _varint_slow(n: int) -> bytes:
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


# Lengths of entities and transforms are almost always below 2**14 (one or two bytes): no
# loop for those (tens of thousands of calls per second of a 256-agent log).
_ONE_BYTE = [bytes((n,)) for n in range(128)]


def varint(n: int) -> bytes:
    if n < 128:
        return _ONE_BYTE[n]
    if n < 16384:
        return bytes((n & 0x7F | 0x80, n >> 7))
    return _varint_slow(n)


_PREFIX_TABLES: dict[bytes, list[bytes]] = {}
_TABLE_MAX = 16384  # longer fields (rare: a large mesh entity) get their prefix made each time


def length_prefixes(tag: bytes, lengths: list[int]) -> list[bytes]:
    """The tag and varint length of each length-delimited field of ``lengths``."""
    table = _PREFIX_TABLES.get(tag, [])
    top = max(lengths, default=0)
    if top >= len(table):
        if top >= _TABLE_MAX:
            return [tag + varint(n) for n in lengths]
        # One list lookup per field: the lengths seen so far, up to the next power of two (the
        # whole table to 2**14 took ~7 ms per tag, at a log's first step).
        size = max(256, 1 << top.bit_length())
        table = _PREFIX_TABLES[tag] = table + [tag + varint(n) for n in range(len(table), size)]
    return list(map(table.__getitem__, lengths))


def join_records(
    tag: bytes, lengths: list[int], stamp: bytes, heads: list[bytes], bodies: list[bytes]
) -> bytes:
    """Records ``tag, len, stamp, head, body`` of every agent as one bytes (one join)."""
    n = len(bodies)
    flat: list[bytes] = [b""] * (4 * n)
    flat[0::4] = length_prefixes(tag, lengths)
    flat[1::4] = [stamp] * n
    flat[2::4] = heads
    flat[3::4] = bodies
    return b"".join(flat)


# Packed records of the usual case, written for all agents in one numpy operation: a Vector3
# or Point3 field (tag, length 27, then x, y, z with their tags) and a rotation with only z and
# w set. Rows with a zero (or -0.0) value, which proto3 writes differently, are encoded one by one.
_XYZ_DTYPE = np.dtype(
    [
        ("tag", "u1"),
        ("len", "u1"),
        ("tx", "u1"),
        ("x", "<f8"),
        ("ty", "u1"),
        ("y", "<f8"),
        ("tz", "u1"),
        ("z", "<f8"),
    ]
)
_ZW_DTYPE = np.dtype([("tag", "u1"), ("len", "u1"), ("tz", "u1"), ("z", "<f8"), ("tw", "u1"), ("w", "<f8")])


VECTOR_BYTES = _XYZ_DTYPE.itemsize  # a Vector3/Point3 field with x, y and z all non-zero


def vector_blob(tag: int, xyz: np.ndarray) -> bytes | None:
    """The fields ``tag`` of every row of ``xyz`` (n, 3) joined, ``VECTOR_BYTES`` each, when
    no value is +-0.0 (the usual case); None otherwise (then :func:`vector_fields`)."""
    if not (xyz != 0.0).all():
        return None
    rec = np.empty(len(xyz), dtype=_XYZ_DTYPE)
    rec["tag"], rec["len"], rec["tx"], rec["ty"], rec["tz"] = tag, 27, 0x09, 0x11, 0x19
    rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    return rec.tobytes()


def vector_fields(tag: int, xyz: np.ndarray) -> list[bytes]:
    """Per row of ``xyz`` (n, 3): the field ``tag`` holding a Vector3/Point3 of it, as
    protobuf writes it (``XYZ`` when x, y and z are all non-zero, else ``vector_bytes``)."""
    n = len(xyz)
    rec = np.empty(n, dtype=_XYZ_DTYPE)
    rec["tag"], rec["len"], rec["tx"], rec["ty"], rec["tz"] = tag, 27, 0x09, 0x11, 0x19
    rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    blob = rec.tobytes()
    size = VECTOR_BYTES
    out = [blob[k : k + size] for k in range(0, n * size, size)]
    odd = np.flatnonzero(~(xyz != 0.0).all(axis=1))
    if len(odd):
        field = bytes((tag,))
        for i in odd.tolist():
            out[i] = vector_bytes(field, tuple(xyz[i].tolist()), DOUBLE_TAGS[:3])
    return out


_POSE_DTYPE = np.dtype(_XYZ_DTYPE.descr + [(f"r{name}", kind) for name, kind in _ZW_DTYPE.descr])


def pose_fields(xyz: np.ndarray, qz: np.ndarray, qw: np.ndarray) -> list[bytes]:
    """Per agent: a FrameTransform's translation (4) and rotation (5, the quaternion
    (0, 0, qz, qw)) fields, as protobuf writes them."""
    n = len(xyz)
    rec = np.empty(n, dtype=_POSE_DTYPE)
    rec["tag"], rec["len"], rec["tx"], rec["ty"], rec["tz"] = 0x22, 27, 0x09, 0x11, 0x19
    rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    rec["rtag"], rec["rlen"], rec["rtz"], rec["rtw"] = 0x2A, 18, 0x19, 0x21
    rec["rz"], rec["rw"] = qz, qw
    blob = rec.tobytes()
    size = _POSE_DTYPE.itemsize
    out = [blob[k : k + size] for k in range(0, n * size, size)]
    odd = np.flatnonzero(~((xyz != 0.0).all(axis=1) & (qz != 0.0) & (qw != 0.0)))
    for i in odd.tolist():
        x, y, z = xyz[i].tolist()
        trans = XYZ(0x22, 27, 0x09, x, 0x11, y, 0x19, z) if x and y and z else None
        trans = trans or vector_bytes(b"\x22", (x, y, z), DOUBLE_TAGS[:3])
        out[i] = trans + vector_bytes(b"\x2a", (0.0, 0.0, float(qz[i]), float(qw[i])), DOUBLE_TAGS)
    return out


class Patched:
    """A message whose bytes change between steps only in a timestamp (of a given length) and in
    doubles at fixed places: the bytes once (``message``, made by the general encoder), then
    each step two numpy scatters into them (:meth:`fill`) instead of a join of per-agent pieces.

    ``stamp_at`` (n,): where each record's timestamp starts; ``double_at``: where each double
    starts, in the order of the values given to :meth:`fill` (e.g. (n, k) for k per record).
    Every byte that can change is overwritten by ``fill``, so the template is filled in place."""

    __slots__ = ("_bytes", "_buf", "_stamp_at", "_double_at", "_stamp_idx", "_value_idx")

    def __init__(self, message: bytes, stamp_at: np.ndarray, stamp_len: int, double_at: np.ndarray):
        self._bytes = bytearray(message)  # _buf is a view of it (a part written by slicing)
        self._buf = np.frombuffer(self._bytes, dtype=np.uint8)
        self._stamp_at = np.asarray(stamp_at, dtype=np.intp)
        self._double_at = np.asarray(double_at, dtype=np.intp).ravel()
        self._stamp_idx = self._stamp_at[:, None] + np.arange(stamp_len)
        self._value_idx = (self._double_at[:, None] + np.arange(8)).ravel()

    def write(self, at: int, data: bytes) -> None:
        """``data`` in place at ``at`` (a part of the message that changed, same length)."""
        self._bytes[at : at + len(data)] = data

    def fill_nonzero(self, stamp: bytes, values: np.ndarray, kernels: ModuleType) -> bytes | None:
        """:meth:`fill` by the compiled writer when no value is +-0.0 (the layout proto3 gives
        then is the template's); None, nothing written, otherwise. ``values``: C-contiguous."""
        done = kernels.patch_nonzero(
            self._buf, self._stamp_at, np.frombuffer(stamp, dtype=np.uint8), self._double_at, values
        )
        return bytes(self._bytes) if done else None

    def fill_poses(
        self,
        stamp: bytes,
        kernels: ModuleType,
        vel: np.ndarray,
        slots: np.ndarray,
        qz: np.ndarray,
        qw: np.ndarray,
        pos: np.ndarray,
    ) -> bytes | None:
        """``/tf``'s compiled step: the headings of ``vel`` into ``qz``, ``qw`` at ``slots``
        (``headings``), then, when no position or rotation component is +-0.0, the message with
        ``stamp`` and per record x, y, z, qz, qw in place; None (headings written) otherwise."""
        done = kernels.patch_poses(
            self._buf, self._stamp_at, np.frombuffer(stamp, dtype=np.uint8), self._double_at,
            vel, slots, qz, qw, pos,
        )  # fmt: skip
        return bytes(self._bytes) if done else None

    def fill(self, stamp: bytes, values: np.ndarray, kernels: ModuleType | None = None) -> bytes:
        """The message with ``stamp`` and ``values`` (as little-endian doubles) in place; with
        ``kernels`` (``swarmplan.io._record_kernels``) written by its compiled ``patch``."""
        if kernels is not None:
            flat = np.ascontiguousarray(values, dtype="<f8").ravel()
            kernels.patch(
                self._buf, self._stamp_at, np.frombuffer(stamp, dtype=np.uint8), self._double_at, flat
            )
            return self._buf.tobytes()
        buf = self._buf
        buf[self._stamp_idx] = np.frombuffer(stamp, dtype=np.uint8)
        buf[self._value_idx] = np.ascontiguousarray(values, dtype="<f8").view(np.uint8).ravel()
        return buf.tobytes()


def record_starts(lengths: list[int]) -> np.ndarray:
    """Where the content of each length-delimited record (a one-byte tag, the varint
    ``lengths[i]``, then ``lengths[i]`` bytes) starts in their concatenation."""
    n = np.asarray(lengths, dtype=np.intp)
    prefix = 2 + (n >= 128) + (n >= 16384) + (n >= 2**21) + (n >= 2**28)
    return np.cumsum(prefix + n) - n


def point_bytes(pt: tuple[float, float, float]) -> bytes:
    """One ``LinePrimitive.points`` field (5) holding the Point3 ``pt``."""
    x, y, z = pt
    if x and y and z:
        return XYZ(0x2A, 27, 0x09, x, 0x11, y, 0x19, z)
    return vector_bytes(b"\x2a", pt, DOUBLE_TAGS[:3])


def file_descriptor_set(message_class) -> FileDescriptorSet:
    """FileDescriptorSet of a message's .proto file and all its dependencies (deps first)."""
    fds = FileDescriptorSet()
    seen: set[str] = set()

    def add(fd):
        if fd.name in seen:
            return
        seen.add(fd.name)
        for dep in fd.dependencies:
            add(dep)
        fd.CopyToProto(fds.file.add())

    add(message_class.DESCRIPTOR.file)
    return fds

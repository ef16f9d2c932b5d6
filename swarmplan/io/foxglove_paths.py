"""Flown paths for the Foxglove scene, sent as they grow (every message bounded by the run's
length, not growing with it).

``/scene/paths``: per agent with new points since the last message, one line strip entity
``path/<id>/<k>`` (k = 0, 1, ...) holding those points, from the previous chunk's last point
on, so the chunks join into the whole path in the 3D panel (entities without a lifetime stay).
``/scene/paths/overview``: every agent's whole path as ``path/<id>``, at most
``overview_points`` points evenly spaced over the kept ones (the i-th of m of n kept:
index round(i (n - 1) / (m - 1)), halves up; kept: at most ``max_points``,
the older half's resolution halved when full), drawn thinner: after a seek, Foxglove restores
each topic from its latest message, and the overview draws every path whole again.

The entities are assembled in protobuf's wire format from the points encoded all at once
(``swarmplan.io.wire.vector_fields``), the bytes protobuf's own serializer gives
(tests/test_foxglove_tf_bytes.py).
"""

from __future__ import annotations

import itertools
from types import ModuleType

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive

from swarmplan.io.foxglove_shapes import FRAME, set_color, set_pose
from swarmplan.io.wire import VECTOR_BYTES, length_prefixes, varint, vector_blob, vector_fields

PATH_RGBA = (0.12, 0.47, 0.71, 0.9)
PATH_THICKNESS = 2.0  # px (scale invariant); the overview is drawn at half of it
_ENTITIES_TAG = b"\x12"  # SceneUpdate.entities
_POINTS_TAG = 0x2A  # LinePrimitive.points: field 5, wire type 2
_FRAME_FIELD = b"\x12" + varint(len(FRAME)) + FRAME.encode()  # SceneEntity.frame_id
_ID_TAG = b"\x1a"  # SceneEntity.id
_LINES_TAG = b"\x5a"  # SceneEntity.lines


def _line_fixed_fields(thickness: float) -> tuple[bytes, bytes]:
    """A path line's fields before its points (1-4: type, pose, thickness, scale_invariant) and
    after them (6: colour), serialized by protobuf itself."""
    line = LinePrimitive(type=LinePrimitive.LINE_STRIP, thickness=thickness, scale_invariant=True)
    set_pose(line.pose, (0.0, 0.0, 0.0))
    color = Color()
    set_color(color, PATH_RGBA)
    c = color.SerializeToString()
    return line.SerializeToString(), b"\x32" + varint(len(c)) + c


_LINE_HEAD, _LINE_COLOR = _line_fixed_fields(PATH_THICKNESS)
_OVERVIEW_HEAD, _ = _line_fixed_fields(PATH_THICKNESS / 2)
_U8 = {k: np.frombuffer(v, dtype=np.uint8) for k, v in (("frame", _FRAME_FIELD), ("line", _LINE_HEAD),
       ("overview", _OVERVIEW_HEAD), ("color", _LINE_COLOR))}  # fmt: skip


def _line_entities(stamp: bytes, eids: list[bytes], points: list[bytes], head: bytes) -> bytes:
    """``SceneUpdate.entities`` records, one per entity id: an entity with one line strip of
    its encoded ``points`` (fields: timestamp, frame id, id, lines), all joined at once."""
    n = len(eids)
    line_lens = [len(head) + len(p) + len(_LINE_COLOR) for p in points]
    lines = length_prefixes(_LINES_TAG, line_lens)
    ids = length_prefixes(_ID_TAG, [len(e) for e in eids])
    fixed = len(stamp) + len(_FRAME_FIELD)
    sizes = [
        fixed + len(i) + len(e) + len(p) + k for i, e, p, k in zip(ids, eids, lines, line_lens, strict=True)
    ]
    flat: list[bytes] = [b""] * (9 * n)
    flat[0::9] = length_prefixes(_ENTITIES_TAG, sizes)
    flat[1::9] = [stamp] * n
    flat[2::9] = [_FRAME_FIELD] * n
    flat[3::9] = ids
    flat[4::9] = eids
    flat[5::9] = lines
    flat[6::9] = [head] * n
    flat[7::9] = points
    flat[8::9] = [_LINE_COLOR] * n
    return b"".join(flat)


def _point_groups(xyz: np.ndarray, bounds: list[int]) -> list[bytes]:
    """The ``LinePrimitive.points`` fields of the rows ``bounds[j]:bounds[j + 1]`` of ``xyz``,
    per group (slices of one encoding of all rows in the usual case, no coordinate +-0.0)."""
    blob = vector_blob(_POINTS_TAG, xyz)
    if blob is not None:
        size = VECTOR_BYTES
        return [blob[size * a : size * b] for a, b in itertools.pairwise(bounds)]
    fields = vector_fields(_POINTS_TAG, xyz)
    return [b"".join(fields[a:b]) for a, b in itertools.pairwise(bounds)]


class PathTrails:
    """The agents' paths by slot (an index per agent, given by the scene): :meth:`sample` each
    scene update, :meth:`chunks` and :meth:`overview` give the messages' bytes."""

    def __init__(self, max_points: int = 400, overview_points: int = 32):
        self.max_points = max(4, int(max_points))
        self.overview_points = max(2, int(overview_points))
        self.order: dict[str, int] = {}  # agents with a path, in the order they started -> slot
        self.last = np.zeros((0, 3))  # per slot: the last point (the next chunk starts there)
        self.has = np.zeros(0, dtype=bool)
        self.points = np.zeros((0, self.max_points + 1, 3))  # per slot: kept points
        self.count = np.zeros(0, dtype=np.intp)
        self.chunk_index = np.zeros(0, dtype=np.intp)
        self._sent_last = np.zeros((0, 3))  # per slot: the last point of its last chunk
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []  # (slots, points) since the last chunks
        # for the compiled writer (line_entities): the slots in path order, and per slot the
        # entity ids' bytes ("path/<id>/" of the chunks, "path/<id>" of the overview)
        self._ids_for = -1  # len(order) they were made for
        self._order_slots = np.zeros(0, dtype=np.intp)
        self._chunk_ids: tuple[np.ndarray, np.ndarray] | None = None
        self._overview_ids: tuple[np.ndarray, np.ndarray] | None = None

    def grow(self, k: int) -> None:
        """Room for ``k`` more slots."""
        self.last = np.concatenate([self.last, np.full((k, 3), np.nan)])
        self.has = np.concatenate([self.has, np.zeros(k, dtype=bool)])
        self.points = np.concatenate([self.points, np.zeros((k,) + self.points.shape[1:])])
        self.count = np.concatenate([self.count, np.zeros(k, dtype=np.intp)])
        self.chunk_index = np.concatenate([self.chunk_index, np.zeros(k, dtype=np.intp)])
        self._sent_last = np.concatenate([self._sent_last, np.zeros((k, 3))])

    def sample(
        self, ids: tuple[str, ...], pos: np.ndarray, slots: np.ndarray, kernels: ModuleType | None = None
    ) -> None:
        """Append the agents' positions to their paths; an agent standing on its last point adds
        none. ``kernels``: by the compiled ``sample_paths`` (the same arrays)."""
        if kernels is not None and self.points.shape[1] == self.max_points + 1:
            pos = np.ascontiguousarray(pos, dtype=float)
            new = np.empty(len(slots), dtype=np.intp)
            first = np.empty(len(slots), dtype=np.intp)
            n_new, n_first = kernels.sample_paths(
                pos, slots, self.has, self.last, self.points, self.count, self.max_points, new, first
            )
            for i in first[:n_first].tolist():  # first points: paths start (message order)
                self.order[ids[i]] = int(slots[i])
            if n_new:
                new = new[:n_new]
                self._pending.append((slots[new], pos[new]))
            return
        same = self.has[slots] & (self.last[slots] == pos).all(axis=1)
        new = np.flatnonzero(~same)
        if not len(new):
            return
        s, p = slots[new], pos[new]
        for i in np.flatnonzero(~self.has[s]).tolist():  # first points: paths start (message order)
            self.order[ids[new[i]]] = int(s[i])
        self._pending.append((s, p.copy()))
        self.last[s] = p
        self.has[s] = True
        room = self.max_points + 1 - self.points.shape[1]
        if room > 0:  # max_points was raised after construction
            self.points = np.pad(self.points, ((0, 0), (0, room), (0, 0)))
        counts = self.count[s]
        self.points[s, counts] = p
        counts += 1
        self.count[s] = counts
        for k in s[counts > self.max_points].tolist():
            # halve the resolution of the older part, keep the newest point
            pts = self.points[k, : self.max_points + 1]
            kept = np.concatenate([pts[:-1:2], pts[-1:]])
            self.points[k, : len(kept)] = kept
            self.count[k] = len(kept)

    def _slot_ids(self) -> None:
        """The per-slot entity ids (bytes) of the paths started so far, for the compiled writer."""
        if self._ids_for == len(self.order):
            return
        self._ids_for = len(self.order)
        self._order_slots = np.fromiter(self.order.values(), dtype=np.intp, count=len(self.order))
        n = len(self.count)
        names = [b""] * n
        for aid, k in self.order.items():
            names[k] = f"path/{aid}".encode()
        for which, tail in (("_overview_ids", b""), ("_chunk_ids", b"/")):
            ids = [name + tail if name else b"" for name in names]
            at = np.zeros(n + 1, dtype=np.intp)
            np.cumsum([len(i) for i in ids], out=at[1:])
            setattr(self, which, (np.frombuffer(b"".join(ids) or b"\0", dtype=np.uint8), at))

    def _compiled_entities(
        self,
        kernels: ModuleType,
        stamp: bytes,
        head: str,
        ids: tuple[np.ndarray, np.ndarray],
        entity_slot: np.ndarray,
        index: np.ndarray,
        pts: np.ndarray,
        counts: np.ndarray,
    ) -> bytes:
        """The entities' records by ``kernels.line_entities`` (the bytes of :func:`_line_entities`):
        per slot ``counts`` of the rows of ``pts`` (in slot order), after its chunk's first point
        (the last sent) when ``index`` says it is not the first chunk."""
        prefix_at = ids[1]
        end = np.cumsum(counts)
        per_entity = 72 + len(stamp) + len(_FRAME_FIELD) + len(_LINE_HEAD) + len(_LINE_COLOR)
        out = np.empty(len(entity_slot) * per_entity + int(prefix_at[-1]) + 29 * len(pts), dtype=np.uint8)
        fields = (np.frombuffer(stamp, dtype=np.uint8), _U8["frame"], _U8[head], _U8["color"])
        size = kernels.line_entities(
            fields, ids, entity_slot, index, self._sent_last, np.ascontiguousarray(pts, dtype=float),
            end - counts, end, out,
        )  # fmt: skip
        return out[:size].tobytes()

    def chunks(self, stamp: bytes, kernels: ModuleType | None = None) -> bytes | None:
        """The ``/scene/paths`` message: per agent with new points, its next chunk (None: none new).
        ``kernels``: written by the compiled writer (the same bytes)."""
        if not self._pending:
            return None
        slots = np.concatenate([s for s, _ in self._pending])
        pts = np.concatenate([p for _, p in self._pending])
        self._pending = []
        by_slot = np.argsort(slots, kind="stable")  # each slot's points in the order they came
        slots, pts = slots[by_slot], pts[by_slot]
        if kernels is not None:
            self._slot_ids()
            counts = np.bincount(slots, minlength=len(self.count))
            entity_slot = self._order_slots[counts[self._order_slots] > 0]
            data = self._compiled_entities(
                kernels, stamp, "line", self._chunk_ids, entity_slot, self.chunk_index, pts, counts
            )
            moved = counts > 0
            self._sent_last[moved] = self.last[moved]
            self.chunk_index[moved] += 1
            return data
        first = np.flatnonzero(np.diff(slots, prepend=-1))
        moved = slots[first]
        sizes = np.diff(first, append=len(slots))
        # a chunk after an agent's first starts at the last point of the one before
        joined = self.chunk_index[moved] > 0
        pts = np.insert(pts, first[joined], self._sent_last[moved[joined]], axis=0)
        bounds = np.concatenate([[0], np.cumsum(sizes + joined)]).tolist()
        encoded = dict(zip(moved.tolist(), _point_groups(pts, bounds), strict=True))
        order = [(aid, k) for aid, k in self.order.items() if k in encoded]
        index = self.chunk_index.tolist()
        eids = [f"path/{aid}/{index[k]}".encode() for aid, k in order]
        data = _line_entities(stamp, eids, [encoded[k] for _, k in order], _LINE_HEAD)
        self._sent_last[moved] = self.last[moved]
        self.chunk_index[moved] += 1
        return data

    def overview(self, stamp: bytes, kernels: ModuleType | None = None) -> bytes | None:
        """The ``/scene/paths/overview`` message (None: no path yet); ``kernels`` as in :meth:`chunks`."""
        if not self.order:
            return None
        paths = slots = np.fromiter(self.order.values(), dtype=np.intp, count=len(self.order))
        if kernels is not None:
            slots = np.sort(paths)  # the compiled writer takes the points in slot order
        counts = self.count[slots]
        m = np.minimum(counts, self.overview_points)
        # per path: m evenly spaced indices over its kept points (all of them when few)
        i = np.arange(m.max())
        idx = (2 * i * (counts - 1)[:, None] + (m - 1)[:, None]) // (2 * np.maximum(m - 1, 1))[:, None]
        valid = i < m[:, None]
        pts = self.points[np.repeat(slots, m), idx[valid]]
        if kernels is not None:
            self._slot_ids()
            per_slot = np.zeros(len(self.count), dtype=np.intp)
            per_slot[slots] = m
            none = np.full(len(self.count), -1, dtype=np.intp)
            return self._compiled_entities(
                kernels, stamp, "overview", self._overview_ids, paths, none, pts, per_slot
            )
        bounds = np.concatenate([[0], np.cumsum(m)]).tolist()
        eids = [f"path/{aid}".encode() for aid in self.order]
        points = _point_groups(pts, bounds)
        return _line_entities(stamp, eids, points, _OVERVIEW_HEAD)

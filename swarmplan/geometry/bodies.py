"""The obstacle shapes and the table of a world's bodies.

:data:`SHAPES` is the one list of shapes: per shape its name in the world format, its code
in the compiled distance functions (:mod:`swarmplan.geometry._shape_kernel`, numpy twin
:mod:`swarmplan.geometry.shapes`), the keys it takes in a world file (the world format
validates them from here), its three kernel parameters, its bounding radius, its FCL
geometry and a triangle surface for drawings. :func:`body_table` turns a world's obstacles
into one frozen :class:`Bodies` table (shape code, pose, parameters, bounding radius) that
the field, the swept checks, the guide and the escapes' costs read.

Meshes are listed (code -1) but have no analytic distance: their distance grid
(``shapes.MeshGrid``) and FCL measure them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

Values = Mapping[str, Any]
"""A shape's parameters by their world-format keys (an obstacle's ``params``, or an obstacle
of a log's ``/world`` message)."""

MESH = -1
"""The code of meshes (no analytic distance)."""


@dataclass(frozen=True)
class Key:
    """A parameter of a shape in the world format: a number or a list of three numbers."""

    name: str
    vector: bool = False
    positive: bool = True  # > 0; otherwise >= 0


@dataclass(frozen=True)
class Shape:
    """One obstacle shape (see the module docstring)."""

    name: str
    code: int
    keys: tuple[Key, ...]
    params: Callable[[Values], tuple[float, float, float]]
    """The kernel parameters ``a, b, c`` of ``_shape_kernel.sdf``."""
    bound: Callable[[Values], float]
    """Radius of a sphere about the body's centre holding the whole shape."""
    fcl: Callable[[Values], Any]
    """The ``fcl.CollisionGeometry`` in the body's frame."""
    surface: Callable[[Values], Any]
    """A ``trimesh.Trimesh`` of the surface in the body's frame (drawings)."""


def _f(v: Values, key: str) -> float:
    return float(v[key])


def _half(v: Values, key: str) -> np.ndarray:
    return np.asarray(v[key], dtype=float) / 2


def _fcl() -> Any:
    import fcl

    return fcl


def _trimesh() -> Any:
    import trimesh

    return trimesh


def _box_params(v: Values) -> tuple[float, float, float]:
    h = _half(v, "size")
    return float(h[0]), float(h[1]), float(h[2])


def _mesh_only(v: Values) -> Any:
    raise ValueError("a mesh's geometry comes from its vertices and faces, not from parameters")


SHAPES: tuple[Shape, ...] = (
    Shape(
        "sphere",
        0,
        (Key("radius"),),
        params=lambda v: (_f(v, "radius"), 0.0, 0.0),
        bound=lambda v: _f(v, "radius"),
        fcl=lambda v: _fcl().Sphere(_f(v, "radius")),
        surface=lambda v: _trimesh().creation.icosphere(subdivisions=2, radius=_f(v, "radius")),
    ),
    Shape(
        "box",
        1,
        (Key("size", vector=True),),
        params=_box_params,
        bound=lambda v: float(np.linalg.norm(np.asarray(v["size"], dtype=float)) / 2),
        fcl=lambda v: _fcl().Box(*np.asarray(v["size"], dtype=float)),
        surface=lambda v: _trimesh().creation.box(extents=np.asarray(v["size"], dtype=float)),
    ),
    Shape(
        "cylinder",
        2,
        (Key("radius"), Key("height")),
        params=lambda v: (_f(v, "radius"), _f(v, "height") / 2, 0.0),
        bound=lambda v: math.hypot(_f(v, "radius"), _f(v, "height") / 2),
        fcl=lambda v: _fcl().Cylinder(_f(v, "radius"), _f(v, "height")),
        surface=lambda v: _trimesh().creation.cylinder(
            radius=_f(v, "radius"), height=_f(v, "height"), sections=24
        ),
    ),
    Shape(
        "capsule",
        3,
        (Key("radius"), Key("height", positive=False)),  # height: the straight section
        params=lambda v: (_f(v, "radius"), _f(v, "height") / 2, 0.0),
        bound=lambda v: _f(v, "radius") + _f(v, "height") / 2,
        fcl=lambda v: _fcl().Capsule(_f(v, "radius"), _f(v, "height")),
        surface=lambda v: _trimesh().creation.capsule(
            height=max(_f(v, "height"), 1e-6), radius=_f(v, "radius"), count=[16, 16]
        ),
    ),
    Shape(
        "ellipsoid",
        4,
        (Key("semi_axes", vector=True),),
        params=lambda v: tuple(float(e) for e in np.asarray(v["semi_axes"], dtype=float)),
        bound=lambda v: float(np.max(np.asarray(v["semi_axes"], dtype=float))),
        fcl=lambda v: _fcl().Ellipsoid(*(float(e) for e in np.asarray(v["semi_axes"], dtype=float))),
        surface=lambda v: _trimesh().Trimesh(
            _trimesh().creation.icosphere(subdivisions=3).vertices * np.asarray(v["semi_axes"], dtype=float),
            _trimesh().creation.icosphere(subdivisions=3).faces,
        ),
    ),
    Shape(
        "mesh",
        MESH,
        (),  # file and scale: read by the world format's mesh loader
        params=_mesh_only,
        bound=_mesh_only,
        fcl=_mesh_only,
        surface=_mesh_only,
    ),
)

BY_NAME: dict[str, Shape] = {s.name: s for s in SHAPES}
NAMES: tuple[str, ...] = tuple(s.name for s in SHAPES)
ANALYTIC: tuple[str, ...] = tuple(s.name for s in SHAPES if s.code >= 0)
"""The shapes with an analytic distance (every one but the mesh), in code order."""


def shape(name: str) -> Shape:
    """The shape called ``name`` (``KeyError`` naming the known ones if none is)."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown shape {name!r} (known: {', '.join(NAMES)})") from None


def code_of(name: str) -> int:
    """The code of the shape ``name`` (-1 for meshes and unknown shapes)."""
    s = BY_NAME.get(name)
    return MESH if s is None else s.code


@dataclass(frozen=True)
class Bodies:
    """The bodies of a world, one row per obstacle in world order (arrays, read-only).

    ``code``: shape code (-1 mesh); ``position``: centre at t = 0; ``rotation``: local =
    (p - centre) @ rotation; ``identity``: the rotation is the identity; ``prm``: the three
    kernel parameters (zeros for meshes); ``bound``: bounding radius; ``moving``: the body
    moves."""

    code: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    identity: np.ndarray
    prm: np.ndarray
    bound: np.ndarray
    moving: np.ndarray

    def __len__(self) -> int:
        return len(self.code)

    @property
    def analytic(self) -> bool:
        """Whether every body has an analytic distance (no mesh)."""
        return bool((self.code >= 0).all())

    def rows(self, idx: np.ndarray | Sequence[int]) -> Bodies:
        """The table of the bodies ``idx`` (in that order)."""
        idx = np.asarray(idx, dtype=np.int64)
        return Bodies(*(_frozen(np.ascontiguousarray(getattr(self, f)[idx])) for f in _FIELDS))


_FIELDS = ("code", "position", "rotation", "identity", "prm", "bound", "moving")


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def body_table(obstacles: Sequence[Any]) -> Bodies:
    """The :class:`Bodies` of ``obstacles`` (``world.model.Obstacle``, world order)."""
    m = len(obstacles)
    prm = np.zeros((m, 3))
    for j, o in enumerate(obstacles):
        if o.shape != "mesh":
            prm[j] = shape(o.shape).params(o.shape_params)
    rot = np.ascontiguousarray(np.array([o.rotation for o in obstacles], dtype=float).reshape(m, 3, 3))
    return Bodies(
        code=_frozen(np.array([code_of(o.shape) for o in obstacles], dtype=np.int64)),
        position=_frozen(np.array([o.position for o in obstacles], dtype=float).reshape(m, 3)),
        rotation=_frozen(rot),
        identity=_frozen(np.array([np.array_equal(R, np.eye(3)) for R in rot], dtype=np.bool_)),
        prm=_frozen(prm),
        bound=_frozen(np.array([o.bounding_radius for o in obstacles], dtype=float)),
        moving=_frozen(np.array([o.moving for o in obstacles], dtype=np.bool_)),
    )

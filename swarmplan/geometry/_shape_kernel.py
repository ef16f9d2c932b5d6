"""The signed distance of a local point to each obstacle shape, compiled (numba): the one
place the shapes' distances are written for compiled code.

Every compiled caller (the field, the swept checks, the guide, the escapes' segment costs)
calls these; their numpy twins are :mod:`swarmplan.geometry.shapes` (``SDF``, ``DISTANCE``),
held to them bit for bit by tests/test_shape_distance.py. A shape is its code (the index in
:data:`swarmplan.geometry.bodies.SHAPES`) and three parameters ``a, b, c``
(``bodies.Shape.params``): sphere radius; box half sizes; cylinder and capsule radius and
half height; ellipsoid semi-axes. Points are in the body's frame (centre at the origin, axis along z). Meshes
(code -1) have no analytic distance: their callers use the mesh's distance grid, or FCL.

Compiled with numpy's error model (no exceptions on a division; none divides by zero).
Imported only by kernel modules (numba stays out of start-up).
"""

from __future__ import annotations

import math

from swarmplan.runtime.compiled import njit

EPS = 1e-12
"""The floor of a normalized vector's length (``shapes._EPS``)."""

SPHERE, BOX, CYLINDER, CAPSULE, ELLIPSOID = 0, 1, 2, 3, 4
"""Shape codes (``bodies.SHAPES`` order)."""

ROOT_STEPS = 200
"""Most halvings of the ellipsoid's bracket (its root is found to the last bit well before)."""


@njit(cache=True, nogil=True, error_model="numpy")
def _ellipsoid(x, y, z, a, b, c):  # noqa: ANN001, ANN202
    """Signed distance and local gradient of (x, y, z) to the ellipsoid of semi-axes a, b, c.

    Outside, the nearest surface point is ``q_i = e_i^2 p_i / (t + e_i^2)`` with ``t > 0`` the
    root of ``F(t) = sum (e_i p_i / (t + e_i^2))^2 - 1``, which falls from ``F(0) > 0`` to at
    most 0 at ``t = max(e) |p|``; bisection finds it to the last bit (stopping where the
    midpoint is an end of the bracket): the exact distance ``|p - q|``. Inside, the depth is
    bounded from above by ``|p - p/k|`` (``p/k`` is a surface point, ``k = |p / e|``) and by the
    smallest semi-axis (the deepest point's depth): minus the smaller of them is never above
    the true signed distance (the field never sees less danger than there is; FCL decides
    contacts). The gradient points outwards: from q to p outside, the normal of the scaled
    sphere ``(p_i / e_i^2)`` inside."""
    ux = x / a
    uy = y / b
    uz = z / c
    k = math.sqrt(ux * ux + uy * uy + uz * uz)
    n = math.sqrt(x * x + y * y + z * z)
    ea = a * a
    eb = b * b
    ec = c * c
    if k > 1.0:
        s0 = 0.0
        s1 = max(a, b, c) * n
        s = s0
        for _ in range(ROOT_STEPS):
            s = 0.5 * (s0 + s1)
            if s == s0 or s == s1:
                break
            r0 = a * x / (s + ea)
            r1 = b * y / (s + eb)
            r2 = c * z / (s + ec)
            f = r0 * r0 + r1 * r1 + r2 * r2 - 1.0
            if f > 0.0:
                s0 = s
            elif f < 0.0:
                s1 = s
            else:
                break
        dx = x - ea * x / (s + ea)
        dy = y - eb * y / (s + eb)
        dz = z - ec * z / (s + ec)
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        m = max(d, EPS)
        return d, dx / m, dy / m, dz / m
    depth = min(a, b, c)
    if k > 0.0:
        depth = min(n / k - n, depth)
    vx = x / ea
    vy = y / eb
    vz = z / ec
    m = max(math.sqrt(vx * vx + vy * vy + vz * vz), EPS)
    return -depth, vx / m, vy / m, vz / m


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def sdf_grad(code, x, y, z, a, b, c):  # noqa: ANN001, ANN201
    """:func:`sdf` and its local gradient (a unit vector): ``(d, gx, gy, gz)``, the values of
    ``shapes.SDF`` bit for bit."""
    if code == SPHERE:
        n = math.sqrt(x * x + y * y + z * z)
        m = max(n, EPS)
        return n - a, x / m, y / m, z / m
    if code == BOX:
        sx = 1.0 if x >= 0 else -1.0
        sy = 1.0 if y >= 0 else -1.0
        sz = 1.0 if z >= 0 else -1.0
        qx = abs(x) - a
        qy = abs(y) - b
        qz = abs(z) - c
        px = max(qx, 0.0)
        py = max(qy, 0.0)
        pz = max(qz, 0.0)
        outside = math.sqrt(px * px + py * py + pz * pz)
        qmax = max(qx, qy, qz)
        d = outside + min(qmax, 0.0)
        if outside > 0:
            m = max(outside, EPS)
            return d, px / m * sx, py / m * sy, pz / m * sz
        # Inside or on the surface: the face of the largest q (the first on ties, np.argmax).
        if qx >= qy and qx >= qz:
            return d, sx, 0.0, 0.0
        if qy >= qz:
            return d, 0.0, sy, 0.0
        return d, 0.0, 0.0, sz
    if code == CYLINDER:
        rxy = math.sqrt(x * x + y * y)
        dr = rxy - a
        dz = abs(z) - b
        out_r = max(dr, 0.0)
        out_z = max(dz, 0.0)
        outside = math.hypot(out_r, out_z)
        d = outside + min(max(dr, dz), 0.0)
        m = max(rxy, EPS)
        ux = x / m
        uy = y / m
        zd = 1.0 if z >= 0 else -1.0
        if outside > 0:
            # radial * out_r + zdir * out_z, component by component as numpy adds them (the
            # zero terms decide the sign of a zero).
            vx = ux * out_r + 0.0 * out_z
            vy = uy * out_r + 0.0 * out_z
            vz = 0.0 * out_r + zd * out_z
            n = max(math.sqrt(vx * vx + vy * vy + vz * vz), EPS)
            return d, vx / n, vy / n, vz / n
        if dr > dz:
            return d, ux, uy, 0.0
        return d, 0.0, 0.0, zd
    if code == ELLIPSOID:
        return _ellipsoid(x, y, z, a, b, c)
    # capsule: to the closest point of its axis segment
    vz = z - min(max(z, -b), b)
    n = math.sqrt(x * x + y * y + vz * vz)
    m = max(n, EPS)
    return n - a, x / m, y / m, vz / m


@njit(cache=True, nogil=True, error_model="numpy")
def sdf(code, x, y, z, a, b, c):  # noqa: ANN001, ANN201
    """Signed distance (positive outside, negative inside) of the local point (x, y, z) to the
    shape ``code`` with parameters ``a, b, c``: :func:`sdf_grad`'s distance (inlined, the
    gradient's work left out by the compiler)."""
    return sdf_grad(code, x, y, z, a, b, c)[0]


@njit(cache=True, nogil=True, error_model="numpy")
def half_extents(code, a, b, c):  # noqa: ANN001, ANN201
    """Half sizes of the shape's local bounding box."""
    if code == BOX:
        return a, b, c
    if code == CYLINDER:
        return a, a, b
    if code == CAPSULE:
        return a, a, b + a
    if code == ELLIPSOID:
        return a, b, c
    return a, a, a


@njit(cache=True, nogil=True, error_model="numpy")
def exact(code):  # noqa: ANN001, ANN201
    """Whether :func:`sdf` is the exact distance of the shape (then it is 1-Lipschitz and, the
    shapes being convex, convex along a line: the swept checks may decide with it). The
    ellipsoid's is exact outside only: FCL decides its sweeps."""
    return 0 <= code <= CAPSULE

"""Kinematic models, vectorized over agents: commanded velocity in, limited velocity out.

- ``multirotor``: point mass; |v| <= speed.max and |v1 - v0| <= max_accel * dt per step.
- ``fixed_wing`` (a Dubins-airplane model): speed in [speed.min, speed.max] changing by at most
  max_accel * dt; flight-path angle within ±max_climb_angle; heading and flight-path angle turn
  together, so that the direction of flight turns by at most V * dt / min_turn_radius per step
  (V the slower of the step's two speeds): the 3D curvature of the flown path, turning angle
  over distance, stays <= 1 / min_turn_radius at every speed. It rolls into and out of turns:
  the bank of one step's horizontal curvature, atan(k_h * V^2 / g), differs from the last
  one's by at most roll_rate * dt, so the turn's curvature changes continuously (the
  simulation keeps each fixed wing's turn state, the last step's curvature;
  ``swarmplan.flight._fixed_wing_kernel``).
Positions advance with the new velocity (semi-implicit Euler), so the recorded velocity
is exactly the step's displacement over dt.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.geometry.vec3 import norm3
from swarmplan.runtime.compiled import kernel_module

if TYPE_CHECKING:
    from swarmplan.world.model import World


MARGIN_FRACTION = 0.2
"""The safety margin of an agent's body as a fraction of its radius (at most ``MAX_MARGIN``):
kept from every obstacle surface, and between two agents' swept bodies (each its own)."""

MAX_MARGIN = 0.25
"""m: the largest safety margin of an agent's body."""


def safety_margin(radius: np.ndarray) -> np.ndarray:
    """The safety margin of bodies of ``radius``: ``MARGIN_FRACTION`` of it, at most ``MAX_MARGIN``.
    Scaled to the agent, a 5 cm drone keeps 1 cm (a margin in metres sized for 0.5 m agents kept
    crazyflies further apart than the separation they asked for, and froze them there)."""
    return np.minimum(MAX_MARGIN, MARGIN_FRACTION * radius)


def checked_radius(radius: np.ndarray) -> np.ndarray:
    """The radius the safety filter sweeps bodies of ``radius`` with: the radius and its
    :func:`safety_margin`. What an agent needs to pass between surfaces (a gap narrower than
    twice this holds it), so the static guide's ways keep it too."""
    return radius + safety_margin(radius)


@dataclass(frozen=True)
class AgentParams:
    """Per-agent limits as arrays of shape (N,) (``separation`` (N, 3)), in SI units and radians."""

    ids: tuple[str, ...]
    fixed_wing: np.ndarray  # bool
    radius: np.ndarray
    speed_min: np.ndarray
    speed_max: np.ndarray
    speed_cruise: np.ndarray
    max_accel: np.ndarray
    min_turn_radius: np.ndarray
    max_climb: np.ndarray
    min_altitude: np.ndarray
    separation: np.ndarray
    roll_rate: np.ndarray  # rad/s (fixed wings)
    clearance: np.ndarray  # m the turn-ahead guard keeps from every body (fixed wings)
    # (N, 2) m: the heights a climbing or diving manoeuvre of the turn-ahead guard levels off
    # at, (floor, ceiling) of the flight volume three body radii inside it (none: never).
    levels: np.ndarray | None = None
    # (N,) the length scale of each agent's own potential field against the world's (``field_scales``).
    field_scale: np.ndarray | None = None

    @classmethod
    def from_world(cls, world: World) -> AgentParams:
        a = world.agents
        arr = lambda f: np.array([f(x) for x in a], dtype=float)  # noqa: E731
        return cls(
            ids=tuple(x.id for x in a),
            fixed_wing=np.array([x.model == "fixed_wing" for x in a]),
            radius=arr(lambda x: x.radius),
            speed_min=arr(lambda x: x.speed_min),
            speed_max=arr(lambda x: x.speed_max),
            speed_cruise=arr(lambda x: x.speed_cruise),
            max_accel=arr(lambda x: x.max_accel),
            min_turn_radius=arr(lambda x: x.min_turn_radius),
            max_climb=arr(lambda x: x.max_climb_angle),
            min_altitude=arr(lambda x: x.min_altitude),
            separation=np.array([x.separation for x in a], dtype=float).reshape(-1, 3),
            roll_rate=arr(lambda x: x.roll_rate if x.roll_rate > 0 else np.inf),
            clearance=arr(lambda x: max(x.clearance, x.radius)),
            levels=guard_levels(world),
            field_scale=field_scales(world),
        )


def field_scales(world: World) -> np.ndarray:
    """Per agent: the length scale of the potential field it flies, against the world's
    (``planner.apf.influence``, sized for the agent that needs the most room). A multirotor
    flies the field scaled to its own room (``AgentSpec.field_room``, four braking distances
    from its cruise speed) over the largest agent's: its influence, repulsion gains and
    quadratic radius shrink with it (``apf.ApfField``), the field's shape kept. A slow lab
    drone that brakes in centimetres sharing a room with one that needs metres is not pushed
    by every body within those metres (summed, such pushes sank one under a slab to the
    ground and held it there). Fixed wings, which turn away rather than stop, keep the
    world's field (scale 1); so do agents of one kind."""
    room = np.array([a.field_room for a in world.agents], dtype=float)
    if not len(room):
        return room
    fixed_wing = np.array([a.model == "fixed_wing" for a in world.agents])
    return np.where(fixed_wing, 1.0, room / room.max())


GUARD_LEVEL_RADII = 3.0
"""A climbing or diving manoeuvre of the turn-ahead guard levels off this many body radii inside
the floor or the ceiling of the flight volume (the guard keeps its body radius beyond the body,
two; one more for the steps of the level-off)."""


def guard_levels(world: World) -> np.ndarray:
    """Per agent (N, 2): the floor and the ceiling a turn-ahead guard's dive or climb levels off
    at, ``GUARD_LEVEL_RADII`` body radii inside the bounds (the floor no lower than flat ground,
    z = 0, which the guard measures its predictions over)."""
    r = np.array([a.radius for a in world.agents], dtype=float)
    floor = max(float(world.bounds_min[2]), 0.0) + GUARD_LEVEL_RADII * r
    ceiling = float(world.bounds_max[2]) - GUARD_LEVEL_RADII * r
    return np.column_stack([floor, ceiling])


def initial_velocity(params: AgentParams, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Multirotors start at rest; fixed wings already fly at cruise speed, level, towards the goal."""
    v = np.zeros_like(start)
    d = goal - start
    d[:, 2] = 0.0
    n = np.linalg.norm(d, axis=1)
    heading = np.where(n[:, None] > 1e-9, d / np.maximum(n, 1e-9)[:, None], np.array([1.0, 0.0, 0.0]))
    fw = params.fixed_wing
    v[fw] = heading[fw] * params.speed_cruise[fw, None]
    return v


def limit_multirotor(
    v0: np.ndarray, v_cmd: np.ndarray, vmax: np.ndarray, amax: np.ndarray, dt: float
) -> np.ndarray:
    """New velocity: the command clipped to vmax, reached with at most amax*dt of change."""
    s = norm3(v_cmd)
    v_cmd = v_cmd * np.minimum(1.0, vmax / np.maximum(s, 1e-12))[:, None]
    dv = v_cmd - v0
    n = norm3(dv)
    return v0 + dv * np.minimum(1.0, amax * dt / np.maximum(n, 1e-12))[:, None]


def fixed_wing_model():  # noqa: ANN201
    """:mod:`swarmplan.flight._fixed_wing_kernel` (numba loads with it at the first call)."""
    return kernel_module("swarmplan.flight._fixed_wing_kernel")


def fly_fixed_wing(
    v0: np.ndarray,
    v_cmd: np.ndarray,
    vmin: np.ndarray,
    vmax: np.ndarray,
    amax: np.ndarray,
    turn_radius: np.ndarray,
    climb: np.ndarray,
    dt: float,
    kappa: np.ndarray | None = None,
    roll: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """New velocities (n, 3) and turn states (n, 2) of fixed wings: speed within [vmin, vmax]
    by at most amax * dt a step, |flight-path angle| <= climb, and the direction of flight
    turned towards the command's by at most ``min(V0, V1) * dt / turn_radius`` (heading and
    flight-path angle together); with turn states ``kappa`` (n, 2, the curvature of the last
    step, :func:`turn_states`) and roll rates ``roll`` (rad/s), the bank of the horizontal
    curvature, ``atan(k_h V^2 / g)`` (V the faster speed), changes by at most ``roll dt``. Without them the
    turn is not rate-limited.

    A command of (near) zero keeps the direction; a vertical one keeps the heading and asks
    for the full climb or dive (``swarmplan.flight._fixed_wing_kernel.fly_step``)."""
    n = len(v0)
    f = np.ascontiguousarray
    kappa = np.zeros((n, 2)) if kappa is None else f(kappa, dtype=float)
    roll = np.full(n, np.inf) if roll is None else f(roll, dtype=float)
    return fixed_wing_model().fly_steps(
        f(v0, dtype=float), f(v_cmd, dtype=float), kappa,
        *(_per_row(x, n) for x in (vmin, vmax, amax, turn_radius, climb)), roll, dt,
    )  # fmt: skip


def _per_row(x: np.ndarray | float, n: int) -> np.ndarray:
    """``x`` as a contiguous float array (n,), broadcast when it is not one already."""
    if isinstance(x, np.ndarray) and x.shape == (n,) and x.dtype == float and x.flags.c_contiguous:
        return x
    return np.ascontiguousarray(np.broadcast_to(x, (n,)), dtype=float)


def limit_fixed_wing(
    v0: np.ndarray,
    v_cmd: np.ndarray,
    vmin: np.ndarray,
    vmax: np.ndarray,
    amax: np.ndarray,
    turn_radius: np.ndarray,
    climb: np.ndarray,
    dt: float,
    kappa: np.ndarray | None = None,
    roll: np.ndarray | None = None,
) -> np.ndarray:
    """The new velocities of :func:`fly_fixed_wing`."""
    return fly_fixed_wing(v0, v_cmd, vmin, vmax, amax, turn_radius, climb, dt, kappa, roll)[0]


def turn_states(
    params: AgentParams, v0: np.ndarray, v1: np.ndarray, dt: float, idx: np.ndarray
) -> np.ndarray:
    """Turn states (rows of ``idx``, (n, 2)) of the steps ``v0 -> v1`` of fixed wings ``idx``:
    each step's curvature, as :func:`fly_fixed_wing` left it."""
    f = np.ascontiguousarray
    climb = f(params.max_climb[idx])
    return fixed_wing_model().turn_states(f(v0, dtype=float), f(v1, dtype=float), climb, dt)


def limit_velocity(
    params: AgentParams,
    v0: np.ndarray,
    v_cmd: np.ndarray,
    dt: float,
    idx: np.ndarray,
    kappa: np.ndarray | None = None,
) -> np.ndarray:
    """New velocities of agents ``idx`` under their own model's limits; ``kappa`` (rows of
    ``idx``, (n, 2)): the fixed wings' turn states, whose curvature their roll rate changes
    (None: turns not rate-limited)."""
    out = np.empty((len(idx), 3))
    fw = params.fixed_wing[idx]
    mr = ~fw
    if mr.any():
        k = idx[mr]
        out[mr] = limit_multirotor(v0[mr], v_cmd[mr], params.speed_max[k], params.max_accel[k], dt)
    if fw.any():
        k = idx[fw]
        out[fw] = limit_fixed_wing(
            v0[fw],
            v_cmd[fw],
            params.speed_min[k],
            params.speed_max[k],
            params.max_accel[k],
            params.min_turn_radius[k],
            params.max_climb[k],
            dt,
            None if kappa is None else kappa[fw],
            None if kappa is None else params.roll_rate[k],
        )
    return out

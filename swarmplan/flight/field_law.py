"""The potential field's repulsion law, its ranges and its goal factor, in one place.

The numpy field (``_apf_numpy``) computes its terms with these; the escape planner's gates and
waypoint limits call them to ask what the field would do (``planner.escape_gates``,
``planner.escape``). The compiled field (``_apf_kernel``: ``_rep``, ``_power``, its ranges) is
their twin, held to the numpy field bit for bit by tests/test_apf_numpy.py.
"""

from __future__ import annotations

import math

import numpy as np

NEAREST = 0.1
"""Of the agent's radius: the clearance below which the repulsion stops growing (a body touched,
or passed into): half its safety margin (``kinematics.safety_margin``), 5 cm for a 0.5 m agent,
5 mm for a 5 cm lab drone, whose whole margin (1 cm) a clearance in metres swallowed."""

BOUNDS = 0.25
"""Of the influence: the range of the repulsion of the flight volume's faces on multirotors."""

FIXED_WING_BOUNDS = 10.0
"""m: the longest range of the repulsion of the flight volume's faces on fixed wings."""


def nearest(radius: np.ndarray | float) -> np.ndarray | float:
    """The clearance below which the repulsion on agents of ``radius`` stops growing: ``NEAREST``
    of the radius."""
    return NEAREST * radius


def repulsion(rho: np.ndarray, k: float | np.ndarray, rho0: float, near: np.ndarray | float) -> np.ndarray:
    """The push at clearance ``rho``: ``k (1 / max(rho, near) - 1 / rho0)`` within the range
    ``rho0``, nothing beyond (``near``: :func:`nearest` of the agent's radius)."""
    return np.where(rho < rho0, k * (1.0 / np.maximum(rho, near) - 1.0 / rho0), 0.0)


def urgency(tau: np.ndarray, horizon: float) -> np.ndarray:
    """The weight of another agent's predicted closest approach ``tau`` s ahead, within the
    prediction ``horizon``: ``(1 - tau / horizon) ** 2``, 1 now, 0 at the horizon and flat there.
    A conflict first seen at the horizon's edge adds nothing at once: the approaches of a whole
    crowd converging on one point, which enter the horizon together, do not brake every agent
    in the same step (a linear weight rose by up to k / 0.02 x dtau / horizon per step). Both
    agents of a pair act on it, so each may start later; a moving obstacle does not give way,
    and its predicted approach keeps the linear weight ``1 - tau / horizon``."""
    soon = 1.0 - tau / (horizon + 1e-9)  # apf._EPS
    return soon * soon


def clearance_at(push: float, k: float, rho0: float) -> float:
    """The clearance (above :func:`nearest`) at which :func:`repulsion` pushes with ``push``."""
    return 1.0 / (push / k + 1.0 / rho0)


def ground_range(
    influence: float,
    floor: np.ndarray | float,
    goal_height: np.ndarray | float,
    radius: np.ndarray | float,
    can_stop: np.ndarray | bool = True,
) -> np.ndarray | float:
    """The range of the ground's repulsion (a clearance) on an agent of ``radius`` whose least
    altitude flown is ``floor`` and whose goal lies ``goal_height`` above the ground under it.

    For agents that ``can_stop`` (multirotors), the clearance at the floor, lowered to the
    goal's height: the ground holds an agent at its floor while it flies level, and an agent
    whose goal lies below its floor flies there at the goal's height instead of climbing to the
    floor and descending again (a 5 m/s multirotor between two points 1 m up, held at three
    floors, climbed to 4 m and back). At least the agent's radius, a body of air under it. Its
    descent towards the ground is braked as towards any surface (``apf.commanded_velocity``).
    On fixed wings, which turn away rather than stop: the influence, down to three times the
    floor, never below a quarter of the influence."""
    low = np.minimum(floor, goal_height)
    fly = np.maximum(np.minimum(influence, 3.0 * np.asarray(floor, dtype=float)), 0.25 * influence)
    return np.where(can_stop, np.maximum(low - radius, radius), fly)


def bounds_range(influence: float, can_stop: np.ndarray | bool = True) -> np.ndarray | float:
    """The range of the repulsion of the flight volume's faces on agents that ``can_stop``
    (multirotors): ``BOUNDS`` of the influence, the braking distance from cruise speed of the
    agent that needs the most room (the influence is four of them, ``schema.default_influence``):
    a face pushes where such an agent could no longer stop short of it (10 m for a 10 m/s
    multirotor braking at 5 m/s^2, 16 cm for a 0.8 m/s lab drone braking at 2 m/s^2; a range of
    the whole influence held goals near the walls of a small room under the faces' push). On
    fixed wings, which turn away rather than stop, the influence, at most ``FIXED_WING_BOUNDS``."""
    return np.where(can_stop, BOUNDS * influence, np.minimum(influence, FIXED_WING_BOUNDS))


def _pow1(x: float, p: float) -> float:
    try:
        return math.pow(x, p)
    except (ValueError, OverflowError):  # C's pow answers (inf, nan) where Python raises
        with np.errstate(all="ignore"):
            return float(np.power(x, p))


def power(x: np.ndarray, p: float) -> np.ndarray:
    """``x ** p`` elementwise as the compiled field's ``_power`` (numpy's fast paths, else C's
    ``pow``)."""
    if p == 2.0:
        return x * x
    if p == 1.0:
        return x.copy()
    if p == 0.5:
        return np.sqrt(x)
    if p == -1.0:
        return 1.0 / x
    if p == 0.0:
        return np.ones_like(x)
    return np.array([_pow1(float(v), p) for v in x.ravel()]).reshape(x.shape)


def goal_factor(to_goal: np.ndarray, influence: float, goal_power: float) -> np.ndarray:
    """The factor on the repulsion of an agent ``to_goal`` m from its goal: ``min(1, to_goal /
    influence) ** goal_power`` (a goal near a body stays reachable)."""
    return power(np.minimum(1.0, to_goal / influence), goal_power)


SQUEEZE = 0.1
"""Of the influence: the clearance (beyond the radius) under which a multirotor's straight line
to its goal counts as blocked, and the guide leads it (``swarmplan.flight.guide``)."""


def squeeze(influence: float, fixed_wing: np.ndarray, radius: np.ndarray) -> float:
    """The guide's squeeze for agents of ``radius`` (``fixed_wing`` marking the fixed wings):
    ``SQUEEZE`` of the ``influence`` ``rho0`` where multirotors fly. There a surface pushes
    with ``k_rep (1 / rho - 1 / rho0) = 4.5 k_att rho0`` at the default ``k_rep = 0.5 k_att
    rho0^2``, several times the strongest pull (``k_att rho0``): the bare field cannot hold
    the agent on such a line. 1 m for a 5 m/s multirotor braking at 5 m/s^2 (10 m of
    influence), 6 cm for a 0.8 m/s lab drone braking at 2 m/s^2. Where fixed wings fly, at
    least their radius (one body of air): they fly clear lines without the static bodies'
    push, kept off the bodies by their turn-ahead guard."""
    fixed = np.asarray(fixed_wing, dtype=bool)
    need = SQUEEZE * float(influence) if (~fixed).any() else 0.0
    return max(need, float(np.max(np.asarray(radius, dtype=float)[fixed], initial=0.0)))

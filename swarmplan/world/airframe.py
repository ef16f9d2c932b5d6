"""A fixed wing's own agent keys and their defaults from its airframe (``agents[i].roll_rate``,
``agents[i].clearance``: docs/world-format.md)."""

from __future__ import annotations

import math
from typing import Any

FIXED_WING_KEYS = ("roll_rate", "clearance")
"""Agent keys of fixed wings only, defaulting from the airframe (:func:`fixed_wing_defaults`)."""

GRAVITY = 9.80665
"""m/s²: the bank of a level turn of radius R at speed V is atan(V² / (g R))."""


def fixed_wing_defaults(params: dict[str, Any]) -> dict[str, float]:
    """A fixed wing's ``roll_rate`` (deg/s) and ``clearance`` (m) unless its world sets them:
    it rolls into the bank of a minimum-radius turn at cruise speed, atan(V² / (g R_min)),
    while it flies a quarter of its turn radius, within a second at most (its turns start
    where they are asked for, to a quarter radius); it keeps from every body the largest of
    its radius, half its horizontal separation and the tracking error a fixed wing is
    allowed (``0.05 min_turn_radius``, docs/tracking.md)."""
    v, r = params["speed"]["cruise"], params["min_turn_radius"]
    sep = params["separation"]
    out = dict(params)
    if out.get("roll_rate") is None:
        roll_in = min(1.0, 0.25 * r / max(v, 1e-9))  # s
        out["roll_rate"] = math.degrees(math.atan(v * v / (GRAVITY * r))) / roll_in
    if out.get("clearance") is None:
        out["clearance"] = max(params["radius"], 0.5 * max(sep[0], sep[1]), 0.05 * r)
    return out


def fixed_wing_spec(params: dict[str, Any]) -> dict[str, float]:
    """The fixed-wing keys of an agent's resolved keys ``params`` as its ``AgentSpec`` takes them:
    ``roll_rate`` in rad/s (0: none, a multirotor's), ``clearance`` in m (a multirotor's: its radius)."""
    return {
        "roll_rate": math.radians(params.get("roll_rate", 0.0)),
        "clearance": params.get("clearance", params["radius"]),
    }


def airframe_keys(params: dict[str, Any], complete: bool) -> dict[str, Any]:
    """An agent's resolved keys: a multirotor's without the fixed-wing keys; a fixed wing's with
    their defaults when ``complete`` (every other key resolved, none missing)."""
    if params["model"] != "fixed_wing":
        return {k: v for k, v in params.items() if k not in FIXED_WING_KEYS}
    return fixed_wing_defaults(params) if complete else params

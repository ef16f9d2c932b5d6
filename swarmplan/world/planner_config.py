"""The ``planner`` section of a world file as typed, frozen settings (:class:`PlannerConfig`);
the checks of its own sections ``planner.escape`` and ``planner.global``, run by the world
parser so that ``load_world`` returns a world that is valid as a whole; and the cost models'
weights (the names ``planner.global.weights`` may use, with their defaults)."""

from __future__ import annotations

import copy
import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from swarmplan.world.errors import WorldError

COST_WEIGHTS: dict[str, dict[str, float]] = {
    # Paper 004: J = w1 L + w2 H + w3 S, with a penalty per unit of violation.
    "mcfo": {"w1": 0.6, "w2": 0.2, "w3": 0.2, "penalty": 1000.0},
    # Paper 000. path: δ_O; threat_unit: metres per paper unit (km); max_altitude: 0 = the
    # bounds' top; max_climb_angle: degrees for P_B (0 = the agent's).
    "iba": {
        "path": 0.1,
        "threat_unit": 1000.0,
        "max_altitude": 0.0,
        "max_climb_angle": 0.0,
        # l_max of 000 eq 5 in metres (0 = no limit; 000 prints no value).
        "max_length": 0.0,
        "penalty": 1000.0,
    },
    # Paper 002. max_turn_angle / max_climb_angle in degrees (0 = no turn limit / the agent's
    # climb limit).
    "iafsa": {
        "alpha1": 0.5,
        "alpha2": 0.5,
        "xi1": 1.0,
        "xi2": 2.0,
        "payload": 0.5,
        "payload_max": 1.0,
        "payload_penalty_max": 1.5,
        "max_turn_angle": 0.0,
        "max_climb_angle": 0.0,
        "penalty": 1000.0,
    },
}


ESCAPE_DEFAULTS = {
    "waypoints": 4,
    "horizon": None,  # m; left out: 2 influence
    "margin": None,  # m; left out: influence / 10
    "fcl_margin": None,  # m; left out: 3 % of the influence
    "retries": 2,
    "growth": 1.5,
    "max_escapes": 25,
    "rounds": 3,
}


def check_escape(planner: dict[str, Any]) -> dict[str, Any]:
    """``planner.escape`` merged over the defaults; every problem raises one ``WorldError``."""

    raw = planner.get("escape") or {}
    if not isinstance(raw, dict):
        raise WorldError([f"planner.escape: expected a mapping, got {raw!r}"])
    problems = []
    for k in raw:
        if k not in ESCAPE_DEFAULTS:
            close = difflib.get_close_matches(str(k), list(ESCAPE_DEFAULTS), n=1, cutoff=0.6)
            hint = f"did you mean '{close[0]}'?" if close else f"known keys: {', '.join(ESCAPE_DEFAULTS)}"
            problems.append(f"planner.escape.{k}: unknown key ({hint})")
    cfg = dict(ESCAPE_DEFAULTS)
    cfg.update({k: v for k, v in raw.items() if k in ESCAPE_DEFAULTS and v is not None})
    # Lengths left out scale with the field's influence (four braking distances of the agents):
    # at 10 m they are the classic 20 m horizon, 1 m margin and 0.3 m FCL margin.
    rho0 = float(planner["apf"]["influence"])
    for k, share in (("horizon", 2.0), ("margin", 0.1), ("fcl_margin", 0.03)):
        if cfg[k] is None:
            cfg[k] = share * rho0
    counts = {"waypoints": 1, "retries": 0, "max_escapes": 1, "rounds": 1}
    for k, v in cfg.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            problems.append(f"planner.escape.{k}: expected a number, got {v!r}")
        elif k in counts and (v != int(v) or v < counts[k]):
            problems.append(f"planner.escape.{k}: expected a whole number >= {counts[k]}, got {v!r}")
        elif k in ("horizon", "margin") and v <= 0:
            problems.append(f"planner.escape.{k}: must be > 0, got {v!r}")
        elif k == "growth" and v < 1:
            problems.append(f"planner.escape.{k}: must be >= 1, got {v!r}")
        elif k == "fcl_margin" and v < 0:
            problems.append(f"planner.escape.{k}: must be >= 0, got {v!r}")
    if problems:
        raise WorldError(problems)
    return cfg


ENCODINGS = ("planes", "spline")
_NUMBERS = ("lateral", "vertical", "margin")
_COUNTS = ("waypoints", "samples", "population", "iterations", "retries")
_KEYS = ("cost", "encoding", "waypoints", "lateral", "vertical", "margin", "samples", "population",
         "iterations", "retries", "shortcut", "warm_start", "weights")  # fmt: skip


@dataclass(frozen=True)
class GlobalConfig:
    cost: str = "mcfo"
    encoding: str = "planes"
    waypoints: int = 8
    lateral: float = 0.0
    vertical: float = 0.0
    margin: float = 0.0
    samples: int = 40
    population: int = 0
    iterations: int = 0
    retries: int = 2
    shortcut: bool = True
    warm_start: bool = True
    weights: dict[str, float] = field(default_factory=dict)


def check_global(planner: dict[str, Any]) -> GlobalConfig:
    """Validate ``planner.global``; raise ``WorldError`` listing every problem."""
    raw = planner.get("global") or {}
    problems: list[str] = []
    p = "planner.global"
    if not isinstance(raw, dict):
        raise WorldError([f"{p}: expected a mapping"])
    for k in raw:
        if k not in _KEYS:
            problems.append(f"{p}.{k}: unknown key (known keys: {', '.join(_KEYS)})")
    cost = raw.get("cost", "mcfo")
    if cost not in COST_WEIGHTS:
        problems.append(f"{p}.cost: '{cost}' is not one of {', '.join(COST_WEIGHTS)}")
        cost = "mcfo"
    encoding = raw.get("encoding", "spline" if cost == "iafsa" else "planes")
    if encoding not in ENCODINGS:
        problems.append(f"{p}.encoding: '{encoding}' is not one of {', '.join(ENCODINGS)}")
    values: dict[str, Any] = {}
    for k in _NUMBERS + _COUNTS:
        if k not in raw:
            continue
        v = raw[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            problems.append(f"{p}.{k}: expected a number >= 0, got {v!r}")
        elif k in _COUNTS and v != int(v):
            problems.append(f"{p}.{k}: must be a whole number, got {v!r}")
        elif k == "waypoints" and v < 1:
            problems.append(f"{p}.{k}: must be >= 1, got {v!r}")
        elif k == "population" and 0 < v < 2:
            problems.append(f"{p}.{k}: must be >= 2 (or 0 for planner.optimizer.population), got {v!r}")
        else:
            values[k] = int(v) if k in _COUNTS else float(v)
    for k in ("shortcut", "warm_start"):
        if k in raw and not isinstance(raw[k], bool):
            problems.append(f"{p}.{k}: expected true or false, got {raw[k]!r}")
        else:
            values[k] = bool(raw.get(k, True))
    weights = raw.get("weights") or {}
    if not isinstance(weights, dict):
        problems.append(f"{p}.weights: expected a mapping, got {weights!r}")
        weights = {}
    known = COST_WEIGHTS[cost]
    for k, v in weights.items():
        if k not in known:
            problems.append(f"{p}.weights.{k}: unknown weight for cost '{cost}' (known: {', '.join(known)})")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            problems.append(f"{p}.weights.{k}: expected a number >= 0, got {v!r}")
    if cost == "mcfo" and not problems:
        w = {**known, **weights}
        if abs(w["w1"] + w["w2"] + w["w3"] - 1.0) > 1e-6:
            problems.append(
                f"{p}.weights: w1 + w2 + w3 must be 1 (004 eq 2), got {w['w1'] + w['w2'] + w['w3']:g}"
            )
    if cost == "iafsa" and not problems:
        w = {**known, **weights}
        if abs(w["alpha1"] + w["alpha2"] - 1.0) > 1e-6:
            problems.append(f"{p}.weights: alpha1 + alpha2 must be 1 (002 eq 2)")
        if w["payload_max"] <= 0:
            problems.append(f"{p}.weights.payload_max: must be > 0")
    if cost == "iba" and not problems and {**known, **weights}["threat_unit"] <= 0:
        problems.append(f"{p}.weights.threat_unit: must be > 0")
    if problems:
        raise WorldError(problems)
    return GlobalConfig(cost=cost, encoding=encoding, weights=dict(weights), **values)


@dataclass(frozen=True)
class ApfConfig:
    """``planner.apf``: gains and ranges of the potential field (``swarmplan.flight.apf``)."""

    k_att: float
    k_rep: float
    influence: float
    k_agent: float
    quadratic_radius: float
    goal_power: float
    k_moving: float
    horizon: float
    guide: bool = True
    """Whether agents whose straight line is blocked are led round static obstacles
    (``swarmplan.flight.guide``); false flies the bare field, with its local minima."""


@dataclass(frozen=True)
class StuckConfig:
    """``planner.stuck``: less than ``min_progress`` m towards the goal in ``window`` s is stuck."""

    window: float
    min_progress: float


@dataclass(frozen=True)
class OptimizerConfig:
    name: str
    population: int
    iterations: int
    params: Mapping[str, Any]


@dataclass(frozen=True)
class PlannerConfig:
    """The whole ``planner`` section, defaults applied."""

    mode: str  # reactive | global
    apf: ApfConfig
    stuck: StuckConfig
    optimizer: OptimizerConfig
    smoothing: bool
    escape: Mapping[str, Any]  # ESCAPE_DEFAULTS' keys
    global_: GlobalConfig
    mapping: Mapping[str, Any] = field(repr=False, compare=False, default_factory=dict)
    """The validated mapping these settings were read from (the ``/world`` message's ``planner``,
    which keeps the file's own ``escape`` and ``global`` sections as written): :meth:`to_dict`."""

    def to_dict(self) -> dict[str, Any]:
        """The section as a plain mapping (a copy), as a world file or the ``/world`` message has it."""
        return copy.deepcopy(dict(self.mapping))


def planner_config(planner: dict[str, Any]) -> PlannerConfig:
    """The typed view of a validated ``planner`` mapping (raises ``WorldError`` if it is not valid)."""
    opt = planner["optimizer"]
    return PlannerConfig(
        mode=planner["mode"],
        apf=ApfConfig(**planner["apf"]),
        stuck=StuckConfig(**planner["stuck"]),
        optimizer=OptimizerConfig(
            opt["name"], int(opt["population"]), int(opt["iterations"]), MappingProxyType(dict(opt["params"]))
        ),
        smoothing=bool(planner.get("smoothing", {}).get("enabled", True)),
        escape=MappingProxyType(check_escape(planner)),
        global_=check_global(planner),
        mapping=MappingProxyType(copy.deepcopy(dict(planner))),
    )

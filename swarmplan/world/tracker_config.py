"""Vehicle parameters and controller gains of the tracking quadrotor, and the ``tracker:`` world section.

Paper 004 (Chen et al., §7-8) flies its smoothed routes with a six-degree-of-freedom quadrotor
model (from its ref. [28]) under a cascaded PID controller (eq 35): an outer position loop
whose output, inverted, gives the desired attitude, and an inner attitude loop. It states no
mass, inertia or gains; the only numbers it gives are the rated speed 5 m/s and rated
acceleration 0.5 m/s^2 of its VTOL UAV, and the result (following error within 1.2 m). The
defaults below are therefore ours, chosen for a generic 1.5 kg quadrotor (inertia, drag and
motor lag of that class) and tuned so that each loop is 3-5x slower than the one it drives:

    motors        ~50 rad/s   (thrust lag 0.02 s)
    rate loop     ~40 rad/s   (rate.kp = 40 1/s, torque = J * rate PID output)
    attitude loop ~12 rad/s   (attitude.kp = 12 1/s gives body-rate set-points)
    position loop ~2.4 rad/s  (position.kp = 6 1/s^2, kd = 4.5 1/s: damping 0.92; ki = 0.5 1/s^3)

The tilt limit of 55 degrees leaves, at a thrust-to-weight ratio of 2, a vertical margin of
2 cos 55 = 1.15 g. On quickstart these gains and limits took the worst agent's max error from
1.43 m (position 4/0.4/3.6, attitude 8, rate 25, tilt 45, motor 0.03 s) to 1.05 m, both
dominated by the log's instantaneous stops (see docs/tracking.md).

The thrust-to-weight ratio of 2 and the quadratic drag complete the vehicle model.
``parse_tracker`` validates a raw ``tracker:`` mapping the way the world parser validates
every other key: all problems collected as ``tracker.mass: must be > 0, got -1`` strings,
unknown keys answered with the nearest known key.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any


@dataclass(frozen=True)
class PID:
    """Gains of one loop. ``kd`` acts on the derivative of the loop's error."""

    kp: float
    ki: float = 0.0
    kd: float = 0.0


def _pos_pid() -> PID:
    return PID(kp=6.0, ki=0.5, kd=4.5)


def _att_pid() -> PID:
    return PID(kp=12.0, ki=0.0, kd=0.0)


def _rate_pid() -> PID:
    return PID(kp=40.0, ki=0.0, kd=0.0)


@dataclass(frozen=True)
class TrackerConfig:
    """Quadrotor model and cascaded PID gains (SI units; angles in degrees as in the world file)."""

    mass: float = 1.5  # kg
    inertia: tuple[float, float, float] = (0.0347, 0.0347, 0.0617)  # kg m^2, body-axis diagonal
    thrust_to_weight: float = 2.0  # max collective thrust / (mass * g)
    drag: float = 0.05  # N s^2/m^2: drag force = -drag * |v| * v
    drag_feedforward: bool = True  # the controller adds the drag it expects at the reference velocity
    motor_time_constant: float = 0.02  # s, first-order lag from commanded to actual thrust
    max_tilt_deg: float = 55.0  # the position loop never asks for more tilt than this
    max_rate_deg_s: float = 220.0  # body-rate set-points are clipped to this
    dt: float = 0.005  # s, control period and fixed RK4 integration step
    settle_time: float = 2.0  # s of hover at the last recorded position after the log ends
    reference: str = "velocity"  # how the recorded samples become a reference (reference.py)
    position: PID = field(default_factory=_pos_pid)
    attitude: PID = field(default_factory=_att_pid)
    rate: PID = field(default_factory=_rate_pid)

    @property
    def max_thrust(self) -> float:
        return self.thrust_to_weight * self.mass * G

    def to_dict(self) -> dict[str, Any]:
        """The resolved section, as it would be written back into a world file (and into /world)."""
        d = asdict(self)
        d["inertia"] = list(self.inertia)
        return d


G = 9.81  # m/s^2

# (key, lower bound, bound inclusive?) for the scalar numbers; None = no bound beyond finiteness.
_SCALARS: dict[str, tuple[float, bool]] = {
    "mass": (0.0, False),
    "thrust_to_weight": (1.0, False),  # at or below 1 the vehicle cannot hover
    "drag": (0.0, True),
    "motor_time_constant": (0.0, False),
    "max_tilt_deg": (0.0, False),
    "max_rate_deg_s": (0.0, False),
    "dt": (0.0, False),
    "settle_time": (0.0, True),
}
_LOOPS = ("position", "attitude", "rate")
_GAINS = ("kp", "ki", "kd")
REFERENCE_METHODS = ("velocity", "cubic")
KEYS = (*_SCALARS, "inertia", "drag_feedforward", "reference", *_LOOPS)


def _typename(v: Any) -> str:
    return {dict: "mapping", list: "list", str: "string", bool: "boolean", type(None): "nothing"}.get(
        type(v), type(v).__name__
    )


def _unknown(node: dict, allowed: tuple[str, ...], path: str, problems: list[str]) -> None:
    for k in node:
        if k not in allowed:
            close = difflib.get_close_matches(str(k), list(allowed), n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else f" (known keys: {', '.join(allowed)})"
            problems.append(f"{path}.{k}: unknown key{hint}")


def _number(v: Any, p: str, problems: list[str]) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        problems.append(f"{p}: expected a number, got {_typename(v)} {v!r}")
        return None
    return float(v)


def parse_tracker(raw: object, path: str = "tracker") -> tuple[TrackerConfig, list[str]]:
    """Validate a raw ``tracker:`` mapping (``None`` = all defaults).

    Returns the resolved config (defaults wherever a value is missing or wrong) and every
    problem found, each as ``"<path>.<key>: <message>"``. The config is only meaningful when
    the list is empty.
    """
    problems: list[str] = []
    base = TrackerConfig()
    if raw is None:
        return base, problems
    if not isinstance(raw, dict):
        return base, [f"{path}: expected a mapping, got {_typename(raw)}"]
    _unknown(raw, KEYS, path, problems)
    vals: dict[str, Any] = {}
    for key, (lo, inclusive) in _SCALARS.items():
        if raw.get(key) is None:
            continue
        v = _number(raw[key], f"{path}.{key}", problems)
        if v is None:
            continue
        if inclusive and v < lo:
            problems.append(f"{path}.{key}: must be >= {lo:g}, got {v:g}")
        elif not inclusive and v <= lo:
            problems.append(f"{path}.{key}: must be > {lo:g}, got {v:g}")
        else:
            vals[key] = v
    if vals.get("max_tilt_deg", 0.0) >= 90.0:
        problems.append(f"{path}.max_tilt_deg: must be < 90, got {vals.pop('max_tilt_deg'):g}")
    if vals.get("dt", 0.0) > 0.05:
        # The rate loop (~25 rad/s) needs a control period well below its time constant.
        problems.append(f"{path}.dt: must be <= 0.05 s for the attitude loops, got {vals.pop('dt'):g}")
    if raw.get("inertia") is not None:
        v = raw["inertia"]
        p = f"{path}.inertia"
        if (
            not isinstance(v, (list, tuple))
            or len(v) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) for x in v)
        ):
            problems.append(f"{p}: expected a list of 3 numbers, got {v!r}")
        elif any(x <= 0 for x in v):
            problems.append(f"{p}: every value must be > 0, got {v!r}")
        else:
            vals["inertia"] = tuple(float(x) for x in v)
    if raw.get("drag_feedforward") is not None:
        v = raw["drag_feedforward"]
        if isinstance(v, bool):
            vals["drag_feedforward"] = v
        else:
            problems.append(f"{path}.drag_feedforward: expected true or false, got {v!r}")
    if raw.get("reference") is not None:
        v = raw["reference"]
        if v in REFERENCE_METHODS:
            vals["reference"] = v
        else:
            close = difflib.get_close_matches(str(v), list(REFERENCE_METHODS), n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            problems.append(f"{path}.reference: {v!r} is not one of {', '.join(REFERENCE_METHODS)}{hint}")
    for loop in _LOOPS:
        node = raw.get(loop)
        if node is None:
            continue
        p = f"{path}.{loop}"
        if not isinstance(node, dict):
            problems.append(f"{p}: expected a mapping with {', '.join(_GAINS)}, got {_typename(node)}")
            continue
        _unknown(node, _GAINS, p, problems)
        gains = asdict(getattr(base, loop))
        for g in _GAINS:
            if node.get(g) is None:
                continue
            v = _number(node[g], f"{p}.{g}", problems)
            if v is None:
                continue
            if g == "kp" and v <= 0:
                problems.append(f"{p}.{g}: must be > 0, got {v:g}")
            elif v < 0:
                problems.append(f"{p}.{g}: must be >= 0, got {v:g}")
            else:
                gains[g] = v
        vals[loop] = PID(**gains)
    return replace(base, **vals), problems

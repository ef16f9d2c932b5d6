"""``/agents/speed``: every agent's speed (m/s, 6 decimals), their mean and their maximum, for
plots (Foxglove's Plot panel: ``/agents/speed.max``, ``/agents/speed.speed[:]``), written with
each ``/scene`` message of the Foxglove scene (``swarmplan.io.foxglove_scene``)."""

from __future__ import annotations

import numpy as np

from swarmplan.io.json_floats import Interleaved, record_kernels

SPEED_TOPIC = "/agents/speed"
SPEED_SCHEMA = {
    "title": "swarmplan.AgentSpeeds",
    "type": "object",
    "required": ["t", "mean", "max", "speed"],
    "properties": {
        "t": {"type": "number"},
        "mean": {"type": "number"},
        "max": {"type": "number"},
        "speed": {
            "type": "array",
            "items": {"type": "number"},
            "description": "per agent, /agents/state order",
        },
    },
}


class SpeedText:
    """The message's JSON text from the agents' velocities: the text around the numbers once
    per number of agents, then the numbers; with ``compiled`` the speeds, their sum and
    maximum and the text by compiled passes (the same bytes)."""

    def __init__(self) -> None:
        self._text: tuple[int, bool, Interleaved] | None = None

    def encode(self, t: float, vel: np.ndarray, compiled: bool) -> bytes | None:
        """The message at time ``t`` (None: no agents, or a speed that is not finite)."""
        n = len(vel)
        if not n:
            return None
        if self._text is None or self._text[:2] != (n, compiled):
            pieces = [b'{"t":', b',"mean":', b',"max":', b',"speed":['] + [b","] * (n - 1) + [b"]}"]
            self._text = (n, compiled, Interleaved(pieces, compiled=compiled))
        text = self._text[2]
        if compiled:
            values = np.empty(n + 3)
            total, top = record_kernels().speeds(np.ascontiguousarray(vel, dtype=float), values[3:])
            values[0], values[1], values[2] = round(t, 9), round(total / n, 6), top
            data = text.fill_compiled(values)
            if data is not None:
                return data
            speed = values[3:]
        else:
            speed = np.round(np.sqrt((vel * vel).sum(axis=1)), 6)
        values = np.concatenate(([round(t, 9), round(float(speed.mean()), 6), speed.max()], speed))
        return text.fill(values) if np.isfinite(values).all() else None

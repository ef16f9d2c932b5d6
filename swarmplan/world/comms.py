"""The world's optional ``comms`` and ``sensing`` sections: what each agent hears of the others
(state broadcasts with a rate, a delay, losses and a range) and what it senses itself.

Without ``comms`` every agent flies on the true, current state of every other (a perfect,
instantaneous network). With it, each agent flies on the last state it received from each
other agent, extrapolated by its age (``swarmplan.sim.network``). ``sensing.range`` limits the
onboard sensing of moving obstacles and of agents not heard; static bodies stay the known map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from swarmplan.world.checker import Checker


@dataclass(frozen=True)
class Comms:
    """State broadcasts: ``rate`` Hz per agent (None: one per step), each message delayed by
    ``delay`` s plus a uniform spread of +-``jitter`` s, lost with probability ``loss``, and not
    heard at all beyond ``range`` m (inf: unlimited)."""

    rate: float | None = None
    delay: float = 0.0
    jitter: float = 0.0
    loss: float = 0.0
    range: float = math.inf

    def period(self, dt: float) -> float:
        """Seconds between two broadcasts of one agent (at least one step)."""
        return dt if self.rate is None else max(1.0 / self.rate, dt)


@dataclass(frozen=True)
class Sensing:
    """Onboard sensing: moving obstacles, and agents not heard, are seen within ``range`` m."""

    range: float = math.inf


def resolve_comms(c: Checker, raw: Any) -> tuple[dict[str, Any] | None, Comms | None]:
    """``comms``: the resolved section for ``/world`` and the :class:`Comms`; (None, None) without it."""
    if raw is None or not c.keys(raw, "comms", ["rate", "delay", "loss", "range"]):
        return None, None
    rate = c.number(raw, "rate", "comms", math.nan, positive=True)
    delay, jitter = 0.0, 0.0
    d = raw.get("delay")
    if isinstance(d, dict):
        if c.keys(d, "comms.delay", ["mean", "jitter"], ("mean",)):
            delay = c.number(d, "mean", "comms.delay", 0.0, nonneg=True)
            jitter = c.number(d, "jitter", "comms.delay", 0.0, nonneg=True)
            if jitter > delay:
                c.add("comms.delay.jitter", f"must be <= the mean ({delay:g} s): a delay is never negative")
    else:
        delay = c.number(raw, "delay", "comms", 0.0, nonneg=True)
    loss = c.number(raw, "loss", "comms", 0.0, lo=0.0)
    if loss >= 1.0:
        c.add("comms.loss", "must be < 1 (every message lost: nobody hears anybody)")
    heard = c.number(raw, "range", "comms", math.inf, positive=True)
    spec = Comms(None if math.isnan(rate) else rate, delay, jitter, loss, heard)
    resolved = {
        "rate": spec.rate,
        "delay": {"mean": delay, "jitter": jitter},
        "loss": loss,
        "range": None if math.isinf(heard) else heard,
    }
    return resolved, spec


def resolve_sensing(c: Checker, raw: Any) -> tuple[dict[str, Any] | None, Sensing | None]:
    """``sensing``: the resolved section for ``/world`` and the :class:`Sensing`; (None, None) without it."""
    if raw is None or not c.keys(raw, "sensing", ["range"], ("range",)):
        return None, None
    seen = c.number(raw, "range", "sensing", math.inf, positive=True)
    return {"range": seen}, Sensing(seen)

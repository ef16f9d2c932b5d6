"""Masks of the agents' modes (``SwarmState.mode``, an object array of ``Mode``).

``(mode == a) | (mode == b)`` on an object array runs numpy's object loop twice, each with a
fixed cost of a few microseconds; a set's membership test over the modes as a list is one
pass for any number of modes (a third of the time at 64 agents, the same at 512), with the
same booleans (``Mode`` values hash and compare as their strings).
"""

from __future__ import annotations

import numpy as np

from swarmplan.core import Mode

PARKED = frozenset((Mode.ARRIVED, Mode.FAILED))
"""Agents that no longer fly but stay in the air (arrived ones hover, failed ones stopped)."""

ARRIVED = frozenset((Mode.ARRIVED,))
"""Agents at their goals."""


def mode_in(mode: np.ndarray, modes: frozenset[Mode]) -> np.ndarray:
    """Per agent: whether its mode is one of ``modes`` (a bool array)."""
    return np.fromiter(map(modes.__contains__, mode.tolist()), dtype=bool, count=len(mode))

"""Masks of the agents' modes (``SwarmState.mode``, an object array of ``Mode``).

``(mode == a) | (mode == b)`` on an object array runs numpy's object loop twice, each with a
fixed cost of a few microseconds; one lookup per agent in a table of every mode is one pass
for any number of modes (a third of the time at 64 agents, the same at 512). As
``SwarmState.active``, a value that is not a ``Mode`` is a ``KeyError``, never a silent False.
The masks of the last modes seen are kept (``swarmplan.core.mode_codes``): a step asks for
several of the same modes.
"""

from __future__ import annotations

import numpy as np

from swarmplan.core import Mode, mode_codes


def mode_table(*modes: Mode) -> dict[Mode, bool]:
    """The lookup table of ``modes``: every mode to whether it is one of them."""
    return {m: m in modes for m in Mode}


PARKED = mode_table(Mode.ARRIVED, Mode.FAILED)
"""Agents that no longer fly but stay in the air (arrived ones hover, failed ones stopped)."""

ARRIVED = mode_table(Mode.ARRIVED)
"""Agents at their goals."""


def mode_in(mode: np.ndarray, table: dict[Mode, bool]) -> np.ndarray:
    """Per agent: whether its mode is one of a :func:`mode_table`'s modes (a bool array)."""
    return mode_codes(mode, table)

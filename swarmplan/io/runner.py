"""Running one episode to its end: reset, step until terminated or truncated, finish the log.

Observers (e.g. a progress bar) see every step's result. ``should_stop`` is asked between
steps, so a stop requested by a signal ends the run on a step boundary: every step the
summary counts is in the log.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from swarmplan.core import StepResult
from swarmplan.sim import Simulation

Observer = Callable[[StepResult], None]


def run_episode(
    sim: Simulation,
    seed: int,
    observers: Iterable[Observer] = (),
    should_stop: Callable[[], bool] | None = None,
) -> dict[str, Any]:
    """Run ``sim`` from ``reset(seed)`` to its end; returns the summary.

    The recorder (if any) gets the summary and is closed whatever happens: when
    ``should_stop`` says so, or on an exception (which propagates after the file is closed),
    the summary says ``interrupted``.
    """
    observers = list(observers)
    interrupted = False
    try:
        sim.reset(seed=seed)
        while True:
            if should_stop is not None and should_stop():
                interrupted = True
                break
            result = sim.step()
            for observe in observers:
                observe(result)
            if result.terminated or result.truncated:
                break
    except BaseException:
        interrupted = True
        raise
    finally:
        summary = sim.summary(interrupted=interrupted) if sim.state is not None else {"interrupted": True}
        recorder = sim.recorder
        if recorder is not None:
            try:
                if sim.state is not None:
                    recorder.write_summary(summary)
            finally:
                close = getattr(recorder, "close", None)
                if close is not None:
                    close()
    return summary

"""Running a world to its end: overrides of the command line, one recorded episode (reset, step
until terminated or truncated, finish the log).

Observers (e.g. a progress bar) see every step's result. ``should_stop`` is asked between
steps, so a stop requested by a signal ends the run on a step boundary: every step the
summary counts is in the log.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

from swarmplan.core import StepResult
from swarmplan.planner import make_planner, validate_planner_settings
from swarmplan.sim import Simulation
from swarmplan.world import World, WorldError

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


def apply_overrides(world: World, optimizer: str | None, max_time: float | None) -> World:
    changes: dict[str, Any] = {}
    if max_time is not None:
        changes["max_time"] = float(max_time)
    if optimizer is not None:
        planner = dict(world.planner)
        opt = dict(planner["optimizer"], name=optimizer)
        if optimizer != world.planner_config.optimizer.name:
            # The world's params are settings of its own algorithm (e.g. rscdwoa's beta): another
            # algorithm runs with its papers' defaults.
            opt["params"] = {}
        planner["optimizer"] = opt
        changes["planner"] = planner
    return world.with_overrides(**changes) if changes else world


def check_planner_settings(world: World, source: str) -> None:
    """The planner's own sections of the world file (``planner.escape``, ``planner.global``);
    ``load_world`` checks them already, this is for a world changed since."""
    try:
        validate_planner_settings(world)
    except WorldError as exc:
        raise WorldError(exc.problems, source) from None


def simulate(
    world: World,
    seed: int,
    log_path: Path | None,
    *,
    progress: bool = False,
    stream: TextIO = sys.stderr,
    stop_on_signals: bool = False,
) -> dict[str, Any]:
    """Run ``world`` to its end with ``seed``, recording to ``log_path``; returns the summary.

    The log is finished whatever happens: on an exception the summary says ``interrupted``
    and the exception propagates after the file is closed. With ``stop_on_signals`` (the
    command line), Ctrl-C and SIGTERM end the run at the next step boundary instead, and the
    summary says ``interrupted``; a second signal stops at once.
    """
    from swarmplan.io.recording import McapRecorder  # here: mcap and protobuf cost ~0.1 s of start-up

    recorder = (
        McapRecorder(
            log_path,
            flush_interval=world.resolved["log"]["flush_interval"],
            foxglove=world.resolved["log"]["foxglove"],
        )
        if log_path is not None
        else None
    )
    sim = Simulation(world, planner=make_planner(world), recorder=recorder)
    from tqdm import tqdm  # here, not at import: start-up (importlib.metadata, ~0.1 s)

    bar = tqdm(
        total=world.max_time,
        unit="sim-s",
        file=stream,
        disable=not progress,
        delay=2.0,  # only runs that take a while show a bar
        mininterval=0.2,
        bar_format="{l_bar}{bar}| t={n:.1f}/{total:.0f} s [{elapsed}<{remaining}, {rate_fmt}]{postfix}",
    )

    def show(result: StepResult) -> None:
        bar.update(result.state.t - bar.n)
        bar.set_postfix_str(f"{int(result.state.active.sum())} flying", refresh=False)

    try:
        with _stop_requests(stop_on_signals) as stop_requested:
            return run_episode(sim, seed, observers=[show], should_stop=stop_requested)
    finally:
        bar.close()


@contextmanager
def _stop_requests(enabled: bool) -> Iterator[Callable[[], bool]]:
    """While active, SIGINT and SIGTERM only request a stop (the second one stops at once)."""
    requested: list[int] = []
    if not enabled or threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return

    def handler(signum: int, frame: object) -> None:
        if requested:
            raise KeyboardInterrupt
        requested.append(signum)

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield lambda: bool(requested)
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)

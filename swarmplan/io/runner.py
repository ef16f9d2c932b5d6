"""Running a world to its end: overrides of the command line, one recorded episode (reset, step
until terminated or truncated, finish the log).

The simulation writes nothing: observers see every reset and step result (a
:class:`RecordingObserver` writes the log from them, a progress bar counts time), and the
runner owns the log from open to ``/summary`` to close. ``should_stop`` is asked between
steps, so a stop requested by a signal ends the run on a step boundary: every step the
summary counts is in the log.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from swarmplan.core import Event, Observer, Recorder, ResetResult, StepResult
from swarmplan.io.compile_notice import CompileNotice, said_marker
from swarmplan.planner import make_planner, validate_planner_settings
from swarmplan.sim import Simulation
from swarmplan.world import World, WorldError

StepObserver = Callable[[StepResult], None]


class RecordingObserver:
    """Writes a run to a :class:`~swarmplan.core.Recorder` from the results alone: the world,
    planning before flight and the state at t = 0 from the reset; per step its optimizer runs,
    its state, then its events. ``/summary`` and closing are the runner's (:func:`run_episode`)."""

    def __init__(self, recorder: Recorder):
        self.recorder = recorder

    def on_reset(self, result: ResetResult) -> None:
        rec = self.recorder
        rec.write_world(result.world)
        for r in result.records:
            if isinstance(r, Event):
                rec.write_event(r.to_json())
            else:
                rec.write_optimizer(r.to_json())
        rec.write_state(result.state.t, result.agents, result.obstacles)

    def on_step(self, result: StepResult) -> None:
        rec = self.recorder
        for run in result.optimizer_runs:
            rec.write_optimizer(run.to_json())
        rec.write_state(result.state.t, result.agents, result.obstacles)
        if result.comms is not None:
            rec.write_comms(result.comms)
        for e in result.events:
            rec.write_event(e.to_json())


class _StepOnly:
    """A plain callable seeing step results only, as an :class:`~swarmplan.core.Observer`."""

    def __init__(self, fn: StepObserver):
        self.on_step = fn

    def on_reset(self, result: ResetResult) -> None:
        pass


def run_episode(
    sim: Simulation,
    seed: int,
    observers: Iterable[Observer | StepObserver] = (),
    should_stop: Callable[[], bool] | None = None,
    recorder: Recorder | None = None,
) -> dict[str, Any]:
    """Run ``sim`` from ``reset(seed)`` to its end; returns the summary.

    ``observers`` see every result (objects with ``on_reset`` and ``on_step``, or callables of
    a step result). With ``recorder``, the run is written to it (a :class:`RecordingObserver`
    first), then ``/summary``, and it is closed whatever happens: when ``should_stop`` says
    so, or on an exception (which propagates after the file is closed), the summary says
    ``interrupted``.
    """
    watchers: list[Observer] = [RecordingObserver(recorder)] if recorder is not None else []
    watchers += [o if hasattr(o, "on_step") else _StepOnly(o) for o in observers]
    interrupted = started = False
    try:
        first = sim.start(seed=seed)
        started = True
        for o in watchers:
            o.on_reset(first)
        while True:
            if should_stop is not None and should_stop():
                interrupted = True
                break
            result = sim.step()
            for o in watchers:
                o.on_step(result)
            if result.terminated or result.truncated:
                break
    except BaseException:
        interrupted = True
        raise
    finally:
        summary = sim.summary(interrupted=interrupted) if sim.state is not None else {"interrupted": True}
        if recorder is not None:
            try:
                if sim.state is not None:
                    if not started:  # planning before flight failed: the log still names its world
                        recorder.write_world(sim.world_message())
                    recorder.write_summary(summary)
            finally:
                recorder.close()
    return summary


@dataclass(frozen=True)
class LiveView:
    """Serve the run live (Foxglove WebSocket protocol) on ``host:port`` (port 0: a free one),
    paced to ``speed`` times real time (0: as fast as it runs)."""

    host: str = "127.0.0.1"
    port: int = 8765
    speed: float = 1.0


class Pacer:
    """Holds each step until its simulated time, divided by ``speed``, has passed on the wall
    clock since the reset (waits in slices of at most 50 ms, so a stop request is seen)."""

    def __init__(self, speed: float, should_stop: Callable[[], bool] = lambda: False):
        if not speed > 0:
            raise ValueError(f"speed: must be > 0, got {speed}")
        self.speed = float(speed)
        self.should_stop = should_stop
        self._start = 0.0

    def on_reset(self, result: ResetResult) -> None:
        self._start = time.perf_counter()

    def on_step(self, result: StepResult) -> None:
        due = self._start + result.state.t / self.speed
        while not self.should_stop():
            left = due - time.perf_counter()
            if left <= 0:
                return
            time.sleep(min(left, 0.05))


def apply_overrides(
    world: World, optimizer: str | None, max_time: float | None, guide: bool | None = None
) -> World:
    """``world`` with the command line's choices: the optimizer (``none``: pure APF),
    ``sim.max_time`` and ``planner.apf.guide`` (False: the bare potential field); None keeps
    the world's."""
    changes: dict[str, Any] = {}
    if max_time is not None:
        changes["max_time"] = float(max_time)
    planner = world.planner
    if optimizer is not None:
        opt = dict(planner["optimizer"], name=optimizer)
        if optimizer != world.planner_config.optimizer.name:
            # The world's params are settings of its own algorithm (e.g. rscdwoa's beta): another
            # algorithm runs with its papers' defaults.
            opt["params"] = {}
        planner["optimizer"] = opt
        changes["planner"] = planner
    if guide is not None:
        planner["apf"] = dict(planner["apf"], guide=bool(guide))
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
    live: LiveView | None = None,
    notices: bool | CompileNotice = False,
) -> dict[str, Any]:
    """Run ``world`` to its end with ``seed``, recording to ``log_path``; returns the summary.

    The log is finished whatever happens: on an exception the summary says ``interrupted``
    and the exception propagates after the file is closed. With ``stop_on_signals`` (the
    command line), Ctrl-C and SIGTERM end the run at the next step boundary instead, and the
    summary says ``interrupted``; a second signal stops at once. With ``live`` the log's
    channels are also served live (its address is printed on ``stream``), the run paced as
    it says; the server stops when the log is closed. With ``notices``, a run that compiles
    kernels (the first on a machine) says so on ``stream`` (``CompileNotice``: pass one to learn
    afterwards whether it compiled, its ``compiled``). The progress bar ends at 100 % when the run ends
    by itself.
    """
    from swarmplan.io.recording import McapRecorder  # here: the writer's import costs start-up

    if live is not None and log_path is None:
        raise ValueError("a live view needs a log path (the log is written as well)")
    recorder = (
        McapRecorder(
            log_path,
            flush_interval=world.resolved["log"]["flush_interval"],
            foxglove=world.resolved["log"]["foxglove"],
            live=None if live is None else (live.host, live.port),
        )
        if log_path is not None
        else None
    )
    if live is not None:
        print(
            f"live view: ws://{live.host}:{recorder.live_port} (in Foxglove: Open connection, "
            "Foxglove WebSocket)",
            file=stream,
            flush=True,
        )
    try:
        sim = Simulation(world, planner=make_planner(world))
    except BaseException:
        if recorder is not None:
            recorder.close()
        raise
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

    notice = notices if isinstance(notices, CompileNotice) else None
    if notice is None and notices:
        notice = CompileNotice(marker=said_marker())
    if notice is not None:
        notice.write = lambda text: tqdm.write(text, file=stream)  # past the progress bar
        notice.start()
    try:
        with _stop_requests(stop_on_signals) as stop_requested:
            observers: list[Observer | StepObserver] = [show]
            if live is not None and live.speed > 0:
                observers.append(Pacer(live.speed, stop_requested))
            summary = run_episode(
                sim, seed, observers=observers, should_stop=stop_requested, recorder=recorder
            )
        if not summary["interrupted"]:
            bar.total = bar.n  # ended before max_time (every agent done): the bar says 100 %
            bar.refresh()
        return summary
    finally:
        if notice is not None:
            notice.stop()
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

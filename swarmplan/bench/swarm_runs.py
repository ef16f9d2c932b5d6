"""One run of swarmplan in a benchmark scenario and what ``bench swarm`` and its lab measure of
it: arrivals, contacts between agents (:class:`ContactMeter`), path ratios, real-time factor."""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from swarmplan.bench.swarm_report import Row
from swarmplan.bench.swarm_scenarios import (
    scenario_world,
)


class ContactMeter:
    """Pairs of agents closer than the sum of their radii between consecutive samples (the
    relative motion of a step taken as straight), and the minimum surface distance."""

    def __init__(self, radius: np.ndarray):
        self.radius = np.asarray(radius, dtype=float)
        self.pairs: set[tuple[int, int]] = set()
        self.min_gap = math.inf

    def update(self, p0: np.ndarray, p1: np.ndarray) -> None:
        from scipy.spatial import cKDTree

        move = float(np.linalg.norm(p1 - p0, axis=1).max(initial=0.0))
        reach = 2.0 * float(self.radius.max()) + 2.0 * move + 5.0
        pairs = cKDTree(p1).query_pairs(reach, output_type="ndarray")
        if not len(pairs):
            return
        a, b = pairs[:, 0], pairs[:, 1]
        dp = p0[a] - p0[b]
        dv = (p1[a] - p1[b]) - dp
        vv = np.einsum("ij,ij->i", dv, dv)
        t = np.clip(-np.einsum("ij,ij->i", dp, dv) / np.maximum(vv, 1e-12), 0.0, 1.0)
        d = np.linalg.norm(dp + t[:, None] * dv, axis=1)
        gap = d - self.radius[a] - self.radius[b]
        self.min_gap = min(self.min_gap, float(gap.min()))
        for k in np.flatnonzero(gap < 0.0):
            self.pairs.add((int(a[k]), int(b[k])))


def straight_lengths(world) -> np.ndarray:  # noqa: ANN001
    return np.array([np.linalg.norm(np.subtract(a.goal, a.start)) for a in world.agents])


class _TimedRecorder:
    """A recorder whose every call's wall time is summed in ``wall``: the log's writing, taken
    out of the stepping loop's time (a peer writes no log) and kept apart."""

    def __init__(self, recorder):  # noqa: ANN001
        self.recorder = recorder
        self.wall = 0.0

    def __getattr__(self, name: str):  # noqa: ANN204
        call = getattr(self.recorder, name)

        def timed(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
            clock = time.perf_counter()
            try:
                return call(*args, **kwargs)
            finally:
                self.wall += time.perf_counter() - clock

        return timed


class _RunMeter:
    """Observer of a run (``io.runner.run_episode``): contacts from consecutive positions, the
    flown paths (every 5th sample) and the wall time of the stepping loop from the end of the
    first step (start-up and the first step excluded; the meter's own work subtracted), without
    the log's writing (``wall``) and with it (``wall_logged``)."""

    def __init__(self, radius: np.ndarray, keep_paths: bool, recorder: _TimedRecorder):
        self.meter = ContactMeter(radius)
        self.keep_paths = keep_paths
        self.recorder = recorder
        self.paths: list[np.ndarray] = []
        self.steps = 0
        self.wall = 0.0
        self.wall_logged = 0.0
        self.t_first = 0.0
        self._clock = 0.0
        self._logged = 0.0  # the log's writing so far, at _clock
        self._pos: np.ndarray | None = None

    def on_reset(self, result) -> None:  # noqa: ANN001
        self._pos = result.state.position.copy()
        if self.keep_paths:
            self.paths.append(self._pos)

    def on_step(self, result) -> None:  # noqa: ANN001
        now = time.perf_counter()
        self.steps += 1
        if self.steps == 1:
            self.t_first = result.state.t
        else:
            self.wall_logged += now - self._clock
            self.wall += now - self._clock - (self.recorder.wall - self._logged)
        pos = result.state.position.copy()
        self.meter.update(self._pos, pos)
        self._pos = pos
        if self.keep_paths and (self.steps % 5 == 0 or result.terminated or result.truncated):
            self.paths.append(pos)
        self._logged = self.recorder.wall
        self._clock = time.perf_counter()


def run_swarmplan(  # noqa: ANN201
    name: str, agents: int, seed: int, system: str, keep_paths: bool = False, comms: dict | None = None,
    separation: float | None = None,
):  # fmt: skip
    """One run of swarmplan (``system``: 'planner' or 'apf'), recording its MCAP log as the
    command line does, with the world's ``comms`` section ``comms`` and the agents'
    ``separation`` when given; (Row, paths (samples, N, 3) or None)."""
    from swarmplan.io.recording import McapRecorder
    from swarmplan.io.runner import run_episode
    from swarmplan.sim import Simulation

    world = scenario_world(name, agents, seed, comms=comms, separation=separation)
    sim = Simulation(world, planner="world" if system == "planner" else "none")
    with tempfile.TemporaryDirectory() as tmp:
        recorder = _TimedRecorder(McapRecorder(Path(tmp) / "run.mcap"))
        run = _RunMeter(sim.params.radius, keep_paths, recorder)
        run_episode(sim, seed, observers=[run], recorder=recorder)
    m = sim.metrics
    arrived = np.isfinite(m.arrival_time)
    straight = straight_lengths(world)[arrived]
    ratio = float(np.mean(m.path_length[arrived] / np.maximum(straight, 1e-9))) if arrived.any() else math.nan
    flown = sim.state.t - run.t_first
    row = Row(name, agents, system, seed, int(arrived.sum()), len(run.meter.pairs), run.meter.min_gap, ratio,
              float(np.nanmax(m.arrival_time)) if arrived.any() else math.nan, sim.state.t, run.wall,
              flown / run.wall if run.wall > 0 else math.nan, int(m.escapes.sum()),
              float(np.nanmean(m.arrival_time)) if arrived.any() else math.nan,
              flown / run.wall_logged if run.wall_logged > 0 else math.nan)  # fmt: skip
    return row, (np.array(run.paths) if keep_paths else None)

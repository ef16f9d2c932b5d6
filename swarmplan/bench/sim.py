"""Simulation throughput: simulated seconds per wall second on a generated swarm world, and
the wall time of every shipped world.

``python -m swarmplan.bench sim --agents 64 --movers 16 [--statics 24] [--sim-time 30]``
builds a 64-agent world with 16 moving and 24 static obstacles (seeded layout), runs it
for ``--sim-time`` simulated seconds (with the MCAP recorder unless ``--no-log``) and
prints sim-s per wall-s (the first step, where compiled kernels load, not timed; a run that
compiled a kernel later says so, and its target is not judged) and the mean step time;
configurations with a speed target (``TARGETS``: 512 agents + 64 movers, pure APF, recording
on: >= 25x) print their verdict. ``--worlds`` instead runs every world in
``worlds/`` (and its sub-folders) to its end and prints each one's wall time; ``--world PATH``
times that world file's stepping loop the same way (its own optimizer and end unless
``--optimizer``/``--sim-time`` say otherwise; fixed-wing worlds, recording on: >= 30x).

:func:`swarm_world` and :func:`swap_world` (an antipodal swap through a hub, full of escapes)
also generate the worlds of ``python -m swarmplan.bench scale``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np


def swarm_world(agents: int, movers: int, statics: int, seed: int = 0) -> dict[str, Any]:
    """A square field with agents crossing between opposite edges among random obstacles."""
    rng = np.random.default_rng(seed)
    size = 100.0 * max(2.0, np.sqrt(agents / 4.0))
    obstacles = []
    for k in range(statics):
        c = rng.uniform(0.2 * size, 0.8 * size, 2)
        if k % 3 == 0:
            obstacles.append({"id": f"s{k}", "shape": "sphere", "radius": 6.0, "position": [*c, 25.0]})
        elif k % 3 == 1:
            obstacles.append(
                {
                    "id": f"s{k}",
                    "shape": "box",
                    "size": [10.0, 10.0, 50.0],
                    "position": [*c, 25.0],
                    "rotation": [0, 0, float(rng.uniform(0, 90))],
                }
            )
        else:
            obstacles.append(
                {"id": f"s{k}", "shape": "cylinder", "radius": 5.0, "height": 50.0, "position": [*c, 25.0]}
            )
    for k in range(movers):
        c = rng.uniform(0.15 * size, 0.85 * size, 2)
        v = rng.normal(size=2)
        v = 4.0 * v / np.linalg.norm(v)
        obstacles.append(
            {
                "id": f"m{k}",
                "shape": "sphere",
                "radius": 4.0,
                "position": [*c, 25.0],
                "motion": {"type": "linear", "velocity": [*v, 0.0]},
            }
        )
    agent_list = []
    for i in range(agents):
        side = i % 4
        u = (i // 4 + 0.5) / max(1, int(np.ceil(agents / 4))) * size
        start, goal = {
            0: ([5.0, u, 20.0], [size - 5.0, size - u, 25.0]),
            1: ([size - 5.0, u, 25.0], [5.0, size - u, 20.0]),
            2: ([u, 5.0, 30.0], [size - u, size - 5.0, 30.0]),
            3: ([u, size - 5.0, 35.0], [size - u, 5.0, 35.0]),
        }[side]
        agent_list.append({"id": f"a{i}", "start": start, "goal": goal})
    return {
        "name": f"bench-{agents}a-{movers}m",
        "seed": seed,
        "bounds": {"min": [0, 0, 0], "max": [size, size, 60]},
        "sim": {"dt": 0.1, "max_time": 600, "goal_tolerance": 2.0},
        "obstacles": obstacles,
        "agent_defaults": {
            "radius": 1.0,
            "speed": {"min": 0, "max": 12, "cruise": 8},
            "max_accel": 4,
            "min_altitude": 5,
            "separation": [4, 4, 2],
        },
        "agents": agent_list,
        "planner": {
            "apf": {"influence": 20.0, "k_rep": 50.0, "quadratic_radius": 10.0},
            "escape": {"margin": 1.0, "fcl_margin": 0.3},
        },
    }


def swap_world(agents: int = 32, movers: int = 1, seed: int = 0, max_time: float = 120.0) -> dict[str, Any]:
    """Antipodal swap: ``agents`` on a circle fly to the opposite point through a central hub
    (a cylinder) while ``movers`` spheres cross the circle: a crowded world full of escapes."""
    rng = np.random.default_rng(seed)
    ring = max(40.0, 8.0 * agents / (2 * np.pi))  # about 8 m of arc per agent
    size = 2 * ring + 40.0
    c = np.array([size / 2, size / 2])
    obstacles: list[dict[str, Any]] = [
        {"id": "hub", "shape": "cylinder", "radius": 8.0, "height": 60.0, "position": [*c, 30.0]}
    ]
    for k in range(movers):
        a = rng.uniform(0, 2 * np.pi)
        p0 = c + 0.8 * ring * np.array([np.cos(a), np.sin(a)])
        v = 3.0 * (c - p0) / np.linalg.norm(c - p0)
        obstacles.append(
            {
                "id": f"m{k}",
                "shape": "sphere",
                "radius": 3.0,
                "position": [*p0, 20.0],
                "motion": {"type": "linear", "velocity": [*v, 0.0]},
            }
        )
    agent_list = []
    for i in range(agents):
        a = 2 * np.pi * i / agents
        u = np.array([np.cos(a), np.sin(a)])
        z = 20.0 + 2.0 * (i % 3)
        agent_list.append({"id": f"a{i}", "start": [*(c + ring * u), z], "goal": [*(c - ring * u), z]})
    return {
        "name": f"swap-{agents}a-{movers}m",
        "seed": seed,
        "bounds": {"min": [0, 0, 0], "max": [size, size, 40]},
        "sim": {"dt": 0.1, "max_time": max_time, "goal_tolerance": 2.0},
        "obstacles": obstacles,
        "agent_defaults": {
            "radius": 1.0,
            "speed": {"min": 0, "max": 10, "cruise": 7},
            "max_accel": 4,
            "min_altitude": 3,
            "separation": [3, 3, 2],
        },
        "agents": agent_list,
        "planner": {
            "apf": {"k_att": 1.0, "k_rep": 50.0, "influence": 8.0, "k_agent": 20.0, "quadratic_radius": 10.0},
            "escape": {"margin": 1.0, "fcl_margin": 0.3},
            "stuck": {"window": 2.0, "min_progress": 0.5},
            "optimizer": {"name": "rscdwoa", "population": 30, "iterations": 100},
        },
    }


TARGETS = {(512, 64, 24, "none", True): 25.0}
"""Real-time factor targets by (agents, movers, statics, optimizer, recording on): the run
prints its verdict beside its figure."""


FIXED_WING_TARGET = 30.0
"""Real-time factor target of a fixed-wing world file (``--world``, recording on)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--agents", type=int, default=64, help="agents of the generated swarm world")
    parser.add_argument("--movers", type=int, default=16, help="moving obstacles of the generated world")
    parser.add_argument("--statics", type=int, default=24, help="static obstacles of the generated world")
    parser.add_argument(
        "--sim-time",
        type=float,
        default=None,
        help="simulated seconds to run (unset: 30; with --world: its end)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the generated world and of the run")
    parser.add_argument(
        "--optimizer",
        default=None,
        help="planner optimizer ('none' = pure APF; unset: none, with --world its own)",
    )
    parser.add_argument(
        "--world", type=Path, default=None, help="time this world file instead of a generated one"
    )
    parser.add_argument("--no-log", action="store_true", help="do not record (measures the simulator alone)")
    parser.add_argument("--worlds", action="store_true", help="time every shipped world instead")


def _time_worlds() -> int:
    from swarmplan.io.runner import simulate
    from swarmplan.world import load_world

    root = Path(__file__).resolve().parents[2] / "worlds"
    print(f"{'world':45s} {'sim s':>7s} {'wall s':>7s} {'sim-s/s':>8s}  result")
    with tempfile.TemporaryDirectory() as tmp:
        for path in sorted(root.rglob("*.yaml")):
            world = load_world(path)
            start = time.perf_counter()
            summary = simulate(world, world.seed, Path(tmp) / f"{path.stem}.mcap")
            wall = time.perf_counter() - start
            verdict = (
                "success" if summary["success"] else f"{summary['arrived']}/{summary['agents_total']} arrived"
            )
            print(
                f"{str(path.relative_to(root)):45s} {summary['sim_time']:7.1f} {wall:7.2f} "
                f"{summary['sim_time'] / wall:8.1f}  {verdict}"
            )
    return 0


def verdict(rtf: float, target: float, compiled: bool) -> str:
    """A real-time factor against its target: met, NOT met, or (below it in a run that compiled
    kernels inside the timed loop) not judged."""
    if rtf >= target:
        return "met"
    return "not judged (compiling included)" if compiled else "NOT met"


def check_arguments(args: argparse.Namespace) -> list[str]:
    """Every bad argument, before any work."""
    problems = []
    if args.agents < 1:
        problems.append(f"--agents: must be >= 1, got {args.agents}")
    for name in ("movers", "statics", "seed"):
        if getattr(args, name) < 0:
            problems.append(f"--{name}: must be >= 0, got {getattr(args, name)}")
    if args.sim_time is not None and not args.sim_time > 0:
        problems.append(f"--sim-time: must be > 0, got {args.sim_time:g}")
    if args.world is not None and not args.world.is_file():
        problems.append(f"--world: no such file: {args.world}")
    return problems


def main(args: argparse.Namespace) -> int:
    if args.worlds:
        return _time_worlds()
    from swarmplan.io.compile_notice import CompileNotice
    from swarmplan.io.recording import McapRecorder
    from swarmplan.io.runner import RecordingObserver
    from swarmplan.planner import make_planner
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    if args.world is not None:
        from swarmplan.world import WorldError, load_world

        try:
            world = load_world(args.world)
        except WorldError as exc:
            more = f" (and {len(exc.problems) - 1} more)" if len(exc.problems) > 1 else ""
            print(f"--world: {args.world}: {exc.problems[0]}{more}", file=sys.stderr)
            return 2
        optimizer = world.planner_config.optimizer.name if args.optimizer is None else args.optimizer
        sim_time = world.max_time if args.sim_time is None else args.sim_time
    else:
        world = parse_world(swarm_world(args.agents, args.movers, args.statics, args.seed))
        optimizer = "none" if args.optimizer is None else args.optimizer
        sim_time = 30.0 if args.sim_time is None else args.sim_time
    with tempfile.TemporaryDirectory() as tmp:
        recorder = None if args.no_log else McapRecorder(Path(tmp) / "bench.mcap")
        log = RecordingObserver(recorder) if recorder is not None else None
        sim = Simulation(world, planner=make_planner(world, optimizer))
        first = sim.start(seed=args.seed)
        if log is not None:
            log.on_reset(first)
        # The first step is start-up (compiled kernels load at their first call): not timed.
        r = sim.step()
        if log is not None:
            log.on_step(r)
        t_first = sim.state.t
        # A kernel first met later (an escape's, a check's) compiles inside the timed loop when
        # numba's cache does not hold it yet (a fresh install, an edited kernel): watched, said.
        compiling = CompileNotice(write=lambda text: None).start()
        start, cpu0 = time.perf_counter(), time.process_time()
        steps = 0
        try:
            while not (r.terminated or r.truncated) and sim.state.t < sim_time - 1e-9:
                r = sim.step()
                if log is not None:
                    log.on_step(r)
                steps += 1
        finally:
            wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
            compiling.stop()
            if recorder is not None:
                recorder.write_summary(sim.summary())
                recorder.close()
        size = (Path(tmp) / "bench.mcap").stat().st_size if recorder is not None else 0
    s = sim.summary()
    print(
        f"world: {world.name}: {len(world.agents)} agents, {len(world.moving_obstacles)} moving and "
        f"{len(world.static_obstacles)} static obstacles, dt {world.dt} s, optimizer {optimizer}, "
        f"recording {'off' if args.no_log else 'on'}"
    )
    flown = sim.state.t - t_first
    print(f"simulated {flown:.1f} s in {steps} steps after the first, wall {wall:.2f} s")
    # CPU time beside wall time: on a loaded machine wall time counts other processes' turns.
    rtf = flown / max(wall, 1e-9)
    print(
        f"sim-seconds per wall-second: {rtf:.2f} "
        f"(per CPU-second: {flown / max(cpu, 1e-9):.2f}; CPU share {cpu / max(wall, 1e-9):.0%})"
        + (", compiling included: run it again for the stepping figure" if compiling.compiled else "")
    )
    print(
        f"mean step: {1000 * wall / max(steps, 1):.2f} ms wall, {1000 * cpu / max(steps, 1):.2f} ms CPU "
        f"({1e6 * cpu / max(steps, 1) / len(world.agents):.0f} "
        f"us CPU per agent-step)"
    )
    print(
        f"agents arrived {s['arrived']}/{s['agents_total']}, collisions {s['collisions']}"
        + (f", log {size / 1e6:.1f} MB" if size else "")
    )
    target = TARGETS.get((args.agents, args.movers, args.statics, optimizer, not args.no_log))
    if args.world is not None:
        fixed = any(a.model == "fixed_wing" for a in world.agents)
        target = FIXED_WING_TARGET if fixed and not args.no_log else None
    if target is not None:
        print(
            f"target: >= {target:g}x real time (wall, the first step excluded): {rtf:.1f}x "
            f"{verdict(rtf, target, compiling.compiled)}"
        )
    return 0

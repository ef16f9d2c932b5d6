"""The papers' scenarios (worlds/papers) run to arrival, pass the log audit (replay's recomputation
agrees with ``/summary``, as ``replay --strict`` asks; plus check_log.py where it exists) and
respect the kinematics, the turn limits of ``/summary`` included."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import audit

from swarmplan.io.runner import simulate
from swarmplan.world import load_world

ROOT = Path(__file__).resolve().parents[2]
WORLDS = sorted((ROOT / "worlds" / "papers").glob("*.yaml"))


def _states(log: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[list[str]]]:
    from mcap.reader import make_reader

    t, pos, vel, modes = [], [], [], []
    with open(log, "rb") as f:
        for _, _ch, msg in make_reader(f).iter_messages(topics=["/agents/state"]):
            d = json.loads(msg.data)
            t.append(d["t"])
            pos.append([a["position"] for a in d["agents"]])
            vel.append([a["velocity"] for a in d["agents"]])
            modes.append([a["mode"] for a in d["agents"]])
    return np.array(t), np.array(pos), np.array(vel), modes


@pytest.mark.parametrize("path", WORLDS, ids=[p.stem for p in WORLDS])
def test_paper_world(path: Path, tmp_path: Path) -> None:
    _check_paper_run(path, None, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("path", WORLDS, ids=[p.stem for p in WORLDS])
def test_paper_world_other_seeds(path: Path, seed: int, tmp_path: Path) -> None:
    """Not only the world's own seed: the plan, the fallbacks and the flight hold on others."""
    _check_paper_run(path, seed, tmp_path)


def _check_paper_run(path: Path, seed: int | None, tmp_path: Path) -> None:
    world = load_world(path)
    assert world.planner["mode"] == "global"
    log = tmp_path / "run.mcap"
    summary = simulate(world, world.seed if seed is None else seed, log)
    assert summary["success"], summary
    problems, _notes, stats = audit(log)
    assert problems == [], problems
    assert stats["arrived"] == stats["agents"] == len(world.agents) and stats["collisions"] == 0
    # A fixed wing's curvature within 1.05 / R_min, a multirotor's lateral acceleration within
    # 1.05 max_accel (as for every shipped world, tests/test_strict_all_worlds.py).
    assert [a["id"] for a in summary["agents"] if a.get("curvature_violation")] == []
    t, pos, vel, modes = _states(log)
    dt = world.dt
    for i, a in enumerate(world.agents):
        flying = np.array([m[i] not in ("arrived", "collided", "failed") for m in modes])
        flying[0] = True
        v = vel[flying, i]
        speed = np.linalg.norm(v, axis=1)
        assert speed.max() <= a.speed_max + 1e-3
        # The recorded velocity is the step's displacement over dt (semi-implicit Euler).
        steps = np.flatnonzero(flying[1:]) + 1
        assert np.allclose(pos[steps, i] - pos[steps - 1, i], vel[steps, i] * dt, atol=2e-5)
        if a.model == "multirotor":
            dv = np.linalg.norm(np.diff(v, axis=0), axis=1)
            # An emergency stop (logged, counted in the summary) is the one allowed excess: to rest.
            over = dv > a.max_accel * dt + 1e-3
            stops = summary["agents"][i]["emergency_stops"]
            assert over.sum() <= stops and np.all(speed[1:][over] == 0.0)
        else:
            assert speed[1:].min() >= a.speed_min - 1e-3
            assert np.abs(np.diff(speed)).max() <= a.max_accel * dt + 1e-3
            # The direction of flight (heading and flight-path angle together) turns by at most
            # V dt / R_min a step: the 3D curvature stays <= 1 / R_min.
            u = v / speed[:, None]
            turn = np.arccos(np.clip(np.einsum("ij,ij->i", u[1:], u[:-1]), -1.0, 1.0))
            turn_max = np.minimum(speed[:-1], speed[1:]) / a.min_turn_radius * dt
            assert np.all(turn <= turn_max + 1e-4), "turn radius below the minimum"
            gamma = np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1]))
            assert np.abs(gamma).max() <= a.max_climb_angle + 1e-4

"""Scenario runner for the dynamic-obstacle scenarios: build the world, run it through the real
``simulate`` path (pure APF, or the default refinement planner when ``swarmplan.planner`` exists),
then audit the log independently (replay's recomputation, plus ``check_log.py`` where it exists)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
from helpers import audit, describe_failure, make_world

AGENT_DEFAULTS = {
    "model": "multirotor",
    "radius": 1.0,
    "speed": {"min": 0, "max": 12, "cruise": 8},
    "max_accel": 4,
    "min_altitude": 5,
    "separation": [4, 4, 2],
}


def scenario_world(name: str, agents: list[dict], movers: list[dict], statics: list[dict] | None = None,
                   bounds=((0, 0, 0), (200, 120, 50)), max_time: float = 60.0) -> dict[str, Any]:  # fmt: skip
    return {
        "name": name,
        "seed": 0,
        "bounds": {"min": list(bounds[0]), "max": list(bounds[1])},
        "sim": {"dt": 0.1, "max_time": max_time, "goal_tolerance": 2.0},
        "obstacles": copy.deepcopy((statics or []) + movers),
        "agent_defaults": copy.deepcopy(AGENT_DEFAULTS),
        "agents": copy.deepcopy(agents),
        "planner": {
            "apf": {"k_att": 1.0, "k_rep": 50.0, "influence": 20.0, "k_agent": 20.0},
            "optimizer": {"name": "rscdwoa", "population": 20, "iterations": 30},
        },
        "log": {"foxglove": False},
    }


def planner_available() -> bool:
    try:
        import swarmplan.planner  # noqa: F401
    except ImportError:
        return False
    return True


DEFAULT = "default" if planner_available() else "apf"


@pytest.fixture
def run_scenario(tmp_path):
    """``run_scenario(raw, planner, seed)`` → (summary, log path), asserting success from both sides."""
    from swarmplan.io.runner import simulate

    def run(raw: dict, planner: str, seed: int = 0) -> tuple[dict, Path]:
        raw = copy.deepcopy(raw)
        if planner == "apf":
            raw["planner"]["optimizer"]["name"] = "none"
        world = make_world(raw)
        log = tmp_path / f"{raw['name']}-{planner}-{seed}.mcap"
        summary = simulate(world, seed, log)
        why = describe_failure(summary, log)
        problems, _notes, stats = audit(log)
        assert problems == [], f"audit of {log.name}: {problems}\n{why}"
        assert stats["arrived"] == stats["agents"] == len(raw["agents"]), why
        assert stats["collisions"] == 0, why
        assert summary["success"], why
        assert summary["collisions"] == 0 and summary["arrived"] == len(raw["agents"]), why
        return summary, log

    return run

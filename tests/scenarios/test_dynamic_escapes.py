"""Moving obstacles that force the planner to escape: the shipped worlds
``worlds/scenarios/parked_mover_corridor.yaml`` (a mover parks across the far mouth of the
corridor the agent is in) and ``closing_gap.yaml`` (two movers close the only gap of a wall
in front of two agents). On the bare potential field (without its guide round obstacles at
rest) pure APF stays trapped in both; the planner must detect the stuck agents and escape.
Both movers park for good, and the guide (the default) then goes round them as round static
bodies: every agent arrives, with or without the planner. (In ``closing_gap`` the bare field
itself slides one agent round the wall's end; the other stays trapped and must escape.)
Every run is audited from its log (replay, plus check_log where found).

These worlds found that escape planning ignored parked movers: it placed its sub-goal past
*static* blockers only, so the sub-goal landed just behind the mover (closing_gap seed 2:
east's first escape waypoint [65.8, 44.3, 15] right behind the closed doors at x = 62), and
its FCL validation and shortcutting swept static bodies only; 0/1 and 0/2 agents arrived
after 4 and 6 escapes. Escape planning now sees every mover at its predicted pose while the
escape is flown (``swarmplan/planner/movers.py``), and one escape per agent gets them out.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from helpers import audit, describe_failure, events_of, make_world, without_guide

from swarmplan.io.runner import simulate

ROOT = Path(__file__).resolve().parents[2]
WORLDS = ROOT / "worlds" / "scenarios"
# When the movers are in place (s): distance to their last waypoint over their speed.
PARKED_BY = {"parked_mover_corridor": 36 / 8, "closing_gap": 10 / 3}
NAMES = sorted(PARKED_BY)


def _raw(name: str) -> dict:
    return yaml.safe_load((WORLDS / f"{name}.yaml").read_text())


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Each world run once with its own seed and optimizer, on the bare field unless ``guide``:
    (name, optimizer, guide) -> (summary, log)."""
    cache: dict[str, tuple[dict, Path]] = {}

    def get(name: str, optimizer: str | None = None, guide: bool = False) -> tuple[dict, Path]:
        key = f"{name}-{optimizer or 'default'}-{'guided' if guide else 'bare'}"
        if key not in cache:
            raw = _raw(name)
            if optimizer is not None:
                raw["planner"]["optimizer"]["name"] = optimizer
            world = make_world(raw)
            log = tmp_path_factory.mktemp(key) / "run.mcap"
            cache[key] = (simulate(world if guide else without_guide(world), world.seed, log), log)
        return cache[key]

    return get


def _trapped(name: str, runs) -> list[str]:  # noqa: ANN001
    """The agents pure APF on the bare field does not get home in ``name``."""
    summary, _log = runs(name, "none")
    return [a["id"] for a in summary["agents"] if not a["arrived"]]


@pytest.mark.parametrize("name", NAMES)
def test_the_movers_trap_pure_apf(name, runs):
    summary, log = runs(name, "none")
    problems, _notes, stats = audit(log, allow_failure=True)
    assert problems == [], problems
    trapped = _trapped(name, runs)
    assert trapped and stats["collisions"] == 0, describe_failure(summary, log)
    stuck = events_of(log, "stuck")
    assert stuck and min(e["t"] for e in stuck) > PARKED_BY[name]


@pytest.mark.parametrize("name", NAMES)
def test_the_movers_make_the_planner_escape_without_collision(name, runs):
    summary, log = runs(name)
    why = describe_failure(summary, log)
    problems, _notes, stats = audit(log, allow_failure=True)
    assert problems == [], f"{problems}\n{why}"
    assert stats["collisions"] == 0 and summary["collisions"] == 0, why
    for aid in _trapped(name, runs):  # the agents the bare field leaves behind must escape
        stuck = [e for e in events_of(log, "stuck") if e["agent"] == aid]
        escapes = [e for e in events_of(log, "escape_start") if e["agent"] == aid]
        assert stuck and escapes, f"{aid}: stuck {len(stuck)}, escapes {len(escapes)}\n{why}"
        # stuck because of the parked movers, not before they arrived
        assert min(e["t"] for e in stuck) > PARKED_BY[name]
        row = next(a for a in summary["agents"] if a["id"] == aid)
        assert row["stuck_events"] == len(stuck) and row["escapes"] >= 1


@pytest.mark.parametrize("name", NAMES)
def test_the_planner_escapes_and_every_agent_arrives(name, runs):
    summary, log = runs(name)
    why = describe_failure(summary, log)
    problems, _notes, stats = audit(log)
    assert problems == [], f"{problems}\n{why}"
    assert stats["arrived"] == stats["agents"] == len(_raw(name)["agents"]) and summary["success"], why


@pytest.mark.parametrize("name", NAMES)
def test_the_guide_goes_round_the_parked_movers(name, runs):
    """With the guide (the default) every agent arrives and none is ever stuck, so no escape
    starts: the default planner flies pure APF's steps (``none`` is not flown again)."""
    summary, log = runs(name, None, guide=True)
    why = describe_failure(summary, log)
    problems, _notes, stats = audit(log)
    assert problems == [], f"{problems}\n{why}"
    assert stats["arrived"] == stats["agents"] and stats["collisions"] == 0 and summary["success"], why
    assert [a["stuck_events"] for a in summary["agents"]] == [0] * len(summary["agents"]), why
    assert sum(a["escapes"] for a in summary["agents"]) == 0, why


def test_the_corridor_with_a_static_plug_is_solved_by_one_escape(tmp_path):
    """Control: the same pocket with the plug static from the start."""
    raw = _raw("parked_mover_corridor")
    plug = next(o for o in raw["obstacles"] if o["id"] == "plug")
    plug["position"] = copy.deepcopy(plug["motion"]["waypoints"][-1])
    del plug["motion"]
    world = make_world(raw)
    log = tmp_path / "static.mcap"
    summary = simulate(without_guide(world), world.seed, log)
    why = describe_failure(summary, log)
    problems, _notes, stats = audit(log)
    assert problems == [], f"{problems}\n{why}"
    assert summary["success"] and stats["collisions"] == 0, why
    assert len(events_of(log, "escape_start")) >= 1

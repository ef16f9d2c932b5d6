"""``planner.apf.guide``: the world key that turns the field's guide round static obstacles
on (the default) or off (the bare potential field), its command-line override ``--no-guide``,
and what it changes: on the trap with the goal behind a block, pure APF arrives guided and
stays in front of the block on the bare field."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import base_world, make_world, read_log

from swarmplan.cli.run import main as run_main
from swarmplan.io.runner import apply_overrides
from swarmplan.sim import Simulation
from swarmplan.world import WorldError, load_world

ROOT = Path(__file__).resolve().parents[1]
BLOCK = ROOT / "worlds" / "traps" / "goal_beside_obstacle.yaml"
WALL = {"id": "wall", "shape": "box", "size": [4, 60, 50], "position": [50, 50, 25]}


def with_apf(**apf) -> dict:
    raw = base_world(obstacles=[WALL])
    raw["planner"] = {"apf": apf}
    return raw


def test_the_guide_is_on_by_default():
    world = make_world(with_apf())
    assert world.planner_config.apf.guide is True
    assert world.planner["apf"]["guide"] is True  # recorded in the /world message
    assert Simulation(world).guide is not None


@pytest.mark.parametrize("value", [True, False])
def test_the_key_is_parsed(value):
    world = make_world(with_apf(guide=value))
    assert world.planner_config.apf.guide is value
    assert world.to_message(0)["planner"]["apf"]["guide"] is value
    assert (Simulation(world).guide is not None) is value


@pytest.mark.parametrize("value", ["no", 0, 1, [True]])
def test_a_wrong_type_is_one_clear_problem(value):
    with pytest.raises(WorldError) as exc:
        make_world(with_apf(guide=value))
    assert exc.value.problems == [f"planner.apf.guide: expected true or false, got {value!r}"]


def test_the_other_apf_keys_are_still_numbers():
    with pytest.raises(WorldError) as exc:
        make_world(with_apf(k_att=True, guide=False))
    assert exc.value.problems == ["planner.apf.k_att: expected a number, got boolean True"]


def test_the_override_turns_it_off_and_on_and_keeps_the_rest():
    world = make_world(with_apf(k_rep=30.0))
    off = apply_overrides(world, None, None, guide=False)
    assert off.planner_config.apf.guide is False and off.planner_config.apf.k_rep == 30.0
    assert apply_overrides(off, None, None, guide=True).planner_config.apf.guide is True
    assert apply_overrides(off, "none", 5.0).planner_config.apf.guide is False  # None keeps it
    assert world.planner_config.apf.guide is True  # the original is left as it was


def test_the_trap_worlds_fly_the_bare_field():
    for path in sorted((ROOT / "worlds" / "traps").glob("*.yaml")):
        assert load_world(path).planner_config.apf.guide is False, path.name


def test_the_bare_field_is_trapped_where_the_guided_one_arrives(tmp_path):
    """The goal 5 m behind a 40 m wide block, pure APF, 20 s, flown from the command line on the
    world with the guide on: guided, the agent arrives (at 14.6 s, exit 0); ``--no-guide`` flies
    the bare field (exit 1: trapped), where it stays in front of the block (x < 52, the face)."""
    raw = BLOCK.read_text(encoding="utf-8").replace(", guide: false", "")
    guided = tmp_path / "guided.yaml"
    guided.write_text(raw, encoding="utf-8")
    common = ["--optimizer", "none", "--max-time", "20", "--quiet"]
    assert run_main([str(guided), "--out", str(tmp_path / "a.mcap"), *common]) == 0
    assert run_main([str(guided), "--out", str(tmp_path / "b.mcap"), "--no-guide", *common]) == 1
    guided_log, bare_log = read_log(tmp_path / "a.mcap"), read_log(tmp_path / "b.mcap")
    assert guided_log["/world"][0][1]["planner"]["apf"]["guide"] is True
    assert bare_log["/world"][0][1]["planner"]["apf"]["guide"] is False
    guided, bare = guided_log["/summary"][-1][1], bare_log["/summary"][-1][1]
    assert guided["success"] and guided["collisions"] == 0
    assert not bare["success"] and bare["arrived"] == 0 and bare["collisions"] == 0
    assert bare["agents"][0]["escapes"] == 0 and bare["agents"][0]["stuck_events"] > 0
    state = bare_log["/agents/state"][-1][1]
    assert state["agents"][0]["position"][0] < 52.0


def test_the_key_is_documented():
    doc = (ROOT / "docs" / "world-format.md").read_text(encoding="utf-8")
    assert "| `planner.apf.guide` | boolean | true |" in doc
    assert "--no-guide" in (ROOT / "README.md").read_text(encoding="utf-8")

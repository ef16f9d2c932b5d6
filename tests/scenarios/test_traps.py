"""Trap worlds (``worlds/traps``): local minima of the bare potential field (each sets
``planner.apf.guide: false``), which the refinement planner escapes; with its guide round
static obstacles on (``swarmplan.flight.guide``) the field gets out of every one by itself.

Each world is run through the real ``simulate`` path and the log is audited independently
with ``check_log.py``. The default suite runs each trap with ``none`` on the bare field
(must fail), with ``none`` guided (every agent arrives, no agent is ever stuck, so no escape
is planned and the refinement planner flies the same steps: one trap flown guided with ``pso``
shows it bit for bit), and each trapping world with two optimizers over two seeds on the bare
field (every agent arrives after at least one escape, zero collisions, log audit clean); the
slow suite runs every registered optimizer over ten seeds on the bare field.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import audit, log_positions

from swarmplan import optimizers
from swarmplan.io.runner import apply_overrides, simulate
from swarmplan.world import load_world

TRAPS = Path(__file__).resolve().parents[2] / "worlds" / "traps"
WORLDS = sorted(p.stem for p in TRAPS.glob("*.yaml"))
FAST_OPTIMIZERS = ["de", "pso"]
#: Traps the potential field now gets out of by itself: in narrow_gap_swap the two agents meet
#: head-on in the gap and pass over and under each other (the agent term's vertical part of the
#: way past); every agent arrives with pure APF, so escapes are not needed there.
SOLVED_BY_FIELD = {"narrow_gap_swap"}
TRAPPING = [w for w in WORLDS if w not in SOLVED_BY_FIELD]


def run_trap(name: str, optimizer: str, seed: int, tmp_path: Path, guide: bool = False) -> tuple[dict, Path]:
    """One run of a trap, on the bare field (the trap) unless ``guide`` (``planner.apf.guide``)."""
    world = load_world(TRAPS / f"{name}.yaml", optimizers.available())
    world = apply_overrides(world, optimizer, None, guide)
    log = tmp_path / f"{name}-{optimizer}-{seed}-{'guided' if guide else 'bare'}.mcap"
    return simulate(world, seed, log), log


def test_there_are_four_traps():
    assert set(WORLDS) == {"u_pocket", "concave_wall", "goal_beside_obstacle", "narrow_gap_swap"}


def _never_stuck(summary: dict) -> None:
    """Every agent home, no contact, and none ever stuck: the refinement planner, whose escapes
    start only from a stuck agent, flies these steps whatever its optimizer and seed."""
    assert summary["success"] and summary["collisions"] == 0
    assert [a["stuck_events"] for a in summary["agents"]] == [0] * len(summary["agents"])
    assert sum(a["escapes"] for a in summary["agents"]) == 0


@pytest.mark.parametrize("name", sorted(SOLVED_BY_FIELD))
def test_pure_apf_gets_out_by_itself(name, tmp_path):
    summary, log = run_trap(name, "none", 0, tmp_path)
    _never_stuck(summary)
    problems, _, _ = audit(log)
    assert problems == []


@pytest.mark.parametrize("name", WORLDS)
def test_the_guided_field_gets_out_of_every_trap_by_itself(name, tmp_path):
    """Pure APF with the guide round static obstacles: every agent arrives, none is ever stuck,
    so the default planner (refinement with the guide) needs no escape there either."""
    summary, log = run_trap(name, "none", 0, tmp_path, guide=True)
    _never_stuck(summary)
    problems, _, _ = audit(log)
    assert problems == []


def test_guided_refinement_flies_the_guided_field_where_nothing_is_stuck(tmp_path):
    """The default planner with the guide, another seed: the same steps, bit for bit, as pure
    APF with the guide (the trap the bare field holds longest)."""
    _, none_log = run_trap("u_pocket", "none", 0, tmp_path, guide=True)
    summary, log = run_trap("u_pocket", "pso", 1, tmp_path, guide=True)
    _never_stuck(summary)
    ids, t, p = log_positions(log)
    ids0, t0, p0 = log_positions(none_log)
    assert ids == ids0 and t.tobytes() == t0.tobytes() and p.tobytes() == p0.tobytes()


@pytest.mark.parametrize("name", TRAPPING)
def test_pure_apf_is_trapped(name, tmp_path):
    summary, log = run_trap(name, "none", 0, tmp_path)
    assert not summary["success"]
    assert summary["arrived"] < summary["agents_total"]
    assert any(a["stuck_events"] > 0 for a in summary["agents"])
    problems, _, _ = audit(log, allow_failure=True)
    assert problems == []  # trapped, but safe and a well-formed log


def _assert_escaped(name: str, optimizer: str, seed: int, tmp_path: Path) -> None:
    summary, log = run_trap(name, optimizer, seed, tmp_path)
    detail = [(a["id"], a["final_mode"], a["collisions"]) for a in summary["agents"]]
    assert summary["success"], f"{name} {optimizer} seed {seed}: {detail}"
    assert summary["collisions"] == 0
    if name not in SOLVED_BY_FIELD:
        assert sum(a["escapes"] for a in summary["agents"]) >= 1
    problems, _, _ = audit(log)
    assert problems == [], problems


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("optimizer", FAST_OPTIMIZERS)
@pytest.mark.parametrize("name", TRAPPING)
def test_refinement_escapes(name, optimizer, seed, tmp_path):
    """Each trap the bare field holds (the one it gets out of by itself, never stuck, plans no
    escape: ``test_pure_apf_gets_out_by_itself``)."""
    _assert_escaped(name, optimizer, seed, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize("optimizer", optimizers.available())
@pytest.mark.parametrize("name", WORLDS)
def test_refinement_escapes_every_optimizer(name, optimizer, seed, tmp_path):
    _assert_escaped(name, optimizer, seed, tmp_path)

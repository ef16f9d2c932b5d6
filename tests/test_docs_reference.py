"""docs/world-format.md and docs/log-format.md stay in step with the code.

Every key the world parser accepts (recorded from its own key checks while it parses a world
that uses every section, shape and motion type) is in a table of docs/world-format.md, and
every key of those tables is accepted; the complete example is a valid world. Every key of a
run's ``/summary`` (a world with threats, so the exposure keys too) is in docs/log-format.md,
and so is every topic a run's log contains (Foxglove channels on).
The README and docs point only inside the repository.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
import yaml

sys.path.insert(0, str(Path(__file__).parent))

from helpers import base_world, make_world, run_to_end  # noqa: E402

import swarmplan.world.tracker_config as tracker_config  # noqa: E402
from swarmplan.world.checker import Checker  # noqa: E402
from swarmplan.world.planner_config import _KEYS as GLOBAL_KEYS  # noqa: E402
from swarmplan.world.planner_config import COST_WEIGHTS, ESCAPE_DEFAULTS  # noqa: E402
from swarmplan.world.schema import parse_world  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORLD_DOC = ROOT / "docs" / "world-format.md"
LOG_DOC = ROOT / "docs" / "log-format.md"

MOTIONS = [
    {"type": "linear", "velocity": [1, 0, 0]},
    {"type": "waypoints", "waypoints": [[80, 80, 40]], "speed": 2, "loop": True},
    {"type": "circle", "center": [80, 20, 40], "radius": 5, "angular_speed": 0.2},
]
SHAPES = [
    {"shape": "sphere", "radius": 2},
    {"shape": "box", "size": [2, 2, 2]},
    {"shape": "cylinder", "radius": 1, "height": 3},
    {"shape": "capsule", "radius": 1, "height": 3},
    {"shape": "ellipsoid", "semi_axes": [2, 1.5, 1]},
    {"shape": "mesh", "file": "meshes/hangar.stl", "scale": 0.05},
]


def everything_world() -> dict:
    """A valid world that uses every section, every shape and every motion type."""
    obstacles = [
        {"id": f"o{k}", "position": [20 + 10 * k, 20, 10], "rotation": [0, 0, 10], **shape}
        for k, shape in enumerate(SHAPES)
    ]
    obstacles += [
        {"id": f"m{k}", "shape": "sphere", "radius": 1, "position": [20 + 10 * k, 80, 40], "motion": m}
        for k, m in enumerate(MOTIONS)
    ]
    params = {
        "model": "multirotor",
        "radius": 1,
        "speed": {"min": 0, "max": 12, "cruise": 8},
        "max_accel": 4,
        "min_turn_radius": 20,
        "max_climb_angle": 45,
        "min_altitude": 5,
        "separation": [4, 4, 2],
    }
    threat = {"kind": "radar", "position": [50, 50, 0], "r_min": 5, "r_max": 20, "weight": 1, "avoid": True}
    planner = {
        "mode": "reactive",
        "apf": {"k_att": 1},
        "stuck": {"window": 3},
        "smoothing": {"enabled": True},
        "escape": {"waypoints": 4},
        "global": {"cost": "mcfo"},
        "optimizer": {"name": "woa", "population": 10, "iterations": 5, "params": {}},
    }
    return base_world(
        terrain={"peaks": [{"center": [50, 50], "height": 5, "spread": [10, 10]}], "clearance": 2},
        obstacles=obstacles,
        threats=[threat],
        agent_defaults=params,
        agents=[{"id": "a", "start": [10, 50, 30], "goal": [90, 50, 30], **params}],
        planner=planner,
        log={"path": "logs/x.mcap", "foxglove": False, "flush_interval": 1.0},
        tracker={"mass": 1.5, "position": {"kp": 6}, "attitude": {"kp": 12}, "rate": {"kp": 40}},
        origin={"lat": 47.4, "lon": 8.5, "alt": 400},
        comms={"rate": 20, "delay": {"mean": 0.1, "jitter": 0.02}, "loss": 0.1, "range": 50},
        sensing={"range": 15},
    )  # fmt: skip


def _norm(path: str) -> str:
    return re.sub(r"\[\d+\]", "[i]", path)


def accepted_keys(monkeypatch: pytest.MonkeyPatch) -> set[str]:
    """Every key path the parser accepts, recorded from its own key checks."""
    seen: set[str] = set()
    original_keys = Checker.keys
    original_unknown = tracker_config._unknown

    def keys(self, node, path, allowed, required=()):  # noqa: ANN001, ANN202
        seen.update(f"{_norm(path)}.{k}" if path else str(k) for k in allowed)
        return original_keys(self, node, path, allowed, required)

    def unknown(node, allowed, path, problems):  # noqa: ANN001, ANN202
        seen.update(f"{_norm(path)}.{k}" for k in allowed)
        return original_unknown(node, allowed, path, problems)

    monkeypatch.setattr(Checker, "keys", keys)
    monkeypatch.setattr(tracker_config, "_unknown", unknown)
    parse_world(everything_world(), base_dir=ROOT / "worlds")
    # planner.escape and planner.global are checked against these tables (planner_config.py)
    seen.update(f"planner.escape.{k}" for k in ESCAPE_DEFAULTS)
    seen.update(f"planner.global.{k}" for k in GLOBAL_KEYS)
    seen.update(f"planner.global.weights.{k}" for w in COST_WEIGHTS.values() for k in w)
    return seen


def documented_keys(doc: Path) -> set[str]:
    """The backticked keys in the first cell of every table row."""
    keys: set[str] = set()
    for line in doc.read_text(encoding="utf-8").splitlines():
        if line.startswith("| `"):
            first = line.split(" | ")[0]
            keys.update(re.findall(r"`([^`]+)`", first))
    return keys


def test_the_everything_world_uses_every_shape_and_motion_type():
    from swarmplan.world.model import MOTIONS as ALL_MOTIONS
    from swarmplan.world.model import SHAPES as ALL_SHAPES

    assert sorted(s["shape"] for s in SHAPES) == sorted(ALL_SHAPES)
    assert sorted(m["type"] for m in MOTIONS) == sorted(ALL_MOTIONS)


def test_every_key_the_parser_accepts_is_documented(monkeypatch):
    accepted = accepted_keys(monkeypatch)
    sections = {k for k in accepted if any(o.startswith((k + ".", k + "[")) for o in accepted)}
    missing = sorted(accepted - sections - documented_keys(WORLD_DOC))
    assert missing == [], f"keys the parser accepts but docs/world-format.md does not list: {missing}"
    assert {"threats[i].avoid", "tracker.position.kp", "planner.global.weights.w1"} <= accepted


def test_every_documented_key_is_accepted(monkeypatch):
    unknown = sorted(documented_keys(WORLD_DOC) - accepted_keys(monkeypatch))
    assert unknown == [], f"docs/world-format.md lists keys the parser rejects: {unknown}"


def test_the_complete_example_is_a_valid_world():
    text = WORLD_DOC.read_text(encoding="utf-8")
    example = text.split("## A complete example", 1)[1].split("```yaml", 1)[1].split("```", 1)[0]
    world = parse_world(yaml.safe_load(example), base_dir=ROOT / "worlds")
    assert world.name == "crossing-traffic" and len(world.agents) == 2 and world.threats[0].avoid


def test_every_summary_key_is_documented():
    threat = {"kind": "radar", "position": [50, 50, 20], "r_min": 5, "r_max": 20}
    world = make_world(base_world(threats=[threat], sim={"dt": 0.1, "max_time": 3, "goal_tolerance": 2}))
    _sim, summary, _ = run_to_end(world)
    text = LOG_DOC.read_text(encoding="utf-8")
    keys = set(summary) | {f"agents[].{k}" for k in summary["agents"][0]}
    missing = sorted(k for k in keys if f"`{k.removeprefix('agents[].')}`" not in text)
    assert missing == [], f"/summary keys docs/log-format.md does not describe: {missing}"


def test_readme_and_docs_point_only_inside_the_repository():
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    outside = [
        f"{f.name}:{n}: {line.strip()}"
        for f in files
        for n, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1)
        if re.search(r"(^|[\s`(./])shared/(spec|tools|notes|seeds)", line)
    ]
    assert outside == []
    for ref in ("docs/world-format.md", "docs/log-format.md"):
        assert ref in (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_replay_example_figures_are_those_of_the_code():
    """docs/replay.md's paper 001 example: arrivals, collisions and simulated time as run now."""
    from swarmplan.world import load_world

    text = " ".join((ROOT / "docs" / "replay.md").read_text(encoding="utf-8").split())
    found = re.search(r"run (\d+)/(\d+) fixed wings arrived, (\d+) collisions, ([\d.]+) s simulated", text)
    assert found, "the example's figures are missing from docs/replay.md"
    world = load_world(ROOT / "worlds" / "papers" / "rscdwoa_multi_uav.yaml")
    from helpers import default_planner

    _sim, summary, _ = run_to_end(world, planner=default_planner(world))
    assert (summary["arrived"], summary["agents_total"], summary["collisions"]) == tuple(
        int(found.group(k)) for k in (1, 2, 3)
    )
    assert f"{summary['sim_time']:.1f}" == found.group(4)


def documented_topics() -> set[str]:
    """The topics named in the first cell of a table row of docs/log-format.md."""
    return {k for k in documented_keys(LOG_DOC) if k.startswith("/")}


def test_every_topic_a_log_contains_is_documented(tmp_path):
    """Short runs of the quickstart world (movers, events, Foxglove channels on) and of the
    concave wall (an escape, on the bare field: the guide leads out of the trap without one):
    every topic of their logs is a row of a channel table in docs/log-format.md."""
    from helpers import default_planner, read_log, without_guide

    topics: set[str] = set()
    for name, max_time in (("quickstart.yaml", 12), ("traps/concave_wall.yaml", 30)):
        raw = yaml.safe_load((ROOT / "worlds" / name).read_text(encoding="utf-8"))
        raw["sim"]["max_time"] = max_time
        world = make_world(raw, base_dir=(ROOT / "worlds" / name).parent)
        log = tmp_path / f"{len(topics)}.mcap"
        world = without_guide(world)
        run_to_end(world, log_path=log, planner=default_planner(world), foxglove=True)
        topics |= set(read_log(log))
    expected = {"/agents/speed", "/events/log", "/scene/paths/overview", "/tf", "/optimizer"}
    expected.add("/obstacles/state")
    assert expected <= topics, f"the run no longer writes {sorted(expected - topics)}"
    missing = sorted(topics - documented_topics())
    assert missing == [], f"topics a log contains that docs/log-format.md does not document: {missing}"

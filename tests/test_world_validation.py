"""World validation: every kind of problem, each named by its path, all reported at once."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from helpers import base_world, make_world

from swarmplan.world import WorldError, load_world

WORLDS = Path(__file__).resolve().parents[1] / "worlds"

KNOWN = [
    "afsa",
    "ba",
    "cfo",
    "de",
    "ga",
    "iafsa",
    "iba_abc",
    "iba_gauss",
    "mcfo",
    "pso",
    "random",
    "rscdwoa",
    "woa",
]


def problems_of(raw, base_dir=".") -> list[str]:
    with pytest.raises(WorldError) as exc:
        make_world(raw, base_dir)
    assert exc.value.problems, "a WorldError must list its problems"
    # The exception text lists them all too (what a user sees).
    for p in exc.value.problems:
        assert p in str(exc.value)
    return exc.value.problems


def has(problems: list[str], path: str, *fragments: str) -> bool:
    return any(p.startswith(f"{path}:") and all(f in p for f in fragments) for p in problems)


def assert_has(problems, path, *fragments):
    assert has(problems, path, *fragments), f"expected '{path}: ...{' ... '.join(fragments)}' in {problems}"


def test_base_world_is_valid():
    w = make_world(base_world())
    assert w.name == "t" and len(w.agents) == 1


# ----------------------------------------------------------------------------- missing / types


def test_missing_required_top_level_keys():
    raw = base_world()
    for k in ("name", "bounds", "agents"):
        del raw[k]
    probs = problems_of(raw)
    for k in ("name", "bounds", "agents"):
        assert_has(probs, k, "required key is missing")


@pytest.mark.parametrize(
    "where, key",
    [
        ("agents", "id"),
        ("agents", "start"),
        ("agents", "goal"),
        ("obstacles", "id"),
        ("obstacles", "position"),
    ],
)
def test_missing_required_nested_keys(where, key):
    raw = base_world(obstacles=[{"id": "rock", "shape": "sphere", "radius": 2, "position": [50, 80, 20]}])
    del raw[where][0][key]
    assert_has(problems_of(raw), f"{where}[0].{key}", "required key is missing")


def test_missing_bounds_max_and_shape_specific_keys():
    raw = base_world(
        bounds={"min": [0, 0, 0]},
        obstacles=[
            {"id": "s", "shape": "sphere", "position": [50, 80, 20]},
            {"id": "c", "shape": "cylinder", "radius": 2, "position": [50, 80, 20]},
            {"id": "m", "shape": "circle", "position": [50, 80, 20]},
        ],
    )
    probs = problems_of(raw)
    assert_has(probs, "bounds.max", "required key is missing")
    assert_has(probs, "obstacles[0].radius", "required key is missing")
    assert_has(probs, "obstacles[1].height", "required key is missing")
    assert_has(probs, "obstacles[2].shape", "'circle'", "sphere", "box", "cylinder", "capsule", "mesh")


@pytest.mark.parametrize(
    "patch, path, fragment",
    [
        ({"name": 5}, "name", "expected a non-empty string"),
        ({"seed": "seven"}, "seed", "whole number"),
        ({"seed": -1}, "seed", "whole number"),
        ({"bounds": [0, 100]}, "bounds", "expected a mapping"),
        ({"bounds": {"min": [0, 0], "max": [100, 100, 50]}}, "bounds.min", "list of 3 numbers"),
        ({"sim": {"dt": "fast"}}, "sim.dt", "expected a number"),
        ({"sim": {"max_time": True}}, "sim.max_time", "expected a number"),
        ({"agents": {"id": "a"}}, "agents", "expected a list"),
        ({"agents": []}, "agents", "at least one"),
        ({"obstacles": [{"id": "r", "shape": "sphere", "radius": "big", "position": [50, 80, 20]}]},
         "obstacles[0].radius", "expected a number"),
        ({"obstacles": [{"id": "r", "shape": "box", "size": [1, 2, "x"], "position": [50, 80, 20]}]},
         "obstacles[0].size", "list of 3 numbers"),
        ({"agent_defaults": {"model": "helicopter"}}, "agent_defaults.model", "multirotor"),
        ({"log": {"foxglove": "yes"}}, "log.foxglove", "true or false"),
    ],
)  # fmt: skip
def test_wrong_types(patch, path, fragment):
    raw = base_world()
    raw.update(copy.deepcopy(patch))
    assert_has(problems_of(raw), path, fragment)


# ----------------------------------------------------------------------------- values


@pytest.mark.parametrize(
    "obstacle, path",
    [
        ({"id": "r", "shape": "sphere", "radius": -5, "position": [50, 80, 20]}, "obstacles[0].radius"),
        ({"id": "r", "shape": "sphere", "radius": 0, "position": [50, 80, 20]}, "obstacles[0].radius"),
        ({"id": "r", "shape": "box", "size": [1, -2, 3], "position": [50, 80, 20]}, "obstacles[0].size"),
        ({"id": "r", "shape": "cylinder", "radius": 1, "height": -4, "position": [50, 80, 20]},
         "obstacles[0].height"),
        ({"id": "r", "shape": "capsule", "radius": -1, "height": 4, "position": [50, 80, 20]},
         "obstacles[0].radius"),
    ],
)  # fmt: skip
def test_negative_sizes(obstacle, path):
    assert_has(problems_of(base_world(obstacles=[obstacle])), path, "must be > 0")


def test_negative_agent_sizes_and_times():
    raw = base_world(sim={"dt": -0.1, "max_time": 0, "goal_tolerance": -1})
    raw["agents"][0].update({"radius": -1, "max_accel": 0, "separation": [1, -1, 1]})
    probs = problems_of(raw)
    for path in ("sim.dt", "sim.max_time", "sim.goal_tolerance", "agents[0].radius", "agents[0].max_accel"):
        assert_has(probs, path, "> 0")
    assert_has(probs, "agents[0].separation", ">= 0")


def test_min_above_max():
    raw = base_world(bounds={"min": [0, 0, 60], "max": [100, 100, 50]})
    assert_has(problems_of(raw), "bounds", "min is not below max", "z")
    raw = base_world()
    raw["agents"][0]["speed"] = {"min": 10, "max": 5}
    assert_has(problems_of(raw), "agents[0].speed", "min (10) is above max (5)")
    raw = base_world(agent_defaults={"speed": {"min": 20, "max": 5, "cruise": 6}})
    assert_has(problems_of(raw), "agent_defaults.speed", "min (20) is above max (5)")
    raw = base_world(threats=[{"kind": "radar", "position": [50, 50, 0], "r_min": 300, "r_max": 20}])
    assert_has(problems_of(raw), "threats[0]", "r_min", "r_max")


def test_cruise_outside_speed_band_and_fixed_wing_floor():
    raw = base_world()
    raw["agents"][0]["speed"] = {"min": 2, "max": 10, "cruise": 12}
    assert_has(problems_of(raw), "agents[0].speed.cruise", "between")
    raw = base_world()
    raw["agents"][0].update({"model": "fixed_wing", "speed": {"min": 0, "max": 20, "cruise": 10}})
    assert_has(problems_of(raw), "agents[0].speed.min", "fixed_wing")


@pytest.mark.parametrize(
    "mutate, path, suggestion",
    [
        (lambda r: r["agents"][0].update(sped={"max": 3}), "agents[0].sped", "speed"),
        (lambda r: r["agents"][0].update(speed={"mn": 1}), "agents[0].speed.mn", "min"),
        (lambda r: r.update(obstacle=[]), "obstacles", None),
        (lambda r: r.update(bounds={"min": [0, 0, 0], "mx": [1, 1, 1]}), "bounds.mx", "max"),
        (lambda r: r["sim"].update(time_step=0.1), "sim.time_step", None),
        (lambda r: r.update(planner={"apf": {"k_attr": 1.0}}), "planner.apf.k_attr", "k_att"),
        (lambda r: r.update(obstacles=[{"id": "o", "shape": "sphere", "radius": 1, "position": [50, 80, 20],
                                        "rotaton": [0, 0, 0]}]), "obstacles[0].rotaton", "rotation"),
    ],
)  # fmt: skip
def test_unknown_key_names_path_and_suggests(mutate, path, suggestion):
    raw = base_world()
    mutate(raw)
    probs = problems_of(raw)
    if path == "obstacles":  # a misspelt top-level key: reported at the top level
        assert any("obstacle: unknown key" in p and "did you mean 'obstacles'?" in p for p in probs), probs
        return
    if suggestion is None:
        assert_has(probs, path, "unknown key")
    else:
        assert_has(probs, path, "unknown key", f"(did you mean '{suggestion}'?)")


# ----------------------------------------------------------------------------- placement


def test_agent_start_inside_an_obstacle_names_it():
    raw = base_world(
        obstacles=[{"id": "tower", "shape": "cylinder", "radius": 5, "height": 40, "position": [50, 50, 20]}],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
            {"id": "b", "start": [50, 52, 20], "goal": [90, 80, 20]},
        ],
    )
    probs = problems_of(raw)
    assert any(p.startswith("agents[1].start: inside obstacle 'tower'") for p in probs), probs
    assert not any(p.startswith("agents[0]") for p in probs)


def test_agent_goal_inside_or_touching_an_obstacle():
    raw = base_world(
        obstacles=[
            {
                "id": "block",
                "shape": "box",
                "size": [10, 10, 10],
                "position": [80, 50, 20],
                "rotation": [0, 0, 45],
            },
            {"id": "ball", "shape": "sphere", "radius": 3, "position": [50, 20, 20]},
        ],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [80, 50, 20]},
            {"id": "b", "start": [10, 20, 20], "goal": [50, 23.5, 20]},  # 0.5 m from the surface, radius 1
        ],
    )
    probs = problems_of(raw)
    assert any(p.startswith("agents[0].goal: inside obstacle 'block'") for p in probs), probs
    assert any(p.startswith("agents[1].goal: touching obstacle 'ball'") for p in probs), probs


def test_agent_start_in_a_moving_obstacles_initial_position():
    raw = base_world(
        obstacles=[
            {
                "id": "drone",
                "shape": "sphere",
                "radius": 4,
                "position": [10, 52, 20],
                "motion": {"type": "linear", "velocity": [0, 5, 0]},
            }
        ]
    )
    assert_has(problems_of(raw), "agents[0].start", "obstacle 'drone'")


@pytest.mark.parametrize(
    "key, point", [("start", [-5, 50, 20]), ("goal", [90, 50, 51]), ("goal", [101, 0, 0])]
)
def test_agent_outside_bounds(key, point):
    raw = base_world()
    raw["agents"][0][key] = point
    assert_has(problems_of(raw), f"agents[0].{key}", "outside bounds")


def test_agent_below_terrain():
    raw = base_world(terrain={"peaks": [{"center": [90, 50], "height": 30, "spread": [10, 10]}]})
    assert_has(problems_of(raw), "agents[0].goal", "below the terrain")


# ----------------------------------------------------------------------------- files, optimizer


def test_missing_mesh_file(tmp_path):
    raw = base_world(
        obstacles=[{"id": "hangar", "shape": "mesh", "file": "nope.stl", "position": [50, 80, 10]}]
    )
    assert_has(problems_of(raw, tmp_path), "obstacles[0].file", "not found", "nope.stl")


def test_unreadable_mesh_file(tmp_path):
    (tmp_path / "bad.stl").write_text("this is not a mesh at all\n")
    (tmp_path / "dir.obj").mkdir()
    raw = base_world(
        obstacles=[
            {"id": "hangar", "shape": "mesh", "file": "bad.stl", "position": [50, 80, 10]},
            {"id": "shed", "shape": "mesh", "file": "dir.obj", "position": [50, 20, 10]},
        ]
    )
    probs = problems_of(raw, tmp_path)
    assert_has(probs, "obstacles[0].file", "bad.stl")
    assert_has(probs, "obstacles[1].file", "dir.obj")


def test_mesh_file_resolves_against_the_world_folder(tmp_path):
    import trimesh

    (tmp_path / "meshes").mkdir()
    trimesh.creation.box(extents=(4, 4, 4)).export(tmp_path / "meshes" / "cube.stl")
    raw = base_world(
        obstacles=[{"id": "cube", "shape": "mesh", "file": "meshes/cube.stl", "position": [50, 80, 10]}]
    )
    path = tmp_path / "w.yaml"
    path.write_text(yaml.safe_dump(raw))
    w = load_world(path)
    assert w.obstacles[0].vertices.shape == (8, 3)
    # The log's resolved world inlines the mesh in world coordinates.
    verts = w.resolved["obstacles"][0]["vertices"]
    assert min(v[0] for v in verts) == pytest.approx(48.0)


def test_unknown_optimizer_lists_the_known_ones():
    probs = problems_of(base_world(planner={"optimizer": {"name": "rscdwao"}}))
    assert_has(probs, "planner.optimizer.name", "unknown optimizer 'rscdwao'", "(did you mean 'rscdwoa'?)")
    msg = next(p for p in probs if p.startswith("planner.optimizer.name"))
    for name in ["none", *KNOWN]:
        assert name in msg


# ----------------------------------------------------------------------------- all at once


def test_several_problems_are_reported_at_once(tmp_path):
    raw = base_world(
        sim={"dt": -1},
        obstacles=[
            {"id": "tower", "shape": "sphere", "radius": 5, "position": [50, 50, 20]},
            {"id": "bad", "shape": "box", "size": [1, -1, 1], "position": [10, 10, 10]},
            {"id": "hangar", "shape": "mesh", "file": "missing.stl", "position": [80, 80, 10]},
        ],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20], "speed": {"min": 9, "max": 3}},
            {"id": "b", "start": [50, 51, 20], "goal": [150, 50, 20], "colour": "red"},
        ],
        planner={"optimizer": {"name": "nope"}},
    )
    probs = problems_of(raw, tmp_path)
    expected = [
        "sim.dt",
        "obstacles[1].size",
        "obstacles[2].file",
        "agents[0].speed",
        "agents[1].colour",
        "agents[1].start",
        "agents[1].goal",
        "planner.optimizer.name",
    ]
    for path in expected:
        assert any(p.startswith(f"{path}:") for p in probs), f"{path} missing from {probs}"
    assert len(probs) >= len(expected)


def test_each_problem_is_reported_once():
    raw = base_world(bounds={"min": [0, 0, 0]})
    del raw["name"]
    probs = problems_of(raw)
    assert len(probs) == len(set(probs)), f"duplicated problems: {probs}"


def test_load_world_reports_yaml_syntax_and_missing_files(tmp_path):
    p = tmp_path / "broken.yaml"
    p.write_text("name: x\nbounds: {min: [0, 0, 0], max: [1, 1\n")
    with pytest.raises(WorldError) as exc:
        load_world(p)
    assert "line" in exc.value.problems[0] and "invalid YAML" in exc.value.problems[0]
    with pytest.raises(WorldError) as exc:
        load_world(tmp_path / "absent.yaml")
    assert "cannot read" in exc.value.problems[0]
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    with pytest.raises(WorldError):
        load_world(empty)


def test_duplicate_ids():
    raw = base_world(
        obstacles=[
            {"id": "x", "shape": "sphere", "radius": 1, "position": [50, 80, 20]},
            {"id": "x", "shape": "sphere", "radius": 1, "position": [50, 20, 20]},
        ],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
            {"id": "a", "start": [10, 60, 20], "goal": [90, 60, 20]},
        ],
    )
    probs = problems_of(raw)
    assert_has(probs, "obstacles[1].id", "already used")
    assert_has(probs, "agents[1].id", "already used")


def test_with_overrides_keeps_the_world_message_in_step_and_refuses_other_fields():
    w = load_world(WORLDS / "quickstart.yaml")
    v = w.with_overrides(max_time=7.5, seed=3)
    assert v.max_time == 7.5 and v.seed == 3
    msg = v.to_message(3)
    assert msg["sim"]["max_time"] == 7.5 and msg["seed"] == 3
    assert w.resolved["sim"]["max_time"] == w.max_time != 7.5  # the original is untouched
    with pytest.raises(ValueError, match="dt"):
        w.with_overrides(dt=0.05)


def test_typed_planner_config_reads_the_validated_mapping_and_is_frozen():
    import dataclasses

    w = load_world(WORLDS / "papers" / "rscdwoa_multi_uav.yaml")
    cfg = w.planner_config
    assert cfg.mode == w.planner["mode"] == "global"
    assert cfg.apf.influence == w.planner["apf"]["influence"]
    assert cfg.stuck.window == w.planner["stuck"]["window"]
    assert cfg.optimizer.name == "rscdwoa" and cfg.optimizer.params["beta"] == 0.74
    assert cfg.escape["retries"] == 2 and cfg.global_.cost in ("mcfo", "iba", "iafsa")
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.stuck.window = 1.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        cfg.escape["retries"] = 5  # type: ignore[index]
    # An override is seen by the typed settings of the new world and by its /world message.
    v = w.with_overrides(planner={**w.planner, "mode": "reactive"})
    assert v.planner_config.mode == "reactive" == v.to_message(0)["planner"]["mode"]
    assert w.to_message(0)["planner"]["mode"] == "global"


def test_planner_settings_are_carried_once():
    """One copy: the typed settings; the mapping and the /world message are read from them, and
    a change to a mapping handed out changes nothing in the world."""
    w = load_world(WORLDS / "papers" / "rscdwoa_multi_uav.yaml")
    assert "planner" not in w.resolved
    msg = w.to_message(0)
    assert msg["planner"] == w.planner == w.planner_config.to_dict()
    assert list(msg).index("planner") == list(msg).index("agents") + 1
    w.planner["apf"]["influence"] = -1.0
    msg["planner"]["mode"] = "reactive"
    assert w.planner["apf"]["influence"] == w.planner_config.apf.influence > 0
    assert w.to_message(0)["planner"]["mode"] == "global"


# ----------------------------------------------------------------------------- tracker:


def test_tracker_section_problems_are_collected_with_the_others():
    raw = base_world(tracker={"dragg": 0.1, "mass": -1, "position": {"kq": 2}})
    raw["sim"]["dt"] = -1
    probs = problems_of(raw)
    assert_has(probs, "tracker.dragg", "unknown key", "(did you mean 'drag'?)")
    assert_has(probs, "tracker.mass", "must be > 0, got -1")
    assert_has(probs, "tracker.position.kq", "unknown key", "(did you mean 'kp'?)")
    assert_has(probs, "sim.dt", "> 0")


def test_tracker_is_a_known_top_level_key_and_is_resolved_into_the_world_message():
    w = make_world(base_world(tracker={"mass": 2.0, "position": {"kp": 5.0}}))
    tr = w.to_message(seed=0)["tracker"]
    assert tr["mass"] == 2.0 and tr["position"] == {"kp": 5.0, "ki": 0.5, "kd": 4.5}
    assert tr["max_tilt_deg"] == 55.0  # defaults filled in
    # Without the section, /world carries the defaults the tracker will use.
    from swarmplan.track import TrackerConfig

    assert make_world(base_world()).resolved["tracker"] == TrackerConfig().to_dict()
    probs = problems_of(base_world(trackr={}))
    assert any(p.startswith("trackr: unknown key") and "'tracker'" in p for p in probs), probs


def test_bad_tracker_key_in_a_world_file_exits_2_naming_it(tmp_path):
    import os
    import subprocess
    import sys

    world = tmp_path / "w.yaml"
    world.write_text(yaml.safe_dump(base_world(tracker={"max_tilt": 30})))
    r = subprocess.run(
        [sys.executable, "-m", "swarmplan.run", str(world), "--out", str(tmp_path / "out.mcap")],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1])),  # this checkout's package
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert "tracker.max_tilt: unknown key (did you mean 'max_tilt_deg'?)" in r.stderr
    assert not (tmp_path / "out.mcap").exists()

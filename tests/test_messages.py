"""Messages and outputs a newcomer reads: hints, single problems, names, digits, verdicts.

Each test pins one behaviour: run's "did you mean" and its refusal of a log without the
.mcap extension, one problem per cause in world and sweep validation, replay's header of a
pure-APF log, the sweep's run and plot names, p-values printed on the right side of alpha,
the note when too few seeds can never be significant, the box plot's legend and labels,
CSV floats, and quick scale runs without verdicts.
"""

from __future__ import annotations

import itertools
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import base_world as log_world  # noqa: E402
from conftest_replay import states_from_arrays, write_log  # noqa: E402
from helpers import base_world  # noqa: E402

from swarmplan.cli.replay import describe  # noqa: E402
from swarmplan.cli.run import main as run_main  # noqa: E402
from swarmplan.cli.sweep import main as sweep_main  # noqa: E402
from swarmplan.replay.recording import load  # noqa: E402
from swarmplan.sweep import engine, report  # noqa: E402
from swarmplan.sweep.spec import parse_spec  # noqa: E402
from swarmplan.world import WorldError  # noqa: E402
from swarmplan.world.schema import parse_world  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def world_file(tmp_path: Path) -> Path:
    raw = base_world(planner={"optimizer": {"name": "rscdwoa", "population": 10, "iterations": 5}})
    path = tmp_path / "w.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def test_run_suggests_the_nearest_optimizer(world_file, capsys):
    assert run_main([str(world_file), "--optimizer", "rscdwao"]) == 2
    assert "--optimizer: unknown optimizer 'rscdwao' (did you mean 'rscdwoa'?)" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["x.txt", "x", "x.mcap.bak"])
def test_run_refuses_a_log_name_without_the_mcap_extension(world_file, tmp_path, capsys, name):
    out = tmp_path / name
    assert run_main([str(world_file), "--out", str(out)]) == 2
    assert "give it the .mcap extension" in capsys.readouterr().err
    assert not out.exists()


def test_a_negative_speed_in_agent_defaults_is_one_problem():
    raw = base_world(agent_defaults={"speed": {"max": -3}})
    raw["agents"] += [{"id": "b", "start": [10, 40, 20], "goal": [90, 40, 20]}]
    with pytest.raises(WorldError) as exc:
        parse_world(raw)
    assert exc.value.problems == ["agent_defaults.speed.max: must be > 0, got -3"]


def test_an_agent_own_bad_speed_is_still_named_on_the_agent():
    raw = base_world()
    raw["agents"][0]["speed"] = {"min": 10, "max": 5}
    with pytest.raises(WorldError) as exc:
        parse_world(raw)
    assert exc.value.problems == ["agents[0].speed: min (10) is above max (5)"]


def test_a_swept_bad_population_is_one_problem_naming_the_swept_optimizer(world_file, tmp_path, capsys):
    spec = tmp_path / "s.yaml"
    spec.write_text(yaml.safe_dump({"name": "s", "worlds": ["w.yaml"], "optimizers": ["woa"], "seeds": 1,
                                    "overrides": {"planner.optimizer.population": [-5]}}))  # fmt: skip
    assert sweep_main([str(spec)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "planner.optimizer.population: must be >= 2, got -5" in err[0]
    assert "rscdwoa" not in err[0] and "[optimizer woa" in err[0]


def test_replay_of_a_pure_apf_log_shows_no_optimizer_budget(tmp_path):
    world = log_world([{"id": "a", "start": [0, 0, 10], "goal": [5, 0, 10]}])
    world["planner"] = {"optimizer": {"name": "none", "population": 20, "iterations": 40}}
    times = np.arange(11) * 0.1
    pos = np.stack([np.linspace(0, 5, 11), np.zeros(11), np.full(11, 10.0)], axis=1)[None]
    states = states_from_arrays(times, ["a"], pos, goals=[[5, 0, 10]])
    path = write_log(tmp_path / "n.mcap", world, states, summary={"optimizer": "none", "agents": []})
    head = describe(load(path))[0]
    assert "optimizer none " in head and "pop" not in head and "iter" not in head


def test_runs_are_named_after_the_world_file_wherever_it_lies(tmp_path):
    (tmp_path / "sub").mkdir()
    world = tmp_path / "sub" / "u_pocket.yaml"
    world.write_text(yaml.safe_dump(base_world(), sort_keys=False))
    outside = parse_spec({"worlds": [str(world)], "optimizers": ["woa"], "seeds": 1}, base_dir=tmp_path / "x")
    beside = parse_spec({"worlds": [world.name], "optimizers": ["woa"], "seeds": 1}, base_dir=world.parent)
    for spec in (outside, beside):
        assert spec.tasks()[0].run_id.startswith("u_pocket-woa-s0-")
    assert report.plot_name(outside.worlds[0][0], [outside.worlds[0][0]]) == "u_pocket"
    assert report.plot_name("a/w.yaml", ["a/w.yaml", "b/w.yaml"]) == "a_w"


def test_p_is_printed_on_its_side_of_alpha():
    assert report.p_text(0.049534613, 0.05) == "0.0495"
    assert report.p_text(0.0505, 0.05) == "0.051"
    assert report.p_text(0.00012, 0.05) == "0.00012"
    # 3 runs against 3, fully apart: p = 0.0495, significant, and printed so
    assert report.verdict([10.0, 11.0, 12.0], [1.0, 2.0, 3.0], 0.05) == "+ (p=0.0495)"
    for p in np.linspace(0.03, 0.07, 401):
        assert (float(report.p_text(p, 0.05)) < 0.05) == (p < 0.05)


def _rows(n_seeds: int) -> list[dict]:
    return [
        {"optimizer": o, "seed": s, "status": "ok", "success": True,
         "path_length_mean": 10.0 + s + 5 * (o == "b"), "arrival_time_mean": 5.0 + s,
         "planning_ms": 1.0, "plan_cost": math.nan, "path_ratio_mean": 1.0, "curvature_mean": 0.01}
        for o, s in itertools.product("ab", range(n_seeds))
    ]  # fmt: skip


def test_too_few_seeds_for_significance_is_said():
    assert report.seeds_needed(0.05) == 3
    notes = " ".join(report.table_notes(_rows(2), ["a", "b"], 0.05))
    assert "no verdict can be significant" in notes and "at least 3 seeds" in notes
    assert "no verdict can be significant" not in " ".join(report.table_notes(_rows(3), ["a", "b"], 0.05))


def test_agents_home_beside_success_and_a_note_where_no_optimizer_ran():
    """A failed run may have brought most agents home; rows of runs that called no optimizer are
    pure APF's, which a note says (only when every run of that optimizer says so)."""
    rows = [dict(r, success=False, agents="3", arrived="2", optimizer_runs="0") for r in _rows(2)]
    text = report.table(rows, ["a", "b"])
    head, _, first, _ = text.splitlines()
    cells = [c.strip() for c in first.split("|")]
    assert cells[2:4] == ["0/2 (0%)", "4/6"] and "agents home" in head
    notes = report.table_notes(rows, ["a", "b"], 0.05)
    assert any(n.startswith("no optimizer ran in any run of a, b: ") for n in notes)
    rows[0]["optimizer_runs"] = "5"
    notes = report.table_notes(rows, ["a", "b"], 0.05)
    assert any(n.startswith("no optimizer ran in any run of b: ") for n in notes)
    assert not any("no optimizer ran" in n for n in report.table_notes(_rows(3), ["a", "b"], 0.05))


def test_box_plot_has_a_legend_and_tick_labels_that_do_not_overlap():
    rows = []
    labels = []
    for o, pop in itertools.product(["woa", "rscdwoa", "iba_gauss"], [10, 20, 40]):
        rows += [dict(r, optimizer=o, pop=pop) for r in _rows(3) if r["optimizer"] == "a"]
        labels.append((f"{o} population={pop}", lambda r, o=o, p=pop: r["optimizer"] == o and r["pop"] == p))
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = report.box_figure("w.yaml", rows, labels)
    FigureCanvasAgg(fig).draw()
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == ["median", "mean", "outlier (beyond 1.5 IQR)"]
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        boxes = [t.get_window_extent(renderer) for t in ax.get_xticklabels() if t.get_text()]
        assert len(boxes) == 9
        for a, b in itertools.combinations(boxes, 2):
            assert not a.overlaps(b)


def test_csv_floats_are_short():
    assert engine._cell(20.291999999999998) == "20.292"
    assert engine._cell(1 / 3) == "0.333333333333"
    assert engine._cell(math.nan) == ""


def test_quick_scale_figures_have_no_verdict():
    from swarmplan.bench import scale

    try:
        scale.judge_targets(False)
        assert scale._verdict(5.86, 1.0, False) == scale.QUICK_VERDICT
        scale.judge_targets(True)
        assert scale._verdict(5.86, 1.0, False) == "NOT met"
        assert scale._verdict(0.76, 1.0, False) == "met"
    finally:
        scale.judge_targets(True)


def _parsers():
    import argparse

    from swarmplan.cli import bench, compare, replay, run, sweep, track

    out = {m.__name__: m.build_parser() for m in (run, replay, track, sweep, compare)}
    top = bench.build_parser()
    out["bench"] = top
    for action in top._actions:
        if isinstance(action, argparse._SubParsersAction):
            out.update({f"bench {name}": p for name, p in action.choices.items()})
    return out


def test_every_help_is_plain_text_with_each_default_once_and_every_option_explained():
    import re

    for name, parser in _parsers().items():
        text = parser.format_help()
        assert "(default: None)" not in text, name
        assert not re.search(r"\(default: [^()]*\)\s+\(default:", text), name
        assert "``" not in text and ":mod:" not in text, name
        assert not re.search(r"\bissue \d+", text), name
        for action in parser._actions:
            if action.option_strings and action.dest != "help":
                assert action.help, f"{name} {action.option_strings[0]} has no help"


NUMBERS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8}


def test_shipped_world_headers_count_their_agents():
    """A header that says how many agents fly ("Three multirotors ...") says it right."""
    import re

    checked = 0
    for path in sorted((REPO / "worlds").rglob("*.yaml")):
        text = path.read_text(encoding="utf-8")
        header = " ".join(line for line in text.splitlines()[:3] if line.startswith("#")).lower()
        count = r"\b(" + "|".join(NUMBERS) + r")\b (multirotors?|fixed-wing|agents?)"
        found = re.search(count, header)
        if found:
            n = len(yaml.safe_load(text)["agents"])
            assert NUMBERS[found.group(1)] == n, f"{path.name}: header says {found.group(0)!r}, {n} fly"
            checked += 1
    assert checked >= 6

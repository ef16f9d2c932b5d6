"""The test suite's log audit (tests/helpers.py): replay's recomputation always runs, the shared
checker joins where it exists, and CI fails rather than skips when the checker is missing."""

from __future__ import annotations

import helpers
import pytest
from conftest_replay import states_from_arrays, straight_past_sphere_log, write_log


@pytest.fixture
def no_checker(monkeypatch, tmp_path):
    monkeypatch.setenv("SWARMPLAN_CHECK_LOG", str(tmp_path / "absent" / "check_log.py"))
    monkeypatch.setattr(helpers, "REPO", tmp_path / "repo")  # nothing beside it either
    monkeypatch.setattr(helpers, "_CHECK_LOG_MODULE", None)


def test_replay_audit_runs_without_the_checker(no_checker, monkeypatch, tmp_path):
    monkeypatch.delenv("CI", raising=False)
    log, clearance = straight_past_sphere_log(tmp_path / "ok.mcap")
    problems, notes, stats = helpers.audit(log)
    assert problems == []
    assert any("audited by swarmplan.replay only" in n for n in notes)
    assert stats["agents"] == stats["arrived"] == 1 and stats["collisions"] == 0
    assert stats["min_obstacle_clearance"] == pytest.approx(clearance, abs=1e-9)


def test_missing_checker_fails_on_ci(no_checker, monkeypatch, tmp_path):
    monkeypatch.setenv("CI", "true")
    log, _ = straight_past_sphere_log(tmp_path / "ok.mcap")
    with pytest.raises(pytest.fail.Exception, match="CI=true but shared/tools/check_log.py not found"):
        helpers.audit(log)


def test_replay_audit_flags_a_summary_that_disagrees(no_checker, monkeypatch, tmp_path):
    """A summary whose clearance and success contradict the recorded states is caught by replay alone."""
    monkeypatch.delenv("CI", raising=False)
    log, clearance = straight_past_sphere_log(tmp_path / "ok.mcap")
    from swarmplan.replay import load

    rec = load(log)
    summary = dict(rec.summary)
    summary["agents"] = [dict(summary["agents"][0], min_clearance=clearance + 3.0)]
    states = states_from_arrays(rec.times, ["a1"], rec.positions, modes=rec.modes, goals=rec.goals)
    bad = write_log(
        tmp_path / "bad.mcap", rec.world, states, events=[e.to_json() for e in rec.events], summary=summary
    )
    problems, _notes, _stats = helpers.audit(bad)
    assert problems == ["replay vs /summary: a1: min_clearance recomputed 1.5 vs recorded 4.5"]


def test_replay_audit_counts_non_arrival_unless_allowed(no_checker, monkeypatch, tmp_path):
    monkeypatch.delenv("CI", raising=False)
    log, _ = straight_past_sphere_log(tmp_path / "ok.mcap")
    from swarmplan.replay import load

    rec = load(log)
    cut = 50  # stop halfway, 5 m short of the goal; the summary says so too
    states = states_from_arrays(rec.times[:cut], ["a1"], rec.positions[:, :cut], goals=rec.goals)
    row = dict(rec.summary["agents"][0], arrived=False, arrival_time=None, path_length=4.9)
    summary = dict(rec.summary, success=False, sim_time=float(rec.times[cut - 1]), agents=[row])
    bad = write_log(tmp_path / "short.mcap", rec.world, states, summary=summary)
    problems, _n, stats = helpers.audit(bad)
    assert problems == ["replay: agent a1 did not arrive (5.10 m from goal)"]
    assert helpers.audit(bad, allow_failure=True)[0] == []
    assert stats["arrived"] == 0


def test_checker_found_beside_the_repo(monkeypatch, tmp_path):
    """Without the environment variable, ``<repo>/../shared/tools/check_log.py`` is used."""
    monkeypatch.delenv("SWARMPLAN_CHECK_LOG", raising=False)
    fake = tmp_path / "shared" / "tools" / "check_log.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("def check(path, allow_failure=False):\n    return ['fake problem'], [], {}\n")
    monkeypatch.setattr(helpers, "REPO", tmp_path / "repo")
    monkeypatch.setattr(helpers, "_CHECK_LOG_MODULE", None)
    log, _ = straight_past_sphere_log(tmp_path / "ok.mcap")
    assert helpers.find_check_log() == fake.resolve()
    assert helpers.audit(log)[0] == ["check_log: fake problem"]

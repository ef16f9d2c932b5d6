"""The README's library snippet runs as written and flies what the command line flies."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_library_snippet_runs_and_matches_the_cli_planner(monkeypatch):
    text = (REPO / "README.md").read_text(encoding="utf-8")
    snippet = re.search(r"As a library:\n\n```python\n(.*?)```", text, re.S).group(1)
    monkeypatch.chdir(REPO)
    out = io.StringIO()
    scope: dict = {}
    with contextlib.redirect_stdout(out):
        exec(compile(snippet, "README.md", "exec"), scope)  # the snippet under test
    sim = scope["sim"]
    # The world's own optimizer flies, as with `python -m swarmplan.run` (not pure APF).
    assert sim.optimizer_name == scope["world"].planner["optimizer"]["name"] != "none"
    assert out.getvalue().strip() in ("True", "False")
    assert scope["res"].evaluations <= 20_000

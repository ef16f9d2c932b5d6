"""The docs generator (``python -m swarmplan.bench docs``) and the notes under compare's tables."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import pytest

from swarmplan.bench import docs
from swarmplan.cli.bench import build_parser
from swarmplan.sweep.report import table, table_notes

DOC = """# A page

Text before, kept byte for byte.  Trailing spaces too.\t

<!-- generated: alpha -->
old alpha table
<!-- end: alpha -->

Between the blocks.

<!-- generated: beta -->
| old | beta |
<!-- end: beta -->
Text after, no newline at the end"""


def _gen(name: str, body: str, uses: frozenset[str] = frozenset()) -> docs.Generator:
    return docs.Generator(name, f"test block {name}", lambda opts: docs.Block(f"echo {name}", body), uses)


def _args(root: Path, **kw: object) -> argparse.Namespace:
    ns = build_parser().parse_args(["docs", "--root", str(root)])
    for k, v in kw.items():
        setattr(ns, k, v)
    return ns


def test_rewrite_replaces_only_the_named_block_exactly() -> None:
    out = docs.rewrite(DOC, {"alpha": "\nnew line 1\nnew line 2\n"})
    expected = DOC.replace("old alpha table", "\nnew line 1\nnew line 2\n")
    assert out == expected
    # idempotent: the same contents again change nothing
    assert docs.rewrite(out, {"alpha": "\nnew line 1\nnew line 2\n"}) == out
    # and a block can shrink back
    assert docs.rewrite(out, {"alpha": "old alpha table"}) == DOC


def test_rewrite_of_two_blocks_and_empty_contents() -> None:
    out = docs.rewrite(DOC, {"alpha": "A", "beta": ""})
    assert "<!-- generated: alpha -->\nA\n<!-- end: alpha -->" in out
    assert "<!-- generated: beta -->\n\n<!-- end: beta -->" in out
    assert out.endswith("Text after, no newline at the end")
    assert out.startswith("# A page\n\nText before, kept byte for byte.  Trailing spaces too.\t\n")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("<!-- generated: a -->\nx\n", "test.md:1: block 'a' is never closed"),
        ("x\n<!-- end: a -->\n", "test.md:2: end of block 'a' without its opening marker"),
        ("<!-- generated: a -->\n<!-- generated: b -->\n", "test.md:2: block 'b' opens inside block 'a'"),
        ("<!-- generated: a -->\n<!-- end: b -->\n", "test.md:2: end of block 'b' but block 'a' is open"),
        ("<!-- generated: a --> text\n", "test.md:1: malformed marker"),
        ("<!--generated: a-->\n", "test.md:1: malformed marker"),
    ],
)
def test_malformed_markers_name_file_and_line(text: str, message: str) -> None:
    with pytest.raises(docs.DocsError, match=message):
        docs.find_blocks(text, "test.md")


def _tree(tmp_path: Path, text: str) -> Path:
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "page.md").write_text(text, encoding="utf-8")
    (tmp_path / "README.md").write_text("# readme, no blocks\n", encoding="utf-8")
    return tmp_path / "docs" / "page.md"


def test_main_rewrites_with_a_stamp_and_is_idempotent_apart_from_it(tmp_path: Path) -> None:
    page = _tree(tmp_path, DOC)
    gens = {"alpha": _gen("alpha", "| a | b |\n|---|---|\n| 1 | 2 |"), "beta": _gen("beta", "B")}
    assert docs.main(_args(tmp_path), gens) == 0
    text = page.read_text(encoding="utf-8")
    spans = docs.find_blocks(text)
    assert [s.name for s in spans] == ["alpha", "beta"]
    lines = text.split("\n")
    inside = lines[spans[0].open_line + 1 : spans[0].end_line]
    assert inside[0] == "" and inside[-1] == ""
    assert inside[1].startswith("_Generated at commit `")
    assert "by `python -m swarmplan.bench docs --only alpha`, which ran: `echo alpha`._" in inside[1]
    assert inside[2:-1] == ["", "| a | b |", "|---|---|", "| 1 | 2 |"]
    # everything outside the blocks is unchanged
    assert text.split("<!-- generated: alpha -->")[0] == DOC.split("<!-- generated: alpha -->")[0]
    assert text.endswith("<!-- end: beta -->\nText after, no newline at the end")
    # a second run rewrites the same lines (only the stamp's time may differ)
    assert docs.main(_args(tmp_path), gens) == 0
    again = page.read_text(encoding="utf-8")
    assert [ln for ln in again.split("\n") if not ln.startswith("_Generated")] == [
        ln for ln in text.split("\n") if not ln.startswith("_Generated")
    ]


def test_only_regenerates_the_named_block(tmp_path: Path) -> None:
    page = _tree(tmp_path, DOC)
    gens = {"alpha": _gen("alpha", "A"), "beta": _gen("beta", "B")}
    assert docs.main(_args(tmp_path, only="beta"), gens) == 0
    text = page.read_text(encoding="utf-8")
    assert "old alpha table" in text and "| old | beta |" not in text


def test_unknown_block_is_a_clear_error_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    page = _tree(tmp_path, DOC.replace("beta", "gamma"))
    ran = []
    gens = {"alpha": docs.Generator("alpha", "", lambda o: ran.append(1) or docs.Block("x", "A"))}
    assert docs.main(_args(tmp_path), gens) == 2
    err = capsys.readouterr().err
    assert f"error: {page}:11: unknown generated block 'gamma'; known: alpha" in err
    assert ran == [] and page.read_text(encoding="utf-8") == DOC.replace("beta", "gamma")
    assert docs.main(_args(tmp_path, only="delta"), gens) == 2
    assert "--only: unknown block 'delta'" in capsys.readouterr().err


def test_only_a_block_that_no_doc_has_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    _tree(tmp_path, "no blocks here\n")
    assert docs.main(_args(tmp_path, only="alpha"), {"alpha": _gen("alpha", "A")}) == 2
    assert "--only: block 'alpha' is in no file under" in capsys.readouterr().err


def test_shipped_docs_have_only_known_well_formed_blocks() -> None:
    found, problems = docs.scan(docs.doc_files(docs.ROOT), docs.GENERATORS)
    assert problems == []
    names = {s.name for spans in found.values() for s in spans}
    assert {f"comparison-{w}" for w in docs.COMPARISON} <= names
    for path, spans in found.items():
        text = path.read_text(encoding="utf-8").split("\n")
        for s in spans:  # every shipped block says which commit and command made it
            assert text[s.open_line + 2].startswith("_Generated at commit `"), (path, s.name)


def test_stamp_names_commit_date_and_commands() -> None:
    from datetime import datetime, timezone

    line = docs.stamp(
        docs.Block("python -m swarmplan.compare w.yaml", ""),
        "python -m swarmplan.bench docs --only x",
        "abc1234 dirty",
        datetime(2026, 11, 23, 12, 5, tzinfo=timezone.utc),
        1.25,
    )
    assert line == (
        "_Generated at commit `abc1234 dirty` on 2026-11-23 12:05 UTC, load average 1.2 (2 cores) by "
        "`python -m swarmplan.bench docs --only x`, which ran: `python -m swarmplan.compare w.yaml`._"
    )


def _row(opt: str, seed: int, length: float, cost: float = math.nan) -> dict:
    return {
        "world": "w.yaml", "optimizer": opt, "seed": seed, "status": "ok", "success": not math.isnan(length),
        "path_length_mean": length, "path_ratio_mean": 1.0, "curvature_mean": 0.1,
        "arrival_time_mean": length / 10, "planning_ms": 5.0 + seed, "plan_cost": cost,
    }  # fmt: skip


def test_compare_says_why_cells_are_empty() -> None:
    # reactive world (no plan cost), one optimizer that never arrives, one seed
    rows = [_row("a", 0, 100.0), _row("b", 0, math.nan)]
    text = table(rows, ["a", "b"])
    assert "plan cost" not in text and "n/a" in text
    notes = table_notes(rows, ["a", "b"])
    assert any(n.startswith("no plan cost column: no run made a global plan") for n in notes)
    assert any(n.startswith("n/a in length, curvature and arrival for b: no agent") for n in notes)
    assert any(n.startswith("n/a in a verdict column: fewer than 2 values on a side (a, b)") for n in notes)
    # global world, enough seeds, everyone arrives: nothing to explain
    rows = [_row(o, s, 100.0 + s, 10.0 + s) for o in "ab" for s in range(3)]
    assert "plan cost" in table(rows, ["a", "b"]) and table_notes(rows, ["a", "b"]) == []


def test_compare_help_shows_defaults(monkeypatch: pytest.MonkeyPatch) -> None:
    from swarmplan.cli.compare import build_parser as compare_parser

    monkeypatch.setenv("COLUMNS", "200")  # no line breaks inside the defaults
    text = compare_parser().format_help()
    assert "(default: 10)" in text and "(default: woa,rscdwoa,ba,iba_abc,cfo,mcfo)" in text


def test_a_marker_mentioned_in_prose_is_not_a_block() -> None:
    assert docs.find_blocks("the `<!-- generated: NAME -->` markers are rewritten\n", "t.md") == []


def test_stamp_names_only_the_options_a_block_uses(tmp_path: Path) -> None:
    page = _tree(tmp_path, DOC)
    gens = {"alpha": _gen("alpha", "A", frozenset({"seeds"})), "beta": _gen("beta", "B")}
    assert docs.main(_args(tmp_path, seeds=3, quick=True), gens) == 0
    text = page.read_text(encoding="utf-8")
    assert "by `python -m swarmplan.bench docs --only alpha --seeds 3`, which ran" in text
    assert "by `python -m swarmplan.bench docs --only beta`, which ran" in text

"""The docs cite their sources and name only what exists: docs/references.md cites the five
papers in full and every "paper 00N" of the README and docs links to its entry; every source
file a doc names exists; the world format lists every optimizer a world may name; the
performance page is a page of current figures, not a log."""

from __future__ import annotations

import re
from pathlib import Path

from swarmplan.optimizers import available

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_references_cite_the_five_papers_in_full():
    text = (ROOT / "docs" / "references.md").read_text(encoding="utf-8")
    entries = re.split(r"^## ", text, flags=re.M)[1:]
    assert [e.split("\n", 1)[0] for e in entries] == [f"Paper 00{k}" for k in range(5)]
    for entry in entries:
        citation = entry.split("\n\n")[1]
        assert re.search(r"\*\*[^*]{20,}\*\*", citation), citation  # the title
        assert re.search(r"\*[A-Z][^*]+\*", citation.replace("**", "")), citation  # the venue
        assert re.search(r"\b(19|20)\d\d\b", citation), citation  # the year


def test_every_paper_mention_links_to_its_reference():
    mention = re.compile(r"\bpaper (00[0-4])\b", re.I)
    unlinked = []
    for page in PAGES:
        if page.name == "references.md":
            continue
        target = "docs/references.md" if page.name == "README.md" else "references.md"
        for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            if line.lstrip().startswith("!["):  # an image's alt text cannot hold a link
                continue
            for m in mention.finditer(line):
                link = f"[{m.group(0)}]({target}#paper-{m.group(1)})"
                if line[m.start() - 1 : m.start() - 1 + len(link)] != link:
                    unlinked.append(f"{page.name}:{n}: {m.group(0)}")
    assert unlinked == []


def test_every_source_file_a_page_names_exists():
    named = re.compile(r"`((?:swarmplan/)?(?:[a-z_]+/)+[A-Za-z0-9_]+\.py)")
    missing = []
    for page in PAGES:
        for path in named.findall(page.read_text(encoding="utf-8")):
            here = [ROOT / path, ROOT / "swarmplan" / path, ROOT / "tests" / path]
            if not any(p.is_file() for p in here):
                missing.append(f"{page.name}: {path}")
    assert missing == []


def test_the_world_format_lists_every_optimizer():
    text = (ROOT / "docs" / "world-format.md").read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith("| `planner.optimizer.name`"))
    listed = set(re.findall(r"`([a-z_]+)`", row.split("|")[5])) - {"none"}
    assert listed == set(available())


def test_the_performance_page_is_current_figures_in_under_300_lines():
    text = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) < 300
    assert "## Current figures" in text and "## Reproduce" in text

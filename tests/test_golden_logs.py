"""Behaviour is frozen: the logs of ``tests/golden/golden.py``'s worlds hold exactly the content
of the stored digests (wall clock frozen). Re-store only for a deliberate change."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location("golden", Path(__file__).parent / "golden" / "golden.py")
golden = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(golden)
STORED = json.loads(golden.DIGESTS.read_text())


@pytest.mark.parametrize("name", sorted(golden.CASES))
def test_log_content_is_identical(name: str, tmp_path: Path) -> None:
    got = golden.describe(golden.make_log(name, tmp_path))
    want = STORED[name]
    # Facts first: a mismatch there says where the logs part; the digest says whether they do.
    assert {k: got[k] for k in want if k != "sha256"} == {k: want[k] for k in want if k != "sha256"}
    assert got["sha256"] == want["sha256"]

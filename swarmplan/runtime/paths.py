"""Output paths checked before any work: why a file or folder cannot be written, or None.

Every command-line program (and benchmark) checks its output files and folders with these
before it loads, simulates or benchmarks anything, so a typo never costs a finished
computation. Missing parent folders are fine (the programs create them); the first existing
folder on the way is probed with a temporary entry, because permissions alone do not tell
(e.g. for root under /proc). Nothing is left behind.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def _probe(parent: Path, option: str, path: str, create_here: bool) -> str | None:
    try:
        if create_here:
            with tempfile.NamedTemporaryFile(dir=parent, prefix=".swarmplan-probe-"):
                pass
        else:  # the missing folders will be created there
            os.rmdir(tempfile.mkdtemp(dir=parent, prefix=".swarmplan-probe-"))
    except OSError as exc:
        return f"{option} {path}: cannot write in {parent} ({exc.strerror or exc})"
    return None


def _existing_ancestor(p: Path) -> Path:
    parent = p
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    return parent


def output_file_problem(option: str, path: str | os.PathLike[str]) -> str | None:
    """Why ``path`` cannot be written as an output file (its folders may be missing), or None."""
    p = Path(path)
    if p.is_dir():
        return f"{option} {path}: is a directory, not a file"
    if p.exists() and not os.access(p, os.W_OK):
        return f"{option} {path}: the file exists and is not writable"
    parent = _existing_ancestor(p.parent if str(p.parent) else Path("."))
    if not parent.is_dir():
        return f"{option} {path}: {parent} is a file, not a directory"
    return _probe(parent, option, str(path), create_here=parent == (p.parent if str(p.parent) else Path(".")))


def output_dir_problem(option: str, path: str | os.PathLike[str]) -> str | None:
    """Why ``path`` cannot be used (or created) as an output folder, or None."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        return f"{option} {path}: is a file, not a directory"
    parent = _existing_ancestor(p)
    if not parent.is_dir():
        return f"{option} {path}: {parent} is a file, not a directory"
    return _probe(parent, option, str(path), create_here=False)

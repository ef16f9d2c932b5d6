"""Arrays kept on disk between runs, keyed by everything they are computed from.

Some work depends on a world's geometry alone and costs more than the rest of a small run's
start-up: the static guide's grid and its first ways (:mod:`swarmplan.flight.guide_cache`), a
mesh's distance grid (:class:`swarmplan.geometry.shapes.MeshGrid`). It is computed once and
read back by later runs of the same world, in this process or another (a sweep's workers, the
next run of a world file being edited).

- **Where:** ``$SWARMPLAN_CACHE_DIR``, else ``$XDG_CACHE_HOME/swarmplan``, else
  ``~/.cache/swarmplan``. ``SWARMPLAN_CACHE_DIR`` set to an empty value turns the cache off.
- **Key:** a SHA-256 over the caller's inputs (:func:`digest`) and the code that computes them:
  the package's sources (path, size and modification time of every ``.py`` file), the Python,
  numpy and numba installations. Editing the package or upgrading a library starts afresh.
- **Entries** are ``.npz`` files (no pickles), written to a temporary name and renamed into
  place, so a reader never sees half a file and two processes writing the same entry both leave
  a whole one. Each holds its own key: a file that cannot be read or holds another key is a
  miss (and is written again). Beyond ``MAX_BYTES`` in all the oldest entries are removed.
- A cache that cannot be written (read-only home, full disk) costs nothing but the speed-up:
  the computation's answer is the same either way.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import os
import sys
import tempfile
import zipfile
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

ENV = "SWARMPLAN_CACHE_DIR"
MAX_BYTES = 512 * 2**20
"""The cache's size in all, beyond which the least recently used entries are removed."""
MAX_ENTRY_BYTES = MAX_BYTES // 8
"""An entry larger than this is not stored (it would push out most of the others)."""

_KEY = "__key__"


def cache_dir() -> Path | None:
    """The folder of the entries, or None when the cache is off (see the module docstring)."""
    own = os.environ.get(ENV)
    if own is not None:
        return Path(own).expanduser() if own.strip() else None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "swarmplan"


@cache
def code_fingerprint() -> str:
    """What the cached answers depend on besides their inputs: this package's sources (path,
    size and modification time of each, ~1 ms for all: content hashes cost 25x more) and the
    Python, numpy and numba installations (numba's by its files, without importing it)."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parents[1]
    for dirpath, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(f for f in files if f.endswith(".py")):
            st = os.stat(os.path.join(dirpath, name))
            h.update(f"{os.path.relpath(dirpath, root)}/{name}:{st.st_size}:{st.st_mtime_ns};".encode())
    h.update(f"python {sys.version}; numpy {np.__version__};".encode())
    spec = importlib.util.find_spec("numba")
    if spec is not None and spec.origin:
        st = os.stat(spec.origin)
        h.update(f"numba {spec.origin}:{st.st_size}:{st.st_mtime_ns}".encode())
    return h.hexdigest()


def _feed(h: Any, obj: object) -> None:
    """Feed ``obj`` to hash ``h`` in a form that tells apart every value and type it can hold."""
    if obj is None or isinstance(obj, bool):
        h.update(f"<{obj!r}>".encode())
    elif isinstance(obj, int | float | str):
        text = float.hex(obj) if isinstance(obj, float) else str(obj)
        h.update(f"<{type(obj).__name__}:{len(text)}:{text}>".encode())
    elif isinstance(obj, np.ndarray | np.generic):
        a = np.ascontiguousarray(obj)
        if a.dtype.hasobject:
            raise TypeError("disk_cache.digest: arrays of Python objects have no stable bytes")
        h.update(f"<array:{a.dtype.str}:{a.shape}>".encode())
        h.update(a.tobytes())
    elif isinstance(obj, tuple | list):
        h.update(f"<seq:{len(obj)}>".encode())
        for item in obj:
            _feed(h, item)
    elif isinstance(obj, dict):
        h.update(f"<map:{len(obj)}>".encode())
        for k in sorted(obj, key=repr):
            _feed(h, k)
            _feed(h, obj[k])
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(f"<{type(obj).__qualname__}>".encode())
        for f in dataclasses.fields(obj):
            _feed(h, f.name)
            _feed(h, getattr(obj, f.name))
    else:
        raise TypeError(f"disk_cache.digest: cannot key a {type(obj).__name__}")


def digest(*parts: object) -> str:
    """The key of an entry computed from ``parts`` (numbers, strings, arrays, sequences,
    mappings and dataclasses of these) by this package's code (:func:`code_fingerprint`)."""
    h = hashlib.sha256(code_fingerprint().encode())
    _feed(h, parts)
    return h.hexdigest()


def _path(folder: Path, kind: str, key: str) -> Path:
    return folder / f"{kind}-{key[:40]}.npz"


def load(kind: str, key: str) -> dict[str, np.ndarray] | None:
    """The arrays stored as ``kind`` under ``key``, or None (off, missing, unreadable, other key)."""
    folder = cache_dir()
    if folder is None:
        return None
    path = _path(folder, kind, key)
    try:
        with np.load(path, allow_pickle=False) as f:
            arrays = {name: f[name] for name in f.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile):  # damaged or foreign
        return None
    try:
        os.utime(path)  # recently used: the last to be removed
    except OSError:  # a cache one may read but not write
        pass
    if str(arrays.pop(_KEY, "")) != key:
        return None
    return arrays


def save(kind: str, key: str, arrays: dict[str, np.ndarray]) -> None:
    """Store ``arrays`` as ``kind`` under ``key`` (nothing when the cache is off or unwritable,
    or the arrays exceed ``MAX_ENTRY_BYTES``)."""
    folder = cache_dir()
    if folder is None or sum(np.asarray(a).nbytes for a in arrays.values()) > MAX_ENTRY_BYTES:
        return
    tmp = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{kind}-", suffix=".npz")
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **{_KEY: np.array(key)}, **arrays)
        os.replace(tmp, _path(folder, kind, key))
        tmp = None
        _trim(folder)
    except OSError:
        pass
    finally:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)


def _trim(folder: Path) -> None:
    """Remove the least recently used entries while the folder holds more than ``MAX_BYTES``."""
    entries = []
    for p in folder.glob("*.npz"):
        try:
            st = p.stat()
        except OSError:
            continue
        entries.append((st.st_mtime_ns, st.st_size, p))
    total = sum(size for _, size, _ in entries)
    for _, size, p in sorted(entries, key=lambda e: e[0]):
        if total <= MAX_BYTES:
            break
        p.unlink(missing_ok=True)
        total -= size

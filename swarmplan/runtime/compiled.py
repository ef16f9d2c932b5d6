"""The compiled (numba) kernels: loaded in one place, at their first use, from a cache that
cannot go stale.

numba's import and the loading of a kernel module's cached machine code cost ~0.5-1 s of CPU
per process, so no module imports a kernel module (``_*kernel*.py``, ``swept_kernels.py``) at
its top: the code that runs a kernel asks :func:`kernel_module` for it when it first needs it,
e.g. ``kernel_module("swarmplan.geometry.swept_kernels")``, and each module is imported once
per process.

**Which path runs: one rule, here.** Below ``COMPILED_FROM`` agents a world's per-step work runs
numpy (and FCL): numba's one-time load (its import and the cached machine code, ~0.9 s CPU per
process) costs more than a small world's whole run saves, and a 16-agent world would not reach
its first step within 0.5 s. From it on (swarm scale) the field, the nearest surfaces, the
agents' clearance, the swept checks and the recorder's number formatting run compiled
(:func:`use_compiled`, :func:`use_compiled_checks`). Both paths give the same bits (the kernels
follow numpy's formulas and order of sums; the swept checks decide exactly what FCL decides),
so a world runs identically either way, and the choice reads the world only (its size, and
whether it has fixed wings), never what a process has loaded before. A world with fixed wings
runs compiled at any size: their model is compiled (``flight._fixed_wing_kernel``), so numba is
in the process from their first step on and the compiled paths cost only their cached code.
A computation with a numpy twin of the same bits (the potential field, the guide's per-step
calls) runs the twin while numba is not in the process
(:func:`use_numpy_twin`); the field does so for its first ``FIELD_NUMPY_CALLS`` calls only
(:func:`field_numpy_calls`), then loads numba: a small world reaches its first step without
numba, and a long run pays numba's load once instead of numpy's per-call overhead for good.

**The on-disk cache.** Every kernel module takes :func:`njit` from here (not from numba). numba's
own cache (``cache=True``) checks only the file of the function it compiled: a kernel that
calls a compiled function of another file runs its old machine code after that callee is
edited. So before the first kernel is compiled, numba's cache is pointed at a folder of its
own per :func:`kernel_digest`, a SHA-256 over the sources of every kernel module and of every
module of the package they import: an edit in any of them compiles afresh, in a new folder
(the ``KEEP`` most recent folders are kept, older ones removed). The folders lie in
``$NUMBA_CACHE_DIR`` when it is set, else in the package's ``__pycache__`` (else numba's
user-wide cache when that cannot be written). Processes started from this one (a sweep's
workers) inherit the folder, and processes that need the same kernel at once compile it once
(:func:`one_compiler`).
"""

from __future__ import annotations

import hashlib
import importlib
import os
import re
import shutil
import sys
import tempfile
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
KEEP = 3
"""Folders of compiled code (one per digest of the kernel sources) kept beside each other."""

PREFIX = "kernels-"
"""The name of a folder of compiled code: this prefix and the first 16 digits of its digest."""

_KERNEL = re.compile(
    r"^(?:from numba import|import numba\b|from swarmplan\.runtime\.compiled import .*\bnjit\b)", re.M
)
_IMPORT = re.compile(
    r"^[ \t]*(?:from[ \t]+([\w.]+)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)|import[ \t]+([\w., \t]+))", re.M
)


COMPILED_FROM = 49
"""Swarm size (agents in the world) from which the compiled per-step kernels run."""

FIELD_NUMPY_CALLS = 600
"""Calls of a world's field that run numpy below ``COMPILED_FROM`` agents before it goes
compiled: numba's load (~0.3 s of CPU with the field's cached kernel) costs about as much as
this many numpy calls of a 16-agent field (0.36-0.5 ms each, against 0.04 ms compiled), so no
run pays more than about twice the cheaper of the two."""

CHECKS_COMPILED_FROM = COMPILED_FROM
"""Swarm size from which the swept checks (``first_hits``, arrivals, near misses, agent
contacts, the braking margin's free distances) run compiled: the same rule as the field. Their
answers are exact on both paths, so this is a speed choice only (its own name lets the tests
run either path)."""


FIXED_WINGS_COMPILED = True
"""Whether worlds with fixed wings run their per-step work compiled at any size (their model
loads numba at their first step anyway)."""


def use_compiled(n_agents: int, fixed_wings: bool = False) -> bool:
    """Whether a world of ``n_agents`` agents (``fixed_wings``: some of them fixed wings) runs its
    per-step field (and recorder) compiled."""
    return (fixed_wings and FIXED_WINGS_COMPILED) or n_agents >= COMPILED_FROM


def use_compiled_checks(n_agents: int, fixed_wings: bool = False) -> bool:
    """Whether a world of ``n_agents`` agents (``fixed_wings``: some of them fixed wings) runs the
    compiled swept checks."""
    return (fixed_wings and FIXED_WINGS_COMPILED) or n_agents >= CHECKS_COMPILED_FROM


def field_numpy_calls(n_agents: int, fixed_wings: bool = False) -> int:
    """How many calls of the field of a world of ``n_agents`` agents run numpy before it goes
    compiled (none at swarm size, nor with fixed wings)."""
    return 0 if use_compiled(n_agents, fixed_wings) else FIELD_NUMPY_CALLS


def use_numpy_twin(n_agents: int | None = None) -> bool:
    """Whether a computation with a numpy twin of the same bits runs the twin: while numba is not
    in the process and, for a world's per-step work (``n_agents`` given), below swarm size."""
    return not numba_loaded() and (n_agents is None or not use_compiled(n_agents))


@cache
def kernel_module(name: str) -> ModuleType:
    """The compiled kernel module ``name`` (its full dotted name in this package), imported, and
    numba with it, at the first call; the same module afterwards."""
    if not name.startswith("swarmplan."):
        raise ValueError(f"kernel_module: expected a module of swarmplan, got {name!r}")
    return importlib.import_module(name)


def numba_loaded() -> bool:
    """Whether numba is in the process already (then a kernel whose numpy twin gives the same
    bits costs only its own cached code to load, not numba's)."""
    return "numba" in sys.modules


def read_only(a: Any) -> Any:
    """A read-only view of the array ``a`` (no copy). numba compiles a kernel once per type of
    its arguments, and an array's type says whether it can be written: an input that reaches a
    kernel writeable from one caller and read-only from another is compiled twice (seconds of
    CPU each for the larger kernels). Such inputs are passed through this."""
    view = a.view()
    view.flags.writeable = False
    return view


def njit(*args: Any, **kwargs: Any) -> Any:
    """numba's ``njit``, with numba's on-disk cache pointed at the folder of this package's
    :func:`kernel_digest` first (see the module docstring), and each kernel compiled by one
    process at a time (:func:`one_compiler`)."""
    folder = use_kernel_cache(PACKAGE_ROOT, "swarmplan")
    import numba

    if len(args) == 1 and callable(args[0]) and not kwargs:  # bare ``@njit``
        return one_compiler(numba.njit(args[0]), folder)
    decorate = numba.njit(*args, **kwargs)
    if not kwargs.get("cache"):
        return decorate
    return lambda fn: one_compiler(decorate(fn), folder)


_HELD: set[str] = set()


def one_compiler(dispatcher: Any, folder: Path) -> Any:
    """``dispatcher`` (a numba function cached in ``folder``) compiling under a lock file of its
    own in ``folder``: processes that need the same kernel at once (the workers of a sweep or of
    a test run, on a fresh cache) compile it once, and the others wait, then read it from the
    cache instead of compiling it too. Locks are taken inside numba's own compiler lock, one
    thread at a time per process; a kernel's callees (compiled while it is) take theirs after
    it, and calls never go round in a circle, so no two processes wait on each other. Where
    locks cannot be had (no ``fcntl``, a folder that cannot be written) each compiles alone."""
    try:
        import fcntl
    except ImportError:  # not on POSIX
        dispatcher.compile = unliteral_compile(dispatcher.compile)
        return dispatcher
    from numba.core.compiler_lock import global_compiler_lock

    func = dispatcher.py_func
    lock = folder / ".locks" / f"{func.__module__}.{func.__qualname__}"
    compile_ = unliteral_compile(dispatcher.compile)

    def compile(sig: Any) -> Any:
        with global_compiler_lock:
            key = str(lock)
            if key in _HELD:  # this thread holds it (a kernel compiled while it compiles)
                return compile_(sig)
            try:
                lock.parent.mkdir(exist_ok=True)
                fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError:
                return compile_(sig)
            try:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX)
                except OSError:  # a file system without locks
                    return compile_(sig)
                _HELD.add(key)
                try:
                    return compile_(sig)
                finally:
                    _HELD.discard(key)
            finally:
                os.close(fd)  # releases the lock

    dispatcher.compile = compile
    return dispatcher


def unliteral_compile(compile_: Any) -> Any:
    """A dispatcher's ``compile_`` that compiles for the plain types of literal arguments.

    A kernel that calls another with a constant (``f(a, 0)``, ``f(x, True)``) passes a literal
    type (``Literal[int](0)``), and numba compiles the callee once per literal value besides
    its plain signature (0.1-2 s of CPU each, ~10 s for the package). Compiled for the plain
    types, the callee serves every such call (numba converts a literal to its plain type), with
    the same arithmetic, so the same bits. A callee that cannot be typed without the literal
    (a tuple indexed by it) is compiled for the literal as before."""
    from numba.core import types
    from numba.core.errors import TypingError

    def compile(sig: Any) -> Any:
        if isinstance(sig, tuple):
            plain = tuple(types.unliteral(a) for a in sig)
            if plain != sig:
                try:
                    return compile_(plain)
                except TypingError:
                    pass
        return compile_(sig)

    return compile


def _module_file(root: Path, package: str, name: str) -> Path | None:
    """The source file of module ``name`` of ``package`` (whose folder is ``root``), or None."""
    if name != package and not name.startswith(package + "."):
        return None
    rel = Path(*name.split(".")[1:])
    for path in (root / rel.with_suffix(".py"), root / rel / "__init__.py"):
        if path.is_file():
            return path
    return None


def _imports(root: Path, package: str, text: str) -> set[Path]:
    """The files of ``package`` that source ``text`` imports (any level, function bodies too)."""
    out: set[Path] = set()
    for base, names, plain in _IMPORT.findall(text):
        candidates = [n.split(" as ")[0].strip() for n in plain.split(",")] if plain else [base]
        if base:
            for n in names.strip("()").split(","):
                n = n.split(" as ")[0].strip()
                if n and n != "*":
                    candidates.append(f"{base}.{n}")
        for name in candidates:
            path = _module_file(root, package, name)
            if path is not None:
                out.add(path)
    return out


def kernel_sources(root: Path = PACKAGE_ROOT, package: str = "swarmplan") -> list[Path]:
    """The kernel modules of ``package`` (those that import numba or this module's ``njit``)
    and every module of the package they import, directly or through each other."""
    texts = {p: p.read_text(encoding="utf-8") for p in root.rglob("*.py") if "__pycache__" not in p.parts}
    todo = [p for p, text in texts.items() if _KERNEL.search(text)]
    seen = set(todo)
    while todo:
        for dep in _imports(root, package, texts[todo.pop()]):
            if dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return sorted(seen)


def kernel_digest(root: Path = PACKAGE_ROOT, package: str = "swarmplan") -> str:
    """SHA-256 over the path and content of each of :func:`kernel_sources`."""
    h = hashlib.sha256()
    for path in kernel_sources(root, package):
        data = path.read_bytes()
        h.update(f"{path.relative_to(root).as_posix()}:{len(data)};".encode())
        h.update(data)
    return h.hexdigest()


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-"):
            pass
    except OSError:
        return False
    return True


def _trim(base: Path, own: Path) -> None:
    """Remove all but the ``KEEP`` most recently used folders of compiled code in ``base``."""
    try:
        folders = sorted(
            (p for p in base.glob(PREFIX + "*") if p.is_dir() and p != own),
            key=lambda p: p.stat().st_mtime,
            reverse=True,
        )
    except OSError:
        return
    for old in folders[KEEP - 1 :]:
        shutil.rmtree(old, ignore_errors=True)


_POINTED: dict[tuple[Path, str], Path] = {}


def use_kernel_cache(root: Path, package: str) -> Path:
    """Point numba's on-disk cache at the folder of ``package``'s :func:`kernel_digest` (once per
    process and package; call it before the package's first compiled function is defined)."""
    key = (root, package)
    if key in _POINTED:
        return _POINTED[key]
    name = PREFIX + kernel_digest(root, package)[:16]
    inherited = os.environ.get("NUMBA_CACHE_DIR", "")
    if inherited and Path(inherited).name.startswith(PREFIX):  # set by the process that started this one
        base = Path(inherited).parent
    elif inherited:
        base = Path(inherited)
    else:
        base = root / "__pycache__"
        if not _writable(base):
            base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "numba"
    folder = base / name
    if not folder.is_dir():
        _trim(base, folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.utime(folder)  # recently used: the last to be removed
    except OSError:  # numba then warns that it cannot cache, and compiles in memory
        pass
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    if "numba.core.config" in sys.modules:  # already imported: its settings too
        sys.modules["numba.core.config"].CACHE_DIR = str(folder)
    _POINTED[key] = folder
    return folder

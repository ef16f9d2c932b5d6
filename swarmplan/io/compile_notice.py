"""Saying that the kernels are compiling, instead of looking frozen.

The first runs on a machine compile the numba kernels they use (15-30 s of CPU in all on the
first world; a world that needs other kernels, fixed wings or a swarm of 49 agents or
more, compiles those when it first runs); later runs load them from numba's cache in
milliseconds each. :class:`CompileNotice` watches numba's compiler lock from a background
thread while a run goes on: numba holds it while it loads a cached kernel (milliseconds) or
compiles one (seconds), so a lock held for longer than ``patience`` means compiling, and the
notice is written once. Once said, a file in the cache folder
(:func:`swarmplan.runtime.disk_cache.cache_dir`, keyed by the package's version and the Python
and numba installations) keeps later runs from saying it again: the notice is for the first
run on a machine, not for each world. Nothing is imported for the watching: until a kernel
loads, numba is not in the process and there is nothing to watch.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from swarmplan import __version__
from swarmplan.runtime.disk_cache import cache_dir

COMPILE_NOTICE = (
    "compiling the numerical kernels for this machine, once: this run takes longer (about "
    "15-30 s on an idle machine); later runs load them from the cache"
)


def said_marker() -> Path | None:
    """The file whose presence says the notice was given on this machine for this version of
    the package, Python and numba (None when the cache folder is off)."""
    folder = cache_dir()
    if folder is None:
        return None
    spec = importlib.util.find_spec("numba")
    numba = os.stat(spec.origin) if spec is not None and spec.origin else None
    key = f"{__version__};{sys.version};{numba and (spec.origin, numba.st_size, numba.st_mtime_ns)}"
    return folder / f"compile-notice-{hashlib.sha256(key.encode()).hexdigest()[:16]}"


def _numba_compiler_lock() -> Any:
    """numba's global compiler lock (a threading lock), or None while numba is not loaded."""
    module = sys.modules.get("numba.core.compiler_lock")
    return getattr(getattr(module, "global_compiler_lock", None), "_lock", None)


class CompileNotice:
    """Writes :data:`COMPILE_NOTICE` with ``write`` once when the compiler lock stays held for
    ``patience`` seconds (checked every ``interval`` s) between :meth:`start` and :meth:`stop`,
    unless the ``marker`` file says it was said before; a notice said leaves the marker at
    :meth:`stop`. ``compiled`` tells whether this run compiled (said or not), ``said`` whether
    it wrote the notice."""

    def __init__(
        self,
        write: Callable[[str], None] | None = None,
        patience: float = 1.0,
        interval: float = 0.2,
        lock: Callable[[], Any] = _numba_compiler_lock,
        marker: Path | None = None,
    ):
        self.write = write if write is not None else (lambda text: print(text, file=sys.stderr))
        self.patience = patience
        self.interval = interval
        self.lock = lock
        self.marker = marker
        self.said = False
        self.compiled = False
        self._quiet = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> CompileNotice:
        self._quiet = self.marker is not None and self.marker.exists()  # said on this machine before
        self._thread = threading.Thread(target=self._watch, name="compile-notice", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self.said and self.marker is not None:
            try:
                self.marker.parent.mkdir(parents=True, exist_ok=True)
                self.marker.touch()
            except OSError:  # a cache that cannot be written: the notice comes again, nothing else
                pass

    def _watch(self) -> None:
        held_since: float | None = None
        while not self._stop.wait(self.interval):
            lock = self.lock()
            if lock is None:
                continue
            if lock.acquire(blocking=False):
                lock.release()
                held_since = None
                continue
            now = time.monotonic()
            held_since = now if held_since is None else held_since
            if now - held_since >= self.patience:
                self.compiled = True
                if not self._quiet:
                    self.write(COMPILE_NOTICE)
                    self.said = True
                return

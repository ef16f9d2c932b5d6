"""Saying that the kernels are compiling, instead of looking frozen.

The first run on a machine compiles the numba kernels it uses (10-30 s in all); later runs
load them from numba's cache in milliseconds each. :class:`CompileNotice` watches numba's
compiler lock from a background thread while a run goes on: numba holds it while it loads a
cached kernel (milliseconds) or compiles one (seconds), so a lock held for longer than
``patience`` means compiling, and the notice is written once. Nothing is imported for it:
until a kernel loads, numba is not in the process and there is nothing to watch.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import Any

COMPILE_NOTICE = (
    "compiling the numerical kernels for this machine (the first run takes about 10-30 s "
    "longer, once; later runs load them in under a second)"
)


def _numba_compiler_lock() -> Any:
    """numba's global compiler lock (a threading lock), or None while numba is not loaded."""
    module = sys.modules.get("numba.core.compiler_lock")
    return getattr(getattr(module, "global_compiler_lock", None), "_lock", None)


class CompileNotice:
    """Writes :data:`COMPILE_NOTICE` with ``write`` once when the compiler lock stays held for
    ``patience`` seconds (checked every ``interval`` s) between :meth:`start` and :meth:`stop`."""

    def __init__(
        self,
        write: Callable[[str], None],
        patience: float = 1.0,
        interval: float = 0.2,
        lock: Callable[[], Any] = _numba_compiler_lock,
    ):
        self.write = write
        self.patience = patience
        self.interval = interval
        self.lock = lock
        self.said = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> CompileNotice:
        self._thread = threading.Thread(target=self._watch, name="compile-notice", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()

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
                self.write(COMPILE_NOTICE)
                self.said = True
                return

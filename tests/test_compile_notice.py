"""A run that compiles kernels says so once: the notice follows numba's compiler lock (held for
more than a moment means compiling, not loading from the cache)."""

from __future__ import annotations

import threading
import time

from swarmplan.io.compile_notice import COMPILE_NOTICE, CompileNotice, _numba_compiler_lock


def _watch(lock, seconds: float) -> list[str]:
    said: list[str] = []
    notice = CompileNotice(said.append, patience=0.3, interval=0.05, lock=lambda: lock).start()
    time.sleep(seconds)
    notice.stop()
    return said


def test_a_compiler_lock_held_long_is_said_once():
    lock = threading.Lock()
    lock.acquire()
    try:
        assert _watch(lock, 0.8) == [COMPILE_NOTICE]
    finally:
        lock.release()


def test_a_free_lock_or_no_numba_says_nothing():
    assert _watch(threading.Lock(), 0.5) == []
    assert _watch(None, 0.3) == []


def test_a_short_hold_is_a_cache_load_not_a_compile():
    lock = threading.Lock()

    def blink():
        for _ in range(10):
            with lock:
                time.sleep(0.05)
            time.sleep(0.03)

    t = threading.Thread(target=blink)
    t.start()
    said = _watch(lock, 0.8)
    t.join()
    assert said == []


def test_numba_s_lock_is_found_once_numba_is_loaded():
    import numba  # noqa: F401  (the package's kernels load it the same way)

    lock = _numba_compiler_lock()
    assert lock.acquire(blocking=False)
    lock.release()

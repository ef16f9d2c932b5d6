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
    notice = CompileNotice(lambda text: None, patience=0.2, interval=0.05, lock=threading.Lock)
    notice.start()
    time.sleep(0.4)
    notice.stop()
    assert not notice.compiled and not notice.said


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


def test_the_notice_is_said_once_per_machine_not_once_per_run(tmp_path):
    """Said once, a marker file keeps a later run (another world that compiles more kernels)
    from saying it again; either run tells that it compiled (``compiled``: its speed figure
    says so)."""
    marker = tmp_path / "cache" / "compile-notice-x"
    lock = threading.Lock()
    lock.acquire()
    try:
        for expected in ([COMPILE_NOTICE], []):
            said: list[str] = []
            notice = CompileNotice(said.append, patience=0.2, interval=0.05, lock=lambda: lock, marker=marker)
            notice.start()
            time.sleep(0.5)
            notice.stop()
            assert said == expected and notice.said == bool(expected) and notice.compiled
            assert marker.exists()
    finally:
        lock.release()


def test_the_run_summary_says_when_its_speed_includes_compiling():
    from swarmplan.cli.run import format_summary

    agent = {"id": "a", "arrived": True, "final_mode": "arrived", "arrival_time": 10.0, "path_length": 80.0,
             "length_ratio": 1.0, "min_clearance": 5.0, "max_curvature": 0.0, "curvature_limit": 0.06,
             "max_lateral_accel": 0.0, "lateral_accel_limit": 4.0, "cusps": 0, "collisions": 0,
             "stuck_events": 0, "escapes": 0}  # fmt: skip
    summary = {"agents": [agent], "success": True, "interrupted": False, "arrived": 0, "agents_total": 0,
               "collisions": 0, "sim_time": 10.0, "wall_time": 20.0, "world": "w", "seed": 0,
               "optimizer": "none"}  # fmt: skip
    assert "(0.5 sim-s/s, compiling included)" in format_summary(summary, None, compiled=True)
    assert "(0.5 sim-s/s)" in format_summary(summary, None)

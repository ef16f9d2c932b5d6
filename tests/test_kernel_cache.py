"""A first run says that kernels are compiling: which kernel modules have no fresh numba cache,
which ones a world's run loads, and the notice printed once."""

from __future__ import annotations

import io
import os
import sys
from pathlib import Path

from helpers import base_world, make_world

from swarmplan.io import runner
from swarmplan.runtime.kernel_cache import COMPILE_NOTICE, kernel_modules, uncompiled_kernel_modules


def test_a_kernel_is_compiled_while_its_cache_index_is_newer_than_its_source(tmp_path: Path):
    src = tmp_path / "_k.py"
    src.write_text("from numba import njit\n\n\n@njit(cache=True)\ndef f(x):\n    return x\n")
    (tmp_path / "plain.py").write_text("'''no kernel here: @njit(cache=True) in a docstring'''\n")
    assert kernel_modules(tmp_path) == [src]
    assert uncompiled_kernel_modules([src]) == [src]
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    index = cache / f"_k.f-4.py{sys.version_info.major}{sys.version_info.minor}.nbi"
    index.write_bytes(b"")
    t = src.stat().st_mtime
    os.utime(index, (t + 5, t + 5))
    assert uncompiled_kernel_modules([src]) == []
    os.utime(src, (t + 10, t + 10))  # the source changed since: compiles again
    assert uncompiled_kernel_modules([src]) == [src]


def test_the_modules_a_run_loads():
    swarm = make_world(
        base_world(
            agents=[{"id": f"a{i}", "start": [5 + i, 5, 20], "goal": [5 + i, 95, 20]} for i in range(49)]
        )
    )
    small = make_world(base_world())
    names = {p.name for p in runner.kernel_modules_for(swarm)}
    assert {"sweep_kernels.py", "_record_kernels.py", "_apf_kernel.py", "_field_kernels.py"} <= names
    assert all(p.exists() for p in runner.kernel_modules_for(small))
    assert "_record_kernels.py" not in {p.name for p in runner.kernel_modules_for(small)}
    assert set(runner.kernel_modules_for(swarm)) <= set(kernel_modules())


def test_the_notice_is_printed_once_when_something_compiles(tmp_path: Path, monkeypatch):
    world = make_world(base_world(sim={"dt": 0.1, "max_time": 0.3, "goal_tolerance": 2.0}))
    for stale, expected in (([Path("x.py")], 1), ([], 0)):
        monkeypatch.setattr(runner, "uncompiled_kernel_modules", lambda mods, s=stale: s)
        out = io.StringIO()
        runner.simulate(world, 0, tmp_path / "r.mcap", stream=out, notices=True)
        assert out.getvalue().count(COMPILE_NOTICE) == expected

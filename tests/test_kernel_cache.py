"""numba's on-disk cache of the compiled kernels is keyed on the sources of every kernel and of
what it calls (``swarmplan.runtime.compiled``): an edited callee in another file is compiled
afresh, never run stale from the cache."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from swarmplan.runtime import compiled

ROOT = Path(__file__).resolve().parents[1]

RUN = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    sys.path[:0] = [{root!r}, {tmp!r}]
    from swarmplan.runtime.compiled import use_kernel_cache
    folder = use_kernel_cache(Path({tmp!r}) / "kpkg", "kpkg")
    from kpkg.entry import f
    print(f(), sum(f.stats.cache_hits.values()), folder.name)
    """
)


def _run(tmp: Path) -> tuple[int, int, str]:
    """The kernel's value, its cache hits and its cache folder, in a fresh process. The process
    writes no bytecode (``-B``): a source edited to the same size within the same second would
    otherwise be run from its stale bytecode by Python itself, before numba sees it."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    out = subprocess.run(
        [sys.executable, "-B", "-c", RUN.format(root=str(ROOT), tmp=str(tmp))],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    value, hits, folder = out.stdout.split()
    return int(value), int(hits), folder


def test_an_edited_callee_in_another_file_is_compiled_afresh(tmp_path: Path) -> None:
    pkg = tmp_path / "kpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    callee = "from numba import njit\n\n\n@njit(cache=True)\ndef g():\n    return {}\n"
    (pkg / "callee.py").write_text(callee.format(1))
    (pkg / "entry.py").write_text(
        "from numba import njit\n\nfrom kpkg.callee import g\n\n\n"
        "@njit(cache=True)\ndef f():\n    return g() + 10\n"
    )
    first = _run(tmp_path)
    again = _run(tmp_path)
    assert first[:2] == (11, 0)  # compiled
    assert again == (11, 1, first[2])  # read back from the cache
    # The same size, possibly the same modification time: only the content tells.
    (pkg / "callee.py").write_text(callee.format(2))
    edited = _run(tmp_path)
    assert edited[0] == 12 and edited[2] != first[2]
    assert _run(tmp_path) == (12, 1, edited[2])
    # The folder of the first sources is kept (a few are), in the package's __pycache__.
    assert (pkg / "__pycache__" / first[2]).is_dir() and (pkg / "__pycache__" / edited[2]).is_dir()


def test_the_digest_covers_every_kernel_and_the_kernels_it_calls() -> None:
    sources = {p.relative_to(compiled.PACKAGE_ROOT).as_posix() for p in compiled.kernel_sources()}
    kernels = {
        p.relative_to(compiled.PACKAGE_ROOT).as_posix()
        for p in compiled.PACKAGE_ROOT.rglob("*.py")
        if "kernel" in p.name
    }
    assert kernels and kernels <= sources
    assert "optimizers/_kernels.py" in sources  # called by the bat's and the baselines' kernels


def test_every_compiled_function_takes_njit_from_the_loader() -> None:
    direct = [
        p.relative_to(compiled.PACKAGE_ROOT).as_posix()
        for p in compiled.PACKAGE_ROOT.rglob("*.py")
        if p.parent.name != "runtime" and "from numba import" in p.read_text(encoding="utf-8")
    ]
    assert direct == []


RACE = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    sys.path[:0] = [{root!r}, {tmp!r}]
    from racepkg.entry import f
    tmp = Path({tmp!r})
    (tmp / "ready-{i}").touch()
    while not all((tmp / f"ready-{{j}}").exists() for j in (0, 1)):
        time.sleep(0.005)
    print(f(3), sum(f.stats.cache_misses.values()), sum(f.stats.cache_hits.values()))
    """
)


def test_processes_needing_a_kernel_at_once_compile_it_once(tmp_path: Path) -> None:
    """Two processes call a kernel nobody has compiled, at the same moment: one compiles it, the
    other waits on its lock and reads it from the cache."""
    pkg = tmp_path / "racepkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "entry.py").write_text(
        "from swarmplan.runtime.compiled import njit\n\n\n@njit(cache=True)\ndef f(n):\n"
        "    s = 0\n    for i in range(n):\n        s += i * i\n    return s\n"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", RACE.format(root=str(ROOT), tmp=str(tmp_path), i=i)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        for i in (0, 1)
    ]
    outs = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [err for _, err in outs]
    results = sorted(tuple(int(x) for x in out.split()) for out, _ in outs)
    assert results == [(5, 0, 1), (5, 1, 0)]  # 0 + 1 + 4; one compiled, one read it back

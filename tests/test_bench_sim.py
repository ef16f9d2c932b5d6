"""``python -m swarmplan.bench sim --world``: its speed figure and verdict, and a run that
compiled kernels inside the timed loop says so instead of judging the target."""

from __future__ import annotations

from pathlib import Path

import pytest

from swarmplan.bench.sim import verdict
from swarmplan.cli.bench import main as bench_main

ROOT = Path(__file__).resolve().parents[1]


class _Compiled:
    """A compile watcher that saw numba compiling (what a fresh cache does in the loop)."""

    compiled = True

    def __init__(self, write=None) -> None:  # noqa: ANN001
        pass

    def start(self) -> _Compiled:
        return self

    def stop(self) -> None:
        pass


@pytest.mark.parametrize("compiled", [False, True])
def test_fixed_wing_world_figure_and_verdict(compiled, monkeypatch, capsys):
    if compiled:
        monkeypatch.setattr("swarmplan.io.compile_notice.CompileNotice", _Compiled)
    code = bench_main(["sim", "--world", str(ROOT / "worlds" / "fixed_wing.yaml"), "--sim-time", "3"])
    out = capsys.readouterr().out
    assert code == 0
    (figure,) = [line for line in out.splitlines() if line.startswith("sim-seconds per wall-second")]
    (target,) = [line for line in out.splitlines() if line.startswith("target: >= 30x")]
    assert ("compiling included" in figure) == compiled
    rtf = float(figure.split(":")[1].split()[0])
    assert target.endswith(verdict(rtf, 30.0, compiled))


def test_verdict():
    assert verdict(30.0, 30.0, False) == verdict(31.0, 30.0, True) == "met"
    assert verdict(29.9, 30.0, False) == "NOT met"
    assert verdict(29.9, 30.0, True) == "not judged (compiling included)"

"""Every command line ends quietly when the reader of its output has gone (``... | head``):
no traceback, exit status 141 (128 + SIGPIPE, as a shell reports a program that signal ends),
and a run's log is still finished. Standard output is a pipe whose read end is closed before
the program starts, so its first write fails every time."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from swarmplan.cli.common import EXIT_CLOSED_STDOUT, quiet_on_closed_stdout

ROOT = Path(__file__).resolve().parents[1]
CLI = sorted(
    p.stem for p in (ROOT / "swarmplan" / "cli").glob("*.py") if p.stem not in ("__init__", "common")
)


def run_into_closed_pipe(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        env = dict(os.environ, PYTHONPATH=str(ROOT))  # this checkout's package, wherever cwd is
        return subprocess.run(
            [sys.executable, *args],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            cwd=cwd,
            timeout=120,
            env=env,
        )
    finally:
        os.close(write_end)


@pytest.fixture(scope="module")
def closed_run(tmp_path_factory) -> tuple[subprocess.CompletedProcess, Path]:
    """A 1 s quickstart run whose summary table goes into a closed pipe, and its log."""
    tmp = tmp_path_factory.mktemp("closed")
    log = tmp / "q.mcap"
    world = str(ROOT / "worlds" / "quickstart.yaml")
    out = run_into_closed_pipe(["-m", "swarmplan.run", world, "--max-time", "1", "--out", str(log)], tmp)
    return out, log


def test_a_run_into_a_closed_pipe_ends_quietly_and_finishes_its_log(closed_run):
    from swarmplan.replay import load

    out, log = closed_run
    assert out.returncode == EXIT_CLOSED_STDOUT
    assert "Traceback" not in out.stderr and "BrokenPipe" not in out.stderr, out.stderr
    rec = load(log)
    assert rec.summary is not None and rec.summary["interrupted"] is False


@pytest.mark.parametrize("program", ["replay", "track"])
def test_reading_a_log_into_a_closed_pipe_ends_quietly(program, closed_run, tmp_path):
    out = run_into_closed_pipe(["-m", f"swarmplan.{program}", str(closed_run[1])], tmp_path)
    assert (out.returncode, out.stderr) == (EXIT_CLOSED_STDOUT, "")


def test_every_command_line_main_is_wrapped():
    """Each ``swarmplan.cli`` program's ``main`` (the console scripts' entry points too) is the
    wrapper of :func:`quiet_on_closed_stdout`."""
    wrapper_code = quiet_on_closed_stdout(lambda: 0).__code__
    assert {"run", "replay", "track", "sweep", "compare", "bench"} <= set(CLI)
    unwrapped = [
        m for m in CLI if importlib.import_module(f"swarmplan.cli.{m}").main.__code__ is not wrapper_code
    ]
    assert unwrapped == []


def test_an_open_stdout_keeps_the_programs_status(capsys):
    @quiet_on_closed_stdout
    def main() -> int:
        print("fine")
        return 3

    assert main() == 3
    assert capsys.readouterr().out == "fine\n"


def test_a_broken_pipe_elsewhere_still_raises():
    """Only a closed standard output is ended quietly: a worker's or a socket's broken pipe is
    an error of the program."""

    @quiet_on_closed_stdout
    def main() -> int:
        raise BrokenPipeError(32, "Broken pipe")

    with pytest.raises(BrokenPipeError):
        main()

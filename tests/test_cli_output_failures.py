"""Every command line fails on an output it cannot write with one line naming the problem on
standard error and status 2, never a traceback: standard output on a full device
(``> /dev/full``) or closed (``>&-``), and a log whose writing fails part way (no space left).
A reader that has gone (``| head``) is tests/test_cli_closed_stdout.py's."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from swarmplan.cli.common import EXIT_BAD_OUTPUT, quiet_on_closed_stdout

ROOT = Path(__file__).resolve().parents[1]
WORLD = str(ROOT / "worlds" / "quickstart.yaml")
FULL = Path("/dev/full")
needs_full = pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")


def run(args: list[str], cwd: Path, stdout=None, close_stdout: bool = False) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *args],
        stdout=stdout,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),  # this checkout's package, wherever cwd is
        timeout=120,
        preexec_fn=(lambda: os.close(1)) if close_stdout else None,
    )


def one_line(out: subprocess.CompletedProcess) -> str:
    assert "Traceback" not in out.stderr, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    return lines[0]


@pytest.fixture(scope="module")
def log(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("full")
    path = tmp / "q.mcap"
    out = run(["-m", "swarmplan.run", WORLD, "--max-time", "1", "--out", str(path), "--quiet"], tmp)
    assert out.returncode in (0, 1) and path.exists(), out.stderr
    return path


@needs_full
def test_a_run_onto_a_full_device_says_so_and_finishes_its_log(tmp_path):
    from swarmplan.replay import load

    path = tmp_path / "q.mcap"
    with FULL.open("w") as full:
        out = run(["-m", "swarmplan.run", WORLD, "--max-time", "1", "--out", str(path)], tmp_path, full)
    assert out.returncode == EXIT_BAD_OUTPUT
    assert one_line(out) == "error: standard output: cannot write (No space left on device)"
    rec = load(path)  # the table comes after the log is closed: the log is whole
    assert rec.summary is not None and rec.summary["interrupted"] is False


@needs_full
@pytest.mark.parametrize("program", ["replay", "track"])
def test_reading_a_log_onto_a_full_device_says_so(program, log, tmp_path):
    with FULL.open("w") as full:
        out = run(["-m", f"swarmplan.{program}", str(log)], tmp_path, full)
    assert out.returncode == EXIT_BAD_OUTPUT
    assert "cannot write (No space left on device)" in one_line(out)


@needs_full
@pytest.mark.parametrize("program", ["compare", "sweep", "bench"])
def test_help_onto_a_full_device_says_so(program, tmp_path):
    # argparse drops a failed write of its help silently; the command does not.
    with FULL.open("w") as full:
        out = run(["-m", f"swarmplan.{program}", "--help"], tmp_path, full)
    assert out.returncode == EXIT_BAD_OUTPUT
    assert "cannot write (No space left on device)" in one_line(out)


@pytest.mark.parametrize("program", ["run", "replay"])
def test_a_closed_stdout_is_refused_before_any_work(program, log, tmp_path):
    args = (
        [WORLD, "--max-time", "1", "--out", str(tmp_path / "never.mcap")] if program == "run" else [str(log)]
    )
    out = run(["-m", f"swarmplan.{program}", *args], tmp_path, close_stdout=True)
    assert out.returncode == EXIT_BAD_OUTPUT
    assert one_line(out) == "error: standard output: cannot write (it is closed)"
    assert not (tmp_path / "never.mcap").exists()


@needs_full
def test_a_log_that_cannot_be_written_ends_in_one_line(tmp_path):
    full_log = tmp_path / "full.mcap"
    full_log.symlink_to(FULL)  # a writable path whose writes fail: no space left
    out = run(["-m", "swarmplan.run", WORLD, "--max-time", "2", "--out", str(full_log)], tmp_path)
    assert out.returncode == 2
    assert one_line(out) == f"error: {full_log}: cannot write the log (No space left on device)"


def test_another_os_error_is_not_taken_for_stdout(capsys):
    @quiet_on_closed_stdout
    def main() -> int:
        print("fine")
        raise OSError(5, "Input/output error", "some.file")

    with pytest.raises(OSError):
        main()
    assert capsys.readouterr().out == "fine\n"

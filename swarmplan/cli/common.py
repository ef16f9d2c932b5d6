"""What the command-line programs share: output-path checks (:mod:`swarmplan.runtime.paths`),
help text, and a quiet end when the reader of their output goes away."""

from __future__ import annotations

import argparse
import contextlib
import functools
import logging
import os
import re
import sys
from collections.abc import Callable, Iterator
from typing import Any, ParamSpec, TextIO

from swarmplan.runtime.paths import output_dir_problem, output_file_problem

__all__ = [
    "EXIT_BAD_OUTPUT",
    "EXIT_CLOSED_STDOUT",
    "HelpFormatter",
    "output_dir_problem",
    "output_file_problem",
    "plain",
    "write_failure",
    "writer_messages",
    "quiet_on_closed_stdout",
]

EXIT_CLOSED_STDOUT = 141
"""Exit status when standard output was closed by its reader (``... | head``): 128 + SIGPIPE,
what a shell reports for a program that signal ends."""

_P = ParamSpec("_P")


def quiet_on_closed_stdout(main: Callable[_P, int]) -> Callable[_P, int]:
    """``main``, ending quietly (no traceback, status :data:`EXIT_CLOSED_STDOUT`) when standard
    output is a pipe whose reader has gone (``python -m swarmplan.run W | head -3``). What was
    buffered is flushed before returning, so a failing write shows here and not at the
    interpreter's exit; a broken pipe elsewhere (a worker, a socket) still raises.

    Any other failure to write standard output (``> /dev/full``: no space left; a closed file
    descriptor, ``>&-``, found before any work) ends the program with one line naming the
    problem on standard error and status :data:`EXIT_BAD_OUTPUT`, never a traceback. A run has
    finished its log by the time it prints (the log is closed whatever happens to the table)."""

    @functools.wraps(main)
    def run(*args: _P.args, **kwargs: _P.kwargs) -> int:
        if sys.stdout is None:  # file descriptor 1 closed when the program started
            return _say("error: standard output: cannot write (it is closed)")
        watched = _Watched(sys.stdout)
        sys.stdout = watched
        try:
            try:
                code = main(*args, **kwargs)
            except SystemExit:  # argparse's --help (which hides a failed write) and usage errors
                watched.flush()
                if watched.failure is not None:
                    raise watched.failure from None
                raise
            watched.flush()
            return code
        except BrokenPipeError:
            if not _stdout_closed():
                raise
            _discard_stdout()
            return EXIT_CLOSED_STDOUT
        except (OSError, ValueError) as exc:
            if watched.failure is None:
                raise
            _discard_stdout()
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            return _say(f"error: standard output: cannot write ({reason})")
        finally:
            if sys.stdout is watched:
                sys.stdout = watched.stream

    return run


class _Watched:
    """Standard output, remembering a failed write (anything but a reader that has gone)."""

    def __init__(self, stream: TextIO):
        self.stream = stream
        self.failure: OSError | ValueError | None = None

    def _guard(self, call: Callable[[], int | None]) -> int | None:
        try:
            return call()
        except BrokenPipeError:
            raise
        except (OSError, ValueError) as exc:
            self.failure = exc
            raise

    def write(self, text: str) -> int | None:
        return self._guard(lambda: self.stream.write(text))

    def flush(self) -> None:
        self._guard(self.stream.flush)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


EXIT_BAD_OUTPUT = 2
"""Exit status when standard output cannot be written (other than a reader that has gone)."""


class WriterMessages(logging.Handler):
    """What the MCAP writer (foxglove-sdk, logger ``foxglove``) complains about while a command
    writes a log: kept instead of printed (it says it once per message it could not write), so a
    failed write ends in one line; :func:`writer_messages` passes them on when nothing failed."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        if len(self.records) < 100:
            self.records.append(record)

    def first_reason(self) -> str | None:
        """The OS's reason in the first complaint (e.g. 'No space left on device'), if any."""
        for record in self.records:
            found = re.search(r'message: "([^"]+)"', record.getMessage())
            if found:
                return found.group(1)
        return None


@contextlib.contextmanager
def writer_messages() -> Iterator[WriterMessages]:
    """Collect the MCAP writer's complaints while the block writes (see :class:`WriterMessages`);
    when the block ends without an error they are logged as they would have been."""
    logger = logging.getLogger("foxglove")
    handler, propagate = WriterMessages(), logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    failed = True
    try:
        yield handler
        failed = False
    finally:
        logger.removeHandler(handler)
        logger.propagate = propagate
        if not failed:
            for record in handler.records:
                logger.handle(record)


def write_failure(exc: BaseException, messages: WriterMessages | None = None) -> str | None:
    """Why writing an output file failed, from the error writing it raised (an ``OSError``, or the
    MCAP writer's ``RuntimeError``, whose reason ``messages`` may hold), or None when ``exc`` is
    something else."""
    if isinstance(exc, OSError):
        return exc.strerror or str(exc)
    text = str(exc)
    if isinstance(exc, RuntimeError) and "MCAP error" in text:
        reason = messages.first_reason() if messages is not None else None
        return reason or text.split("MCAP error:", 1)[1].strip() or text
    return None


def _say(line: str) -> int:
    """``line`` on standard error (if that can be written at all); returns :data:`EXIT_BAD_OUTPUT`."""
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError, AttributeError):
        pass
    return EXIT_BAD_OUTPUT


def _discard_stdout() -> None:
    """Python flushes stdout once more at exit: let that write go nowhere."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, sys.stdout.fileno())
        finally:
            os.close(devnull)
    except (OSError, ValueError, AttributeError):  # no file behind stdout (captured in-process)
        pass


def _stdout_closed() -> bool:
    """Whether standard output is a pipe its reader closed (it still holds unwritten bytes, or
    the pipe reports an error)."""
    if isinstance(sys.stdout, _Watched):
        sys.stdout = sys.stdout.stream
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        return True
    except (OSError, ValueError):
        return False
    try:
        import select

        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
    except (AttributeError, OSError, ValueError):  # no poll (Windows) or no file behind stdout
        return False
    return any(events & select.POLLERR for _, events in poller.poll(0))


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults shown once: not for options without a value (None, flags) nor when the help
    already says its default; descriptions keep their line breaks."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        help_text = action.help or ""
        if action.default is None or action.default is False or "default" in help_text.lower():
            return help_text
        return super()._get_help_string(action)


def plain(doc: str) -> str:
    """A module docstring as plain text for ``--help``: reStructuredText roles and literals
    (``:mod:`x```, ````x````) become their text."""
    doc = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", doc)
    return doc.replace("``", "").strip()


def comms_line(counts: dict[str, Any], oldest_max: float, oldest_mean: float) -> str:
    """One line on a run's messages (``/summary`` or ``/comms`` counts) and the ages acted on."""
    sent = int(counts.get("sent", 0))
    lost, far = int(counts.get("lost", 0)), int(counts.get("out_of_range", 0))
    share = f" ({100.0 * lost / sent:.1f} %)" if sent else ""
    return (
        f"comms: {sent} messages sent, {lost} lost{share}, {far} out of range; oldest state acted on: "
        f"{oldest_max:.3f} s at most, {oldest_mean:.3f} s on average"
    )

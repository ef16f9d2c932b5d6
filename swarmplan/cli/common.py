"""What the command-line programs share: output-path checks (:mod:`swarmplan.runtime.paths`),
help text, and a quiet end when the reader of their output goes away."""

from __future__ import annotations

import argparse
import functools
import os
import re
import sys
from collections.abc import Callable
from typing import ParamSpec

from swarmplan.runtime.paths import output_dir_problem, output_file_problem

__all__ = [
    "EXIT_CLOSED_STDOUT",
    "HelpFormatter",
    "output_dir_problem",
    "output_file_problem",
    "plain",
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
    interpreter's exit; a broken pipe elsewhere (a worker, a socket) still raises."""

    @functools.wraps(main)
    def run(*args: _P.args, **kwargs: _P.kwargs) -> int:
        try:
            try:
                code = main(*args, **kwargs)
            except SystemExit:  # argparse's --help and usage errors
                sys.stdout.flush()
                raise
            sys.stdout.flush()
            return code
        except BrokenPipeError:
            if not _stdout_closed():
                raise
            # Python flushes stdout once more at exit: let that write go nowhere.
            devnull = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(devnull, sys.stdout.fileno())
            finally:
                os.close(devnull)
            return EXIT_CLOSED_STDOUT

    return run


def _stdout_closed() -> bool:
    """Whether standard output is a pipe its reader closed (it still holds unwritten bytes, or
    the pipe reports an error)."""
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

"""What the command-line programs share: output-path checks (:mod:`swarmplan.runtime.paths`)
and help text."""

from __future__ import annotations

import argparse
import re

from swarmplan.runtime.paths import output_dir_problem, output_file_problem

__all__ = ["HelpFormatter", "output_dir_problem", "output_file_problem", "plain"]


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

"""``python -m swarmplan.run``: the command line lives in :mod:`swarmplan.cli.run`."""

import sys

from swarmplan.cli.run import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    apply_overrides,
    build_parser,
    check_planner_settings,
    format_summary,
    log_path_for,
    main,
    make_planner,
    simulate,
)

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_OK",
    "apply_overrides",
    "build_parser",
    "check_planner_settings",
    "format_summary",
    "log_path_for",
    "main",
    "make_planner",
    "simulate",
]

if __name__ == "__main__":
    sys.exit(main())

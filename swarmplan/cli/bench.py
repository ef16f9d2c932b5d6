"""``python -m swarmplan.bench SUBCOMMAND ...``: an argparse dispatcher over the benchmarks.

Each subcommand is a module with ``add_arguments(parser)`` and ``main(args) -> int``, and may have
``check_arguments(args) -> list[str]`` (every problem, printed here before any work). To add
one (e.g. ``sim``), write the module and add a line to :data:`SUBCOMMANDS`.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from swarmplan.cli.common import HelpFormatter, plain, quiet_on_closed_stdout
from swarmplan.runtime.blas import limit_blas_threads

#: subcommand name -> (module path, one-line help). Modules are imported lazily.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "optimizers": ("swarmplan.bench.optimizers", "run a paper benchmark suite over the optimizers"),
    "overhead": ("swarmplan.bench.overhead", "measure the library's own overhead per evaluation"),
    "scale": ("swarmplan.bench.scale", "speed figures at swarm scale, each beside its target"),
    "sim": ("swarmplan.bench.sim", "simulated seconds per wall second; wall time of the shipped worlds"),
    "swarm": ("swarmplan.bench.swarm", "dense swarms on the standard scenarios, beside ORCA-3D"),
    "reach": ("swarmplan.bench.reach", "random worlds of every class: is every reachable goal reached"),
    "export": (
        "swarmplan.export.bench",
        "random worlds exported to vehicles and flown again: --check pass rates",
    ),
    "docs": ("swarmplan.bench.docs", "re-run the commands behind the docs' tables and rewrite them"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m swarmplan.bench",
        description="Benchmarks: optimizers against their papers and peers, overhead, simulation speed.",
        formatter_class=HelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND")
    for name, (module_path, help_text) in SUBCOMMANDS.items():
        module = importlib.import_module(module_path)
        p = sub.add_parser(
            name,
            help=help_text,
            # help shows plain text: reStructuredText literals (``x``) become x
            description=plain(module.__doc__ or help_text),
        )
        module.add_arguments(p)
        p.formatter_class = HelpFormatter  # every subcommand's help alike: each default once
        p.set_defaults(_main=module.main, _check=getattr(module, "check_arguments", None))
    return parser


@quiet_on_closed_stdout
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    # a subcommand's check_arguments (where it has one) names every problem before any work
    problems = args._check(args) if args._check is not None else []
    if problems:
        for problem in problems:
            print(f"error: {problem}", file=sys.stderr)
        return 2
    limit_blas_threads()
    return int(args._main(args) or 0)


if __name__ == "__main__":
    sys.exit(main())

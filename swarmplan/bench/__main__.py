"""``python -m swarmplan.bench SUBCOMMAND ...``: an argparse dispatcher.

Each subcommand is a module with ``add_arguments(parser)`` and ``main(args) -> int``. To add
one (e.g. ``sim``), write the module and add a line to :data:`SUBCOMMANDS`.
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: subcommand name -> (module path, one-line help). Modules are imported lazily.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "optimizers": ("swarmplan.bench.optimizers", "run a paper benchmark suite over the optimizers"),
    "overhead": ("swarmplan.bench.overhead", "measure the library's own overhead per evaluation"),
    "scale": ("swarmplan.bench.scale", "issue 10's speed figures at swarm scale, each beside its target"),
    "sim": ("swarmplan.bench.sim", "simulated seconds per wall second; wall time of the shipped worlds"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m swarmplan.bench", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND")
    for name, (module_path, help_text) in SUBCOMMANDS.items():
        module = importlib.import_module(module_path)
        p = sub.add_parser(name, help=help_text, description=(module.__doc__ or help_text).strip())
        module.add_arguments(p)
        p.set_defaults(_main=module.main)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args._main(args) or 0)


if __name__ == "__main__":
    sys.exit(main())

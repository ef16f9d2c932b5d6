"""Regenerate the numeric tables of README.md and docs/*.md from the commands behind them.

A generated block in a markdown file is delimited by two HTML comments (invisible when the
page is rendered)::

    <!-- generated: NAME -->
    ...rewritten by this command...
    <!-- end: NAME -->

``python -m swarmplan.bench docs`` re-runs the command of every block found in the docs (or
of the blocks named in ``--only``) and rewrites the text between the markers: a stamp line
(commit, ``dirty`` when the work tree has changes, date, load average and the exact command)
and the table the command produced. Everything outside the markers is left byte for byte as
it was. An unknown block name, an unclosed or a nested block is an error (exit 2) before any
work. ``--list`` prints the known blocks. ``--resume`` reuses the finished runs' logs of an
earlier (or interrupted) sweep in ``--out-dir``, e.g. of ``python -m swarmplan.compare``
with the same ``--out-dir``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

_OPEN = re.compile(r"^<!-- generated: (?P<name>[A-Za-z0-9_.-]+) -->$")
_END = re.compile(r"^<!-- end: (?P<name>[A-Za-z0-9_.-]+) -->$")
_ANY = re.compile(r"^<!--\s*(generated|end)\b")  # a marker attempt, not a mention in prose


class DocsError(ValueError):
    """A problem with the markers of a file (its message names the file and line)."""


@dataclass(frozen=True)
class Options:
    quick: bool
    seeds: int | None  # None: each generator's default
    jobs: int
    out_dir: Path
    resume: bool


@dataclass(frozen=True)
class Block:
    """What a generator produced: the equivalent shell command(s) and the markdown body."""

    command: str
    body: str


@dataclass(frozen=True)
class Generator:
    name: str
    help: str
    run: Callable[[Options], Block]
    #: the options of :class:`Options` it reads (the stamp names only those)
    uses: frozenset[str] = frozenset()


# ----------------------------------------------------------------------------- markers


@dataclass(frozen=True)
class Span:
    name: str
    open_line: int  # 0-based index of the opening marker line
    end_line: int  # 0-based index of the end marker line


def find_blocks(text: str, source: str = "<text>") -> list[Span]:
    """The generated blocks of ``text``; :class:`DocsError` on a malformed marker."""
    spans: list[Span] = []
    current: tuple[str, int] | None = None
    for i, line in enumerate(text.split("\n")):
        stripped = line.strip()
        m_open, m_end = _OPEN.match(stripped), _END.match(stripped)
        if m_open:
            if current is not None:
                raise DocsError(
                    f"{source}:{i + 1}: block {m_open['name']!r} opens inside block {current[0]!r} "
                    f"(opened on line {current[1] + 1})"
                )
            current = (m_open["name"], i)
        elif m_end:
            if current is None:
                raise DocsError(
                    f"{source}:{i + 1}: end of block {m_end['name']!r} without its opening marker"
                )
            if m_end["name"] != current[0]:
                raise DocsError(
                    f"{source}:{i + 1}: end of block {m_end['name']!r} but block {current[0]!r} is open "
                    f"(since line {current[1] + 1})"
                )
            spans.append(Span(current[0], current[1], i))
            current = None
        elif _ANY.search(stripped):
            raise DocsError(
                f"{source}:{i + 1}: malformed marker {stripped!r}: write '<!-- generated: NAME -->' "
                "or '<!-- end: NAME -->' alone on a line"
            )
    if current is not None:
        raise DocsError(
            f"{source}:{current[1] + 1}: block {current[0]!r} is never closed ('<!-- end: {current[0]} -->')"
        )
    return spans


def rewrite(text: str, contents: dict[str, str], source: str = "<text>") -> str:
    """``text`` with the inside of every block named in ``contents`` replaced by its value.

    Blocks not in ``contents`` and everything outside the markers stay exactly as they were;
    the lines between the two markers become ``contents[name].split("\\n")`` (so a content
    that starts and ends with a newline keeps a blank line after and before the markers), and
    rewriting with the same contents is the identity.
    """
    lines = text.split("\n")
    out: list[str] = []
    pos = 0
    for span in find_blocks(text, source):
        if span.name not in contents:
            continue
        out += lines[pos : span.open_line + 1]
        out += contents[span.name].split("\n")
        pos = span.end_line
    out += lines[pos:]
    return "\n".join(out)


def stamp(block: Block, invocation: str, commit: str, when: datetime, load: float | None) -> str:
    """The first line of a generated block: where the numbers come from."""
    load_txt = f", load average {load:.1f} (2 cores)" if load is not None else ""
    return (
        f"_Generated at commit `{commit}` on {when:%Y-%m-%d %H:%M} UTC{load_txt} by `{invocation}`, "
        f"which ran: `{block.command}`._"
    )


def git_commit(root: Path = ROOT) -> str:
    """``git rev-parse --short HEAD``, plus ``dirty`` when tracked files have changes."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return f"{head} dirty" if dirty else head


# ----------------------------------------------------------------------------- generators

#: The optimizers of docs/comparison.md per paper world (first = the paper's own = reference).
COMPARISON: dict[str, list[str]] = {
    "iafsa_mountains": ["iafsa", "afsa", "woa", "rscdwoa", "ba", "iba_abc", "cfo", "mcfo", "abc"],
    "iba_battlefield": ["iba_abc", "ba", "iba_gauss", "woa", "rscdwoa", "cfo", "mcfo", "abc"],
    "mcfo_600m": ["mcfo", "cfo", "woa", "rscdwoa", "ba", "iba_abc", "abc"],
    "rscdwoa_multi_uav": ["rscdwoa", "woa", "ba", "iba_abc", "cfo", "mcfo", "abc"],
}


def _rel(path: Path) -> str:
    try:
        return path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return str(path)


def _comparison(stem: str) -> Callable[[Options], Block]:
    def run(opts: Options) -> Block:
        from swarmplan.sweep.engine import make_client, run_tasks
        from swarmplan.sweep.report import table, table_notes
        from swarmplan.sweep.spec import parse_spec

        names = COMPARISON[stem]
        seeds = opts.seeds or (2 if opts.quick else 10)
        world = ROOT / "worlds" / "papers" / f"{stem}.yaml"
        out_dir = opts.out_dir / "comparison" / stem
        # the same one-world study as `python -m swarmplan.compare` (same run ids: its logs resume)
        raw = {"name": "compare", "worlds": [world.name], "optimizers": names, "seeds": seeds}
        spec = parse_spec(raw, base_dir=world.parent, source="docs generator")
        client = make_client(opts.jobs, None)
        try:
            rows, reused = run_tasks(spec.tasks(), out_dir, [], client, resume=opts.resume)
        finally:
            cluster = getattr(client, "cluster", None)
            client.close()
            if cluster is not None:
                cluster.close()
        command = (
            f"python -m swarmplan.compare {_rel(world)} --optimizers {','.join(names)} --seeds {seeds} "
            f"--jobs {opts.jobs} --out-dir {_rel(out_dir)}"
        )
        ok = [r for r in rows if r["status"] == "ok"]
        collisions = sum(int(r["collisions"]) for r in ok)
        lines = [
            table(rows, names),
            "",
            f"{len(rows)} runs ({seeds} seeds, 0..{seeds - 1}, per optimizer), {len(rows) - len(ok)} "
            f"error(s), {collisions} collision(s) in total"
            + (f"; {reused} finished run(s) reused from the logs in `{_rel(out_dir)}`" if reused else "")
            + ".",
        ]
        lines += [f"- {n}" for n in table_notes(rows, names)]
        return Block(command, "\n".join(lines))

    return run


def _paper_worlds(opts: Options) -> Block:
    """Each paper world with its own seed and optimizer, timed (``bench sim --worlds`` per world)."""
    from swarmplan.io.runner import simulate
    from swarmplan.world import load_world

    paths = sorted((ROOT / "worlds" / "papers").glob("*.yaml"))
    rows = ["| world | result | sim s | wall s | sim-s per wall-s |", "|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory(prefix="swarmplan-docs-") as tmp:
        for path in paths:
            world = load_world(path)
            t0 = time.perf_counter()
            s = simulate(world, world.seed, Path(tmp) / f"{path.stem}.mcap")
            wall = time.perf_counter() - t0
            result = f"{s['arrived']}/{s['agents_total']} arrived, {s['collisions']} collision(s)"
            speed = s["sim_time"] / wall
            rows.append(f"| `{path.name}` | {result} | {s['sim_time']:.1f} | {wall:.1f} | {speed:.1f} |")
    command = "python -m swarmplan.run worlds/papers/NAME.yaml (each world's own seed and optimizer), timed"
    return Block(command, "\n".join(rows))


def _overhead(opts: Options) -> Block:
    from swarmplan.bench.overhead import measure
    from swarmplan.optimizers import available

    evals, repeats = (3000, 1) if opts.quick else (30_000, 3)
    rows = [
        "| algorithm | overhead µs/eval (min) | median | sphere µs/eval | rows per cost call |",
        "|---|---|---|---|---|",
    ]
    for name in available():
        m = measure(name, dim=50, evals=evals, repeats=repeats)
        rows.append(
            f"| {name} | {m['overhead_us_min']:.2f} | {m['overhead_us_median']:.2f} | "
            f"{m['cost_us']:.3f} | {m['rows_per_call']:.1f} |"
        )
    return Block(
        f"python -m swarmplan.bench overhead --dim 50 --evals {evals} --repeats {repeats}", "\n".join(rows)
    )


def _swarm_bench(opts: Options) -> Block:
    """The 64-agent, 16-mover bench world with rscdwoa escapes (docs/escape.md)."""
    sim_time = 10.0 if opts.quick else 60.0
    cmd = [
        sys.executable, "-m", "swarmplan.bench", "sim", "--agents", "64", "--movers", "16",
        "--sim-time", f"{sim_time:g}", "--optimizer", "rscdwoa",
    ]  # fmt: skip
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
    }
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[1:])} failed (exit {res.returncode}): {res.stderr.strip()[-500:]}")
    body = "```\n" + res.stdout.strip() + "\n```"
    return Block("python " + " ".join(cmd[1:]), body)


def _paper_table(name: str) -> Callable[[Options], Block]:
    def run(opts: Options) -> Block:
        from swarmplan.bench import paper_tables

        return Block(*getattr(paper_tables, name)(opts))

    return run


GENERATORS: dict[str, Generator] = {
    **{
        f"comparison-{stem}": Generator(
            f"comparison-{stem}",
            f"docs/comparison.md table of {stem}.yaml (sweep engine)",
            _comparison(stem),
            frozenset({"quick", "seeds", "jobs", "out_dir", "resume"}),
        )
        for stem in COMPARISON
    },
    "paper-worlds": Generator("paper-worlds", "run and wall time of each paper world", _paper_worlds),
    "overhead": Generator(
        "overhead", "optimizer overhead per evaluation at d = 50", _overhead, frozenset({"quick"})
    ),
    "table10": Generator(
        "table10",
        "000 Table 10 cell by cell, eq 10 literal and with the floor (5 runs, 3e5 evaluations)",
        _paper_table("table10"),
        frozenset({"quick", "seeds"}),
    ),
    "table4": Generator(
        "table4",
        "003 Table 4 (CEC2013) cell by cell at 3e5 evaluations (3 runs)",
        _paper_table("table4"),
        frozenset({"quick", "seeds"}),
    ),
    "shifted-peers": Generator(
        "shifted-peers",
        "shifted suite with mealpy/niapy peers, vs random search, best vs best (20 runs)",
        _paper_table("shifted_peers"),
        frozenset({"quick", "seeds"}),
    ),
    "rscdwoa-table4": Generator(
        "rscdwoa-table4",
        "001 Table 4 functions: each improved algorithm against its base (10 runs)",
        _paper_table("rscdwoa_table4"),
        frozenset({"quick", "seeds"}),
    ),
    "escape-swarm-bench": Generator(
        "escape-swarm-bench",
        "64 agents, 16 movers, rscdwoa escapes: wall time",
        _swarm_bench,
        frozenset({"quick"}),
    ),
}


# ----------------------------------------------------------------------------- command line


def doc_files(root: Path) -> list[Path]:
    """README.md and docs/*.md under ``root``."""
    files = [root / "README.md"] if (root / "README.md").is_file() else []
    return files + sorted((root / "docs").glob("*.md"))


def scan(files: list[Path], known: dict[str, Any]) -> tuple[dict[Path, list[Span]], list[str]]:
    """Blocks per file and every problem (malformed markers, unknown names)."""
    found: dict[Path, list[Span]] = {}
    problems: list[str] = []
    for f in files:
        try:
            spans = find_blocks(f.read_text(encoding="utf-8"), str(f))
        except DocsError as exc:
            problems.append(str(exc))
            continue
        for s in spans:
            if s.name not in known:
                problems.append(
                    f"{f}:{s.open_line + 1}: unknown generated block {s.name!r}; known: {', '.join(known)}"
                )
        found[f] = spans
    return found, problems


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--only", help="comma-separated block names; none = every block in the docs")
    p.add_argument("--quick", action="store_true", help="small budgets (2 seeds, short runs): a smoke test")
    p.add_argument(
        "--seeds", type=int, help="seeds per optimizer in the comparison tables; none = 10 (2 quick)"
    )
    p.add_argument("--jobs", type=int, default=2, help="worker processes for the sweeps")
    p.add_argument("--out-dir", default="logs/docs", help="where the runs' logs go")
    p.add_argument("--resume", action="store_true", help="reuse finished runs' logs in --out-dir")
    p.add_argument("--root", help="folder with README.md and docs/; none = this package's checkout")
    p.add_argument("--list", action="store_true", help="list the known blocks and exit")


def main(args: argparse.Namespace, generators: dict[str, Generator] | None = None) -> int:
    gens = GENERATORS if generators is None else generators
    if args.list:
        for g in gens.values():
            print(f"{g.name:28s} {g.help}")
        return 0
    root = Path(args.root) if args.root else ROOT
    files = doc_files(root)
    found, problems = scan(files, gens)
    present = {s.name for spans in found.values() for s in spans}
    if args.only:
        wanted = [n.strip() for n in args.only.split(",") if n.strip()]
        problems += [
            f"--only: unknown block {n!r}; known: {', '.join(gens)}" for n in wanted if n not in gens
        ]
        problems += [
            f"--only: block {n!r} is in no file under {root}"
            for n in wanted
            if n in gens and n not in present
        ]
    else:
        wanted = [n for n in gens if n in present]
    if args.seeds is not None and args.seeds < 1:
        problems.append(f"--seeds: must be >= 1, got {args.seeds}")
    if args.jobs < 1:
        problems.append(f"--jobs: must be >= 1, got {args.jobs}")
    if problems:
        for p in problems:
            print(f"error: {p}", file=sys.stderr)
        return 2
    opts = Options(args.quick, args.seeds, args.jobs, Path(args.out_dir), args.resume)
    commit = git_commit(ROOT)  # the code that makes the numbers, wherever the docs are
    given = {
        "quick": " --quick" if args.quick else "",
        "seeds": f" --seeds {args.seeds}" if args.seeds else "",
        "jobs": f" --jobs {args.jobs}" if args.jobs != 2 else "",
        "out_dir": f" --out-dir {args.out_dir}" if args.out_dir != "logs/docs" else "",
        "resume": " --resume" if args.resume else "",
    }
    for name in wanted:
        print(f"{name}: running ...", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        block = gens[name].run(opts)
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
        flags = "".join(v for k, v in given.items() if k in gens[name].uses)
        invocation = f"python -m swarmplan.bench docs --only {name}{flags}"
        # blank lines around the block: markdown ends the table before the end marker
        content = (
            "\n"
            + stamp(block, invocation, commit, datetime.now(timezone.utc), load)
            + "\n\n"
            + block.body
            + "\n"
        )
        for f, spans in found.items():
            if any(s.name == name for s in spans):
                text = f.read_text(encoding="utf-8")
                f.write_text(rewrite(text, {name: content}, str(f)), encoding="utf-8")
                print(f"{name}: rewrote {f} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    return 0

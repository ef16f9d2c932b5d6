"""The sweep spec: which worlds, optimizers, seeds and override grid make up a study.

A spec is validated as a whole before anything runs: every problem is collected (unknown
keys, globs matching nothing, unknown optimizers, bad seeds, override paths or values the
world format rejects) and raised together in one :class:`SpecError`.
"""

from __future__ import annotations

import copy
import difflib
import glob
import hashlib
import itertools
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from swarmplan import optimizers as registry
from swarmplan.sweep.adapter import OverrideError, build_world, read_raw, set_dotted
from swarmplan.world import WorldError

SPEC_KEYS = ("name", "worlds", "optimizers", "seeds", "overrides", "alpha")


class SpecError(Exception):
    """A sweep spec that cannot run; ``problems`` names every one of them."""

    def __init__(self, problems: list[str], source: str = "spec"):
        super().__init__(f"{source}: " + "; ".join(problems))
        self.problems = problems
        self.source = source


@dataclass(frozen=True)
class Task:
    """One run of the study: a world file with an optimizer, a seed and override values."""

    index: int
    world: str  # the world's label in the rows: its path relative to the spec's folder
    world_path: str  # absolute path of the world file
    optimizer: str
    seed: int
    overrides: tuple[tuple[str, Any], ...]  # (dotted path, value), in the spec's key order

    @property
    def key(self) -> tuple:
        """What identifies the run in the rows (and on --resume)."""
        return (self.world, self.optimizer, self.seed, _canon(self.overrides))

    @property
    def run_id(self) -> str:
        """File-name-safe id: readable parts plus a hash of the full key (values may be long)."""
        digest = hashlib.sha1(repr(self.key).encode()).hexdigest()[:8]
        # the file's name, wherever it lies (compare and sweep name the same runs alike); the
        # digest keeps worlds of the same name in different folders apart
        stem = re.sub(r"[^A-Za-z0-9_.=+-]+", "_", Path(self.world).stem)
        parts = [stem, self.optimizer, f"s{self.seed}"]
        parts += [f"{k.rsplit('.', 1)[-1]}={_short(v)}" for k, v in self.overrides]
        readable = re.sub(r"[^A-Za-z0-9_.=+-]+", "_", "-".join(parts))[:120]
        return f"{readable}-{digest}"


@dataclass(frozen=True)
class Spec:
    name: str
    source: Path
    worlds: tuple[tuple[str, str], ...]  # (label, absolute path)
    optimizers: tuple[str, ...]
    seeds: tuple[int, ...]
    overrides: tuple[tuple[str, tuple[Any, ...]], ...]
    alpha: float

    @property
    def override_keys(self) -> list[str]:
        return [k for k, _ in self.overrides]

    def tasks(self) -> list[Task]:
        """Every run, in a fixed order: world, override combination, optimizer, seed."""
        combos = list(itertools.product(*(vals for _, vals in self.overrides)))
        out: list[Task] = []
        for label, path in self.worlds:
            for combo in combos:
                ovr = tuple(zip(self.override_keys, combo, strict=True))
                for opt in self.optimizers:
                    for seed in self.seeds:
                        out.append(Task(len(out), label, path, opt, seed, ovr))
        return out


def _canon(overrides: tuple[tuple[str, Any], ...]) -> str:
    return json.dumps([[k, v] for k, v in overrides], sort_keys=True, default=str)


def _short(v: Any) -> str:
    return json.dumps(v, default=str).replace(" ", "")[:24]


def load_spec(path: str | Path) -> Spec:
    """Read and validate a spec file; raise :class:`SpecError` naming every problem."""
    path = Path(path)
    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise SpecError([f"cannot read file: {exc.strerror or exc}"], str(path)) from None
    except yaml.YAMLError as exc:
        raise SpecError([f"invalid YAML: {exc}"], str(path)) from None
    return parse_spec(raw, base_dir=path.parent, source=path)


def parse_spec(raw: Any, base_dir: str | Path = ".", source: str | Path = "spec") -> Spec:
    """Validate an already-parsed spec mapping; world paths and globs are relative to ``base_dir``."""
    base_dir = Path(base_dir).resolve()
    problems: list[str] = []
    if not isinstance(raw, dict):
        raise SpecError(
            [f"expected a mapping of {', '.join(SPEC_KEYS)}, got {type(raw).__name__}"], str(source)
        )
    for k in raw:
        if k not in SPEC_KEYS:
            close = difflib.get_close_matches(str(k), SPEC_KEYS, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            problems.append(f"{k}: unknown key{hint}; known: {', '.join(SPEC_KEYS)}")
    for k in ("worlds", "optimizers"):
        if k not in raw:
            problems.append(f"{k}: required")

    name = raw.get("name", Path(str(source)).stem)
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_.-]+", name or ""):
        problems.append(f"name: expected a word of letters, digits, '_', '.', '-', got {name!r}")
        name = "sweep"

    worlds: list[tuple[str, str]] = []
    pats = raw.get("worlds", [])
    pats = [pats] if isinstance(pats, str) else pats
    if not isinstance(pats, list) or not pats or not all(isinstance(p, str) for p in pats):
        if "worlds" in raw:
            problems.append("worlds: expected a non-empty list of paths or globs")
        pats = []
    for pat in pats:
        full = pat if Path(pat).is_absolute() else str(base_dir / pat)
        hits = sorted(glob.glob(full, recursive=True))
        hits = [h for h in hits if Path(h).is_file()]
        if not hits:
            problems.append(f"worlds: no world file matches {pat!r} (relative to {base_dir})")
        for h in hits:
            p = Path(h).resolve()
            try:
                label = p.relative_to(base_dir).as_posix()
            except ValueError:
                label = p.as_posix()
            if all(label != w for w, _ in worlds):
                worlds.append((label, str(p)))

    known = ["none", *registry.available()]
    opts = raw.get("optimizers", [])
    opts = [opts] if isinstance(opts, str) else opts
    if not isinstance(opts, list) or not opts:
        if "optimizers" in raw:
            problems.append("optimizers: expected a non-empty list ('none' = pure APF)")
        opts = []
    for o in opts:
        if o not in known:
            close = difflib.get_close_matches(str(o), known, n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            problems.append(f"optimizers: unknown optimizer {o!r}{hint}; known: {', '.join(known)}")
    dup = sorted({o for o in opts if opts.count(o) > 1}, key=str)
    if dup:
        problems.append(f"optimizers: listed twice: {', '.join(map(str, dup))}")

    seeds_raw = raw.get("seeds", 10)
    seeds: list[int] = []
    if isinstance(seeds_raw, int) and not isinstance(seeds_raw, bool):
        if seeds_raw < 1:
            problems.append(f"seeds: a count must be >= 1, got {seeds_raw}")
        seeds = list(range(max(seeds_raw, 0)))
    elif isinstance(seeds_raw, list) and seeds_raw:
        bad = [s for s in seeds_raw if isinstance(s, bool) or not isinstance(s, int) or s < 0]
        if bad:
            problems.append(f"seeds: expected whole numbers >= 0, got {bad}")
        elif len(set(seeds_raw)) != len(seeds_raw):
            problems.append("seeds: a seed is listed twice")
        else:
            seeds = list(seeds_raw)
    else:
        problems.append(f"seeds: expected a count (>= 1) or a non-empty list of seeds, got {seeds_raw!r}")

    alpha = raw.get("alpha", 0.05)
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not 0 < alpha < 1:
        problems.append(f"alpha: expected a number in (0, 1), got {alpha!r}")
        alpha = 0.05

    overrides: list[tuple[str, tuple[Any, ...]]] = []
    ovr_raw = raw.get("overrides") or {}
    if not isinstance(ovr_raw, dict):
        problems.append("overrides: expected a mapping of dotted world paths to lists of values")
        ovr_raw = {}
    for k, vals in ovr_raw.items():
        if not isinstance(k, str) or not k or any(not part for part in k.split(".")):
            problems.append(
                f"overrides: bad path {k!r} (dotted world keys, e.g. planner.optimizer.population)"
            )
        elif k in ("planner.optimizer.name", "planner.optimizer", "planner"):
            problems.append(f"overrides.{k}: the optimizer is chosen by 'optimizers:', not by an override")
        elif k == "seed":
            problems.append("overrides.seed: seeds are chosen by 'seeds:', not by an override")
        elif not isinstance(vals, list) or not vals:
            problems.append(f"overrides.{k}: expected a non-empty list of values, got {vals!r}")
        elif len({json.dumps(v, sort_keys=True, default=str) for v in vals}) != len(vals):
            problems.append(f"overrides.{k}: a value is listed twice")
        else:
            overrides.append((k, tuple(vals)))

    spec = Spec(name, Path(str(source)), tuple(worlds), tuple(opts), tuple(seeds), tuple(overrides), alpha)
    # The worlds are built with whatever is valid so far, so that one call names every problem.
    good_opts = tuple(dict.fromkeys(o for o in opts if o in known))
    if worlds and good_opts:
        problems += check_worlds(Spec(name, spec.source, spec.worlds, good_opts, (0,), spec.overrides, alpha))
    if problems:
        raise SpecError(problems, str(source))
    return spec


def check_worlds(spec: Spec) -> list[str]:
    """Build every (world, optimizer, override combination) once, as the runs will: the override
    paths and values are validated against the world format before any task starts."""
    problems: list[str] = []
    seen: set[str] = set()
    for label, path in spec.worlds:
        try:
            raw = read_raw(path)
        except WorldError as exc:
            problems += [f"{label}: {p}" for p in exc.problems]
            continue
        keys = []
        for key, vals in spec.overrides:  # paths that do not fit the file's structure, each once
            try:
                set_dotted(copy.deepcopy(raw), key, vals[0])
                keys.append((key, vals))
            except OverrideError as exc:
                problems.append(f"overrides.{key}: {exc} (in {label})")
        for combo in itertools.product(*(vals for _, vals in keys)):
            ovr = tuple(zip([k for k, _ in keys], combo, strict=True))
            for opt in spec.optimizers:
                try:
                    build_world(path, opt, ovr)
                except (OverrideError, WorldError) as exc:
                    # The same problem usually shows for every optimizer and combination: name it
                    # once, with the first setting that shows it.
                    where = ", ".join(f"{k}={json.dumps(v, default=str)}" for k, v in ovr)
                    ctx = f" [optimizer {opt}{', ' + where if where else ''}]"
                    for p in getattr(exc, "problems", None) or [str(exc)]:
                        if f"{label}: {p}" not in seen:
                            seen.add(f"{label}: {p}")
                            problems.append(f"{label}: {p}{ctx}")
    return problems

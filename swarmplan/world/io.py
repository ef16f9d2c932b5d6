"""Reading a world file: YAML text -> validated :class:`~swarmplan.world.model.World`."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import Any

from swarmplan.world.model import World, WorldError
from swarmplan.world.schema import parse_world


def load_world(path: str | Path, optimizer_names: list[str] | None = None) -> World:
    """Read, validate and resolve the world file at ``path``; raise :class:`WorldError` on any problem."""
    import yaml  # here: worlds built in code (parse_world) never need the YAML parser

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise WorldError([f"cannot read file: {exc.strerror or exc}"], str(path)) from None
    try:
        raw = _parse(yaml, text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        raise WorldError([f"{where}invalid YAML: {getattr(exc, 'problem', exc)}"], str(path)) from None
    return parse_world(raw, base_dir=path.parent, source=path, optimizer_names=optimizer_names)


def _parse(yaml: ModuleType, text: str) -> Any:
    """``yaml.safe_load(text)``, through libyaml's parser where PyYAML has it (the same
    constructor and resolver, several times faster on a large world); a text libyaml refuses is
    parsed again by ``safe_load``, so a problem is reported in its words."""
    loader = getattr(yaml, "CSafeLoader", None)
    if loader is not None:
        try:
            return yaml.load(text, Loader=loader)
        except yaml.YAMLError:
            pass
    return yaml.safe_load(text)

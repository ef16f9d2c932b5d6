"""The one place the sweep engine touches the simulator: build a world, run it, read its log.

Everything here goes through the package's public entry points (``swarmplan.world.parse_world``,
``swarmplan.run.apply_overrides`` / ``check_planner_settings`` / ``simulate``) and the log
contract (shared/spec/log-format.md), so a refactor of the simulator only has to keep those.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import yaml

from swarmplan import optimizers
from swarmplan.io.runner import apply_overrides, check_planner_settings, simulate
from swarmplan.world import World, WorldError, parse_world

OPTIMIZER_PARAMS = "planner.optimizer.params."


class OverrideError(ValueError):
    """A dotted override path that cannot be applied to a world mapping."""

    def __init__(self, key: str, msg: str):
        super().__init__(msg)
        self.key = key


def set_dotted(raw: dict[str, Any], key: str, value: Any) -> None:
    """``raw[a][b][c] = value`` for ``key = 'a.b.c'``; a number indexes a list (``agents.0.radius``).

    Missing mappings on the way are created (an absent section means its defaults); whether the
    final key exists in the world format is for :func:`swarmplan.world.parse_world` to say.
    """
    parts = key.split(".")
    node: Any = raw
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join(parts[:depth]) or "the world"
        if isinstance(node, list):
            if not part.isdigit():
                raise OverrideError(key, f"{where} is a list: index it with a number, not {part!r}")
            if int(part) >= len(node):
                raise OverrideError(key, f"{where} has {len(node)} item(s), no index {part}")
            if last:
                node[int(part)] = copy.deepcopy(value)
            else:
                node = node[int(part)]
        elif isinstance(node, dict):
            if last:
                node[part] = copy.deepcopy(value)
            else:
                if node.get(part) is None:
                    node[part] = {}
                node = node[part]
        else:
            raise OverrideError(key, f"{where} is a {type(node).__name__}, not a mapping or a list")


def read_raw(path: str | Path) -> dict[str, Any]:
    """The world file's YAML mapping, as written (before defaults)."""
    path = Path(path)
    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise WorldError([f"cannot read file: {exc.strerror or exc}"], str(path)) from None
    except yaml.YAMLError as exc:
        raise WorldError([f"invalid YAML: {' '.join(str(exc).split())}"], str(path)) from None
    if not isinstance(raw, dict):
        raise WorldError([f"expected a mapping, got {type(raw).__name__}"], str(path))
    return raw


def build_world(world_path: str | Path, optimizer: str, overrides: tuple[tuple[str, Any], ...]) -> World:
    """The world one run flies: the file with the dotted ``overrides`` applied to its raw mapping,
    validated by ``parse_world``, flown with ``optimizer`` as ``swarmplan.run --optimizer`` would.

    Raises :class:`WorldError` (bad world or override value) or :class:`OverrideError` (a path
    that does not fit the file's structure).
    """
    path = Path(world_path)
    raw = read_raw(path)
    for key, value in overrides:
        set_dotted(raw, key, value)
    names = optimizers.available()
    world = parse_world(copy.deepcopy(raw), base_dir=path.parent, source=path, optimizer_names=names)
    if optimizer != world.planner_config.optimizer.name:
        # Another algorithm than the file's: ``apply_overrides`` drops the file's params (they are
        # settings of its own algorithm), so params the sweep overrides are set on the raw mapping
        # and validated against the algorithm that will run them.
        opt = raw.setdefault("planner", {}).setdefault("optimizer", {})
        opt["name"] = optimizer
        opt["params"] = {}
        for key, value in overrides:
            if key.startswith(OPTIMIZER_PARAMS):
                set_dotted(raw, key, value)
        world = parse_world(raw, base_dir=path.parent, source=path, optimizer_names=names)
    world = apply_overrides(world, optimizer, None)
    check_planner_settings(world, str(path))
    return world


def run_world(world: World, seed: int, log_path: Path) -> dict[str, Any]:
    """Run ``world`` with ``seed`` to its end, logging to ``log_path``; the run's summary."""
    return simulate(world, seed, log_path)


def read_log(log_path: str | Path) -> tuple[dict[str, Any] | None, list[dict[str, Any]]]:
    """(``/summary`` or None, ``/optimizer`` messages) of a finished log; (None, []) when the file
    is missing or unreadable (e.g. cut short by a killed worker)."""
    from mcap.reader import make_reader

    summary = None
    runs: list[dict[str, Any]] = []
    try:
        with open(log_path, "rb") as f:
            for _schema, channel, message in make_reader(f).iter_messages(topics=["/summary", "/optimizer"]):
                msg = json.loads(message.data)
                if channel.topic == "/summary":
                    summary = msg
                else:
                    runs.append(msg)
    except Exception:  # noqa: BLE001 - any unreadable file counts as "no finished log"
        return None, []
    runs.sort(key=lambda m: float(m.get("t", 0.0)))
    return summary, runs

"""Name → optimizer class registry, ``make`` and ``available``."""

from __future__ import annotations

from typing import Any

from swarmplan.optimizers.core import Optimizer

_REGISTRY: dict[str, type[Optimizer]] = {}


def register(cls: type[Optimizer]) -> type[Optimizer]:
    """Class decorator: make ``cls`` available under ``cls.name``."""
    if not cls.name:
        raise TypeError(f"{cls.__name__} has no name")
    if cls.name in _REGISTRY and _REGISTRY[cls.name] is not cls:
        raise TypeError(f"optimizer name {cls.name!r} registered twice")
    _REGISTRY[cls.name] = cls
    return cls


def available() -> list[str]:
    """Names of every registered optimizer, sorted."""
    return sorted(_REGISTRY)


def make(name: str, **params: Any) -> Optimizer:
    """Build the optimizer registered as ``name``; unknown names or parameters raise ``ValueError``."""
    try:
        cls = _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown optimizer {name!r}; known: {', '.join(available())}") from None
    return cls(**params)


def defaults(name: str) -> dict[str, Any]:
    """The paper-recommended default parameters of ``name``."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown optimizer {name!r}; known: {', '.join(available())}")
    return dict(_REGISTRY[name].defaults)

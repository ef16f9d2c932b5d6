"""Name → optimizer class registry, ``make`` and ``available``.

The built-in algorithms are listed by name with the module that defines them and imported on
first use: a run that flies one optimizer does not pay the import of the other thirteen
(start-up to the first step, issue 10). ``register`` still adds any class, built-in or not.
"""

from __future__ import annotations

import importlib
from typing import Any

from swarmplan.optimizers.core import Optimizer

#: built-in algorithm name -> module (under ``swarmplan.optimizers``) whose import registers it;
#: tests/test_optimizer_registry.py checks that this table and the modules' ``name`` attributes agree
BUILTIN_MODULES: dict[str, str] = {
    "random": "baselines",
    "pso": "baselines",
    "de": "baselines",
    "ga": "baselines",
    "ba": "bat",
    "iba_abc": "bat",
    "iba_gauss": "bat_gauss",
    "abc": "bee_colony",
    "cfo": "central_force",
    "mcfo": "central_force",
    "afsa": "fish_swarm",
    "iafsa": "fish_swarm",
    "woa": "whale",
    "rscdwoa": "whale",
    "lshade": "shade",
}

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
    """Names of every registered optimizer (built-in or added with ``register``), sorted."""
    return sorted(set(BUILTIN_MODULES) | set(_REGISTRY))


def optimizer_class(name: str) -> type[Optimizer]:
    """The class registered as ``name``, importing its built-in module on first use;
    unknown names raise ``ValueError``."""
    if name not in _REGISTRY and name in BUILTIN_MODULES:
        importlib.import_module(f"swarmplan.optimizers.{BUILTIN_MODULES[name]}")
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown optimizer {name!r}; known: {', '.join(available())}") from None


def make(name: str, **params: Any) -> Optimizer:
    """Build the optimizer registered as ``name``; unknown names or parameters raise ``ValueError``."""
    return optimizer_class(name)(**params)


def defaults(name: str) -> dict[str, Any]:
    """The paper-recommended default parameters of ``name``."""
    return dict(optimizer_class(name).defaults)

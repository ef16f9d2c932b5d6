"""Name → optimizer class registry, ``make`` and ``available``.

The built-in algorithms are listed by name with the module and class that define them, and
their module is imported on first use: a run that flies one optimizer does not pay the import
of the other thirteen (start-up to the first step). The algorithm modules know nothing of
the registry. ``register`` adds any other class under a name of its own.
"""

from __future__ import annotations

import importlib
from typing import Any

from swarmplan.optimizers.base import Optimizer

#: built-in algorithm name -> (module under ``swarmplan.optimizers``, class in it);
#: tests/test_optimizer_registry.py checks that the classes' ``name`` attributes agree
BUILTIN: dict[str, tuple[str, str]] = {
    "random": ("baselines", "RandomSearch"),
    "pso": ("baselines", "PSO"),
    "de": ("baselines", "DE"),
    "ga": ("baselines", "GA"),
    "ba": ("bat", "BatAlgorithm"),
    "iba_abc": ("bat", "IbaAbc"),
    "iba_gauss": ("bat_gauss", "IbaGauss"),
    "abc": ("bee_colony", "ArtificialBeeColony"),
    "cfo": ("central_force", "CentralForce"),
    "mcfo": ("central_force", "ModifiedCentralForce"),
    "afsa": ("fish_swarm", "ArtificialFishSwarm"),
    "iafsa": ("fish_swarm", "ImprovedFishSwarm"),
    "woa": ("whale", "WOA"),
    "rscdwoa": ("whale", "RSCDWOA"),
    "lshade": ("shade", "LShade"),
}

_REGISTRY: dict[str, type[Optimizer]] = {}


def register(cls: type[Optimizer]) -> type[Optimizer]:
    """Class decorator: make ``cls`` available under ``cls.name`` (not a built-in's name)."""
    if not cls.name:
        raise TypeError(f"{cls.__name__} has no name")
    if cls.name in BUILTIN or (cls.name in _REGISTRY and _REGISTRY[cls.name] is not cls):
        raise TypeError(f"optimizer name {cls.name!r} registered twice")
    _REGISTRY[cls.name] = cls
    return cls


def available() -> list[str]:
    """Names of every optimizer (built-in or added with ``register``), sorted."""
    return sorted(set(BUILTIN) | set(_REGISTRY))


def optimizer_class(name: str) -> type[Optimizer]:
    """The class of ``name``, importing its built-in module on first use; unknown names raise
    ``ValueError``."""
    if name in BUILTIN:
        module, cls = BUILTIN[name]
        return getattr(importlib.import_module(f"swarmplan.optimizers.{module}"), cls)
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

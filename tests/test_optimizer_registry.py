"""The optimizer registry: built-in names import their module on first use, and the table of
built-in classes agrees with the classes those modules define."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from swarmplan.optimizers import available, defaults, make, optimizer_class, register
from swarmplan.optimizers.base import Optimizer
from swarmplan.optimizers.registry import _REGISTRY, BUILTIN


def test_builtin_table_matches_the_classes():
    for name, (module, cls_name) in BUILTIN.items():
        cls = optimizer_class(name)
        assert cls.__module__ == f"swarmplan.optimizers.{module}", name
        assert cls.__name__ == cls_name and cls.name == name


def test_a_builtin_name_cannot_be_registered_again():
    with pytest.raises(TypeError, match="'woa' registered twice"):
        register(type("MyWoa", (Optimizer,), {"name": "woa"}))


def test_make_imports_only_the_family_it_needs():
    code = (
        "import sys\n"
        "from swarmplan import optimizers\n"
        "opt = optimizers.make('rscdwoa')\n"
        "loaded = sorted(m for m in sys.modules if m.startswith('swarmplan.optimizers.'))\n"
        "print(' '.join(loaded))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = set(out.stdout.split())
    assert "swarmplan.optimizers.whale" in loaded
    for other in ("baselines", "bat", "bat_gauss", "bee_colony", "central_force", "fish_swarm"):
        assert f"swarmplan.optimizers.{other}" not in loaded, loaded


def test_unknown_names_raise_value_error_listing_the_known():
    for call in (lambda: make("no_such"), lambda: defaults("no_such"), lambda: optimizer_class("no_such")):
        with pytest.raises(ValueError, match="unknown optimizer 'no_such'; known: abc, afsa"):
            call()


def test_registered_user_class_is_available_and_made():
    class Mine(Optimizer):
        name = "test_registry_mine"
        defaults = {"population": 4}

        def setup(self, problem, rng, x0):  # uniform samples, one batch per iteration
            problem.evaluate(problem.uniform(rng, self.population))

        def iterate(self, state, problem, rng, iteration):
            problem.evaluate(problem.uniform(rng, self.population))

    try:
        register(Mine)
        assert "test_registry_mine" in available()
        opt = make("test_registry_mine")
        assert isinstance(opt, Mine)
        r = opt.minimize(
            lambda X: (X**2).sum(axis=1), np.full(2, -1.0), np.full(2, 1.0), max_evals=40, seed=1
        )
        assert r.evaluations == 40 and r.f >= 0.0
        assert defaults("test_registry_mine") == {"population": 4}
        with pytest.raises(TypeError, match="registered twice"):
            register(type("Other", (Mine,), {}))
    finally:
        _REGISTRY.pop("test_registry_mine", None)

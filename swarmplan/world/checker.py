"""Walking a raw world mapping while collecting every problem (with its path and a
"did you mean" for typos) instead of stopping at the first."""

from __future__ import annotations

import difflib
import math
from typing import Any

import numpy as np


class Checker:
    """Collects problems while walking the raw YAML tree."""

    def __init__(self) -> None:
        self.problems: list[str] = []

    def add(self, path: str, msg: str) -> None:
        # Several checks may reach the same missing key (the required-keys pass and the typed
        # read that follows it); the user should see each problem once.
        problem = f"{path}: {msg}"
        if problem not in self.problems:
            self.problems.append(problem)

    def keys(
        self, node: Any, path: str, allowed: list[str] | tuple[str, ...], required: tuple[str, ...] = ()
    ) -> bool:
        if not isinstance(node, dict):
            self.add(path, f"expected a mapping, got {typename(node)}")
            return False
        for k in node:
            if k not in allowed:
                close = difflib.get_close_matches(str(k), list(allowed), n=1, cutoff=0.5)
                hint = f" (did you mean '{close[0]}'?)" if close else f" (known keys: {', '.join(allowed)})"
                self.add(join(path, str(k)), f"unknown key{hint}")
        for k in required:
            if k not in node or node[k] is None:
                self.add(join(path, k), "required key is missing")
        return True

    def number(
        self,
        node: dict,
        key: str,
        path: str,
        default: float | None = None,
        *,
        positive: bool = False,
        nonneg: bool = False,
        lo: float | None = None,
        hi: float | None = None,
    ) -> float | None:
        p = join(path, key)
        if key not in node or node[key] is None:
            if default is None:
                self.add(p, "required key is missing")
            return default
        v = node[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.add(p, f"expected a number, got {typename(v)} {v!r}")
            return default
        v = float(v)
        if positive and v <= 0:
            self.add(p, f"must be > 0, got {v:g}")
        elif nonneg and v < 0:
            self.add(p, f"must be >= 0, got {v:g}")
        if lo is not None and v < lo:
            self.add(p, f"must be >= {lo:g}, got {v:g}")
        if hi is not None and v > hi:
            self.add(p, f"must be <= {hi:g}, got {v:g}")
        return v

    def vector(
        self,
        node: dict,
        key: str,
        path: str,
        n: int,
        default: Any = None,
        *,
        positive: bool = False,
        nonneg: bool = False,
    ) -> np.ndarray | None:
        p = join(path, key)
        if key not in node or node[key] is None:
            if default is None:
                self.add(p, "required key is missing")
                return None
            return np.asarray(default, dtype=float)
        return self.vector_value(node[key], p, n, positive=positive, nonneg=nonneg)

    def vector_value(
        self, v: Any, p: str, n: int, *, positive: bool = False, nonneg: bool = False
    ) -> np.ndarray | None:
        if (
            not isinstance(v, (list, tuple))
            or len(v) != n
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) for x in v)
        ):
            self.add(p, f"expected a list of {n} numbers, got {v!r}")
            return None
        arr = np.asarray(v, dtype=float)
        if positive and np.any(arr <= 0):
            self.add(p, f"every value must be > 0, got {v!r}")
        elif nonneg and np.any(arr < 0):
            self.add(p, f"every value must be >= 0, got {v!r}")
        return arr

    def string(
        self, node: dict, key: str, path: str, default: str | None = None, choices: tuple[str, ...] = ()
    ) -> str | None:
        p = join(path, key)
        if key not in node or node[key] is None:
            if default is None:
                self.add(p, "required key is missing")
            return default
        v = node[key]
        if not isinstance(v, str) or not v:
            self.add(p, f"expected a non-empty string, got {typename(v)} {v!r}")
            return default
        if choices and v not in choices:
            close = difflib.get_close_matches(v, list(choices), n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            self.add(p, f"'{v}' is not one of {', '.join(choices)}{hint}")
            return default
        return v

    def boolean(self, node: dict, key: str, path: str, default: bool) -> bool:
        if key not in node or node[key] is None:
            return default
        v = node[key]
        if not isinstance(v, bool):
            self.add(join(path, key), f"expected true or false, got {v!r}")
            return default
        return v

    def listing(self, node: dict, key: str, path: str, required: bool = False) -> list:
        if key not in node or node[key] is None:
            if required:
                self.add(join(path, key), "required key is missing")
            return []
        v = node[key]
        if not isinstance(v, list):
            self.add(join(path, key), f"expected a list, got {typename(v)}")
            return []
        return v


def join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def typename(v: Any) -> str:
    return {dict: "mapping", list: "list", str: "string", bool: "boolean", type(None): "nothing"}.get(
        type(v), type(v).__name__
    )

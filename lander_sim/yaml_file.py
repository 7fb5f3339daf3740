"""Typed accessors for a parsed scene file, whose errors name the file and the key.

The file itself is read by :func:`lander_yaml.read_yaml` (one reader for every user's YAML file);
the scene loader and each model's own section parser (:mod:`lander_sim.physics.models.table`)
walk the parsed mapping with :class:`Reader`.
"""
from __future__ import annotations

import math
from typing import Any


class Reader:
    """Small typed accessors for a parsed YAML file whose errors name ``file: key.path`` and the
    expectation, as ``error`` (a ``ValueError`` subclass: ``SceneError`` for scenes). The scene
    loader and each model's own section parser (:mod:`lander_sim.physics.models.table`) use it."""

    def __init__(self, file: str, error: type[ValueError] = ValueError) -> None:
        self.file = file
        self.error = error

    def fail(self, path: str, msg: str) -> ValueError:
        return self.error(f"{self.file}: {path}: {msg}")

    def mapping(self, node: Any, path: str, allowed: set[str], required: tuple[str, ...] = ()) -> dict[str, Any]:
        if node is None:
            node = {}
        if not isinstance(node, dict):
            raise self.fail(path, f"expected a mapping, got {type(node).__name__} {node!r}")
        for k in node:
            if k not in allowed:
                raise self.fail(f"{path}.{k}" if path else str(k), f"unknown key; allowed keys: {', '.join(sorted(allowed))}")
        for k in required:
            if k not in node:
                raise self.fail(f"{path}.{k}" if path else k, "missing required key")
        return node

    def number(self, node: Any, path: str, lo: float | None = None, hi: float | None = None, strict_lo: bool = False) -> float:
        if isinstance(node, bool) or not isinstance(node, (int, float)):
            raise self.fail(path, f"expected a number, got {node!r}")
        x = float(node)
        if not math.isfinite(x):
            raise self.fail(path, f"expected a finite number, got {node!r}")
        if lo is not None and (x < lo or (strict_lo and x == lo)):
            raise self.fail(path, f"expected a number {'>' if strict_lo else '>='} {lo}, got {x}")
        if hi is not None and x > hi:
            raise self.fail(path, f"expected a number <= {hi}, got {x}")
        return x

    def integer(self, node: Any, path: str, lo: int) -> int:
        if isinstance(node, bool) or not isinstance(node, int) or node < lo:
            raise self.fail(path, f"expected an integer >= {lo}, got {node!r}")
        return node

    def vector(self, node: Any, path: str, n: int = 3) -> tuple[float, ...]:
        if not isinstance(node, list) or len(node) != n:
            raise self.fail(path, f"expected a list of {n} numbers, got {node!r}")
        return tuple(self.number(x, f"{path}[{i}]") for i, x in enumerate(node))

    def vector3(self, node: Any, path: str) -> tuple[float, float, float]:
        """A 3-vector (a world- or body-frame quantity: the frame is in ``path``)."""
        x, y, z = self.vector(node, path, 3)
        return x, y, z

    def boolean(self, node: Any, path: str) -> bool:
        if not isinstance(node, bool):
            raise self.fail(path, f"expected true or false, got {node!r}")
        return node

    def string(self, node: Any, path: str) -> str:
        if not isinstance(node, str):
            raise self.fail(path, f"expected a string, got {node!r}")
        return node

    def choice(self, node: Any, path: str, choices: tuple[str, ...]) -> str:
        if node not in choices:
            raise self.fail(path, f"expected one of {', '.join(choices)}, got {node!r}")
        return node

"""The laws are parts with public contracts: no object in ``lander_autopilot`` reads or writes
another object's underscored attributes, the de-orbit law's parts subclass no concrete law, and no
module of the package is over 600 lines. Read from the source with ``ast``."""
from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "lander_autopilot"
MAX_LINES = 600


def _modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def _imported_names(tree: ast.AST) -> set[str]:
    """Names bound by import statements (modules, or names taken from them)."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


def cross_object_private_access(source: str) -> list[tuple[int, str]]:
    """``X._name`` where ``X`` is not ``self``, ``cls``, ``super()`` or an imported module or name:
    one object reaching into another's private state. Dunders (``__dict__``) are Python's, not a
    part's, and are left out."""
    tree = ast.parse(source)
    imported = _imported_names(tree)
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Attribute) or not node.attr.startswith("_") or node.attr.startswith("__"):
            continue
        owner = node.value
        if isinstance(owner, ast.Name) and (owner.id in ("self", "cls") or owner.id in imported):
            continue
        if isinstance(owner, ast.Call) and isinstance(owner.func, ast.Name) and owner.func.id == "super":
            continue
        found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def test_the_scan_finds_an_object_reaching_into_another():
    src = "import math\nclass A:\n    def f(self, other):\n        self._x = other._y + math._z\n        return self.part._w\n"
    assert cross_object_private_access(src) == [(4, "other._y"), (5, "self.part._w")]


def test_no_cross_object_private_access_in_lander_autopilot():
    found = [f"{p.relative_to(REPO)}:{line}: {text}" for p in _modules()
             for line, text in cross_object_private_access(p.read_text())]
    assert found == []


def test_the_deorbit_parts_subclass_no_concrete_law():
    """Every class in ``controllers/deorbit`` derives from ``Controller`` itself (the mission), from
    another class of the package it is in (the MPC mission from the mission), or from no law at all:
    the descent and the hover hold the laws they fly."""
    concrete = {"LandingController", "GroundSpeedController", "SumController", "AltitudeController",
                "QuaternionAttitudeController", "EulerAttitudeController"}
    found = []
    for p in sorted((PACKAGE / "controllers" / "deorbit").glob("*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ClassDef):
                bases = {ast.unparse(b).split(".")[-1] for b in node.bases}
                found += [f"{p.name}: {node.name}({b})" for b in bases & concrete]
    assert found == []


def test_no_module_over_600_lines():
    long = {str(p.relative_to(REPO)): n for p in _modules() if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert long == {}

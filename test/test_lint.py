"""Lint and types, part of the test suite so that `./dev test` (and CI, which runs exactly that)
fails on a violation. The rule sets and their reasons are in pyproject.toml: ruff (pycodestyle,
pyflakes, bugbear, pyupgrade, isort) over the whole tree; mypy --strict over the core (physics,
integrators, scenes, simulation, compiled kernels), the design library, the nodes' shared helpers
(lander_ros), the YAML reader (lander_yaml) and the tools (lander_tools)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _run(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", *argv], cwd=REPO, capture_output=True, text=True, timeout=600)


def test_ruff_finds_nothing() -> None:
    r = _run("ruff", "check", "--output-format", "concise", ".")
    assert r.returncode == 0, r.stdout + r.stderr


def test_mypy_strict_on_the_core_the_design_library_and_the_tools_finds_nothing() -> None:
    r = _run("mypy")  # files and options: pyproject.toml [tool.mypy]
    assert r.returncode == 0, r.stdout + r.stderr
    assert "Success: no issues found" in r.stdout

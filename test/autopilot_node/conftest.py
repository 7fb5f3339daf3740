"""Fixtures of the autopilot node tests: a ground-station node and, per module, the real processes.

The suite-wide test/conftest.py has already given this run its own ROS_DOMAIN_ID and
localhost-only discovery; the child processes inherit both.
"""
from __future__ import annotations

import sys
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

import rosutil


@dataclass
class Rig:
    """Processes of one test module and the ground station that watches them."""

    ground: object
    children: dict[str, rosutil.ChildProcess]

    def start(self, module: str, name: str, params: dict[str, object], params_file: str | None = None) -> rosutil.ChildProcess:
        child = rosutil.start_node(module, params, name=name, params_file=params_file)
        self.children[name] = child
        return child

    def check_alive(self) -> None:
        for c in self.children.values():
            if c.returncode is not None:
                raise AssertionError(f"{c.name} exited with {c.returncode}:\n{c.output()}")


@pytest.fixture(scope="module")
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    """rclpy in a private context, a :class:`~.ground.Ground` node; children are started by the module."""
    import rclpy
    from rclpy.context import Context

    from .ground import Ground

    ctx = Context()
    rclpy.init(context=ctx)
    ground = Ground(ctx)
    rig = Rig(ground, {})
    failed_before = request.session.testsfailed
    try:
        yield rig
    finally:
        for child in rig.children.values():
            child.stop()
            if request.session.testsfailed > failed_before:
                sys.stderr.write(f"--- output of {child.name} ---\n{child.output()[-20000:]}\n")
            child.close()
        ground.close()
        rclpy.shutdown(context=ctx)

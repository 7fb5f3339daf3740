"""Fixtures of the reliability tests: the running stack, a watch node, a busy CPU core, hypothesis.

The suite-wide test/conftest.py has given this run its own ROS_DOMAIN_ID and loopback-only
discovery; the child processes inherit both. Hypothesis runs with a fixed seed and bounded example
counts by default (profile ``reliability-ci``), so a failure is reproduced by re-running; set
``HYPOTHESIS_PROFILE=reliability-long`` for more examples.
"""
from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, settings

from .stack import Stack, Watch

settings.register_profile(
    "reliability-ci",
    derandomize=True,  # the same examples every run: a failure reproduces as it is
    max_examples=15,
    deadline=None,  # a live ROS round trip has no useful per-example deadline
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    database=None,
)
settings.register_profile(
    "reliability-long",
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
#: Applied to the tests of this folder via ``settings(parent=...)`` (the global profile is left alone).
PROFILE = settings.get_profile(os.environ.get("HYPOTHESIS_PROFILE", "reliability-ci")
                               if os.environ.get("HYPOTHESIS_PROFILE", "").startswith("reliability")
                               else "reliability-ci")


@pytest.fixture
def stack(request: pytest.FixtureRequest) -> Iterator[Stack]:
    s = Stack()
    yield s
    rep = getattr(request.node, "rep_call", None)
    s.close(failed=rep is not None and rep.failed)


@pytest.fixture
def watch() -> Iterator[Watch]:
    """A :class:`Watch` node in a private rclpy context."""
    import rclpy
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx)
    w = Watch(ctx)
    try:
        yield w
    finally:
        w.close()
        rclpy.shutdown(context=ctx)


@pytest.fixture
def busy_core() -> Iterator[subprocess.Popen]:
    """A process spinning one CPU core flat out for the duration of the test (load on a 2-core box)."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)
    try:
        yield proc
    finally:
        proc.kill()  # by its own handle: only the burner we started
        proc.wait()

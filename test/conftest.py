"""Project-wide test set-up: middleware isolation, ROS fixtures, the ``slow`` marker.

At import (before any test creates a ROS context) this run gets its own ROS_DOMAIN_ID in 1..101
and localhost-only discovery, so parallel runs and other engineers' nodes never cross-talk; child
processes inherit both through the environment. Each test module then gets a fresh domain of its
own, so nodes a failing test leaves behind cannot disturb the next module; at the module's end any
process still in its domain is given 5 s to exit, then killed, and the module's last test errors
naming it (a leaked node is a defect) and dead processes' Fast DDS segments and half-made ports
are removed. At session end (in the controller, under xdist) all dead processes' shm files go.

In pytest-xdist workers (``./dev test`` runs ``-n auto --dist loadgroup``) each worker is a run of
its own in the sense above (its own domain ids, held by lock files); the ROS test files that use
Fast DDS's shared-memory transport (``rosutil.ROS_SHM_TESTS``) run in one worker, the other ROS
files file by file in any worker over loopback UDP alone (``rosutil.transports_env``; README,
"Tests in parallel").

Fixtures for other tests:
  ros_context   a fresh rclpy Context, initialised for the test and shut down after it
  ros_node      (node, executor) in that context; ``ros_node.wait_for(pred, timeout, what)``
  spawn_python  factory starting a Python child process (a node) with this env, stopped at teardown
Helpers: ``import rosutil`` (wait_for, ChildProcess, clean_stale_fastdds_shm).
"""

from __future__ import annotations

import itertools
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

import rosutil

ROS_DOMAIN_ID = rosutil.isolate_middleware()
#: In a pytest-xdist worker (the others are running tests meanwhile), not the whole run.
XDIST_WORKER = "PYTEST_XDIST_WORKER" in os.environ
# Before any participant could open a dead port (see its docstring). A worker leaves ports to
# Fast DDS: its siblings may be opening them; the controller cleaned before starting them.
rosutil.clean_stale_fastdds_shm(zombie_ports=not XDIST_WORKER)
_module_seeds = itertools.count(ROS_DOMAIN_ID)  # claim_domain_id maps the seed into 1..101
REPO_ROOT = Path(__file__).resolve().parent.parent
TEST_DIR = Path(__file__).resolve().parent


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--runslow", action="store_true", default=False, help="also run tests marked slow")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "slow: long test, skipped unless --runslow is given")
    # Set on every test (rosutil.ROS_TESTS); pytest-xdist defines it too, but it may be absent (colcon test).
    config.addinivalue_line("markers", "xdist_group(name): the pytest-xdist worker group of a test")


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook: without it (a plain `colcon test`) one process runs all
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: one worker per core, at most 4 (each flight test runs several processes itself)."""
    return max(1, min(4, os.cpu_count() or 1))


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's, which reads the groups into the test ids
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        rel = Path(item.path).resolve().relative_to(TEST_DIR).as_posix()
        item.add_marker(pytest.mark.xdist_group(rosutil.xdist_group(rel)))
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def pytest_report_header(config: pytest.Config) -> str:
    return (f"ROS_DOMAIN_ID={ROS_DOMAIN_ID} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']}")


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    rosutil.clean_stale_fastdds_shm(zombie_ports=not XDIST_WORKER)  # the controller's comes last


@pytest.fixture(scope="module", autouse=True)
def module_ros_domain(request: pytest.FixtureRequest) -> Iterator[int]:
    """A domain of the module's own (see the module docstring), and the module's transports
    (``rosutil.transports_env``); yields the domain's id."""
    # Walk on from the last module's id, so consecutive modules never share one.
    domain = rosutil.claim_domain_id(seed=next(_module_seeds))
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    transports = rosutil.transports_env(Path(request.path).resolve().relative_to(TEST_DIR).as_posix())
    suite_env = {name: os.environ.get(name) for name in transports}
    os.environ.update(transports)
    try:
        yield domain
    finally:
        for name, value in suite_env.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        os.environ["ROS_DOMAIN_ID"] = str(ROS_DOMAIN_ID)
        leaked = rosutil.reap_domain(domain)
        # A killed node's half-made port must not hang the next module; its dead ports with locks
        # are left to Fast DDS, since another run's participants may be opening them now.
        rosutil.clean_stale_fastdds_shm(zombie_ports=False)
        rosutil.release_domain_id(domain)
        if leaked:
            raise RuntimeError(f"processes left running in ROS_DOMAIN_ID={domain} (killed):\n  " + "\n  ".join(leaked))


@pytest.fixture(autouse=True)
def no_figure_outlives_its_test() -> Iterator[None]:
    """Every pyplot figure a test made is closed after it: pyplot keeps figures until closed, and a
    worker that runs many plotting tests in turn otherwise passes matplotlib's 20-figure warning
    (an error under this suite's filterwarnings) in whichever test comes next."""
    yield
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close("all")


@pytest.fixture
def ros_context() -> Iterator[Any]:
    """A private rclpy Context (not the global one): tests cannot leak nodes into each other."""
    import rclpy
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        yield ctx
    finally:
        if ctx.ok():
            rclpy.shutdown(context=ctx)


@dataclass
class RosNode:
    node: Any
    executor: Any

    def wait_for(self, predicate: Callable[[], bool], timeout: float = 10.0, what: str = "condition") -> None:
        rosutil.wait_for(predicate, timeout, self.executor, what)


@pytest.fixture
def ros_node(ros_context: Any, request: pytest.FixtureRequest) -> Iterator[RosNode]:
    """A node named after the test, with a single-threaded executor, in ``ros_context``."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    name = "test_" + "".join(c if c.isalnum() else "_" for c in request.node.name)[:60]
    node = Node(name, context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        yield RosNode(node, executor)
    finally:
        executor.shutdown()
        node.destroy_node()


@pytest.fixture
def spawn_python(request: pytest.FixtureRequest) -> Iterator[Callable[..., rosutil.ChildProcess]]:
    """``spawn_python(args, name=...)`` starts ``python args...`` with this env; test/ is on its
    PYTHONPATH so children can ``import rosutil`` and test helper modules. All are stopped at
    teardown; if the test failed, their output is printed."""
    children: list[rosutil.ChildProcess] = []
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TEST_DIR), *filter(None, [env.get("PYTHONPATH")])])

    def spawn(args: Sequence[str], name: str = "child") -> rosutil.ChildProcess:
        child = rosutil.ChildProcess(args, env=env, cwd=REPO_ROOT, name=name)
        children.append(child)
        return child

    yield spawn
    failed = getattr(request.node, "rep_call", None)
    for child in children:
        child.stop()
        if failed is not None and failed.failed:
            sys.stderr.write(f"--- output of {child.name} ---\n{child.output()}\n")
        child.close()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    """Keep each phase's report on the item (spawn_python prints children's logs on failure)."""
    report = yield
    setattr(item, f"rep_{report.when}", report)
    return report

"""The running system under test: sim, autopilot and recorder as real processes, and a watch node.

No mocks: :class:`Stack` starts ``python -m lander_sim.node``, ``python -m lander_autopilot.node``
and ``python -m lander_tools.recorder`` as children (environment of this run: its own
ROS_DOMAIN_ID), and :class:`Watch` is an ordinary rclpy node in the test process that records
what they publish, publishes inputs and calls their services. Every wait spins until a condition
holds or a timeout expires; nothing sleeps a fixed time.
"""
from __future__ import annotations

import importlib.util
import os
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rosutil

REPO = Path(__file__).resolve().parents[2]
#: Process start-up and discovery on a loaded 2-core machine (rclpy + python-control imports).
START_TIMEOUT = 45.0
#: One request/answer or a short chain of messages over the middleware.
REPLY_TIMEOUT = 15.0


def _load_bench() -> Any:
    """bench/full_stack.py (the /proc readers live there once; the benchmark uses them too)."""
    spec = importlib.util.spec_from_file_location("full_stack_bench", REPO / "bench" / "full_stack.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("full_stack_bench", mod)
    spec.loader.exec_module(mod)
    return mod


bench = _load_bench()


def ros_args(params: dict[str, object]) -> list[str]:
    """``--ros-args -p k:=v ...`` for a child node."""
    args = ["--ros-args"]
    for k, v in params.items():
        lit = ("true" if v else "false") if isinstance(v, bool) else (v or "''") if isinstance(v, str) else repr(v)
        args += ["-p", f"{k}:={lit}"]
    return args


class Stack:
    """Child processes of one test (stopped and, on failure, their output printed at teardown)."""

    def __init__(self) -> None:
        self.children: dict[str, rosutil.ChildProcess] = {}
        self.env = dict(os.environ)

    def start(self, name: str, args: list[str]) -> rosutil.ChildProcess:
        old = self.children.get(name)
        if old is not None:
            old.close()
        child = rosutil.ChildProcess(args, env=self.env, cwd=REPO, name=name)
        self.children[name] = child
        return child

    def sim(self, **params: object) -> rosutil.ChildProcess:
        return self.start("sim", ["-m", "lander_sim.node", *ros_args(params)])

    def autopilot(self, **params: object) -> rosutil.ChildProcess:
        return self.start("autopilot", ["-m", "lander_autopilot.node", *ros_args(params)])

    def recorder(self, bag: Path, topics: tuple[str, ...]) -> rosutil.ChildProcess:
        return self.start("recorder", ["-m", "lander_tools.recorder", "-o", str(bag), *topics])

    def kill(self, name: str) -> None:
        """SIGKILL: no clean-up of any kind in the victim (a crash)."""
        child = self.children[name]
        child.proc.send_signal(signal.SIGKILL)
        child.proc.wait(timeout=REPLY_TIMEOUT)

    def stop(self, name: str) -> int:
        """SIGINT (the clean exit); returns the exit code."""
        return self.children[name].stop(grace=REPLY_TIMEOUT)

    def check_alive(self, *names: str) -> None:
        for n in names or tuple(self.children):
            c = self.children[n]
            if c.returncode is not None:
                raise AssertionError(f"{n} exited with {c.returncode}:\n{c.output()[-5000:]}")

    def close(self, failed: bool) -> None:
        for child in self.children.values():
            child.stop()
            if failed:
                sys.stderr.write(f"--- output of {child.name} ---\n{child.output()[-8000:]}\n")
            child.close()


class Watch:
    """Test-side node: records outputs of sim and autopilot, publishes inputs, calls services."""

    def __init__(self, context: Any, name: str = "reliability_watch") -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import Vector3Stamped
        from rcl_interfaces.srv import GetParameters, SetParameters
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from std_msgs.msg import Float64

        from lander_interfaces.msg import AutopilotStatus, FlightEvent, LanderState, ThrottleCommand
        from lander_interfaces.srv import SwitchController

        self.node = Node(name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        n = self.node
        self.states: list[Any] = []
        self.throttles: list[Any] = []
        self.statuses: list[Any] = []
        self.events: list[Any] = []
        self.diagnostics: list[dict[str, str]] = []
        self.received = 0
        deep = 100_000
        n.create_subscription(LanderState, "/lander/state", self._keep(self.states), deep)
        n.create_subscription(ThrottleCommand, "/lander/throttle", self._keep(self.throttles), deep)
        n.create_subscription(AutopilotStatus, "/autopilot/status", self._keep(self.statuses), deep)
        n.create_subscription(FlightEvent, "/lander/events", self._keep(self.events), deep)
        n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 1000)
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = {
            "throttle": n.create_publisher(ThrottleCommand, "/lander/throttle", reliable),
            "wind": n.create_publisher(Vector3Stamped, "/lander/wind", reliable),
            "demand": n.create_publisher(Float64, "/lander/demand_altitude", reliable),
            "state": n.create_publisher(LanderState, "/lander/state", reliable),
        }
        self.clients = {
            **rosutil.sim_service_clients(n),
            "switch_controller": n.create_client(SwitchController, "/autopilot/switch_controller"),
            "sim_set_parameters": n.create_client(SetParameters, "/lander_sim/set_parameters"),
            "sim_get_parameters": n.create_client(GetParameters, "/lander_sim/get_parameters"),
            "ap_set_parameters": n.create_client(SetParameters, "/autopilot/set_parameters"),
            "ap_get_parameters": n.create_client(GetParameters, "/autopilot/get_parameters"),
        }

    def _keep(self, store: list) -> Callable[[Any], None]:
        def keep(msg: Any) -> None:
            store.append(msg)
            self.received += 1

        return keep

    def _on_diag(self, msg: Any) -> None:
        for st in msg.status:
            if st.name.startswith("lander_sim"):
                self.diagnostics.append({kv.key: kv.value for kv in st.values})

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()

    # --- waiting -------------------------------------------------------------------------------

    def wait_for(self, predicate: Callable[[], bool], timeout: float = REPLY_TIMEOUT, what: str = "condition") -> None:
        rosutil.wait_for(predicate, timeout, self.executor, what, poll=0.01)

    def drain(self, timeout: float = REPLY_TIMEOUT) -> None:
        """Take every message already queued: spin until two spins in a row take none."""
        idle = 0

        def quiet() -> bool:
            nonlocal idle
            before = self.received
            self.executor.spin_once(timeout_sec=0.05)
            idle = idle + 1 if self.received == before else 0
            return idle >= 2

        rosutil.wait_for(quiet, timeout, None, "queued messages drained", poll=0.0)

    def wait_graph(self, subscribers: dict[str, int], publishers: dict[str, int] | None = None,
                   services: tuple[str, ...] = ()) -> None:
        """Until this node sees the given numbers of subscribers/publishers and the services answer."""
        n = self.node
        pubs = publishers or {}

        def ready() -> bool:
            return (all(n.count_subscribers(t) >= k for t, k in subscribers.items())
                    and all(n.count_publishers(t) >= k for t, k in pubs.items())
                    and all(self.clients[s].service_is_ready() for s in services))

        self.wait_for(ready, START_TIMEOUT, f"discovery of {subscribers} / {pubs} / {services}")

    def call(self, name: str, request: Any = None, timeout: float = REPLY_TIMEOUT) -> Any:
        client = self.clients[name]
        self.wait_for(client.service_is_ready, START_TIMEOUT, f"service {client.srv_name}")
        future = client.call_async(client.srv_type.Request() if request is None else request)
        self.wait_for(future.done, timeout, f"answer of {client.srv_name}")
        return future.result()

    def latest_diag(self, after: int | None = None, timeout: float = REPLY_TIMEOUT) -> dict[str, str]:
        """The first sim diagnostics report after the ``after`` reports received so far (default: a new one)."""
        n0 = len(self.diagnostics) if after is None else after
        self.wait_for(lambda: len(self.diagnostics) > n0, timeout, "a diagnostics report of the sim")
        return self.diagnostics[-1]

    def parameter(self, node: str, name: str) -> Any:
        """Current value of ``node``'s (``sim`` / ``ap``) parameter ``name`` through its parameter service."""
        from rcl_interfaces.msg import Parameter as ParameterMsg
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import Parameter

        reply = self.call(f"{node}_get_parameters", GetParameters.Request(names=[name]))
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=reply.values[0])).value


def stamp_s(stamp: Any) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def raw_messages(bag: Path, since: dict[str, int] | None = None) -> dict[str, list[tuple[bytes, Any]]]:
    """Every message of a bag per topic as (raw CDR bytes, decoded message), in bag order.

    ``since``: per topic, the bag time [ns] before which messages are skipped."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[tuple[bytes, Any]]] = {}
    with AnyReader([bag]) as reader:
        for conn, t, raw in reader.messages():
            if since and t < since.get(conn.topic, 0):
                continue
            out.setdefault(conn.topic, []).append((bytes(raw), reader.deserialize(raw, conn.msgtype)))
    return out

"""Helpers for the node tests: start the real node as a subprocess, talk to it over the middleware.

No mocks of ROS: a :class:`Probe` is an ordinary rclpy node in the test process
(with ``use_sim_time``, so it is also "a second node following the sim's clock").
Every wait has a timeout and spins the executor; nothing sleeps a fixed time.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import Parameter
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter as RclParameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

import rosutil
from lander_interfaces.msg import FlightEvent, LanderState, ThrottleCommand

REPO = Path(__file__).resolve().parents[2]


@contextmanager
def sim_node(params: dict[str, object], log: Path) -> Iterator[subprocess.Popen]:
    """Run ``python -m lander_sim.node`` with ``params`` (``-p k:=v``); stop it with SIGINT afterwards."""
    args = [sys.executable, "-m", "lander_sim.node", "--ros-args"]
    for k, v in params.items():
        args += ["-p", f"{k}:={_ros_literal(v)}"]
    with open(log, "w") as out:
        proc = subprocess.Popen(args, cwd=REPO, stdout=out, stderr=subprocess.STDOUT, env=os.environ.copy())
        try:
            yield proc
        finally:
            if proc.poll() is None:
                proc.send_signal(2)
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()


def _ros_literal(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return v if v else "''"
    return repr(v)


class Probe:
    """A test-side node: subscribes to the sim's outputs, publishes inputs, calls services."""

    def __init__(self, name: str = "sim_test_probe") -> None:
        self.node = Node(name, parameter_overrides=[RclParameter("use_sim_time", value=True)])
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.states: deque[LanderState] = deque(maxlen=100_000)
        self.clock_seen_at_state: deque[tuple[int, int]] = deque(maxlen=100_000)  # (state stamp ns, probe clock ns)
        self.events: list[FlightEvent] = []
        self.diagnostics: list[dict[str, str]] = []
        self.clocks: deque[int] = deque(maxlen=100_000)
        self.answer: Callable[[LanderState], list[float] | None] | None = None  # lockstep controller, if set
        n = self.node
        n.create_subscription(LanderState, "/lander/state", self._on_state, 1000)
        n.create_subscription(Clock, "/clock", lambda m: self.clocks.append(_ns(m.clock)), 1000)
        n.create_subscription(FlightEvent, "/lander/events", self.events.append, 10_000)
        n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.throttle_pub = n.create_publisher(ThrottleCommand, "/lander/throttle", qos)
        self.wind_pub = n.create_publisher(Vector3Stamped, "/lander/wind", qos)
        self.clients = {
            **rosutil.sim_service_clients(n),
            "set_parameters": n.create_client(SetParameters, "/lander_sim/set_parameters"),
        }

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.node.destroy_node()

    # --- callbacks ---------------------------------------------------------------------------

    def _on_state(self, msg: LanderState) -> None:
        self.states.append(msg)
        self.clock_seen_at_state.append((_ns(msg.header.stamp), self.node.get_clock().now().nanoseconds))
        if self.answer is not None:
            throttles = self.answer(msg)
            if throttles is not None:
                self.send_throttles(throttles, msg.sequence)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            self.diagnostics.append({kv.key: kv.value for kv in st.values})

    # --- waiting -----------------------------------------------------------------------------

    def wait_for(self, predicate: Callable[[], bool], timeout: float, what: str) -> None:
        """Spin until ``predicate()`` holds; fail the test naming ``what`` after ``timeout`` wall seconds."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out after {timeout} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.01)

    def spin_for(self, seconds: float) -> None:
        """Serve callbacks for ``seconds`` of wall time (a measurement window, not a synchronisation)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.01, max(0.0, end - time.monotonic())))

    def call(self, name: str, request=None, timeout: float = 30.0):
        """Call service ``name`` and return its response."""
        client = self.clients[name]
        if not client.wait_for_service(timeout_sec=timeout):
            raise AssertionError(f"service {name} not available after {timeout} s")
        if request is None:
            request = client.srv_type.Request()
        future = client.call_async(request)
        self.wait_for(future.done, timeout, f"a response from {name}")
        return future.result()

    def set_params(self, **params: object) -> None:
        """Set sim-node parameters through its standard parameter service; fail on refusal."""
        req = SetParameters.Request()
        for k, v in params.items():
            req.parameters.append(Parameter(name=k, value=rosutil.param_value(v)))
        res = self.call("set_parameters", req)
        for k, r in zip(params, res.results):
            assert r.successful, f"parameter {k} refused: {r.reason}"

    def set_params_result(self, **params: object):
        req = SetParameters.Request()
        for k, v in params.items():
            req.parameters.append(Parameter(name=k, value=rosutil.param_value(v)))
        return self.call("set_parameters", req).results

    def wait_connected(self, timeout: float = 30.0) -> None:
        """Until the sim node's subscribers see our publishers and its services answer."""
        self.wait_for(
            lambda: self.throttle_pub.get_subscription_count() > 0 and self.wind_pub.get_subscription_count() > 0,
            timeout,
            "the sim node to subscribe to /lander/throttle and /lander/wind",
        )
        for c in self.clients.values():
            assert c.wait_for_service(timeout_sec=timeout), f"service {c.srv_name} not available"

    def latest_state_after(self, action: Callable[[], object], timeout: float = 10.0) -> LanderState:
        """Do ``action`` (a service call that publishes a state) and return the state it published."""
        n0 = len(self.states)
        action()
        self.wait_for(lambda: len(self.states) > n0, timeout, "a state message")
        return self.states[-1]

    def send_throttles(self, throttles: list[float], sequence: int = 0) -> None:
        msg = ThrottleCommand()
        msg.state_sequence = sequence
        msg.throttles = [float(x) for x in throttles]
        self.throttle_pub.publish(msg)

    def send_wind(self, x: float, y: float, z: float, frame: str = "mars") -> None:
        msg = Vector3Stamped()
        msg.header.frame_id = frame
        msg.vector.x, msg.vector.y, msg.vector.z = x, y, z
        self.wind_pub.publish(msg)

    def diag_after(self, n_before: int, timeout: float = 10.0) -> dict[str, str]:
        """The first diagnostics report newer than the first ``n_before`` received."""
        self.wait_for(lambda: len(self.diagnostics) > n_before, timeout, "a diagnostics report")
        return self.diagnostics[-1]


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def state_ns(msg: LanderState) -> int:
    return _ns(msg.header.stamp)


def state_fields(msg: LanderState) -> dict[str, object]:
    """Every physical field of a state message (all but ``sequence``), for exact comparisons."""
    return {
        "stamp": _ns(msg.header.stamp),
        "frame_id": msg.header.frame_id,
        "position": (msg.position.x, msg.position.y, msg.position.z),
        "velocity": (msg.velocity.x, msg.velocity.y, msg.velocity.z),
        "orientation": (msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w),
        "euler_zxz": tuple(msg.euler_zxz),
        "gimbal_lock": msg.gimbal_lock,
        "angular_velocity": (msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z),
        "altitude": msg.altitude,
        "climb_rate": msg.climb_rate,
        "ground_speed": msg.ground_speed,
        "mass": msg.mass,
        "fuel_mass": msg.fuel_mass,
        "throttles": tuple(msg.throttles),
        "phase": msg.phase,
        "parachute_deployed": msg.parachute_deployed,
        "stabiliser_on": msg.stabiliser_on,
    }

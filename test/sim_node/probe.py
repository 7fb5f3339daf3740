"""Helpers for the node tests: start the real node as a subprocess, talk to it over the middleware.

No mocks of ROS: a :class:`Probe` is an ordinary rclpy node in the test process
(with ``use_sim_time``, so it is also "a second node following the sim's clock").
Every wait has a timeout and spins the executor; nothing sleeps a fixed time.
"""
from __future__ import annotations

import subprocess
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import Parameter
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter as RclParameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

import rosutil
from lander_interfaces.msg import FlightEvent, LanderState, ThrottleCommand

REPO = Path(__file__).resolve().parents[2]


@contextmanager
def sim_node(params: dict[str, object], log: Path) -> Iterator[subprocess.Popen]:
    """Run ``python -m lander_sim.node`` with ``params`` (``-p k:=v``); stop it with SIGINT afterwards.
    ``log`` shows its output while it runs (a link to the child's log) and keeps it afterwards."""
    child = rosutil.start_node("lander_sim.node", params, name="sim")
    log.symlink_to(child.log.name)
    try:
        yield child.proc
    finally:
        child.stop(grace=10.0)
        log.unlink()
        log.write_text(child.output())
        child.close()


class Probe(rosutil.Observer):
    """A test-side node: subscribes to the sim's outputs, publishes inputs, calls services."""

    start_timeout = 30.0
    reply_timeout = 30.0

    def __init__(self, name: str = "sim_test_probe") -> None:
        super().__init__(name, node_kwargs={"parameter_overrides": [RclParameter("use_sim_time", value=True)]})
        self.states: deque[LanderState] = deque(maxlen=100_000)
        self.clock_seen_at_state: deque[tuple[int, int]] = deque(maxlen=100_000)  # (state stamp ns, probe clock ns)
        self.diagnostics: list[dict[str, str]] = []
        self.clocks: deque[int] = deque(maxlen=100_000)
        self.answer: Callable[[LanderState], list[float] | None] | None = None  # lockstep controller, if set
        n = self.node
        n.create_subscription(LanderState, "/lander/state", self._on_state, 1000)
        n.create_subscription(Clock, "/clock", lambda m: self.clocks.append(_ns(m.clock)), 1000)
        self.events: list[FlightEvent] = self.record("/lander/events", FlightEvent)
        n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.throttle_pub = n.create_publisher(ThrottleCommand, "/lander/throttle", qos)
        self.wind_pub = n.create_publisher(Vector3Stamped, "/lander/wind", qos)
        self.clients = {
            **rosutil.sim_service_clients(n),
            "set_parameters": n.create_client(SetParameters, "/lander_sim/set_parameters"),
        }

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

    # --- the sim's parameters ------------------------------------------------------------------

    def set_params(self, **params: object) -> None:
        """Set sim-node parameters through its standard parameter service; fail on refusal."""
        for k, r in zip(params, self.set_params_result(**params)):
            assert r.successful, f"parameter {k} refused: {r.reason}"

    def set_params_result(self, **params: object) -> Any:
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
        self.wait_graph({}, services=tuple(self.clients))

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

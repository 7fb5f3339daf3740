"""The running system under test: sim, autopilot and recorder as real processes, and a watch node.

No mocks: :class:`Stack` starts ``python -m lander_sim.node``, ``python -m lander_autopilot.node``
and ``python -m lander_tools.recorder`` as children (environment of this run: its own
ROS_DOMAIN_ID), and :class:`Watch` is an ordinary rclpy node in the test process that records
what they publish, publishes inputs and calls their services. Every wait spins until a condition
holds or a timeout expires; nothing sleeps a fixed time.
"""
from __future__ import annotations

import os
import signal
import sys
from pathlib import Path
from typing import Any

import rosutil
from lander_ros.flight_span import sim_report
from lander_ros.stamps import stamp_to_seconds

REPO = Path(__file__).resolve().parents[2]
#: Process start-up and discovery on a loaded 2-core machine (rclpy + python-control imports).
START_TIMEOUT = 45.0
#: One request/answer or a short chain of messages over the middleware.
REPLY_TIMEOUT = 15.0


stamp_s = stamp_to_seconds


class Stack:
    """Child processes of one test (stopped and, on failure, their output printed at teardown)."""

    def __init__(self) -> None:
        self.children: dict[str, rosutil.ChildProcess] = {}
        self.env = dict(os.environ)

    def _keep(self, name: str, child: rosutil.ChildProcess) -> rosutil.ChildProcess:
        old = self.children.get(name)
        if old is not None:
            old.close()
        self.children[name] = child
        return child

    def sim(self, **params: object) -> rosutil.ChildProcess:
        return self._keep("sim", rosutil.start_node("lander_sim.node", params, name="sim", env=self.env))

    def autopilot(self, **params: object) -> rosutil.ChildProcess:
        return self._keep("autopilot", rosutil.start_node("lander_autopilot.node", params, name="autopilot", env=self.env))

    def recorder(self, bag: Path, topics: tuple[str, ...]) -> rosutil.ChildProcess:
        return self._keep("recorder", rosutil.ChildProcess(["-m", "lander_tools.recorder", "-o", str(bag), *topics],
                                                          env=self.env, cwd=REPO, name="recorder"))

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


class Watch(rosutil.Observer):
    """Test-side node: records outputs of sim and autopilot, publishes inputs, calls services."""

    start_timeout = START_TIMEOUT
    reply_timeout = REPLY_TIMEOUT

    def __init__(self, context: Any, name: str = "reliability_watch") -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import Vector3Stamped
        from rcl_interfaces.srv import GetParameters, SetParameters
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from std_msgs.msg import Float64
        from std_srvs.srv import Trigger

        from lander_interfaces.msg import AutopilotStatus, FlightEvent, LanderState, ThrottleCommand
        from lander_interfaces.srv import SwitchController

        super().__init__(name, context)
        n = self.node
        deep = 100_000
        self.states: list[Any] = self.record("/lander/state", LanderState, depth=deep)
        self.throttles: list[Any] = self.record("/lander/throttle", ThrottleCommand, depth=deep)
        self.statuses: list[Any] = self.record("/autopilot/status", AutopilotStatus, depth=deep)
        self.events: list[Any] = self.record("/lander/events", FlightEvent, depth=deep)
        self.diagnostics: list[dict[str, str]] = []
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
            "autopilot_matched": n.create_client(Trigger, "/autopilot/matched"),
        }

    def _on_diag(self, msg: Any) -> None:
        report = sim_report(msg)
        if report is not None:
            self.diagnostics.append(report)

    def latest_diag(self, after: int | None = None, timeout: float = REPLY_TIMEOUT) -> dict[str, str]:
        """The first sim diagnostics report after the ``after`` reports received so far (default: a new one)."""
        n0 = len(self.diagnostics) if after is None else after
        self.wait_for(lambda: len(self.diagnostics) > n0, timeout, "a diagnostics report of the sim")
        return self.diagnostics[-1]

    def parameter(self, node: str, name: str) -> Any:  # type: ignore[override]  # by node name here
        """Current value of ``node``'s (``sim`` / ``ap``) parameter ``name`` through its parameter service."""
        return super().parameter(f"{node}_get_parameters", name)


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

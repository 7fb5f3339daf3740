"""A client of a running flight over ROS: what ``ros2 topic pub`` / ``ros2 service call`` /
``ros2 param set`` would do on a full install, for the CLI verbs and the live bridge.

Every action goes to the nodes' own doors, so validation and rejection counting stay theirs
(docs/sim_node.md "Bad input", docs/autopilot_node.md "Parameters"):

* demand altitude, controller, gains: the autopilot's parameter services (``/autopilot/set_parameters``,
  ``set_parameters_atomically``): the answer carries the node's reason when it refuses;
* switch controller: ``/autopilot/switch_controller``;
* pause / resume / step / reset: ``/lander/*`` services, their response as is;
* wind, manual throttles: the topics ``/lander/wind`` and ``/lander/throttle``. A topic has no
  answer, so :meth:`FlightLink.publish_wind` watches ``/lander/events`` for the simulator's
  ``INPUT_REJECTED`` of that kind for ``REJECT_WINDOW`` s of wall time.

The link's node spins in a thread of its own (the owner's thread only waits on futures).
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from lander_tools.bagio import message_class

#: Wall seconds a CLI verb waits for the flight's nodes to appear (discovery takes up to ~3 s with
#: several processes starting on 2 cores: /work/shared/notes/ros2-from-pypi.md).
DISCOVERY_TIMEOUT = 3.0
#: Wall seconds to wait for a service's answer.
CALL_TIMEOUT = 10.0
#: [s] a query unanswered this long is sent again (:meth:`FlightLink.call`, ``ask_again``)
ASK_AGAIN = 1.0
#: Wall seconds to watch for the simulator's rejection of a published input (it answers within a
#: callback pass, ~1 ms when idle; the window covers a loaded 2-core machine).
REJECT_WINDOW = 0.5
SIM_NODE = "/lander_sim"
AUTOPILOT_NODE = "/autopilot"
ESTIMATOR_NODE = "/lander_estimator"  #: lander_autopilot.estimator_node


class NoFlight(ValueError):
    """No flight (simulator node) is running in this ROS domain."""


@dataclass(frozen=True)
class Outcome:
    """The answer of one action: ``ok`` and the node's message (its reason when refused).
    ``values`` holds extra response fields (e.g. ``sim_time`` of a step)."""

    ok: bool
    message: str = ""
    values: dict[str, Any] | None = None


def message_to_dict(msg: Any) -> Any:
    """A ROS message as plain Python (dicts, lists, numbers, strings), for JSON and printing."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {f: message_to_dict(getattr(msg, f)) for f in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == "ndarray" or type(msg).__name__ == "array":
        return [message_to_dict(x) for x in msg]
    if isinstance(msg, bytes):
        return list(msg)
    return msg


class FlightLink:
    """A node (``name``) in its own context and executor thread, talking to the flight's nodes.

    Use as a context manager or call :meth:`close`. ``context``: an rclpy Context to use
    (default: a new one, initialised here and shut down by :meth:`close`).
    """

    def __init__(self, name: str = "lander_cli", context: Any = None) -> None:
        import rclpy
        from rclpy.context import Context

        from lander_ros.delivery import events_executor

        self._own_context = context is None
        self.context = Context() if context is None else context
        if self._own_context:
            rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context, start_parameter_services=False)
        self._clients: dict[str, Any] = {}
        self._pubs: dict[str, Any] = {}
        self._rejections: list[tuple[float, str]] = []  # (monotonic time, detail) from the sim
        self._lock = threading.Lock()
        self._event_sub: Any = None
        self._executor = events_executor(self.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name=f"{name}-spin", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.05)
            except Exception as exc:  # noqa: BLE001 - a callback's error must not stop the link
                if not self.context.ok():
                    break  # context shut down under us: the link is over
                self.node.get_logger().error(f"callback failed: {type(exc).__name__}: {exc}")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        try:
            self._executor.shutdown()
            self.node.destroy_node()
        except Exception:  # noqa: BLE001 - context may be gone already
            pass
        if self._own_context and self.context.ok():
            import rclpy

            rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> FlightLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- graph ------------------------------------------------------------------------------

    def node_names(self) -> set[str]:
        return {(ns.rstrip("/") + "/" + n) for n, ns in self.node.get_node_names_and_namespaces()}

    def wait_for_node(self, full_name: str = SIM_NODE, timeout: float = DISCOVERY_TIMEOUT) -> None:
        """Return once ``full_name`` is in the graph; :class:`NoFlight` naming the wait otherwise."""
        import os

        deadline = time.monotonic() + timeout
        while full_name not in self.node_names():
            if time.monotonic() > deadline:
                what = "no flight running" if full_name == SIM_NODE else f"no {full_name} node in the flight"
                raise NoFlight(f"{what}: {full_name} not seen in ROS_DOMAIN_ID="
                               f"{os.environ.get('ROS_DOMAIN_ID', '0')} within {timeout:g} s")
            time.sleep(0.02)

    def topics(self) -> list[tuple[str, list[str]]]:
        return sorted(self.node.get_topic_names_and_types())

    def await_topics(self, topics: Sequence[str], timeout: float = DISCOVERY_TIMEOUT
                     ) -> tuple[list[tuple[str, list[str]]], list[str]]:
        """The graph's topics once every one of ``topics`` is in it with a type, or at ``timeout``
        with those still missing: ``(rows, missing)``. A node is in the graph before all its
        endpoints are (the node list and the endpoints are discovered apart), so a list taken
        the moment the node appears can lack some of its topics."""
        deadline = time.monotonic() + timeout
        while True:
            rows = self.topics()
            seen = {name for name, types in rows if types}
            missing = [t for t in topics if t not in seen]
            if not missing or time.monotonic() > deadline:
                return rows, missing
            time.sleep(0.02)

    def topic_type(self, topic: str, timeout: float = DISCOVERY_TIMEOUT) -> str:
        """The type of ``topic`` once it appears; :class:`NoFlight` if it does not."""
        rows, missing = self.await_topics([topic], timeout)
        if missing:
            raise NoFlight(f"topic {topic} not seen within {timeout:g} s (see 'lander topics')")
        return dict(rows)[topic][0]

    # --- services ---------------------------------------------------------------------------

    def _client(self, srv_type: Any, name: str) -> Any:
        with self._lock:
            if name not in self._clients:
                self._clients[name] = self.node.create_client(srv_type, name)
            return self._clients[name]

    def call(self, srv_type: Any, name: str, request: Any, timeout: float = CALL_TIMEOUT,
             ask_again: float | None = None, confirm: Callable[[], Any] | None = None) -> Any:
        """Call service ``name`` and return its response; :class:`NoFlight` if it is not there,
        ``TimeoutError`` if it does not answer in ``timeout`` s.

        A service is "available" once this client's requests reach it; the server's reply reaches
        this client only if the server has matched this client's reply reader within 100 ms of
        sending it (rmw_fastrtps; rclpy then logs "failed to send response (timeout)" in the
        server and drops the reply), which a fresh client on a loaded machine can miss.

        ``ask_again`` [s], for a request that changes nothing (a query): sent again at that interval
        until answered; a second request finds the reply path matched. Never for a request that
        acts (step, switch, set). For one that acts, ``confirm`` (called every :data:`ASK_AGAIN` s
        while no reply has come) reads back through a query whether the request took effect: its
        value, if not None, is returned in place of the reply."""
        client = self._client(srv_type, name)
        if not client.wait_for_service(timeout_sec=timeout):
            raise NoFlight(f"service {name} not available within {timeout:g} s (is a flight running?)")
        deadline = time.monotonic() + timeout
        while True:
            done = threading.Event()
            fut = client.call_async(request)
            fut.add_done_callback(lambda _f, d=done: d.set())
            while True:
                left = max(deadline - time.monotonic(), 0.0)
                if done.wait(left if ask_again is None and confirm is None else min(ask_again or ASK_AGAIN, left)):
                    return fut.result()
                if confirm is not None and left > 0.0:
                    seen = confirm()
                    if done.is_set():  # the reply came while the read-back was asked: it speaks
                        return fut.result()
                    if seen is not None:
                        client.remove_pending_request(fut)
                        return seen
                    continue
                break
            client.remove_pending_request(fut)
            if ask_again is None or time.monotonic() >= deadline:
                raise TimeoutError(f"service {name} did not answer within {timeout:g} s")

    def sim_service(self, name: str, **fields: Any) -> Outcome:
        """``/lander/<name>`` (pause, resume, step, reset, deploy_parachute, ...): its response."""
        from std_srvs.srv import SetBool, Trigger

        from lander_interfaces.srv import LoadScene, Reset, RunUntil, StepSimulation

        types = {"load_scene": LoadScene, "reset": Reset, "pause": Trigger, "resume": Trigger,
                 "step": StepSimulation, "run_until": RunUntil, "deploy_parachute": Trigger,
                 "set_stabiliser": SetBool}
        if name not in types:
            raise ValueError(f"unknown simulator service {name!r}; choose one of {', '.join(types)}")
        srv = types[name]
        req = srv.Request()
        for k, v in fields.items():
            setattr(req, k, v)
        resp = self.call(srv, f"/lander/{name}", req)
        extra = {k: getattr(resp, k) for k in ("sim_time", "sim_time_reached") if hasattr(resp, k)}
        return Outcome(bool(resp.success), resp.message, extra or None)

    def switch_controller(self, controller: str, parameters_yaml: str = "") -> Outcome:
        """Swap the autopilot's controller (``/autopilot/switch_controller``). Should the reply be
        lost (:meth:`call`), the autopilot's ``controller`` and ``controller_params`` read back
        tell whether the switch was made, when they differed from the request's before it."""
        from lander_interfaces.srv import SwitchController

        names = ["controller", "controller_params"]
        before = self.get_parameters(AUTOPILOT_NODE, names)
        asked = {"controller": controller, "controller_params": parameters_yaml}

        def made() -> Outcome | None:
            now = self.get_parameters(AUTOPILOT_NODE, names)
            if now != asked:
                return None
            return Outcome(True, f"switched {before['controller']!r} -> {controller!r} (the autopilot's reply was "
                                 "lost on the way; its parameters read back show the switch made)",
                           {"active_controller": controller})

        resp = self.call(SwitchController, "/autopilot/switch_controller",
                         SwitchController.Request(controller=controller, parameters_yaml=parameters_yaml),
                         confirm=made if before != asked else None)
        if isinstance(resp, Outcome):
            return resp
        return Outcome(bool(resp.success), resp.message or f"active controller: {resp.active_controller}",
                       {"active_controller": resp.active_controller})

    # --- parameters ---------------------------------------------------------------------------

    def set_parameters(self, node: str, values: dict[str, Any], atomically: bool = False) -> Outcome:
        """Set parameters of ``node`` (e.g. ``/autopilot``) through its parameter services; typed by
        the Python value (float -> double, str -> string, ...). Refused: the node's reason. Should
        the reply be lost (:meth:`call`), the values read back tell whether they were set, when
        they differed from the request's before it."""
        from rcl_interfaces.msg import Parameter
        from rcl_interfaces.srv import SetParameters, SetParametersAtomically

        from lander_tools.live.params import parameter_value

        names = list(values)
        before = self.get_parameters(node, names)

        def made() -> Outcome | None:
            if self.get_parameters(node, names) != values:
                return None
            return Outcome(True, f"ok (the reply of {node} was lost on the way; its parameters read back "
                                 "are those asked)")

        confirm = made if before != values else None
        params = [Parameter(name=k, value=parameter_value(v)) for k, v in values.items()]
        if atomically:
            resp = self.call(SetParametersAtomically, f"{node}/set_parameters_atomically",
                             SetParametersAtomically.Request(parameters=params), confirm=confirm)
            if isinstance(resp, Outcome):
                return resp
            results = [resp.result]
        else:
            resp = self.call(SetParameters, f"{node}/set_parameters", SetParameters.Request(parameters=params),
                             confirm=confirm)
            if isinstance(resp, Outcome):
                return resp
            results = list(resp.results)
        bad = [r.reason or "refused" for r in results if not r.successful]
        return Outcome(not bad, "; ".join(bad) if bad else "ok")

    def get_parameters(self, node: str, names: Sequence[str]) -> dict[str, Any]:
        """Current values of ``names`` on ``node`` (None for one it does not have)."""
        from rcl_interfaces.srv import GetParameters

        from lander_tools.live.params import python_value

        resp = self.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=list(names)),
                         ask_again=ASK_AGAIN)
        return {n: python_value(v) for n, v in zip(names, resp.values)}

    def set_demand(self, altitude_m: float) -> Outcome:
        """Demand altitude [m]: the autopilot's ``demand_altitude`` parameter (the door its
        ``/lander/demand_altitude`` topic uses too)."""
        return self.set_parameters(AUTOPILOT_NODE, {"demand_altitude": float(altitude_m)})

    # --- topics -------------------------------------------------------------------------------

    def _publisher(self, msg_type: Any, topic: str) -> Any:
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        with self._lock:
            if topic not in self._pubs:
                self._pubs[topic] = self.node.create_publisher(
                    msg_type, topic, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
            return self._pubs[topic]

    def watch_rejections(self) -> None:
        """Start collecting the simulator's INPUT_REJECTED events (call before publishing)."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        from lander_interfaces.msg import FlightEvent

        with self._lock:
            if self._event_sub is not None:
                return

            def on_event(msg: Any) -> None:
                if msg.kind == FlightEvent.INPUT_REJECTED:
                    with self._lock:
                        self._rejections.append((time.monotonic(), msg.detail))

            self._event_sub = self.node.create_subscription(
                FlightEvent, "/lander/events", on_event, QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))

    def _wait_matched(self, pub: Any, timeout: float = DISCOVERY_TIMEOUT) -> None:
        deadline = time.monotonic() + timeout
        while pub.get_subscription_count() == 0:
            if time.monotonic() > deadline:
                raise NoFlight(f"nobody subscribes to {pub.topic_name} within {timeout:g} s (is a flight running?)")
            time.sleep(0.01)
        if self._event_sub is not None:
            while self._event_sub.get_publisher_count() == 0 and time.monotonic() < deadline:
                time.sleep(0.01)

    def _publish_checked(self, pub: Any, msg: Any, kind: str, wait: bool) -> Outcome:
        self._wait_matched(pub)
        t0 = time.monotonic()
        pub.publish(msg)
        if not wait:
            return Outcome(True, "published")
        deadline = t0 + REJECT_WINDOW
        while time.monotonic() < deadline:
            with self._lock:
                hits = [d for t, d in self._rejections if t >= t0 and d.startswith(kind + ".")]
            if hits:
                return Outcome(False, f"{SIM_NODE}: {hits[0]}")
            time.sleep(0.01)
        return Outcome(True, "published (no rejection from the simulator within "
                             f"{REJECT_WINDOW:g} s)")

    def publish_demand_altitude(self, altitude_m: float, wait: bool = False) -> Outcome:
        """Demand altitude [m] on the autopilot's ``/lander/demand_altitude`` topic (what a client
        publishing on that topic means; :meth:`set_demand` takes the parameter's door)."""
        from std_msgs.msg import Float64

        if wait:
            self.watch_rejections()
        return self._publish_checked(self._publisher(Float64, "/lander/demand_altitude"), Float64(data=float(altitude_m)),
                                     "demand", wait)

    def publish_wind(self, wind_W: Sequence[float], frame_id: str = "mars", wait: bool = True) -> Outcome:
        """Wind [m/s], world frame, on ``/lander/wind``; with ``wait``, watch for its refusal."""
        from geometry_msgs.msg import Vector3Stamped

        msg = Vector3Stamped()
        msg.header.frame_id = frame_id
        msg.vector.x, msg.vector.y, msg.vector.z = (float(c) for c in wind_W)
        if wait:
            self.watch_rejections()
        return self._publish_checked(self._publisher(Vector3Stamped, "/lander/wind"), msg, "wind", wait)

    def publish_throttles(self, throttles: Sequence[float], wait: bool = False) -> Outcome:
        """Manual throttles (0..1 per thruster) on ``/lander/throttle`` with ``state_sequence`` 0
        (not an answer to a state: held by the simulator's command hold, docs/sim_node.md)."""
        from lander_interfaces.msg import ThrottleCommand

        msg = ThrottleCommand(state_sequence=0, throttles=[float(x) for x in throttles])
        if wait:
            self.watch_rejections()
        return self._publish_checked(self._publisher(ThrottleCommand, "/lander/throttle"), msg, "throttle", wait)

    def create_subscription(self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: Any) -> Any:
        """A subscription of the link's node with the QoS given, made under the link's lock as its
        clients and publishers are (the owner's threads may be making them meanwhile)."""
        with self._lock:
            return self.node.create_subscription(msg_type, topic, callback, qos)

    def subscribe(self, topic: str, msgtype: str, callback: Callable[[Any], None], depth: int = 100) -> Any:
        """Subscribe to ``topic`` (QoS following its publishers, as the recorder does)."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        pubs = self.node.get_publishers_info_by_topic(topic)
        reliable = bool(pubs) and all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in pubs)
        latched = bool(pubs) and all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in pubs)
        qos = QoSProfile(depth=depth,
                         reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
        return self.create_subscription(message_class(msgtype), topic, callback, qos)

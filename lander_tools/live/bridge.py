"""``lander live``: serve a running flight over the Foxglove WebSocket protocol, and a student page.

Run (project venv, next to a flight in the same ROS domain)::

    ./dev fly hover --speed 1 &            # or: ./dev fly hover --live
    ./dev live                              # ws://127.0.0.1:8765 and http://127.0.0.1:8766/
    ./dev exec python -m lander_tools.live.bridge --port 0 --page-port 0   # free ports, printed

One rclpy node (``/lander_live``) in one process. It only *subscribes* to the flight (it is no
lockstep participant and never asks for the sim's optional outputs: odometry, pose, markers), so
a lockstep flight is bit-identical with and without it. The state subscription is best effort
with depth 1 and polled (not one Python callback per state): a busy bridge drops states, it never
holds the simulator back, and its cost does not grow with the flight's speed.

Served (foxglove-sdk ``start_server``; sim time of the latest state is the server's time):

* ``/live/state`` (JSON, :data:`lander_tools.live.views.STATE_SCHEMA`): altitude, climb rate,
  ground speed, Euler angles, body rates, throttles, fuel, demand, controller, paused; the latest
  state, taken every ``1 / (2 max_rate)`` s and sent at most ``max_rate`` times a wall second
  (every state while they come slower than that).
* ``/live/scene`` (``foxglove.SceneUpdate``): body, one plume per thruster scaled by its
  throttle, trail, ground, parachute when open; ``/live/tf`` (``foxglove.FrameTransforms``):
  ``mars -> surface`` and ``mars -> base_link`` (frames: :mod:`lander_tools.live.views`).
* ``/live/events`` (JSON): every ``FlightEvent``; ``/live/status`` (JSON): the bridge's counters.

Client actions go to the flight's own doors through :class:`lander_tools.live.link.FlightLink`,
so the nodes validate and count them exactly as for any ROS client:

* parameters ``demand_altitude``, ``controller``, ``controller_params`` (the autopilot's);
* client publish: ``/lander/demand_altitude`` ``{"data": m}``, ``/lander/wind`` ``{"x","y","z"}``
  (world frame, m/s), ``/lander/throttle`` ``{"throttles": [...]}``, re-published on the ROS topics;
* services (JSON request and response, the ROS service's fields): ``/lander/pause``,
  ``/lander/resume``, ``/lander/step``, ``/lander/reset``, ``/lander/deploy_parachute``,
  ``/lander/set_stabiliser``, ``/autopilot/switch_controller``.

What the bridge cannot even forward (malformed JSON, unknown topic, a field of the wrong type) is
refused with a one-line status to the clients and counted under ``refused`` in ``/live/status``;
refusals by the nodes are counted there too (``refused.node.*``: the nodes' own counters stay the
record). See docs/live.md.
"""
from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lander_ros.flight_span import sim_report
from lander_ros.stamps import stamp_to_seconds
from lander_tools.live import scene, views
from lander_tools.live.clientinput import (
    SERVICE_FIELDS,
    ClientInputError,
    parse_client_message,
    parse_service_request,
)
from lander_tools.live.link import (
    AUTOPILOT_NODE,
    SIM_NODE,
    FlightLink,
    NoFlight,
    Outcome,
)

DEFAULT_PORT = 8765
#: Upper bound on the page's update rate [Hz, wall]: above what a screen shows, below what would
#: cost the machine the flight's speed at ``--speed 0``.
DEFAULT_MAX_RATE = 60.0
WEB_DIR = Path(__file__).resolve().parent / "web"
AUTOPILOT_PARAMETERS = ("demand_altitude", "controller", "controller_params")
#: The simulator's topics the bridge subscribes to: what a launcher that starts it must count
#: among the subscriptions to wait for (lander_tools.fly.flight.expected_subscribers).
SUBSCRIBED_TOPICS = ("/lander/state", "/lander/events", "/diagnostics")
NODE_NAME = "lander_live"

class LiveBridge:
    """The bridge: a :class:`FlightLink` node plus a foxglove WebSocket server and the page server.

    ``port``/``page_port``: 0 picks free ports (read :attr:`port`, :attr:`page_port`);
    ``page_port=None``: no page server. ``context``: an rclpy Context (default: a new one).
    """

    def __init__(self, port: int = DEFAULT_PORT, page_port: int | None = DEFAULT_PORT + 1,
                 host: str = "127.0.0.1", max_rate: float = DEFAULT_MAX_RATE, context: Any = None) -> None:
        import foxglove
        from foxglove import Capability
        from foxglove.channels import FrameTransformsChannel, SceneUpdateChannel
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

        if not max_rate > 0:
            raise ValueError(f"max_rate must be > 0 Hz, got {max_rate!r}")
        self.min_interval = 1.0 / max_rate
        self.refused: Counter[str] = Counter()
        self.forwarded = 0
        self.states_in = 0
        self.states_out = 0
        self.paused = False
        self.params: dict[str, Any] = {"demand_altitude": None, "controller": "", "controller_params": ""}
        self.tracker: views.SceneTracker | None = None
        self.history = views.History()
        #: The mean wind in force [m/s, world]: the scene's until the simulator reports its own
        #: (``mean_wind_W`` in its /diagnostics, sent at once when a wind is accepted); a reset
        #: restores the scene's, as the simulator does.
        self.wind_W: list[float] | None = None
        self._scene_wind_W: list[float] | None = None
        self._latest: bytes | None = None
        self._latest_published = True
        self._last_out = 0.0
        self._last_seq = 0
        self._lock = threading.Lock()
        self._pub_lock = threading.Lock()
        self._call_lock = threading.Lock()  # one publisher at a time: the spin thread or poll()
        self._client_topics: dict[tuple[int, int], str] = {}
        self.ready = False  # the simulator was found and its scene read
        self.autopilot_read = False  # the autopilot (if any) was found and its parameters read

        self.link = FlightLink(NODE_NAME, context=context)
        from lander_interfaces.msg import FlightEvent, LanderState

        self._LanderState = LanderState
        ctx = foxglove.Context()
        self.ctx = ctx
        self.ch_state = foxglove.Channel("/live/state", schema=views.STATE_SCHEMA, context=ctx)
        self.ch_events = foxglove.Channel("/live/events", schema={"type": "object", "title": "lander.LiveEvent"},
                                          context=ctx)
        self.ch_status = foxglove.Channel("/live/status", schema={"type": "object", "title": "lander.LiveStatus"},
                                          context=ctx)
        self.ch_scene = SceneUpdateChannel("/live/scene", context=ctx)
        self.ch_tf = FrameTransformsChannel("/live/tf", context=ctx)
        self.server = foxglove.start_server(
            name="mars-lander", host=host, port=port, context=ctx, server_listener=_Listener(self),
            capabilities=[Capability.Parameters, Capability.ClientPublish, Capability.Services, Capability.Time],
            supported_encodings=["json"], services=self._services(),
        )
        self.port = self.server.port
        self.host = host
        self.page = None
        self.page_port: int | None = None
        if page_port is not None:
            from lander_tools.live.page import PageServer

            self.page = PageServer(host, page_port, self.port, routes={"/history.json": self.history_json})
            self.page_port = self.page.port

        state_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
        reliable = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE)
        # The state is not taken per message by an executor (up to thousands a second at --speed 0,
        # ~26 us of Python each): a node of its own that no executor spins holds the latest state
        # (depth 1, best effort: DDS keeps it without Python), and a reader thread takes it at
        # twice the publishing rate cap. Every state is shown while they come slower than that.
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rcl_interfaces.msg import ParameterEvent

        self._state_node = rclpy.create_node(NODE_NAME + "_state", context=self.link.context,
                                             start_parameter_services=False)
        self._state_sub = self._state_node.create_subscription(LanderState, "/lander/state", lambda _m: None,
                                                               state_qos, raw=True)
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read_states, name="live-states", daemon=True)
        self._reader.start()
        self.link.create_subscription(FlightEvent, "/lander/events", self._on_event, reliable)
        self.link.create_subscription(ParameterEvent, "/parameter_events", self._on_parameter_event, reliable)
        self.link.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, reliable)

    # --- lifecycle ---------------------------------------------------------------------------

    def urls(self) -> tuple[str, str | None]:
        ws = f"ws://{self.host}:{self.port}"
        page = f"http://{self.host}:{self.page_port}/" if self.page_port is not None else None
        return ws, page

    def poll(self) -> None:
        """Called every ~0.1 s from the owner's thread: find the flight, flush a held-back state."""
        if not self.ready or not self.autopilot_read:
            names = self.link.node_names()
            if not self.ready and SIM_NODE in names:
                self._read_flight()
            if not self.autopilot_read and AUTOPILOT_NODE in names:
                self._read_autopilot()
        self._publish_status()

    def _read_flight(self) -> None:
        from lander_sim.look import Look
        from lander_sim.scenes import load_scene

        try:
            scene = load_scene(self.link.get_parameters(SIM_NODE, ["scene"])["scene"])
        except (NoFlight, TimeoutError, ValueError) as exc:
            self._status(f"flight found but not read yet: {exc}", error=False)
            return
        with self._lock:
            self._scene_wind_W = [float(v) for v in scene.wind_W]
            if self.wind_W is None:
                self.wind_W = self._scene_wind_W
        self.tracker = views.SceneTracker(Look.of(scene.vehicle), fixed_pivot=not scene.translation)
        self.ready = True

    def _read_autopilot(self) -> None:
        """The autopilot's parameters in force (later changes come as parameter events)."""
        try:
            self.params.update(self.link.get_parameters(AUTOPILOT_NODE, list(AUTOPILOT_PARAMETERS)))
        except (NoFlight, TimeoutError) as exc:
            self._status(f"autopilot parameters not read yet: {exc}", error=False)
            return
        self.autopilot_read = True
        self._publish_parameters()

    def close(self) -> None:
        self._stop.set()
        self._reader.join(timeout=2.0)
        self.server.stop()
        if self.page is not None:
            self.page.close()
        try:
            self._state_node.destroy_node()
        except Exception:  # noqa: BLE001 - the context may be gone already
            pass
        self.link.close()

    # --- flight -> clients --------------------------------------------------------------------

    def _take_state(self) -> bytes | None:
        """The latest state's CDR bytes if one arrived since the last take, else None."""
        sub = self._state_sub
        with sub.handle:  # rclpy's stub omits it: the take gives None when no message is waiting
            taken: tuple[Any, ...] | None = sub.handle.take_message(sub.msg_type, True)
        if taken is None:
            return None
        data: bytes = taken[0]
        return data

    def _read_states(self) -> None:
        """The reader thread: take the latest state every half publishing interval; publish it
        when at least ``1 / max_rate`` has passed since the last one sent."""
        period = self.min_interval / 2.0
        while not self._stop.wait(period):
            try:
                data = self._take_state()
            except Exception:  # noqa: BLE001 - the context is shutting down
                if self._stop.is_set() or not self.link.context.ok():
                    return
                raise
            with self._lock:
                if data is not None:
                    self.states_in += 1
                    self._latest, self._latest_published = data, False
                due = not self._latest_published and time.monotonic() - self._last_out >= self.min_interval
            if due:
                self._publish_latest()

    def _publish_latest(self) -> None:
        with self._pub_lock:
            self._publish_latest_locked()

    def _publish_latest_locked(self) -> None:
        from rclpy.serialization import deserialize_message

        with self._lock:
            data, self._latest_published = self._latest, True
            self._last_out = time.monotonic()
        if data is None:
            return
        msg = deserialize_message(data, self._LanderState)
        t_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if msg.sequence < self._last_seq and self.tracker is not None:
            self.tracker.reset()  # a new epoch (reset / scene load): new trail
            with self._lock:
                self.wind_W = self._scene_wind_W  # a reset restores the scene's mean wind
        self._last_seq = msg.sequence
        record = views.state_record(msg, self.params.get("demand_altitude"), str(self.params.get("controller") or ""),
                                    self.paused)
        record["controller_params"] = str(self.params.get("controller_params") or "")
        with self._lock:
            record["wind_W"] = self.wind_W
        here = None
        if self.tracker is not None:
            p, q = msg.position, msg.orientation
            here = self.tracker.add((p.x, p.y, p.z))
            record["position_S"], record["up_S"] = list(here), list(self.tracker.body_up((q.x, q.y, q.z, q.w)))
            record.update(views.view_fields(self.tracker, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), msg.throttles,
                                            bool(msg.parachute_deployed)))
        with self._lock:
            self.history.add(record)
        self.ch_state.log(record, log_time=t_ns)
        self.server.broadcast_time(t_ns)
        self.states_out += 1
        if self.tracker is None or here is None:
            return
        transforms, update = scene.messages(self.tracker, msg, here)
        self.ch_tf.log(transforms, log_time=t_ns)
        self.ch_scene.log(update, log_time=t_ns)

    def _on_event(self, msg: Any) -> None:
        from lander_interfaces.msg import FlightEvent

        st = msg.header.stamp
        name = views.event_name(msg.kind)
        self.ch_events.log({"t": stamp_to_seconds(st), "kind": name, "detail": msg.detail,
                            "values": [float(v) for v in msg.values]})
        if msg.kind == FlightEvent.INPUT_REJECTED:
            with self._lock:
                self.refused["node." + (msg.detail.split(":", 1)[0] or "input")] += 1
            self._status(f"refused by the flight: {msg.detail}", error=True)

    def _on_parameter_event(self, msg: Any) -> None:
        from lander_tools.live.params import python_value

        if msg.node != AUTOPILOT_NODE:
            return
        changed = False
        for p in list(msg.changed_parameters) + list(msg.new_parameters):
            if p.name in AUTOPILOT_PARAMETERS:
                self.params[p.name] = python_value(p.value)
                changed = True
        if changed:
            self._publish_parameters()

    def history_json(self) -> bytes:
        """The graph fields of this epoch's states from t = 0 (:class:`views.History`), as JSON."""
        with self._lock:
            records = list(self.history.records)
        return json.dumps(records).encode()

    def _on_diagnostics(self, msg: Any) -> None:
        report = sim_report(msg) or {}
        paused = report.get("paused")
        if paused is not None:
            self.paused = paused.lower() in ("true", "1", "yes")
        wind = views.parse_wind(report.get("mean_wind_W"))
        if wind is not None:
            with self._lock:
                self.wind_W = wind

    def _publish_parameters(self) -> None:
        self.server.publish_parameter_values(self.parameter_list())

    def parameter_list(self) -> list[Any]:
        from foxglove import Parameter, ParameterType

        out = []
        for name in AUTOPILOT_PARAMETERS:
            v = self.params.get(name)
            if v is None:
                continue
            if isinstance(v, float):
                out.append(Parameter(name, value=v, type=ParameterType.Float64))
            else:
                out.append(Parameter(name, value=v))
        return out

    def _status(self, text: str, error: bool) -> None:
        from foxglove import StatusLevel

        self.server.publish_status(text, StatusLevel.Error if error else StatusLevel.Info)

    def _publish_status(self) -> None:
        with self._lock:
            status = {"ready": self.ready, "autopilot": self.autopilot_read, "states_in": self.states_in, "states_out": self.states_out,
                      "forwarded": self.forwarded, "refused": dict(self.refused),
                      "refused_total": sum(self.refused.values()), "paused": self.paused}
        self.ch_status.log(status)

    # --- clients -> flight --------------------------------------------------------------------

    def refuse(self, kind: str, text: str) -> None:
        with self._lock:
            self.refused[kind] += 1
        self._status(f"refused: {text}", error=True)

    def client_message(self, topic: str, data: bytes) -> None:
        try:
            kind, value = parse_client_message(topic, data)
        except ClientInputError as exc:
            self.refuse(f"client.{topic.rsplit('/', 1)[-1] or 'topic'}", str(exc))
            return
        try:
            if kind == "demand":
                self.link.publish_demand_altitude(value, wait=False)
            elif kind == "wind":
                self.link.publish_wind(value, wait=False)
            else:
                self.link.publish_throttles(value, wait=False)
        except NoFlight as exc:
            self.refuse("no_flight", str(exc))
            return
        with self._lock:
            self.forwarded += 1

    def set_parameters(self, changes: dict[str, Any]) -> list[Any]:
        """Forward a client's parameter set to the autopilot; the result is the values in force."""
        unknown = [k for k in changes if k not in AUTOPILOT_PARAMETERS]
        if unknown:
            self.refuse("parameter.unknown", f"parameter(s) {', '.join(unknown)} not served "
                                             f"(served: {', '.join(AUTOPILOT_PARAMETERS)})")
        wanted = {k: v for k, v in changes.items() if k in AUTOPILOT_PARAMETERS}
        if "demand_altitude" in wanted and isinstance(wanted["demand_altitude"], int) \
                and not isinstance(wanted["demand_altitude"], bool):
            wanted["demand_altitude"] = float(wanted["demand_altitude"])  # JSON 520 means 520.0 m
        if wanted:
            try:
                result = self.link.set_parameters(AUTOPILOT_NODE, wanted, atomically=len(wanted) > 1)
            except (NoFlight, TimeoutError) as exc:
                result = Outcome(False, str(exc))
            if result.ok:
                self.params.update(wanted)
                with self._lock:
                    self.forwarded += 1
            else:  # the autopilot counted it (and announced it: INPUT_REJECTED, counted in _on_event)
                self._status(f"refused: {', '.join(wanted)}: {result.message}", error=True)
        return self.parameter_list()

    def call_service(self, name: str, payload: bytes) -> bytes:
        """A client's service call: forwarded as is; the ROS response's fields as JSON."""
        try:
            fields = parse_service_request(name, payload)
        except ClientInputError as exc:
            self.refuse("service." + name.rsplit("/", 1)[-1], str(exc))
            raise
        short = name.rsplit("/", 1)[-1]
        # One call at a time: foxglove runs handlers concurrently, ROS gives no order between
        # services either; a client that needs an order awaits each answer (the page does).
        with self._call_lock:
            if name == "/autopilot/switch_controller":
                out = self.link.switch_controller(fields.get("controller", ""), fields.get("parameters_yaml", ""))
            else:
                out = self.link.sim_service(short, **fields)
                if out.ok and short in ("pause", "resume"):
                    self.paused = short == "pause"
        with self._lock:
            self.forwarded += 1
        if not out.ok:  # the node counted and announced it (INPUT_REJECTED, counted in _on_event)
            self._status(f"refused: {name}: {out.message}", error=True)
        return json.dumps({"success": out.ok, "message": out.message, **(out.values or {})}).encode()

    def _services(self) -> list[Any]:
        from foxglove import MessageSchema, Schema, Service, ServiceSchema

        services = []
        for name, (ros_type, fields) in SERVICE_FIELDS.items():
            req = {"type": "object", "properties": {k: {"type": t} for k, t in fields.items()}}
            schema = ServiceSchema(ros_type, request=MessageSchema(
                encoding="json", schema=Schema(name=ros_type + "_Request", encoding="jsonschema",
                                               data=json.dumps(req).encode())))
            services.append(Service(name, schema=schema, handler=self._handler(name)))
        return services

    def _handler(self, name: str) -> Callable[[Any], bytes]:
        return lambda request: self.call_service(name, request.payload)


def _make_listener_base() -> type:
    from foxglove.websocket import ServerListener

    return ServerListener


class _Listener(_make_listener_base()):  # type: ignore[misc]  # base chosen at import: foxglove's, or object without it
    """foxglove's callbacks (server threads) -> the bridge."""

    def __init__(self, bridge: LiveBridge) -> None:
        self.bridge = bridge

    def on_client_advertise(self, client: Any, channel: Any) -> None:
        self.bridge._client_topics[(client.id, channel.id)] = channel.topic

    def on_client_unadvertise(self, client: Any, client_channel_id: int) -> None:
        self.bridge._client_topics.pop((client.id, client_channel_id), None)

    def on_message_data(self, client: Any, client_channel_id: int, data: bytes) -> None:
        topic = self.bridge._client_topics.get((client.id, client_channel_id), f"<channel {client_channel_id}>")
        self.bridge.client_message(topic, data)

    def on_get_parameters(self, client: Any, param_names: list[str], request_id: str | None = None) -> list[Any]:
        params = self.bridge.parameter_list()
        return [p for p in params if not param_names or p.name in param_names]

    def on_set_parameters(self, client: Any, parameters: list[Any], request_id: str | None = None) -> list[Any]:
        return self.bridge.set_parameters({p.name: p.get_value() for p in parameters})


def build_parser(parser: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    p = parser or argparse.ArgumentParser(prog="lander live", description=__doc__.split("\n\n")[0])
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"Foxglove WebSocket port (default {DEFAULT_PORT}; 0: a free one)")
    p.add_argument("--page-port", type=int, default=None,
                   help="student page HTTP port (default: --port + 1, or a free one with --port 0)")
    p.add_argument("--no-page", action="store_true", help="serve no student page")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--max-rate", type=float, default=DEFAULT_MAX_RATE, metavar="HZ",
                   help=f"most states per wall second sent to clients (default {DEFAULT_MAX_RATE:g})")
    p.add_argument("--stop-when-gone", metavar="NODE",
                   help="exit when this node (e.g. /lander_sim) leaves the graph after having been seen")
    return p


def serve(args: argparse.Namespace) -> int:
    """Run the bridge until Ctrl-C / SIGTERM (or the watched node is gone). 0, or 2 if a port is taken."""
    page_port = None if args.no_page else (args.page_port if args.page_port is not None
                                           else (0 if args.port == 0 else args.port + 1))
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        bridge = LiveBridge(args.port, page_port, args.host, args.max_rate)
    except (OSError, RuntimeError) as exc:  # a port in use comes back as RuntimeError from foxglove
        print(f"lander live: cannot serve on {args.host}:{args.port}/{page_port}: {exc}", file=sys.stderr)
        return 2
    ws, page = bridge.urls()
    print(f"live: Foxglove server {ws}" + (f"  student page {page}" if page else ""), flush=True)
    seen = False
    try:
        while not stop.wait(0.05):
            bridge.poll()
            if args.stop_when_gone:
                alive = args.stop_when_gone in bridge.link.node_names()
                seen = seen or alive
                if seen and not alive:
                    break
    finally:
        bridge.close()
        with bridge._lock:
            print(f"live: {bridge.states_in} states in, {bridge.states_out} sent, {bridge.forwarded} client "
                  f"actions forwarded, {sum(bridge.refused.values())} refused", flush=True)
    return 0


def command(port: int, page_port: int | None = None, extra: list[str] | None = None) -> list[str]:
    """The argv that starts a bridge as a child of this process (for the launcher), stopping
    itself when the simulator leaves the graph."""
    from lander_tools.child import command as child_command

    args = ["--port", str(port), "--stop-when-gone", SIM_NODE]
    if page_port is not None:
        args += ["--page-port", str(page_port)]
    return child_command("lander_tools.live.bridge", args + list(extra or []))


def main(argv: list[str] | None = None) -> int:
    return serve(build_parser().parse_args(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    sys.exit(main())

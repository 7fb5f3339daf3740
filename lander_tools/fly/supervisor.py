"""The launcher's own node in this process (``/lander_fly``): it watches the flight (states, events,
the sim's FLIGHT_ENDED), answers the sim when the flight has no autopilot, carries out timeline
actions, holds the recorder and counts what it received and sent for the bag check."""
from __future__ import annotations

import math
import time
from typing import Any, TextIO

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

from lander_interfaces.msg import AutopilotStatus, FlightEvent, LanderState, ThrottleCommand
from lander_interfaces.srv import Reset, SwitchController
from lander_ros.flight_span import SENSOR_KEYS, SENSOR_TOPICS, FlightEnd, sim_paused
from lander_ros.stamps import stamp_to_seconds
from lander_ros.strangers import STRANGER_KIND
from lander_sim.scenes import load_scene
from lander_tools.fly.plan import AUTOPILOT_NODE, ESTIMATE_TOPICS, SIM_NODE, Action, FlightPlan, LaunchError, pilot_mode
from lander_tools.recorder import DEFAULT_TOPICS, Recorder, RecorderConfig

#: Wall seconds allowed for discovery, service answers and the first state.
STARTUP_TIMEOUT = 30.0
#: MODE_CHANGED events printed by ``lander fly`` (the rest are counted in one line at the end).
MODE_LINES = 20
#: Events printed as they happen (``[fly] event at t = ...``).
PRINTED_EVENTS = (FlightEvent.LANDED, FlightEvent.HARD_LANDING, FlightEvent.CRASHED, FlightEvent.GIMBAL_LOCK,
                  FlightEvent.CONTROLLER_SWITCHED, FlightEvent.FUEL_OUT, FlightEvent.LANDING_UNREACHABLE,
                  FlightEvent.MODE_CHANGED)
TOUCHDOWNS = {FlightEvent.LANDED: "safe", FlightEvent.HARD_LANDING: "hard", FlightEvent.CRASHED: "crash"}

RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
#: Latched: an autopilot (re)started mid-flight still gets the demand in force.
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def event_values(msg: Any) -> dict[str, float]:
    """A FlightEvent's ``values`` by name: the core's events end their detail with
    ``[values: a, b, ...]`` (lander_sim.ros.convert.event_fields); empty when it does not."""
    detail = str(msg.detail)
    _, sep, names = detail.rpartition("[values: ")
    if not sep or not names.endswith("]"):
        return {}
    keys = [k.strip() for k in names[:-1].split(",")]
    return dict(zip(keys, (float(v) for v in msg.values))) if len(keys) == len(msg.values) else {}


def event_text(detail: str) -> str:
    """A FlightEvent's detail as a user reads it: without the ``[values: ...]`` key of its numbers
    (the sentence gives them with their units)."""
    text, sep, names = detail.rpartition(" [values: ")
    return text if sep and names.endswith("]") else detail


def stall_reason(now: float, last_state_wall: float, paused: bool, last_word_wall: float, t: float,
                 limit: float) -> str | None:
    """Why a flight counts as stalled at wall time ``now`` [s], else None: no state for ``limit`` s
    while the simulator runs, or, while it says it is paused (its ``/diagnostics``), no word from
    it at all for ``limit`` s. A paused flight stays paused as long as the user wants."""
    if now - last_state_wall <= limit or (paused and now - last_word_wall <= limit):
        return None
    if paused:
        return f"no word from the simulator for {limit} s (paused at t = {t:.3f} s)"
    return f"no state from the simulator for {limit} s at t = {t:.3f} s"


class Supervisor:
    """The launcher's own node: watches the flight, applies the timeline, records, counts.

    Built in four parts: what it sends (:meth:`_create_outputs`: inputs to the sim and the
    service clients), what it watches (:meth:`_create_watch`), the flight's state as watched
    (attributes set in ``__init__``), and the recorder (:meth:`_create_recorder`)."""

    def __init__(self, plan: FlightPlan, controller: str | None, out: TextIO, progress: Any) -> None:
        self.plan, self.controller, self.out, self.progress = plan, controller, out, progress
        self.node = rclpy.create_node("lander_fly")
        #: Sim-time driven timeline (pauses at each action instant): every flight with an autopilot.
        self.timed = controller is not None
        #: The sim waits for the autopilot's answer to every state.
        self.lockstep = controller is not None and plan.lockstep is not False
        #: This node answers every state (lockstep) when the flight has no autopilot.
        self.pilot = pilot_mode(plan, controller)
        #: Messages this node received per topic since the flight's reset (the reference for the
        #: bag's counts of the topics the sim does not count), and those it published itself.
        self.received: dict[str, int] = {}
        self.sent: dict[str, int] = {}
        self._create_outputs()
        self.subs = self._create_watch()
        self.answered_first = False  #: the autopilot answered state 1 (the reset's) since the last reset
        self.last_answer = 0  #: highest state sequence answered on /lander/throttle since the reset
        #: Latest stamp [s] of an /autopilot/status (the autopilot stamps it with the state it answers).
        self.last_status_t = -math.inf
        self.clock_t = 0.0  #: latest /clock [s]: where a paused sim stands before its state is out
        self.state: Any = None  #: the latest LanderState
        self.states = 0
        self.t = 0.0
        self.last_state_wall = time.monotonic()
        #: What the sim's latest /diagnostics said (paused or not) and when it came (wall clock)
        self.sim_paused = False
        self.sim_word_wall = time.monotonic()
        #: The autopilot's latest control report: its controller and the gains in force ("" none).
        self.autopilot_gains: tuple[str, str] = ("", "")
        #: The sim's FLIGHT_ENDED, decoded: the flight is over.
        self.flight_end: FlightEnd | None = None
        #: Named values of the LANDED / CRASHED event (t_impact [s], descent_rate [m/s], ...).
        self.touchdown: dict[str, float] = {}
        self.touchdown_class = ""  #: safe / hard / crash, from the event's kind
        self.gimbal_locks: list[float] = []  #: sim times [s] of GIMBAL_LOCK events (printed once, counted)
        self.mode_changes: list[float] = []  #: sim times [s] of MODE_CHANGED events (the first MODE_LINES printed)
        self.strangers: list[str] = []  #: the sim's refusals of strangers' throttles (one event per stranger)
        self.pending = sorted(plan.timeline, key=lambda a: a.t)
        self.held_throttle: Action | None = None
        self.futures: list[tuple[str, Any]] = []  #: service calls started by apply(), by name
        self.recorder = self._create_recorder()

    def _create_outputs(self) -> None:
        """The sim's inputs this node publishes and the services it calls (the autopilot's and the
        sim's parameters only when the flight has an autopilot)."""
        n = self.node
        self.pub_demand = n.create_publisher(Float64, "/lander/demand_altitude", LATCHED)
        self.pub_wind = n.create_publisher(Vector3Stamped, "/lander/wind", RELIABLE)
        self.pub_throttle = n.create_publisher(ThrottleCommand, "/lander/throttle", RELIABLE)
        self.cli_reset: Any = n.create_client(Reset, "/lander/reset")
        self.cli_resume: Any = n.create_client(Trigger, "/lander/resume")
        self.cli_subscribers: Any = n.create_client(Trigger, "/lander/subscribers")
        self.cli_autopilot_matched: Any = n.create_client(Trigger, "/autopilot/matched")
        self.cli_estimator_matched: Any = n.create_client(Trigger, "/lander_estimator/matched")
        self.cli_stab: Any = n.create_client(SetBool, "/lander/set_stabiliser")
        self.cli_chute: Any = n.create_client(Trigger, "/lander/deploy_parachute")
        #: the sim's parameters: its flight_id says whether it is this flight's (wait_until_matched)
        self.cli_sim_get: Any = n.create_client(GetParameters, f"/{SIM_NODE}/get_parameters")
        self.cli_switch: Any = None
        if self.controller is not None:
            self.cli_switch = n.create_client(SwitchController, "/autopilot/switch_controller")
            self.cli_ap_get: Any = n.create_client(GetParameters, "/autopilot/get_parameters")
            self.cli_sim_set: Any = n.create_client(SetParameters, f"/{SIM_NODE}/set_parameters")
            n.create_subscription(Clock, "/clock", self._on_clock, RELIABLE)

    def _create_watch(self) -> dict[str, Any]:
        """The subscriptions that watch the flight, by topic (the matching phase counts their publishers)."""
        n = self.node
        subs: dict[str, Any] = {
            "/lander/state": n.create_subscription(LanderState, "/lander/state", self._on_state, RELIABLE),
            "/lander/events": n.create_subscription(FlightEvent, "/lander/events", self._on_event, QoSProfile(depth=1000)),
            "/lander/throttle": n.create_subscription(ThrottleCommand, "/lander/throttle", self._on_throttle, RELIABLE),
        }
        if self.controller is not None:
            subs["/autopilot/status"] = n.create_subscription(
                AutopilotStatus, "/autopilot/status", self._on_status, RELIABLE)
        # The autopilot's reports (the bag check's reference; the sim counts its own) and the sim's
        # (paused or running: the stall watch, stall_reason).
        subs["/diagnostics"] = n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, RELIABLE)
        return subs

    def _create_recorder(self) -> Recorder | None:
        """The flight's recorder (``--record``), in this node, its bag's metadata naming the flight."""
        plan = self.plan
        if plan.record is None:
            return None
        meta = {"scene": plan.scene, "controller": self.controller or "none", "speed": str(plan.speed)}
        meta.update({k: str(v) for k, v in plan.sim_params.items()})
        meta.update(plan.meta)
        # the sensors' topics only when the scene has sensors: the recorder waits for nothing else
        topics = plan.topics or tuple(t for t in DEFAULT_TOPICS if t not in SENSOR_TOPICS or sensor_topics(plan.scene))
        if plan.estimate and plan.topics is None:  # the estimator's outputs beside the truth
            topics += ESTIMATE_TOPICS
        return Recorder(self.node, RecorderConfig(plan.record, plan.storage, topics, meta=meta))

    @property
    def end(self) -> str | None:
        """How the flight ended (time-limit, landed, crashed), once the sim announced it."""
        return None if self.flight_end is None else self.flight_end.reason

    # callbacks ------------------------------------------------------------------------------
    def _count(self, topic: str) -> None:
        self.received[topic] = self.received.get(topic, 0) + 1

    def _on_diagnostics(self, msg: Any) -> None:
        if any(st.name.startswith(f"{AUTOPILOT_NODE}:") for st in msg.status):
            self._count("/diagnostics")  # the autopilot's only: the sim's come from FLIGHT_ENDED
        for st in msg.status:
            if st.name == f"{AUTOPILOT_NODE}: control":  # lander_autopilot's control-loop report
                values = {kv.key: kv.value for kv in st.values}
                self.autopilot_gains = (values.get("controller", ""), values.get("gains", ""))
        paused = sim_paused(msg)
        if paused is not None:
            self.sim_word_wall, self.sim_paused = time.monotonic(), paused

    def _on_throttle(self, msg: Any) -> None:
        self._count("/lander/throttle")
        if msg.state_sequence == 1:
            self.answered_first = True
        self.last_answer = max(self.last_answer, int(msg.state_sequence))

    def _on_status(self, msg: Any) -> None:
        self._count("/autopilot/status")
        self.last_status_t = max(self.last_status_t, stamp_to_seconds(msg.header.stamp))

    def _on_clock(self, msg: Any) -> None:
        self.clock_t = stamp_to_seconds(msg.clock)

    def _on_state(self, msg: Any) -> None:
        self._count("/lander/state")
        self.state = msg
        self.states += 1
        self.t = stamp_to_seconds(msg.header.stamp)
        self.last_state_wall = time.monotonic()
        self.progress.update(self.t, msg.altitude)
        # Nothing is applied at the end instant (the first at or after the duration) or later; the
        # pilot still answers the end state, as an autopilot does, so the bag is the same every time.
        at_end = self.flight_end is not None or (self.plan.duration is not None and self.t >= self.plan.duration - 1e-9)
        if not at_end:
            self.apply_due()  # timed flights: only throttle overrides are left in `pending` (reset_flight)
        held = self.held_throttle
        if held is not None and held.until is not None and self.t >= held.until - 1e-9:
            self.held_throttle = held = None
            if not self.pilot:
                self._send_throttle([0.0] * len(msg.throttles), 0)
        if self.pilot:
            # Lockstep pilot of a flight without autopilot: answer every state, so overrides
            # start and stop exactly at the state they are due.
            self._send_throttle(held.value if held is not None else [0.0] * len(msg.throttles), msg.sequence)
        elif held is not None:
            self._send_throttle(held.value, 0)

    def _on_event(self, msg: Any) -> None:
        self._count("/lander/events")
        t = stamp_to_seconds(msg.header.stamp)
        E = FlightEvent
        if msg.kind == E.FLIGHT_ENDED:
            try:
                self.flight_end = FlightEnd.from_values(list(msg.values))
            except ValueError as exc:
                self.out.write(f"[fly] ignored a malformed FLIGHT_ENDED: {exc}\n")
            return
        if msg.kind in TOUCHDOWNS:
            self.touchdown = event_values(msg)  # touchdown figures: the event's own named values
            self.touchdown_class = TOUCHDOWNS[msg.kind]
        if msg.kind == E.GIMBAL_LOCK:
            # The angles can flap in and out of the near-lock region: report the first, count the rest.
            self.gimbal_locks.append(t)
            if len(self.gimbal_locks) > 1:
                return
        if msg.kind == E.MODE_CHANGED:
            # A law's phases (e.g. deorbit's eight) as they happen; a law that flapped would flood.
            self.mode_changes.append(t)
            if len(self.mode_changes) > MODE_LINES:
                return
        if msg.kind == E.INPUT_REJECTED and str(msg.detail).startswith(STRANGER_KIND + ":"):
            self.strangers.append(str(msg.detail))  # announced once per stranger (the sim's own log line)
        if msg.kind in PRINTED_EVENTS:
            self.out.write(f"[fly] event at t = {t:.2f} s: {event_text(str(msg.detail))}\n")

    # actions --------------------------------------------------------------------------------
    def _publish(self, pub: Any, msg: Any) -> None:
        pub.publish(msg)
        self.sent[pub.topic_name] = self.sent.get(pub.topic_name, 0) + 1

    def _send_throttle(self, values: list[float], seq: int) -> None:
        m = ThrottleCommand()
        m.header.stamp = self.state.header.stamp
        m.state_sequence = int(seq)  # 0: an override that answers no particular state
        m.throttles = [float(v) for v in values]
        self._publish(self.pub_throttle, m)

    def apply_due(self) -> None:
        """Carry out the pending actions due at the latest state's time."""
        while self.pending and self.pending[0].t <= self.t + 1e-9:
            self.apply(self.pending.pop(0), self.t)

    def apply(self, a: Action, at: float) -> None:
        """Carry out one timeline action now; ``at`` [s] is the sim instant it applies at (logged)."""
        self.out.write(f"[fly] t = {at:.2f} s: {a.kind} {a.value if a.value is not None else ''}\n")
        if a.kind == "demand_altitude":
            m = Float64()
            m.data = float(a.value)
            self._publish(self.pub_demand, m)
        elif a.kind == "wind":
            w = Vector3Stamped()
            w.header.stamp.sec, w.header.stamp.nanosec = divmod(round(at * 1e9), 1_000_000_000)
            w.header.frame_id = "mars"
            w.vector.x, w.vector.y, w.vector.z = (float(v) for v in a.value)
            self._publish(self.pub_wind, w)
        elif a.kind == "throttle":
            self.held_throttle = a  # sent with the answer to the current state (see _on_state)
        elif a.kind == "controller":
            if self.cli_switch is None:
                raise LaunchError(f"timeline: controller swap at t = {a.t} needs an autopilot, but this flight has none")
            req = SwitchController.Request()
            req.controller = str(a.value)
            req.parameters_yaml = yaml.safe_dump(a.params) if a.params else ""
            self.futures.append(("switch_controller", self.cli_switch.call_async(req)))
        elif a.kind == "stabiliser":
            stab = SetBool.Request()
            stab.data = bool(a.value)
            self.futures.append(("set_stabiliser", self.cli_stab.call_async(stab)))
        elif a.kind == "parachute":
            self.futures.append(("deploy_parachute", self.cli_chute.call_async(Trigger.Request())))

    def check_futures(self) -> None:
        """Print the answers to the service calls of :meth:`apply` that have come."""
        for name, fut in list(self.futures):
            if fut.done():
                self.futures.remove((name, fut))
                res = fut.result()
                ok = getattr(res, "success", True)
                self.out.write(f"[fly] {name}: {'ok' if ok else 'FAILED'}: {getattr(res, 'message', '')}\n")


def call(executor: Any, client: Any, request: Any, timeout: float, what: str) -> Any:
    """Call a service through ``executor`` and return its answer; LaunchError naming ``what`` when
    the service is not there or does not answer within ``timeout`` wall seconds."""
    deadline = time.monotonic() + timeout
    while not client.service_is_ready():
        if time.monotonic() > deadline:
            raise LaunchError(f"{what}: service {client.srv_name} not available within {timeout} s")
        executor.spin_once(timeout_sec=0.05)
    fut = client.call_async(request)
    while not fut.done():
        if time.monotonic() > deadline:
            raise LaunchError(f"{what}: no answer from {client.srv_name} within {timeout} s")
        executor.spin_once(timeout_sec=0.05)
    return fut.result()


def sensor_topics(scene: str) -> tuple[str, ...]:
    """The sensor topics the simulator of ``scene`` (a name or a YAML path) publishes: one per
    sensor the scene switches on (lander_ros.flight_span.SENSOR_TOPICS), none for a scene without."""
    sensors = load_scene(scene).sensors
    on = () if sensors is None else tuple(sensors.sections)
    return tuple(t for k, t in zip(SENSOR_KEYS, SENSOR_TOPICS) if k in on)

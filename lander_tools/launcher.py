"""``lander fly``: start the simulator and the autopilot, fly, record, stop cleanly.

The launcher for machines without ``ros2 launch`` (ROS 2 from PyPI); on a full
install ``ros2 launch mars_lander fly.launch.py`` starts the same two nodes
(``launch/fly.launch.py``). Run (project venv)::

    ./dev fly hover --duration 60 --speed 0 --record out/hover
    ./dev fly free-spin                      # no autopilot in the scene: the sim alone
    ./dev fly 7 --controller altitude-p --params my.yaml --compose

What it does:

1. writes one ROS parameters file per node (``lander_sim``, ``autopilot``)
   from the flight's settings, after the user's ``--params`` file;
2. starts the sim node (paused) and, when the scene or ``--controller`` names a
   controller, the autopilot node, as separate processes (or both in one
   process with ``--compose``), forwarding their output line by line with a
   ``[sim]`` / ``[autopilot]`` prefix;
3. records (``--record``) from inside this process with :class:`~lander_tools.recorder.Recorder`,
   waits until the nodes and the recorder have discovered each other, resets the
   sim (so state 1 at t = 0 reaches everyone) and resumes it;
4. applies the flight's timeline (demand-altitude steps, wind gusts, controller
   swaps, throttle overrides) at the first control instant at or after each time,
   exactly in sim time at any speed: with an autopilot the sim pauses at each such
   instant (its ``pause_at`` parameter: /clock shows the instant, its state is held
   back) while the launcher acts and waits until the action is in force, then
   resumes (:func:`plan_stops`); the flight's end is such a stop too;
5. ends on landing or crash, at the time limit (sim time), on Ctrl-C/SIGTERM or
   when a node dies; stops the nodes, autopilot first (SIGINT, then SIGTERM,
   then SIGKILL after a grace period), closes the bag (noting the end time and
   outcome in its metadata) and prints a summary.

Exit status (documented in docs/flying.md):

====  ===========================================================
0     landed, or the time limit was reached while flying
1     crashed
2     error: a node failed to start or died, bad configuration,
      no state from the simulator
130   interrupted by Ctrl-C / SIGTERM (the bag is still closed validly)
====  ===========================================================
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import yaml

from lander_tools import child

EXIT_OK = 0
EXIT_CRASHED = 1
EXIT_ERROR = 2
EXIT_INTERRUPTED = 130

SIM_NODE = "lander_sim"
AUTOPILOT_NODE = "autopilot"
#: Wall seconds allowed for discovery, service answers and the first state.
STARTUP_TIMEOUT = 30.0
#: Wall seconds without a new state (while not paused) after which the flight is an error.
STALL_TIMEOUT = 30.0
#: Wall seconds a node gets to stop after SIGINT, then again after SIGTERM.
STOP_GRACE = 5.0

ACTION_KINDS = ("demand_altitude", "wind", "controller", "throttle", "stabiliser", "parachute")
#: Wall seconds to wait for the autopilot to report a new demand in force.
CONFIRM_TIMEOUT = 10.0


class LaunchError(ValueError):
    """A flight that cannot be launched as configured; the message names the setting."""


@dataclass(frozen=True)
class Action:
    """One timeline entry, applied at the first state with sim time >= ``t`` [s].

    ``kind`` / ``value``:

    * ``demand_altitude``: float, metres above the surface -> ``/lander/demand_altitude``
    * ``wind``: 3 floats, world frame m/s -> ``/lander/wind`` (frame ``mars``)
    * ``controller``: controller name (``value``) and ``params`` (mapping) ->
      ``/autopilot/switch_controller``
    * ``throttle``: list of throttles in [0, 1], held (re-sent with every state, so the sim's
      staleness limit never zeroes it) until ``until`` [s]; then zeros are sent once
    * ``stabiliser``: bool -> ``/lander/set_stabiliser``
    * ``parachute``: ignored value -> ``/lander/deploy_parachute``
    """

    t: float
    kind: str
    value: Any = None
    until: float | None = None
    params: dict[str, Any] = field(default_factory=dict)


@dataclass
class FlightPlan:
    """Everything a flight needs. ``controller``: ``None`` = the scene's autopilot, ``"none"`` = no autopilot."""

    scene: str
    controller: str | None = None
    controller_params: dict[str, Any] = field(default_factory=dict)
    duration: float | None = None
    speed: float = 1.0
    lockstep: bool | None = None
    params_file: Path | None = None
    sim_params: dict[str, Any] = field(default_factory=dict)
    autopilot_params: dict[str, Any] = field(default_factory=dict)
    record: Path | None = None
    storage: str = "mcap"
    topics: tuple[str, ...] | None = None
    compose: bool = False
    timeline: list[Action] = field(default_factory=list)
    end_on: tuple[str, ...] = ("landed", "crashed")
    meta: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise LaunchError(f"duration = {self.duration!r}: must be a finite number of seconds > 0")
        if not (math.isfinite(self.speed) and self.speed >= 0):
            raise LaunchError(f"speed = {self.speed!r}: must be >= 0 (0 = as fast as possible)")
        for a in self.timeline:
            if a.kind not in ACTION_KINDS:
                raise LaunchError(f"timeline action {a.kind!r} is not known; choose one of {', '.join(ACTION_KINDS)}")
        bad = [e for e in self.end_on if e not in ("landed", "crashed")]
        if bad:
            raise LaunchError(f"end_on {bad}: allowed are landed, crashed")
        if self.params_file is not None and not Path(self.params_file).is_file():
            raise LaunchError(f"--params {self.params_file}: no such file")


@dataclass
class FlightResult:
    """How a flight ended."""

    outcome: str  #: landed | crashed | time-limit | interrupted | error
    exit_code: int
    sim_time: float
    states: int
    message: str = ""
    counts: dict[str, int] = field(default_factory=dict)
    bag: Path | None = None
    wall_time: float = 0.0
    #: The last state seen: altitude [m], climb rate [m/s], ground speed [m/s], fuel [kg], tilt [deg].
    final: dict[str, float] = field(default_factory=dict)


def resolve_controller(plan: FlightPlan) -> str | None:
    """The controller to fly, or ``None`` for the sim alone (scene without autopilot, or ``none``)."""
    if plan.controller is not None:
        return None if plan.controller.lower() == "none" else plan.controller
    try:
        from lander_sim.scenes import load_scene

        scene = load_scene(plan.scene)
    except ValueError as exc:
        raise LaunchError(str(exc)) from None
    ap = getattr(scene, "autopilot", None)
    if ap is None:
        return None
    return ap.get("controller") if hasattr(ap, "get") else getattr(ap, "controller", None)


def scene_end_time(name: str) -> float | None:
    """The scene's ``end.max_time`` [s] (None: the flight ends on landing, crash or Ctrl-C)."""
    from lander_sim.scenes import load_scene

    try:
        return load_scene(name).end_time
    except ValueError as exc:
        raise LaunchError(str(exc)) from None


# --- child processes --------------------------------------------------------------------------


class NodeProcess:
    """A node in its own process, with its output forwarded line by line under a prefix."""

    def __init__(self, name: str, argv: list[str], out: TextIO, env: dict[str, str] | None = None) -> None:
        self.name = name
        self.argv = argv
        # Own session: a terminal's Ctrl-C reaches only the launcher, which then stops the
        # nodes in order (nodes first, bag last) instead of all at once.
        self.proc = subprocess.Popen(
            argv,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=env,
            start_new_session=True,
            text=True,
            bufsize=1,
        )
        self.lines: list[str] = []  # last lines, for error messages
        self._thread = threading.Thread(target=self._forward, args=(out,), daemon=True)
        self._thread.start()

    def _forward(self, out: TextIO) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines = (self.lines + [line.rstrip()])[-20:]
            out.write(f"[{self.name}] {line}")
            out.flush()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, grace: float = STOP_GRACE, interrupted: bool = False) -> int | None:
        """SIGINT (the nodes' clean exit), then SIGTERM, then SIGKILL; returns the exit code.

        ``interrupted``: SIGINT was already sent; a second one would break the node's clean-up.
        """
        for sig in (None if interrupted else signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if self.proc.poll() is not None:
                break
            try:
                if sig is not None:
                    self.proc.send_signal(sig)
                self.proc.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                continue
            except ProcessLookupError:
                break
        self._thread.join(timeout=2.0)
        return self.proc.returncode


@dataclass
class Stop:
    """Where a sim-time driven flight pauses: control instant ``index`` (t = index * period)."""

    index: int
    t: float
    actions: list[Action] = field(default_factory=list)
    end: bool = False


def plan_stops(timeline: list[Action], period: float, duration: float | None) -> list[Stop]:
    """The pauses that make ``timeline`` exact on the control grid ``t_k = k * period``.

    An action due at ``t`` belongs to the first instant ``t_k >= t``. The sim pauses having
    reached ``t_k`` but before publishing its state (``pause_at``), so sim-side actions (wind,
    stabiliser, parachute) act from the step leaving ``t_k`` and autopilot-side ones (demand,
    controller) from its answer to state k. The end (first instant >= ``duration``) is the last
    stop. Throttle overrides (sent with the states) and actions at instant 0 (applied before the
    flight starts) are not listed.
    """
    by_index: dict[int, Stop] = {}

    def stop(k: int) -> Stop:
        return by_index.setdefault(k, Stop(k, k * period))

    for a in timeline:
        k = max(0, math.ceil(a.t / period - 1e-9))
        if a.kind == "throttle" or k == 0:
            continue
        stop(k).actions.append(a)
    if duration is not None:
        k_end = math.ceil(duration / period - 1e-9)
        for k in [k for k in by_index if k >= k_end]:
            del by_index[k]  # nothing happens after the end
        stop(k_end).end = True
    return [by_index[k] for k in sorted(by_index)]


def pilot_mode(plan: FlightPlan, controller: str | None) -> bool:
    """True when the launcher itself answers the sim in lockstep (no autopilot; throttle
    overrides in the timeline, or ``lockstep`` asked for): timeline actions then happen
    exactly at the state they are due and the flight stops exactly at its time limit."""
    if controller is not None:
        return False
    return plan.lockstep is True or (plan.lockstep is None and any(a.kind == "throttle" for a in plan.timeline))


def _params_yaml(node: str, params: dict[str, Any], folder: Path) -> Path:
    path = folder / f"{node}.params.yaml"
    path.write_text(yaml.safe_dump({node: {"ros__parameters": params}}, sort_keys=True))
    return path


def node_commands(plan: FlightPlan, controller: str | None, folder: Path) -> dict[str, list[str]]:
    """The command lines of the node processes (``sim``, ``autopilot`` or ``composed``)."""
    sim_params = {"scene": plan.scene, "speed": float(plan.speed), "start_paused": True}
    if controller is not None:
        sim_params["lockstep"] = plan.lockstep is not False
    else:
        sim_params["lockstep"] = pilot_mode(plan, controller)
        # The sim alone holds the last command (the user's or the timeline's) for good.
        sim_params["command_timeout"] = 0.0
    sim_params.update(plan.sim_params)
    files = []
    if plan.params_file is not None:
        files += ["--params-file", str(plan.params_file)]
    sim_file = _params_yaml(SIM_NODE, sim_params, folder)
    cmds = {}
    ap_args: list[str] = []
    if controller is not None:
        ap_params: dict[str, Any] = {"scene": plan.scene, "controller": controller, "use_sim_time": True}
        if plan.controller_params:
            ap_params["controller_params"] = yaml.safe_dump(
                dict(plan.controller_params), default_flow_style=True, sort_keys=True
            ).strip()
        ap_params.update(plan.autopilot_params)
        ap_args = ["--params-file", str(_params_yaml(AUTOPILOT_NODE, ap_params, folder))]
    if plan.compose and controller is not None:
        cmds["composed"] = child.command("lander_tools.launcher", ["--composed", "--ros-args", *files,
                                                                   "--params-file", str(sim_file), *ap_args])
    else:
        cmds["sim"] = child.command("lander_sim.node", ["--ros-args", *files, "--params-file", str(sim_file)])
        if controller is not None:
            cmds["autopilot"] = child.command("lander_autopilot.node", ["--ros-args", *files, *ap_args])
    return cmds


def composed_main(argv: list[str]) -> int:
    """Both nodes in one process and one executor (``--compose``): no inter-process hops.

    The sim node's own loop drives the executor, so the autopilot's callbacks run
    between the sim's ticks.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from lander_autopilot.node import AutopilotNode
    from lander_sim.node import SimNode

    rclpy.init(args=argv)
    nodes: list[Any] = []
    try:
        sim = SimNode()
        nodes.append(sim)
        ap = AutopilotNode()
        nodes.append(ap)
        executor = SingleThreadedExecutor()
        executor.add_node(sim)
        executor.add_node(ap)
        sim.run(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as exc:
        print(f"composed: {exc}", file=sys.stderr)
        return EXIT_ERROR
    finally:
        for n in nodes:
            n.destroy_node()
        rclpy.try_shutdown()
    return 0


# --- the supervisor ---------------------------------------------------------------------------


class _Supervisor:
    """The launcher's own node: watches the flight, applies the timeline, records."""

    def __init__(self, plan: FlightPlan, controller: str | None, out: TextIO, progress: Any) -> None:
        import rclpy
        from geometry_msgs.msg import Vector3Stamped
        from lander_interfaces.msg import FlightEvent, LanderState, ThrottleCommand
        from lander_interfaces.srv import Reset
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import Float64
        from std_srvs.srv import SetBool, Trigger

        from lander_tools.recorder import DEFAULT_TOPICS, Recorder, RecorderConfig

        self.plan, self.controller, self.out, self.progress = plan, controller, out, progress
        self.node = rclpy.create_node("lander_fly")
        n = self.node
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_demand = n.create_publisher(Float64, "/lander/demand_altitude", latched)
        self.pub_wind = n.create_publisher(Vector3Stamped, "/lander/wind", reliable)
        self.pub_throttle = n.create_publisher(ThrottleCommand, "/lander/throttle", reliable)
        self.cli_reset = n.create_client(Reset, "/lander/reset")
        self.cli_resume = n.create_client(Trigger, "/lander/resume")
        self.cli_stab = n.create_client(SetBool, "/lander/set_stabiliser")
        self.cli_chute = n.create_client(Trigger, "/lander/deploy_parachute")
        self.cli_switch = None
        #: Sim-time driven timeline (pauses at each action instant): every flight with an autopilot.
        self.timed = controller is not None
        if controller is not None:
            from lander_interfaces.srv import SwitchController
            from rcl_interfaces.srv import GetParameters, SetParameters

            self.cli_switch = n.create_client(SwitchController, "/autopilot/switch_controller")
            self.cli_ap_get = n.create_client(GetParameters, "/autopilot/get_parameters")
            self.cli_sim_set = n.create_client(SetParameters, f"/{SIM_NODE}/set_parameters")
            self.cli_sim_get = n.create_client(GetParameters, f"/{SIM_NODE}/get_parameters")
            from rosgraph_msgs.msg import Clock

            n.create_subscription(Clock, "/clock", self._on_clock, reliable)
            n.create_subscription(ThrottleCommand, "/lander/throttle", self._on_throttle, reliable)
        self.answered_first = False  #: the autopilot answered state 1 (the reset's) since the last reset
        self.clock_t = 0.0  #: latest /clock [s]: where a paused sim stands before its state is out
        self.types = {"Float64": Float64, "Vector3Stamped": Vector3Stamped, "ThrottleCommand": ThrottleCommand}
        self.LanderState, self.FlightEvent = LanderState, FlightEvent
        self.state: Any = None
        self.states = 0
        self.t = 0.0
        self.last_state_wall = time.monotonic()
        self.end: str | None = None
        self.end_t: float | None = None  #: sim time of the state that ended the flight
        self.touchdown: float | None = None
        self.pending = sorted(plan.timeline, key=lambda a: a.t)
        self.held_throttle: Action | None = None
        self.futures: list[Any] = []
        #: This node answers every state (lockstep) when the flight has no autopilot.
        self.pilot = pilot_mode(plan, controller)
        n.create_subscription(LanderState, "/lander/state", self._on_state, reliable)
        n.create_subscription(FlightEvent, "/lander/events", self._on_event, QoSProfile(depth=1000))
        self.recorder = None
        if plan.record is not None:
            meta = {"scene": plan.scene, "controller": controller or "none", "speed": str(plan.speed)}
            meta.update({k: str(v) for k, v in plan.sim_params.items()})
            meta.update(plan.meta)
            self.recorder = Recorder(n, RecorderConfig(plan.record, plan.storage, plan.topics or DEFAULT_TOPICS, meta=meta))

    # callbacks ------------------------------------------------------------------------------
    def _on_throttle(self, msg: Any) -> None:
        if msg.state_sequence == 1:
            self.answered_first = True

    def _on_clock(self, msg: Any) -> None:
        self.clock_t = msg.clock.sec + 1e-9 * msg.clock.nanosec

    def _on_state(self, msg: Any) -> None:
        self.state = msg
        self.states += 1
        self.t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self.last_state_wall = time.monotonic()
        self.progress.update(self.t, msg.altitude)
        if self.end is None:
            if msg.phase == self.LanderState.PHASE_LANDED and "landed" in self.plan.end_on:
                self.end = "landed"
            elif msg.phase == self.LanderState.PHASE_CRASHED and "crashed" in self.plan.end_on:
                self.end = "crashed"
            elif self.plan.duration is not None and self.t >= self.plan.duration - 1e-9:
                self.end = "time-limit"
        if self.end is not None:
            if self.end_t is None:
                self.end_t = self.t
            return  # no more actions or answers: in lockstep the sim now waits to be paused
        self._apply_due()  # timed flights: only throttle overrides are left in `pending` (fly())
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
        if msg.kind in (self.FlightEvent.LANDED, self.FlightEvent.CRASHED) and msg.values:
            self.touchdown = float(msg.values[0])
        if msg.kind in (self.FlightEvent.LANDED, self.FlightEvent.CRASHED, self.FlightEvent.GIMBAL_LOCK,
                        self.FlightEvent.CONTROLLER_SWITCHED, self.FlightEvent.FUEL_OUT):
            self.out.write(f"[fly] event at t = {msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec:.2f} s: {msg.detail}\n")

    def _send_throttle(self, values: list[float], seq: int) -> None:
        m = self.types["ThrottleCommand"]()
        m.header.stamp = self.state.header.stamp
        m.state_sequence = int(seq)  # 0: an override that answers no particular state
        m.throttles = [float(v) for v in values]
        self.pub_throttle.publish(m)

    def _apply_due(self) -> None:
        while self.pending and self.pending[0].t <= self.t + 1e-9:
            self.apply(self.pending.pop(0))

    def apply(self, a: Any) -> None:
        """Carry out one timeline action now."""
        from std_srvs.srv import SetBool, Trigger

        self.out.write(f"[fly] t = {self.t:.2f} s: {a.kind} {a.value if a.value is not None else ''}\n")
        if a.kind == "demand_altitude":
            m = self.types["Float64"]()
            m.data = float(a.value)
            self.pub_demand.publish(m)
        elif a.kind == "wind":
            m = self.types["Vector3Stamped"]()
            if self.timed:  # the sim stands at /clock's instant (its state is held back until resume)
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(round(self.clock_t * 1e9), 1_000_000_000)
            elif self.state is not None:
                m.header.stamp = self.state.header.stamp
            m.header.frame_id = "mars"
            m.vector.x, m.vector.y, m.vector.z = (float(v) for v in a.value)
            self.pub_wind.publish(m)
        elif a.kind == "throttle":
            self.held_throttle = a  # sent with the answer to the current state (see _on_state)
        elif a.kind == "controller":
            if self.cli_switch is None:
                raise LaunchError(f"timeline: controller swap at t = {a.t} needs an autopilot, but this flight has none")
            req = self.cli_switch.srv_type.Request()
            req.controller = str(a.value)
            req.parameters_yaml = yaml.safe_dump(a.params) if a.params else ""
            self.futures.append(("switch_controller", self.cli_switch.call_async(req)))
        elif a.kind == "stabiliser":
            req = SetBool.Request()
            req.data = bool(a.value)
            self.futures.append(("set_stabiliser", self.cli_stab.call_async(req)))
        elif a.kind == "parachute":
            self.futures.append(("deploy_parachute", self.cli_chute.call_async(Trigger.Request())))

    def check_futures(self) -> None:
        for name, fut in list(self.futures):
            if fut.done():
                self.futures.remove((name, fut))
                res = fut.result()
                ok = getattr(res, "success", True)
                self.out.write(f"[fly] {name}: {'ok' if ok else 'FAILED'}: {getattr(res, 'message', '')}\n")


def _control_period(executor: Any, sup: _Supervisor, plan: FlightPlan) -> float:
    """The sim's control period [s]: ``steps_per_tick(dt, publish_rate) * dt``, read from the running node."""
    from rcl_interfaces.srv import GetParameters

    from lander_sim.ros.pacing import steps_per_tick

    res = _call(executor, sup.cli_sim_get, GetParameters.Request(names=["dt", "publish_rate"]), STARTUP_TIMEOUT,
                "sim parameters")
    dt, rate = res.values[0].double_value, res.values[1].double_value
    if dt <= 0.0:
        from lander_sim.scenes import load_scene

        dt = load_scene(plan.scene).dt
    return steps_per_tick(dt, rate) * dt


def _arm(executor: Any, sup: _Supervisor, t: float) -> None:
    """Set the sim's ``pause_at`` to ``t`` [s] (< 0: none): it pauses on reaching that instant."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    req = SetParameters.Request(parameters=[Parameter("pause_at", value=float(t)).to_parameter_msg()])
    res = _call(executor, sup.cli_sim_set, req, STARTUP_TIMEOUT, "pause_at")
    if not res.results[0].successful:
        raise LaunchError(f"the sim refused pause_at = {t}: {res.results[0].reason}")


def _apply_now(executor: Any, sup: _Supervisor, a: Action) -> None:
    """Apply ``a`` while the sim is paused and wait until it is in force (demand, services)."""
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters

    sup.apply(a)
    if a.kind == "demand_altitude":
        # Topic to the autopilot; its parameter says when the new demand is in force.
        deadline = time.monotonic() + CONFIRM_TIMEOUT
        while True:
            res = _call(executor, sup.cli_ap_get, GetParameters.Request(names=["demand_altitude"]), CONFIRM_TIMEOUT,
                        "demand_altitude")
            v = res.values[0]
            if (v.double_value if v.type == ParameterType.PARAMETER_DOUBLE else float(v.integer_value)) == float(a.value):
                break
            if time.monotonic() > deadline:
                raise LaunchError(f"the autopilot did not take demand_altitude = {a.value} within {CONFIRM_TIMEOUT} s")
            executor.spin_once(timeout_sec=0.01)
    # Service calls (switch, stabiliser, parachute) were started by apply(): wait for their answers.
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while sup.futures:
        if time.monotonic() > deadline:
            raise LaunchError(f"no answer to {', '.join(n for n, _ in sup.futures)} within {STARTUP_TIMEOUT} s")
        executor.spin_once(timeout_sec=0.01)
        sup.check_futures()


def _call(executor: Any, client: Any, request: Any, timeout: float, what: str) -> Any:
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


def fly(plan: FlightPlan, out: TextIO | None = None, progress: Any = None, env: dict[str, str] | None = None) -> FlightResult:
    """Fly ``plan`` to its end and return how it ended (see the module docstring for the steps).

    Must run in the main thread (it installs SIGINT/SIGTERM handlers for the duration).
    """
    import rclpy
    from lander_interfaces.srv import Reset
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from std_srvs.srv import Trigger

    from lander_tools.progress import Progress

    out = out or sys.stdout
    if plan.duration is None:
        plan.duration = scene_end_time(plan.scene)  # the scene's own end.max_time, if it has one
    progress = progress or Progress(total=plan.duration)
    wall0 = time.monotonic()
    controller = resolve_controller(plan)
    stop_reason: list[str] = []

    def on_signal(signum: int, _frame: Any) -> None:
        stop_reason.append(signal.Signals(signum).name)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    tmp = tempfile.TemporaryDirectory(prefix="lander-fly-")
    procs: dict[str, NodeProcess] = {}
    executor: Any = None
    sup: _Supervisor | None = None
    result: FlightResult | None = None
    ctx_started = False
    try:
        cmds = node_commands(plan, controller, Path(tmp.name))
        rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
        ctx_started = True
        sup = _Supervisor(plan, controller, out, progress)
        executor = SingleThreadedExecutor()
        executor.add_node(sup.node)
        for name, argv in cmds.items():
            procs[name] = NodeProcess(name, argv, out, env)
        out.write(
            f"[fly] scene {plan.scene!r}, controller {controller or 'none (sim alone)'}, "
            f"speed {plan.speed or 'max'}, pids " + ", ".join(f"{k} {p.pid}" for k, p in procs.items()) + "\n"
        )

        def check_children() -> None:
            for name, p in procs.items():
                if not p.alive():
                    tail = "\n".join(p.lines[-5:])
                    raise _NodeDied(f"node process {name!r} exited with code {p.proc.returncode}" + (f":\n{tail}" if tail else ""))

        # Discovery: the nodes' endpoints and (if recording) the recorder's subscriptions.
        deadline = time.monotonic() + STARTUP_TIMEOUT
        need = ["/lander/state", "/clock"] + (["/lander/throttle", "/autopilot/status"] if controller else [])

        def ready() -> bool:
            n = sup.node
            sims = [x for x, _ in n.get_node_names_and_namespaces() if x == SIM_NODE]
            if len(sims) > 1:
                raise LaunchError(
                    f"{len(sims)} simulator nodes in ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}: "
                    "another flight is running there; set ROS_DOMAIN_ID (0-101) to keep flights apart"
                )
            if not sup.cli_reset.service_is_ready() or n.count_publishers("/lander/state") < 1:
                return False
            own_state_subs = 1 + int(sup.recorder is not None and "/lander/state" in sup.recorder.subscribed())
            if controller is not None and (
                n.count_subscribers("/lander/state") <= own_state_subs or n.count_publishers("/lander/throttle") < 2
            ):
                return False  # the autopilot listens to states and has its command publisher up
            if sup.recorder is not None:
                sup.recorder.discover()
                return all(t in sup.recorder.subscribed() for t in need if sup.recorder.wanted(t))
            return True

        while not ready():
            check_children()
            if stop_reason:
                raise _Interrupted()
            if time.monotonic() > deadline:
                raise LaunchError(f"nodes not ready within {STARTUP_TIMEOUT} s (waiting for {', '.join(need)} and /lander/reset)")
            executor.spin_once(timeout_sec=0.05)
        # Reset republishes state 1 at t = 0 now that everyone listens; retried if it was missed.
        # The sim publishes one state per instant (resume publishes nothing), so in lockstep the
        # autopilot must have answered state 1 before time runs: reset again if it missed it.
        def reset_seen(seen: int) -> bool:
            return sup.states > seen and (controller is None or sup.answered_first)

        for attempt in range(5):
            seen = sup.states
            sup.answered_first = False
            _call(executor, sup.cli_reset, Reset.Request(), STARTUP_TIMEOUT, "reset")
            t_wait = time.monotonic() + 1.0 + attempt
            while not reset_seen(seen) and time.monotonic() < t_wait:
                executor.spin_once(timeout_sec=0.02)
            if reset_seen(seen):
                break
        else:
            raise LaunchError("no state from the simulator (or no answer from the autopilot) after reset")
        sup._apply_due()  # actions at t = 0 (e.g. the first demand) before the first step
        stops: list[Stop] = []
        if sup.timed:
            period = _control_period(executor, sup, plan)
            stops = plan_stops([a for a in sup.pending if a.kind != "throttle"], period, plan.duration)
            sup.pending = [a for a in sup.pending if a.kind == "throttle"]
            _arm(executor, sup, stops[0].t if stops else -1.0)
        _call(executor, sup.cli_resume, Trigger.Request(), STARTUP_TIMEOUT, "resume")
        sup.last_state_wall = time.monotonic()
        while sup.end is None:
            if stop_reason:
                raise _Interrupted()
            check_children()
            if time.monotonic() - sup.last_state_wall > STALL_TIMEOUT:
                raise LaunchError(f"no state from the simulator for {STALL_TIMEOUT} s at t = {sup.t:.3f} s")
            executor.spin_once(timeout_sec=0.05)
            sup.check_futures()
            if stops and sup.end is None and sup.clock_t >= stops[0].t - 1e-6:
                stop = stops.pop(0)  # the sim stands at stop.t, its state not yet out
                for a in stop.actions:
                    _apply_now(executor, sup, a)
                # At the end: pause_at = now, so resume publishes the end state and pauses again.
                _arm(executor, sup, stop.t if stop.end else stops[0].t if stops else -1.0)
                _call(executor, sup.cli_resume, Trigger.Request(), STARTUP_TIMEOUT, "resume")
        # Stop at once, autopilot first: in lockstep the sim then waits for an answer that never
        # comes, so it cannot run on (a pause request can wait behind a busy lockstep loop).
        _stop_all(procs)
        code = EXIT_CRASHED if sup.end == "crashed" else EXIT_OK
        result = FlightResult(sup.end, code, sup.end_t if sup.end_t is not None else sup.t, sup.states)
        if sup.state is not None:
            result.final = final_state(sup.state)
    except _Interrupted:
        result = FlightResult("interrupted", EXIT_INTERRUPTED, sup.t if sup else 0.0, sup.states if sup else 0,
                              f"stopped by {stop_reason[0] if stop_reason else 'signal'}")
    except _NodeDied as exc:
        result = FlightResult("error", EXIT_ERROR, sup.t if sup else 0.0, sup.states if sup else 0, str(exc))
    except (LaunchError, ValueError, OSError) as exc:
        result = FlightResult("error", EXIT_ERROR, sup.t if sup else 0.0, sup.states if sup else 0, str(exc))
    finally:
        progress.finish()
        _stop_all(procs)
        if sup is not None and sup.recorder is not None and result is not None and executor is not None:
            _drain(sup, executor)  # what the nodes sent before they stopped is still queued here
        if sup is not None and sup.recorder is not None:
            if result is not None:
                # The flight's end, so analysis can ignore states the sim produced while stopping.
                sup.recorder.writer.set_custom_data("end_time", repr(sup.end_t if sup.end_t is not None else sup.t))
                sup.recorder.writer.set_custom_data("outcome", result.outcome)
            counts = sup.recorder.close()
            if result is not None:
                result.counts, result.bag = counts, plan.record
            out.write(sup.recorder.summary() + "\n")
        if sup is not None:
            sup.node.destroy_node()
        if ctx_started:
            rclpy.try_shutdown()
        tmp.cleanup()
        for s, h in old.items():
            signal.signal(s, h)
    assert result is not None
    result.wall_time = time.monotonic() - wall0
    if sup is not None and sup.touchdown is not None:
        result.message = (result.message + f" touchdown speed {sup.touchdown:.3f} m/s").strip()
    return result


def _stop_all(procs: dict[str, NodeProcess]) -> None:
    """Signal every node to stop (autopilot first), then wait for each (see NodeProcess.stop)."""
    order = sorted(procs.values(), key=lambda p: p.name != "autopilot")
    interrupted = set()
    for p in order:
        if p.alive():
            try:
                p.proc.send_signal(signal.SIGINT)
                interrupted.add(p.name)
            except ProcessLookupError:
                pass
    for p in order:
        p.stop(interrupted=p.name in interrupted)


def _drain(sup: _Supervisor, executor: Any, quiet: float = 0.2, limit: float = 3.0) -> None:
    """Spin until no message has arrived for ``quiet`` s (bounded), so queued messages reach the bag."""
    rec = sup.recorder
    t_end = time.monotonic() + limit
    last, t_quiet = -1, time.monotonic() + quiet
    while time.monotonic() < min(t_end, t_quiet):
        executor.spin_once(timeout_sec=0.02)
        total = sum(rec.counts.values())
        if total != last:
            last, t_quiet = total, time.monotonic() + quiet


class _Interrupted(Exception):
    pass


class _NodeDied(Exception):
    pass


def final_state(msg: Any) -> dict[str, float]:
    """What a pilot reads off the last LanderState: altitude, rates, fuel and the tilt of the
    body z axis from the local vertical (the message's orientation components are the core's
    quaternion, lander_sim.ros.convert)."""
    from lander_tools.sweep.metrics import altitude_and_tilt

    o, p = msg.orientation, msg.position
    _, tilt = altitude_and_tilt(np.array([p.x, p.y, p.z]), np.array([o.w, o.x, o.y, o.z]))
    return {
        "altitude": float(msg.altitude),
        "climb_rate": float(msg.climb_rate),
        "ground_speed": float(msg.ground_speed),
        "fuel": float(msg.fuel_mass),
        "tilt_deg": math.degrees(tilt),
    }


def summary(result: FlightResult) -> str:
    """The short flight summary ``lander fly`` prints."""
    rtf = result.sim_time / result.wall_time if result.wall_time > 0 else 0.0
    lines = [
        f"flight ended: {result.outcome} at t = {result.sim_time:.2f} s "
        f"({result.states} states, {result.wall_time:.1f} s wall, RTF {rtf:.1f}x), exit code {result.exit_code}"
    ]
    if result.message:
        lines.append(f"  {result.message}")
    f = result.final
    if f:
        lines.append(
            f"  last state: altitude {f['altitude']:.2f} m, climb rate {f['climb_rate']:+.3f} m/s, "
            f"ground speed {f['ground_speed']:.3f} m/s, tilt {f['tilt_deg']:.2f} deg, fuel {f['fuel']:.2f} kg"
        )
    if result.bag is not None:
        lines.append(f"  bag: {result.bag} ({sum(result.counts.values())} messages)")
    return "\n".join(lines)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--composed":
        sys.exit(composed_main(sys.argv[:1] + sys.argv[2:]))
    print("usage: lander fly SCENE ... (this module is the launcher behind `lander fly`)", file=sys.stderr)
    sys.exit(EXIT_ERROR)

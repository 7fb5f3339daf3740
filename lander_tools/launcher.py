"""``lander fly``: start the simulator and the autopilot, fly, record, stop cleanly.

The launcher for machines without ``ros2 launch`` (ROS 2 from PyPI); on a full
install ``ros2 launch mars_lander fly.launch.py`` starts the same two nodes
(``launch/fly.launch.py``). Run (project venv)::

    ./dev fly hover --duration 60 --speed 0 --record out/hover
    ./dev fly free-spin                      # no autopilot in the scene: the sim alone
    ./dev fly 7 --controller altitude-p --params my.yaml --compose

What it does:

Before anything starts, the scene, controller and flight names and the ``--params`` file are
checked (:func:`check_plan`: one line naming what is wrong, with the closest name). Then
:func:`fly` runs these phases, top-down, each a function of its own:

1. :func:`start_nodes`: one ROS parameters file per node (``lander_sim``, ``autopilot``) from
   the user's ``--params`` sections and the flight's settings; the sim node (paused, with the
   flight's end as its ``end_time``/``end_on``) and, when the scene or ``--controller`` names a
   controller, the autopilot node, as processes (or one with ``--compose``), their output
   forwarded under a ``[sim]`` / ``[autopilot]`` prefix; the recorder (``--record``) in this
   process (:class:`~lander_tools.recorder.Recorder`);
2. :func:`wait_until_matched`: every subscriber the flight needs (recorder on every recorded
   topic, autopilot, this launcher) is matched by the publishers' writers, asked of the sim
   (``/lander/subscribers``) and of the recorder's readers;
3. :func:`reset_flight`: reset the sim, so state 1 at t = 0 reaches everyone (and, in lockstep,
   the autopilot has answered it);
4. :func:`run_to_end`: resume and apply the flight's timeline (demand steps, wind, controller
   swaps, throttle overrides) at the first control instant at or after each time, exactly in
   sim time at any speed (with an autopilot the sim pauses there, ``pause_at``, while the
   action is put in force: :func:`plan_stops`), until the sim announces ``FLIGHT_ENDED``: the
   sim itself stops at the end instant (time limit, landing or crash), so the flight's span does
   not depend on how fast this process reacts (docs/sim_node.md, "A flight's span");
5. :func:`stop_nodes`: wait until the recorder holds every message the sim counted, then stop
   the nodes, autopilot first (SIGINT, SIGTERM, SIGKILL after a grace period);
6. :func:`close_and_check_bag`: close the bag and compare its counts with what was published
   (the sim's ``FLIGHT_ENDED`` counts; for the autopilot's and this launcher's topics what this
   launcher's own subscriptions received or it sent): a missing message is an error (exit 3).

Exit status (documented in docs/flying.md):

====  ===========================================================
0     landed, or the time limit was reached while flying
1     crashed
2     error: a node failed to start or died, bad configuration,
      no state from the simulator
3     the flight ended as reported, but the bag misses messages that were published
130   interrupted by Ctrl-C / SIGTERM (the bag is still closed validly)
====  ===========================================================
"""
from __future__ import annotations

import difflib
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

from lander_ros.stamps import stamp_to_seconds
from lander_tools import child

EXIT_OK = 0
EXIT_CRASHED = 1
EXIT_ERROR = 2
EXIT_INCOMPLETE_BAG = 3
EXIT_INTERRUPTED = 130

SIM_NODE = "lander_sim"
AUTOPILOT_NODE = "autopilot"
#: Sections a ``--params`` file may have, and the node each one configures (``/**``: both).
PARAMS_SECTIONS: dict[str, tuple[str, ...]] = {
    SIM_NODE: (SIM_NODE,), f"/{SIM_NODE}": (SIM_NODE,),
    AUTOPILOT_NODE: (AUTOPILOT_NODE,), f"/{AUTOPILOT_NODE}": (AUTOPILOT_NODE,),
    "lander_autopilot": (AUTOPILOT_NODE,), "/lander_autopilot": (AUTOPILOT_NODE,),
    "/**": (SIM_NODE, AUTOPILOT_NODE),
}
#: Wall seconds to wait for a lockstep autopilot's answer to state 1, and resets tried in all.
ANSWER_TIMEOUT = 5.0
RESET_ATTEMPTS = 3
#: Wall seconds to wait, after the sim announced the end, for the recorder to hold what it counted.
DELIVERY_TIMEOUT = 10.0
#: Wall seconds allowed for discovery, service answers and the first state.
STARTUP_TIMEOUT = 30.0
#: Wall seconds without a new state (while not paused) after which the flight is an error.
STALL_TIMEOUT = 30.0
#: The sim's ``lockstep_timeout`` [wall s] in a lockstep flight at speed 0 unless the user sets one:
#: flat out there is no wall clock to keep, so the sim waits out an answer that takes seconds (a
#: controller's design, the MPC's reference solve at the handover) and the flight stays the
#: deterministic one; kept under STALL_TIMEOUT so a hung autopilot shows as counted timeouts.
FLAT_OUT_LOCKSTEP_TIMEOUT = 20.0
#: Wall seconds a node gets to stop after SIGINT, then again after SIGTERM.
STOP_GRACE = 5.0

#: MODE_CHANGED events printed by ``lander fly`` (the rest are counted in one line at the end).
MODE_LINES = 20

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
    live: int | None = None  #: Foxglove port of a `lander live` started with the flight (docs/live.md); None: none

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
    #: Named values of the touchdown event (t_impact [s], descent_rate [m/s], ground_speed [m/s], ...).
    touchdown: dict[str, float] = field(default_factory=dict)
    #: The touchdown's classification against the scene's limits: safe, hard or crash ("" if none).
    touchdown_class: str = ""
    #: The bag's counts against what was published (close_and_check_bag).
    bag_check: str = ""
    #: Lockstep states the sim advanced past without the autopilot's answer (its FLIGHT_ENDED): with
    #: any, the flight is not the deterministic one (the autopilot was late, e.g. starved of CPU).
    lockstep_timeouts: int = 0


def resolve_controller(plan: FlightPlan) -> str | None:
    """The controller to fly, or ``None`` for the sim alone (scene without autopilot, or ``none``)."""
    if plan.controller is not None:
        return None if plan.controller.lower() == "none" else plan.controller
    try:
        from lander_sim.scenes import load_scene

        scene = load_scene(plan.scene)
    except ValueError as exc:
        raise LaunchError(str(exc)) from None
    return None if scene.autopilot is None else scene.autopilot.controller


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


def plan_stops(timeline: list[Action], period: float, duration: float | None) -> list[Stop]:
    """The pauses that make ``timeline`` exact on the control grid ``t_k = k * period``.

    An action due at ``t`` belongs to the first instant ``t_k >= t``. The sim pauses having
    reached ``t_k`` but before publishing its state (``pause_at``), so sim-side actions (wind,
    stabiliser, parachute) act from the step leaving ``t_k`` and autopilot-side ones (demand,
    controller) from its answer to state k. Nothing is planned at or after the end (the first
    instant >= ``duration``, where the sim itself stops: its ``end_time``). Throttle overrides
    (sent with the states) and actions at instant 0 (applied before the flight starts) are not
    listed.
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
            del by_index[k]  # nothing happens at or after the end: the flight stops there
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


def did_you_mean(name: str, choices: list[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest of ``choices`` (difflib), or ``""``."""
    close = difflib.get_close_matches(name, choices, n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else ""


def read_params_file(path: Path) -> dict[str, dict[str, Any]]:
    """The ``--params`` file's parameters per node (``lander_sim``, ``autopilot``).

    Sections: :data:`PARAMS_SECTIONS` (``lander_autopilot`` is the autopilot's package name, accepted
    for it); each holds only ``ros__parameters``. An unknown section or key is a
    :class:`LaunchError` naming it and what is allowed (rcl would ignore it without a word).
    """
    from lander_autopilot.ros.config import SPECS as AP_SPECS
    from lander_ros.params import ROS_BUILTIN, check_value
    from lander_sim.ros.config import SPECS as SIM_SPECS
    from lander_sim.yaml_file import read_yaml

    specs = {SIM_NODE: SIM_SPECS, AUTOPILOT_NODE: AP_SPECS}
    known = {node: set(s) for node, s in specs.items()}
    data = read_yaml(Path(path), "parameters file", LaunchError)
    allowed = ", ".join(PARAMS_SECTIONS)
    if not isinstance(data, dict):
        raise LaunchError(f"--params {path}: expected a mapping of sections ({allowed})")
    out: dict[str, dict[str, Any]] = {SIM_NODE: {}, AUTOPILOT_NODE: {}}
    for key, section in data.items():
        nodes = PARAMS_SECTIONS.get(str(key))
        if nodes is None:
            raise LaunchError(f"--params {path}: unknown section {key!r}{did_you_mean(str(key), list(PARAMS_SECTIONS))} "
                              f"(allowed: {allowed})")
        if not isinstance(section, dict) or set(section) != {"ros__parameters"} or not isinstance(
                section["ros__parameters"], dict):
            raise LaunchError(f"--params {path}: section {key!r} must hold only a 'ros__parameters' mapping")
        for name, value in section["ros__parameters"].items():
            for node in nodes:
                if name not in known[node] | ROS_BUILTIN:
                    names = sorted(known[node])
                    raise LaunchError(f"--params {path}: section {key!r}: {node} has no parameter {name!r}"
                                      f"{did_you_mean(str(name), names)} (allowed: {', '.join(names)})")
                if name not in ROS_BUILTIN:
                    reason = check_value(specs[node], name, value)
                    if reason is not None:
                        raise LaunchError(f"--params {path}: section {key!r}: {reason}")
                out[node][name] = value
    return out


def check_plan(plan: FlightPlan) -> str | None:
    """Check every name and file of ``plan`` before anything starts; returns the controller to fly
    (None: the sim alone). A bad scene, controller (also in the timeline) or ``--params`` file is a
    one-line :class:`LaunchError` naming it, with the closest known name."""
    from lander_autopilot.controllers.registry import available_controllers
    from lander_sim.scenes import list_scenes, load_scene

    s = str(plan.scene)
    if not (s.endswith((".yaml", ".yml")) or Path(s).is_file()):
        infos = list_scenes()
        if not any(s == i.name or s in i.aliases for i in infos):
            from lander_tools.scripted import shipped_flights

            names = [i.name for i in infos] + [a for i in infos for a in i.aliases]
            flights = {p.stem: f"flights/{p.name}" for p in shipped_flights()}
            close = difflib.get_close_matches(s, names + list(flights), n=1, cutoff=0.5)
            hint = f"; did you mean {flights.get(close[0], close[0])!r}?" if close else ""
            raise LaunchError(f"unknown scene {s!r}{hint} ('lander scenes' lists them; scripted flights: flights/*.yaml)")
    try:
        load_scene(s)
    except ValueError as exc:  # a YAML parser's message spans lines: one line for the user
        raise LaunchError(" ".join(str(exc).split())) from None
    controller = resolve_controller(plan)
    names = available_controllers()
    wanted = [controller] if controller is not None else []
    wanted += [str(a.value) for a in plan.timeline if a.kind == "controller"]
    for c in wanted:
        if c not in names:
            raise LaunchError(f"unknown controller {c!r}{did_you_mean(c, names)} (known: {', '.join(names)}, or none)")
    if plan.params_file is not None:
        read_params_file(plan.params_file)
    return controller


def node_commands(plan: FlightPlan, controller: str | None, folder: Path) -> dict[str, list[str]]:
    """The command lines of the node processes (``sim``, ``autopilot`` or ``composed``).

    Each node gets one parameters file: its section of the user's ``--params`` file
    (:func:`read_params_file`), then the flight's settings, which win."""
    user = read_params_file(plan.params_file) if plan.params_file is not None else {SIM_NODE: {}, AUTOPILOT_NODE: {}}
    sim_params = dict(user[SIM_NODE])
    sim_params.update({
        "scene": plan.scene, "speed": float(plan.speed), "start_paused": True,
        # The sim stops by itself at the end instant, and its diagnostics are the flight's only.
        "end_time": float(plan.duration) if plan.duration is not None else -1.0,
        "end_on": ",".join(plan.end_on), "idle_diagnostics": False,
    })
    if controller is not None:
        sim_params["lockstep"] = plan.lockstep is not False
        if sim_params["lockstep"] and plan.speed == 0:
            sim_params.setdefault("lockstep_timeout", FLAT_OUT_LOCKSTEP_TIMEOUT)
    else:
        sim_params["lockstep"] = pilot_mode(plan, controller)
        # The sim alone holds the last command (the user's or the timeline's) for good.
        sim_params["command_timeout"] = 0.0
    sim_params.update(plan.sim_params)
    files: list[str] = []
    sim_file = _params_yaml(SIM_NODE, sim_params, folder)
    cmds = {}
    ap_args: list[str] = []
    if controller is not None:
        ap_params: dict[str, Any] = dict(user[AUTOPILOT_NODE])
        ap_params.update({"scene": plan.scene, "controller": controller, "use_sim_time": True})
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
    from lander_ros.params import check_overrides
    from lander_sim.node import SimNode
    from lander_sim.ros.config import SPECS, ConfigError

    rclpy.init(args=argv)
    nodes: list[Any] = []
    try:
        check_overrides(SPECS, argv, SIM_NODE, ConfigError)
        sim = SimNode()
        nodes.append(sim)
        ap = AutopilotNode(argv)
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


def event_values(msg: Any) -> dict[str, float]:
    """A FlightEvent's ``values`` by name: the core's events end their detail with
    ``[values: a, b, ...]`` (lander_sim.ros.convert.event_fields); empty when it does not."""
    detail = str(msg.detail)
    _, sep, names = detail.rpartition("[values: ")
    if not sep or not names.endswith("]"):
        return {}
    keys = [k.strip() for k in names[:-1].split(",")]
    return dict(zip(keys, (float(v) for v in msg.values))) if len(keys) == len(msg.values) else {}


class _Supervisor:
    """The launcher's own node: watches the flight, applies the timeline, records, counts."""

    def __init__(self, plan: FlightPlan, controller: str | None, out: TextIO, progress: Any) -> None:
        import rclpy
        from geometry_msgs.msg import Vector3Stamped
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import Float64
        from std_srvs.srv import SetBool, Trigger

        from lander_interfaces.msg import (
            AutopilotStatus,
            FlightEvent,
            LanderState,
            ThrottleCommand,
        )
        from lander_interfaces.srv import Reset
        from lander_tools.recorder import DEFAULT_TOPICS, Recorder, RecorderConfig

        self.plan, self.controller, self.out, self.progress = plan, controller, out, progress
        self.node = rclpy.create_node("lander_fly")
        n = self.node
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        # Latched: an autopilot (re)started mid-flight still gets the demand in force.
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_demand = n.create_publisher(Float64, "/lander/demand_altitude", latched)
        self.pub_wind = n.create_publisher(Vector3Stamped, "/lander/wind", reliable)
        self.pub_throttle = n.create_publisher(ThrottleCommand, "/lander/throttle", reliable)
        self.cli_reset = n.create_client(Reset, "/lander/reset")
        self.cli_resume = n.create_client(Trigger, "/lander/resume")
        self.cli_subscribers = n.create_client(Trigger, "/lander/subscribers")
        self.cli_autopilot_matched = n.create_client(Trigger, "/autopilot/matched")
        self.cli_stab = n.create_client(SetBool, "/lander/set_stabiliser")
        self.cli_chute = n.create_client(Trigger, "/lander/deploy_parachute")
        self.cli_switch = None
        #: Sim-time driven timeline (pauses at each action instant): every flight with an autopilot.
        self.timed = controller is not None
        #: The sim waits for the autopilot's answer to every state.
        self.lockstep = controller is not None and plan.lockstep is not False
        if controller is not None:
            from rcl_interfaces.srv import GetParameters, SetParameters

            from lander_interfaces.srv import SwitchController

            self.cli_switch = n.create_client(SwitchController, "/autopilot/switch_controller")
            self.cli_ap_get = n.create_client(GetParameters, "/autopilot/get_parameters")
            self.cli_sim_set = n.create_client(SetParameters, f"/{SIM_NODE}/set_parameters")
            self.cli_sim_get = n.create_client(GetParameters, f"/{SIM_NODE}/get_parameters")
            n.create_subscription(Clock, "/clock", self._on_clock, reliable)
        #: Messages this node received per topic since the flight's reset (the reference for the
        #: bag's counts of the topics the sim does not count), and those it published itself.
        self.received: dict[str, int] = {}
        self.sent: dict[str, int] = {}
        self.subs = {
            "/lander/state": n.create_subscription(LanderState, "/lander/state", self._on_state, reliable),
            "/lander/events": n.create_subscription(FlightEvent, "/lander/events", self._on_event, QoSProfile(depth=1000)),
            "/lander/throttle": n.create_subscription(ThrottleCommand, "/lander/throttle", self._on_throttle, reliable),
        }
        if controller is not None:
            from diagnostic_msgs.msg import DiagnosticArray

            self.subs["/autopilot/status"] = n.create_subscription(
                AutopilotStatus, "/autopilot/status", lambda _m: self._count("/autopilot/status"), reliable)
            # The autopilot's reports on /diagnostics (the sim counts its own): the bag check's reference.
            self.subs["/diagnostics"] = n.create_subscription(
                DiagnosticArray, "/diagnostics", self._on_diagnostics, reliable)
        self.answered_first = False  #: the autopilot answered state 1 (the reset's) since the last reset
        self.last_answer = 0  #: highest state sequence answered on /lander/throttle since the reset
        self.clock_t = 0.0  #: latest /clock [s]: where a paused sim stands before its state is out
        self.types = {"Float64": Float64, "Vector3Stamped": Vector3Stamped, "ThrottleCommand": ThrottleCommand}
        self.LanderState, self.FlightEvent = LanderState, FlightEvent
        self.state: Any = None
        self.states = 0
        self.t = 0.0
        self.last_state_wall = time.monotonic()
        #: The sim's FLIGHT_ENDED, decoded (lander_ros.flight_span.FlightEnd): the flight is over.
        self.flight_end: Any = None
        #: Named values of the LANDED / CRASHED event (t_impact [s], descent_rate [m/s], ...).
        self.touchdown: dict[str, float] = {}
        self.touchdown_class = ""  #: safe / hard / crash, from the event's kind
        self.gimbal_locks: list[float] = []  #: sim times [s] of GIMBAL_LOCK events (printed once, counted)
        self.mode_changes: list[float] = []  #: sim times [s] of MODE_CHANGED events (the first MODE_LINES printed)
        self.pending = sorted(plan.timeline, key=lambda a: a.t)
        self.held_throttle: Action | None = None
        self.futures: list[Any] = []
        #: This node answers every state (lockstep) when the flight has no autopilot.
        self.pilot = pilot_mode(plan, controller)
        self.recorder = None
        if plan.record is not None:
            meta = {"scene": plan.scene, "controller": controller or "none", "speed": str(plan.speed)}
            meta.update({k: str(v) for k, v in plan.sim_params.items()})
            meta.update(plan.meta)
            self.recorder = Recorder(n, RecorderConfig(plan.record, plan.storage, plan.topics or DEFAULT_TOPICS, meta=meta))

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

    def _on_throttle(self, msg: Any) -> None:
        self._count("/lander/throttle")
        if msg.state_sequence == 1:
            self.answered_first = True
        self.last_answer = max(self.last_answer, int(msg.state_sequence))

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
        from lander_ros.flight_span import FlightEnd

        self._count("/lander/events")
        t = stamp_to_seconds(msg.header.stamp)
        E = self.FlightEvent
        if msg.kind == E.FLIGHT_ENDED:
            try:
                self.flight_end = FlightEnd.from_values(list(msg.values))
            except ValueError as exc:
                self.out.write(f"[fly] ignored a malformed FLIGHT_ENDED: {exc}\n")
            return
        if msg.kind in (E.LANDED, E.HARD_LANDING, E.CRASHED):
            self.touchdown = event_values(msg)  # touchdown figures: the event's own named values
            self.touchdown_class = {E.LANDED: "safe", E.HARD_LANDING: "hard"}.get(msg.kind, "crash")
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
        if msg.kind in (E.LANDED, E.HARD_LANDING, E.CRASHED, E.GIMBAL_LOCK, E.CONTROLLER_SWITCHED, E.FUEL_OUT,
                        E.LANDING_UNREACHABLE, E.MODE_CHANGED):
            self.out.write(f"[fly] event at t = {t:.2f} s: {msg.detail}\n")

    def _publish(self, pub: Any, msg: Any) -> None:
        pub.publish(msg)
        self.sent[pub.topic_name] = self.sent.get(pub.topic_name, 0) + 1

    def _send_throttle(self, values: list[float], seq: int) -> None:
        m = self.types["ThrottleCommand"]()
        m.header.stamp = self.state.header.stamp
        m.state_sequence = int(seq)  # 0: an override that answers no particular state
        m.throttles = [float(v) for v in values]
        self._publish(self.pub_throttle, m)

    def _apply_due(self) -> None:
        while self.pending and self.pending[0].t <= self.t + 1e-9:
            self.apply(self.pending.pop(0), self.t)

    def apply(self, a: Any, at: float) -> None:
        """Carry out one timeline action now; ``at`` [s] is the sim instant it applies at (logged)."""
        from std_srvs.srv import SetBool, Trigger

        self.out.write(f"[fly] t = {at:.2f} s: {a.kind} {a.value if a.value is not None else ''}\n")
        if a.kind == "demand_altitude":
            m = self.types["Float64"]()
            m.data = float(a.value)
            self._publish(self.pub_demand, m)
        elif a.kind == "wind":
            m = self.types["Vector3Stamped"]()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(round(at * 1e9), 1_000_000_000)
            m.header.frame_id = "mars"
            m.vector.x, m.vector.y, m.vector.z = (float(v) for v in a.value)
            self._publish(self.pub_wind, m)
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


def _apply_now(executor: Any, sup: _Supervisor, a: Action, at: float) -> None:
    """Apply ``a`` at instant ``at`` [s] while the sim is paused there, and wait until it is in force."""
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters

    sup.apply(a, at)
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


# --- the phases of a flight -------------------------------------------------------------------


@dataclass
class LaunchedFlight:
    """One flight being flown: its plan, its node processes and this process's own ROS side."""

    plan: FlightPlan
    controller: str | None
    out: TextIO
    progress: Any
    env: dict[str, str] | None = None
    procs: dict[str, NodeProcess] = field(default_factory=dict)
    sup: _Supervisor | None = None
    executor: Any = None
    stop_reason: list[str] = field(default_factory=list)  #: signals received (SIGINT, SIGTERM)
    stopped: bool = False  #: stop_nodes() ran
    folder: Path | None = None  #: where the nodes' parameter files are written

    def spin(self, timeout: float = 0.05) -> None:
        """One executor pass; raises if a signal arrived or a node process died."""
        if self.stop_reason:
            raise _Interrupted()
        for name, p in self.procs.items():
            if not p.alive():
                tail = "\n".join(p.lines[-5:])
                raise _NodeDied(f"node process {name!r} exited with code {p.proc.returncode}" + (f":\n{tail}" if tail else ""))
        self.executor.spin_once(timeout_sec=timeout)

    def wait_for(self, done: Any, timeout: float, what: str) -> None:
        """Spin until ``done()``; LaunchError naming ``what`` after ``timeout`` wall seconds."""
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                raise LaunchError(f"{what} within {timeout} s")
            self.spin()


def start_nodes(f: LaunchedFlight) -> None:
    """Phase 1: this process's node (and recorder), then the node processes, paused."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    assert f.folder is not None
    cmds = node_commands(f.plan, f.controller, f.folder)
    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    f.sup = _Supervisor(f.plan, f.controller, f.out, f.progress)
    f.executor = SingleThreadedExecutor()
    f.executor.add_node(f.sup.node)
    for name, argv in cmds.items():
        f.procs[name] = NodeProcess(name, argv, f.out, f.env)
    if f.plan.live is not None:  # `lander live` beside the nodes; counted in expected_subscribers
        from lander_tools.live.bridge import command as live_command

        f.procs["live"] = NodeProcess("live", live_command(f.plan.live, f.plan.live + 1 if f.plan.live else 0),
                                      f.out, f.env)
    f.out.write(
        f"[fly] scene {f.plan.scene!r}, controller {f.controller or 'none (sim alone)'}, "
        f"speed {f.plan.speed or 'max'}, pids " + ", ".join(f"{k} {p.pid}" for k, p in f.procs.items()) + "\n"
    )


def expected_subscribers(f: LaunchedFlight) -> dict[str, int]:
    """Per sim topic, the subscriptions its writer must have matched before the flight starts:
    this launcher's, the autopilot's and the recorder's (``sub:TOPIC``: publishers the sim's own
    subscription to TOPIC must have matched)."""
    from lander_ros.flight_span import COUNTED_TOPICS

    sup = f.sup
    assert sup is not None
    need = {"/lander/state": 1, "/lander/events": 1, "sub:/lander/throttle": 1, "sub:/lander/wind": 1}
    if sup.timed:
        need["/clock"] = 1
    if f.controller is not None:
        need["/lander/state"] += 1
        need["sub:/lander/throttle"] += 1
    if sup.recorder is not None:
        for t in COUNTED_TOPICS:
            if sup.recorder.wanted(t):
                need[t] = need.get(t, 0) + 1
    if f.plan.live is not None:
        from lander_tools.live.bridge import SUBSCRIBED_TOPICS

        for t in SUBSCRIBED_TOPICS:
            need[t] = need.get(t, 0) + 1
    return need


def expected_publishers(f: LaunchedFlight) -> dict[str, int]:
    """Per topic this process subscribes to (recorder, launcher), the publishers it must have
    matched: the sim's outputs, the autopilot's and this launcher's own."""
    from lander_ros.flight_span import COUNTED_TOPICS, SIM_INPUT_TOPICS

    pubs = {t: 1 for t in COUNTED_TOPICS}
    pubs.update({t: 1 for t in (*SIM_INPUT_TOPICS, "/lander/demand_altitude")})
    if f.controller is not None:
        pubs["/lander/throttle"] += 1
        pubs["/lander/events"] += 1
        pubs["/autopilot/status"] = 1
        pubs["/diagnostics"] += 1
    return pubs


def wait_until_matched(f: LaunchedFlight) -> None:
    """Phase 2: wait until every subscriber the flight needs is matched on every topic it needs.

    Asked from both ends: the sim's writers (``/lander/subscribers``), this process's readers
    (the recorder's and the launcher's own) and, with an autopilot, its state reader
    (``/autopilot/matched``). One more observer (a bridge process) is one more
    entry in :func:`expected_subscribers`."""
    from std_srvs.srv import Trigger

    from lander_ros.flight_span import parse_matched

    sup = f.sup
    assert sup is not None
    need_sim, need_here = expected_subscribers(f), expected_publishers(f)
    waiting: list[str] = []

    def matched() -> bool:
        sims = [x for x, _ in sup.node.get_node_names_and_namespaces() if x == SIM_NODE]
        if len(sims) > 1:
            raise LaunchError(
                f"{len(sims)} simulator nodes in ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}: "
                "another flight is running there; set ROS_DOMAIN_ID (0-101) to keep flights apart"
            )
        waiting[:] = []
        for topic, sub in sup.subs.items():
            if sub.get_publisher_count() < need_here.get(topic, 1):
                waiting.append(f"launcher <- {topic}")
        if sup.recorder is not None:
            for topic, n in need_here.items():
                if sup.recorder.wanted(topic) and sup.recorder.matched(topic) < n:
                    waiting.append(f"recorder <- {topic}")
        services = (sup.cli_subscribers, sup.cli_reset, sup.cli_resume)
        if waiting or not all(c.service_is_ready() for c in services):
            waiting.append("the sim's services")
            return False
        res = _call(f.executor, sup.cli_subscribers, Trigger.Request(), STARTUP_TIMEOUT, "subscribers")
        have = parse_matched(res.message)
        waiting.extend(f"sim -> {t}" for t, n in need_sim.items() if have.get(t, 0) < n)
        if f.controller is not None and not waiting:
            # the other end of the state's match: the autopilot's reader has the sim's writer
            if not sup.cli_autopilot_matched.service_is_ready():
                waiting.append("the autopilot's services")
                return False
            res = _call(f.executor, sup.cli_autopilot_matched, Trigger.Request(), STARTUP_TIMEOUT, "autopilot matched")
            have_ap = parse_matched(res.message)
            if have_ap.get("sub:/lander/state", 0) < 1:
                waiting.append("autopilot <- /lander/state")
            # its first report goes out with its answer to state 1: its writer must have the readers
            readers = 1 + (sup.recorder is not None and sup.recorder.wanted("/diagnostics"))
            if have_ap.get("/diagnostics", 0) < readers:
                waiting.append("autopilot -> /diagnostics")
        return not waiting

    deadline = time.monotonic() + STARTUP_TIMEOUT
    while not matched():
        if time.monotonic() > deadline:
            raise LaunchError(f"nodes not matched within {STARTUP_TIMEOUT} s (still waiting for {', '.join(waiting)})")
        f.spin()


def reset_flight(f: LaunchedFlight) -> list[Stop]:
    """Phase 3: plan the timeline's stops and arm the first (``pause_at``); reset the sim (state 1
    at t = 0 goes to everyone matched), wait for that state (and, in lockstep, the autopilot's
    answer to it), apply the timeline's actions at t = 0. Returns the stops still to come.

    Everything that asks the sim something is done before the reset, so that the flight resumes
    right after it: a lockstep autopilot waiting long for its second state would report it lost."""
    from lander_interfaces.srv import Reset

    sup, plan = f.sup, f.plan
    assert sup is not None
    stops: list[Stop] = []
    at_zero: list[Action] = []  # timed flights: actions of instant 0, put in force before the first step
    if sup.timed:
        period = _control_period(f.executor, sup, plan)
        timed = [a for a in sup.pending if a.kind != "throttle"]
        stops = plan_stops(timed, period, plan.duration)
        at_zero = [a for a in timed if math.ceil(a.t / period - 1e-9) <= 0]
        sup.pending = [a for a in sup.pending if a.kind == "throttle"]
        _arm(f.executor, sup, stops[0].t if stops else -1.0)
    for attempt in range(1, RESET_ATTEMPTS + 1):
        sup.received.clear()  # counts of the flight: from its reset on
        sup.answered_first, sup.last_answer, states0 = False, 0, sup.states
        res = _call(f.executor, sup.cli_reset, Reset.Request(), STARTUP_TIMEOUT, "reset")
        if not res.success:
            raise LaunchError(f"the sim refused the reset: {res.message}")
        f.wait_for(lambda: sup.states > states0, STARTUP_TIMEOUT,  # noqa: B023 - called within this attempt
                   "no state 1 from the simulator")
        try:
            f.wait_for(lambda: not sup.lockstep or sup.answered_first, ANSWER_TIMEOUT,
                       "no answer from the autopilot to state 1")
            break
        except LaunchError:
            # The sim's writer matched the autopilot's reader, but that reader had not yet matched
            # the writer (Fast DDS: a volatile reader then drops the sample). Resetting again asks
            # again; a recorder then holds both epochs, which the bag check reports (exit 3).
            if attempt == RESET_ATTEMPTS:
                raise
            f.out.write(f"[fly] the autopilot did not answer state 1 within {ANSWER_TIMEOUT} s: resetting again\n")
    for a in at_zero:
        _apply_now(f.executor, sup, a, 0.0)  # in force (the autopilot took the demand) before the first step
    sup._apply_due()  # untimed flights: actions at t = 0 (e.g. a throttle override) before the first step
    return stops


def run_to_end(f: LaunchedFlight, stops: list[Stop]) -> None:
    """Phase 4: resume, apply the timeline at its stops, until the sim announces the end."""
    from std_srvs.srv import Trigger

    sup = f.sup
    assert sup is not None
    _call(f.executor, sup.cli_resume, Trigger.Request(), STARTUP_TIMEOUT, "resume")
    sup.last_state_wall = time.monotonic()
    while sup.flight_end is None:
        if time.monotonic() - sup.last_state_wall > STALL_TIMEOUT:
            raise LaunchError(f"no state from the simulator for {STALL_TIMEOUT} s at t = {sup.t:.3f} s")
        f.spin()
        sup.check_futures()
        if stops and sup.flight_end is None and sup.clock_t >= stops[0].t - 1e-6:
            stop = stops.pop(0)  # the sim stands at stop.t, its state not yet out
            for a in stop.actions:
                _apply_now(f.executor, sup, a, stop.t)
            _arm(f.executor, sup, stops[0].t if stops else -1.0)
            res = _call(f.executor, sup.cli_resume, Trigger.Request(), STARTUP_TIMEOUT, "resume")
            if not res.success:  # the flight ended at this very instant (a touchdown): its event follows
                f.out.write(f"[fly] {res.message}\n")


def stop_nodes(f: LaunchedFlight) -> None:
    """Phase 5: once the recorder holds every message the sim counted (or after DELIVERY_TIMEOUT),
    stop the nodes, autopilot first, and take in what they flushed on their way out."""
    sup = f.sup
    f.stopped = True
    if sup is not None and sup.flight_end is not None:
        # Topics are not ordered among themselves: the end state may still be on its way here.
        published = sup.flight_end.counts
        rec = sup.recorder
        wanted = {t: n for t, n in published.items() if rec is not None and rec.wanted(t)}

        def delivered() -> bool:
            # In lockstep the autopilot answers the end state too: that answer belongs to the flight.
            answered = not sup.lockstep or sup.last_answer >= published["/lander/state"]
            # The states counted where they are kept (the bag): this node's own watch subscription
            # may lose some on a loaded machine or a flat-out flight (it is the slower reader), and
            # waiting for them here only ran out the delivery timeout (10 s of "state lost" from the
            # autopilot, or of a flat-out flight's end). The watch needs the end state itself: the
            # summary's last state (it had printed one 3-4 s of flight before a crash). One reliable
            # writer delivers in order, so the latest state the watch holds is the highest.
            seen_end = sup.state is not None and sup.state.sequence >= published["/lander/state"]
            return answered and seen_end and all(rec.counts.get(t, 0) >= n for t, n in wanted.items())

        deadline = time.monotonic() + DELIVERY_TIMEOUT
        while not delivered() and time.monotonic() < deadline:
            f.executor.spin_once(timeout_sec=0.02)
    _stop_all(f.procs)
    if sup is not None and sup.recorder is not None and f.executor is not None:
        # what the nodes flushed before they exited is still queued here
        sup.recorder.wait_quiet(0.2, 3.0, pause=lambda s: f.executor.spin_once(timeout_sec=s))


def reference_counts(sup: _Supervisor) -> dict[str, tuple[int, bool]]:
    """What the bag must hold per recorded topic: ``(count, exact)``.

    * the sim's own outputs: its FLIGHT_ENDED counts, exactly (``/lander/events`` too when the sim
      is its only publisher);
    * ``/lander/throttle``: in lockstep exactly one answer per state (the sim's ``/lander/state``
      count: the autopilot answers every lockstep state once, the end state too), or, if the sim
      advanced past some states without their answer (``FlightEnd.lockstep_timeouts``), at least one
      per state less those (an answer may still come after its timeout); otherwise at least
      what this launcher's own subscription received since the reset (nobody commands before the
      first state; that subscription can lose messages on a loaded machine, so it is no exact count);
    * ``/autopilot/status`` and, with an autopilot, ``/lander/events``: at least that (the
      autopilot may report before the flight, e.g. its start-up status, which the recorder may
      hold too);
    * ``/diagnostics`` with an autopilot: at least the sim's count plus the autopilot's reports this
      launcher received (both publish there; the bag cannot tell whose a message is by its count);
    * inputs this launcher published (wind, demand): at least what it sent (anyone may add more).
    """
    assert sup.recorder is not None
    ref: dict[str, tuple[int, bool]] = {}
    if sup.flight_end is not None:
        ref.update({t: (n, True) for t, n in sup.flight_end.counts.items()})
    if sup.lockstep and sup.controller is not None and sup.flight_end is not None:
        missed = sup.flight_end.lockstep_timeouts
        ref["/lander/throttle"] = (sup.flight_end.counts.get("/lander/state", 0) - missed, missed == 0)
    else:
        ref["/lander/throttle"] = (sup.received.get("/lander/throttle", 0), False)
    if sup.controller is not None:
        ref["/autopilot/status"] = (sup.received.get("/autopilot/status", 0), False)
        ref["/lander/events"] = (max(ref.get("/lander/events", (0, False))[0], sup.received.get("/lander/events", 0)),
                                 False)
        ref["/diagnostics"] = (ref.get("/diagnostics", (0, False))[0] + sup.received.get("/diagnostics", 0), False)
    for t in ("/lander/wind", "/lander/demand_altitude"):
        ref[t] = (sup.sent.get(t, 0), False)
    return {t: v for t, v in ref.items() if sup.recorder.wanted(t)}


def close_and_check_bag(f: LaunchedFlight, result: FlightResult) -> None:
    """Phase 6: close the bag, print its counts and compare them with :func:`reference_counts`;
    a missing message makes the result exit :data:`EXIT_INCOMPLETE_BAG` with a line naming it."""
    sup = f.sup
    if sup is None or sup.recorder is None:
        return
    sup.recorder.writer.set_custom_data("outcome", result.outcome)
    counts = sup.recorder.close()
    result.counts, result.bag = counts, f.plan.record
    f.out.write(sup.recorder.summary() + "\n")
    if sup.flight_end is None:
        result.bag_check = "not checked: the flight did not reach its end"
        return
    from lander_ros.flight_span import shortfalls

    bad = shortfalls(reference_counts(sup), counts)
    if bad:
        result.bag_check = "INCOMPLETE: " + ", ".join(bad) + " published"
        if result.exit_code in (EXIT_OK, EXIT_CRASHED):
            result.exit_code = EXIT_INCOMPLETE_BAG
    else:
        result.bag_check = "complete: every message published in the flight is in it"


def fly(plan: FlightPlan, out: TextIO | None = None, progress: Any = None, env: dict[str, str] | None = None) -> FlightResult:
    """Fly ``plan`` to its end and return how it ended: the phases of the module docstring, in order.

    Must run in the main thread (it installs SIGINT/SIGTERM handlers for the duration).
    """
    import rclpy

    from lander_tools.progress import Progress

    out = out or sys.stdout
    if plan.duration is None:
        plan.duration = scene_end_time(plan.scene)  # the scene's own end.max_time, if it has one
    progress = progress or Progress(total=plan.duration)
    wall0 = time.monotonic()
    try:
        controller = check_plan(plan)
    except LaunchError as exc:
        progress.finish()
        return FlightResult("error", EXIT_ERROR, 0.0, 0, str(exc))
    f = LaunchedFlight(plan, controller, out, progress, env)

    def on_signal(signum: int, _frame: Any) -> None:
        f.stop_reason.append(signal.Signals(signum).name)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    tmp = tempfile.TemporaryDirectory(prefix="lander-fly-")
    f.folder = Path(tmp.name)
    result: FlightResult | None = None
    try:
        start_nodes(f)
        wait_until_matched(f)
        stops = reset_flight(f)
        run_to_end(f, stops)
        sup = f.sup
        assert sup is not None and sup.flight_end is not None
        stop_nodes(f)
        end = sup.flight_end
        # the sim's count of the states it published (this node's watch may have lost some under load)
        states = end.counts.get("/lander/state", sup.states)
        result = FlightResult(end.reason, EXIT_CRASHED if end.reason == "crashed" else EXIT_OK, end.t, states)
        result.lockstep_timeouts = end.lockstep_timeouts
    except _Interrupted:
        result = _failed(f, "interrupted", EXIT_INTERRUPTED, f"stopped by {f.stop_reason[0] if f.stop_reason else 'signal'}")
    except _NodeDied as exc:
        result = _failed(f, "error", EXIT_ERROR, str(exc))
    except (LaunchError, ValueError, OSError) as exc:
        result = _failed(f, "error", EXIT_ERROR, str(exc))
    finally:
        progress.finish()
        if result is None:  # an unexpected exception is on its way out: still stop everything
            _stop_all(f.procs)
        if result is not None:
            if not f.stopped:
                stop_nodes(f)
            close_and_check_bag(f, result)
        elif f.sup is not None and f.sup.recorder is not None:
            f.sup.recorder.close()
        if f.sup is not None:
            f.sup.node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
        tmp.cleanup()
        for s, h in old.items():
            signal.signal(s, h)
    assert result is not None
    result.wall_time = time.monotonic() - wall0
    sup = f.sup
    if sup is not None:
        if sup.state is not None:
            result.final = final_state(sup.state)
        result.touchdown = dict(sup.touchdown)
        result.touchdown_class = sup.touchdown_class
        if len(sup.gimbal_locks) > 1:
            ts = sup.gimbal_locks
            out.write(f"[fly] gimbal lock: {len(ts)} events in all, t = {ts[0]:.2f} to {ts[-1]:.2f} s "
                      "(only the first is shown)\n")
        if len(sup.mode_changes) > MODE_LINES:
            ts = sup.mode_changes
            out.write(f"[fly] mode changes: {len(ts)} in all, t = {ts[0]:.2f} to {ts[-1]:.2f} s "
                      f"(the first {MODE_LINES} are shown)\n")
    return result


def _failed(f: LaunchedFlight, outcome: str, code: int, message: str) -> FlightResult:
    sup = f.sup
    return FlightResult(outcome, code, sup.t if sup else 0.0, sup.states if sup else 0, message)


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


class _Interrupted(Exception):
    pass


class _NodeDied(Exception):
    pass


def final_state(msg: Any) -> dict[str, float]:
    """What a pilot reads off the last LanderState: altitude [m], climb rate [m/s], ground speed
    [m/s], fuel [kg] and the tilt [deg] of the body z axis from the local vertical (the message's
    orientation components are the core's quaternion, lander_sim.ros.convert). Altitude and tilt
    are NaN where they do not apply: a fixed pivot (the rotor scenes, position r = 0) has no
    local vertical."""
    from lander_tools.sweep.metrics import altitude_and_tilt

    o, p = msg.orientation, msg.position
    r = np.array([p.x, p.y, p.z])
    altitude, tilt = altitude_and_tilt(r, np.array([o.w, o.x, o.y, o.z]))
    return {
        "altitude": float(msg.altitude) if math.isfinite(altitude) else math.nan,
        "climb_rate": float(msg.climb_rate),
        "ground_speed": float(msg.ground_speed),
        "fuel": float(msg.fuel_mass),
        "tilt_deg": math.degrees(tilt),
    }


def _figure(value: float, fmt: str, unit: str) -> str:
    return f"{value:{fmt}} {unit}" if math.isfinite(value) else "n/a"


def summary(result: FlightResult) -> str:
    """The flight summary ``lander fly`` prints: every figure named, with its unit; "n/a" where a
    figure does not apply (no touchdown in an orbit, no altitude or tilt on a fixed pivot)."""
    from lander_ros.flight_span import lockstep_warning

    rtf = result.sim_time / result.wall_time if result.wall_time > 0 else 0.0
    lines = [
        f"flight ended: {result.outcome} at sim time t = {result.sim_time:.2f} s "
        f"({result.states} states; {result.wall_time:.1f} s wall time, real-time factor {rtf:.1f}x), "
        f"exit code {result.exit_code}"
    ]
    if result.message:
        lines.append(f"  {result.message}")
    f = result.final
    if f:
        lines.append(
            f"  last state: altitude {_figure(f['altitude'], '.2f', 'm')}, "
            f"climb rate {_figure(f['climb_rate'], '+.3f', 'm/s')}, "
            f"ground speed {_figure(f['ground_speed'], '.3f', 'm/s')}, tilt {_figure(f['tilt_deg'], '.2f', 'deg')}, "
            f"fuel {_figure(f['fuel'], '.2f', 'kg')}"
        )
    # Touchdown figures come from the LANDED/CRASHED event's own named values (the core's
    # touchdown classification), never from the last state.
    td = result.touchdown
    if td:
        figures = [f"descent rate {_figure(td.get('descent_rate', math.nan), '.2f', 'm/s')}",
                   f"ground speed {_figure(td.get('ground_speed', math.nan), '.2f', 'm/s')}"]
        units = {"tilt_deg": ("tilt", ".2f", "deg"), "fuel_left": ("fuel left", ".2f", "kg")}
        figures += [f"{units[k][0]} {_figure(v, units[k][1], units[k][2])}" if k in units else f"{k} {v:.6g} (SI)"
                    for k, v in td.items() if k not in ("descent_rate", "ground_speed", "t_impact")]
        if result.touchdown_class:
            figures.append(f"{result.touchdown_class} (against the scene's touchdown limits)")
        lines.append(f"  touchdown at t = {_figure(td.get('t_impact', math.nan), '.3f', 's')}: " + ", ".join(figures))
    elif f:
        lines.append("  touchdown: n/a (none in this flight)")
    warning = lockstep_warning(result.lockstep_timeouts)
    if warning:
        lines.append(f"  lockstep: {warning}")
    if result.bag is not None:
        lines.append(f"  bag: {result.bag} ({sum(result.counts.values())} messages; {result.bag_check})")
    return "\n".join(lines)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--composed":
        sys.exit(composed_main(sys.argv[:1] + sys.argv[2:]))
    print("usage: lander fly SCENE ... (this module is the launcher behind `lander fly`)", file=sys.stderr)
    sys.exit(EXIT_ERROR)

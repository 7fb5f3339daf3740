"""``autopilot``: the ROS 2 autopilot node, a thin shell around a controller plug-in.

Run (project venv, no ROS install needed)::

    ./dev exec autopilot_node                                     # the scene 'hover' and its controller
    ./dev exec autopilot_node --ros-args --params-file config/autopilot.yaml
    ./dev exec autopilot_node --ros-args -p scene:=hover-canted -p controller:=combined \\
        -p controller_params:='{altitude_poles: [-0.9, -1.1]}' -p demand_altitude:=520.0
    ./dev exec python -m lander_autopilot.node --ros-args -p controller:=altitude-p

On a full ROS 2 install: ``ros2 run mars_lander autopilot_node --ros-args --params-file config/autopilot.yaml``.

One control step, once per state the simulator publishes (it publishes at the control rate)::

    /lander/state -> StateView -> controller.update(t, state, demand) -> /lander/throttle
                                                                      -> /autopilot/status
                                     (timed: lander_autopilot.ros.loop_stats) -> /diagnostics

With ``state_source: estimate`` the states come from the estimator node's ``/lander/estimate/state``
(the same message type, filled from the navigation filter; lander_autopilot.estimator_node) and
nothing else changes: the controller flies on the estimate as it flies on the truth.

``/diagnostics`` (``DiagnosticArray``): the control loop's figures (control period, compute time
per period, overruns) and the controller's own ``diagnostics()`` when it has one, once per second
of sim time and at every mode change (docs/autopilot_node.md, "/diagnostics").

Swapping the controller while flying: service ``/autopilot/switch_controller``
(``lander_interfaces/srv/SwitchController``) or an atomic change of the parameters
``controller`` and ``controller_params``. The new controller is built and checked completely
before it is installed between two control steps, and a ``FlightEvent`` ``CONTROLLER_SWITCHED``
goes to ``/lander/events``. The node spins a single-threaded executor; the switch service builds
in a worker thread while the old controller keeps answering states (its callback awaits the
build), a parameter change builds in the executor's thread (the control loop waits for the design,
tens of milliseconds). rclpy's MultiThreadedExecutor is not used: on these wheels it woke ~6000
times a second with nothing to do and cut the full stack's speed tenfold (docs/autopilot_node.md). python-control is
imported and the design path warmed up at start-up, before the node answers anything. A refused change
leaves the running controller flying. See docs/autopilot_node.md. No control law and no physics here.
"""
from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.base import REQUEST_DEPLOY_PARACHUTE, REQUEST_LANDING_UNREACHABLE, DemandError
from lander_autopilot.ros import convert
from lander_autopilot.ros.config import (
    CONTROLLER_PARAMETERS,
    DEFAULT_STATE_TIMEOUT,
    NODE_NAME,
    PARAMETER_NAMES,
    SPECS,
    STATE_SOURCES,
    ConfigError,
    check_state_timeout,
    check_string,
    dump_controller_params,
    parse_controller_params,
    scene_autopilot,
)
from lander_autopilot.ros.loop_stats import (
    LoopStats,
    ReportClock,
    control_status,
    controller_status,
    format_gains,
)
from lander_autopilot.ros.slot import ControllerSlot, OutputError, build_choice
from lander_interfaces.msg import AutopilotStatus, FlightEvent, LanderState, ThrottleCommand
from lander_interfaces.srv import SwitchController
from lander_ros.delivery import FLUSH_TIMEOUT, OUTPUT_QOS, flush, run_node_process
from lander_ros.flight_span import sim_paused
from lander_ros.params import check_overrides
from lander_ros.strangers import InputGuard, with_message_info
from lander_sim.scenes import load_scene

#: Only the newest state matters: a controller must never work through a backlog of old states.
_STATE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: The same in a launched flight, whose autopilot refuses other simulators' states: one sample of
#: history is shared by every writer, so a stranger's state would push out the flight's own, which a
#: lockstep simulator then waits for in vain. The flight's simulator has one state out at a time.
_FLIGHT_STATE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: Demand altitude input: only the newest demand matters, a few queued are plenty.
_DEMAND_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
_EVENT_QOS = QoSProfile(depth=1000)  # as the simulator's events publisher: none is lost in a burst
#: [s] wall time the simulator's last "paused" report stays good: a few of its reports (1 Hz by
#: default); past it the simulator has gone quiet, and a missing state is a loss again
PAUSED_REPORT_TIMEOUT = 5.0
#: Wall period [s] of the state watchdog (steady clock: it must notice a simulator whose /clock stopped).
_WATCHDOG_PERIOD = 0.1


#: Executor threads: control (states, demand, watchdog), the switch service, the parameter services.
class AutopilotNode(Node):
    """The autopilot node. Build it, then spin it in :func:`make_executor`'s executor."""

    def __init__(self, argv: list[str] | None = None, **kwargs) -> None:
        """``argv``: the command line the node's overrides come from (default ``sys.argv``): each is
        checked before the node exists (an unknown name or a bad value is a ConfigError naming it),
        and ``use_sim_time`` defaults to true unless it is given there."""
        given = check_overrides(SPECS, sys.argv if argv is None else argv, NODE_NAME, ConfigError)
        super().__init__(NODE_NAME, **kwargs)
        # Sim time by default (the simulator is the clock); an explicit override still wins.
        if "use_sim_time" not in given:
            self.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])

        # Defaults follow the scene: declare it first, then the rest with its autopilot section.
        scene = check_string("scene", self._declare("scene", "hover"))
        loaded = load_scene(scene)
        wanted = scene_autopilot(loaded)
        controller = check_string("controller", self._declare("controller", wanted.controller))
        params_text = self._declare("controller_params", dump_controller_params(wanted.parameters))
        demand = self._declare("demand_altitude", wanted.demand_altitude)
        self._state_timeout = check_state_timeout(self._declare("state_timeout", DEFAULT_STATE_TIMEOUT))
        # A launched flight's autopilot takes states only from its flight's simulator (lander_ros.strangers).
        # The states flown on: the simulator's truth or the estimator's estimate (parameter state_source).
        source = self._declare("state_source", "truth")
        if source not in STATE_SOURCES:
            raise ConfigError(f"parameter 'state_source' = {source!r} must be one of {', '.join(STATE_SOURCES)}")
        self._state_topic, publisher = STATE_SOURCES[source]
        self._guard = InputGuard(bool(self._declare("flight_id", "")), (publisher,), self._state_topic, verbs=False)
        # Before any subscription or timer exists: importing python-control holds the GIL for
        # seconds in stretches, and in a background thread it starved the control steps, so the
        # first states of a lockstep flight waited out the simulator's timeout (measured: 10 states
        # unanswered in a soak). Done here, it only lengthens the start-up, which everyone waits for.
        self._warm_up(scene)
        self.slot = ControllerSlot(
            build_choice(scene, controller, parse_controller_params(params_text)), Demand(altitude=_number(demand))
        )

        # A validated change (controller choice, demand, state timeout; None: unchanged) waits here
        # between the two parameter callbacks of one set-parameters call. Every callback runs in the
        # executor's one thread, so a swap always falls between two control steps.
        self._pending: tuple[Any, float | None, float | None] = (None, None, None)
        self._stop = threading.Event()  # set by request_stop(): run() returns
        #: (scene, controller, controller_params) -> controller built by the switch service's worker
        #: thread (or the ValueError that refused it), taken by the set-parameters check that follows.
        self._prebuilt: tuple[tuple[str, str, str], Any] | None = None
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)

        self._pub_throttle = self.create_publisher(ThrottleCommand, "/lander/throttle", OUTPUT_QOS)
        self._pub_status = self.create_publisher(AutopilotStatus, "/autopilot/status", OUTPUT_QOS)
        self._pub_events = self.create_publisher(FlightEvent, "/lander/events", _EVENT_QOS)
        self._pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", OUTPUT_QOS)
        self._sub_state = self.create_subscription(LanderState, self._state_topic, with_message_info(self._on_state),
                                                   _FLIGHT_STATE_QOS if self._guard.active else _STATE_QOS)
        self.create_subscription(Float64, "/lander/demand_altitude", self._on_demand, _DEMAND_QOS)
        self.create_subscription(Vector3Stamped, "/lander/demand_velocity", self._on_demand_velocity, _DEMAND_QOS)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, _DEMAND_QOS)
        # "Land": switch to the landing law with demand altitude 0 (docs/autopilot_node.md).
        self.create_service(Trigger, "/autopilot/land", self._srv_land)
        # Matching seen from this side: a writer can count this reader matched before the reader has
        # matched the writer (Fast DDS), and a volatile reader drops what comes in between; so a
        # launcher asks both ends before it starts a flight (docs/autopilot_node.md).
        self.create_service(Trigger, "/autopilot/matched", self._srv_matched)
        # A law's "deploy the parachute" request goes to the simulator's service.
        self._cli_chute = self.create_client(Trigger, "/lander/deploy_parachute")
        # Own group: while a switch awaits its build, the default group (states, demands, watchdog)
        # stays free to run.
        self.create_service(SwitchController, "/autopilot/switch_controller", self._srv_switch,
                            callback_group=MutuallyExclusiveCallbackGroup())

        # Kept and refilled: no per-step construction of message objects.
        self._cmd = ThrottleCommand()
        self._status = AutopilotStatus()
        self._last_stamp = None  # stamp of the last state answered (sim time)
        self._start_wall = time.monotonic()
        self._last_state_wall: float | None = None
        self._state_lost = False
        self._next_lost_report = 0.0
        self._sim_paused, self._sim_report_wall = False, -float("inf")  # the simulator's latest /diagnostics
        self._paused_said = False
        self._mode = ""  # the controller mode last announced
        # /diagnostics: compute time per control period, reported on the sim clock (ReportClock).
        self._loop = LoopStats()
        self._reports = ReportClock()
        self._diag = DiagnosticArray()
        self.create_timer(_WATCHDOG_PERIOD, self._watchdog, clock=Clock(clock_type=ClockType.STEADY_TIME))
        #: The flying law's gains as one line, made once per controller installed (a law's gains
        #: are fixed at its construction): the control report carries it every second.
        self._gains_line = gains = self._gains_text()
        self.get_logger().info(
            f"controller {self.slot.name!r} for scene {loaded.name!r}, demand altitude {self.slot.demand.altitude} m"
            + (f", gains {gains}" if gains else "")
        )

    def run(self, executor: SingleThreadedExecutor) -> None:
        """Spin ``executor`` (holding this node) until :meth:`request_stop`. The stop falls between
        two callbacks (the watchdog timer wakes the wait at least every 0.1 s), so no control step
        is cut short."""
        while not self._stop.is_set():
            executor.spin_once()

    def request_stop(self) -> None:
        """End :meth:`run` (safe from a signal handler)."""
        self._stop.set()

    def _warm_up(self, scene: str) -> None:
        """Import python-control and run one design at start-up (the first import takes seconds),
        so the first switch to a designed controller only pays for its own design."""
        t0 = time.monotonic()
        try:
            import control  # noqa: F401

            build_choice(scene, "lqr", {})
        except Exception as exc:  # noqa: BLE001 - only a warm-up: a real build reports its own errors
            self.get_logger().debug(f"design warm-up failed: {type(exc).__name__}: {exc}")
            return
        self.get_logger().debug(f"python-control imported and design path warmed in {time.monotonic() - t0:.2f} s")

    def _declare(self, name: str, default):
        """Declare a parameter from its spec with ``default`` (the scene's, where the spec has
        none); return its value (an override wins over the default)."""
        spec = SPECS[name]
        descriptor = ParameterDescriptor(description=spec.description, dynamic_typing=spec.dynamic_typing,
                                         read_only=spec.read_only)
        return self.declare_parameter(name, default if spec.default is None else spec.default, descriptor).value

    # --- control step ------------------------------------------------------------------------

    def _on_state(self, msg: LanderState, info=None) -> None:
        refusal = self._guard.refusal(info, lambda: self.get_publishers_info_by_topic(self._state_topic))
        if refusal is not None:  # another flight's simulator: announced once, then counted
            if refusal:
                self._refuse(refusal, self._last_stamp)
            else:
                self.slot.reject(self.slot.last_error)  # counted; the reason stays the announced one
            return
        first = self._last_state_wall is None
        self._last_state_wall = time.monotonic()
        self._paused_said = False
        if self._state_lost:
            self._state_lost = False
            if not first:  # the first state ends a start-up wait, not a loss (debug-logged only)
                self.get_logger().info(f"state received again (sequence {msg.sequence})")
        self._control_step(msg)

    def _control_step(self, msg: LanderState) -> None:
        if msg.sequence <= self.slot.last_sequence:
            # The simulator was reset (the slot resets the controller): a new flight, new figures.
            self._loop.reset()
            self._reports.reset()
        try:
            state = convert.state_view(msg, self.slot.choice.vehicle.n_thrusters)
            t0 = time.perf_counter()
            out = self.slot.step(state, msg.sequence)
            self._loop.add(state.t, time.perf_counter() - t0)
        except (convert.StateError, OutputError) as exc:
            self._refuse(str(exc), msg.header.stamp)
            self._publish_status()
            return
        except Exception as exc:  # noqa: BLE001 - a failing plug-in must not take the node down
            self._refuse(f"controller {self.slot.name!r} failed on state {msg.sequence}: {type(exc).__name__}: {exc}",
                         msg.header.stamp)
            self._publish_status()
            return
        convert.fill_throttle(self._cmd, msg, out.throttles)
        self._last_stamp = msg.header.stamp
        mode_changed = self.slot.mode != self._mode
        if not self._act_on(out, msg):  # held: the command goes out once the simulator has deployed the chute
            self._pub_throttle.publish(self._cmd)
            self._publish_status()
        # After the command (a lockstep simulator is not kept waiting): every second of sim time,
        # and at each mode change so that a bag holds the figures at every phase boundary.
        if self._reports.due(state.t) or mode_changed:
            self._publish_diagnostics(msg.header.stamp)

    def _act_on(self, out, msg: LanderState) -> bool:
        """Publish the law's mode changes and reports; ask the simulator for the parachute.

        True when a parachute deployment was requested: the throttle command is then held until
        the simulator has answered, so the chute opens before the step these throttles fly (in
        lockstep, exactly as a core-only loop does it).
        """
        stamp = msg.header.stamp
        if self.slot.mode != self._mode:
            # A change, not the first mode a law reports: that one is in /autopilot/status, and an
            # event at the very first state can go out before a recorder has discovered the topic.
            if self._mode and self.slot.mode:
                self._publish_event(FlightEvent.MODE_CHANGED, f"controller {self.slot.name!r} mode {self._mode!r} -> "
                                    f"{self.slot.mode!r}", [], stamp)
            self._mode = self.slot.mode
        held = False
        for req in getattr(out, "requests", ()):
            values = [float(v) for _, v in req.values]
            detail = req.detail + (f" [values: {', '.join(k for k, _ in req.values)}]" if req.values else "")
            if req.kind == REQUEST_LANDING_UNREACHABLE:
                self.get_logger().warning(req.detail)
                self._publish_event(FlightEvent.LANDING_UNREACHABLE, detail, values, stamp)
            elif req.kind == REQUEST_DEPLOY_PARACHUTE:
                if not self._cli_chute.service_is_ready():
                    self.get_logger().warning(f"{req.detail}: /lander/deploy_parachute is not available")
                    continue
                self.get_logger().info(req.detail)
                cmd = ThrottleCommand()
                convert.fill_throttle(cmd, msg, out.throttles)
                self._cli_chute.call_async(Trigger.Request()).add_done_callback(
                    lambda f, cmd=cmd: self._after_chute(f, cmd))
                held = True
        return held

    def _after_chute(self, future, cmd) -> None:
        """The simulator answered the deployment: log its answer, send the held command."""
        try:
            res = future.result()
            self.get_logger().info(f"parachute: {res.message}")
        except Exception as exc:  # noqa: BLE001 - a failed call must not stop the commands
            self.get_logger().warning(f"parachute deployment failed: {exc}")
        self._pub_throttle.publish(cmd)
        self._publish_status()

    # --- inputs: demand, parameters, switch service ------------------------------------------

    def _on_demand(self, msg: Float64) -> None:
        # Through the parameter so that one validation path serves topic and parameter alike;
        # a refusal is counted, logged and announced by _on_set_parameters.
        self.set_parameters([Parameter("demand_altitude", Parameter.Type.DOUBLE, float(msg.data))])

    def _on_demand_velocity(self, msg: Vector3Stamped) -> None:
        try:
            self.slot.set_demand_velocity(convert.demand_velocity(msg))
        except DemandError as exc:
            self._refuse(f"refused /lander/demand_velocity: {exc}", self._last_stamp)
            self._publish_status()
            return
        self.get_logger().info(f"demand velocity {self.slot.demand.velocity} m/s (east, north)")

    def _srv_matched(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Publishers matched by the state reader (``sub:/lander/state``, or ``sub:/lander/estimate/state``
        flying on the estimate) and subscriptions matched by
        the throttle writer (``/lander/throttle``), as the sim's ``/lander/subscribers`` says them."""
        from lander_ros.flight_span import format_matched

        response.success = True
        response.message = format_matched({f"sub:{self._state_topic}": self._sub_state.get_publisher_count(),
                                           "/lander/throttle": self._pub_throttle.get_subscription_count(),
                                           "/diagnostics": self._pub_diag.get_subscription_count()})
        return response

    def _srv_land(self, request: Trigger.Request, response: Trigger.Response):
        """Switch to the ``landing`` law with demand altitude 0 (one atomic parameter change)."""
        params = [Parameter("demand_altitude", Parameter.Type.DOUBLE, 0.0)]
        if self.slot.name != "landing":
            params += [Parameter("controller", Parameter.Type.STRING, "landing"),
                       Parameter("controller_params", Parameter.Type.STRING, "")]
        result = self.set_parameters_atomically(params)
        response.success = result.successful
        response.message = result.reason if not result.successful else f"landing with {self.slot.name!r}"
        return response

    async def _srv_switch(self, request: SwitchController.Request, response: SwitchController.Response):
        # The build (a python-control design: tens of ms) runs in a worker thread; this callback
        # waits for it as a task of the executor, which meanwhile keeps answering states.
        key = (self.get_parameter("scene").value, request.controller, request.parameters_yaml)
        try:
            self._prebuilt = (key, await _in_thread(lambda: _build_or_error(*key), self.executor.wake))
        except Exception as exc:  # noqa: BLE001 - a failing plug-in build must not take the node down
            self._prebuilt = (key, ValueError(f"building controller {request.controller!r} failed: "
                                              f"{type(exc).__name__}: {exc}"))
        old = self.slot.name
        result = self.set_parameters_atomically([
            Parameter("controller", Parameter.Type.STRING, request.controller),
            Parameter("controller_params", Parameter.Type.STRING, request.parameters_yaml),
        ])
        response.success = result.successful
        response.message = result.reason if not result.successful else f"switched {old!r} -> {self.slot.name!r}"
        response.active_controller = self.slot.name
        return response

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate a change; build a new controller completely before anything is swapped
        (or take the one the switch service built for exactly these values)."""
        self._pending = (None, None, None)
        choice = demand = timeout = None
        new = {p.name: p.value for p in params if p.name in PARAMETER_NAMES}
        try:
            if new.keys() & CONTROLLER_PARAMETERS:
                value = {n: new.get(n, self.get_parameter(n).value) for n in CONTROLLER_PARAMETERS}
                key = (value["scene"], value["controller"], value["controller_params"])
                prebuilt, self._prebuilt = self._prebuilt, None
                built = prebuilt[1] if prebuilt is not None and prebuilt[0] == key else _build_or_error(*key)
                if isinstance(built, ValueError):
                    raise built
                choice = built
            if "demand_altitude" in new:
                demand = _number(new["demand_altitude"])
                ControllerSlot.check_demand_altitude(demand)
            if "state_timeout" in new:
                timeout = check_state_timeout(new["state_timeout"])
        except ValueError as exc:
            reason = str(exc)
            self._refuse(f"refused {', '.join(sorted(new))}: {reason}", self._last_stamp)
            self._publish_status()
            return SetParametersResult(successful=False, reason=reason)
        self._pending = (choice, demand, timeout)
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        """Apply a validated change (between two control steps: one thread runs both)."""
        (choice, demand, timeout), self._pending = self._pending, (None, None, None)
        if choice is not None:
            seq = self.slot.last_sequence
            old = self.slot.swap(choice)
            self._gains_line = self._gains_text()
            self._loop.reset(keep_period=True)  # the figures are the installed controller's
            detail = (f"controller {old.name!r} -> {choice.name!r} after state {seq} "
                      f"(parameters {dump_controller_params(choice.params) or '{}'}, scene {choice.scene!r})")
            self.get_logger().info(detail)
            self._publish_event(FlightEvent.CONTROLLER_SWITCHED, detail, [float(seq)])
            self._publish_status()
        if demand is not None:
            self.slot.set_demand_altitude(demand)
            self.get_logger().info(f"demand altitude {demand} m")
        if timeout is not None:
            self._state_timeout = timeout

    # --- health --------------------------------------------------------------------------------

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        paused = sim_paused(msg)
        if paused is not None:
            self._sim_report_wall, self._sim_paused = time.monotonic(), paused

    def _watchdog(self) -> None:
        """Report a lost state stream (no command is sent without a state, so nothing unsafe goes out);
        a simulator that says it is paused has lost nothing: said once, at info level."""
        now = time.monotonic()
        since = self._last_state_wall if self._last_state_wall is not None else self._start_wall
        if now - since <= self._state_timeout:
            return
        if self._sim_paused and now - self._sim_report_wall <= PAUSED_REPORT_TIMEOUT:
            if not self._paused_said and self._last_state_wall is not None:
                self.get_logger().info("the simulator is paused: waiting for its next state")
            self._paused_said = True
            self._next_lost_report = now  # a loss after the pause is reported at once
            return
        if not self._state_lost:
            self._state_lost = True
            self._next_lost_report = now
        if now >= self._next_lost_report:
            self._next_lost_report = now + self._state_timeout
            what = "no state received yet" if self._last_state_wall is None else "state lost"
            self.slot.last_error = f"{what}: nothing on {self._state_topic} for {now - since:.1f} s; sending no commands"
            # Before the first state this is a start-up (a launcher resets the sim once all are matched):
            # in the status, not a warning at every start; a lost stream is a warning.
            (self.get_logger().warning if self._last_state_wall is not None else self.get_logger().debug)(
                self.slot.last_error)
            self._publish_status()

    def _refuse(self, reason: str, stamp) -> None:
        """Count, log (throttled) and announce a refused input; a repeated reason is announced once."""
        repeated = reason == self.slot.last_error
        count = self.slot.reject(reason)
        self.get_logger().warning(f"rejected (#{count}): {reason}", throttle_duration_sec=1.0)
        if not repeated:
            self._publish_event(FlightEvent.INPUT_REJECTED, reason, [float(count)], stamp)

    def _stamp(self, stamp=None):
        if stamp is not None:
            return stamp
        return self._last_stamp if self._last_stamp is not None else self.get_clock().now().to_msg()

    def _publish_status(self) -> None:
        s = self.slot
        last = self._last_state_wall
        state_ok = last is not None and time.monotonic() - last <= self._state_timeout
        convert.fill_status(self._status, stamp=self._stamp(), controller=s.name, saturated=s.saturated,
                            steps=s.steps, rejected=s.rejected, last_error=s.last_error, throttles=s.throttles,
                            state_ok=state_ok)
        convert.fill_demand_status(self._status, s.demand, s.mode)
        self._pub_status.publish(self._status)

    def _publish_diagnostics(self, stamp) -> None:
        """One ``DiagnosticArray``: the control loop's status, then the controller's own figures
        when its ``diagnostics()`` gives any (a failing one is reported, never raised)."""
        name = self.slot.name
        statuses = [(f"{NODE_NAME}: control", control_status(self._loop.summary(), name, self.slot.mode,
                                                             self._gains_line,
                                                             dump_controller_params(self.slot.choice.params)))]
        try:
            figures = dict(self.slot.choice.controller.diagnostics())
            own = controller_status(figures) if figures else None
        except Exception as exc:  # noqa: BLE001 - a plug-in's diagnostics must not take the node down
            own = controller_status(None, f"diagnostics() failed: {type(exc).__name__}: {exc}")
        if own is not None:
            statuses.append((f"{NODE_NAME}: {name}", own))
        convert.fill_diagnostics(self._diag, stamp=stamp, hardware_id=self.get_fully_qualified_name(),
                                 statuses=statuses)
        self._pub_diag.publish(self._diag)

    def _gains_text(self) -> str:
        """The flying law's gains in force as one line ("" for a law that names none; a failing
        ``gains()`` of a plug-in is said in the line, never raised)."""
        try:
            gains = getattr(self.slot.choice.controller, "gains", dict)()
            return format_gains(gains)
        except Exception as exc:  # noqa: BLE001 - a plug-in's gains() must not take the node down
            return f"gains() failed: {type(exc).__name__}: {exc}"

    def _publish_event(self, kind: int, detail: str, values: list[float], stamp=None) -> None:
        ev = FlightEvent()
        convert.fill_event(ev, stamp=self._stamp(stamp), kind=kind, detail=detail, values=values)
        self._pub_events.publish(ev)


    def flush(self, timeout: float = FLUSH_TIMEOUT) -> bool:
        """Wait until the subscribers acknowledged the commands, status and events published
        (before the process exits: a recorder then gets the last ones too)."""
        return flush((self._pub_throttle, self._pub_status, self._pub_events, self._pub_diag), timeout)


def _number(value) -> float:
    """A parameter value as float; refused (naming it) unless it is a number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"parameter 'demand_altitude' = {value!r} must be a number of metres")
    return float(value)


def make_executor(context=None) -> SingleThreadedExecutor:
    """The executor the node needs: one thread; a switch's build runs in a worker (:func:`_in_thread`)."""
    return SingleThreadedExecutor(context=context)


def _build_or_error(scene: Any, controller: Any, params_text: Any) -> Any:
    """The controller choice for these parameter values, or the ValueError that refuses them."""
    try:
        return build_choice(check_string("scene", scene), check_string("controller", controller),
                            parse_controller_params(params_text))
    except ValueError as exc:
        return exc


def _in_thread(work: Callable[[], Any], wake: Callable[[], None]) -> Future:
    """Run ``work`` in a new daemon thread; an rclpy Future (awaitable in a callback) of its
    result, or of its exception. ``wake`` (the executor's) is called when it is done: the
    executor resumes the awaiting callback on its next pass, and nothing else may wake it."""
    future: Future = Future()

    def run() -> None:
        try:
            future.set_result(work())
        except Exception as exc:  # noqa: BLE001 - handed to the awaiting callback
            future.set_exception(exc)
        wake()

    threading.Thread(target=run, name="controller-build", daemon=True).start()
    return future


def main(argv: list[str] | None = None) -> int:
    """Entry point ``autopilot_node``: build the node and run it until Ctrl-C or SIGTERM."""
    argv = sys.argv if argv is None else argv
    return run_node_process("autopilot_node", argv, lambda: AutopilotNode(argv), make_executor)


if __name__ == "__main__":
    sys.exit(main())

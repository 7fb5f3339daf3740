"""``lander_sim``: the ROS 2 simulation node, a thin shell around :class:`lander_sim.simulation.Simulation`.

Run (project venv, no ROS install needed)::

    ./dev exec sim_node                                   # default parameters
    ./dev exec sim_node --ros-args --params-file config/sim.yaml -p scene:=hover -p speed:=20.0
    ./dev exec python -m lander_sim.node --ros-args -p speed:=0.0 -p lockstep:=true

On a full ROS 2 install: ``ros2 run mars_lander sim_node --ros-args --params-file config/sim.yaml``.

One control tick (at ``publish_rate`` of sim time, paced to the wall clock at
``speed``)::

    [lockstep gate] -> staleness check -> Simulation.step(k) -> events -> publish
    (/clock, /lander/state, odometry, pose, TF, markers, events)

A scene with sensors steps one physics step at a time and publishes each sensor's measurements
as they fall due (``lander_sim.ros.sensor_out``).

Whether a tick may run and what pause, resume, step and the end do is decided by the gate
(``lander_sim.ros.gate``, plain Python): the node feeds it every event and does what it answers.
What an instant publishes, and the count of each topic's messages that ``FLIGHT_ENDED`` carries,
is :class:`lander_sim.ros.outputs.SimOutputs`'s: the node creates the publishers and says when.

No physics and no control law here: messages, parameters, services and time are
translated to and from the core (see docs/sim_node.md).
"""
from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from visualization_msgs.msg import MarkerArray

from lander_interfaces.msg import FlightEvent, LanderState, ThrottleCommand
from lander_ros.delivery import (
    FLUSH_TIMEOUT,
    OUTPUT_QOS,
    events_executor,
    flush,
    run_node_process,
)
from lander_ros.flight_span import FlightEnd, parse_end_on
from lander_ros.params import check_overrides
from lander_ros.strangers import STRANGER_KIND, InputGuard, with_message_info
from lander_sim.errors import InputError
from lander_sim.ros import convert
from lander_sim.ros.command_hold import CommandHold
from lander_sim.ros.config import (
    NODE_NAME,
    PARAMETERS,
    SCENE_SEED,
    SPECS,
    ConfigError,
    check_change,
    check_parameter,
)
from lander_sim.ros.diagnostics import NodeHealth, diagnostics_array
from lander_sim.ros.gate import Gate, GateSettings, Mode, Publish, TickOutcome
from lander_sim.ros.outputs import SimOutputs
from lander_sim.ros.pacing import Pacer, steps_per_tick
from lander_sim.ros.sensor_out import SensorOutputs
from lander_sim.ros.services import SimServices
from lander_sim.ros.sim_adapter import SimAdapter, build_simulation

try:  # TF only on a full ROS 2 install (tf2_ros is not on PyPI).
    from tf2_ros import TransformBroadcaster
except ImportError:  # pragma: no cover - depends on the install
    TransformBroadcaster = None

#: Queue depth of the input topics: large enough that a burst of commands is counted, not dropped.
_INPUT_QOS = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: Wall time between executor passes while ticks are due back to back (speed 0 or catching up) [s].
#: One idle pass of the EventsExecutor costs ~70 us (measured), a tick ~150 us, so passing after every
#: tick would cost a third of the speed; a pass drains everything pending (see _serve), so a
#: request waits at most this long plus one tick.
_BUSY_SPIN_INTERVAL = 0.001
#: Most executor passes in one drain (a flood of inputs must not stall the simulation).
_MAX_DRAIN_PASSES = 50
#: Longest wall time the loop blocks in the executor while idle (paused / waiting), so diagnostics keep flowing.
_IDLE_WAIT = 0.05


class SimNode(Node):
    """The simulation node. Build it, then call :meth:`run` with an executor."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        for spec in PARAMETERS:
            self.declare_parameter(
                spec.name,
                spec.default,
                ParameterDescriptor(description=spec.description, read_only=spec.read_only),
            )
        for spec in PARAMETERS:  # overrides (command line / params file) are checked like any later change
            reason = check_parameter(spec.name, self.get_parameter(spec.name).value)
            if reason is not None:
                raise ConfigError(reason)

        self.health = NodeHealth()
        self._hold = CommandHold()  # the held throttle command and its age limit (command_timeout)
        #: Running, paused, held at pause_at, awaiting the lockstep answer or ended (lander_sim.ros.gate):
        #: the node feeds it every event and advances or publishes only as it answers.
        self.gate = Gate(self._gate_settings(), start_paused=bool(self._param("start_paused")))
        self._seq = 0  # sequence of the last state published since the last reset
        #: The flight's number: 0 the node's first, one more at each reset or scene load. In
        #: /diagnostics and the pause answer, so a recorder can drop a wall-paced report sent before
        #: the reset it awaits (lander_tools.whole_flight).
        self.flight = 0
        self._callbacks = 0  # callbacks run so far (the drain loop watches it)
        self._next_diag_wall = time.monotonic()
        self._stop_requested = False  # set by request_stop() (a signal handler): run() returns
        self._timeouts_at_reset = 0  # health.lockstep_timeouts at the flight's reset (FLIGHT_ENDED counts this flight's)

        self.sim: SimAdapter = self.load(self._param("scene"))
        self._k = steps_per_tick(self.sim.dt, self._param("publish_rate"))
        self.pacer = Pacer(self._param("speed"), self._k * self.sim.dt)

        def output(cls, topic: str):
            return self.create_publisher(cls, topic, OUTPUT_QOS)

        #: What goes out, filled and counted (lander_sim.ros.outputs): this node only creates the publishers.
        self.out = SimOutputs(
            clock=output(Clock, "/clock"), state=output(LanderState, "/lander/state"),
            odom=output(Odometry, "/lander/odom"), pose=output(PoseStamped, "/lander/pose"),
            markers=output(MarkerArray, "/lander/markers"),
            events=self.create_publisher(FlightEvent, "/lander/events", QoSProfile(depth=1000)),
            diagnostics=output(DiagnosticArray, "/diagnostics"),
            tf=TransformBroadcaster(self) if TransformBroadcaster is not None else None,
            sensors=SensorOutputs(output), trajectory_length=self._param("trajectory_length"))
        self._cache_parameters()
        self._set_sensors()

        c = self._counted
        # A launched flight's simulator takes throttles only from the flight's nodes (lander_ros.strangers).
        self._guard = InputGuard(bool(self._param("flight_id")), tuple(self._param("flight_nodes").split()))
        self._inputs = (
            self.create_subscription(ThrottleCommand, "/lander/throttle", with_message_info(c(self._on_throttle)),
                                     _INPUT_QOS),
            self.create_subscription(Vector3Stamped, "/lander/wind", c(self._on_wind), _INPUT_QOS),
        )

        self.service_handlers = SimServices(self)
        for srv_type, name, handler in self.service_handlers.table():
            self.create_service(srv_type, name, c(handler))

        # Parameter changes are taken only now that everything they act on exists.
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)

        if self.gate.mode is Mode.RUNNING:
            self._publish_outputs()  # state 1 at t = 0: the controller's first question in lockstep
        # Started paused: state 1 goes out with the first reset, resume or step (never twice).
        self.get_logger().info(
            f"scene {self.sim.scene.name!r}: dt {self.sim.dt} s, {self._k} steps per tick, "
            f"speed {self._param('speed')}, lockstep {self._param('lockstep')}, paused {self.gate.mode.paused}"
        )

    # --- main loop ---------------------------------------------------------------------------

    def run(self, executor: SingleThreadedExecutor) -> None:
        """Serve callbacks and advance the simulation until shutdown (the node's own loop).

        A dedicated loop rather than a ROS timer: the node's clock is the wall
        clock (it is the source of sim time, so never uses it), and at speed 0 it
        must run as fast as possible while still serving inputs between ticks.
        """
        last_spin = 0.0
        while self.context.ok() and not self._stop_requested:
            wait = self._loop_once()
            now = time.monotonic()
            # Running flat out an executor pass costs about half a tick (~70 us measured): serve
            # inputs every _BUSY_SPIN_INTERVAL rather than after every tick. Waiting (pacing,
            # lockstep, paused) always serves them.
            if wait > 0.0 or now - last_spin >= _BUSY_SPIN_INTERVAL:
                try:
                    self._serve(executor, wait)
                except Exception:
                    if not self.context.ok():
                        break  # shut down from outside (Ctrl-C) while in the executor
                    raise
                last_spin = now

    def request_stop(self) -> None:
        """Make :meth:`run` return after the current pass (safe to call from a signal handler)."""
        self._stop_requested = True

    def flush(self, timeout: float = FLUSH_TIMEOUT) -> bool:
        """Wait until the subscribers acknowledged every output published (before the process exits)."""
        return flush(self.out.publishers, timeout)

    def _serve(self, executor, wait: float) -> None:
        """One executor pass (blocking up to ``wait`` s), then drain whatever else is pending.

        An executor pass runs at most one callback, so a single pass per loop would let a
        burst of inputs (commands, wind) delay a service request by many control periods;
        passes repeat while they run callbacks (bounded), so every pending service, parameter
        change and command is handled before the next tick.
        """
        before = self._callbacks
        executor.spin_once(timeout_sec=wait)
        passes = 1
        while self._callbacks != before and passes < _MAX_DRAIN_PASSES and self.context.ok():
            before = self._callbacks
            executor.spin_once(timeout_sec=0.0)
            passes += 1

    def _counted(self, callback):
        """``callback`` counting its calls, so :meth:`_serve` knows a pass did work."""

        def run(*args):
            self._callbacks += 1
            return callback(*args)

        return run

    def _loop_once(self) -> float:
        """Advance one tick if one is due; return how long the executor may block [s]."""
        now = time.monotonic()
        mode = self.gate.mode
        # After the end nothing more (its counts are final); before the first flight only if asked.
        if (now >= self._next_diag_wall and mode is not Mode.ENDED
                and (mode is not Mode.NOT_STARTED or self._param("idle_diagnostics"))):
            self._publish_diagnostics(now)
        if now >= self.out.next_subscriber_check:
            self.check_subscribers(now)
        poll = self.gate.poll(now, self.sim.t)
        if poll.timed_out:
            self.health.lockstep_timeouts += 1
            self.get_logger().warning(
                f"lockstep: no answer to state {poll.timed_out} within {self.gate.settings.lockstep_timeout} s; advancing",
                throttle_duration_sec=1.0,
            )
        if not poll.advance:
            return min(_IDLE_WAIT, poll.wait)
        wait = self.pacer.wait_time(self.sim.t + self._k * self.sim.dt)
        if wait > 0.0:
            return min(wait, _IDLE_WAIT)
        self._tick(self._k, may_pause=True)
        return 0.0

    def _tick(self, n_steps: int, may_pause: bool = False) -> None:
        """The pipeline of one control period: staleness -> physics -> publish what the gate answers.

        The end instant publishes its state, then the end (an end wins over a pause there). With
        ``may_pause`` (the running loop) a tick reaching ``pause_at`` publishes /clock but
        holds the state back and pauses: whoever drives the timeline acts at exactly this instant
        (inputs take effect from the step leaving it, and a controller's answer to this state
        already sees them); resume then publishes the state.
        """
        self._check_staleness()
        w0 = time.perf_counter()
        if self.out.sensors.on:  # one step at a time: the sensors sample the truth over each
            self.sim.step_each(n_steps, self.out.sensors_after_step)
        else:
            self.sim.step(n_steps)
        self.health.step_wall_s += time.perf_counter() - w0
        self.health.physics_steps += n_steps
        self.health.ticks += 1
        sim = self.sim
        outcome = self.gate.ticked(sim.t, None if sim.flying else sim.phase_name, honour_pause_at=may_pause)
        if outcome is TickOutcome.END:
            self._publish_outputs()
            self._end_flight(str(self.gate.end_reason))
            return
        if outcome is TickOutcome.HOLD:
            self.out.clock(self.sim.t)
            self.publish_core_events()
            # Debug only: a launcher pauses here at every timeline action, so at info level it would flood the log.
            self.get_logger().debug(f"paused at t = {self.sim.t!r} s (pause_at); its state follows on resume")
            return
        self._publish_outputs()

    def _set_sensors(self) -> None:
        """The current scene's sensors at switch-on, their publishers, and the flight's counts from zero."""
        self.out.set_sensors(self.sim.scene.sensors, self.sim.seed)

    def _end_flight(self, reason: str) -> None:
        """Stop at the end instant (its state is out): a last /diagnostics, then FLIGHT_ENDED with the
        counts of everything published since the reset and of the lockstep timeouts in this flight
        (lander_ros.flight_span), then nothing
        more until a reset; so a recording ends here whatever its launcher does next."""
        self._publish_diagnostics(time.monotonic())
        counts = self.out.counts
        counts["/lander/events"] += 1  # the FLIGHT_ENDED itself
        end = FlightEnd(self.sim.t, reason, dict(counts), self.health.lockstep_timeouts - self._timeouts_at_reset)
        counts["/lander/events"] -= 1  # _publish_event counts it again
        self._publish_event(FlightEvent.FLIGHT_ENDED, end.detail(), end.values())
        self.get_logger().debug(end.detail())

    def advance(self, n_steps: int, stop_on_touchdown: bool = False) -> None:
        """Advance ``n_steps`` physics steps now (services), publishing at every tick boundary; the
        held command flies them all (nobody can answer inside the call) and is not aged by them."""
        self._hold.step_begins(self.sim.t)
        try:
            while n_steps > 0:
                k = min(self._k, n_steps)
                self._tick(k)
                n_steps -= k
                if self.gate.mode is Mode.ENDED or (stop_on_touchdown and not self.sim.flying):
                    break
        finally:
            self._hold.step_ends(self.sim.t)
        self.pacer.restart()

    def _check_staleness(self) -> None:
        """Zero-order hold with a staleness limit in sim time; zero throttles once it is exceeded."""
        age, limit = self._hold.expired(self.sim.t), self._hold.timeout
        if age is not None:
            self.health.stale_commands += 1
            self.sim.zero_throttles()
            detail = f"throttle command is {age:.3f} s old (limit command_timeout = {limit} s): throttles set to 0"
            self.get_logger().warning(detail, throttle_duration_sec=1.0)
            self._publish_event(FlightEvent.COMMAND_STALE, detail, [age, limit])

    # --- outputs -----------------------------------------------------------------------------

    def _publish_outputs(self, clock: bool = True) -> None:
        """Publish the current instant: one state per sim time, with the next sequence number.

        Callers publish only after the simulation advanced or after a reset/scene load, so within
        one reset epoch sequences and stamps both strictly increase (docs/sim_node.md).
        ``clock=False``: /clock already shows this instant (a state held back at ``pause_at``).
        """
        snap = self.sim.readout()
        out = self.out
        if clock:
            out.clock(snap.t)
        self._seq += 1
        if self._seq == 1:  # the flight's first instant, t = 0: the sensors' first samples
            out.sensors_at_start(self.sim.sim)
        out.fill_state(self._seq, snap)
        now = time.monotonic()
        self.health.state_published(self._seq, now)
        out.publish_state()
        self.gate.published(self._seq, now)
        out.views(snap, self.sim.vehicle, now)
        self.publish_core_events()

    def publish_pending(self, what: Publish) -> None:
        """Publish what the gate answered: the current instant's state when it is not out yet."""
        if what is not Publish.NOTHING:
            self._publish_outputs(clock=what is Publish.STATE_AND_CLOCK)

    def check_subscribers(self, now: float) -> None:
        """Re-read who listens to the optional outputs (a graph query per tick would cost ~7 us)."""
        self.out.check_subscribers(now)

    def publish_core_events(self) -> None:
        for event in self.sim.drain_events():
            name, detail, values = convert.event_fields(event)
            self._publish_event(getattr(FlightEvent, name), detail, values, t=event.t)

    def _publish_event(self, kind: int, detail: str, values, t: float | None = None) -> None:
        self.out.event(kind, detail, values, self.sim.t if t is None else t)

    def report_now(self) -> None:
        """A /diagnostics report now (the pause service: ``paused`` is news to the flight's watchers)."""
        self._publish_diagnostics(time.monotonic())

    def _publish_diagnostics(self, now: float) -> None:
        self._next_diag_wall = now + 1.0 / self._param("diagnostics_rate")
        self.health.update_rtf(self.sim.t, now)
        extra = self.sim.health_values() | {
            "sim_time": repr(self.sim.t),
            "paused": str(self.gate.mode.paused),
            "steps_per_tick": str(self._k),
            "flight": str(self.flight),
            "pacer_overruns": str(self.pacer.overruns),
            # Matched by this node's writer (not just seen in the graph): a start-up handshake
            # can wait for it, so the first state reaches everyone (test/reliability).
            "state_subscribers": str(self.out.state_subscribers),
            # The mean wind in force [m/s, world frame], x y z: what a live view shows.
            "mean_wind_W": " ".join(repr(float(v)) for v in self.sim.mean_wind_W),
        }
        self.out.diagnostics(diagnostics_array(self.health, t=self.sim.t, name=f"{NODE_NAME}: simulation",
                                               hardware_id=self.sim.scene.name, extra=extra))

    # --- inputs ------------------------------------------------------------------------------

    def reject(self, kind: str, detail: str) -> None:
        """Count, log (throttled) and announce one rejected input; the simulation is untouched."""
        count = self.health.reject(kind)
        self.get_logger().warning(f"rejected {kind} (#{count}): {detail}", throttle_duration_sec=1.0)
        self._publish_event(FlightEvent.INPUT_REJECTED, f"{kind}: {detail}", [float(count)])

    def _on_throttle(self, msg: ThrottleCommand, info=None) -> None:
        refusal = self._guard.refusal(info, lambda: self.get_publishers_info_by_topic("/lander/throttle"))
        if refusal is not None:  # a stranger's: announced once, then counted
            if refusal:
                self.reject(STRANGER_KIND, refusal)
            else:
                self.health.reject(STRANGER_KIND)
            return
        values = msg.throttles
        try:
            self.sim.set_throttles(values)
        except InputError as exc:
            self.reject("throttle." + convert.throttle_fault(values, self.sim.vehicle.n_thrusters), str(exc))
            return
        self.health.commands_accepted += 1
        self._hold.accepted(self.sim.t)
        if msg.state_sequence != 0:
            self.health.command_received(msg.state_sequence, time.monotonic())
            self.gate.answered(msg.state_sequence)

    def _on_wind(self, msg: Vector3Stamped) -> None:
        frame = msg.header.frame_id
        if frame not in ("", self.out.world_frame):
            self.reject("wind.frame", f"header.frame_id {frame!r}: wind must be given in {self._param('world_frame')!r}")
            return
        try:
            self.sim.set_wind(convert.vector3_to_array(msg.vector))
        except InputError as exc:
            self.reject("wind.non_finite", str(exc))
            return
        self.report_now()  # the wind in force is news to a live view

    # --- what the services read ---------------------------------------------------------------

    @property
    def steps_per_tick(self) -> int:
        """Physics steps in one control tick (``publish_rate`` of sim time)."""
        return self._k

    def matched(self) -> dict[str, int]:
        """Subscriptions matched by each output's writer, and publishers matched by each input's
        reader as ``sub:TOPIC`` (lander_ros.flight_span.format_matched)."""
        matched = {p.topic_name: p.get_subscription_count() for p in self.out.publishers}
        matched.update({f"sub:{s.topic_name}": s.get_publisher_count() for s in self._inputs})
        return matched

    # --- parameters and scene ----------------------------------------------------------------

    def _param(self, name: str):
        return self.get_parameter(name).value

    def _cache_parameters(self) -> None:
        """Parameters read every tick, as attributes (``get_parameter`` costs ~3 us a call, measured)."""
        self._hold.timeout = float(self._param("command_timeout"))
        self.out.publish_tf = bool(self._param("publish_tf"))
        self.out.marker_period = 1.0 / float(self._param("marker_rate"))
        self.out.set_frames(str(self._param("world_frame")), str(self._param("body_frame")))

    def _gate_settings(self) -> GateSettings:
        """The parameters the gate reads (lockstep, pause_at, the end)."""
        return GateSettings(
            lockstep=bool(self._param("lockstep")),
            lockstep_timeout=float(self._param("lockstep_timeout")),
            pause_at=float(self._param("pause_at")),
            end_time=float(self._param("end_time")),
            end_on=parse_end_on(self._param("end_on")),
        )

    def set_parameters(self, parameter_list):
        """rclpy's ``set_parameters``, with every refused parameter counted and announced."""
        results = super().set_parameters(parameter_list)  # raises on an undeclared name (counted below)
        for param, result in zip(parameter_list, results):
            if not result.successful:
                self._reject_parameters([param], result.reason)
        return results

    def set_parameters_atomically(self, parameter_list):
        """rclpy's ``set_parameters_atomically`` (what the parameter services call), with a refusal
        counted and announced like any other bad input: our validation, a read-only or wrongly
        typed value, or an undeclared name (rclpy's own checks, which run before our callback)."""
        try:
            result = super().set_parameters_atomically(parameter_list)
        except ParameterNotDeclaredException as exc:
            self._reject_parameters(parameter_list, str(exc))
            raise
        if not result.successful:
            self._reject_parameters(parameter_list, result.reason)
        return result

    def _reject_parameters(self, params, reason: str) -> None:
        """One rejection per refused request, of kind ``parameter.<name>`` (``parameter.undeclared``
        for a name the node does not have: the kinds in the diagnostics stay a bounded set)."""
        self._callbacks += 1
        name = params[0].name if params else ""
        self.reject(f"parameter.{name if self.has_parameter(name) else 'undeclared'}", reason)

    def _on_set_parameters(self, params) -> SetParametersResult:
        self._callbacks += 1
        for p in params:
            reason = check_change(p.name, p.value)
            if reason is not None:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params) -> None:
        names = {p.name for p in params}
        self._cache_parameters()
        self.gate.parameters_changed(self._gate_settings(), names)  # re-arms pause_at; lockstep waits anew
        if names & {"publish_rate"}:
            self._k = steps_per_tick(self.sim.dt, self._param("publish_rate"))
            self.pacer.set_period(self._k * self.sim.dt)
        if "speed" in names:
            self.pacer.set_speed(self._param("speed"))
        if "stabiliser" in names:
            self.apply_stabiliser(self.sim)

    def apply_stabiliser(self, sim: SimAdapter) -> None:
        choice = self._param("stabiliser")
        if choice != "scene":
            sim.set_stabiliser(choice == "on")

    def load(self, name: str) -> SimAdapter:
        """Build the simulation of scene ``name`` with this node's overrides (integrator, dt, threshold, seed)."""
        sim = build_simulation(
            name,
            integrator=self._param("integrator") or None,
            dt=self._param("dt") or None,
            gimbal_threshold=self._param("gimbal_threshold") or None,
            seed=None if self._param("seed") == SCENE_SEED else self._param("seed"),
        )
        self.apply_stabiliser(sim)
        return sim

    def start_flight(self) -> None:
        """Node-side state that follows a reset or a new scene: sequence, held command, trajectory.

        The sequence restarts: the reset instant is published as state 1 (a new epoch; a
        controller sees the sequence fall and clears its memory).
        """
        self._seq = 0
        self.flight += 1
        pending = self.gate.reset()  # running stays running; paused, held or ended: paused
        self._set_sensors()  # a new flight: its sensors at switch-on, its counts start here
        self._timeouts_at_reset = self.health.lockstep_timeouts
        self.check_subscribers(time.monotonic())  # state 1 goes to every output someone listens to
        self.health.forget_published()
        self._hold.clear()
        self._k = steps_per_tick(self.sim.dt, self._param("publish_rate"))
        self.pacer.set_period(self._k * self.sim.dt)
        self.out.clear_trajectory()
        self.health.restart_window(self.sim.t)
        self.publish_pending(pending)


def main(argv: list[str] | None = None) -> int:
    """Entry point ``sim_node``: build the node and run it until Ctrl-C or shutdown."""
    argv = sys.argv if argv is None else argv
    try:
        # rcl would ignore an unknown name without a word: every override is checked first
        check_overrides(SPECS, argv, NODE_NAME, ConfigError)
    except ConfigError as exc:
        print(f"sim_node: {exc}", file=sys.stderr)
        return 2
    return run_node_process("sim_node", argv, SimNode, events_executor)


if __name__ == "__main__":
    sys.exit(main())

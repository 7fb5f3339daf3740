"""``lander_estimator``: the ROS 2 estimator node, a thin shell around the core's navigation filter.

Run (project venv)::

    python -m lander_autopilot.estimator_node --ros-args -p scene:=landing-sensors
    lander fly landing-sensors --estimate          # beside the sim, the autopilot flying on it

It subscribes to the sensor topics of its scene (``/lander/sensors/*``, docs/sim_node.md) and to
the simulator's ``/lander/state`` (the control ticks: their stamp and sequence, and the fields the
lander knows of itself without navigating: mass, fuel, throttles, phase), and runs one
:class:`lander_autopilot.estimation.ekf.NavFilter` through
:class:`lander_autopilot.estimation.ticks.TickFeeder`, the object the core tests run. Per control
tick ``k``, once every reading the sensors' schedule says tick ``k`` brings is in::

    readings of (t_(k-1), t_k] -> TickFeeder.advance (propagate, update) -> /lander/estimate/odometry
                                                                          -> /lander/estimate/state

both stamped ``t_k`` and the state with the simulator's sequence ``k``, so an autopilot with
``state_source: estimate`` answers it as it answers ``/lander/state`` and a lockstep simulator
waits for that answer as usual. Which readings a tick brings is a function of the scene (the
schedule), not of the order messages of different topics arrive in: the estimate is the same bits
whatever DDS does.

The filter starts at a flight's first state (sequence 1, ``t = 0``): at that truth plus an error
drawn from the initial sigmas with ``seed`` (:func:`lander_autopilot.estimation.flights.start_filter`,
the handover from an approach solution). A state whose sequence does not increase is a reset: the
filter starts again at the next first state. A bad reading is refused by the filter, counted and
logged in one line; the node flies on. No filter mathematics here.
"""
from __future__ import annotations

import sys
import threading
import time
from collections import deque
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, Range
from std_srvs.srv import Trigger

from lander_autopilot.estimation.flights import initial_covariance, initial_error_rng, start_filter
from lander_autopilot.estimation.ticks import TickFeeder
from lander_autopilot.ros import estimator_convert as convert
from lander_autopilot.ros.estimator_config import (
    NODE_NAME,
    ODOMETRY_TOPIC,
    SCENE_SEED,
    SPECS,
    STATE_TOPIC,
    ConfigError,
    initial_sigma,
)
from lander_interfaces.msg import LanderState
from lander_ros.delivery import FLUSH_TIMEOUT, OUTPUT_QOS, flush, run_node_process
from lander_ros.flight_span import SENSOR_KEYS, SENSOR_TOPICS, format_matched
from lander_ros.params import check_overrides
from lander_ros.strangers import InputGuard, with_message_info
from lander_sim.scenes import load_scene

#: Every message of a flight is needed (a lost reading would stall its tick): a deep reliable queue.
_INPUT_QOS = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: Wall seconds between two reports of a tick still waiting for its readings.
_WAIT_REPORT = 5.0


class EstimatorNode(Node):
    """The estimator node (module docstring). Build it, then spin it in :func:`make_executor`'s executor."""

    def __init__(self, argv: list[str] | None = None, **kwargs: Any) -> None:
        check_overrides(SPECS, sys.argv if argv is None else argv, NODE_NAME, ConfigError)
        super().__init__(NODE_NAME, **kwargs)
        values = {name: self._declare(name) for name in SPECS}
        scene = load_scene(values["scene"])
        if scene.sensors is None or "imu" not in scene.sensors:
            raise ConfigError(f"parameter 'scene' = {values['scene']!r}: the scene switches no IMU on "
                              "(sensors.imu): the filter propagates on it")
        g = scene.models.get("gravity")
        if g is None or g.kind != "inverse-square":
            raise ConfigError(f"parameter 'scene' = {values['scene']!r}: the filter's gravity model needs "
                              "models.gravity.kind: inverse-square")
        self._gm, self._radius = float(g.gm), float(g.radius)
        self._sensors = scene.sensors
        self._seed = scene.sensors.seed if values["seed"] == SCENE_SEED else int(values["seed"])
        self._P0 = initial_covariance(scene.sensors, initial_sigma(values))
        self._gimbal_threshold = float(scene.gimbal_threshold)
        self.feeder = TickFeeder(scene.sensors)
        self._guard = InputGuard(bool(values["flight_id"]), ("/lander_sim",), "/lander/state", verbs=False)

        self._pub_odom = self.create_publisher(Odometry, ODOMETRY_TOPIC, OUTPUT_QOS)
        self._pub_state = self.create_publisher(LanderState, STATE_TOPIC, OUTPUT_QOS)
        self._sub_state = self.create_subscription(LanderState, "/lander/state", with_message_info(self._on_state),
                                                   _INPUT_QOS)
        types = {"imu": Imu, "star_tracker": PoseWithCovarianceStamped, "altimeter": Range,
                 "doppler": TwistWithCovarianceStamped, "ground_fix": Odometry}  # docs/sim_node.md, "Sensors"
        self._subs = {}
        self._sensor_guards = {}
        for key, topic in zip(SENSOR_KEYS, SENSOR_TOPICS):
            if key in scene.sensors:
                self._sensor_guards[key] = InputGuard(self._guard.active, ("/lander_sim",), topic, verbs=False)
                self._subs[topic] = self.create_subscription(types[key], topic, with_message_info(self._reader(key)),
                                                             _INPUT_QOS)
        self.create_service(Trigger, "/lander_estimator/matched", self._srv_matched)

        self._ticks: deque[Any] = deque()  # the simulator's states not yet answered with an estimate
        self._last_sequence = 0
        self._waiting_since: float | None = None
        self._next_wait_report = 0.0
        self.estimates = 0
        self.refused = 0  # states and readings refused (strangers, non-increasing stamps)
        self._state_msg = LanderState()
        self._odom_msg = Odometry()
        self._odom_msg.header.frame_id = "mars"
        self._odom_msg.child_frame_id = "base_link"
        self._stop = threading.Event()
        self.create_timer(1.0, self._watchdog, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(f"estimating for scene {scene.name!r}: sensors {', '.join(scene.sensors.sections)}; "
                               f"initial-error seed {self._seed}")

    def _declare(self, name: str) -> Any:
        spec = SPECS[name]
        descriptor = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
        value = self.declare_parameter(name, spec.default, descriptor).value
        reason = spec.check(value)
        if reason is not None:
            raise ConfigError(f"parameter {name!r} = {value!r} {reason}")
        return value

    def run(self, executor: SingleThreadedExecutor) -> None:
        """Spin ``executor`` until :meth:`request_stop`."""
        while not self._stop.is_set():
            executor.spin_once(timeout_sec=0.5)

    def request_stop(self) -> None:
        """End :meth:`run` (safe from a signal handler)."""
        self._stop.set()

    def flush(self, timeout: float = FLUSH_TIMEOUT) -> bool:
        """Wait until the subscribers acknowledged the estimates published."""
        return flush((self._pub_odom, self._pub_state), timeout)

    # --- inputs --------------------------------------------------------------------------------

    def _reader(self, key: str):
        guard, topic = self._sensor_guards[key], dict(zip(SENSOR_KEYS, SENSOR_TOPICS))[key]

        def on_message(msg: Any, info: Any = None) -> None:
            refusal = guard.refusal(info, lambda: self.get_publishers_info_by_topic(topic))
            if refusal is not None:  # another flight's simulator: said once, then counted
                self.refused += 1
                if refusal:
                    self.get_logger().warning(refusal)
                return
            self.feeder.add(convert.reading(key, msg))
            self._answer()
        return on_message

    def _on_state(self, msg: LanderState, info: Any = None) -> None:
        refusal = self._guard.refusal(info, lambda: self.get_publishers_info_by_topic("/lander/state"))
        if refusal is not None:
            self.refused += 1
            if refusal:
                self.get_logger().warning(refusal)
            return
        if msg.sequence <= self._last_sequence:  # a reset: a new flight from its first state
            self.get_logger().info(f"state {msg.sequence} after {self._last_sequence}: the flight was reset")
            self.feeder.restart()
            self._ticks.clear()
        self._last_sequence = msg.sequence
        if self.feeder.filter is None:
            if msg.sequence != 1:
                self.refused += 1
                self.get_logger().warning(f"state {msg.sequence}: waiting for a flight's first state (sequence 1) "
                                          "to start the filter", throttle_duration_sec=5.0)
                return
            p, v, o = msg.position, msg.velocity, msg.orientation
            self.feeder.start(start_filter(
                self._sensors, np.array((p.x, p.y, p.z)), np.array((v.x, v.y, v.z)), np.array((o.w, o.x, o.y, o.z)),
                convert.stamp_ns(msg.header.stamp) * 1e-9, self._P0, initial_error_rng(self._seed), self._gm,
                self._radius))
        self._ticks.append(msg)
        self._answer()

    # --- the tick ------------------------------------------------------------------------------

    def _answer(self) -> None:
        """Publish the estimate of every tick whose readings are all in, oldest first."""
        while self._ticks:
            truth = self._ticks[0]
            t_ns = convert.stamp_ns(truth.header.stamp)
            if not self.feeder.ready(t_ns):
                if self._waiting_since is None:
                    self._waiting_since = time.monotonic()
                return
            self._ticks.popleft()
            self._waiting_since = None
            rejected, unexpected = self.feeder.rejected, self.feeder.unexpected
            self.feeder.advance(t_ns)
            if self.feeder.rejected > rejected:
                self.get_logger().warning(f"reading refused (#{self.feeder.rejected}): {self.feeder.last_error}",
                                          throttle_duration_sec=1.0)
            if self.feeder.unexpected > unexpected:
                self.get_logger().warning(f"reading dropped (#{self.feeder.unexpected}): its stamp is no due instant "
                                          f"of its sensor in state {truth.sequence}'s tick", throttle_duration_sec=1.0)
            est = self.feeder.estimate()
            convert.fill_state(self._state_msg, truth, est, self._gimbal_threshold)
            self._pub_state.publish(self._state_msg)
            assert self.feeder.filter is not None
            convert.fill_odometry(self._odom_msg, truth, est, self.feeder.filter, self.feeder.omega_var)
            self._pub_odom.publish(self._odom_msg)
            self.estimates += 1

    def _watchdog(self) -> None:
        """Say (every few seconds) which tick waits for readings that have not come."""
        since = self._waiting_since
        now = time.monotonic()
        if since is None or now - since < _WAIT_REPORT or now < self._next_wait_report:
            return
        self._next_wait_report = now + _WAIT_REPORT
        tick = self._ticks[0] if self._ticks else None
        if tick is not None:
            held = ", ".join(f"{k} {len(q)}" for k, q in self.feeder.queues.items())
            self.get_logger().warning(
                f"state {tick.sequence}: its sensor readings are not all in after {now - since:.0f} s "
                f"(readings held: {held}); no estimate until they are")

    def _srv_matched(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Publishers matched by the state and sensor readers (``sub:TOPIC``), subscriptions matched by
        the estimate writers (as the sim's ``/lander/subscribers`` says them)."""
        counts = {"sub:/lander/state": self._sub_state.get_publisher_count()}
        counts.update({f"sub:{t}": s.get_publisher_count() for t, s in self._subs.items()})
        counts[STATE_TOPIC] = self._pub_state.get_subscription_count()
        counts[ODOMETRY_TOPIC] = self._pub_odom.get_subscription_count()
        response.success = True
        response.message = format_matched(counts)
        return response


def make_executor(context: Any = None) -> SingleThreadedExecutor:
    """The executor the node needs: one thread."""
    return SingleThreadedExecutor(context=context)


def main(argv: list[str] | None = None) -> int:
    """Entry point: build the node and run it until Ctrl-C or SIGTERM."""
    argv = sys.argv if argv is None else argv
    return run_node_process("estimator_node", argv, lambda: EstimatorNode(argv), make_executor)


if __name__ == "__main__":
    sys.exit(main())

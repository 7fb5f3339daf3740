"""The simulator's outputs: what one instant publishes, and how many messages went out per topic
(docs/sim_node.md, "One tick" and "A flight's span").

An instant the node publishes goes out as ``/clock``, ``/lander/state``, then, only while someone
subscribes (the counts re-read every :data:`SUBSCRIBER_CHECK_PERIOD` of wall time, a graph query per
tick would cost ~7 us), ``/lander/odom``, ``/lander/pose`` and the markers (at most ``marker_rate``
Hz of wall time), and the ``mars -> base_link`` transform when a broadcaster exists and
``publish_tf`` is on. The message objects are kept and refilled at each instant (no per-tick
construction). Beside them: the flight events on ``/lander/events``, the reports on
``/diagnostics`` and the sensors' measurements (:mod:`lander_sim.ros.sensor_out`). Every message is
counted per topic from the flight's reset: ``FLIGHT_ENDED`` carries the counts
(:mod:`lander_ros.flight_span`) so a recording can be checked complete.

No rclpy here: the node creates the publishers (with their QoS) and the TF broadcaster and passes
them in; this fills, publishes and counts.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock

from lander_interfaces.msg import FlightEvent, LanderState
from lander_ros.flight_span import COUNTED_TOPICS
from lander_sim.physics.vehicle import Vehicle
from lander_sim.ros import convert
from lander_sim.ros.markers import MarkerBuilder
from lander_sim.ros.sensor_out import SensorOutputs
from lander_sim.ros.sim_adapter import Readout
from lander_sim.sensors.suite import SensorsConfig

#: Wall period [s] of re-reading the subscriber counts of the optional outputs (odometry, pose, markers).
SUBSCRIBER_CHECK_PERIOD = 0.2


class SimOutputs:
    """The node's publishers, the messages they send, and the count of each topic's messages.

    ``clock`` ... ``diagnostics`` are the node's publishers, ``tf`` its transform broadcaster (None
    without ``tf2_ros``), ``sensors`` its :class:`SensorOutputs`; ``trajectory_length`` the points
    the trajectory marker keeps. ``publish_tf``, ``marker_period`` [s of wall time] and the frames
    (:meth:`set_frames`) follow the node's parameters.
    """

    def __init__(self, *, clock: Any, state: Any, odom: Any, pose: Any, markers: Any, events: Any,
                 diagnostics: Any, tf: Any, sensors: SensorOutputs, trajectory_length: int) -> None:
        self._pub_clock, self._pub_state, self._pub_odom, self._pub_pose = clock, state, odom, pose
        self._pub_markers, self._pub_events, self._pub_diag, self._tf = markers, events, diagnostics, tf
        self.sensors = sensors
        self.publish_tf = True
        self.marker_period = 0.0
        self.world_frame, self.body_frame = "", ""
        #: Messages published per output topic since the last reset (reported by FLIGHT_ENDED).
        self.counts: dict[str, int] = dict.fromkeys(COUNTED_TOPICS, 0)
        #: Every publisher (flush on exit, the matched counts), the sensors' among them.
        self.publishers: tuple[Any, ...] = ()
        self.state_subscribers = 0  # subscriptions matched by the state publisher (diagnostics)
        self.next_subscriber_check = 0.0  # wall time [s, monotonic] of the next re-read
        self._want_odom = self._want_pose = self._want_markers = False
        self._last_marker_wall = -math.inf
        self._clock_msg = Clock()
        self._state_msg = LanderState()
        self._odom_msg = Odometry()
        self._pose_msg = PoseStamped()
        self._tf_msg = TransformStamped()
        self._markers = MarkerBuilder("", trajectory_length)

    def set_sensors(self, config: SensorsConfig | None, seed: int | None) -> None:
        """A (new) flight's sensors at switch-on, their publishers, and every count from zero."""
        self.sensors.set_scene(config, seed)
        self.publishers = (self._pub_clock, self._pub_state, self._pub_odom, self._pub_pose, self._pub_markers,
                           self._pub_events, self._pub_diag, *self.sensors.publishers.values())
        self.counts = dict.fromkeys(COUNTED_TOPICS + self.sensors.topics(), 0)

    def set_frames(self, world: str, body: str) -> None:
        """The frame ids: ``world`` of the state, pose, odometry, transform, markers and events,
        ``body`` the odometry's and the transform's child."""
        self.world_frame, self.body_frame = world, body
        self._state_msg.header.frame_id = world
        self._pose_msg.header.frame_id = world
        self._odom_msg.header.frame_id = world
        self._odom_msg.child_frame_id = body
        self._tf_msg.header.frame_id = world
        self._tf_msg.child_frame_id = body
        self._markers.frame_id = world

    def check_subscribers(self, now: float) -> None:
        """Re-read who listens to the optional outputs (``now``: wall time, monotonic [s])."""
        self.next_subscriber_check = now + SUBSCRIBER_CHECK_PERIOD
        self.state_subscribers = self._pub_state.get_subscription_count()
        self._want_odom = self._pub_odom.get_subscription_count() > 0
        self._want_pose = self._pub_pose.get_subscription_count() > 0
        self._want_markers = self._pub_markers.get_subscription_count() > 0

    # --- one instant ------------------------------------------------------------------------------

    def clock(self, t: float) -> None:
        """``/clock`` at sim time ``t`` [s]."""
        convert.fill_stamp(self._clock_msg.clock, t)
        self._pub_clock.publish(self._clock_msg)
        self.counts["/clock"] += 1

    def fill_state(self, seq: int, snap: Readout) -> None:
        """Fill the state message of ``snap`` with sequence ``seq`` (:meth:`publish_state` sends it)."""
        convert.fill_state(self._state_msg, seq, snap)

    def publish_state(self) -> None:
        """``/lander/state`` as :meth:`fill_state` left it."""
        self._pub_state.publish(self._state_msg)
        self.counts["/lander/state"] += 1

    def views(self, snap: Readout, vehicle: Vehicle, now: float) -> None:
        """The optional views of the instant just published as a state: odometry and pose (while
        someone subscribes), the transform, and the markers (the trajectory always keeps the
        point; the array goes out while someone subscribes, at most once per ``marker_period``
        of wall time, ``now`` [s, monotonic])."""
        if self._want_odom:
            convert.fill_odometry(self._odom_msg, snap)
            self._pub_odom.publish(self._odom_msg)
            self.counts["/lander/odom"] += 1
        if self._want_pose:
            self._pose_msg.header.stamp = self._state_msg.header.stamp
            convert.fill_pose(self._pose_msg.pose, snap)
            self._pub_pose.publish(self._pose_msg)
            self.counts["/lander/pose"] += 1
        if self._tf is not None and self.publish_tf:
            convert.fill_transform(self._tf_msg, snap)
            self._tf.sendTransform(self._tf_msg)
        self._markers.record(snap.r_W)
        if self._want_markers and now - self._last_marker_wall >= self.marker_period:
            self._last_marker_wall = now
            self._pub_markers.publish(self._markers.build(snap, vehicle))
            self.counts["/lander/markers"] += 1

    def clear_trajectory(self) -> None:
        """Forget the trajectory marker's points (a new flight)."""
        self._markers.clear_trajectory()

    # --- the sensors, the events, the reports -----------------------------------------------------

    def sensors_at_start(self, sim: Any) -> None:
        """The sensors' samples of the flight's first instant, ``t = 0``."""
        self.sensors.at_start(sim, self.counts, self.world_frame, self.body_frame)

    def sensors_after_step(self, sim: Any, y_before: Any, dt: float) -> None:
        """The sensors' samples of the physics step of ``dt`` [s] from ``y_before`` that fall due."""
        self.sensors.after_step(sim, y_before, dt, self.counts, self.world_frame, self.body_frame)

    def event(self, kind: int, detail: str, values: Sequence[float], t: float) -> None:
        """One ``FlightEvent`` of ``kind`` at sim time ``t`` [s] on ``/lander/events``."""
        ev = FlightEvent()
        ev.header.frame_id = self.world_frame
        convert.fill_stamp(ev.header.stamp, t)
        ev.kind, ev.detail, ev.values = int(kind), detail, [float(v) for v in values]
        self._pub_events.publish(ev)
        self.counts["/lander/events"] += 1

    def diagnostics(self, msg: Any) -> None:
        """One report on ``/diagnostics``."""
        self._pub_diag.publish(msg)
        self.counts["/diagnostics"] += 1

"""Conversions between the simulator core and ROS messages (no physics here).

This is the one place where the core's attitude convention meets ROS's:

* The core's quaternion ``q = (s, x, y, z)`` maps world to body,
  ``x_B = q* x_W q`` (dynamics reference eq 12-13). Read as an *active*
  rotation the same ``q`` rotates body into world, which is what ROS
  (REP 103) means by the ``orientation`` of ``base_link`` in ``mars``. So the
  conversion is a pure re-ordering, ``(x, y, z, w) = (q[1], q[2], q[3], q[0])``,
  with no conjugate: see :func:`ros_orientation`.
* ``nav_msgs/Odometry`` gives its twist in the child (body) frame, so the
  world-frame velocity is rotated into the body with
  :func:`lander_sim.physics.rotation.world_to_body` (eq 12); the body rates
  ``omega_B`` are already in that frame.

Functions ``fill_*`` write into a message the caller keeps, so the node does
not build new message objects on every tick.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from lander_ros.stamps import fill_stamp, sim_time_to_ns  # noqa: F401 - the sim shell's conversions, re-exported
from lander_sim.physics import rotation


def ros_orientation(q: Sequence[float]) -> tuple[float, float, float, float]:
    """ROS ``(x, y, z, w)`` orientation (body -> world) of the core's world -> body quaternion ``(s, x, y, z)``.

    The same unit quaternion, re-ordered (see the module docstring): the core's
    passive world->body map and ROS's active body->world rotation coincide.
    """
    return float(q[1]), float(q[2]), float(q[3]), float(q[0])


def _set_xyz(v, a: Sequence[float]) -> None:
    v.x, v.y, v.z = float(a[0]), float(a[1]), float(a[2])


def _set_quat(msg_q, q: Sequence[float]) -> None:
    msg_q.x, msg_q.y, msg_q.z, msg_q.w = ros_orientation(q)


def fill_state(msg, sequence: int, snap) -> None:
    """Fill a ``lander_interfaces/LanderState`` from a :class:`lander_sim.ros.sim_adapter.Readout`."""
    fill_stamp(msg.header.stamp, snap.t)
    msg.sequence = sequence
    _set_xyz(msg.position, snap.r_W)
    _set_xyz(msg.velocity, snap.v_W)
    _set_quat(msg.orientation, snap.q)
    msg.euler_zxz = [float(e) for e in snap.euler]
    msg.gimbal_lock = bool(snap.gimbal_lock)
    _set_xyz(msg.angular_velocity, snap.omega_B)
    msg.altitude = float(snap.altitude)
    msg.climb_rate = float(snap.climb_rate)
    msg.ground_speed = float(snap.ground_speed)
    msg.mass = float(snap.mass)
    msg.fuel_mass = float(snap.fuel)
    msg.throttles = [float(x) for x in snap.throttles]
    msg.phase = int(snap.phase)
    msg.parachute_deployed = bool(snap.parachute_deployed)
    msg.stabiliser_on = bool(snap.stabiliser_on)


def fill_pose(msg, snap) -> None:
    """Fill a ``geometry_msgs/Pose`` (position in the world frame, orientation body -> world)."""
    _set_xyz(msg.position, snap.r_W)
    _set_quat(msg.orientation, snap.q)


def fill_odometry(msg, snap) -> None:
    """Fill ``nav_msgs/Odometry``: pose in ``header.frame_id`` (world), twist in ``child_frame_id`` (body).

    Covariances stay zero: the simulation's state is exact, not an estimate.
    """
    fill_stamp(msg.header.stamp, snap.t)
    fill_pose(msg.pose.pose, snap)
    v_B = rotation.world_to_body(snap.q, snap.v_W)  # eq 12: REP 105 twist is in the child frame
    _set_xyz(msg.twist.twist.linear, v_B)
    _set_xyz(msg.twist.twist.angular, snap.omega_B)


def fill_transform(msg, snap) -> None:
    """Fill a ``geometry_msgs/TransformStamped`` world -> body (the pose of ``base_link`` in ``mars``)."""
    fill_stamp(msg.header.stamp, snap.t)
    _set_xyz(msg.transform.translation, snap.r_W)
    _set_quat(msg.transform.rotation, snap.q)


def vector3_to_array(v) -> np.ndarray:
    """A ``geometry_msgs/Vector3`` as a (3,) float array (no validation: the core checks finiteness)."""
    return np.array((v.x, v.y, v.z), dtype=float)


#: Core event kind (``lander_sim.physics.events.EventKind`` value) -> ``FlightEvent`` constant name.
FLIGHT_EVENT_NAMES = {
    "landed": "LANDED",
    "hard_landing": "HARD_LANDING",
    "crashed": "CRASHED",
    "gimbal_lock": "GIMBAL_LOCK",
    "fuel_empty": "FUEL_OUT",
    "parachute_deployed": "PARACHUTE_DEPLOYED",
    "parachute_lost": "PARACHUTE_DESTROYED",
}


def event_fields(event) -> tuple[str, str, list[float]]:
    """``(FlightEvent constant name, detail, values)`` of a core ``Event``.

    The detail ends with the names of the numbers in ``values`` (SI units), since
    ``FlightEvent.values`` is a bare array.
    """
    kind = getattr(event.kind, "value", str(event.kind))
    names = list(event.values)
    detail = event.detail + (f" [values: {', '.join(names)}]" if names else "")
    return FLIGHT_EVENT_NAMES[kind], detail, [float(event.values[k]) for k in names]


#: Kinds of rejected throttle command, as counted in the diagnostics.
THROTTLE_FAULTS = ("wrong_length", "nan", "inf", "out_of_range")


def throttle_fault(values: Sequence[float], n_thrusters: int) -> str:
    """Which of :data:`THROTTLE_FAULTS` best names why a command the core refused was bad.

    Only labels a rejection for the diagnostics counters: whether a command is
    accepted is decided by the core (``Simulation.set_throttles`` raises
    ``InputError``). Returns ``"other"`` when none of the kinds applies.
    """
    if len(values) != n_thrusters:
        return "wrong_length"
    if any(math.isnan(x) for x in values):
        return "nan"
    if any(math.isinf(x) for x in values):
        return "inf"
    if any(not 0.0 <= x <= 1.0 for x in values):
        return "out_of_range"
    return "other"

"""Messages <-> the estimator's core types, for the estimator node (no filter here).

* A sensor message (docs/sim_node.md, "Sensors") -> :class:`lander_autopilot.estimation.ticks.Reading`:
  ``z`` and ``sigma`` (the square roots of the covariance's diagonal) as the core's
  :class:`lander_sim.sensors.base.Measurement` held them; a "no reading" (variance -1, the
  altimeter's range +inf) -> a reading with ``z`` None. The quaternion's ROS order ``(x, y, z, w)``
  is re-ordered to the core's ``(s, x, y, z)``: floats pass unchanged, so the filter gets the
  simulator's numbers bit for bit.
* :class:`~lander_autopilot.estimation.ticks.Estimate` -> ``lander_interfaces/LanderState``: the
  kinematic fields from the estimate, the rest (mass, fuel, throttles, phase, parachute, stabiliser:
  what the lander knows of itself without navigating) copied from the simulator's state of the same
  tick, whose stamp and sequence it carries.
* The estimate and its covariance -> ``nav_msgs/Odometry`` (REP 105: pose in the world frame,
  twist in the body frame). Pose covariance: position (world axes) and the attitude error angles
  ``dth`` about the body axes (the filter's error state); twist covariance: the body-frame velocity
  ``R P_vv R^T`` and the body rate's, the gyro bias's ``P_bg`` plus the variance of the gyro
  reading the filter last applied (``TickFeeder.omega_var``: a function of the tick, not of arrival).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from lander_sim.physics import rotation

from ..estimation.ekf import DBG, DR, DTH, DV, NavFilter
from ..estimation.ticks import Estimate, Reading

#: Flat 6 x 6 covariance index of diagonal element ``i``.
_D6 = (0, 7, 14, 21, 28, 35)


def stamp_ns(stamp: Any) -> int:
    """A ``builtin_interfaces/Time`` as integer nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _sig(values: Any) -> np.ndarray:
    return np.sqrt(np.array(values, dtype=float))


def reading(key: str, msg: Any) -> Reading:
    """The :class:`Reading` of sensor ``key``'s message (module docstring)."""
    t = stamp_ns(msg.header.stamp)
    if key == "imu":
        w, f = msg.angular_velocity, msg.linear_acceleration
        cw, cf = msg.angular_velocity_covariance, msg.linear_acceleration_covariance
        return Reading(key, t, np.array((w.x, w.y, w.z, f.x, f.y, f.z)),
                       _sig((cw[0], cw[4], cw[8], cf[0], cf[4], cf[8])))
    if key == "star_tracker":
        c = msg.pose.covariance
        if c[21] < 0.0:
            return Reading(key, t)
        o = msg.pose.pose.orientation
        return Reading(key, t, np.array((o.w, o.x, o.y, o.z)), _sig((c[21], c[28], c[35])))
    if key == "altimeter":
        if msg.variance < 0.0 or not math.isfinite(msg.range):
            return Reading(key, t)
        return Reading(key, t, np.array((msg.range,)), _sig((msg.variance,)))
    if key == "doppler":
        c = msg.twist.covariance
        if c[0] < 0.0:
            return Reading(key, t)
        v = msg.twist.twist.linear
        return Reading(key, t, np.array((v.x, v.y, v.z)), _sig((c[0], c[7], c[14])))
    if key == "ground_fix":
        p, v = msg.pose.pose.position, msg.twist.twist.linear
        cp, cv = msg.pose.covariance, msg.twist.covariance
        return Reading(key, t, np.array((p.x, p.y, p.z, v.x, v.y, v.z)),
                       _sig((cp[0], cp[7], cp[14], cv[0], cv[7], cv[14])))
    raise ValueError(f"no sensor {key!r}")


def _xyz(v: Any, a: Any) -> None:
    v.x, v.y, v.z = float(a[0]), float(a[1]), float(a[2])


def _quat(o: Any, q: np.ndarray) -> None:
    o.x, o.y, o.z, o.w = float(q[1]), float(q[2]), float(q[3]), float(q[0])


def fill_state(msg: Any, truth: Any, est: Estimate, gimbal_threshold: float) -> None:
    """A ``LanderState`` of the estimate at the tick of ``truth`` (the simulator's state message)."""
    msg.header.stamp = truth.header.stamp
    msg.header.frame_id = truth.header.frame_id
    msg.sequence = truth.sequence
    _xyz(msg.position, est.r_W)
    _xyz(msg.velocity, est.v_W)
    _quat(msg.orientation, est.q)
    msg.euler_zxz = [float(e) for e in est.euler]
    msg.gimbal_lock = bool(rotation.near_gimbal_lock(est.euler, gimbal_threshold))
    _xyz(msg.angular_velocity, est.omega_B)
    msg.altitude = float(est.altitude)
    msg.climb_rate = float(est.climb_rate)
    msg.ground_speed = float(est.ground_speed)
    msg.mass = truth.mass
    msg.fuel_mass = truth.fuel_mass
    msg.throttles = list(truth.throttles)
    msg.phase = truth.phase
    msg.parachute_deployed = truth.parachute_deployed
    msg.stabiliser_on = truth.stabiliser_on


def fill_odometry(msg: Any, truth: Any, est: Estimate, filt: NavFilter, gyro_variance: np.ndarray) -> None:
    """``nav_msgs/Odometry`` of the estimate with its covariance (module docstring)."""
    msg.header.stamp = truth.header.stamp
    _xyz(msg.pose.pose.position, est.r_W)
    _quat(msg.pose.pose.orientation, est.q)
    P = filt.state.P
    R = rotation.quat_to_matrix(est.q)
    pose = np.zeros((6, 6))
    idx = np.r_[DR, DTH]
    pose[:, :] = P[np.ix_(idx, idx)]
    twist = np.zeros((6, 6))
    twist[0:3, 0:3] = R @ P[DV, DV] @ R.T
    twist[3:6, 3:6] = P[DBG, DBG] + np.diag(gyro_variance)
    msg.pose.covariance = [float(x) for x in pose.reshape(-1)]
    _xyz(msg.twist.twist.linear, R @ est.v_W)
    _xyz(msg.twist.twist.angular, est.omega_B)
    msg.twist.covariance = [float(x) for x in twist.reshape(-1)]


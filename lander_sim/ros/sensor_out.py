"""The sensors' measurements on ROS: one topic per sensor, standard message types, stamped in sim time.

For a scene with a ``sensors:`` section (:mod:`lander_sim.sensors`, docs/estimation.md) the sim
node samples the :class:`~lander_sim.sensors.suite.SensorSuite` once at the flight's start (``t =
0``, the truth of that instant, :func:`~lander_sim.sensors.truth.truth_of`) and after every physics
step (the truth over the step, :func:`~lander_sim.sensors.truth.truth_after_step`), and publishes each
:class:`~lander_sim.sensors.base.Measurement` at once, stamped with its time ``t``. A sensor of rate
``f`` is due at ``t = j / f``: a flight of duration ``D`` gives ``floor(D f) + 1`` messages per
sensor (the instants ``0, 1/f, ..., D``). A sample due that gives no measurement (a dropout: out of
range, lost lock) is published too, marked "no reading": every variance -1 and every value 0, and
for the altimeter ``range = +inf`` (REP 117, "no return within ``max_range``"). So which messages a
step brings is the schedule's alone (:class:`~lander_sim.sensors.suite.SampleSchedule`), and a
reader that waits for a step's messages (the estimator node) never waits for one that will not
come. The covariances
are the measurement's white noise, ``diag(sigma^2)`` (the ``R`` a filter takes); a quantity the
message carries but the sensor does not measure has the variance -1 on its diagonal (the
``sensor_msgs`` convention for "not provided") and the value 0 (identity for a quaternion).

=============================  ==============================================  =========================
topic                          type                                            frame (``header.frame_id``)
=============================  ==============================================  =========================
``/lander/sensors/imu``        ``sensor_msgs/Imu``: ``angular_velocity`` the   body
                               gyro's ``omega_B`` [rad/s], ``linear_acceleration``
                               the specific force ``f_B`` [m/s^2] (REP 145)
``/lander/sensors/star_tracker``  ``geometry_msgs/PoseWithCovarianceStamped``:   world
                               the orientation only (body -> world, as
                               ``/lander/pose``); its covariance is of the
                               error angles about the body axes [rad^2]
``/lander/sensors/altimeter``  ``sensor_msgs/Range``: slant range along the    body
                               beam [m], ``variance`` [m^2], ``max_range`` the
                               sensor's
``/lander/sensors/doppler``    ``geometry_msgs/TwistWithCovarianceStamped``:   body
                               velocity over the ground [m/s], body axes
``/lander/sensors/ground_fix`` ``nav_msgs/Odometry``: position [m] and         world (``child_frame_id``
                               velocity [m/s], both world axes                 world too: the twist's)
=============================  ==============================================  =========================

The star tracker's message is ``PoseWithCovarianceStamped`` rather than ``QuaternionStamped``
because the latter has no covariance, and a filter (``robot_localization`` among them) needs the
measurement's noise with it. ``sensor_msgs/Range`` has no radar value of ``radiation_type``
(ultrasound 0, infrared 1): it is left 0, and ``field_of_view`` 0 (the model is one ray along
the beam ``beam_B`` of the scene, in body axes).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from lander_ros.flight_span import SENSOR_KEYS, SENSOR_TOPICS
from lander_ros.stamps import fill_stamp
from lander_sim.ros.convert import ros_orientation
from lander_sim.sensors.base import Measurement, Truth
from lander_sim.sensors.suite import SensorsConfig, SensorSuite
from lander_sim.sensors.truth import truth_after_step, truth_of

#: Variance that says "not measured" (sensor_msgs/Imu's convention for a covariance not provided).
NOT_MEASURED = -1.0

#: Sensor key -> its topic (the suite's keys, in lander_ros.flight_span.SENSOR_TOPICS order).
TOPICS: dict[str, str] = dict(zip(SENSOR_KEYS, SENSOR_TOPICS))


def _diag6(msg_cov, first: np.ndarray | None, second: np.ndarray | None) -> None:
    """A 6x6 row-major covariance: ``diag(first^2, second^2)``, a block None: not measured."""
    cov = [0.0] * 36
    for block, sig in enumerate((first, second)):
        for i in range(3):
            cov[(3 * block + i) * 7] = NOT_MEASURED if sig is None else float(sig[i]) ** 2
    msg_cov[:] = cov


def _diag3(sigma: np.ndarray | None) -> list[float]:
    cov = [0.0] * 9
    for i in range(3):
        cov[4 * i] = NOT_MEASURED if sigma is None else float(sigma[i]) ** 2
    return cov


def _xyz(v, a) -> None:
    v.x, v.y, v.z = float(a[0]), float(a[1]), float(a[2])


def fill_imu(msg: Any, m: Measurement) -> None:
    """``sensor_msgs/Imu`` from the IMU's ``z = [omega_m, f_m]``; no orientation (covariance[0] = -1)."""
    fill_stamp(msg.header.stamp, m.t)
    msg.orientation.x = msg.orientation.y = msg.orientation.z = 0.0
    msg.orientation.w = 1.0
    msg.orientation_covariance = _diag3(None)
    _xyz(msg.angular_velocity, m.z[0:3])
    msg.angular_velocity_covariance = _diag3(m.sigma[0:3])
    _xyz(msg.linear_acceleration, m.z[3:6])
    msg.linear_acceleration_covariance = _diag3(m.sigma[3:6])


def fill_star_tracker(msg: Any, m: Measurement) -> None:
    """``geometry_msgs/PoseWithCovarianceStamped`` from the tracker's quaternion ``z`` (world -> body, the core's)."""
    fill_stamp(msg.header.stamp, m.t)
    p = msg.pose.pose
    p.position.x = p.position.y = p.position.z = 0.0
    o = p.orientation
    o.x, o.y, o.z, o.w = ros_orientation(m.z)
    _diag6(msg.pose.covariance, None, m.sigma)


def fill_altimeter(msg: Any, m: Measurement, max_range: float) -> None:
    """``sensor_msgs/Range`` from the altimeter's ``z = [rho_m]``."""
    fill_stamp(msg.header.stamp, m.t)
    msg.radiation_type = 0
    msg.field_of_view = 0.0
    msg.min_range = 0.0
    msg.max_range = float(max_range)
    msg.range = float(m.z[0])
    msg.variance = float(m.sigma[0]) ** 2


def fill_doppler(msg: Any, m: Measurement) -> None:
    """``geometry_msgs/TwistWithCovarianceStamped`` from the velocimeter's body-frame ``z`` (3)."""
    fill_stamp(msg.header.stamp, m.t)
    _xyz(msg.twist.twist.linear, m.z)
    _xyz(msg.twist.twist.angular, (0.0, 0.0, 0.0))
    _diag6(msg.twist.covariance, m.sigma, None)


def fill_ground_fix(msg: Any, m: Measurement) -> None:
    """``nav_msgs/Odometry`` from the fix's ``z = [r_W, v_W]``; no orientation, no body rate."""
    fill_stamp(msg.header.stamp, m.t)
    p = msg.pose.pose
    _xyz(p.position, m.z[0:3])
    p.orientation.x = p.orientation.y = p.orientation.z = 0.0
    p.orientation.w = 1.0
    _diag6(msg.pose.covariance, m.sigma[0:3], None)
    _xyz(msg.twist.twist.linear, m.z[3:6])
    _xyz(msg.twist.twist.angular, (0.0, 0.0, 0.0))
    _diag6(msg.twist.covariance, m.sigma[3:6], None)


def fill_no_reading(msg: Any, key: str, t: float, max_range: float = 0.0) -> None:
    """A due sample of sensor ``key`` at ``t`` [s] with no measurement (module docstring): values 0,
    variances -1; the altimeter's ``range`` +inf (REP 117). The IMU and the ground fix never drop out."""
    if key == "star_tracker":
        fill_stamp(msg.header.stamp, t)
        p = msg.pose.pose
        p.position.x = p.position.y = p.position.z = 0.0
        p.orientation.x = p.orientation.y = p.orientation.z = 0.0
        p.orientation.w = 1.0
        _diag6(msg.pose.covariance, None, None)
    elif key == "altimeter":
        fill_stamp(msg.header.stamp, t)
        msg.radiation_type = 0
        msg.field_of_view = 0.0
        msg.min_range = 0.0
        msg.max_range = float(max_range)
        msg.range = math.inf
        msg.variance = NOT_MEASURED
    elif key == "doppler":
        fill_stamp(msg.header.stamp, t)
        _xyz(msg.twist.twist.linear, (0.0, 0.0, 0.0))
        _xyz(msg.twist.twist.angular, (0.0, 0.0, 0.0))
        _diag6(msg.twist.covariance, None, None)
    else:
        raise ValueError(f"sensor {key!r} has no 'no reading' message: it never drops out")


def message_types() -> dict[str, Any]:
    """Sensor key -> its ROS message class."""
    from geometry_msgs.msg import PoseWithCovarianceStamped, TwistWithCovarianceStamped
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu, Range

    return {"imu": Imu, "star_tracker": PoseWithCovarianceStamped, "altimeter": Range,
            "doppler": TwistWithCovarianceStamped, "ground_fix": Odometry}


class SensorOutputs:
    """The sim node's sensors: the suite of its scene and one publisher per sensor switched on.

    ``create_publisher(type, topic)`` makes a publisher (the node's, with its output QoS);
    ``counts`` is the node's per-topic count of messages published in the flight, which this
    adds to. Publishers are made for the sensors of each scene given to :meth:`set_scene` and kept
    (a node that loads a scene without a sensor keeps the publisher, silent).
    """

    def __init__(self, create_publisher: Callable[[Any, str], Any]) -> None:
        self._create = create_publisher
        self._types = message_types()
        self.publishers: dict[str, Any] = {}
        self._msgs: dict[str, Any] = {}
        self.suite: SensorSuite | None = None
        self._max_range = 0.0

    def set_scene(self, config: SensorsConfig | None, seed: int | None) -> None:
        """The sensors of a (new) scene, at switch-on; ``seed`` None: the scene's ``sensors.seed``."""
        self.suite = None if config is None or not config.sections else SensorSuite(config, seed)
        if self.suite is None:
            return
        for key in self.suite.sensors:
            if key not in self.publishers:
                self.publishers[key] = self._create(self._types[key], TOPICS[key])
                self._msgs[key] = self._types[key]()
        if "altimeter" in self.suite.sensors:
            self._max_range = float(self.suite.config.sections["altimeter"]["max_range"])

    def reset(self, seed: int | None) -> None:
        """Back to switch-on (a reset of the flight)."""
        if self.suite is not None:
            self.suite.reset(seed)

    @property
    def on(self) -> bool:
        """Whether the scene has sensors."""
        return self.suite is not None

    def topics(self) -> tuple[str, ...]:
        """The topics of the scene's sensors (all of SENSOR_TOPICS when it has any, else none):
        the counts FLIGHT_ENDED carries."""
        return SENSOR_TOPICS if self.suite is not None else ()

    def at_start(self, sim: Any, counts: dict[str, int], world: str, body: str) -> None:
        """Sample and publish the instant ``t = 0`` (the flight's first state)."""
        if self.suite is not None:
            self._publish(truth_of(sim), counts, world, body)

    def after_step(self, sim: Any, y_before: np.ndarray, dt: float, counts: dict[str, int],
                   world: str, body: str) -> None:
        """Sample the step of ``dt`` [s] that started from ``y_before`` and publish what is due."""
        if self.suite is not None:
            self._publish(truth_after_step(sim, y_before, dt), counts, world, body)

    def _publish(self, truth: Truth, counts: dict[str, int], world: str, body: str) -> None:
        assert self.suite is not None
        for key, m in self.suite.sample_due(truth):
            msg = self._msgs[key]
            if m is None:
                fill_no_reading(msg, key, truth.t, self._max_range)
                msg.header.frame_id = world if key == "star_tracker" else body
            elif m.key == "imu":
                fill_imu(msg, m)
                msg.header.frame_id = body
            elif m.key == "star_tracker":
                fill_star_tracker(msg, m)
                msg.header.frame_id = world
            elif m.key == "altimeter":
                fill_altimeter(msg, m, self._max_range)
                msg.header.frame_id = body
            elif m.key == "doppler":
                fill_doppler(msg, m)
                msg.header.frame_id = body
            else:
                fill_ground_fix(msg, m)
                msg.header.frame_id = msg.child_frame_id = world
            self.publishers[key].publish(msg)
            counts[TOPICS[key]] += 1

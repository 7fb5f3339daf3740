"""The sim node's sensor outputs without ROS running (lander_sim/ros/sensor_out.py, sim_adapter.step_each):
the measurement in the standard fields with its covariance, and stepping one step at a time for the
sensors flies the same flight."""
from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, Range

from lander_ros.stamps import stamp_to_seconds
from lander_sim.ros import convert, sensor_out
from lander_sim.ros.sim_adapter import build_simulation
from lander_sim.sensors.base import Measurement


@pytest.mark.parametrize("scene", ["landing-sensors", "hover", "tumbling-descent"])
def test_stepping_one_step_at_a_time_flies_the_same_flight_bit_for_bit(scene: str) -> None:
    """A scene with sensors steps one physics step at a time (each step sampled): the state is the
    same bits as k steps at once, whatever path (compiled kernel or Python) the scene takes."""
    a, b = build_simulation(scene), build_simulation(scene)
    n = a.vehicle.n_thrusters
    dts: list[float] = []
    for i in range(200):
        th = np.full(n, 0.3 + 0.2 * np.sin(i / 10.0))
        a.set_throttles(th)
        b.set_throttles(th)
        a.step(3)
        b.step_each(3, lambda sim, y_before, dt: dts.append(dt))
    assert np.array_equal(a.sim.y, b.sim.y) and a.t == b.t
    assert len(dts) == 600 and max(abs(d - a.dt) for d in dts) <= 1e-9 * a.t  # each step's length


def _m(key: str, z, sigma, t: float = 1.25) -> Measurement:
    return Measurement(key, t, np.array(z, float), np.array(sigma, float))


def test_each_message_carries_z_stamped_t_with_sigma_squared_and_minus_one_for_what_is_not_measured() -> None:
    imu = Imu()
    sensor_out.fill_imu(imu, _m("imu", [0.1, 0.2, 0.3, 1.0, 2.0, 3.0], [1e-3] * 3 + [2e-2] * 3))
    assert stamp_to_seconds(imu.header.stamp) == 1.25
    assert (imu.angular_velocity.x, imu.linear_acceleration.z) == (0.1, 3.0)
    assert imu.orientation_covariance[0] == -1.0
    assert imu.angular_velocity_covariance[4] == pytest.approx(1e-6, rel=1e-15)
    assert imu.linear_acceleration_covariance[8] == pytest.approx(4e-4, rel=1e-15)
    assert imu.angular_velocity_covariance[1] == 0.0  # independent axes

    q = np.array([0.5, 0.5, 0.5, 0.5])  # the core's (s, x, y, z)
    st = PoseWithCovarianceStamped()
    sensor_out.fill_star_tracker(st, _m("star_tracker", q, [1e-4] * 3))
    o = st.pose.pose.orientation
    assert (o.x, o.y, o.z, o.w) == convert.ros_orientation(q)  # as /lander/pose gives the attitude
    cov = np.array(st.pose.covariance).reshape(6, 6)
    assert list(np.diag(cov)) == [-1.0] * 3 + [pytest.approx(1e-8, rel=1e-15)] * 3

    rng = Range()
    sensor_out.fill_altimeter(rng, _m("altimeter", [812.5], [8.0]), max_range=4000.0)
    assert (rng.range, rng.variance, rng.max_range) == (812.5, 64.0, 4000.0)

    tw = TwistWithCovarianceStamped()
    sensor_out.fill_doppler(tw, _m("doppler", [1.0, -2.0, 0.5], [0.1] * 3))
    assert tw.twist.twist.linear.y == -2.0
    assert list(np.diag(np.array(tw.twist.covariance).reshape(6, 6))) == [pytest.approx(0.01, rel=1e-15)] * 3 + [-1.0] * 3

    od = Odometry()
    sensor_out.fill_ground_fix(od, _m("ground_fix", [1e6, 2e6, 3e6, 10.0, 20.0, 30.0], [1000.0] * 3 + [1.0] * 3))
    assert (od.pose.pose.position.z, od.twist.twist.linear.x) == (3e6, 10.0)
    assert list(np.diag(np.array(od.pose.covariance).reshape(6, 6))) == [1e6] * 3 + [-1.0] * 3
    assert list(np.diag(np.array(od.twist.covariance).reshape(6, 6))) == [1.0] * 3 + [-1.0] * 3

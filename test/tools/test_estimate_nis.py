"""NIS of ``lander analyse`` from the estimator re-run (lander_tools.estimate_nis) against theory (no ROS).

A synthetic run whose innovations are known in closed form: a lander whose attitude ``q`` does not
move, an IMU that reads exactly 0 (no noise, no bias: the filter's process noise is 0 with it) and a
star tracker at every 0.2 s tick measuring ``q x dq(n)``, ``n ~ N(0, sigma_t^2)`` per axis, the filter
told ``sigma_f``. Per axis the attitude is then a constant measured ``n`` times: from the prior
``P0`` (the filter's initial error is drawn from it) the filter's variance is
``P_n = 1 / (1/P0 + n / R_f)`` and the true variance of its error
``V_n = P_n^2 (1/P0 + n R_t / R_f^2)``, so the next innovation has ``E[y^2] = V_n + R_t`` against the
filter's ``S = P_n + R_f`` and ``E[NIS_(n+1)] = 3 (V_n + R_t) / (P_n + R_f)``:

* ``sigma_f = sigma_t`` (consistent): ``E[NIS] = 3`` at every update; the time average is inside
  its exact chi-square interval and within 5 standard deviations ``5 sqrt(2 * 3 / N)`` of 3, and the
  fraction inside the single-update interval is 0.95 within 5 binomial standard deviations;
* ``sigma_f = sigma_t / 2`` (the variance reported 4 times too small): the time average is the
  closed form's (about 12) within 5 standard deviations ``sqrt(6 sum c_n^2) / N``.

The check against a recorded estimate: the same inputs reproduce it at every state; one tampered
covariance element, another initial-error seed or a missing reading make the re-run stop at that
state with the reason. Fixed seeds: the draws are the same every run.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from lander_autopilot.estimation.ekf import small_rotation
from lander_autopilot.estimation.flights import initial_covariance, initial_error_rng, start_filter
from lander_autopilot.estimation.ticks import Reading, TickFeeder
from lander_autopilot.ros import estimator_convert as convert
from lander_sim.physics.constants import GM_MARS, MARS_RADIUS
from lander_sim.physics.rotation import quat_mult, quat_normalise
from lander_sim.scenes import load_scene
from lander_sim.sensors.suite import SensorsConfig
from lander_tools import estimate_nis as en

TICK_NS = 200_000_000  #: 5 Hz: the IMU and the star tracker at every tick
N = 1500  #: star tracker updates
SIGMA_ATT0 = math.radians(1.0)  #: the filter's initial attitude sigma (its default) [rad]
Q_TRUE = quat_normalise(np.array([0.9, 0.1, -0.3, 0.2]))


def _sensors() -> SensorsConfig:
    base = load_scene("landing-sensors").sensors
    imu = dict(base.sections["imu"])
    imu.update(rate=5.0, gyro_noise_density=0.0, accel_noise_density=0.0, gyro_bias=0.0, accel_bias=0.0,
               gyro_bias_walk=0.0, accel_bias_walk=0.0)
    star = dict(base.sections["star_tracker"], rate=5.0)
    return SensorsConfig(seed=0, sections={"imu": imu, "star_tracker": star})


def _readings(sigma_true: float, sigma_filter: float, seed: int = 3) -> list[Reading]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(N):
        t = k * TICK_NS
        out.append(Reading("imu", t, np.zeros(6), np.ones(6)))
        q_m = quat_mult(Q_TRUE, small_rotation(sigma_true * rng.standard_normal(3)))
        out.append(Reading("star_tracker", t, q_m, np.full(3, sigma_filter)))
    return out


def _feeder(sensors: SensorsConfig, seed: int = 11) -> TickFeeder:
    f = TickFeeder(sensors)
    r0 = np.array([0.0, -(MARS_RADIUS + 10_000.0), 0.0])
    f.start(start_filter(sensors, r0, np.zeros(3), Q_TRUE, 0.0, initial_covariance(sensors), initial_error_rng(seed),
                         GM_MARS, MARS_RADIUS))
    return f


def _ticks() -> list[int]:
    return [k * TICK_NS for k in range(N)]


def _expected_ratio(r_true: float, r_filter: float) -> np.ndarray:
    """``c_n = (V_n + R_t) / (P_n + R_f)`` for the updates n = 0 .. N-1 (module docstring)."""
    n = np.arange(N, dtype=float)
    p0 = SIGMA_ATT0**2
    P = 1.0 / (1.0 / p0 + n / r_filter)
    V = P**2 * (1.0 / p0 + n * r_true / r_filter**2)
    return (V + r_true) / (P + r_filter)


def test_a_consistent_filter_s_nis_is_chi_square_3_inside_its_bounds() -> None:
    sensors = _sensors()
    sigma = float(sensors.sections["star_tracker"]["noise"])
    run = en.replay(_feeder(sensors), _readings(sigma, sigma), _ticks())
    nis = en.sensor_nis(run.updates)
    assert list(nis) == ["star_tracker"]
    s = nis["star_tracker"]
    assert s.dof == 3 and len(s.values) == N and run.ticks == N
    np.testing.assert_allclose(_expected_ratio(sigma**2, sigma**2), 1.0, rtol=1e-12)
    assert abs(s.mean - 3.0) < 5.0 * math.sqrt(2.0 * 3.0 / N)
    assert s.inside, (s.mean, s.bounds)
    assert abs(s.frac_inside - 0.95) < 5.0 * math.sqrt(0.95 * 0.05 / N)
    assert s.bounds_one == pytest.approx((0.2157953, 9.3484036), rel=1e-6)  # chi2(3) 2.5 % and 97.5 %
    assert np.array_equal(s.t, np.arange(N) * TICK_NS * 1e-9)


def test_a_variance_reported_4_times_too_small_scales_nis_as_theory_says() -> None:
    sensors = _sensors()
    sigma = float(sensors.sections["star_tracker"]["noise"])
    run = en.replay(_feeder(sensors), _readings(sigma, sigma / 2.0), _ticks())
    s = en.sensor_nis(run.updates)["star_tracker"]
    c = _expected_ratio(sigma**2, sigma**2 / 4.0)
    want = 3.0 * float(c.mean())
    assert 11.9 < want < 12.0  # about 4 x 3: the closed form, not a fit
    assert abs(s.mean - want) < 5.0 * math.sqrt(6.0 * float(np.sum(c**2))) / N
    assert not s.inside


def _states() -> list[SimpleNamespace]:
    return [SimpleNamespace(header=SimpleNamespace(stamp=SimpleNamespace(sec=t // 1_000_000_000,
                                                                          nanosec=t % 1_000_000_000)))
            for t in _ticks()]


def _recorded(sensors: SensorsConfig, readings: list[Reading], seed: int = 11) -> list[SimpleNamespace]:
    """The Odometry a node would have published: the estimator's own conversion after each tick."""
    states = _states()
    out = []

    def keep(k: int, feeder: TickFeeder) -> None:
        msg = en.odometry_message()
        convert.fill_odometry(msg, states[k], feeder.estimate(), feeder.filter, feeder.omega_var)
        out.append(msg)
    en.replay(_feeder(sensors, seed), readings, _ticks(), keep)
    return out


def test_the_re_run_is_checked_against_the_recorded_estimate_state_by_state() -> None:
    sensors = _sensors()
    sigma = float(sensors.sections["star_tracker"]["noise"])
    readings = _readings(sigma, sigma)
    recorded = _recorded(sensors, readings)
    run = en.replay(_feeder(sensors), readings, _ticks(), en.odometry_check(_states(), recorded))
    assert run.ticks == N and len(run.updates) == N

    recorded[300].pose.covariance[14] *= 1.0 + 1e-15  # one element tampered by an ulp or so
    with pytest.raises(en.NisUnavailable, match=r"state 301 \(t = 60 s\) differs in pose.covariance$"):
        en.replay(_feeder(sensors), readings, _ticks(), en.odometry_check(_states(), recorded))

    other_seed = en.odometry_check(_states(), _recorded(sensors, readings, seed=12))
    with pytest.raises(en.NisUnavailable, match=r"state 1 \(t = 0 s\) differs in position, orientation"):
        en.replay(_feeder(sensors), readings, _ticks(), other_seed)


def test_a_tick_without_its_reading_stops_the_re_run_naming_the_state() -> None:
    sensors = _sensors()
    readings = [r for r in _readings(1e-4, 1e-4) if not (r.key == "star_tracker" and r.t_ns == 10 * TICK_NS)]
    with pytest.raises(en.NisUnavailable, match=r"state 11 \(t = 2 s\): the bag lacks a sensor reading"):
        en.replay(_feeder(sensors), readings, _ticks())


def test_the_setup_comes_from_the_bag_s_metadata() -> None:
    s = en.setup_from_meta({"scene": "landing-sensors", "seed": "42"})
    assert (s.scene, s.seed) == ("landing-sensors", 42)
    assert s.initial_sigma == pytest.approx((10.0, 0.5, SIGMA_ATT0))
    assert en.setup_from_meta({"scene": "landing-sensors", "seed": "-1"}).seed is None  # the scene's seed
    assert en.setup_from_meta({"scene": "landing-sensors"}).seed is None
    with pytest.raises(en.NisUnavailable, match="names no scene"):
        en.setup_from_meta({"controller": "landing"})
    with pytest.raises(en.NisUnavailable, match="not an integer"):
        en.setup_from_meta({"scene": "landing-sensors", "seed": "x"})

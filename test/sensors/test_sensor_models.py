"""Sensor models (lander_sim/sensors/): noise statistics against chi-square bounds, the bias random walk's
growth, range limits and dropouts, determinism, and the accelerometer's specific force in the simulator."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from lander_sim.physics import constants as c
from lander_sim.physics.rotation import euler_to_quat, quat_conj, quat_mult
from lander_sim.scenes.loader import parse_scene
from lander_sim.sensors.altimeter import RadarAltimeter, slant_range
from lander_sim.sensors.base import RandomWalkBias, Truth
from lander_sim.sensors.doppler import DopplerVelocimeter
from lander_sim.sensors.ground_fix import GroundFix
from lander_sim.sensors.imu import IMU
from lander_sim.sensors.params import defaults
from lander_sim.sensors.star_tracker import StarTracker
from lander_sim.sensors.suite import SENSORS, SensorsConfig, SensorSuite
from lander_sim.sensors.truth import truth_of
from lander_sim.simulation import Simulation

R = c.MARS_RADIUS
UPRIGHT = euler_to_quat(np.radians([0.0, 90.0, 0.0]))  # body z along local up on the world -y axis
N = 4000  # samples per variance check
P = 0.999  # two-sided probability of each chi-square interval (a few dozen intervals in this file)


def _truth(t=0.0, h=500.0, v=(1.0, -2.0, 0.5), q=UPRIGHT, w=(0.0, 0.0, 0.0), f=(0.0, 0.0, 3.7)) -> Truth:
    return Truth(t=t, r_W=np.array([0.0, -(R + h), 0.0]), v_W=np.array(v, float), q=np.array(q, float),
                 omega_B=np.array(w, float), f_B=np.array(f, float), planet_radius=R)


def _values(key: str, **over: float) -> dict:
    return {**defaults(SENSORS[key][0]), **over}


def _variance_ok(samples: np.ndarray, sigma: float) -> bool:
    """Sample variance about the known mean inside the chi-square(n) interval of probability P."""
    n = samples.size
    s = float(np.sum(samples**2))
    lo, hi = chi2.ppf((1 - P) / 2, n), chi2.ppf((1 + P) / 2, n)
    return lo <= s / sigma**2 <= hi


def test_imu_white_noise_has_the_density_over_the_interval() -> None:
    imu = IMU(_values("imu", gyro_bias=0.0, gyro_bias_walk=0.0, accel_bias=0.0, accel_bias_walk=0.0),
              np.random.default_rng(1))
    tr = _truth(w=(0.01, -0.02, 0.03))
    dt = 0.01
    z = np.array([imu.measure(tr, dt).z for _ in range(N)])
    sg = imu.values["gyro_noise_density"] / math.sqrt(dt)
    sa = imu.values["accel_noise_density"] / math.sqrt(dt)
    assert _variance_ok(z[:, 0:3] - tr.omega_B, sg)  # the three axes pooled: chi-square of 3 N
    assert _variance_ok(z[:, 3:6] - tr.f_B, sa)


def test_bias_random_walk_variance_grows_linearly() -> None:
    # Var(b(T) - b(0)) = K^2 T for every walk; 3000 independent axes walked for 200 s in 1 s steps.
    K, T, M = 1e-3, 200.0, 3000
    b = RandomWalkBias(M, 0.0, K, np.random.default_rng(5))
    half = None
    for k in range(int(T)):
        b.advance(1.0)
        if k + 1 == int(T) // 2:
            half = b.value.copy()
    assert _variance_ok(half, K * math.sqrt(T / 2))
    assert _variance_ok(b.value, K * math.sqrt(T))
    # switch-on bias: Var b(0) = b0^2
    assert _variance_ok(RandomWalkBias(M, 0.3, K, np.random.default_rng(6)).value, 0.3)


def test_star_tracker_angle_noise_and_rate_dropout() -> None:
    st = StarTracker(_values("star_tracker"), np.random.default_rng(2))
    tr = _truth()
    angles = []
    for _ in range(N):
        dq = quat_mult(quat_conj(tr.q), st.measure(tr, 0.2).z)
        angles.append(2.0 * dq[1:] * np.sign(dq[0]))
    a = np.array(angles)
    assert _variance_ok(a, st.values["noise"])
    assert st.dropouts == 0
    fast = _truth(w=(0.0, 0.0, 1.01 * st.values["max_rate"]))
    assert st.measure(fast, 0.2) is None
    assert st.dropouts == 1


def test_altimeter_slant_range_noise_and_limits() -> None:
    alt = RadarAltimeter(_values("altimeter"), np.random.default_rng(3))
    h = 800.0
    tr = _truth(h=h)
    z = np.array([alt.measure(tr, 0.05).z[0] for _ in range(N)])
    sigma = math.hypot(0.5, 0.01 * h)
    assert _variance_ok(z - h, sigma)
    # tilted by 20 degrees about body x: the beam's slant range is h / cos(20 deg) to first order in h / R
    tilt = math.radians(20.0)
    q = quat_mult(UPRIGHT, np.array([math.cos(tilt / 2), math.sin(tilt / 2), 0.0, 0.0]))
    s = slant_range(_truth(h=h).r_W, _beam_W(q), R)
    assert s == pytest.approx(h / math.cos(tilt), rel=h / R * 10)
    # out of range, and a beam above the horizon, give no output and are counted
    assert alt.measure(_truth(h=4001.0), 0.05) is None
    assert alt.measure(_truth(q=quat_mult(UPRIGHT, np.array([0.0, 1.0, 0.0, 0.0]))), 0.05) is None
    assert alt.dropouts == 2


def _beam_W(q: np.ndarray) -> np.ndarray:
    from lander_sim.physics.rotation import body_to_world

    return body_to_world(q, np.array([0.0, 0.0, -1.0]))


def test_doppler_measures_body_velocity_below_its_altitude() -> None:
    dop = DopplerVelocimeter(_values("doppler"), np.random.default_rng(4))
    tr = _truth(v=(3.0, -4.0, 0.0))
    from lander_sim.physics.rotation import world_to_body

    vb = world_to_body(tr.q, tr.v_W)
    z = np.array([dop.measure(tr, 0.05).z for _ in range(N)])
    sigma = math.hypot(0.02, 0.01 * 5.0)
    assert _variance_ok(z - vb, sigma)
    assert dop.measure(_truth(h=4000.5), 0.05) is None
    assert dop.dropouts == 1


def test_ground_fix_errors_are_kilometre_level() -> None:
    gf = GroundFix(_values("ground_fix"), np.random.default_rng(8))
    tr = _truth()
    z = np.array([gf.measure(tr, 10.0).z for _ in range(N)])
    assert _variance_ok(z[:, 0:3] - tr.r_W, 1000.0)
    assert _variance_ok(z[:, 3:6] - tr.v_W, 1.0)


def _all_on(seed: int = 11) -> SensorsConfig:
    return SensorsConfig(seed, {k: _values(k) for k in SENSORS})


def _run(suite: SensorSuite, n: int = 300, dt: float = 0.1) -> bytes:
    out = b""
    for k in range(n):
        for m in suite.sample(_truth(t=k * dt, h=500.0 - k)):
            out += m.key.encode() + np.float64(m.t).tobytes() + m.z.tobytes() + m.sigma.tobytes()
    return out


def test_same_seed_same_bytes_other_seed_other_bytes() -> None:
    a, b = _run(SensorSuite(_all_on())), _run(SensorSuite(_all_on()))
    assert a == b and len(a) > 0
    assert _run(SensorSuite(_all_on(12))) != a
    s = SensorSuite(_all_on())
    _run(s)
    s.reset()
    assert _run(s) == a


def test_each_sensor_samples_at_its_rate() -> None:
    suite = SensorSuite(_all_on())
    counts: dict[str, int] = {}
    for k in range(1001):  # 100 s at 0.1 s steps, t = 0 .. 100
        for m in suite.sample(_truth(t=k * 0.1, h=500.0)):
            counts[m.key] = counts.get(m.key, 0) + 1
    # faster than the step (400 and 20 Hz): one sample a step; slower (5 and 0.1 Hz): one per period, t = 0 included
    assert counts == {"imu": 1001, "star_tracker": 501, "altimeter": 1001, "doppler": 1001, "ground_fix": 11}


def test_switching_a_sensor_off_leaves_the_others_draws_unchanged() -> None:
    full = SensorSuite(_all_on())
    part = SensorSuite(SensorsConfig(11, {"imu": _values("imu")}))
    a = [m.z for m in full.sample(_truth()) if m.key == "imu"]
    b = [m.z for m in part.sample(_truth())]
    assert np.array_equal(a[0], b[0])


def _scene(**extra) -> Simulation:
    data = {
        "vehicle": {"preset": "lander"}, "dt": 0.1,
        "initial": {"position_W": [0.0, -(R + 2000.0), 0.0], "attitude": {"euler_deg": [0.0, 90.0, 0.0]}},
        "models": {"gravity": {"kind": "inverse-square"}, "thrusters": {}, **extra},
    }
    return Simulation(parse_scene(data, "sensors-test.yaml"))


def test_accelerometer_reads_zero_in_free_fall() -> None:
    sim = _scene()
    sim.step(20)
    f = truth_of(sim).f_B
    # gravity taken out of an acceleration that is gravity alone: round-off of |g| ~ 3.7 m/s^2
    assert np.abs(f).max() < 1e-12 * c.SURFACE_GRAVITY


def test_accelerometer_reads_g_up_at_hover_balanced_thrust() -> None:
    from lander_autopilot.design.altitude import hover_throttle

    sim = _scene()
    r = float(np.linalg.norm(sim.y[0:3]))
    sim.set_throttles([hover_throttle(sim.scene.vehicle, float(sim.y[13]), r)] * 4)
    f = truth_of(sim).f_B
    g = c.GM_MARS / r**2
    np.testing.assert_allclose(f, [0.0, 0.0, g], atol=1e-12 * g)


def test_the_imu_interval_truth_is_the_steps_mean_rate_and_specific_force() -> None:
    from lander_sim.sensors.truth import truth_after_step

    # free fall: Verlet's velocity step is the trapezoid of gravity, which the interval truth takes
    # out again: zero to round-off of |g| dt
    sim = _scene()
    y0 = sim.y.copy()
    sim.step()
    assert np.abs(truth_after_step(sim, y0, sim.dt).f_B).max() < 1e-12 * c.SURFACE_GRAVITY
    # a spin about the body z axis with no torque: the mean rate is about z, and the constant rate
    # turns the attitude exactly as the step did (the integrator's own rotation angle, which differs
    # from omega dt by its truncation, (omega dt)^2 / 12 relative here)
    from lander_sim.physics.rotation import quat_exp_step

    spin = _scene()
    spin.y[10:13] = (0.0, 0.0, 0.2)
    y0 = spin.y.copy()
    spin.step()
    w = truth_after_step(spin, y0, spin.dt).omega_B
    assert abs(w[0]) < 1e-15 and abs(w[1]) < 1e-15
    assert w[2] == pytest.approx(0.2, rel=(0.2 * spin.dt) ** 2)
    np.testing.assert_allclose(quat_exp_step(y0[6:10], w, spin.dt), spin.y[6:10], atol=1e-15)


def test_the_imus_first_output_averages_from_switch_on() -> None:
    v = _values("imu")
    m = SensorSuite(SensorsConfig(0, {"imu": v})).sample(_truth(t=0.1))[0]
    np.testing.assert_allclose(m.sigma[0:3], v["gyro_noise_density"] / math.sqrt(0.1), rtol=1e-12)
    m0 = SensorSuite(SensorsConfig(0, {"imu": v})).sample(_truth(t=0.0))[0]
    np.testing.assert_allclose(m0.sigma[3:6], v["accel_noise_density"] * math.sqrt(v["rate"]), rtol=1e-12)

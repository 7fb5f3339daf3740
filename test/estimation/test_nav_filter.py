"""The navigation filter (lander_autopilot/estimation/): its measurement Jacobians against finite
differences of its own predictions, the multiplicative attitude update, the propagation against the
simulator, bad input, and consistency (NEES and NIS inside their chi-square 95 % bounds) over a Monte
Carlo of core flights."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_autopilot.estimation.consistency import anees, anis, average_bounds, error_state
from lander_autopilot.estimation.ekf import (
    DTH,
    N_ERR,
    EstimationError,
    NavFilter,
    NavState,
    NoiseModel,
    small_rotation,
)
from lander_autopilot.estimation.flights import fly
from lander_sim.physics import constants as c
from lander_sim.physics.rotation import euler_to_quat, quat_mult, world_to_body
from lander_sim.scenes import load_scene
from lander_sim.sensors.params import defaults
from lander_sim.sensors.suite import SENSORS, SensorsConfig

R = c.MARS_RADIUS
NOISE = NoiseModel(2e-5, 5e-4, 1e-8, 1e-5)


def _filter(h=800.0, v=(2.0, -3.0, 1.0), tilt=(5.0, 80.0, 10.0)) -> NavFilter:
    q = euler_to_quat(np.radians(tilt))
    st = NavState(r_W=np.array([30.0, -(R + h), -40.0]), v_W=np.array(v, float), q=q, b_g=np.zeros(3),
                  b_a=np.zeros(3), P=np.eye(N_ERR) * 1e-2)
    return NavFilter(st, NOISE, planet_radius=R)


def _perturbed(f: NavFilter, dx: np.ndarray) -> NavFilter:
    s = f.state
    st = NavState(r_W=s.r_W + dx[0:3], v_W=s.v_W + dx[3:6], q=quat_mult(s.q, small_rotation(dx[6:9])),
                  b_g=s.b_g + dx[9:12], b_a=s.b_a + dx[12:15], P=s.P.copy())
    return NavFilter(st, NOISE, planet_radius=R)


def _numeric_jacobian(f: NavFilter, h, eps: np.ndarray) -> np.ndarray:
    cols = []
    for i in range(N_ERR):
        d = np.zeros(N_ERR)
        d[i] = eps[i]
        cols.append((h(_perturbed(f, d)) - h(_perturbed(f, -d))) / (2 * eps[i]))
    return np.array(cols).T


EPS = np.array([1.0] * 3 + [1e-3] * 3 + [1e-6] * 3 + [1e-6] * 6)


def test_altimeter_jacobian_is_the_derivative_of_the_slant_range() -> None:
    f = _filter()
    beam = np.array([0.0, 0.0, -1.0])
    s, H = f.predict_slant_range(beam)
    J = _numeric_jacobian(f, lambda g: np.array([g.predict_slant_range(beam)[0]]), EPS)
    # central differences: error O(eps^2 s'''), far under 1e-6 of the entries here
    np.testing.assert_allclose(H, J, atol=1e-6 * np.abs(H).max())


def test_doppler_jacobian_is_the_derivative_of_the_body_velocity() -> None:
    f = _filter()
    from lander_sim.physics.rotation import quat_to_matrix

    u = f.update_doppler(world_to_body(f.state.q, f.state.v_W), np.full(3, 0.1))  # zero innovation
    assert np.abs(u.y).max() < 1e-12
    f = _filter()
    R_ = quat_to_matrix(f.state.q)
    H = np.zeros((3, N_ERR))
    H[:, 3:6] = R_
    vb = R_ @ f.state.v_W
    H[:, DTH] = np.array([[0, -vb[2], vb[1]], [vb[2], 0, -vb[0]], [-vb[1], vb[0], 0]])
    J = _numeric_jacobian(f, lambda g: quat_to_matrix(g.state.q) @ g.state.v_W, EPS)
    np.testing.assert_allclose(J, H, atol=1e-7 * np.abs(H).max())


def test_star_tracker_update_moves_the_attitude_by_the_gain_and_keeps_it_unit() -> None:
    # With P_th = p I, R = r I and no correlations the update is th_hat = p / (p + r) * th.
    f = _filter()
    p, r = 1e-4, 1e-4
    f.state.P = np.eye(N_ERR) * p
    th = np.array([0.01, -0.02, 0.005])
    q_true = quat_mult(f.state.q, small_rotation(th))
    q0 = f.state.q.copy()
    u = f.update_star_tracker(q_true, np.full(3, math.sqrt(r)))
    np.testing.assert_allclose(u.y, th, rtol=1e-9)
    from lander_autopilot.estimation.ekf import attitude_error

    np.testing.assert_allclose(attitude_error(q0, f.state.q), th * p / (p + r), rtol=1e-9)
    assert abs(np.linalg.norm(f.state.q) - 1.0) < 1e-15
    np.testing.assert_allclose(np.diag(f.state.P)[DTH], p * r / (p + r), rtol=1e-9)


def test_propagation_with_a_perfect_imu_follows_a_coasting_flight() -> None:
    # Free fall from rest under inverse-square gravity, no rotation: the IMU reads zeros; after
    # 10 s of 0.1 s steps the filter's position matches r(t) ~ r0 + g t^2 / 2 to the step's
    # truncation, ~g' v t dt ~ 1e-5 m, and its attitude is unchanged.
    f = _filter(h=5000.0, v=(0.0, 0.0, 0.0))
    r0, q0 = f.state.r_W.copy(), f.state.q.copy()
    for _ in range(100):
        f.propagate(np.zeros(3), np.zeros(3), 0.1)
    g = c.GM_MARS / float(r0 @ r0)
    expected = r0 + 0.5 * g * 100.0 * (-r0 / np.linalg.norm(r0))
    assert np.abs(f.state.r_W - expected).max() < 0.05  # the gravity gradient over 187 m of fall: 1e-2 m
    np.testing.assert_allclose(f.state.q, q0, atol=1e-15)  # renormalised each step: round-off only


def test_covariance_grows_with_no_aiding_and_stays_symmetric() -> None:
    f = _filter()
    P0 = f.state.P.copy()
    for _ in range(50):
        f.propagate(np.array([0.01, 0.0, 0.0]), np.array([0.0, 0.0, 3.7]), 0.1)
    P = f.state.P
    assert np.array_equal(P, P.T)
    assert np.all(np.diag(P) >= np.diag(P0) - 1e-15)
    assert np.all(np.linalg.eigvalsh(P) > 0.0)


@pytest.mark.parametrize(("call", "match"), [
    (lambda f: f.propagate(np.array([np.nan, 0, 0]), np.zeros(3), 0.1), "imu: expected 3 finite numbers"),
    (lambda f: f.propagate(np.zeros(3), np.zeros(3), 0.0), "imu: dt must be a finite number > 0"),
    (lambda f: f.update_star_tracker(np.array([2.0, 0, 0, 0]), np.full(3, 1e-4)), "star_tracker: expected a unit quaternion"),
    (lambda f: f.update_doppler(np.zeros(3), np.zeros(3)), "doppler: noise standard deviations must be > 0"),
    (lambda f: f.update_ground_fix(np.zeros(5), np.ones(6)), "ground_fix: expected 6 finite numbers"),
])
def test_bad_input_is_refused_counted_and_leaves_the_state(call, match) -> None:
    f = _filter()
    before = (f.state.r_W.copy(), f.state.q.copy(), f.state.P.copy())
    with pytest.raises(EstimationError, match=match):
        call(f)
    assert sum(f.rejected.values()) == 1
    assert np.array_equal(before[0], f.state.r_W) and np.array_equal(before[1], f.state.q)
    assert np.array_equal(before[2], f.state.P)


def test_error_state_of_the_truth_is_zero_and_of_a_rotation_is_its_angle() -> None:
    f = _filter()
    s = f.state
    assert not np.any(error_state(s, s.r_W, s.v_W, s.q, s.b_g, s.b_a))
    th = np.array([0.0, 0.3, 0.0])
    np.testing.assert_allclose(error_state(s, s.r_W, s.v_W, quat_mult(s.q, small_rotation(th)), s.b_g, s.b_a)[DTH],
                               th, rtol=1e-12, atol=1e-15)


# --- consistency over a Monte Carlo of core flights ------------------------------------------------

RUNS = 8  # ~0.4 s each: what fits in a few seconds; bench/nav_consistency.py flies 100 per scene
SENSOR_SET = ("imu", "star_tracker", "altimeter", "doppler")


@pytest.fixture(scope="module")
def landing_runs():
    sc = load_scene("landing-hover")
    sc = dataclasses.replace(sc, sensors=SensorsConfig(0, {k: defaults(SENSORS[k][0]) for k in SENSOR_SET}))
    return [fly(sc, seed, 30.0) for seed in range(RUNS)]


def test_time_averaged_nees_is_inside_its_95_percent_bounds(landing_runs) -> None:
    K = min(len(r.nees) for r in landing_runs)
    assert K == 300  # 30 s of 0.1 s steps, still flying (touchdown comes after about 35 s)
    check, frac = anees(np.array([r.nees[:K] for r in landing_runs]), N_ERR)
    assert check.inside, check
    # at each time the run-average lies inside the interval with probability 0.95 for a consistent
    # filter; the times are correlated, so allow a wide margin on the fraction
    assert frac > 0.8


@pytest.mark.parametrize("key", ["star_tracker", "altimeter", "doppler"])
def test_time_averaged_nis_of_each_sensor_is_inside_its_95_percent_bounds(landing_runs, key) -> None:
    vals = [n for r in landing_runs for n, _ in r.nis[key]]
    dof = landing_runs[0].nis[key][0][1]
    check = anis(np.array(vals), dof)
    assert check.inside, check


def test_the_bounds_are_the_chi_square_quantiles() -> None:
    # M = 1, n = 2: chi-square(2) is exponential with mean 2, quantiles -2 ln(1 - p)
    lo, hi = average_bounds(2, 1)
    assert lo == pytest.approx(-2 * math.log(0.975), rel=1e-12)
    assert hi == pytest.approx(-2 * math.log(0.025), rel=1e-12)


def test_orbit_with_the_ground_fix_is_consistent() -> None:
    # Coasting in orbit with kilometre-level initial errors: the IMU carries the state between
    # ground fixes every 10 s, the star tracker holds the attitude. 4 runs of 100 s.
    sc = load_scene("circular-orbit")
    sc = dataclasses.replace(sc, sensors=SensorsConfig(0, {k: defaults(SENSORS[k][0])
                                                         for k in ("imu", "star_tracker", "ground_fix")}))
    runs = [fly(sc, seed, 100.0, initial_sigma=(1000.0, 1.0, math.radians(1.0))) for seed in range(4)]
    check, _ = anees(np.array([r.nees for r in runs]), N_ERR)
    assert check.inside, check
    fixes = [n for r in runs for n, _ in r.nis["ground_fix"]]
    assert len(fixes) == 4 * 11  # the first sample after the first step (due since t = 0), then t = 10, ..., 100 s
    assert anis(np.array(fixes), 6).inside

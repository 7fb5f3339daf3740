"""The estimate's figures of ``lander analyse`` (lander_tools.estimate_analysis) against theory, on
synthetic bags whose estimate errors are drawn from known covariances (no ROS):

* errors drawn from ``N(0, P)`` with ``P`` the covariance the Odometry reports: the errors read back
  are the drawn ones (through the Odometry's body-axis twist and the multiplicative attitude
  error), each block's time-averaged NEES is its degrees of freedom within the standard deviation
  of an average of ``K`` chi-square values, ``sqrt(2 n / K)``, and inside its chi-square interval, 95 % of
  the samples are inside the single-time interval and 99.73 % inside 3 sigma;
* a reported covariance 4 times too small: NEES 4 times the degrees of freedom, and
  ``erf(1.5 / sqrt 2) = 86.6 %`` inside the reported 3 sigma;
* percentiles of ``|e|`` for ``e ~ N(0, sigma^2)``: the half-normal's quantiles;
* ``lander analyse``: the figures for a bag with the estimate, n/a (JSON ``applies: false``, no
  table section, no figure) for one without; NIS n/a with its reason for a bag without the sensors'
  messages (lander_tools.estimate_nis re-runs the filter over them).

Tolerances: 5 standard deviations of each statistic (a fixed seed: the draws are the same every run).
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm

from lander_autopilot.estimation.ekf import small_rotation
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.rotation import quat_mult, quat_normalise, quat_to_matrix
from lander_tools import estimate_analysis as ea
from lander_tools.analysis import Flight
from lander_tools.bagio import read_bag
from lander_tools.estimate_nis import NO_IMU

from .synth import write_flight_bag

REPO = Path(__file__).resolve().parents[2]
K = 3000  #: states of a synthetic flight
DT = 0.1


def _spd(rng: np.random.Generator, scales: np.ndarray) -> np.ndarray:
    """A random symmetric positive-definite matrix with correlated components, about ``scales^2``."""
    n = len(scales)
    A = rng.normal(size=(n, n)) / math.sqrt(n)
    S = np.diag(scales)
    return S @ (A @ A.T + 0.5 * np.eye(n)) @ S


def _flight(tmp: Path, rng: np.random.Generator, reported_scale: float = 1.0,
            missing: tuple[int, ...] = (), states: int = K) -> tuple[Path, dict[str, np.ndarray]]:
    """A synthetic bag: truth on the -y axis (write_flight_bag), the estimate = truth - e with
    ``e`` drawn per state from ``N(0, P)`` (pose ``[dr, dth]`` 6 x 6, velocity 3 x 3 in world axes),
    the Odometry reporting ``reported_scale * P``; states in ``missing`` get no estimate."""
    n = states
    t = np.arange(n) * DT
    h, climb = 2000.0 - 3.0 * t, np.full(n, -3.0)
    q = np.array([quat_normalise(v) for v in rng.normal(size=(n, 4))])
    r_true = np.column_stack([np.zeros(n), -(MARS_RADIUS + h), np.zeros(n)])
    v_true = np.column_stack([np.zeros(n), -climb, np.zeros(n)])
    est = {"r_W": np.zeros((n, 3)), "q": np.zeros((n, 4)), "v_B": np.zeros((n, 3)),
           "pose_cov": np.zeros((n, 36)), "twist_cov": np.zeros((n, 36))}
    drawn = {"position": np.zeros((n, 3)), "velocity": np.zeros((n, 3)), "attitude": np.zeros((n, 3))}
    for i in range(n):
        P_pose = _spd(rng, np.array([10.0, 10.0, 10.0, 1e-3, 1e-3, 1e-3]))
        P_v = _spd(rng, np.array([0.5, 0.5, 0.5]))
        e_pose = rng.multivariate_normal(np.zeros(6), P_pose)
        e_v = rng.multivariate_normal(np.zeros(3), P_v)
        drawn["position"][i], drawn["attitude"][i], drawn["velocity"][i] = e_pose[:3], e_pose[3:], e_v
        q_est = quat_mult(q[i], small_rotation(-e_pose[3:]))  # q_true = q_est x dq(th)
        R = quat_to_matrix(q_est)  # world -> body
        twist = np.zeros((6, 6))
        twist[:3, :3] = R @ P_v @ R.T * reported_scale
        est["r_W"][i] = r_true[i] - e_pose[:3]
        est["q"][i] = q_est
        est["v_B"][i] = R @ (v_true[i] - e_v)
        est["pose_cov"][i] = (P_pose * reported_scale).ravel()
        est["twist_cov"][i] = twist.ravel()
    est["r_W"][list(missing)] = np.nan
    bag = tmp / "b"
    write_flight_bag(bag, t, h, climb, q=q, estimate=est, meta={"scene": "hover"})
    return bag, drawn


def _report(bag: Path) -> ea.EstimateReport:
    b = read_bag(bag)
    rep, why = ea.from_bag(b, Flight.from_bag(b))
    assert rep is not None, why
    return rep


def _nees(rep: ea.EstimateReport, block: str) -> np.ndarray:
    err = rep.errors
    if block == "pose":
        return ea.nees_series(np.hstack([err.e["position"], err.e["attitude"]]), err.P_pose)
    return ea.nees_series(err.e[block], err.P[block])


def test_errors_from_the_reported_covariance_give_nees_at_its_degrees_of_freedom(tmp_path: Path) -> None:
    bag, drawn = _flight(tmp_path, np.random.default_rng(7), missing=(5, 6))
    rep = _report(bag)
    keep = np.setdiff1d(np.arange(K), (5, 6))
    assert rep.states == K - 2 and rep.unpaired == 2
    # The errors read back are the drawn ones: position to the rounding of |r| ~ 3.4e6 m, the
    # velocity through R^T (R v), the attitude through dq(-th) and its logarithm.
    np.testing.assert_allclose(rep.errors.e["position"], drawn["position"][keep], rtol=0, atol=1e-8)
    np.testing.assert_allclose(rep.errors.e["velocity"], drawn["velocity"][keep], rtol=0, atol=1e-12)
    np.testing.assert_allclose(rep.errors.e["attitude"], drawn["attitude"][keep], rtol=0, atol=1e-14)
    n = rep.states
    for block, dof in (("position", 3), ("velocity", 3), ("attitude", 3), ("pose", 6)):
        c = rep.nees[block]
        assert c.dof == dof and c.samples == n
        assert abs(c.mean - dof) < 5.0 * math.sqrt(2.0 * dof / n), (block, c)
        # Inside the chi-square interval of K independent samples: at 95 % that fails one flight in
        # 20 by design, so the assertion takes the interval at 1 - 1e-6 (same statistic, same code).
        assert c.inside_one and ea.nees_check(_nees(rep, block), dof, prob=1.0 - 1e-6).inside, (block, c)
        assert abs(c.frac_inside - 0.95) < 5.0 * math.sqrt(0.95 * 0.05 / n), (block, c)
    p3 = ea.inside_3sigma_gaussian()
    for comp in rep.components:
        assert abs(comp.inside_3sigma - p3) < 5.0 * math.sqrt(p3 * (1 - p3) / n), comp


def test_a_covariance_four_times_too_small_gives_four_times_the_nees(tmp_path: Path) -> None:
    bag, _ = _flight(tmp_path, np.random.default_rng(8), reported_scale=0.25)
    rep = _report(bag)
    n = rep.states
    for block, c in rep.nees.items():
        assert abs(c.mean - 4.0 * c.dof) < 5.0 * 4.0 * math.sqrt(2.0 * c.dof / n), (block, c)
        assert c.mean > ea.nees_check(_nees(rep, block), c.dof, prob=1.0 - 1e-6).bounds[1], (block, c)
    # The reported 3 sigma is the true 1.5 sigma.
    p = ea.inside_3sigma_gaussian(1.5)
    assert p == pytest.approx(0.8664, abs=1e-4)
    for comp in rep.components:
        assert abs(comp.inside_3sigma - p) < 5.0 * math.sqrt(p * (1 - p) / n), comp


def test_error_percentiles_are_the_half_normal_quantiles() -> None:
    n, sigma = 40000, np.array([2.0, 0.5, 1e-4])
    e = np.random.default_rng(3).normal(size=(n, 3)) * sigma
    figs = ea.component_figures(e, np.tile(sigma, (n, 1)), ("a", "b", "c"), "m")
    for j, f in enumerate(figs):
        for p, got in zip(ea.PERCENTILES, f.percentiles):
            x = norm.ppf(0.5 + 0.5 * p / 100.0)  # |e| / sigma below x with probability p
            density = 2.0 * norm.pdf(x) / sigma[j]  # of |e| at its quantile
            sd = math.sqrt(p / 100.0 * (1 - p / 100.0) / n) / density  # of the sample quantile
            assert abs(got - x * sigma[j]) < 5.0 * sd, (f.name, p, got, x * sigma[j])


def test_nees_series_is_the_quadratic_form_and_nan_where_p_is_singular() -> None:
    P = np.array([np.diag([4.0, 1.0, 0.25]), np.zeros((3, 3))])
    e = np.array([[2.0, 1.0, 0.5], [1.0, 1.0, 1.0]])
    got = ea.nees_series(e, P)
    assert got[0] == pytest.approx(3.0, rel=1e-15) and math.isnan(got[1])


def test_a_reset_keeps_the_estimates_of_the_last_flight() -> None:
    stamps = np.array([0, 100, 200, 0, 100])  # ns: a reset after the third
    n = len(stamps)
    s = {"header.stamp.sec": np.zeros(n, dtype=np.int64), "header.stamp.nanosec": stamps,
         "pose.covariance": np.tile(np.eye(6).ravel(), (n, 1)), "twist.covariance": np.tile(np.eye(6).ravel(), (n, 1))}
    for a in "xyz":
        s[f"pose.pose.position.{a}"] = np.arange(n, dtype=float)
        s[f"pose.pose.orientation.{a}"] = np.zeros(n)
        s[f"twist.twist.linear.{a}"] = np.zeros(n)
    s["pose.pose.orientation.w"] = np.ones(n)
    track = ea.EstimateTrack.from_series(s)
    assert list(track.t_ns) == [0, 100] and list(track.r_W[:, 0]) == [3.0, 4.0]


def _lander(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", "analyse", *args],
                          capture_output=True, text=True, env=env, cwd=REPO, timeout=240)


def test_analyse_reports_the_estimate_where_the_bag_has_one_and_na_where_not(tmp_path: Path) -> None:
    with_est, _ = _flight(tmp_path, np.random.default_rng(9), states=200)
    plain = tmp_path / "plain"
    t = np.arange(0, 10, DT)
    write_flight_bag(plain, t, 500 + 0 * t, 0 * t)

    r = _lander(str(plain), str(with_est), "--json", "--out", str(tmp_path / "png"))
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)["estimate"]
    assert doc[0]["applies"] is False and ea.ODOMETRY_TOPIC in doc[0]["why"]
    assert doc[1]["applies"] is True and doc[1]["states_paired"] == 200
    assert doc[1]["nis"] is None and doc[1]["nis_why"] == NO_IMU  # no sensor messages: no re-run
    assert set(doc[1]["nees"]) == {"position", "velocity", "attitude", "pose"}
    pngs = sorted(p.name for p in (tmp_path / "png").iterdir())
    assert "flight-estimate-2.png" in pngs and "flight-nees-2.png" in pngs
    assert not any(p.startswith(("flight-estimate-1", "flight-nees-1")) for p in pngs)

    r = _lander(str(plain))
    assert r.returncode == 0 and "estimate" not in r.stdout, r.stdout
    r = _lander(str(plain), str(with_est))
    assert r.returncode == 0, r.stderr
    assert f"estimate of plain: n/a: {ea.NO_ESTIMATE}" in r.stdout
    assert "estimate of b: /lander/estimate/odometry against /lander/state, 200 states paired" in r.stdout
    assert f"NIS: n/a: {NO_IMU}" in r.stdout

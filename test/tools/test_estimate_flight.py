"""``lander analyse`` of a real flight on the estimate: 20 s of landing-sensors flown by ``lander fly
--speed 0 --estimate --record`` (simulator, estimator and autopilot over real middleware):

* every state of the flight pairs with its estimate (one per state, the same stamp);
* the errors read through the Odometry (velocity in the estimate's body axes, rotated back to world
  axes) are those of the independent ``/lander/estimate/state`` (world-axis velocity, the same
  position and attitude), to the rounding of one rotation there and back;
* the filter is consistent on the flight by the test ``consistency.anees`` applies to a
  time-average: each block's time-averaged NEES inside the chi-square(n) single-time 95 % interval;
* NIS: the filter re-run over the bag's sensor messages (lander_tools.estimate_nis) reproduces the
  recorded estimate bit for bit at every state, and reports one star-tracker update per reading
  (the radars give "no readings" above their range: no update), each of 3 components, the time
  average inside the single-update interval; one tampered estimate, or another seed in the bag's
  metadata than the flight's, makes NIS n/a with the state and field that differ;
* the command prints the estimate's section and writes its three figures.
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

from lander_autopilot.estimation.ekf import attitude_error
from lander_tools import estimate_analysis as ea
from lander_tools import estimate_nis as en
from lander_tools.analysis import Flight
from lander_tools.bagio import read_bag

REPO = Path(__file__).resolve().parents[2]
SCENE = "landing-sensors"
DURATION = 20.0  #: [s] the parachute descent from 10 km: IMU and star tracker (the radars are out of range)


def _lander(verb: str, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", verb, *args],
                          capture_output=True, text=True, env=env, cwd=REPO, timeout=300)


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("estimate") / "bag"
    r = _lander("fly", SCENE, "--speed", "0", "--estimate", "--duration", f"{DURATION:g}", "--no-progress",
                "--record", str(path))
    assert r.returncode == 0, r.stdout + r.stderr
    return path


def test_every_state_pairs_with_its_estimate_and_the_odometry_errors_are_the_estimate_states(bag: Path) -> None:
    b = read_bag(bag)
    f = Flight.from_bag(b)
    rep, why = ea.from_bag(b, f)
    assert rep is not None, why
    assert rep.states == len(f.t) and rep.unpaired == 0
    assert rep.errors.t[-1] == pytest.approx(DURATION, abs=1e-9)
    s = b.series("/lander/estimate/state")
    assert np.array_equal(s["sequence"], f.sequence)
    r_est = np.column_stack([s[f"position.{a}"] for a in "xyz"])
    v_est = np.column_stack([s[f"velocity.{a}"] for a in "xyz"])
    q_est = np.column_stack([s[f"orientation.{a}"] for a in "wxyz"])
    assert np.array_equal(rep.errors.e["position"], f.r_W - r_est)
    # R^T (R v) in floating point: a few ulps of |v| (up to ~100 m/s under the parachute).
    np.testing.assert_allclose(rep.errors.e["velocity"], f.v_W - v_est, rtol=0,
                               atol=8 * np.finfo(float).eps * float(np.abs(f.v_W).max()))
    th = np.array([attitude_error(qe, qt) for qe, qt in zip(q_est, f.q)])
    assert np.array_equal(rep.errors.e["attitude"], th)


def test_the_estimate_is_consistent_by_the_single_time_interval(bag: Path) -> None:
    b = read_bag(bag)
    rep, _ = ea.from_bag(b, Flight.from_bag(b))
    assert rep is not None
    for block, c in rep.nees.items():
        assert c.inside_one, (block, c)


def test_analyse_prints_the_estimate_and_draws_its_figures(bag: Path, tmp_path: Path) -> None:
    r = _lander("analyse", str(bag), "--json", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    est = json.loads(r.stdout)["estimate"][0]
    assert est["applies"] is True and est["states_unpaired"] == 0 and est["nis_why"] == ""
    assert set(est["nis"]) == {"star_tracker"} and est["rerun"]["scene"] == SCENE
    for name in ("flight-estimate.png", "flight-nees.png", "flight-nis.png"):
        assert (tmp_path / name).is_file(), name


def test_the_re_run_reproduces_the_recorded_estimate_and_nis_is_reported(bag: Path) -> None:
    b = read_bag(bag)
    rep = en.from_bag(b)
    states = b.messages("/lander/state")
    assert rep.states == len(states) == len(b.messages(ea.ODOMETRY_TOPIC))
    readings = [m for m in b.messages("/lander/sensors/star_tracker") if m.pose.covariance[21] >= 0.0]
    assert list(rep.sensors) == ["star_tracker"]  # the radars are out of range: no reading, no update
    s = rep.sensors["star_tracker"]
    assert s.dof == 3 and len(s.values) == len(readings) == math.floor(DURATION * 5.0) + 1  # 5 Hz, t = 0 .. 20 s
    assert s.bounds_one[0] <= s.mean <= s.bounds_one[1], s


def test_a_tampered_estimate_or_another_seed_gets_nis_na_with_the_reason(bag: Path) -> None:
    b = read_bag(bag)
    odom = b.messages(ea.ODOMETRY_TOPIC)
    k = len(odom) // 2
    odom[k].pose.pose.position.x += 1e-3  # [m]
    with pytest.raises(en.NisUnavailable, match=rf"state {k + 1} \(t = [0-9.]+ s\) differs in position"):
        en.from_bag(b)
    rep, _ = ea.from_bag(b, Flight.from_bag(b))
    assert rep is not None and rep.nis is None and f"state {k + 1}" in rep.nis_why
    assert f"  NIS: n/a: {rep.nis_why}" in rep.lines()

    b = read_bag(bag)
    b.meta["seed"] = "12345"  # not the seed the estimator drew its initial error with
    with pytest.raises(en.NisUnavailable, match=r"state 1 \(t = 0 s\) differs in position.*seed 12345"):
        en.from_bag(b)

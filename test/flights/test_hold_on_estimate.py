"""Hover and ground speed flown on the estimate through the nodes (``lander fly SCENE --estimate
--speed 0 --record``: sim, estimator, autopilot with ``state_source: estimate``), each bag read back:

* hover-canted-sensors (the combined law from scenario 7's tilted, rolling start 50 m over the
  demand) holds the 500 m demand: its true altitude is within 5 sigma of the filter's vertical
  position of the same law flown on the truth;
* ground-speed-sensors (the ground-speed law stopping a 50 m/s drift at 500 m) holds the lander at
  rest over the ground: its true horizontal velocity is within 5 sigma of the filter's horizontal
  velocity of the truth flight's;
* at every state of the hold, truth and estimate differ by at most 5 sigma of the filter's own
  covariance (the Odometry's): the filter's error is what its covariance says.

Where the bound comes from. The law drives the state it is given, the estimate, to the demand, so the
true state is off the demand by the estimation error ``e = x - x_est`` passed through the closed loop.
``e`` changes on the filter's time scale (the altitude estimator's poles are -0.11 and -0.004 1/s,
docs/estimation.md "Observability"), far slower than the laws' loops (altitude -0.9, -1.1 1/s;
ground speed -0.45, -0.5 1/s), for which the loop's gain is 1: the flight on the estimate is the
flight on the truth displaced by ``e``. A consistent filter's ``e`` is Gaussian with its covariance
``P``; ``|e| > 5 sigma`` has probability ``2 Q(5) = 5.7e-7`` in one dimension and ``exp(-25/2) =
3.7e-6`` in two (chi-square, 2 degrees of freedom, against the largest eigenvalue), so over the
``N`` <= 300 states of a hold the union bound leaves at most 1e-3 for any state outside.
The flight on the truth is the same scene and law stepped in the core (no ROS): the same physics,
so the same flight up to the estimation error.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from lander_autopilot.controllers import make_controller
from lander_autopilot.controllers.base import Demand
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation
from lander_tools.bagio import read_bag
from lander_tools.estimate_analysis import EstimateTrack
from lander_tools.fly.phases import fly
from lander_tools.fly.plan import FlightPlan
from lander_tools.fly.summary import summary

#: Sigmas of the bound (module docstring).
K_SIGMA = 5.0
#: (scene, flight length [s], hold from [s]): the start's transient gone by then. Hover: the 50 m
#: offset decays as exp(-0.9 t), under 1 mm at 20 s, and the 0.05 rad/s roll as exp(-2 t).
#: Ground speed: the tilt limit brakes the 50 m/s for about 20 s, its overshoot (0.5 m/s) then
#: decays as exp(-0.45 t), to mm/s by 35 s.
HOVER = ("hover-canted-sensors", 30.0, 20.0)
GROUND_SPEED = ("ground-speed-sensors", 45.0, 35.0)


def _vec(v) -> np.ndarray:
    return np.array((v.x, v.y, v.z))


class Hold:
    """A flight on the estimate from its bag, beside the same law on the truth in the core: per state,
    times ``t`` [s], true ``r``/``v`` and estimated ``r_est``/``v_est`` (world axes), the local up
    ``u``, the filter's position and velocity covariances ``P_r``/``P_v`` (world axes), the truth
    flight's ``r_truth``/``v_truth``; ``hold``: the states from the hold's start."""

    def __init__(self, bag: Path, scene_name: str, hold_from: float) -> None:
        got = read_bag(bag, ["/lander/state", "/lander/estimate/odometry"])
        states = got.messages("/lander/state")
        track = EstimateTrack.from_series(got.series("/lander/estimate/odometry"))
        stamps = [s.header.stamp.sec * 1_000_000_000 + s.header.stamp.nanosec for s in states]
        assert stamps == list(track.t_ns), "one estimate per state, with its stamp"
        self.t = np.array(stamps) * 1e-9
        self.r = np.array([_vec(s.position) for s in states])
        self.v = np.array([_vec(s.velocity) for s in states])
        self.r_est, self.v_est = track.r_W, track.v_W
        self.P_r, self.P_v = track.P_pose[:, :3, :3], track.P_v
        self.u = self.r / np.linalg.norm(self.r, axis=1)[:, None]
        self.r_truth, self.v_truth = _truth_flight(scene_name, len(states))
        self.hold = self.t >= hold_from - 1e-9

    def vertical_sigma(self) -> np.ndarray:
        """sigma of the filter's position along the local up, ``sqrt(u^T P_r u)`` [m]."""
        return np.sqrt(np.einsum("ni,nij,nj->n", self.u, self.P_r, self.u))

    def horizontal(self, x: np.ndarray) -> np.ndarray:
        """The part of the world vectors ``x`` across the local up."""
        return x - np.einsum("ni,ni->n", x, self.u)[:, None] * self.u

    def horizontal_velocity_sigma(self) -> np.ndarray:
        """sqrt of the largest eigenvalue of the filter's horizontal velocity covariance [m/s]."""
        H = np.eye(3)[None] - self.u[:, :, None] * self.u[:, None, :]
        return np.sqrt(np.linalg.eigvalsh(H @ self.P_v @ H)[:, -1])


def _truth_flight(scene_name: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The scene's law flown on the truth in the core, as the lockstep nodes fly it (the law at every
    state, its throttles over the next step): ``n`` states' positions and velocities."""
    scene = load_scene(scene_name)
    assert scene.autopilot is not None
    law = make_controller(scene.autopilot.controller, scene.vehicle, **dict(scene.autopilot.parameters))
    demand = Demand(altitude=500.0 if scene.autopilot.demand_altitude is None else scene.autopilot.demand_altitude)
    sim = Simulation(scene)
    r, v = [], []
    for k in range(n):
        r.append(sim.y[0:3].copy())
        v.append(sim.y[3:6].copy())
        if k < n - 1:
            sim.set_throttles(law.update(k * sim.dt, sim.state(), demand).throttles)
            sim.step()
    return np.array(r), np.array(v)


def _fly(tmp_path_factory: pytest.TempPathFactory, case: tuple[str, float, float]) -> Hold:
    scene, duration, hold_from = case
    bag = tmp_path_factory.mktemp(scene) / "bag"
    plan = FlightPlan(scene=scene, duration=duration, speed=0.0, record=bag, estimate=True)
    with open(os.devnull, "w") as devnull:
        result = fly(plan, out=devnull)
    assert result.exit_code == 0 and result.outcome == "time-limit", summary(result)
    assert result.bag_check.startswith("complete") and result.lockstep_timeouts == 0, summary(result)
    return Hold(bag, scene, hold_from)


@pytest.fixture(scope="module")
def hover(tmp_path_factory: pytest.TempPathFactory) -> Hold:
    return _fly(tmp_path_factory, HOVER)


@pytest.fixture(scope="module")
def ground_speed(tmp_path_factory: pytest.TempPathFactory) -> Hold:
    return _fly(tmp_path_factory, GROUND_SPEED)


def test_the_hover_on_the_estimate_holds_the_demand_within_5_sigma_of_the_filters_altitude(hover: Hold) -> None:
    h = hover
    R = np.linalg.norm(h.r_truth[0]) - 550.0  # the planet's radius: the scene starts 550 m up
    altitude = np.linalg.norm(h.r, axis=1) - R
    truth_flight = np.linalg.norm(h.r_truth, axis=1) - R
    sigma = h.vertical_sigma()
    w = h.hold
    assert np.all(np.abs(truth_flight[w] - 500.0) < 1e-3)  # the law holds the demand on the truth
    off = np.abs(altitude[w] - truth_flight[w])
    bound = K_SIGMA * sigma[w].max()
    assert off.max() <= bound, (off.max(), bound)
    assert bound < 5.0  # the altimeter's noise (5 m at 500 m, 1 sigma) filtered, not passed on
    # flown on the estimate, not on the truth: the true altitude is off by the estimation error
    assert off.max() > 1e-3


def test_the_ground_speed_law_on_the_estimate_holds_the_lander_at_rest_within_5_sigma(ground_speed: Hold) -> None:
    g = ground_speed
    w = g.hold
    truth_flight = np.linalg.norm(g.horizontal(g.v_truth), axis=1)
    # on the truth the law has stopped the drift: under the Doppler's 0.02 m/s noise floor
    assert truth_flight[w].max() < 0.02 and truth_flight[-1] < truth_flight[w][0]
    off = np.linalg.norm(g.horizontal(g.v - g.v_truth), axis=1)
    bound = K_SIGMA * g.horizontal_velocity_sigma()[w].max()
    assert off[w].max() <= bound, (off[w].max(), bound)
    assert bound < 0.1  # the Doppler's 0.02 m/s floor filtered
    assert np.linalg.norm(g.horizontal(g.v)[0]) == pytest.approx(50.0)  # it started drifting at 50 m/s


@pytest.mark.parametrize("case", ["hover", "ground_speed"])
def test_truth_and_estimate_differ_by_at_most_5_sigma_of_the_filters_covariance(case: str, request) -> None:
    h: Hold = request.getfixturevalue(case)
    w = h.hold
    e_up = np.abs(np.einsum("ni,ni->n", h.u, h.r - h.r_est))
    assert np.all(e_up[w] <= K_SIGMA * h.vertical_sigma()[w]), (e_up[w] / h.vertical_sigma()[w]).max()
    e_vh = np.linalg.norm(h.horizontal(h.v - h.v_est), axis=1)
    sigma_vh = h.horizontal_velocity_sigma()
    assert np.all(e_vh[w] <= K_SIGMA * sigma_vh[w]), (e_vh[w] / sigma_vh[w]).max()

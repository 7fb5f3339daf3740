"""One flight: dispersions land where they should, failures and metrics behave as defined."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_sim.physics import rotation
from lander_tools.sweep.case_scene import flown_scene, nominal_scene
from lander_tools.sweep.dispersion import FlightCase
from lander_tools.sweep.flight import fly_case
from lander_tools.sweep.metrics import settling_time as _settling_time
from lander_tools.sweep.spec import parse_spec

from .conftest import SMALL


def test_the_flown_scene_moves_exactly_what_the_case_says(small_spec):
    scene = nominal_scene(small_spec)
    case = FlightCase(index=0, seed=0, tilt=0.2, tilt_azimuth=1.0, altitude_offset=12.5,
                      velocity_W=(0.1, -0.2, 0.3), body_rate_B=(0.01, 0.0, -0.02), mass_error=0.05,
                      inertia_error=-0.1, thrust_error=(0.01, -0.02, 0.03, 0.0), wind_mean_W=(1.0, 2.0, -3.0),
                      wind_gust=0.7, failed_thruster=2, failure_time=12.5)
    flown = flown_scene(small_spec, case)
    y0, y1 = scene.initial_state, flown.initial_state
    # Geometry identities, exact up to rounding (1e-12 on O(1) and 1e-6 m on 3.4e6 m radii).
    assert np.linalg.norm(y1[0:3]) - np.linalg.norm(y0[0:3]) == pytest.approx(12.5, abs=1e-6)
    assert np.allclose(y1[3:6] - y0[3:6], case.velocity_W, atol=1e-15)
    assert np.allclose(y1[10:13] - y0[10:13], case.body_rate_B, atol=1e-15)
    z = np.array([0.0, 0.0, 1.0])
    up0, up1 = rotation.body_to_world(y0[6:10], z), rotation.body_to_world(y1[6:10], z)
    # A rotation by `tilt` about an axis perpendicular to body z turns body z by exactly `tilt`.
    assert math.acos(np.clip(up0 @ up1, -1, 1)) == pytest.approx(0.2, abs=1e-9)
    v0, v1 = scene.vehicle, flown.vehicle
    assert v1.dry_mass == pytest.approx(v0.dry_mass * 1.05, rel=1e-15)
    assert np.allclose(v1.inertia(10.0) / v1.mass(10.0), 0.9 * v0.inertia(10.0) / v0.mass(10.0), rtol=1e-14)
    assert [t.max_thrust for t in v1.thrusters] == pytest.approx(
        [t.max_thrust * (1 + e) for t, e in zip(v0.thrusters, case.thrust_error)], rel=1e-15)
    assert scene.initial_state is not flown.initial_state and y0[0] == nominal_scene(small_spec).initial_state[0]
    # Wind and failure are carried by the scene (the simulator node flies the same scene file).
    assert flown.wind_W == tuple(np.add(scene.wind_W, case.wind_mean_W))
    assert flown.gust.sigma == 0.7 and flown.gust.tau == small_spec.end.gust_time_constant
    assert [(f.thruster, f.time) for f in flown.thruster_failures] == [(2, 12.5)]


def test_failed_thruster_is_off_from_its_failure_time():
    spec = parse_spec({**SMALL, "dispersions": {
        "thruster_failure": {"probability": 1.0, "time": {"fixed": 2.0}}}, "end": {"duration": 4.0, "hover_window": 1.0}})
    res = fly_case(spec, 0, 0, record=True)
    tr, k = res.trajectory, int(res.row["failed_thruster"])
    assert 0 <= k < 4
    after = tr.t >= 2.0
    assert np.all(tr.throttles[after, k] == 0.0)
    assert np.any(tr.throttles[~after, k] > 0.0)  # it was working before (hovering needs thrust)


def test_undispersed_hover_holds_the_demand():
    # No dispersion: scenario 7 starts 50 m above its 500 m demand with poles (-0.9, -1.1); after
    # 60 s the slowest mode has decayed by e^{-0.9 * ~50} (allowing ~10 s of saturated start),
    # so only the drag/attitude coupling remains: well inside the 2 m success band.
    spec = parse_spec({**SMALL, "dispersions": {}, "end": {"duration": 60.0}})
    row = fly_case(spec, 0, 0).row
    assert row["outcome"] == "ok" and row["success"]
    assert row["hover_error"] < 0.1
    assert math.isnan(row["touchdown_speed"])
    # Fuel: hovering needs thrust ~ m g, i.e. a mean throttle near m g / (4 T_max) ~ 0.5 at full
    # tank, so about 4 x 0.5 kg/s x 0.5 x 60 s = 60 kg; the burn lightens the lander, so a bit less.
    assert 40.0 < row["fuel_used"] < 60.0


def test_a_lander_with_every_thruster_dead_falls_and_reports_its_impact_speed():
    spec = parse_spec({**SMALL, "dispersions": {"thrust_error": {"fixed": -0.99}}, "end": {"duration": 40.0}})
    row = fly_case(spec, 0, 0).row
    assert row["outcome"] == "crashed" and not row["success"]
    # Free fall from ~550 m at g = 3.7 m/s^2 (1 % thrust left, thin air): v = sqrt(2 g h) ~ 64 m/s;
    # drag and the residual thrust can only lower it, by less than 15 %.
    h0 = 550.0
    g = 3.737
    assert 0.85 * math.sqrt(2 * g * h0) < row["touchdown_speed"] <= math.sqrt(2 * g * h0) * 1.001
    assert row["flight_time"] < 40.0


def test_settling_time_of_an_exponential_is_its_closed_form():
    # e = A exp(-t) leaves |e| > b for the last time at t = ln(A/b); sampled every 0.1 s the metric
    # is the first sample after that instant, so within one sample period.
    t = np.arange(0.0, 20.0, 0.1)
    e = 40.0 * np.exp(-t)
    assert _settling_time(t, e, 0.0, 1.0) == pytest.approx(math.log(40.0), abs=0.1 + 1e-12)
    assert math.isnan(_settling_time(t, 5.0 + 0 * t, 0.0, 1.0))  # never settles
    assert _settling_time(t, 0 * t, 0.0, 1.0) == 0.0


def test_comparison_flies_both_controllers_on_the_same_case(small_spec):
    spec = dataclasses.replace(parse_spec({**SMALL, "controllers": [
        "combined", {"name": "combined", "label": "aggressive", "params": {"altitude_poles": [-1.8, -2.2]}}]}))
    a, b = fly_case(spec, 0, 2).row, fly_case(spec, 1, 2).row
    for key in ("tilt", "wind_mean", "demand_step", "mass_error", "failed_thruster"):
        assert repr(a[key]) == repr(b[key])
    assert (a["controller"], b["controller"]) == ("combined", "aggressive")
    assert a["fuel_used"] != b["fuel_used"]  # different laws, different flights


def test_gusts_come_from_the_core_model_seeded_by_the_flight(small_spec):
    # The sweep keeps no gust process of its own: the flown scene's GustProcess (tested for its
    # statistics in test/physics/test_wind.py) is seeded from (master seed, index) alone.
    c1 = FlightCase(index=3, seed=9, wind_gust=0.8)
    a, b = flown_scene(small_spec, c1), flown_scene(small_spec, c1)
    other = flown_scene(small_spec, dataclasses.replace(c1, index=4))
    assert a.gust == b.gust and a.gust.seed != other.gust.seed

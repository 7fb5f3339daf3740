"""Sweeps flown on the estimate: the spec's ``navigation``, each flight's sensor seed, the flight
built from the core parts, and the comparison of truth and estimate on the very same cases."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from lander_autopilot.controllers import make_controller
from lander_autopilot.estimation.onboard import fly_on_estimate
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation
from lander_tools.sweep.case_scene import NotRepresentable, flown_scene, nominal_scene, sensor_seed
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.flight import FlightSetupError, fly_case, navigator, preflight
from lander_tools.sweep.runner import choose_path, run_local
from lander_tools.sweep.spec import SweepSpecError, parse_spec

from .conftest import same_rows

#: landing-hover-sensors under a few of the landing sweep's dispersions, short flights from 60 m.
LANDING = {
    "name": "nav",
    "scene": "landing-hover-sensors",
    "controllers": [{"name": "landing", "label": "truth"},
                    {"name": "landing", "label": "estimate", "navigation": "estimate"}],
    "flights": 3,
    "seed": 99,
    "control_rate": 10.0,
    "end": {"duration": 40.0, "max_tilt": 1.0, "land": True},
    "dispersions": {
        "initial_tilt": {"normal": {"mean": 0.0, "std": 0.05}},
        "initial_altitude": {"uniform": {"min": -450.0, "max": -430.0}},
        "initial_velocity": {"normal": {"mean": 0.0, "std": 0.5}},
        "wind_gust": {"uniform": {"min": 0.0, "max": 1.0}},
        "mass_error": {"normal": {"mean": 0.0, "std": 0.02}},
    },
    "metrics": ["touchdown_descent_rate", "touchdown_ground_speed", "touchdown_tilt", "fuel_used", "flight_time"],
}


def spec_of(**changes):
    return parse_spec({**LANDING, **changes}, "nav.yaml")


def test_navigation_is_read_per_spec_and_per_controller():
    spec = spec_of()
    assert [c.navigation for c in spec.controllers] == ["truth", "estimate"]
    top = spec_of(navigation="estimate", controllers=["landing", {"name": "landing", "label": "t", "navigation": "truth"}])
    assert [c.navigation for c in top.controllers] == ["estimate", "truth"]
    assert [c.navigation for c in spec_of(controllers=["landing"]).controllers] == ["truth"]


@pytest.mark.parametrize(("changes", "key"), [
    ({"navigation": "gps"}, "nav.yaml: navigation: expected one of truth, estimate, got 'gps'"),
    ({"controllers": [{"name": "landing", "navigation": True}]}, "nav.yaml: controllers[0].navigation: expected one of"),
    ({"controllers": [{"name": "landing", "navigate": "estimate"}]}, "nav.yaml: controllers[0].navigate: unknown key"),
])
def test_a_bad_navigation_is_refused_naming_the_key(changes, key):
    with pytest.raises(SweepSpecError) as err:
        spec_of(**changes)
    assert str(err.value).startswith(key)
    assert "\n" not in str(err.value)


def test_flying_on_the_estimate_needs_a_scene_with_the_imu():
    spec = spec_of(scene="landing-hover")
    with pytest.raises(FlightSetupError, match=r"controllers\[1\]\.navigation: estimate: scene 'landing-hover' has no sensors.imu"):
        preflight(spec)
    preflight(spec_of())  # the scene with sensors is fine


def test_the_landing_law_on_the_estimate_flies_per_flight_and_not_through_ros(tmp_path):
    path, why = choose_path(spec_of(), "auto", None)
    assert path == "per-flight" and why  # the landing law has no compiled form; numba's absence is a reason too
    from lander_tools.sweep.ros_path import plan_for_case

    with pytest.raises(NotRepresentable, match="flies on the estimate"):
        plan_for_case(spec_of(), 1, 0, tmp_path, None)


def test_each_flight_has_its_own_sensor_seed_and_the_case_is_unchanged():
    spec = spec_of()
    n = nominal_scene(spec).vehicle.n_thrusters
    cases = [draw_case(spec, i, n) for i in range(3)]
    seeds = [flown_scene(spec, c).sensors.seed for c in cases]
    assert seeds == [sensor_seed(c) for c in cases]
    assert len(set(seeds)) == 3 and all(0 <= s < 2**63 for s in seeds)
    # the sensor seed has its own stream: the case's draws are those of the scene without sensors
    plain = dataclasses.replace(spec, scene="landing-hover")
    assert [draw_case(plain, i, n) for i in range(3)] == cases
    assert flown_scene(plain, cases[0]).sensors is None


def test_the_sweeps_flight_on_the_estimate_is_the_core_flight_on_the_estimate_bit_for_bit():
    """fly_case on the estimate = the core's flight on the estimate (onboard.fly_on_estimate) of the
    flight's scene, with its (per-flight) sensor seed and the compiled filter, the law every 0.1 s."""
    spec = spec_of()
    index = 1
    got = fly_case(spec, 1, index, record=True).trajectory
    scene = flown_scene(spec, draw_case(spec, index, nominal_scene(spec).vehicle.n_thrusters))
    law = make_controller("landing", nominal_scene(spec).vehicle)  # designed on the nominal vehicle, as the sweep's
    core = fly_on_estimate(scene, spec.end.duration, compiled=True, controller=law)
    assert core.end == "LANDED"
    assert len(core.t) == len(got.t)
    assert np.array_equal(np.asarray(core.throttles), got.throttles)
    # the law flew on an estimate, not on the truth: metres apart (the initial 10 m, unobserved across)
    assert 0.5 < np.linalg.norm(core.r_true[-1] - core.r_estimate[-1]) < 100.0


def test_comparison_rows_pair_the_same_cases_and_truth_ignores_the_sensors():
    spec = spec_of()
    res = run_local(spec, workers=1, progress=False, path="per-flight")
    rows = list(res.rows)
    assert [(r["index"], r["controller"]) for r in rows] == [(i, c) for i in range(3) for c in ("truth", "estimate")]
    case_cols = ("tilt", "altitude_offset", "velocity_offset", "wind_gust", "mass_error")
    for truth, est in zip(rows[0::2], rows[1::2]):
        assert all(truth[c] == est[c] for c in case_cols)
        assert truth["outcome"] == est["outcome"] == "landed"
        # the law's errors on the estimate are its navigation errors: the flights differ
        assert truth["flight_time"] != est["flight_time"] or truth["fuel_used"] != est["fuel_used"]
    # the truth flights are those of the scene without sensors, bit for bit: sensors only observe
    plain = dataclasses.replace(spec, scene="landing-hover", controllers=spec.controllers[:1])
    assert same_rows(rows[0::2], run_local(plain, workers=1, progress=False, path="per-flight").rows)


def test_an_imu_slower_than_the_step_is_refused_before_any_flight(tmp_path):
    """The filter propagates on each step's IMU reading: a 5 Hz IMU at the 0.1 s step cannot feed it."""
    data = yaml.safe_load(Path(load_scene("landing-hover-sensors").source).read_text())
    data["name"] = "slow-imu"
    data["sensors"]["imu"] = {"rate": 5.0}
    path = tmp_path / "slow-imu.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(FlightSetupError, match=r"sensors.imu.rate \(5 Hz\) must sample every 0.1 s step"):
        preflight(spec_of(scene=str(path)))


def test_sensor_error_dispersions_scale_the_flown_sensors_and_not_the_filters_model():
    spec = spec_of(dispersions={**LANDING["dispersions"],
                                "sensor_noise_error": {"uniform": {"min": 0.5, "max": 0.6}},
                                "sensor_bias_error": {"fixed": -0.25}})
    nominal = nominal_scene(spec).sensors.sections
    case = draw_case(spec, 2, nominal_scene(spec).vehicle.n_thrusters)
    assert 0.5 <= case.sensor_noise_error <= 0.6 and case.sensor_bias_error == -0.25
    # their own streams: the other draws are those of the spec without them
    assert dataclasses.replace(case, sensor_noise_error=0.0, sensor_bias_error=0.0) == draw_case(
        spec_of(), 2, nominal_scene(spec).vehicle.n_thrusters)
    flown = flown_scene(spec, case).sensors.sections
    k_noise, k_bias = 1.0 + case.sensor_noise_error, 0.75
    assert flown["imu"]["gyro_noise_density"] == nominal["imu"]["gyro_noise_density"] * k_noise
    assert flown["altimeter"]["noise_floor"] == nominal["altimeter"]["noise_floor"] * k_noise
    assert flown["doppler"]["noise_fraction"] == nominal["doppler"]["noise_fraction"] * k_noise
    assert flown["imu"]["accel_bias"] == nominal["imu"]["accel_bias"] * k_bias
    assert flown["imu"]["gyro_bias_walk"] == nominal["imu"]["gyro_bias_walk"] * k_bias
    assert all(flown[k]["rate"] == nominal[k]["rate"] for k in nominal)
    # the filter models the nominal IMU (noise densities, and the switch-on bias variance in P0)
    sim = Simulation(flown_scene(spec, case))
    filt = navigator(spec, 1, sim).feeder.filter
    assert filt.noise.gyro_noise_density == nominal["imu"]["gyro_noise_density"]
    assert filt.state.P[9, 9] == nominal["imu"]["gyro_bias"] ** 2
    assert fly_case(spec, 1, 2).row["sensor_noise_error"] == case.sensor_noise_error


def test_sensor_error_dispersions_need_a_scene_with_sensors():
    spec = spec_of(scene="landing-hover", controllers=["landing"],
                   dispersions={"sensor_noise_error": {"fixed": 0.1}})
    with pytest.raises(NotRepresentable, match="dispersions.sensor_noise_error: scene 'landing-hover' has no sensors"):
        preflight(spec)


def test_flights_on_the_estimate_are_the_same_bits_on_two_workers_as_in_this_process():
    spec = spec_of(controllers=[{"name": "landing", "label": "estimate", "navigation": "estimate"}], flights=2)
    one = run_local(spec, workers=1, progress=False)
    two = run_local(spec, workers=2, progress=False)
    assert one.path == two.path == "per-flight"
    assert same_rows(one.rows, two.rows)

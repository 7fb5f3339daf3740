"""--through-ros: cases flown by the simulator and autopilot nodes (lockstep) give the core-only
metrics. Needs the ROS environment: run with ``./dev test test/sweep/test_through_ros.py``."""
from __future__ import annotations

import pytest

from lander_tools.sweep.spec import parse_spec

from .conftest import SMALL

pytest.importorskip("rclpy", reason="the ROS nodes need the project environment: ./dev test")


def test_every_dispersion_flown_through_the_nodes_matches_core_only(tmp_path):
    # Every dispersion of SMALL, the demand step at 1 s included (the launcher pauses the sim at
    # its instant), with a thruster failure for sure at 1.5 s: same scene, same equations, same
    # control instants and exact float64 states over the middleware, so the metrics must agree to
    # round-off (ros_path.RTOL = 1e-9 relative), not merely statistically.
    from lander_tools.sweep.ros_path import RTOL, through_ros

    disp = dict(SMALL["dispersions"])
    disp["thruster_failure"] = {"probability": 1.0, "time": {"fixed": 1.5}}
    spec = parse_spec({**SMALL, "flights": 1, "dispersions": disp,
                       "end": {"duration": 4.0, "demand_step_time": 1.0, "hover_window": 1.0}})
    from lander_tools.sweep.case_scene import nominal_scene
    from lander_tools.sweep.dispersion import draw_case

    assert draw_case(spec, 0, nominal_scene(spec).vehicle.n_thrusters).demand_step != 0.0  # a step is flown
    check = through_ros(spec, 1, tmp_path)
    assert check.agree, check.summary()
    assert len(check.ros_rows) == 1 and RTOL <= 1e-9
    assert check.ros_rows[0]["failed_thruster"] >= 0


def test_a_hover_hold_case_with_the_de_orbit_dispersions_matches_core_only(tmp_path):
    # The scene file carries the orbit (here: the start moved 3 m along r_hat, at rest) and the
    # flown air density; the bag is cut where the core-only loop stopped (the hold), and the
    # measured compute time is left out of the comparison. (A thruster cant has no scene key yet.)
    from lander_tools.sweep.ros_path import through_ros

    spec = parse_spec({**SMALL, "scene": "hover-canted", "flights": 1,
                       "dispersions": {"orbit_altitude": {"fixed": 3.0}, "density_error": {"fixed": 0.25},
                                       "wind_gust": {"fixed": 0.3}},
                       "end": {"duration": 12.0, "hover_window": 1.0, "hover_hold": 2.0, "hover_speed": 0.5},
                       "metrics": ["hover_time", "fuel_left", "flight_time", "max_tilt", "compute_time"]})
    check = through_ros(spec, 1, tmp_path)
    assert check.agree, check.summary()
    core, ros = check.core_rows[0], check.ros_rows[0]
    assert core["outcome"] == ros["outcome"] == "hovered" and ros["flight_time"] < 12.0
    assert ros["compute_time"] != ros["compute_time"]  # NaN: a bag has no compute time


def test_a_case_with_a_thruster_cant_is_reported_not_flown_through_ros(tmp_path):
    from lander_tools.sweep.ros_path import through_ros

    spec = parse_spec({**SMALL, "scene": "hover-canted", "flights": 1, "end": {"duration": 1.0, "hover_window": 1.0},
                       "dispersions": {"thruster_cant_error": {"fixed": 0.005}}})
    check = through_ros(spec, 1, tmp_path)
    assert not check.agree and not check.ros_rows
    assert "cannot be flown through ROS: dispersions.thruster_cant_error" in check.mismatches[0]

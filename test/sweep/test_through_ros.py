"""--through-ros: cases flown by the simulator and autopilot nodes (lockstep) give the core-only
metrics. Needs the ROS environment: run with ``./dev test test/sweep/test_through_ros.py``."""
from __future__ import annotations

import pytest

from lander_tools.sweep.spec import parse_spec

from .conftest import SMALL

pytest.importorskip("rclpy", reason="the ROS nodes need the project environment: ./dev test")


def test_every_dispersion_flown_through_the_nodes_matches_core_only(tmp_path):
    # Every dispersion of SMALL except the demand step (whose instant the nodes do not yet pin down,
    # docs/sweeps.md), with a thruster failure for sure at 1.5 s: same scene, same equations, same
    # control instants and exact float64 states over the middleware, so the metrics must agree to
    # round-off (ros_path.RTOL = 1e-9 relative), not merely statistically.
    from lander_tools.sweep.ros_path import RTOL, through_ros

    disp = {k: v for k, v in SMALL["dispersions"].items() if k != "demand_altitude_step"}
    disp["thruster_failure"] = {"probability": 1.0, "time": {"fixed": 1.5}}
    spec = parse_spec({**SMALL, "flights": 1, "dispersions": disp,
                       "end": {"duration": 4.0, "demand_step_time": 1.0, "hover_window": 1.0}})
    check = through_ros(spec, 1, tmp_path)
    assert check.agree and not check.demand_timing, check.summary()
    assert len(check.ros_rows) == 1 and RTOL <= 1e-9
    assert check.ros_rows[0]["failed_thruster"] >= 0

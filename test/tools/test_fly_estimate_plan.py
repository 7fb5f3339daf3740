"""``lander fly --estimate`` as a plan (no ROS): the processes it starts with their parameters, and
the plans it refuses before anything starts."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from lander_tools.fly.checks import check_plan
from lander_tools.fly.plan import FlightPlan, LaunchError
from lander_tools.fly.processes import node_commands


def _params(argv: list[str]) -> dict:
    path = Path(argv[argv.index("--params-file") + 1])
    (section,) = yaml.safe_load(path.read_text()).values()
    return section["ros__parameters"]


def test_the_estimator_starts_beside_the_sim_and_the_autopilot_flies_on_its_estimate(tmp_path: Path) -> None:
    plan = FlightPlan(scene="landing-sensors", speed=0.0, estimate=True, sim_params={"seed": 7})
    cmds = node_commands(plan, check_plan(plan), tmp_path, flight_id="f00d")
    assert set(cmds) == {"sim", "autopilot", "estimator"}
    assert _params(cmds["estimator"]) == {"scene": "landing-sensors", "seed": 7, "flight_id": "f00d"}
    assert _params(cmds["autopilot"])["state_source"] == "estimate"
    assert _params(cmds["sim"])["lockstep"] is True


def test_without_estimate_nothing_changes(tmp_path: Path) -> None:
    plan = FlightPlan(scene="landing-sensors", speed=0.0)
    cmds = node_commands(plan, check_plan(plan), tmp_path)
    assert set(cmds) == {"sim", "autopilot"} and "state_source" not in _params(cmds["autopilot"])


def test_a_scene_without_an_imu_is_refused_naming_it() -> None:
    with pytest.raises(LaunchError, match="--estimate: scene 'hover' switches no IMU on"):
        check_plan(FlightPlan(scene="hover", estimate=True))


def test_estimate_does_not_go_with_compose() -> None:
    with pytest.raises(LaunchError, match="does not go with --compose"):
        FlightPlan(scene="landing-sensors", estimate=True, compose=True)

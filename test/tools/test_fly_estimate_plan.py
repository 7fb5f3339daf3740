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


# --- what a law that plans from its first state is told of the navigation error -------------------

def _controller_params(cmds: dict[str, list[str]]) -> dict:
    from lander_autopilot.ros.config import parse_controller_params

    return parse_controller_params(_params(cmds["autopilot"]).get("controller_params", ""))


def _estimator_sigmas() -> dict[str, float]:
    """The estimator node's initial sigmas (its parameter table's defaults, which lander fly keeps)."""
    from lander_autopilot.ros.estimator_config import SPECS

    return {"navigation_position_sigma": SPECS["initial_position_sigma"].default,
            "navigation_velocity_sigma": SPECS["initial_velocity_sigma"].default}


@pytest.mark.parametrize("controller", [None, "deorbit-mpc"])
def test_a_de_orbit_law_on_the_estimate_plans_with_the_estimators_initial_sigmas(tmp_path: Path, controller) -> None:
    """The burn is planned from the first estimate, whose error the filter's initial covariance bounds."""
    plan = FlightPlan(scene="deorbit-sensors", controller=controller, speed=0.0, estimate=True)
    params = _controller_params(node_commands(plan, check_plan(plan), tmp_path))
    assert params == _estimator_sigmas() == {"navigation_position_sigma": 10.0, "navigation_velocity_sigma": 0.5}


def test_a_navigation_sigma_the_user_gives_stands_and_the_other_parameters_are_kept(tmp_path: Path) -> None:
    plan = FlightPlan(scene="deorbit-sensors", speed=0.0, estimate=True,
                      controller_params={"navigation_velocity_sigma": 0.2, "slew_time": 30.0})
    params = _controller_params(node_commands(plan, check_plan(plan), tmp_path))
    assert params == {"navigation_velocity_sigma": 0.2, "slew_time": 30.0,
                      "navigation_position_sigma": _estimator_sigmas()["navigation_position_sigma"]}


def test_on_the_truth_the_de_orbit_law_is_told_no_navigation_error(tmp_path: Path) -> None:
    """A flight on the truth is launched as it always was: the law's defaults (0: the truth)."""
    plan = FlightPlan(scene="deorbit-sensors", speed=0.0)
    assert "controller_params" not in _params(node_commands(plan, check_plan(plan), tmp_path)["autopilot"])


def test_a_law_without_navigation_rows_flies_its_parameters_unchanged(tmp_path: Path) -> None:
    plan = FlightPlan(scene="landing-sensors", speed=0.0, estimate=True)
    assert "controller_params" not in _params(node_commands(plan, check_plan(plan), tmp_path)["autopilot"])
    plan = FlightPlan(scene="landing-sensors", speed=0.0, estimate=True, controller_params={"parachute": False})
    assert _controller_params(node_commands(plan, check_plan(plan), tmp_path)) == {"parachute": False}


def test_a_scripted_flight_flies_on_the_estimate_with_estimate_true(tmp_path: Path) -> None:
    from lander_tools.scripted import ScriptError, load_script, parse_script

    repo = Path(__file__).resolve().parents[2]
    plan = load_script(repo / "flights" / "deorbit-sensors-to-landing.yaml").plan()
    assert plan.estimate and plan.scene == "deorbit-sensors"
    # the flight's own parameter stands beside the sigmas the launcher adds
    assert _controller_params(node_commands(plan, check_plan(plan), tmp_path)) == {"land_after_hover": 30.0,
                                                                                   **_estimator_sigmas()}
    assert not parse_script({"scene": "hover", "end": {"time": 1.0}}).plan().estimate
    with pytest.raises(ScriptError, match="estimate: expected true or false, got 'yes'"):
        parse_script({"scene": "hover", "end": {"time": 1.0}, "estimate": "yes"})

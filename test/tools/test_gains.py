"""Gains from design to flight, the pure parts: the gains file `lander design --write` writes holds
the design's K verbatim and builds the same law the poles build; a file for another controller, with
unknown names or gains of the wrong shape is one line; `--set` values are read as YAML; the
controllability warning names the axes a scene's thrusters cannot reach (`lander fly` itself:
test/flights/test_gains_flight.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lander_autopilot.controllers import make_controller
from lander_autopilot.design.report import design_report
from lander_autopilot.ros.config import parse_controller_params
from lander_sim.scenes import load_scene
from lander_tools import cli
from lander_tools.fly.checks import controllability_warning
from lander_tools.fly.plan import FlightPlan
from lander_tools.gains import GainsError, apply_gains, controller_params_text, gains_text, parse_sets, read_gains


def test_the_written_gains_build_the_law_the_poles_build(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "gains.yaml"
    assert cli.main(["design", "hover-canted", "--altitude-poles", "-0.9", "-1.1", "--write", str(path)]) == 0
    assert f"lander fly hover-canted --gains {path}" in capsys.readouterr().out
    controller, params = read_gains(path)
    assert controller == "combined" and set(params) == {"K_altitude", "K_attitude", "design_fuel"}
    scene = load_scene("hover-canted")
    fuel = float(scene.initial_state[13])
    rep = design_report(scene.vehicle, fuel, 500.0, (-0.9, -1.1), (-1.0,) * 6)
    # K verbatim: every bit of the report's gain survives the file (YAML writes floats by repr).
    assert params["K_altitude"] == rep["altitude"]["placement"]["K"]
    assert params["K_attitude"] == rep["attitude"]["placement"]["K"]
    assert params["design_fuel"] == fuel
    from_file = make_controller(controller, scene.vehicle, **params).gains()
    from_poles = make_controller("combined", scene.vehicle, altitude_poles=[-0.9, -1.1], design_fuel=fuel).gains()
    # Same design (place / place_varga at the same fuel): equal to the solver's round-off.
    for name in ("K_altitude", "K_attitude"):
        np.testing.assert_allclose(from_file[name], from_poles[name], rtol=0, atol=1e-9)
    # eq 20's closed form at the seed's poles, the figure docs/control.md quotes for this lander.
    np.testing.assert_allclose(from_file["K_altitude"], [[0.13655, 0.27586]], atol=5e-6)


def test_a_gains_file_for_another_controller_or_with_unknown_names_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "gains.yaml"
    assert cli.main(["design", "hover-canted", "--controller", "altitude", "--write", str(path)]) == 0
    plan = FlightPlan(scene="hover-canted")
    with pytest.raises(GainsError, match=r"holds gains for controller 'altitude', but --controller is 'lqr'"):
        apply_gains(plan, path, [], explicit_controller="lqr")
    apply_gains(plan, path, [], explicit_controller=None)
    assert plan.controller == "altitude" and set(plan.controller_params) == {"K", "design_fuel"}

    bad = tmp_path / "bad.yaml"
    bad.write_text("autopilot:\n  ros__parameters:\n    controller: altitude\n"
                   "    controller_params: '{kp: 0.2}'\n")
    with pytest.raises(GainsError) as err:
        apply_gains(FlightPlan(scene="hover"), bad, [], None)
    assert str(err.value).startswith(f"--gains {bad}: controller 'altitude': unknown parameter(s) kp; accepted: K")
    # Gains for four thrusters flown by a lander of one: the shape is the law's check.
    three = tmp_path / "three.yaml"
    three.write_text("autopilot:\n  ros__parameters:\n    controller: attitude-euler\n"
                     "    controller_params: '{K: [[1, 0, 0, 0, 0, 0]]}'\n")
    with pytest.raises(GainsError, match=r"K: expected shape \(4, 6\), got \(1, 6\)"):
        apply_gains(FlightPlan(scene="hover"), three, [], None)
    other = tmp_path / "sim.yaml"
    other.write_text("lander_sim:\n  ros__parameters:\n    dt: 0.01\n")
    with pytest.raises(GainsError, match="holds the autopilot's section only"):
        read_gains(other)
    extra = tmp_path / "extra.yaml"
    extra.write_text("autopilot:\n  ros__parameters:\n    controller: altitude\n    demand_altitude: 5.0\n")
    with pytest.raises(GainsError, match="unknown key\\(s\\) demand_altitude"):
        read_gains(extra)


def test_the_controller_params_text_is_one_line_the_autopilot_reads_back_bit_for_bit(tmp_path: Path) -> None:
    """The one text of a law's parameters (gains file, `lander switch --gains`, the page): one line
    however long, and what the autopilot parses from it is every float as given (YAML writes repr)."""
    params = {"K_altitude": [[0.1 + 0.2, 1.0 / 3.0]], "K_attitude": [[2.0 ** -40] * 6] * 4, "design_fuel": 100.0}
    text = controller_params_text(params)
    assert "\n" not in text and text.startswith("{") and text.endswith("}")
    assert parse_controller_params(text) == params
    path = tmp_path / "gains.yaml"
    path.write_text(gains_text("combined", params))
    assert read_gains(path) == ("combined", params)


def test_set_reads_yaml_values_on_top_of_the_scene_parameters() -> None:
    assert parse_sets(["kp=0.2", "altitude_poles=[-0.5, -0.6]", "K=null"]) == {
        "kp": 0.2, "altitude_poles": [-0.5, -0.6], "K": None}
    with pytest.raises(GainsError, match="expected NAME=VALUE"):
        parse_sets(["kp"])
    plan = FlightPlan(scene="hover")  # the scene's law: baseline
    apply_gains(plan, None, ["kd=0.3"], None)
    assert plan.controller == "baseline" and plan.controller_params == {"kd": 0.3}
    with pytest.raises(GainsError, match="--set: controller 'baseline': kp: expected a finite number"):
        apply_gains(FlightPlan(scene="hover"), None, ["kp=fast"], None)
    with pytest.raises(GainsError, match="scene 'free-spin' flies no autopilot: name the law with --controller"):
        apply_gains(FlightPlan(scene="8"), None, ["kp=0.2"], None)
    plan = FlightPlan(scene="8", controller="attitude-quaternion")
    apply_gains(plan, None, ["poles=[-2, -2, -2, -2, -2, -2]"], None)  # canted or not, poles place what they can
    assert plan.controller_params == {"poles": [-2, -2, -2, -2, -2, -2]}


def test_the_warning_names_the_axes_the_scene_thrusters_cannot_control() -> None:
    # Scenario 8: one vertical thruster, a torque about one body axis only: rank 2 of eq 6's 6.
    line = controllability_warning("8", "combined")
    assert line is not None and "scene 'free-spin'" in line and "attitude controllability rank 2 of 6" in line
    # Vertical thrusters: no torque about body z, exactly psi and wz (docs/control.md).
    line = controllability_warning("tumbling-descent", "combined")
    assert line is not None and "rank 4 of 6 (the uncontrollable directions involve psi, wz)" in line
    assert controllability_warning("free-spin-canted", "combined") is None  # canted: rank 6
    assert controllability_warning("8", "baseline") is None  # an altitude law: eq 16 is rank 2 of 2
    assert controllability_warning("8", None) is None  # the sim alone


def test_each_law_reports_the_gains_it_flies_in_one_line() -> None:
    from lander_autopilot.ros.loop_stats import format_gains

    vehicle = load_scene("hover").vehicle
    assert format_gains(make_controller("baseline", vehicle, kp=0.2, kd=0.3).gains()) == "kp 0.2, kd 0.3"
    K = [[0.1, 0.25]]
    assert format_gains(make_controller("altitude", vehicle, K=K).gains()) == "K [[0.1, 0.25]]"
    combined = make_controller("combined", vehicle, K_altitude=K).gains()
    assert list(combined) == ["K_altitude", "K_attitude"] and combined["K_attitude"].shape == (4, 6)


def test_a_gains_file_given_as_params_flies_the_controller_it_names(tmp_path: Path) -> None:
    from lander_tools.fly.checks import resolve_controller

    path = tmp_path / "gains.yaml"
    assert cli.main(["design", "hover", "--write", str(path)]) == 0
    # The scene's own law is baseline; the file's gains are combined's and only combined takes them.
    assert resolve_controller(FlightPlan(scene="hover", params_file=path)) == "combined"
    assert resolve_controller(FlightPlan(scene="hover", params_file=path, controller="lqr")) == "lqr"
    assert resolve_controller(FlightPlan(scene="hover")) == "baseline"

"""lander_ros.params: the overrides a node is started with, read as rcl reads them, and checked
with the node's own specs (both nodes use this one path; rcl alone would ignore a typo)."""
from __future__ import annotations

from pathlib import Path

import pytest

from lander_ros.params import ParamSpec, check_overrides, command_line_overrides, positive, string

SPECS = {"speed": ParamSpec("speed", 1.0, "", positive), "scene": ParamSpec("scene", "hover", "", string)}


def test_p_arguments_for_this_node_and_unprefixed_ones_are_read_with_yaml_values() -> None:
    argv = ["prog", "--ros-args", "-p", "speed:=2", "--param", "sim:scene:=rotor", "-p", "other:speed:=9",
            "-r", "__node:=sim", "--", "-p", "speed:=7"]
    assert command_line_overrides(argv, "sim") == {"speed": (2, "-p"), "scene": ("rotor", "-p")}


def test_params_file_sections_for_the_node_and_for_every_node(tmp_path: Path) -> None:
    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters: {speed: 3.0, scene: a}\nsim:\n  ros__parameters: {scene: b}\n"
                 "other:\n  ros__parameters: {speed: 5.0}\n")
    got = command_line_overrides(["prog", "--ros-args", "--params-file", str(f)], "sim")
    assert got == {"speed": (3.0, str(f)), "scene": ("b", str(f))}


def test_an_unknown_name_or_a_bad_value_is_refused_naming_it_and_where(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"^unknown parameter 'sped'; known: scene, speed$"):
        check_overrides(SPECS, ["prog", "--ros-args", "-p", "sped:=2.0"], "sim")
    f = tmp_path / "p.yaml"
    f.write_text("sim:\n  ros__parameters: {speed: -1.0}\n")
    with pytest.raises(ValueError, match=rf"^{f}: parameter 'speed' = -1.0 must be a finite number > 0$"):
        check_overrides(SPECS, ["prog", "--ros-args", "--params-file", str(f)], "sim")
    # an integer literal for a float parameter, and the ROS built-ins, pass
    assert check_overrides(SPECS, ["prog", "--ros-args", "-p", "speed:=2", "-p", "use_sim_time:=true"], "sim") == {
        "speed": 2, "use_sim_time": True}

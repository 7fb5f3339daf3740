"""Scene files: every packaged scene loads; bad files name the file, the key and the expectation."""
from __future__ import annotations

import numpy as np
import pytest

from lander_sim.scenes import SceneError, list_scenes, load_scene

NUMBERED = {"0": "circular-orbit", "1": "descent-10km", "2": "elliptical-orbit", "3": "polar-launch",
            "4": "decaying-orbit", "5": "descent-200km", "6": "tumbling-descent", "7": "hover", "8": "free-spin"}


def test_every_packaged_scene_loads_and_original_numbers_are_aliases():
    infos = list_scenes()
    assert len({i.name for i in infos}) == len(infos)
    for info in infos:
        s = load_scene(info.name)
        assert s.name == info.name and s.dt > 0
        if s.attitude == "quaternion":
            assert abs(np.linalg.norm(s.initial_state[6:10]) - 1.0) < 1e-12
    for num, name in NUMBERED.items():
        assert load_scene(num).name == name
    assert load_scene("rotor").name == "rotor-quaternion"


def test_scenario_initial_conditions_follow_the_original_scenarios():
    R = 3386e3
    hover = load_scene("7")
    assert np.allclose(hover.initial_state[0:3], [0, -(R + 550), 0])
    assert np.allclose(hover.initial_state[6:10], np.array([0.8, 0.7, 0.1, 0.0]) / np.linalg.norm([0.8, 0.7, 0.1]))
    assert hover.autopilot is not None and isinstance(hover.autopilot.controller, str)
    assert load_scene("hover-canted").vehicle.thrusters[0].direction_B[0] > 0
    assert load_scene("1").stabiliser and not load_scene("6").stabiliser
    rotor = load_scene("rotor-euler")
    assert rotor.attitude == "euler" and not rotor.translation and rotor.dt == 0.01
    assert np.allclose(rotor.initial_state[6:9], [0, np.pi / 2, 0])


def write(tmp_path, text: str):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    return p


BASE = "vehicle: {preset: lander}\ninitial: {position_W: [0, -3396000.0, 0]}\ndt: 0.1\n"


@pytest.mark.parametrize(
    "extra, match",
    [
        ("models: {drag: {kind: cone}}\n", r"bad\.yaml: models\.drag\.kind: expected one of sphere, mesh, got 'cone'"),
        ("colour: red\n", r"bad\.yaml: colour: unknown key; allowed keys: .*aliases"),
        ("integrator: leapfrog\n", r"bad\.yaml: integrator: expected one of .*verlet.*got 'leapfrog'"),
        ("models: {drag: {kind: sphere}}\n", r"bad\.yaml: models\.drag: needs air"),
        ("models: {gravity: {kind: inverse-square}, thrusters: {foo: 1}}\n", r"models\.thrusters\.foo: unknown key"),
        ("autopilot: {gains: 3}\n", r"bad\.yaml: autopilot: expected null or a mapping with a string 'controller'"),
        ("gimbal_threshold: -1\n", r"gimbal_threshold: expected a number > 0.0, got -1"),
        ("attitude_mode: matrix\n", r"attitude_mode: expected one of quaternion, euler"),
    ],
)
def test_bad_scene_errors_name_file_key_and_expectation(tmp_path, extra, match):
    with pytest.raises(SceneError, match=match):
        load_scene(write(tmp_path, BASE + extra))


def test_bad_yaml_missing_file_and_unknown_scene(tmp_path):
    with pytest.raises(SceneError, match=r"bad\.yaml: not valid YAML"):
        load_scene(write(tmp_path, "dt: [0.1\n"))
    with pytest.raises(SceneError, match=r"bad\.yaml: vehicle: missing required key"):
        load_scene(write(tmp_path, "initial: {}\ndt: 0.1\n"))
    with pytest.raises(SceneError, match=r"initial\.fuel: expected a number <= 100"):
        load_scene(write(tmp_path, BASE.replace("initial: {", "initial: {fuel: 150, ")))
    with pytest.raises(SceneError, match=r"vehicle\.disabled\[0\]: expected a thruster index 0\.\.3, got 7"):
        load_scene(write(tmp_path, BASE.replace("{preset: lander}", "{preset: lander, disabled: [7]}")))
    with pytest.raises(SceneError, match=r"unknown scene 'nowhere'; choose one of: .*hover \(7\)"):
        load_scene("nowhere")
    assert issubclass(SceneError, ValueError)

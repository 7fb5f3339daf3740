"""The node's plain-Python parts, without middleware: parameters, message conversion, the slot."""
from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from lander_autopilot.controllers import ControlOutput, Demand, make_controller
from lander_autopilot.ros.config import (
    ConfigError,
    dump_controller_params,
    parse_controller_params,
    scene_autopilot,
)
from lander_autopilot.ros.convert import StateError, state_view
from lander_autopilot.ros.slot import ControllerSlot, OutputError, build_choice
from lander_interfaces.msg import LanderState
from lander_sim.physics import rotation
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.ros.convert import fill_state
from lander_sim.scenes import Scene, SceneError, load_scene, parse_scene


def test_controller_params_parse_and_dump_round_trip():
    params = {"altitude_poles": [-0.9, -1.1], "K": [[1.0, 2.0]]}
    assert parse_controller_params(dump_controller_params(params)) == params
    assert parse_controller_params("") == {} and parse_controller_params("  ") == {}


@pytest.mark.parametrize("text, words", [("[1, 2]", "mapping"), ("{a: [1, 2", "not valid YAML"), ("{1: 2}", "mapping")])
def test_bad_controller_params_are_refused_naming_the_parameter(text, words):
    with pytest.raises(ConfigError, match="controller_params") as err:
        parse_controller_params(text)
    assert words in str(err.value)


def test_the_scene_autopilot_section_gives_the_defaults_and_unknown_keys_are_named():
    """Parsed once, by the scene loader (AutopilotSection); the autopilot completes it with defaults."""
    hover = load_scene("hover")
    assert hover.autopilot is not None
    assert scene_autopilot(hover).controller == hover.autopilot.controller
    assert scene_autopilot(hover).demand_altitude == 500.0
    custom = _hover_with_autopilot({"controller": "lqr", "parameters": {"R_altitude": 10.0}, "demand_altitude": 650})
    got = scene_autopilot(custom)
    assert (got.controller, dict(got.parameters), got.demand_altitude) == ("lqr", {"R_altitude": 10.0}, 650.0)
    with pytest.raises(SceneError, match=r"hover.yaml: autopilot\.gains: unknown key"):
        _hover_with_autopilot({"controller": "lqr", "gains": [1]})


def _hover_with_autopilot(section: dict[str, object]) -> Scene:
    import yaml

    data = yaml.safe_load(load_scene("hover").source.read_text())
    data["autopilot"] = section
    return parse_scene(data, "hover.yaml")


def _snapshot(t: float, q: np.ndarray, n: int = 4) -> SimpleNamespace:
    return SimpleNamespace(
        t=t, r_W=np.array((1.5, -(MARS_RADIUS + 512.25), -0.75)), v_W=np.array((0.1, -0.2, 0.3)), q=q,
        euler=rotation.quat_to_euler(q), gimbal_lock=False, omega_B=np.array((0.01, -0.02, 0.03)),
        altitude=512.25, climb_rate=0.2, ground_speed=0.1, mass=190.0, fuel=90.0, throttles=np.full(n, 0.5),
        phase=0, parachute_deployed=False, stabiliser_on=False,
    )


def test_a_state_written_by_the_simulator_reads_back_as_the_same_core_state():
    """Round trip core -> sim's writer -> this reader: positions, rates, quaternion exact (copies of
    doubles); the time to the stamp's 1 ns resolution."""
    q = rotation.quat_normalise(np.array((0.8, 0.7, 0.1, 0.0)))
    snap = _snapshot(12.3456789012, q)
    msg = LanderState()
    fill_state(msg, 7, snap)
    s = state_view(msg, n_thrusters=4)
    for got, want in ((s.r_W, snap.r_W), (s.v_W, snap.v_W), (s.q, q), (s.omega_B, snap.omega_B), (s.euler, snap.euler)):
        assert got.tolist() == want.tolist()
    assert s.fuel == 90.0 and abs(s.t - snap.t) <= 1e-9
    # The ROS orientation rotates body into world: the body z axis seen in the world frame is
    # R(q)^T e_z, i.e. the core's body_to_world (eq 12-13), whichever way it is read.
    assert np.allclose(rotation.body_to_world(s.q, np.array((0, 0, 1.0))), rotation.quat_to_matrix(q)[2], atol=1e-15)


def test_a_state_that_cannot_be_flown_is_refused_naming_the_field():
    msg = LanderState()
    fill_state(msg, 3, _snapshot(1.0, np.array((1.0, 0, 0, 0))))
    msg.angular_velocity.y = math.inf
    with pytest.raises(StateError, match="state 3: angular_velocity is not finite"):
        state_view(msg)
    fill_state(msg, 4, _snapshot(1.0, np.array((1.0, 0, 0, 0)), n=1))
    with pytest.raises(StateError, match="reports 1 thrusters but the controller was built for 4"):
        state_view(msg, n_thrusters=4)


def _state(seq: int, h: float) -> tuple:
    msg = LanderState()
    fill_state(msg, seq, _snapshot(0.1 * seq, rotation.euler_to_quat(np.array((0.0, math.pi / 2, 0.0)))))
    msg.position.y = -(MARS_RADIUS + h)
    return state_view(msg), msg.sequence


def test_a_restarted_sequence_resets_the_controller_memory():
    """After a simulator reset (sequence back to 1) an integral law answers like a fresh one."""
    slots = [ControllerSlot(build_choice("hover-canted", "integral", {}), Demand(altitude=500.0)) for _ in range(2)]
    for slot in slots:
        for k in range(1, 30):
            slot.step(*_state(k, 499.5))  # 0.5 m low for 3 s (unsaturated): the integrator fills
    fresh = make_controller("integral", load_scene("hover-canted").vehicle)
    state, _ = _state(1, 499.5)
    want = fresh.update(state.t, state, Demand(altitude=500.0)).throttles.tolist()
    assert slots[0].step(state, 1).throttles.tolist() == want
    assert slots[1].step(state, 30).throttles.tolist() != want  # without the restart the memory shows


def test_throttles_that_must_not_be_sent_are_refused():
    class Broken:
        name = "broken"

        def reset(self) -> None:
            pass

        def update(self, t, state, demand) -> ControlOutput:
            u = np.array((0.5, math.nan, 0.5, 0.5))
            return ControlOutput(u, False, u)

    choice = build_choice("hover-canted", "combined", {})
    slot = ControllerSlot(dataclasses.replace(choice, controller=Broken(), name="broken"), Demand())
    with pytest.raises(OutputError, match="expected 4 values in"):
        slot.step(*_state(1, 500.0))
    assert slot.steps == 0

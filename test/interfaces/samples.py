"""Sample values for every custom interface, shared by the publishing child and the tests.

Values are distinctive (non-zero, non-default, negative, fractional, multi-element) so that a
field dropped or swapped anywhere in the chain shows up as a mismatch.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

MESSAGES = ["ThrottleCommand", "LanderState", "FlightEvent", "AutopilotStatus"]
SERVICES = ["LoadScene", "Reset", "StepSimulation", "RunUntil", "SwitchController"]


def _header(msg: Any, sec: int, nanosec: int, frame: str) -> None:
    msg.header.stamp.sec = sec
    msg.header.stamp.nanosec = nanosec
    msg.header.frame_id = frame


def make_message(name: str) -> Any:
    from lander_interfaces import msg as m

    if name == "ThrottleCommand":
        x = m.ThrottleCommand(state_sequence=2**40 + 7, throttles=[0.0, 0.25, 0.5, 1.0])
        _header(x, 12, 500_000_000, "")
    elif name == "LanderState":
        x = m.LanderState(sequence=123456789, gimbal_lock=True, altitude=499.75, climb_rate=-1.5,
                          ground_speed=0.125, mass=1234.5, fuel_mass=321.25, throttles=[0.1, 0.2, 0.3, 0.4],
                          phase=m.LanderState.PHASE_CRASHED, parachute_deployed=True, stabiliser_on=True)
        _header(x, 3, 14159, "mars")
        x.position.x, x.position.y, x.position.z = 1.0, -3.3895e6, 2.5
        x.velocity.x, x.velocity.y, x.velocity.z = -0.5, 10.0, 1e-3
        s, q = math.cos(0.3), math.sin(0.3) / math.sqrt(3.0)
        x.orientation.x, x.orientation.y, x.orientation.z, x.orientation.w = q, q, q, s
        x.euler_zxz = [0.1, math.pi / 2, -0.2]
        x.angular_velocity.x, x.angular_velocity.y, x.angular_velocity.z = 0.01, -0.02, 0.03
    elif name == "FlightEvent":
        x = m.FlightEvent(kind=m.FlightEvent.COMMAND_STALE, detail="no command for 0.5 s (λ ok)",
                          values=[0.5, -2.0])
        _header(x, 99, 1, "mars")
    elif name == "AutopilotStatus":
        x = m.AutopilotStatus(controller="pole_placement", saturated=True, steps=2**33, rejected=4,
                              last_error="state 17 was stale", throttles=[1.0, 0.0, 0.75, 0.5],
                              demand_altitude=500.0, velocity_demanded=True, mode="flare")
        x.demand_velocity.x, x.demand_velocity.y = 3.5, -1.25
        _header(x, 7, 7, "")
    else:
        raise ValueError(f"unknown message {name!r}; choices: {MESSAGES}")
    return x


def make_request(name: str) -> Any:
    from lander_interfaces import srv

    return {
        "LoadScene": lambda: srv.LoadScene.Request(scene="hover"),
        "Reset": lambda: srv.Reset.Request(use_seed=True, seed=2**63 + 5),
        "StepSimulation": lambda: srv.StepSimulation.Request(steps=250),
        "RunUntil": lambda: srv.RunUntil.Request(sim_time=12.5),
        "SwitchController": lambda: srv.SwitchController.Request(controller="lqr", parameters_yaml="q: [1, 2]\n"),
    }[name]()


# How the test server answers: a response computed from the request, so the client can check
# that the request arrived intact and the response came back intact.
ANSWERS: dict[str, Callable[[Any, Any], None]] = {
    "LoadScene": lambda req, res: (setattr(res, "success", True), setattr(res, "message", f"loaded {req.scene}")),
    "Reset": lambda req, res: (setattr(res, "success", req.use_seed), setattr(res, "message", f"seed {req.seed}")),
    "StepSimulation": lambda req, res: (setattr(res, "success", True), setattr(res, "message", "ok"),
                                        setattr(res, "sim_time", req.steps * 0.01)),
    "RunUntil": lambda req, res: (setattr(res, "success", False), setattr(res, "message", "landed"),
                                  setattr(res, "sim_time_reached", req.sim_time - 0.25)),
    "SwitchController": lambda req, res: (setattr(res, "success", True), setattr(res, "message", req.parameters_yaml),
                                          setattr(res, "active_controller", req.controller)),
}


def answer(name: str, request: Any) -> Any:
    from lander_interfaces import srv

    response = getattr(srv, name).Response()
    ANSWERS[name](request, response)
    return response


def to_plain(msg: Any) -> Any:
    """A rosidl message (or rosbags message) as nested dicts/lists of Python values, for comparing."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {f: to_plain(getattr(msg, f)) for f in msg.get_fields_and_field_types()}
    if dataclasses.is_dataclass(msg):
        # rosbags messages; types registered at run time list constants as fields. ROS field
        # names are lower case and constants upper case (rosidl naming rules), so skip the latter.
        return {f.name: to_plain(getattr(msg, f.name)) for f in dataclasses.fields(msg)
                if f.name != "__msgtype__" and not f.name.isupper()}
    if hasattr(msg, "tolist"):  # numpy arrays (rclpy float64[] and rosbags arrays)
        return [to_plain(v) for v in msg.tolist()]
    if isinstance(msg, (list, tuple)):
        return [to_plain(v) for v in msg]
    return msg

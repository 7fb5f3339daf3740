"""launch/fly.launch.py as far as a machine without a ROS 2 install allows.

* The plan (lander_tools.fly.launch_plan, plain Python): which processes, with which parameters.
* The launch file itself, built against stand-ins of ``launch`` / ``launch_ros`` (they are not on
  PyPI) that record what it constructs: every argument declared, the sim, the autopilot and the
  ending process started as the plan says, the launch shut down when the sim or that process exits.
  Where the real ``launch_ros`` is importable (a full install) the description is built with it.
* The plan's processes over the real middleware, started as the launch would start them: the sim
  leaves pause only once the autopilot is matched, so no lockstep answer is waited out, and the
  ending process exits at the flight's end instant.
"""
from __future__ import annotations

import importlib.util
import sys
import types
from pathlib import Path
from typing import Any

import pytest

from lander_tools.fly.launch_plan import ARGS, NODE_WAIT_S, launch_plan

REPO = Path(__file__).resolve().parents[2]
LAUNCH_FILE = REPO / "launch" / "fly.launch.py"
WAIT = ["--wait", f"{NODE_WAIT_S:g}"]


def _args(**given: str) -> dict[str, str]:
    return {name: given.get(name, default) for name, (default, _) in ARGS.items()}


def _scene_controller(scene: str) -> str:
    return {"hover": "combined", "free-spin": ""}[scene]


# --- the plan ------------------------------------------------------------------------------------

def test_a_flown_scene_starts_paused_in_lockstep_and_is_started_once_its_autopilot_is_matched() -> None:
    plan = launch_plan(_args(), _scene_controller, environ={})
    assert plan.sim == {"scene": "hover", "speed": 1.0, "start_paused": True, "lockstep": True}
    assert plan.autopilot == {"scene": "hover", "controller": "combined", "use_sim_time": True}
    assert plan.ender == ["start", "--autopilot", "--until-end", *WAIT]
    assert plan.end_reason == "flight ended"
    assert plan.files == []
    assert plan.env == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}  # this machine only, as lander fly


def test_a_discovery_range_the_user_set_is_kept() -> None:
    for value in ("SUBNET", "LOCALHOST", "OFF"):
        assert launch_plan(_args(), _scene_controller, environ={"ROS_AUTOMATIC_DISCOVERY_RANGE": value}).env == {}


def test_the_sim_alone_holds_its_last_command_and_waits_for_no_autopilot() -> None:
    for args in (_args(scene="free-spin"), _args(controller="none"), _args(controller="NONE")):
        plan = launch_plan(args, _scene_controller)
        assert plan.autopilot is None
        assert plan.sim["lockstep"] is False and plan.sim["command_timeout"] == 0.0
        assert plan.ender == ["start", "--until-end", *WAIT]


def test_duration_is_the_sims_end_time_and_a_recording_ends_the_launch() -> None:
    plan = launch_plan(_args(record="out/b", duration="30", params_file="my.yaml"), _scene_controller)
    assert plan.sim["end_time"] == 30.0
    assert plan.files == ["my.yaml"]
    assert plan.ender == ["record", "-o", "out/b", "--whole-flight", "--start", *WAIT]
    assert plan.end_reason == "recording ended"


def test_flat_out_the_sim_keeps_its_own_lockstep_timeout_and_a_params_file_sets_it() -> None:
    """No launch value for ``lockstep_timeout`` at any speed: the node's default stands, or the
    params file's (the autopilot answers every state within one period, even at the handover)."""
    for speed in ("0", "1"):
        assert "lockstep_timeout" not in launch_plan(_args(speed=speed), _scene_controller).sim


def test_a_launch_argument_that_is_not_a_number_is_named() -> None:
    with pytest.raises(ValueError, match=r"duration:='half a minute' is not a number"):
        launch_plan(_args(duration="half a minute"), _scene_controller)


# --- the launch file, against stand-ins of launch / launch_ros ----------------------------------

class _Recorded:
    """A stand-in class: keeps the arguments it was constructed with."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


class _LaunchConfiguration(_Recorded):
    def perform(self, context: dict[str, str]) -> str:
        return context[self.args[0]]


def _stand_ins() -> dict[str, types.ModuleType]:
    names = {
        "launch": ["LaunchDescription"],
        "launch.actions": ["DeclareLaunchArgument", "EmitEvent", "ExecuteProcess", "OpaqueFunction",
                           "RegisterEventHandler", "SetEnvironmentVariable"],
        "launch.event_handlers": ["OnProcessExit"],
        "launch.events": ["Shutdown"],
        "launch.substitutions": [],
        "launch_ros": [],
        "launch_ros.actions": ["Node"],
    }
    modules = {}
    for module, classes in names.items():
        m = types.ModuleType(module)
        for c in classes:
            setattr(m, c, type(c, (_Recorded,), {}))
        modules[module] = m
    modules["launch.substitutions"].LaunchConfiguration = _LaunchConfiguration  # type: ignore[attr-defined]
    return modules


def _load_launch_file(monkeypatch: pytest.MonkeyPatch) -> types.ModuleType:
    for name, module in _stand_ins().items():
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location("fly_launch_under_test", LAUNCH_FILE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_launch_file_declares_every_argument_and_starts_what_the_plan_says(monkeypatch) -> None:
    launch_file = _load_launch_file(monkeypatch)
    monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE", raising=False)  # a user who set no range
    description = launch_file.generate_launch_description()
    (entities,) = description.args
    declared = {e.args[0]: e.kwargs for e in entities[:-1]}
    assert declared == {name: {"default_value": d, "description": doc} for name, (d, doc) in ARGS.items()}
    opaque = entities[-1]
    given = _args(scene="hover-canted", speed="0", duration="12", params_file="p.yaml")
    actions = opaque.kwargs["function"](given)
    plan = launch_plan(given, launch_file._scene_controller)

    set_range, sim, on_sim_exit, autopilot, ender, on_ender_exit = actions
    assert set_range.args == ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")  # before any process starts
    assert sim.kwargs["executable"] == "sim_node" and sim.kwargs["name"] == "lander_sim"
    assert sim.kwargs["parameters"] == ["p.yaml", plan.sim]
    assert plan.sim["start_paused"] and plan.sim["end_time"] == 12.0
    assert autopilot.kwargs["executable"] == "autopilot_node"
    assert autopilot.kwargs["parameters"] == ["p.yaml", plan.autopilot]
    assert ender.kwargs["cmd"] == ["ros2", "run", "mars_lander", "lander", *plan.ender]
    for handler, target, reason in ((on_sim_exit, sim, "sim exited"), (on_ender_exit, ender, "flight ended")):
        (on_exit,) = handler.args
        assert on_exit.kwargs["target_action"] is target
        (emit,) = on_exit.kwargs["on_exit"]
        assert emit.kwargs["event"].kwargs == {"reason": reason}


def test_with_the_real_launch_the_description_builds() -> None:
    pytest.importorskip("launch_ros.actions", reason="launch_ros is not on PyPI: a full ROS 2 install has it")
    spec = importlib.util.spec_from_file_location("fly_launch_real", LAUNCH_FILE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    assert {a.name for a in description.get_launch_arguments()} == set(ARGS)


# --- the plan's processes over the middleware -----------------------------------------------------

def test_the_launched_flight_waits_for_its_autopilot_and_the_launch_ends_at_the_flights_end(ros_node) -> None:
    from lander_sim.scenes import load_scene
    from rosutil import ChildProcess, start_node

    def scene_controller(scene: str) -> str:
        autopilot = load_scene(scene).autopilot
        return "" if autopilot is None else autopilot.controller

    plan = launch_plan(_args(scene="hover", speed="0", duration="3"), scene_controller)
    assert plan.autopilot is not None
    sim_params = dict(plan.sim)
    with start_node("lander_sim.node", sim_params, name="sim") as sim, \
            start_node("lander_autopilot.node", plan.autopilot, name="autopilot") as autopilot, \
            ChildProcess(["-m", "lander_tools.cli", *plan.ender], cwd=REPO, name="ender") as ender:
        ros_node.wait_for(lambda: ender.returncode is not None, 120.0, "the ending process to exit")
        out = ender.output()
        assert ender.returncode == 0, out
        assert "lander start: resumed at t = 0.0 s" in out
        assert "flight ended at t = 3.0 s (time-limit)" in out
        assert "lockstep timeouts" not in out  # every state of the flight answered: none waited out
        assert "no answer to state" not in sim.output(), sim.output()
        assert autopilot.returncode is None  # flying to the end: the launch's Shutdown stops it

"""What ``launch/fly.launch.py`` starts, as plain data: the launch file only turns it into actions.

On a full ROS 2 install ``ros2 launch mars_lander fly.launch.py scene:=S`` starts the sim node,
the autopilot node (unless the scene has none or ``controller:=none``) and one process whose exit
ends the launch:

* with ``record:=BAG``: ``lander record --whole-flight --start``, which waits until it and the
  autopilot are matched, restarts the flight at t = 0, resumes it and ends at the flight's end
  instant with the bag checked;
* otherwise: ``lander start``, which waits until the autopilot is matched both ways, resumes the
  flight and exits at its end instant (``duration:=S``; without it the flight runs until Ctrl-C).

The sim starts paused either way and leaves pause only when every participant is matched, so
state 1 reaches the autopilot and the launched flight is the deterministic flight ``lander fly``
gives (no lockstep answer is waited out at the start). Discovery stays on this machine
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` for every process of the launch) unless the user set
the range, as for ``lander fly`` and the verbs (docs/flying.md, "Flights kept apart"). Plain
Python: tested without ``launch``.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

#: The launch file's arguments: name -> (default, meaning).
ARGS: dict[str, tuple[str, str]] = {
    "scene": ("hover", "scene name, alias or YAML path"),
    "controller": ("", "autopilot controller plug-in; empty: the scene's; none: the sim alone"),
    "speed": ("1.0", "real-time factor, 0 = as fast as possible"),
    "lockstep": ("true", "the sim waits for the autopilot's answer to each state (with an autopilot)"),
    "params_file": ("", "ROS parameters YAML with sections lander_sim / autopilot"),
    "record": ("", "bag folder: record the whole flight (lander record --whole-flight, MCAP); the launch ends "
                   "with the recording"),
    "duration": ("", "end the flight at this sim time [s] (the sim's end_time); the launch ends there; "
                     "empty: no end"),
}

#: Wall seconds the ending process waits for the flight's nodes to appear.
NODE_WAIT_S = 30.0


@dataclass(frozen=True)
class LaunchPlan:
    """The processes of one launched flight.

    ``sim`` comes after the params files (the launch arguments win); ``autopilot`` is None for the sim alone; ``ender`` is the argv after
    ``lander`` of the process whose exit shuts the launch down, for the reason ``end_reason``."""

    sim: dict[str, Any]
    files: list[str]
    autopilot: dict[str, Any] | None
    ender: list[str] = field(default_factory=list)
    end_reason: str = ""
    #: Environment variables the launch sets for all its processes (before any starts).
    env: dict[str, str] = field(default_factory=dict)


def launch_plan(arg: Mapping[str, str], scene_controller: Callable[[str], str],
                environ: Mapping[str, str] | None = None) -> LaunchPlan:
    """The plan for the launch arguments ``arg`` (every name of :data:`ARGS`, as strings).

    ``scene_controller(scene)`` names the scene's own autopilot controller, '' when it has none;
    ``environ`` (default os.environ) is the launch's environment. Raises ValueError naming an
    argument that is not a number where one is needed."""
    import os

    from lander_tools.fly.domain import LOCALHOST, RANGE_VAR

    environ = os.environ if environ is None else environ
    env = {} if environ.get(RANGE_VAR, "").strip() else {RANGE_VAR: LOCALHOST}

    controller = arg["controller"] or scene_controller(arg["scene"])
    if controller.lower() == "none":
        controller = ""
    speed = _number(arg, "speed")
    sim: dict[str, Any] = {"scene": arg["scene"], "speed": speed, "start_paused": True,
                           "lockstep": bool(controller) and arg["lockstep"].lower() == "true"}
    if not controller:
        sim["command_timeout"] = 0.0  # the sim alone holds the last command for good
    if arg["duration"]:
        sim["end_time"] = _number(arg, "duration")  # the sim stops itself there (docs/sim_node.md)
    files = [arg["params_file"]] if arg["params_file"] else []
    autopilot = ({"scene": arg["scene"], "controller": controller, "use_sim_time": True} if controller else None)
    wait = ["--wait", f"{NODE_WAIT_S:g}"]
    if arg["record"]:
        # Not `ros2 bag record`, which holds the flight only from when it is matched: ours restarts
        # the flight from t = 0 once matched and checks the bag at the end (docs/flying.md).
        ender = ["record", "-o", arg["record"], "--whole-flight", "--start", *wait]
        reason = "recording ended"
    else:
        ender = ["start", *(["--autopilot"] if controller else []), "--until-end", *wait]
        reason = "flight ended"
    return LaunchPlan(sim, files, autopilot, ender, reason, env)


def _number(arg: Mapping[str, str], name: str) -> float:
    try:
        return float(arg[name])
    except ValueError:
        raise ValueError(f"{name}:={arg[name]!r} is not a number") from None

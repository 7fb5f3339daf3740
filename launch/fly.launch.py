"""Fly a scene on a full ROS 2 install: the sim node and (unless the scene has no autopilot or
``controller:=none``) the autopilot node, optionally recorded whole (``lander record --whole-flight``).

    ros2 launch mars_lander fly.launch.py scene:=hover speed:=1.0
    ros2 launch mars_lander fly.launch.py scene:=7 controller:=baseline params_file:=my.yaml
    ros2 launch mars_lander fly.launch.py scene:=free-spin controller:=none record:=out/spin duration:=30

Mirrors ``lander fly`` (lander_tools/fly/), which does the same where ``launch`` is not
installed (ROS 2 from PyPI). Differences: the sim starts running rather than paused (a recording
restarts it from t = 0 once matched), the whole launch shuts down when the sim node exits or the
recording ends (``lander fly`` also ends on landing or crash), and there is no ``--compose``
(Python nodes cannot be loaded into a C++ component container).
"""
from launch.actions import DeclareLaunchArgument, EmitEvent, ExecuteProcess, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from launch import LaunchDescription

ARGS = {
    "scene": ("hover", "scene name, alias or YAML path"),
    "controller": ("", "autopilot controller plug-in; empty: the scene's; none: the sim alone"),
    "speed": ("1.0", "real-time factor, 0 = as fast as possible"),
    "lockstep": ("true", "the sim waits for the autopilot's answer to each state (with an autopilot)"),
    "params_file": ("", "ROS parameters YAML with sections lander_sim / autopilot"),
    "record": ("", "bag folder: record the whole flight (lander record --whole-flight, MCAP); the launch ends "
                   "with the recording"),
    "duration": ("", "end the flight at this sim time [s] (the sim's end_time); empty: no end"),
}


def _scene_controller(scene: str) -> str:
    """The scene's own autopilot controller, or '' when it has none (e.g. the rotor, scenario 6)."""
    from lander_sim.scenes import load_scene

    autopilot = load_scene(scene).autopilot
    return "" if autopilot is None else autopilot.controller


def _nodes(context):
    arg = {name: LaunchConfiguration(name).perform(context) for name in ARGS}
    controller = arg["controller"] or _scene_controller(arg["scene"])
    if controller.lower() == "none":
        controller = ""
    files = [arg["params_file"]] if arg["params_file"] else []
    sim_params = {"scene": arg["scene"], "speed": float(arg["speed"]),
                  "lockstep": bool(controller) and arg["lockstep"].lower() == "true"}
    if not controller:
        sim_params["command_timeout"] = 0.0  # the sim alone holds the last command for good
    # As `lander fly`: flat out in lockstep the sim waits out a slow answer; a params file's value wins.
    defaults = []
    if sim_params["lockstep"] and sim_params["speed"] == 0:
        from lander_tools.fly.processes import FLAT_OUT_LOCKSTEP_TIMEOUT

        defaults.append({"lockstep_timeout": FLAT_OUT_LOCKSTEP_TIMEOUT})
    if arg["duration"]:
        sim_params["end_time"] = float(arg["duration"])  # the sim stops itself there (docs/sim_node.md)
    sim = Node(package="mars_lander", executable="sim_node", name="lander_sim", output="screen",
               parameters=[*defaults, *files, sim_params])
    actions = [
        sim,
        RegisterEventHandler(OnProcessExit(target_action=sim, on_exit=[EmitEvent(event=Shutdown(reason="sim exited"))])),
    ]
    if controller:
        actions.append(Node(package="mars_lander", executable="autopilot_node", name="autopilot", output="screen",
                            parameters=[*files, {"scene": arg["scene"], "controller": controller, "use_sim_time": True}]))
    if arg["record"]:
        # Not `ros2 bag record`, which holds the flight only from when it is matched: ours restarts
        # the flight from t = 0 once matched and checks the bag at the end (docs/flying.md).
        recorder = ExecuteProcess(cmd=["ros2", "run", "mars_lander", "lander", "record", "-o", arg["record"],
                                       "--whole-flight", "--wait", "30"], output="screen")
        actions += [recorder, RegisterEventHandler(OnProcessExit(
            target_action=recorder, on_exit=[EmitEvent(event=Shutdown(reason="recording ended"))]))]
    return actions


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=doc) for name, (default, doc) in ARGS.items()]
        + [OpaqueFunction(function=_nodes)]
    )

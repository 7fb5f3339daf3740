"""Fly a scene on a full ROS 2 install: the sim node, the autopilot node (unless the scene has no
autopilot or ``controller:=none``) and the process that starts the flight and ends the launch.

    ros2 launch mars_lander fly.launch.py scene:=hover speed:=1.0
    ros2 launch mars_lander fly.launch.py scene:=7 controller:=baseline params_file:=my.yaml duration:=60
    ros2 launch mars_lander fly.launch.py scene:=free-spin controller:=none record:=out/spin duration:=30

What is started, and why, is plain data (lander_tools.fly.launch_plan): the sim starts paused and
leaves pause once everyone who flies it is matched (``lander start``, or ``lander record
--whole-flight --start`` with ``record:=``), so the launched flight is the deterministic flight
``lander fly`` gives, found on this machine only unless ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is set;
the launch ends when that process exits: at the flight's end instant with
``duration:=``, at the end of the recording with ``record:=``, or when the sim node exits.
Differences from ``lander fly``: it does not end on landing or crash by itself, and there is no
``--compose`` (Python nodes cannot be loaded into a C++ component container).
"""
from launch.actions import (
    DeclareLaunchArgument,
    EmitEvent,
    ExecuteProcess,
    OpaqueFunction,
    RegisterEventHandler,
    SetEnvironmentVariable,
)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from lander_tools.fly.launch_plan import ARGS, launch_plan
from launch import LaunchDescription


def _scene_controller(scene: str) -> str:
    """The scene's own autopilot controller, or '' when it has none (e.g. the rotor, scenario 6)."""
    from lander_sim.scenes import load_scene

    autopilot = load_scene(scene).autopilot
    return "" if autopilot is None else autopilot.controller


def _shutdown_on_exit(action, reason: str) -> RegisterEventHandler:
    return RegisterEventHandler(OnProcessExit(target_action=action, on_exit=[EmitEvent(event=Shutdown(reason=reason))]))


def _nodes(context):
    plan = launch_plan({name: LaunchConfiguration(name).perform(context) for name in ARGS}, _scene_controller)
    sim = Node(package="mars_lander", executable="sim_node", name="lander_sim", output="screen",
               parameters=[*plan.files, plan.sim])
    actions = [*(SetEnvironmentVariable(name, value) for name, value in plan.env.items()),
               sim, _shutdown_on_exit(sim, "sim exited")]
    if plan.autopilot is not None:
        actions.append(Node(package="mars_lander", executable="autopilot_node", name="autopilot", output="screen",
                            parameters=[*plan.files, plan.autopilot]))
    ender = ExecuteProcess(cmd=["ros2", "run", "mars_lander", "lander", *plan.ender], output="screen")
    return [*actions, ender, _shutdown_on_exit(ender, plan.end_reason)]


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=doc) for name, (default, doc) in ARGS.items()]
        + [OpaqueFunction(function=_nodes)]
    )

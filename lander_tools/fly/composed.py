"""Both nodes of a flight in one process and one executor (``lander fly --compose``): no
inter-process hops. Run by the launcher as ``python -m lander_tools.fly.composed --ros-args ...``
(:func:`lander_tools.fly.processes.node_commands`)."""
from __future__ import annotations

import sys
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

from lander_autopilot.node import AutopilotNode
from lander_ros.params import check_overrides
from lander_sim.node import SimNode
from lander_sim.ros.config import SPECS, ConfigError
from lander_tools.fly.plan import EXIT_ERROR, SIM_NODE


def main(argv: list[str]) -> int:
    """Both nodes in one executor, the sim node's own loop driving it, so the autopilot's callbacks
    run between the sim's ticks. ``argv``: the program name, then the nodes' ROS arguments."""
    rclpy.init(args=argv)
    nodes: list[Any] = []
    try:
        check_overrides(SPECS, argv, SIM_NODE, ConfigError)
        sim = SimNode()
        nodes.append(sim)
        ap = AutopilotNode(argv)
        nodes.append(ap)
        executor = SingleThreadedExecutor()
        executor.add_node(sim)
        executor.add_node(ap)
        sim.run(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as exc:
        print(f"composed: {exc}", file=sys.stderr)
        return EXIT_ERROR
    finally:
        for n in nodes:
            n.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

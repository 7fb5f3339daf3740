"""Test-side helpers for the autopilot node: a "ground station" node (a :class:`rosutil.Observer`).

No mocks of ROS: :class:`Ground` is an ordinary rclpy node in the test process that records what
the autopilot and the simulator publish, publishes states/demands itself and calls their
services. Every wait spins the executor until a condition holds or a timeout expires; nothing
sleeps a fixed time.
"""
from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import GetParameters, SetParametersAtomically
from rclpy.parameter import Parameter
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

import rosutil
from lander_interfaces.msg import AutopilotStatus, FlightEvent, LanderState, ThrottleCommand
from lander_interfaces.srv import Reset, SwitchController
from lander_ros.stamps import stamp_to_seconds

#: Generous: discovery and process start-up (imports of rclpy + python-control) on a loaded 2-core machine.
START_TIMEOUT = 30.0
#: One request/answer over the middleware.
REPLY_TIMEOUT = 10.0

seconds = stamp_to_seconds


class Ground(rosutil.Observer):
    """Records /lander/state, /lander/throttle, /autopilot/status, /lander/events; talks to both nodes."""

    start_timeout = START_TIMEOUT
    reply_timeout = REPLY_TIMEOUT

    def __init__(self, context: Any, name: str = "ground") -> None:
        super().__init__(name, context)
        n = self.node
        self.states: list[LanderState] = self.record("/lander/state", LanderState)
        self.throttles: list[ThrottleCommand] = self.record("/lander/throttle", ThrottleCommand)
        self.statuses: list[AutopilotStatus] = self.record("/autopilot/status", AutopilotStatus)
        self.events: list[FlightEvent] = self.record("/lander/events", FlightEvent)
        self.pub_state = n.create_publisher(LanderState, "/lander/state", 10)
        self.pub_demand = n.create_publisher(Float64, "/lander/demand_altitude", 10)
        self.switch = n.create_client(SwitchController, "/autopilot/switch_controller")
        self.set_params = n.create_client(SetParametersAtomically, "/autopilot/set_parameters_atomically")
        self.get_params = n.create_client(GetParameters, "/autopilot/get_parameters")
        self.reset_sim = n.create_client(Reset, "/lander/reset")
        self.pause_sim = n.create_client(Trigger, "/lander/pause")
        self.resume_sim = n.create_client(Trigger, "/lander/resume")

    def switch_controller(self, controller: str, parameters_yaml: str = "") -> SwitchController.Response:
        return self.call(self.switch, SwitchController.Request(controller=controller, parameters_yaml=parameters_yaml))

    def set_autopilot_parameters(self, **values: object) -> Any:
        """Set parameters of /autopilot atomically through its parameter service; return the SetParametersResult."""
        msgs: list[ParameterMsg] = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
        return self.call(self.set_params, SetParametersAtomically.Request(parameters=msgs)).result

    def autopilot_parameter(self, name: str) -> Any:
        """Current value of one of /autopilot's parameters, through its parameter service."""
        return self.parameter(self.get_params, name)

    def publish_demand(self, value: float) -> None:
        self.pub_demand.publish(Float64(data=float(value)))

    def answer_to(self, sequence: int, after: int = 0) -> ThrottleCommand | None:
        """The autopilot's answer to state ``sequence`` among throttles recorded from index ``after``."""
        for cmd in self.throttles[after:]:
            if cmd.state_sequence == sequence:
                return cmd
        return None


def wait_for_graph(ground: Ground, subscribers: dict[str, int], publishers: dict[str, int]) -> None:
    """Wait until the graph shows at least the given numbers of subscribers / publishers per topic."""
    ground.wait_graph(subscribers, publishers)

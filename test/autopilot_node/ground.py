"""Test-side helpers for the autopilot node: a "ground station" node and process launchers.

No mocks of ROS: :class:`Ground` is an ordinary rclpy node in the test process that records what
the autopilot and the simulator publish, publishes states/demands itself and calls their
services. Every wait spins the executor until a condition holds or a timeout expires; nothing
sleeps a fixed time.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import GetParameters, SetParametersAtomically
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

import rosutil
from lander_interfaces.msg import AutopilotStatus, FlightEvent, LanderState, ThrottleCommand
from lander_interfaces.srv import Reset, SwitchController

#: Generous: discovery and process start-up (imports of rclpy + python-control) on a loaded 2-core machine.
START_TIMEOUT = 30.0
#: One request/answer over the middleware.
REPLY_TIMEOUT = 10.0


def ros_args(params: dict[str, object]) -> list[str]:
    """``--ros-args -p k:=v ...`` for a child node."""
    args = ["--ros-args"]
    for k, v in params.items():
        if isinstance(v, bool):
            lit = "true" if v else "false"
        elif isinstance(v, str):
            lit = v if v else "''"
        else:
            lit = repr(v)
        args += ["-p", f"{k}:={lit}"]
    return args


class Ground:
    """Records /lander/state, /lander/throttle, /autopilot/status, /lander/events; talks to both nodes."""

    def __init__(self, context: Any, name: str = "ground") -> None:
        self.node = Node(name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        n = self.node
        self.states: list[LanderState] = []
        self.throttles: list[ThrottleCommand] = []
        self.statuses: list[AutopilotStatus] = []
        self.events: list[FlightEvent] = []
        self.received = 0  # messages taken by the callbacks below (drain() watches it)
        n.create_subscription(LanderState, "/lander/state", self._recorder(self.states), 10_000)
        n.create_subscription(ThrottleCommand, "/lander/throttle", self._recorder(self.throttles), 10_000)
        n.create_subscription(AutopilotStatus, "/autopilot/status", self._recorder(self.statuses), 10_000)
        n.create_subscription(FlightEvent, "/lander/events", self._recorder(self.events), 10_000)
        self.pub_state = n.create_publisher(LanderState, "/lander/state", 10)
        self.pub_demand = n.create_publisher(Float64, "/lander/demand_altitude", 10)
        self.switch = n.create_client(SwitchController, "/autopilot/switch_controller")
        self.set_params = n.create_client(SetParametersAtomically, "/autopilot/set_parameters_atomically")
        self.get_params = n.create_client(GetParameters, "/autopilot/get_parameters")
        self.reset_sim = n.create_client(Reset, "/lander/reset")
        self.pause_sim = n.create_client(Trigger, "/lander/pause")
        self.resume_sim = n.create_client(Trigger, "/lander/resume")

    def _recorder(self, store: list) -> Callable[[Any], None]:
        def record(msg: Any) -> None:
            store.append(msg)
            self.received += 1

        return record

    def drain(self, timeout: float = REPLY_TIMEOUT) -> None:
        """Take every message already queued: spin until a spin takes none (publishers quiet).

        The ground runs one callback per spin while the simulator may publish a thousand
        messages per second, so its records lag; call this once the publishers are quiet
        (simulation paused) before reading them as complete.
        """
        idle = 0

        def quiet() -> bool:
            nonlocal idle
            before = self.received
            self.executor.spin_once(timeout_sec=0.05)
            idle = idle + 1 if self.received == before else 0
            return idle >= 2

        rosutil.wait_for(quiet, timeout, None, "queued messages drained", poll=0.0)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()

    def wait_for(self, predicate: Callable[[], bool], timeout: float = REPLY_TIMEOUT, what: str = "condition") -> None:
        rosutil.wait_for(predicate, timeout, self.executor, what)

    def call(self, client: Any, request: Any, timeout: float = REPLY_TIMEOUT) -> Any:
        self.wait_for(client.service_is_ready, START_TIMEOUT, f"service {client.srv_name}")
        future = client.call_async(request)
        self.wait_for(future.done, timeout, f"answer of {client.srv_name}")
        return future.result()

    def switch_controller(self, controller: str, parameters_yaml: str = "") -> SwitchController.Response:
        return self.call(self.switch, SwitchController.Request(controller=controller, parameters_yaml=parameters_yaml))

    def set_autopilot_parameters(self, **values: object):
        """Set parameters of /autopilot atomically through its parameter service; return the SetParametersResult."""
        msgs: list[ParameterMsg] = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
        return self.call(self.set_params, SetParametersAtomically.Request(parameters=msgs)).result

    def autopilot_parameter(self, name: str) -> Any:
        """Current value of one of /autopilot's parameters, through its parameter service."""
        reply = self.call(self.get_params, GetParameters.Request(names=[name]))
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=reply.values[0])).value

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
    n = ground.node

    def ready() -> bool:
        return all(n.count_subscribers(t) >= k for t, k in subscribers.items()) and all(
            n.count_publishers(t) >= k for t, k in publishers.items()
        )

    ground.wait_for(ready, START_TIMEOUT, f"discovery of {subscribers} / {publishers}")


def seconds(stamp: Any) -> float:
    return stamp.sec + stamp.nanosec * 1e-9

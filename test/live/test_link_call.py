"""FlightLink.call's contract for a request that acts, over the real middleware: a reply that
never comes is read back through ``confirm``; a reply that comes is the answer; without a
read-back a missing reply is a timeout that says which service and how long.

The server is a real rclpy service whose callback acts (sets ``acted``) and then never replies,
as a server does whose reply rmw_fastrtps drops when the client's reply reader is not matched in
time (rclpy logs "failed to send response (timeout)")."""
from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest


@pytest.fixture
def acting_server(ros_node: Any) -> Iterator[dict[str, Any]]:
    """``/test_link/act`` (never replies once it has acted) and ``/test_link/answer`` (replies)."""
    from rclpy.task import Future
    from std_srvs.srv import Trigger

    node, executor = ros_node.node, ros_node.executor
    state: dict[str, Any] = {"acted": threading.Event()}

    async def act(request: Any, response: Any) -> Any:
        state["acted"].set()
        await Future()  # never done: the reply is never sent
        return response

    def answer(request: Any, response: Any) -> Any:
        state["acted"].set()
        response.success, response.message = True, "the reply"
        return response

    node.create_service(Trigger, "/test_link/act", act)
    node.create_service(Trigger, "/test_link/answer", answer)
    stop = threading.Event()
    spinner = threading.Thread(target=lambda: [executor.spin_once(timeout_sec=0.05) for _ in iter(stop.is_set, True)],
                               daemon=True)
    spinner.start()
    try:
        yield state
    finally:
        stop.set()
        spinner.join(5.0)


def test_an_acting_request_whose_reply_is_lost_is_confirmed_by_its_read_back(acting_server: dict[str, Any]) -> None:
    from std_srvs.srv import Trigger

    from lander_tools.live.link import ASK_AGAIN, FlightLink

    acted = acting_server["acted"]
    with FlightLink("test_link_confirm") as link:
        t0 = time.monotonic()
        seen = link.call(Trigger, "/test_link/act", Trigger.Request(), timeout=20.0,
                         confirm=lambda: "read back: done" if acted.is_set() else None)
        took = time.monotonic() - t0
    assert seen == "read back: done"
    assert took < 20.0 - ASK_AGAIN  # answered by the read-back, long before the timeout


def test_a_reply_that_comes_is_the_answer(acting_server: dict[str, Any]) -> None:
    from std_srvs.srv import Trigger

    from lander_tools.live.link import FlightLink

    with FlightLink("test_link_reply") as link:
        resp = link.call(Trigger, "/test_link/answer", Trigger.Request(), timeout=20.0, confirm=lambda: None)
    assert (resp.success, resp.message) == (True, "the reply")


def test_without_a_read_back_a_lost_reply_is_a_timeout_naming_the_service(acting_server: dict[str, Any]) -> None:
    from std_srvs.srv import Trigger

    from lander_tools.live.link import FlightLink

    with FlightLink("test_link_timeout") as link:
        with pytest.raises(TimeoutError, match=r"^service /test_link/act did not answer within 2 s$"):
            link.call(Trigger, "/test_link/act", Trigger.Request(), timeout=2.0)
    assert acting_server["acted"].is_set()


@pytest.fixture
def parameter_server(ros_node: Any) -> Iterator[dict[str, Any]]:
    """``/test_params``: parameter services whose ``set_parameters`` sets and then never replies,
    whose ``get_parameters`` answers (the node's ``end_time`` starts at -1.0)."""
    from rcl_interfaces.msg import ParameterType, ParameterValue, SetParametersResult
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
    from rclpy.task import Future

    node, executor = ros_node.node, ros_node.executor
    values: dict[str, float] = {"end_time": -1.0}
    state: dict[str, Any] = {"values": values, "reply": False}

    async def set_params(request: Any, response: Any) -> Any:
        for p in request.parameters:
            values[p.name] = p.value.double_value
        response.results = [SetParametersResult(successful=True)] * len(request.parameters)
        if not state["reply"]:
            await Future()  # never done: the reply is never sent
        return response

    def get_params(request: Any, response: Any) -> Any:
        response.values = [ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=values[n])
                           for n in request.names]
        return response

    # Groups of their own: the set's unfinished callback must not hold the get back, as a real
    # node's reply lost in the middleware holds nothing.
    node.create_service(SetParameters, "/test_params/set_parameters", set_params,
                        callback_group=MutuallyExclusiveCallbackGroup())
    node.create_service(GetParameters, "/test_params/get_parameters", get_params,
                        callback_group=MutuallyExclusiveCallbackGroup())
    stop = threading.Event()
    spinner = threading.Thread(target=lambda: [executor.spin_once(timeout_sec=0.05) for _ in iter(stop.is_set, True)],
                               daemon=True)
    spinner.start()
    try:
        yield state
    finally:
        stop.set()
        spinner.join(5.0)


def test_parameters_set_whose_reply_is_lost_are_confirmed_by_reading_them_back(parameter_server: dict[str, Any]) -> None:
    from lander_tools.live.link import ASK_AGAIN, FlightLink

    with FlightLink("test_link_params") as link:
        t0 = time.monotonic()
        out = link.set_parameters("/test_params", {"end_time": 3.0})
        took = time.monotonic() - t0
    assert out.ok and "read back are those asked" in out.message, out
    assert parameter_server["values"]["end_time"] == 3.0
    assert took < 10.0 - ASK_AGAIN  # answered by the read-back, before the call's timeout


def test_parameters_already_as_asked_are_not_said_set_when_the_reply_is_lost(parameter_server: dict[str, Any]) -> None:
    from lander_tools.live.link import FlightLink

    # The read-back cannot tell a set made from one never made: a lost reply stays a timeout.
    with FlightLink("test_link_params_same") as link:
        with pytest.raises(TimeoutError, match=r"^service /test_params/set_parameters did not answer within"):
            link.set_parameters("/test_params", {"end_time": -1.0})


def test_parameters_set_whose_reply_comes_are_the_nodes_answer(parameter_server: dict[str, Any]) -> None:
    from lander_tools.live.link import FlightLink

    parameter_server["reply"] = True
    with FlightLink("test_link_params_reply") as link:
        out = link.set_parameters("/test_params", {"end_time": 4.0})
    assert (out.ok, out.message) == (True, "ok")

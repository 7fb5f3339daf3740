"""Every custom message and service of lander_interfaces crosses a process boundary intact.

A child process (sample_node.py) publishes each sample message and serves each service; this
process subscribes / calls and compares field by field. Exact equality is the right check: the
middleware copies bytes (float64 survives CDR unchanged), so any difference is a type or
field-mapping bug. Timeouts only bound waiting for discovery (0.01-3 s measured on 2 cores).
"""

import uuid
from pathlib import Path

import pytest
import samples
from rclpy.qos import QoSProfile, ReliabilityPolicy

HERE = Path(__file__).resolve().parent
DISCOVERY_TIMEOUT_S = 20.0  # generous: the wait ends as soon as the data arrive


@pytest.fixture
def sample_node(spawn_python):
    prefix = f"/itest_{uuid.uuid4().hex[:8]}"  # a private namespace even within this domain
    child = spawn_python([str(HERE / "sample_node.py"), prefix], name="sample_node")
    return prefix, child


def test_each_message_received_from_another_process(ros_node, sample_node):
    from lander_interfaces import msg

    prefix, child = sample_node
    got: dict[str, object] = {}
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    for name in samples.MESSAGES:
        ros_node.node.create_subscription(getattr(msg, name), f"{prefix}/{name}",
                                          lambda m, name=name: got.setdefault(name, m), qos)
    ros_node.wait_for(lambda: len(got) == len(samples.MESSAGES) or child.returncode is not None,
                      DISCOVERY_TIMEOUT_S, what=f"all of {samples.MESSAGES} received")
    assert child.returncode is None, f"sample node died:\n{child.output()}"
    for name in samples.MESSAGES:
        assert samples.to_plain(got[name]) == samples.to_plain(samples.make_message(name)), name


def test_message_constants_match_the_documented_values():
    """Other parts (simulator, analysis, bags) rely on these numeric values: see the .msg files."""
    from lander_interfaces.msg import FlightEvent, LanderState

    assert (LanderState.PHASE_FLYING, LanderState.PHASE_LANDED, LanderState.PHASE_CRASHED) == (0, 1, 2)
    kinds = ["LANDED", "CRASHED", "GIMBAL_LOCK", "FUEL_OUT", "PARACHUTE_DEPLOYED", "PARACHUTE_DESTROYED",
             "INPUT_REJECTED", "CONTROLLER_SWITCHED", "COMMAND_STALE"]
    assert [getattr(FlightEvent, k) for k in kinds] == list(range(len(kinds)))


def test_each_service_called_in_another_process(ros_node, sample_node):
    from lander_interfaces import srv

    prefix, child = sample_node
    for name in samples.SERVICES:
        client = ros_node.node.create_client(getattr(srv, name), f"{prefix}/{name}")
        ros_node.wait_for(lambda: client.service_is_ready() or child.returncode is not None,
                          DISCOVERY_TIMEOUT_S, what=f"service {name} available")
        assert child.returncode is None, f"sample node died:\n{child.output()}"
        request = samples.make_request(name)
        future = client.call_async(request)
        ros_node.wait_for(future.done, DISCOVERY_TIMEOUT_S, what=f"{name} response")
        expected = samples.answer(name, request)
        assert samples.to_plain(future.result()) == samples.to_plain(expected), name

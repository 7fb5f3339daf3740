"""The transports of a ROS test file outside ``rosutil.ROS_SHM_TESTS`` (this one): participants
that open no Fast DDS shared-memory port or segment (the machine-wide ports that two pytest-xdist
workers starting participants at once broke), bind sockets on loopback only (traffic stays on this
machine, as ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` keeps it), and still meet each other."""
from __future__ import annotations

import os
import uuid
from pathlib import Path

import psutil

import rosutil

HERE = Path(__file__).resolve().parent
START_TIMEOUT_S = 30.0  # a Python child importing rclpy on 2 busy cores; the wait ends early


def _shared_memory_files(pid: int) -> set[str]:
    """The Fast DDS files in /dev/shm that process ``pid`` has mapped or open."""
    proc = psutil.Process(pid)
    files = {m.path for m in proc.memory_maps(grouped=True)} | {f.path for f in proc.open_files()}
    return {f for f in files if os.path.basename(f).startswith(("fastdds_", "sem.fastdds_"))}


def test_this_files_participants_run_over_loopback_udp_alone(spawn_python, ros_node) -> None:
    assert {k: os.environ.get(k) for k in rosutil.LOOPBACK_UDP} == rosutil.LOOPBACK_UDP
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from lander_interfaces import msg

    prefix = f"/loopback_{uuid.uuid4().hex[:8]}"
    talker = spawn_python([str(HERE / "sample_node.py"), prefix], name="talker")
    heard: list = []
    ros_node.node.create_subscription(msg.LanderState, f"{prefix}/LanderState", heard.append,
                             QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    # They meet: discovery by unicast to 127.0.0.1 finds a participant in another process.
    ros_node.wait_for(lambda: bool(heard), START_TIMEOUT_S, "a message from the child over loopback UDP")

    # The child is a process of this file's environment from its start (the test process may hold
    # what participants of earlier files in this worker left in Fast DDS's process-wide caches).
    assert not _shared_memory_files(talker.proc.pid), "the child opened Fast DDS shared memory"
    sockets = psutil.Process(talker.proc.pid).net_connections(kind="inet")
    assert sockets, "the child has no socket: the check below would pass vacuously"
    assert {s.laddr.ip for s in sockets} == {"127.0.0.1"}, sockets

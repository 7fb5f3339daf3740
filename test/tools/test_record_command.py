"""`lander record` over the real middleware: the sim node publishes, the recorder (a subprocess,
started through the `lander` CLI) writes a sqlite3 bag and closes it when the sim leaves."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from lander_tools.bagio import read_bag


def test_lander_record_writes_every_state_and_closes_when_the_watched_node_leaves(
    tmp_path: Path, ros_node, spawn_python
) -> None:
    from lander_interfaces.msg import LanderState

    bag = tmp_path / "bag"
    rec = spawn_python(["-m", "lander_tools.cli", "record", "-o", str(bag), "--storage", "sqlite3",
                        "--stop-when-gone", "/lander_sim", "/clock", "/lander/state"], name="record")
    sim = spawn_python(["-m", "lander_sim.node", "--ros-args", "-p", "scene:=hover", "-p", "speed:=20.0",
                        "-p", "start_paused:=true"], name="sim")
    n = ros_node.node
    states: list[float] = []
    n.create_subscription(LanderState, "/lander/state", lambda m: states.append(m.header.stamp.sec), 1000)
    # The recorder subscribes to both topics once they exist (ours is the other state subscriber).
    ros_node.wait_for(lambda: n.count_subscribers("/lander/state") >= 2 and n.count_subscribers("/clock") >= 1,
                      30.0, "the recorder's subscriptions")
    from std_srvs.srv import Trigger

    from lander_interfaces.srv import Reset
    from lander_ros.flight_span import parse_matched

    # Seen in the graph is not yet matched by the sim's writers: a state published before the match
    # is not delivered (volatile). Ask the sim until its writers have matched both readers.
    ask = n.create_client(Trigger, "/lander/subscribers")
    assert ask.wait_for_service(timeout_sec=30.0)

    def matched() -> bool:
        fut = ask.call_async(Trigger.Request())
        ros_node.wait_for(fut.done, 10.0, "answer of /lander/subscribers")
        m = parse_matched(fut.result().message)
        return m.get("/lander/state", 0) >= 2 and m.get("/clock", 0) >= 1

    ros_node.wait_for(matched, 30.0, "the sim's writers to match the recorder")

    for srv, typ in (("/lander/reset", Reset), ("/lander/resume", Trigger)):
        cli = n.create_client(typ, srv)
        assert cli.wait_for_service(timeout_sec=30.0)
        fut = cli.call_async(typ.Request())
        ros_node.wait_for(fut.done, 10.0, f"answer of {srv}")
    ros_node.wait_for(lambda: bool(states) and states[-1] >= 3, 30.0, "3 s of flight")
    sim.stop()
    ros_node.wait_for(lambda: rec.returncode is not None, 30.0, "the recorder to close the bag and exit")
    assert rec.returncode == 0, rec.output()
    assert "/lander/state" in rec.output()  # the per-topic summary

    b = read_bag(bag)
    assert b.storage == "sqlite3" and not b.warnings
    s = b.series("/lander/state")
    seq = s["sequence"].astype(np.int64)
    start = int(np.flatnonzero(seq == 1)[-1])
    # Every state after the reset, none missing or repeated, one /clock with each.
    np.testing.assert_array_equal(seq[start:], np.arange(1, len(seq) - start + 1))
    assert s["t"][-1] >= 3.0
    assert np.count_nonzero(b.series("/clock")["t"] > 0) == np.count_nonzero(s["t"][start:] > 0)
